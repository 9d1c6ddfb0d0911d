// SBDF(3), the third-order IMEX BDF of Ascher, Ruuth & Wetton (1995, k = 3,
// constant step): z₁ = (18 z₀ − 9 z₋₁ + 2 z₋₂)/11 + (6/11) h ż₁ for z = x, v,
// so A_{6/11} v₁ = M v̂ − (6/11) h L_K x̂ + (6/11) h ĝ with
// ĝ = 3 g₀ − 3 g₋₁ + g₋₂; one update a step. It starts with one IMEX
// midpoint step (two updates of the midpoint rule, local error O(h³)) and
// one SBDF(2) step, and takes an SBDF(2) step wherever the last three steps
// differ. Its row, as the registry lists it (harness/registry.cc).
#include "solver/method_row.h"
#include "solver/scheme.h"

namespace clothbench {
namespace {

// The start step: the midpoint rule with exactly two updates. g at the
// midpoint of the first update's v₁ (an O(h²) midpoint state) gives a local
// error O(h³), which keeps the method third order; it evaluates g₀ for the
// extrapolation of the steps after it.
class MidpointStart final : public Scheme {
 public:
  std::string_view name() const override { return "sbdf3"; }
  bool imex() const override { return false; }
  int exact_updates() const override { return 2; }
  bool evaluates_g0() const override { return true; }
  StageCoefficients Prepare(const Stage& s) const override { return MidpointStage(s); }
};

class Sbdf3 final : public Scheme {
 public:
  std::string_view name() const override { return "sbdf3"; }
  bool imex() const override { return true; }
  int past_steps() const override { return 2; }
  int past_g() const override { return 2; }
  const Scheme& ForStep(int past, bool equal_steps) const override {
    static const MidpointStart start;
    if (past == 0) return start;
    return past < 2 || !equal_steps ? Sbdf2Scheme() : *this;
  }
  StageCoefficients Prepare(const Stage& s) const override {
    StageCoefficients k;
    k.alpha = k.beta = k.gamma = k.gamma_g = 6.0 / 11.0;
    k.carry1 = 7.0 / 11.0;  // v̂ − v₀ = (7/11)(v₀ − v₋₁) − (2/11)(v₋₁ − v₋₂)
    k.carry2 = -2.0 / 11.0;
    *s.xhat = (18.0 / 11.0) * *s.x0 - (9.0 / 11.0) * *s.xm1 + (2.0 / 11.0) * *s.xm2;
    *s.vhat = (18.0 / 11.0) * *s.v0 - (9.0 / 11.0) * *s.vm1 + (2.0 / 11.0) * *s.vm2;
    s.engine->LinearProduct(false, *s.xhat, s.tmp);
    *s.b0 = s.mass->asDiagonal() * *s.vhat - (k.alpha * s.h) * *s.tmp;  // one pass (the same roundings as two)
    k.t_g = s.t + s.h;
    return k;
  }
  void Extrapolate(const MatrixN3& g0, const MatrixN3& gm1, const MatrixN3& gm2, double, MatrixN3* g) const override {
    *g = 3.0 * g0 - 3.0 * gm1 + gm2;  // ĝ, third order at a constant step
  }
};

}  // namespace

const Scheme& Sbdf3Scheme() {
  static const Sbdf3 scheme;
  return scheme;
}

/// SBDF(3): 4.2e-1, 4.6e-2, 1.7e-4, 2.2e-5 m at h, h/2, h/4, h/8 on the
/// default scene; at h and h/2 it gains energy (+294 W and +2.2 W: BDF3 is
/// not A-stable), so its rows start at h/4 (`bench_integrators --integrators
/// sbdf2,sbdf3,arkode,arkode/ark4,arkode/ark5,cvode` with sbdf3 at h … h/8).
MethodEntry Sbdf3Row() {
  return {.name = "sbdf3", .layer = "solver", .collisions = true, .pcg = true, .make = MakeEngine<Method::kSbdf3>,
          .best_preconditioner = kBestPreconditioner,
          .defaults = {{.modifiers = "", .h_factors = {1.0 / 4, 1.0 / 8, 1.0 / 16}}}};
}

}  // namespace clothbench
