// Implicit Euler (thesis (3.22)–(3.25), (3.34)): x₁ = x₀ + h v₁,
// A₁ v₁ = M v₀ − h L_K x₀ + h g(t₀ + h, x₀ + h v₁, v₁), iterated to
// convergence. Also BDF(2)'s start step. Its row, as the registry lists it
// (harness/registry.cc).
#include "solver/method_row.h"
#include "solver/scheme.h"

namespace clothbench {

StageCoefficients EulerStage(const Stage& s, bool imex) {
  StageCoefficients k;
  *s.xhat = *s.x0;
  *s.vhat = *s.v0;
  s.b0->noalias() = s.mass->asDiagonal() * *s.v0;
  s.engine->LinearProduct(false, *s.x0, s.tmp);
  *s.b0 -= s.h * *s.tmp;
  if (!imex) *s.xg0 = *s.x0;  // g's base point: only the fully implicit updates move it
  k.t_g = imex ? s.t : s.t + s.h;
  return k;
}

namespace {

class ImplicitEuler final : public Scheme {
 public:
  std::string_view name() const override { return "implicit_euler"; }
  bool imex() const override { return false; }
  StageCoefficients Prepare(const Stage& s) const override { return EulerStage(s, false); }
};

}  // namespace

const Scheme& ImplicitEulerScheme() {
  static const ImplicitEuler scheme;
  return scheme;
}

/// Implicit Euler: 3.0e-3, 1.5e-3, 7.5e-4 m at h/8, h/16, h/32 with the
/// fixed point on the default scene (larger h cost more: fixed-point
/// rejections); with Newton 2.2e-2, 1.1e-2, 5.9e-3 m at h, h/2, h/4 (1e-3 m
/// needs h ≈ 3e-4 s and 15–20 s, a tangent refresh per iterate, so its rows
/// do not bracket 1e-3 m).
MethodEntry ImplicitEulerRow() {
  return {.name = "implicit_euler", .layer = "solver", .nonlinear_solver = true, .collisions = true, .pcg = true,
          .make = MakeEngine<Method::kImplicitEuler>, .best_preconditioner = kBestPreconditioner,
          .defaults = {{.modifiers = "", .h_factors = {1.0 / 8, 1.0 / 16, 1.0 / 32}},
                       {.modifiers = "newton", .h_factors = {1.0, 1.0 / 2, 1.0 / 4}, .newton_variant = true}},
          .thesis_rows = {{"3.2", "tablecloth", 9000, 50, 206, 1038, 3.06}, {"3.2", "dress", -1, -1, 1654, 21424, 204.9}},
          .thesis_experiments = {"Table 5.1"}};
}

}  // namespace clothbench
