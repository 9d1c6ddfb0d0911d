// Newton's method for the fully implicit methods and the Baraff–Witkin peer
// (docs/model.md §10):
// 1. Newton stops at the same discrete solution as the fixed point of
//    Alg. 6 where both converge: both stop when ‖S F(v₁)‖ ≤ η‖S_F b‖, so
//    their v₁ differ by at most 2η‖b‖/λ_min(J_α) per step.
// 2. On the default scene at h = 0.01 s (numerical stiffness 62.5), Newton
//    converges in every step with at most 4 updates per step on average.
// 3. Baraff–Witkin is first order (self-convergence against BDF(2)/Newton
//    at h/64) and keeps the cloth out of the obstacles (depth < δ/2).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "verify/test_metrics.h"
#include "peers/baraff_witkin.h"
#include "results/metrics.h"
#include "solver/run.h"
#include "verify/test_scenes.h"

namespace clothbench {
namespace {

SolverSpec WithSolver(SolverSpec s, NonlinearSolver n) {
  s.nonlinear_solver = n;
  return s;
}

TEST(Newton, EqualsTheFixedPointWhereBothConverge) {
  Scene s = DefaultScene();
  s.solver.cg_tolerance = 1e-10;
  s.solver.max_updates = 200;
  const ParticleSystem sys(s);
  const double h = 0.0025;  // the fixed point converges here without rejections
  const int steps = 20;
  const double m_min = sys.masses().minCoeff();
  for (Method m : {Method::kImplicitEuler, Method::kBdf2, Method::kImplicitMidpoint}) {
    StepEngine fp(sys, m, WithSolver(s.solver, NonlinearSolver::kFixedPoint));
    StepEngine nw(sys, m, WithSolver(s.solver, NonlinearSolver::kNewton));
    ASSERT_TRUE(nw.newton());
    const MatrixN3 zero = MatrixN3::Zero(sys.num_particles(), 3);
    fp.Reset(0.0, sys.rest_positions(), zero);
    nw.Reset(0.0, sys.rest_positions(), zero);
    long fp_updates = 0, nw_updates = 0;
    double bound_v = 0.0;
    for (int k = 0; k < steps; ++k) {
      const StepStats a = fp.Step(h), b = nw.Step(h);
      ASSERT_EQ(a.status, StepStatus::kOk) << ToString(m);
      ASSERT_EQ(b.status, StepStatus::kOk) << ToString(m);
      fp_updates += a.updates;
      nw_updates += b.updates;
      // b ≈ A_α v₁ (to η): one step's stopping error in v is ≤ 2η‖b‖/m_min
      // (J_α ⪰ M with the clamp, up to the explicit terms' small
      // indefinite part, hence the factor 2 below); differences propagate
      // through a stable step with factor ≤ 1, so they add up.
      const MatrixN3 av = fp.system_matrix().matrix() * fp.v();
      bound_v += 2.0 * 2.0 * s.solver.cg_tolerance * av.norm() / m_min;
    }
    const double dv = (fp.v() - nw.v()).norm(), dx = (fp.x() - nw.x()).norm();
    std::printf("[ newton ] %-18s %d steps: updates fixed point %.1f, Newton %.1f per step; |Δv| %.2e (bound %.2e), "
                "|Δx| %.2e m (bound %.2e)\n",
                std::string(ToString(m)).c_str(), steps, double(fp_updates) / steps, double(nw_updates) / steps, dv,
                bound_v, dx, steps * h * bound_v);
    EXPECT_LE(dv, bound_v) << ToString(m);
    EXPECT_LE(dx, steps * h * bound_v) << ToString(m);  // x₁ = x̂ + γ h v₁, γ ≤ 1
    EXPECT_LT(nw_updates, fp_updates) << ToString(m);   // two different iterations, not one
  }
}

TEST(Newton, DefaultSceneAtTheNominalStep) {
  Scene s = DefaultScene();
  s.solver.nonlinear_solver = NonlinearSolver::kNewton;
  s.t_end = 0.5;
  const ParticleSystem sys(s);
  for (Method m : {Method::kImplicitEuler, Method::kBdf2, Method::kImplicitMidpoint}) {
    const RunSummary r = RunIntegrator(sys, m, {0.01, s.t_end, s.frame_dt});
    ASSERT_TRUE(r.ok()) << ToString(m) << ": " << testing::Brief(r);
    const double per_step = double(r.updates) / double(r.steps);
    std::printf("[ newton ] %-18s h = 0.01 s: %.2f updates/step, %.1f CG/step, %ld rejected\n",
                std::string(ToString(m)).c_str(), per_step, double(r.cg_iterations) / double(r.steps), r.rejected);
    EXPECT_EQ(r.rejected, 0) << ToString(m);
    EXPECT_LE(per_step, 4.0) << ToString(m);
  }
}

TEST(BaraffWitkin, IsFirstOrder) {
  Scene s = DefaultScene();
  s.grid.nu = s.grid.nv = 10;
  s.grid.size = {0.36, 0.36};
  s.fixed = {s.Index(0, 9), s.Index(9, 9)};
  s.t_end = 0.2;
  s.frame_dt = 0.2;
  s.solver.cg_tolerance = 1e-10;
  const ParticleSystem sys(s);
  SolverSpec fine = s.solver;
  fine.nonlinear_solver = NonlinearSolver::kNewton;
  StepEngine ref_engine(sys, Method::kBdf2, fine);
  const RunSummary ref = RunStepper(sys, ref_engine, {0.01 / 64, s.t_end, s.frame_dt});
  ASSERT_TRUE(ref.ok()) << testing::Brief(ref);
  std::vector<double> hs, es;
  for (double h : {0.01, 0.005, 0.0025}) {
    BaraffWitkin bw(sys, s.solver);
    const RunSummary r = RunStepper(sys, bw, {h, s.t_end, s.frame_dt});
    ASSERT_TRUE(r.ok()) << testing::Brief(r);
    const auto e = CompareTrajectories(r.trajectory.positions, ref.trajectory.positions);
    ASSERT_TRUE(e);
    hs.push_back(h);
    es.push_back(e->rms_at_end);
  }
  const double order = testing::LeastSquaresOrder(hs, es);
  std::printf("[ baraff_witkin ] e_rms %.3e %.3e %.3e at h = 0.01, 0.005, 0.0025: order %.2f\n", es[0], es[1], es[2],
              order);
  // First order: the reference's own error (BDF(2) at h/64, ~1e-4 of
  // these) and the O(h²) part of the error leave the slope within ±0.2.
  EXPECT_NEAR(order, 1.0, 0.2);
}

class BaraffWitkinPenetration : public ::testing::TestWithParam<const char*> {};

TEST_P(BaraffWitkinPenetration, NoParticleDeeperThanHalfDelta) {
  Scene s = BuiltinScene(GetParam());
  const bool avatar = std::string(GetParam()) == "avatar_drape";
  if (avatar) s.t_end = 1.5;
  const ParticleSystem sys(s);
  BaraffWitkin bw(sys, s.solver);
  const RunSummary r = RunStepper(sys, bw, {s.h, s.t_end, s.frame_dt});
  ASSERT_TRUE(r.ok()) << testing::Brief(r);
  const PenetrationSeries p = ComputePenetration(sys, r.trajectory);
  const double delta = s.obstacles[0].collision_distance;
  const double depth = testing::MaxDepthAfter(p, r.trajectory.times, 0.5);
  std::printf("[ penetration ] %-12s baraff_witkin max depth after 0.5 s %.2e m (δ/2 = %.1e), colliding at t_end %d\n",
              GetParam(), depth, 0.5 * delta, r.step_stats.back().colliding);
  EXPECT_LT(depth, 0.5 * delta);
  EXPECT_GT(r.step_stats.back().colliding, avatar ? 20 : 80);  // the cloth rests on the obstacle
}

// A step's setup time (J's assembly, A_α's update and its prefiltered AMG's
// setups and finest-level updates) is part of the step's wall time, each
// counted once. Counting A_α's adaptation twice made setup_time_s exceed
// solve_time_s in contact; the bound holds exactly, whatever the machine.
TEST(BaraffWitkin, SetupTimeIsPartOfTheStepTime) {
  Scene s = BuiltinScene("round_table");
  s.t_end = 0.6;  // past the impact: contacts in every later step
  s.solver.preconditioner = PreconditionerType::kAmg;
  const ParticleSystem sys(s);
  BaraffWitkin bw(sys, s.solver);
  const RunSummary r = RunStepper(sys, bw, {s.h, s.t_end, s.frame_dt});
  ASSERT_TRUE(r.ok()) << testing::Brief(r);
  int in_contact = 0;
  for (const StepStats& st : r.step_stats) {
    in_contact += st.colliding > 0;
    EXPECT_GT(st.setup_time, 0.0) << "t = " << st.t;
    EXPECT_LE(st.setup_time, st.solve_time) << "t = " << st.t;
  }
  EXPECT_GT(in_contact, 0);
}

INSTANTIATE_TEST_SUITE_P(Scenes, BaraffWitkinPenetration,
                         ::testing::Values("tablecloth", "round_table", "avatar_drape"));

}  // namespace
}  // namespace clothbench
