// The kernel threads of a run on a busy machine (solver/thread_budget.h):
// the budget lowers a run's threads while other processes hold cores and
// raises them again when the cores are free, and a run gives the same bits
// on one thread and on two for every stepper row, so a change of team
// size between steps changes timings only.
#include <chrono>
#include <ctime>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <omp.h>

#include "harness/methods.h"
#include "model/scene.h"
#include "solver/thread_budget.h"
#include "verify/test_scenes.h"

namespace clothbench {
namespace {

// A planted machine: `others` cores busy besides this process, which uses
// `own` cores, over 1 s per reading.
struct PlantedMachine {
  double others = 0.0, own = 1.0;
  CpuTimes now;
  CpuTimes Read() {
    now.wall += 1.0;
    now.machine += others + own;
    now.process += own;
    now.valid = true;
    return now;
  }
};

TEST(ThreadBudget, LowersTheThreadsWhileAnotherProcessHoldsACoreAndRaisesThemAfter) {
  testing::WithThreads(2, [] {
    PlantedMachine m;
    {
      ThreadBudget budget(2, 2, [&] { return m.Read(); });
      EXPECT_EQ(budget.threads(), 2);
      m.others = 1.0;  // one core busy: one left for the run
      budget.ExpireInterval();
      budget.Update();
      EXPECT_EQ(budget.threads(), 1);
      EXPECT_EQ(omp_get_max_threads(), 1);
      m.others = 0.3;  // a light load rounds to a free core
      budget.ExpireInterval();
      budget.Update();
      EXPECT_EQ(budget.threads(), 2);
      EXPECT_EQ(omp_get_max_threads(), 2);
      m.others = 0.7;
      budget.ExpireInterval();
      budget.Update();
      EXPECT_EQ(budget.threads(), 1);
      m.others = 5.0;  // never below one thread
      budget.ExpireInterval();
      budget.Update();
      EXPECT_EQ(budget.threads(), 1);
      EXPECT_EQ(budget.fewest(), 1);
    }
    EXPECT_EQ(omp_get_max_threads(), 2);  // restored when the run ends
  });
}

TEST(ThreadBudget, MeasuresNoMoreOftenThanItsIntervalAndKeepsTheThreadsWithoutProc) {
  PlantedMachine m;
  m.others = 1.0;
  int reads = 0;
  ThreadBudget budget(2, 2, [&] {
    ++reads;
    return m.Read();
  });
  const auto start = std::chrono::steady_clock::now();
  for (int k = 0; k < 1000; ++k) budget.Update();
  // The baseline, then at most one reading per kInterval (a loaded machine
  // may stretch the 1000 calls past one).
  const auto elapsed = std::chrono::steady_clock::now() - start;
  EXPECT_LE(reads, 1 + static_cast<int>(elapsed / ThreadBudget::kInterval));
  EXPECT_EQ(budget.threads(), 2);
  ThreadBudget blind(2, 2, [] { return CpuTimes{}; });  // /proc unreadable
  blind.ExpireInterval();
  blind.Update();
  EXPECT_EQ(blind.threads(), 2);
}

// /proc's times advance with this process' work: a busy loop of 0.2 s of
// this thread's CPU time (CLOCK_THREAD_CPUTIME_ID, whatever the load) adds
// 0.2 s to the process less two of /proc's 10 ms ticks (one at each end),
// and the machine's busy time includes the process'.
TEST(ThreadBudget, ReadsThisProcessAndTheMachineFromProc) {
  const auto cpu = [] {
    timespec ts{};
    ::clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
  };
  const CpuTimes a = ReadCpuTimes();
  ASSERT_TRUE(a.valid);
  const double start = cpu();
  volatile double sink = 0.0;
  while (cpu() - start < 0.2) sink = sink + 1.0;
  const CpuTimes b = ReadCpuTimes();
  ASSERT_TRUE(b.valid);
  EXPECT_GE(b.wall - a.wall, 0.2);
  EXPECT_GE(b.process - a.process, 0.18);
  EXPECT_GE(b.machine - a.machine, b.process - a.process - 0.05);  // 0.05 s: the two files are read 10 ms-ticks apart
}

// Every stepper row, on the fold over the rod at 150×150 particles (above
// the kernels' parallel thresholds, kParallelMinimum = 2·10⁴ items) with
// self-contact, for three steps: the same positions on one and two OpenMP
// threads, with the rows' own preconditioners and with SBDF(2) on
// CHOLMOD's factor. (The BLAS under CHOLMOD keeps its threads, as the
// budget keeps them: with one OpenBLAS thread against two, SBDF(2), BDF(2)
// with Newton, implicit Euler and PD differ at the first frame.)
TEST(ThreadBudget, EveryStepperRowRepeatsBitForBitOnOneAndTwoThreads) {
  Scene s = LoadScene(std::string(CLOTHBENCH_SCENES_DIR) + "/fold_over_rod.toml");
  s.grid.nu = s.grid.nv = 150;
  s.h = 0.005;
  s.t_end = 3 * s.h;
  s.frame_dt = s.t_end;
  const ParticleSystem sys(s);
  for (const std::string label : {"sbdf2", "sbdf2/cholesky", "bdf2/newton", "implicit_euler", "baraff_witkin",
                                  "blender", "xpbd", "vbd", "vbd/chebyshev", "pd", "pd/chebyshev"}) {
    const bool cholesky = label == "sbdf2/cholesky";
    const std::vector<RowMethod> rows = ExpandMethods({cholesky ? "sbdf2" : label}, {s.solver.nonlinear_solver}, "test");
    ASSERT_EQ(rows.size(), 1u) << label;
    const RowMethod& row = rows.front();
    SolverSpec spec = s.solver;
    RunContext ctx;
    if (cholesky) {
      spec.preconditioner = PreconditionerType::kCholesky;
      ctx.preconditioner_from_cli = true;
    }
    const int count = row.kind() == StepKind::kSubstepped ? 4 : row.kind() == StepKind::kIterated ? 8 : 1;
    MethodRun one, two;
    testing::WithThreads(1, [&] { one = row.Run(sys, s, spec, s.h, ctx, count); });
    testing::WithThreads(2, [&] { two = row.Run(sys, s, spec, s.h, ctx, count); });
    ASSERT_EQ(one.status, RunStatus::kOk) << label << ": " << one.message;
    ASSERT_EQ(two.trajectory.positions.size(), one.trajectory.positions.size()) << label;
    for (std::size_t k = 0; k < one.trajectory.positions.size(); ++k)
      EXPECT_TRUE(two.trajectory.positions[k] == one.trajectory.positions[k]) << label << " frame " << k;
    EXPECT_EQ(one.threads_fewest, 1) << label;
  }
}

}  // namespace
}  // namespace clothbench
