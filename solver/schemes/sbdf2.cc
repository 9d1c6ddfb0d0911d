// SBDF(2) (thesis (3.30), (3.35)): BDF(2) on the linear part and g
// extrapolated, ĝ = (1 + ω) g₀ − ω g₋₁ (docs/model.md §4), one update a
// step; it starts with IMEX Euler. Its row, as the registry lists it
// (harness/registry.cc).
#include "solver/method_row.h"
#include "solver/scheme.h"
#include "solver/schemes/notes.h"

namespace clothbench {
namespace {

class Sbdf2 final : public Scheme {
 public:
  std::string_view name() const override { return "sbdf2"; }
  bool imex() const override { return true; }
  int past_steps() const override { return 1; }
  int past_g() const override { return 1; }
  bool error_controlled() const override { return true; }
  const Scheme& ForStep(int past, bool) const override { return past == 0 ? ImexEulerScheme() : *this; }
  StageCoefficients Prepare(const Stage& s) const override { return Bdf2Stage(s, true); }
  void Extrapolate(const MatrixN3& g0, const MatrixN3& gm1, const MatrixN3&, double omega, MatrixN3* g) const override {
    *g = (1 + omega) * g0 - omega * gm1;  // ĝ, variable-step extrapolation (docs/model.md §4)
  }
};

}  // namespace

const Scheme& Sbdf2Scheme() {
  static const Sbdf2 scheme;
  return scheme;
}

/// SBDF(2): 4.4e-2 … 1.5e-3 m at h … h/8 on the default scene, and h/16
/// below 1e-3 m; under error control (sbdf2/error) rtol 1e-2 … 1e-7.
MethodEntry Sbdf2Row() {
  return {.name = "sbdf2", .layer = "solver", .error_control = true, .collisions = true, .pcg = true,
          .make = MakeEngine<Method::kSbdf2>, .kernel_benchmark = true, .best_preconditioner = kBestPreconditioner,
          .defaults = {{.modifiers = "", .h_factors = {1.0, 1.0 / 2, 1.0 / 4, 1.0 / 8, 1.0 / 16}},
                       {.modifiers = "error", .rtols = kDefaultRtols}},
          .status_notes = {{"sbdf2", "penetration", kMultistepPenetration}},
          .thesis_rows = {{"3.2", "tablecloth", 9000, 50, 100, 304, 1.57}, {"3.2", "dress", -1, -1, 500, 15360, 169.5}},
          .thesis_experiments = {"Fig. 5.15"}};
}

}  // namespace clothbench
