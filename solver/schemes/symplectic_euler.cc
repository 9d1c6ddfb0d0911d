// Symplectic (semi-implicit) Euler: v₁ = v₀ + h M⁻¹ f(t₀, x₀, v₀),
// x₁ = x₀ + h v₁, the explicit baseline of the stability maps (the engine's
// explicit step, StepEngine::ExplicitStep). Its row, as the registry lists
// it (harness/registry.cc).
#include "solver/method_row.h"
#include "solver/scheme.h"

namespace clothbench {
namespace {

class SymplecticEuler final : public Scheme {
 public:
  std::string_view name() const override { return "symplectic_euler"; }
  bool imex() const override { return false; }
  bool explicit_step() const override { return true; }
  StageCoefficients Prepare(const Stage&) const override { return {}; }  // not used: the step is explicit
};

}  // namespace

const Scheme& SymplecticEulerScheme() {
  static const SymplecticEuler scheme;
  return scheme;
}

/// Symplectic Euler: the explicit baseline of the stability maps; not a
/// default row.
MethodEntry SymplecticEulerRow() {
  return {.name = "symplectic_euler", .layer = "solver", .collisions = true,
          .make = MakeEngine<Method::kSymplecticEuler>};
}

}  // namespace clothbench
