// XPBD with substeps (peers/xpbd, docs/model.md §10).
//
// 1. The projections against hand-computed two-particle cases (exact up to
//    round-off, 1e-14): the distance constraint (XPBD Eq. 18), its damping
//    (Eq. 26) and the isotropic damper, with one particle fixed (w = 0).
// 2. Convergence: on the swinging sheet (every term but transverse), e_rms
//    at t_end against CVODE (rtol 1e-10) falls by more than 3× per 4× more
//    substeps from 4 to 64 at h = 0.01 s. One sweep per substep makes XPBD a
//    first-order method in Δt = h/n (as Δt → 0 the compliance term α/Δt²
//    dominates and the projection becomes a symplectic Euler step of the
//    spring forces), so the ratio tends to 4; measured 3.6 and 3.9.
// 3. Collisions: on the tablecloth at h = 0.01 s with 4 and 16 substeps, no
//    particle is deeper than δ/2 below the table after settling
//    (t ≥ 0.5 s), and the cloth rests on it (more than 80 particles in the
//    collision area at t_end; 169 lie over the top), as for the thesis'
//    methods (collision_test).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "verify/test_metrics.h"
#include "peers/xpbd.h"
#include "reference/cvode_reference.h"
#include "results/metrics.h"
#include "solver/run.h"

