// A row whose first run is predicted past --time-limit is not started, and
// says why (harness/first_run.h): cvode/klu's prediction is KLU's own
// analysis of its Newton matrix (reference/klu_prediction.h).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "harness/first_run.h"
#include "harness/methods.h"
#include "model/particle_system.h"
#include "model/scene.h"
#include "reference/klu_prediction.h"

namespace clothbench {
namespace {

// KLU's analysis of a tridiagonal matrix: no fill, so L and U hold the
// diagonal and one off-diagonal each, 2n − 1 entries.
TEST(FirstRun, KluAnalysisOfATridiagonalMatrixHasNoFill) {
  const int n = 1000;
  std::vector<Triplet> t;
  for (int i = 0; i < n; ++i) {
    t.emplace_back(i, i, 4.0);
    if (i > 0) t.emplace_back(i, i - 1, -1.0);
    if (i + 1 < n) t.emplace_back(i, i + 1, -1.0);
  }
  SparseMatrix a(n, n);
  a.setFromTriplets(t.begin(), t.end());
  a.makeCompressed();
  const KluAnalysis k = AnalyzeKlu(a);
  EXPECT_EQ(k.rows, n);
  EXPECT_EQ(k.nnz, 3 * n - 2);
  EXPECT_EQ(k.lnz, 2 * n - 1);
  EXPECT_EQ(k.unz, 2 * n - 1);
  EXPECT_GT(k.flops, 0.0);
}

// The default scene (400 particles): one factorisation is far below 10⁹
// flops, and nothing is predicted.
TEST(FirstRun, NothingIsPredictedForASmallSheet) {
  const ParticleSystem sys(DefaultScene());
  const FirstRunPrediction p = PredictKluRun(sys);
  EXPECT_EQ(p.seconds, 0.0);
  EXPECT_EQ(p.bytes, 0.0);
}

// The default sheet refined to 80×80: cvode/klu's first factorisation is
// predicted (above 10⁹ flops; 0.5–1 s here), so with --time-limit 0.01 s
// the row is not started, takes no step and names the prediction's source;
// cvode, the reduced PCG solve, has no prediction and runs.
TEST(FirstRun, KluRowPredictedPastTheLimitIsNotStarted) {
  const Scene scene = RefineGrid(DefaultScene(), 6400);
  const ParticleSystem sys(scene);
  const FirstRunPrediction p = PredictKluRun(sys);
  ASSERT_GT(p.seconds, 0.01);
  EXPECT_GT(p.bytes, 0.0);
  RunContext ctx;
  ctx.limits.time_limit_s = 0.01;
  Scene one_step = scene;
  one_step.t_end = scene.frame_dt;
  const ParticleSystem short_sys(one_step);
  for (const std::string label : {"cvode/klu", "ida/klu"}) {
    const std::vector<RowMethod> rows = ExpandMethods({label}, {scene.solver.nonlinear_solver}, "test");
    ASSERT_EQ(rows.size(), 1u);
    const MethodRun r = rows.front().Run(short_sys, one_step, one_step.solver, 1e-3, ctx);
    EXPECT_EQ(r.status, RunStatus::kNotStarted) << label << ": " << r.message;
    EXPECT_EQ(r.steps, 0);
    EXPECT_NE(r.message.find("past --time-limit 0.01 s (klu_analyze: one factorisation"), std::string::npos)
        << r.message;
    EXPECT_EQ(r.label, label);
  }
}

// The rule itself: past the time limit, or past 80 % of the memory
// available (10¹⁵ B, a petabyte, exceeds any machine's), not started with
// the reason; within both, or without a time limit, started.
TEST(FirstRun, RefusalNamesTheBoundItExceeds) {
  RunSummary run;
  EXPECT_FALSE(RefusedByPrediction({10.0, 1e6, "src"}, 20.0, &run));
  EXPECT_FALSE(RefusedByPrediction({10.0, 1e6, "src"}, 0.0, &run));  // no limit
  EXPECT_EQ(run.status, RunStatus::kNotRun);  // untouched
  EXPECT_TRUE(RefusedByPrediction({30.0, 1e6, "src"}, 20.0, &run));
  EXPECT_EQ(run.status, RunStatus::kNotStarted);
  EXPECT_EQ(run.message, "not started: predicted at 30 s, past --time-limit 20 s (src)");
  RunSummary big;
  EXPECT_TRUE(RefusedByPrediction({1.0, 1e15, "src"}, 20.0, &big));
  EXPECT_EQ(big.status, RunStatus::kNotStarted);
  EXPECT_NE(big.message.find("predicted to hold 1e+06 GB, more than 80 % of the"), std::string::npos) << big.message;
}

}  // namespace
}  // namespace clothbench
