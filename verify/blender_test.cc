// The `blender` row (peers/baraff_witkin.h): Blender's cg_filtered as it
// ships keeps a Δv whose CG stopped at the 100-iteration cap and counts the
// step, where `baraff_witkin` (the same step at its best settings) rejects
// such a step and retries it with h/2.
#include <gtest/gtest.h>

#include "peers/baraff_witkin.h"
#include "solver/run.h"

namespace clothbench {
namespace {

// The swinging sheet at 10×10 with a 10⁴× stiffer tension: numerical
// stiffness 6.25·10⁵ at h = 0.01 s, where CG without a preconditioner
// needs more than 100 iterations to reach 0.01 of ‖S b_Δ‖ in some steps.
Scene StiffSheet() {
  Scene s = BuiltinScene("swinging_sheet");
  s.grid.nu = s.grid.nv = 10;
  s.grid.size = {0.36, 0.36};
  s.fixed = {s.Index(0, 9), s.Index(9, 9)};
  s.material.tension = {1e7, 1e7};
  s.t_end = 0.2;
  s.frame_dt = 0.01;
  return s;
}

TEST(Blender, KeepsUnconvergedSolvesAndCountsThem) {
  const Scene s = StiffSheet();
  const ParticleSystem sys(s);
  BaraffWitkin blender(sys, s.solver, BaraffWitkinOptions{true});
  const RunSummary r = RunStepper(sys, blender, {0.01, s.t_end, s.frame_dt});
  ASSERT_EQ(r.status, RunStatus::kOk) << r.message;
  EXPECT_EQ(r.rejected, 0);  // nothing is retried, as in Blender
  EXPECT_GT(r.cg_unconverged, 0);
  for (const StepStats& st : r.step_stats) EXPECT_LE(st.cg_iterations, 100);  // Blender's conjgrad_looplimit

  // The same step at the scene's settings with the same cap rejects the
  // unconverged solves instead.
  SolverSpec capped = s.solver;
  capped.preconditioner = PreconditionerType::kNone;
  capped.cg_max_iterations = 100;
  BaraffWitkin bw(sys, capped);
  const RunSummary b = RunStepper(sys, bw, {0.01, 0.05, 0.01});
  EXPECT_EQ(b.cg_unconverged, 0);
  EXPECT_GT(b.rejected, 0);
  std::printf("[ blender ] %ld of %ld steps kept an unconverged CG solve; baraff_witkin with the same cap: %ld rejected\n",
              r.cg_unconverged, r.steps, b.rejected);
}

}  // namespace
}  // namespace clothbench