namespace clothbench {
namespace {

TEST(Xpbd, DistanceProjectionMatchesHandComputation) {
  // a at 0, b at 1.5 along x, rest length 1: C = 0.5. w_a = 1, w_b = 2
  // [1/kg], α = 0.01 m/N, Δt = 0.1 s: α̃ = 1, Δλ = −0.5/(3 + 1) = −0.125,
  // p_a = 0 + 1·0.125 = 0.125, p_b = 1.5 − 2·0.125 = 1.25.
  Vector3 pa(0, 0, 0), pb(1.5, 0, 0);
  double dl = Xpbd::ProjectDistance(&pa, &pb, pa, pb, 1.0, 2.0, 1.0, 0.01, 0.0, 0.1);
  EXPECT_NEAR(dl, -0.125, 1e-14);
  EXPECT_NEAR((pa - Vector3(0.125, 0, 0)).norm(), 0.0, 1e-14);
  EXPECT_NEAR((pb - Vector3(1.25, 0, 0)).norm(), 0.0, 1e-14);

  // With damping β = 2 N s/m: γ = α̃ β Δt = 0.2. The substep started at
  // x_b = 1.4 (x_a = p_a = 0), so ∇C·(p − x) = 0.1 and
  // Δλ = (−0.5 − 0.2·0.1)/(1.2·3 + 1) = −0.52/4.6.
  pa = Vector3(0, 0, 0);
  pb = Vector3(1.5, 0, 0);
  dl = Xpbd::ProjectDistance(&pa, &pb, Vector3(0, 0, 0), Vector3(1.4, 0, 0), 1.0, 2.0, 1.0, 0.01, 2.0, 0.1);
  EXPECT_NEAR(dl, -0.52 / 4.6, 1e-14);
  EXPECT_NEAR(pa.x(), 0.52 / 4.6, 1e-14);
  EXPECT_NEAR(pb.x(), 1.5 - 2.0 * 0.52 / 4.6, 1e-14);

  // a fixed (w_a = 0), b at (0, 3, 4): |d| = 5, l = 4, C = 1, n = (0, .6, .8);
  // zero compliance: Δλ = −1/2, b moves by w_b n Δλ = −n onto the sphere |d| = 4.
  pa = Vector3(0, 0, 0);
  pb = Vector3(0, 3, 4);
  dl = Xpbd::ProjectDistance(&pa, &pb, pa, pb, 0.0, 2.0, 4.0, 0.0, 0.0, 0.1);
  EXPECT_NEAR(dl, -0.5, 1e-14);
  EXPECT_EQ(pa, Vector3(0, 0, 0));
  EXPECT_NEAR((pb - Vector3(0, 2.4, 3.2)).norm(), 0.0, 1e-14);
}

TEST(Xpbd, DamperMatchesHandComputation) {
  // Relative displacement over the substep (p_b − x_b) − (p_a − x_a) =
  // (0.2, 0, −0.1) − (0, 0.1, 0) = (0.2, −0.1, −0.1); β Δt = 0.5·0.1 = 0.05,
  // w_a + w_b = 3: Δλ = −0.05/(1 + 0.15) (0.2, −0.1, −0.1).
  Vector3 pa(0, 0.1, 0), pb(1.2, 0, -0.1);
  const Vector3 expected = (-0.05 / 1.15) * Vector3(0.2, -0.1, -0.1);
  const Vector3 dl = Xpbd::ProjectDamper(&pa, &pb, Vector3(0, 0, 0), Vector3(1, 0, 0), 1.0, 2.0, 0.5, 0.1);
  EXPECT_NEAR((dl - expected).norm(), 0.0, 1e-14);
  EXPECT_NEAR((pa - (Vector3(0, 0.1, 0) - expected)).norm(), 0.0, 1e-14);
  EXPECT_NEAR((pb - (Vector3(1.2, 0, -0.1) + 2.0 * expected)).norm(), 0.0, 1e-14);
  // The relative velocity shrinks by 1/(1 + β Δt (w_a + w_b)), as an
  // implicit Euler step of the damper c (v_b − v_a) alone.
  const Vector3 rel = (pb - Vector3(1, 0, 0)) - (pa - Vector3(0, 0, 0));
  EXPECT_NEAR((rel - Vector3(0.2, -0.1, -0.1) / 1.15).norm(), 0.0, 1e-14);
}

TEST(Xpbd, RefusesZeroSubsteps) {
  const ParticleSystem sys(BuiltinScene("swinging_sheet"));
  EXPECT_THROW(Xpbd(sys, 0), std::invalid_argument);
}

TEST(Xpbd, ErrorFallsWithSubstepsOnTheSwingingSheet) {
  const Scene s = BuiltinScene("swinging_sheet");
  const ParticleSystem sys(s);
  const RunSummary ref = RunCvode(sys, {1e-10, -1.0, 5, s.t_end, s.frame_dt});
  ASSERT_TRUE(ref.ok()) << ref.message;
  double previous = 0.0;
  for (int n : {4, 16, 64}) {
    Xpbd xpbd(sys, n);
    const RunSummary r = RunStepper(sys, xpbd, {s.h, s.t_end, s.frame_dt});
    ASSERT_TRUE(r.ok()) << testing::Brief(r);
    const double e = CompareTrajectories(r.trajectory.positions, ref.trajectory.positions)->rms_at_end;
    std::printf("[ xpbd ] swinging_sheet h = %g s, %d substeps: e_rms %.3e m\n", s.h, n, e);
    if (previous > 0.0) {
      EXPECT_GT(previous / e, 3.0);
    }
    previous = e;
  }
}

TEST(Xpbd, NoParticleDeeperThanHalfDeltaOnTheTablecloth) {
  const Scene s = BuiltinScene("tablecloth");
  const ParticleSystem sys(s);
  const double delta = s.obstacles[0].collision_distance;
  for (int n : {4, 16}) {
    Xpbd xpbd(sys, n);
    const RunSummary r = RunStepper(sys, xpbd, {s.h, s.t_end, s.frame_dt});
    ASSERT_TRUE(r.ok()) << testing::Brief(r);
    const PenetrationSeries p = ComputePenetration(sys, r.trajectory);
    const double depth = testing::MaxDepthAfter(p, r.trajectory.times, 0.5);
    std::printf("[ xpbd ] tablecloth %d substeps: max depth after 0.5 s %.2e m (δ/2 = %.1e), colliding at t_end %d\n",
                n, depth, 0.5 * delta, r.step_stats.back().colliding);
    EXPECT_LT(depth, 0.5 * delta);
    EXPECT_GT(r.step_stats.back().colliding, 80);
  }
}

}  // namespace
}  // namespace clothbench
