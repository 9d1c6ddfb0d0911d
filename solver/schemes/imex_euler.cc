// IMEX Euler (thesis (3.22)–(3.25), (3.33)): x₁ = x₀ + h v₁,
// A₁ v₁ = M v₀ − h L_K x₀ + h g(t₀, x₀, v₀); one update a step. Also
// SBDF(2)'s start step. Its row, as the registry lists it (harness/registry.cc).
#include "solver/method_row.h"
#include "solver/scheme.h"

namespace clothbench {
namespace {

class ImexEuler final : public Scheme {
 public:
  std::string_view name() const override { return "imex_euler"; }
  bool imex() const override { return true; }
  StageCoefficients Prepare(const Stage& s) const override { return EulerStage(s, true); }
};

}  // namespace

const Scheme& ImexEulerScheme() {
  static const ImexEuler scheme;
  return scheme;
}

/// IMEX Euler: 0.61, 0.39, 0.18, 0.060 m at h, h/4, h/16, h/64 on the
/// default scene (the swinging sheet, h = 0.01 s; docs/notes/work-precision.md).
/// Its error is 0.017 m at h/256 (`bench_integrators --integrators
/// imex_euler,implicit_euler/newton --h 0.01,0.0025,6.25e-4,1.5625e-4,3.90625e-5`);
/// 1e-3 m would need h ≈ 2e-6 s (order 1), about 45 s of solver time, so
/// its rows do not bracket 1e-3 m.
MethodEntry ImexEulerRow() {
  return {.name = "imex_euler", .layer = "solver", .collisions = true, .pcg = true,
          .make = MakeEngine<Method::kImexEuler>, .best_preconditioner = kBestPreconditioner,
          .defaults = {{.modifiers = "", .h_factors = {1.0, 1.0 / 4, 1.0 / 16, 1.0 / 64}}},
          .thesis_rows = {{"3.2", "tablecloth", 9000, 50, 100, 745, 1.69}, {"3.2", "dress", -1, -1, 500, 17198, 152.7}}};
}

}  // namespace clothbench
