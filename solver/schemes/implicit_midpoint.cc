// The implicit midpoint rule (thesis (3.26)): x₁ = x₀ + (h/2)(v₀ + v₁),
// x_m = x₀ + (h/4)(v₀ + v₁),
// A_½ v₁ = M v₀ − h L_K (x₀ + (h/4) v₀) − (h/2) L_D v₀ + h g(t₀ + h/2, x_m, v_m),
// iterated to convergence. Its row, as the registry lists it
// (harness/registry.cc).
#include "solver/method_row.h"
#include "solver/scheme.h"

namespace clothbench {

StageCoefficients MidpointStage(const Stage& s) {
  StageCoefficients k;
  k.midpoint = true;
  k.alpha = 0.5;
  k.gamma = 0.5;
  k.gamma_g = 0.25;
  const double h = s.h;
  *s.xhat = *s.x0 + (0.5 * h) * *s.v0;
  *s.vhat = *s.v0;
  *s.xg0 = *s.x0 + (0.25 * h) * *s.v0;
  s.b0->noalias() = s.mass->asDiagonal() * *s.v0;
  s.engine->LinearProduct(false, *s.xg0, s.tmp);
  *s.b0 -= h * *s.tmp;
  if (s.engine->system().has_tension_damping()) {
    s.engine->LinearProduct(true, *s.v0, s.tmp);
    *s.b0 -= (0.5 * h) * *s.tmp;
  }
  k.t_g = s.t + 0.5 * h;
  return k;
}

namespace {

// Why implicit midpoint ends `penetration` at a large h (docs/notes/collisions.md,
// "Implicit midpoint at the obstacles").
constexpr std::string_view kMidpointPenetration =
    "implicit_midpoint rows, penetration: the contact response prescribes the normal velocity v1 at the step's end, "
    "and the midpoint rule moves a particle by h (v0 + v1)/2, so an entering particle travels h|<v0, D>|/2 past where "
    "the response aims it; once that exceeds twice the collision distance delta (h > 4 delta/|<v0, D>|) it can end "
    "deeper than delta. A property of the method with this response (docs/notes/collisions.md, \"Implicit midpoint at the "
    "obstacles\").";

class ImplicitMidpoint final : public Scheme {
 public:
  std::string_view name() const override { return "implicit_midpoint"; }
  bool imex() const override { return false; }
  StageCoefficients Prepare(const Stage& s) const override { return MidpointStage(s); }
};

}  // namespace

const Scheme& ImplicitMidpointScheme() {
  static const ImplicitMidpoint scheme;
  return scheme;
}

/// Implicit midpoint with the fixed point: 6.3e-5 m already at h on the
/// default scene (at larger h the fixed point does not converge); with
/// Newton 4.0e-3, 9.9e-4, 2.5e-4 m at 4h, 2h, h.
MethodEntry ImplicitMidpointRow() {
  return {.name = "implicit_midpoint", .layer = "solver", .nonlinear_solver = true, .collisions = true, .pcg = true,
          .make = MakeEngine<Method::kImplicitMidpoint>, .best_preconditioner = kBestPreconditioner,
          .defaults = {{.modifiers = "", .h_factors = {1.0, 1.0 / 2, 1.0 / 4}},
                       {.modifiers = "newton", .h_factors = {4.0, 2.0, 1.0}, .newton_variant = true}},
          .status_notes = {{"implicit_midpoint", "penetration", kMidpointPenetration},
                           {"implicit_midpoint/newton", "penetration", kMidpointPenetration}},
          .thesis_rows = {{"3.2", "tablecloth", 9000, 50, 494, 813, 4.39}, {"3.2", "dress", -1, -1, 2078, 15877, 211.3}}};
}

}  // namespace clothbench
