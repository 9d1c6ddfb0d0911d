// Step engine (docs/model.md §3–4, §6): BDF(2) coefficients, fixed particles,
// bit-for-bit reproducibility, failure as a status, the iteration controller.
// The observed-order tests are in temporal_order_test.cc (label verify).
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include "verify/test_metrics.h"
#include "results/metrics.h"
#include "solver/run.h"
#include "verify/test_scenes.h"

namespace clothbench {
namespace {

TEST(Bdf2Coefficients, ConstantStepValues) {
  const Bdf2Coefficients c(1.0);
  EXPECT_DOUBLE_EQ(c.c1, 4.0 / 3.0);
  EXPECT_DOUBLE_EQ(c.c2, 1.0 / 3.0);
  EXPECT_DOUBLE_EQ(c.c3, 2.0 / 3.0);
}

// Variable-step BDF(2) is exact for polynomials of degree ≤ 2: constants
// (c1 − c2 = 1), t (c2/ω + c3 = 1) and t² (2 c3 − c2/ω² = 1).
TEST(Bdf2Coefficients, ExactForQuadraticsAtAnyRatio) {
  for (double w : {0.25, 0.5, 1.0, 2.0, 3.0}) {
    const Bdf2Coefficients c(w);
    EXPECT_NEAR(c.c1 - c.c2, 1.0, 1e-15);
    EXPECT_NEAR(c.c2 / w + c.c3, 1.0, 1e-15);
    EXPECT_NEAR(2 * c.c3 - c.c2 / (w * w), 1.0, 1e-15);
  }
}

// Fixed particles never move; runs are reproducible bit for bit.
TEST(StepEngine, FixedParticlesStayAndRunsAreReproducible) {
  Scene s = DefaultScene();
  s.t_end = 0.1;
  s.solver.cg_tolerance = 1e-6;
  const ParticleSystem sys(s);
  for (Method m : testing::EngineMethods()) {
    const RunSummary a = RunIntegrator(sys, m, {0.01, s.t_end, s.frame_dt});
    const RunSummary b = RunIntegrator(sys, m, {0.01, s.t_end, s.frame_dt});
    ASSERT_TRUE(a.ok()) << ToString(m) << ": " << a.message;
    EXPECT_EQ(a.trajectory.positions.size(), 11u);
    EXPECT_TRUE((a.trajectory.positions.back().array() == b.trajectory.positions.back().array()).all()) << ToString(m);
    EXPECT_EQ(a.cg_iterations, b.cg_iterations);
    for (int p : sys.fixed())
      EXPECT_EQ((a.trajectory.positions.back().row(p) - sys.rest_positions().row(p)).norm(), 0.0) << ToString(m);
    if (IsImex(m)) {
      // SBDF(3)'s start step (an IMEX midpoint step) takes two.
      EXPECT_EQ(a.updates, a.steps + (m == Method::kSbdf3 ? 1 : 0)) << "IMEX methods do one update per step";
    }
  }
}

// A step that cannot converge is rejected, retried with smaller h, and
// finally reported as a status: no exception, no NaN in the trajectory.
TEST(StepEngine, FailureIsReportedAsStatus) {
  Scene s = DefaultScene();
  s.solver.cg_max_iterations = 1;  // PCG cannot converge in one iteration here
  s.solver.max_rejections = 3;
  const ParticleSystem sys(s);
  const RunSummary r = RunIntegrator(sys, Method::kBdf2, {0.01, 0.1, 0.01});
  EXPECT_FALSE(r.ok());
  EXPECT_EQ(r.status, RunStatus::kCgFailed);
  EXPECT_EQ(r.rejected, 4);
  for (const MatrixN3& x : r.trajectory.positions) EXPECT_TRUE(x.allFinite());
  EXPECT_FALSE(r.message.empty());
}

// Invalid options are a status with a message naming the field, not a crash.
TEST(StepEngine, InvalidOptionsAreReported) {
  Scene s = DefaultScene();
  s.solver.cg_tolerance = 2.0;
  const RunSummary r = RunIntegrator(ParticleSystem(s), Method::kSbdf2, {0.01, 0.1, 0.01});
  EXPECT_FALSE(r.ok());
  EXPECT_EQ(r.status, RunStatus::kInvalidOptions);
  EXPECT_NE(r.message.find("cg_tolerance"), std::string::npos) << r.message;
  const RunSummary r2 = RunIntegrator(ParticleSystem(DefaultScene()), Method::kSbdf2, {-0.01, 0.1, 0.01});
  EXPECT_EQ(r2.status, RunStatus::kInvalidOptions);
  EXPECT_NE(testing::Brief(r2).find("h = -0.01"), std::string::npos) << testing::Brief(r2);
}

// The iteration controller (docs/model.md §6) changes h and still reaches t_end and
// every frame.
TEST(StepEngine, IterationControllerReachesEnd) {
  Scene s = DefaultScene();
  s.t_end = 0.2;
  s.solver.cg_tolerance = 1e-6;
  s.solver.step_control = StepControl::kIterations;
  s.solver.h_max = 0.02;
  const ParticleSystem sys(s);
  const RunSummary r = RunIntegrator(sys, Method::kBdf2, {0.005, s.t_end, s.frame_dt});
  ASSERT_TRUE(r.ok()) << r.message;
  EXPECT_EQ(r.trajectory.times.size(), 21u);
  double hmin = 1, hmax = 0;
  for (const StepStats& st : r.step_stats) {
    hmin = std::min(hmin, st.h);
    hmax = std::max(hmax, st.h);
  }
  EXPECT_GT(hmax, hmin);  // the controller did change h
  EXPECT_NEAR(r.step_stats.back().t, s.t_end, 1e-12);
}

}  // namespace
}  // namespace clothbench
