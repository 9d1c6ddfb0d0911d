// BDF(2) (thesis (3.28)–(3.32), (3.36)): x₁ = c1 x₀ − c2 x₋₁ + c3 h v₁,
// A_c3 v₁ = M(c1 v₀ − c2 v₋₁) − c3 h L_K (c1 x₀ − c2 x₋₁) + c3 h g(t₀ + h, x₁, v₁),
// the variable-step coefficients of ω = h/h₋₁ (Bdf2Coefficients), iterated
// to convergence; it starts with implicit Euler. Its row, as the registry
// lists it (harness/registry.cc).
#include "solver/method_row.h"
#include "solver/scheme.h"
#include "solver/schemes/notes.h"

namespace clothbench {

StageCoefficients Bdf2Stage(const Stage& s, bool imex) {
  const Bdf2Coefficients bdf(s.omega);
  StageCoefficients k;
  k.alpha = k.beta = k.gamma = k.gamma_g = bdf.c3;
  k.carry1 = bdf.c2;  // v̂ − v₀ = (c1 − 1) v₀ − c2 v₋₁, c1 − 1 = c2
  *s.xhat = bdf.c1 * *s.x0 - bdf.c2 * *s.xm1;
  *s.vhat = bdf.c1 * *s.v0 - bdf.c2 * *s.vm1;
  s.engine->LinearProduct(false, *s.xhat, s.tmp);
  *s.b0 = s.mass->asDiagonal() * *s.vhat - (k.alpha * s.h) * *s.tmp;  // one pass (the same roundings as two)
  if (!imex) *s.xg0 = *s.xhat;  // g's base point: only the fully implicit updates move it
  k.t_g = s.t + s.h;
  return k;
}

namespace {

class Bdf2 final : public Scheme {
 public:
  std::string_view name() const override { return "bdf2"; }
  bool imex() const override { return false; }
  int past_steps() const override { return 1; }
  bool error_controlled() const override { return true; }
  const Scheme& ForStep(int past, bool) const override { return past == 0 ? ImplicitEulerScheme() : *this; }
  StageCoefficients Prepare(const Stage& s) const override { return Bdf2Stage(s, false); }
};

}  // namespace

const Scheme& Bdf2Scheme() {
  static const Bdf2 scheme;
  return scheme;
}

/// BDF(2) with the fixed point: 2.3e-4 m already at h on the default scene;
/// at larger h the fixed point does not converge and the step is halved, so
/// no run reaches 1e-3 m. With Newton: 7.9e-3, 2.7e-3, 7.4e-4 m at 4h, 2h,
/// h; under error control (bdf2/newton/error) rtol 1e-2 … 1e-7. It is the
/// method of the self-convergence reference (harness/reference.h).
MethodEntry Bdf2Row() {
  return {.name = "bdf2", .layer = "solver", .nonlinear_solver = true, .error_control = true, .collisions = true,
          .pcg = true, .make = MakeEngine<Method::kBdf2>, .self_convergence_reference = true,
          .best_preconditioner = kBestPreconditioner, .best_preconditioner_error = kBestPreconditioner,
          .defaults = {{.modifiers = "", .h_factors = {1.0, 1.0 / 2, 1.0 / 4, 1.0 / 8}, .rtols = kDefaultRtols},
                       {.modifiers = "newton", .h_factors = {4.0, 2.0, 1.0}, .newton_variant = true},
                       {.modifiers = "newton/error", .rtols = kDefaultRtols}},
          .status_notes = {{"bdf2", "penetration", kMultistepPenetration},
                           {"bdf2/newton", "penetration", kMultistepPenetration}},
          .thesis_rows = {{"3.1", "tablecloth", 1e4, 160, 803, 1160},
                          {"3.1", "tablecloth", 1e4, 1600, 198, 538},
                          {"3.1", "tablecloth", 1e5, 1600, 377, 566},
                          {"3.1", "tablecloth", 1e3, 1600, 52, 52},
                          {"3.2", "tablecloth", 9000, 50, 122, 857, 2.57},
                          {"3.2", "dress", -1, -1, 1431, 19307, 194.4}}};
}

}  // namespace clothbench
