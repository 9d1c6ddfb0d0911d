// Fixed steps are fixed (solver/run.cc, docs/model.md "Fixed steps"): every
// step of a fixed-step run is the same double h, the clock is n·h, frames
// between steps are interpolated, and A_α with its preconditioner is built
// once per distinct αh.
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "peers/baraff_witkin.h"
#include "solver/run.h"
#include "verify/test_scenes.h"

namespace clothbench {
namespace {

// The default scene (swinging sheet) at 10×10 particles with its spacing
// (0.04 m): every method takes every step at its h = 0.01 s.
Scene SmallSheet(PreconditionerType pre) {
  Scene s = BuiltinScene("swinging_sheet");
  s.grid.nu = s.grid.nv = 10;
  s.grid.size = {0.36, 0.36};
  s.fixed = ResolveFixed("corner:u0v1", 10, 10, "");
  for (int p : ResolveFixed("corner:u1v1", 10, 10, "")) s.fixed.push_back(p);
  std::sort(s.fixed.begin(), s.fixed.end());
  s.solver.preconditioner = pre;
  return s;
}

// A 200-step run with h = 0.01 s: each stored step is h bit for bit, the
// step's end time is n·h exactly, and the matrix is rebuilt once per
// distinct αh: IMEX Euler α = 1; SBDF(2) and BDF(2) start with α = 1 and
// continue with α = 2/3; implicit midpoint α = 1/2; implicit Euler α = 1.
// The fully implicit methods iterate with Newton, which converges at this h
// (the fixed-point iteration rejects some steps of 0.01 s on this scene and
// retries them with h/2, which is a second αh by design).
TEST(FixedStep, OneBuildPerDistinctAlphaH) {
  const struct {
    Method method;
    int builds;
  } cases[] = {{Method::kImexEuler, 1},
               {Method::kSbdf2, 2},
               {Method::kBdf2, 2},
               {Method::kImplicitEuler, 1},
               {Method::kImplicitMidpoint, 1}};
  for (PreconditionerType pre : {PreconditionerType::kIc0, PreconditionerType::kCholesky}) {
    Scene scene = SmallSheet(pre);
    scene.solver.nonlinear_solver = NonlinearSolver::kNewton;
    const ParticleSystem sys(scene);
    for (const auto& c : cases) {
      RunOptions o;
      o.h = 0.01;
      o.t_end = 2.0;
      o.frame_dt = 0.1;
      const RunSummary r = RunIntegrator(sys, c.method, o);
      ASSERT_TRUE(r.ok()) << ToString(c.method) << ": " << r.message;
      ASSERT_EQ(r.steps, 200) << ToString(c.method);
      for (std::size_t n = 0; n < r.step_stats.size(); ++n) {
        ASSERT_EQ(r.step_stats[n].h, o.h) << ToString(c.method) << " step " << n;
        ASSERT_EQ(r.step_stats[n].t, static_cast<double>(n + 1) * o.h) << ToString(c.method) << " step " << n;
      }
      EXPECT_EQ(r.matrix_rebuilds, c.builds) << ToString(c.method);
      EXPECT_EQ(r.trajectory.times.back(), o.t_end);
    }
  }
}

// The Baraff–Witkin peer keeps its Laplacian preconditioner for the whole
// run when h is fixed (its J itself is refreshed every step by design).
TEST(FixedStep, BaraffWitkinStepsAreBitEqual) {
  Scene s = SmallSheet(PreconditionerType::kCholesky);
  const ParticleSystem sys(s);
  BaraffWitkin bw(sys, s.solver);
  RunOptions o;
  o.h = 0.01;
  o.t_end = 0.5;
  o.frame_dt = 0.1;
  const RunSummary r = RunStepper(sys, bw, o);
  ASSERT_TRUE(r.ok()) << r.message;
  for (const StepStats& st : r.step_stats) ASSERT_EQ(st.h, o.h);
}

// Frame times that are not multiples of h: the run steps on its own grid
// n·h and the frames in between are cubic Hermite interpolants of the two
// steps around them. A frame time that is also a step time is that step's
// state bit for bit, so frame_dt = 0.025 s with h = 0.01 s gives at t = 0.05,
// 0.1, … the same state as frame_dt = 0.01 s.
TEST(FixedStep, FramesBetweenStepsDoNotPerturbH) {
  const ParticleSystem sys(SmallSheet(PreconditionerType::kIc0));
  RunOptions on, off;
  on.h = off.h = 0.01;
  on.t_end = off.t_end = 0.3;
  on.frame_dt = 0.01;
  off.frame_dt = 0.025;
  const RunSummary a = RunIntegrator(sys, Method::kSbdf2, on);
  const RunSummary b = RunIntegrator(sys, Method::kSbdf2, off);
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_EQ(a.step_stats.size(), b.step_stats.size());
  for (const StepStats& st : b.step_stats) ASSERT_EQ(st.h, off.h);
  ASSERT_EQ(b.trajectory.times.size(), 13u);  // 0, 0.025, …, 0.3
  for (std::size_t k = 0; k < b.trajectory.times.size(); ++k) {
    EXPECT_EQ(b.trajectory.times[k], std::min(static_cast<double>(k) * 0.025, 0.3));
    if (k % 2 == 0) {  // t = 0.05 (k/2): frame 5 (k/2) of the other run
      const std::size_t ka = 5 * (k / 2);
      EXPECT_EQ((b.trajectory.positions[k] - a.trajectory.positions[ka]).cwiseAbs().maxCoeff(), 0.0) << k;
    } else {
      // Between steps: bounded by the neighbouring step states (the sheet
      // moves less than 1e-2 m per step here; interpolation error O(h⁴)).
      const std::size_t lo = static_cast<std::size_t>(std::floor(b.trajectory.times[k] / 0.01));
      const double gap = (a.trajectory.positions[lo + 1] - a.trajectory.positions[lo]).cwiseAbs().maxCoeff();
      const double dev = (b.trajectory.positions[k] - a.trajectory.positions[lo]).cwiseAbs().maxCoeff();
      EXPECT_LE(dev, 1.5 * gap) << k;
    }
  }
}

// t_end not a multiple of h: the last step is the remainder, every other
// step is h, and the run ends at t_end exactly.
TEST(FixedStep, LastStepIsTheRemainder) {
  const ParticleSystem sys(SmallSheet(PreconditionerType::kIc0));
  RunOptions o;
  o.h = 0.01;
  o.t_end = 0.105;
  o.frame_dt = 0.105;
  const RunSummary r = RunIntegrator(sys, Method::kImexEuler, o);
  ASSERT_TRUE(r.ok());
  ASSERT_EQ(r.step_stats.size(), 11u);
  for (std::size_t n = 0; n + 1 < r.step_stats.size(); ++n) EXPECT_EQ(r.step_stats[n].h, 0.01);
  EXPECT_EQ(r.step_stats.back().h, 0.105 - 10 * 0.01);
  EXPECT_EQ(r.step_stats.back().t, 0.105);
  EXPECT_EQ(r.matrix_rebuilds, 2);  // h, then the remainder
}

}  // namespace
}  // namespace clothbench
