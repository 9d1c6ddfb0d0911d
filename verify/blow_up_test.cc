// The blow-up statuses (solver/run.h, BlowUpGuard; docs/model.md, "Blow-up
// statuses"): two runs that blew up and used to be stored as "ok" now end
// with a failure naming the time and the quantity, and the committed scenes'
// rows at a quarter of the scene's step are not flagged.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "harness/methods.h"
#include "verify/test_rows.h"
#include "model/particle_system.h"
#include "model/scene.h"
#include "peers/arkode.h"
#include "solver/run.h"

namespace clothbench {
namespace {

using testing::RunRow;

// SBDF(3) at h = 0.01 s on the swinging box gains energy once the sheet
// meets the box (the gain passes E_scale ≈ 6.7 J at t ≈ 0.6 s and 2.4 kJ by
// t = 2 s); at h/4 it rests like the other rows.
TEST(BlowUp, Sbdf3AtTheScenesStepFailsOnTheSwingingBox) {
  const Scene scene = BuiltinScene("swinging_box");
  const MethodRun r = RunRow(scene, "sbdf3", 0.01);
  EXPECT_EQ(r.status, RunStatus::kEnergyGrowth) << r.message;
  EXPECT_NE(r.message.find("at t = "), std::string::npos) << r.message;
  EXPECT_NE(r.message.find("E_scale"), std::string::npos) << r.message;
  EXPECT_LT(r.steps, 100) << "the failure is reported where the gain passes the bound, not at t_end";
  ASSERT_FALSE(r.trajectory.times.empty());
  EXPECT_LT(r.trajectory.times.back(), 1.0);
  const MethodRun fine = RunRow(scene, "sbdf3", 0.0025);
  EXPECT_TRUE(fine.ok()) << fine.message;
}

// With solver.contact_history = "restart" (model/solver_spec.h) SBDF(3)
// restarts with its one-step start whenever the contact set changes: at
// h = 0.01 s on the swinging box it no longer gains energy and comes to
// rest on the box (docs/notes/collisions.md, "Multistep history across contact
// events": 53.4 particles in contact at rest, 65.8 at h/16).
TEST(BlowUp, Sbdf3RestartedAtContactEventsRestsOnTheSwingingBox) {
  Scene scene = BuiltinScene("swinging_box");
  scene.solver.contact_history = ContactHistory::kRestart;
  const MethodRun r = RunRow(scene, "sbdf3", 0.01);
  ASSERT_TRUE(r.ok()) << r.status << " " << r.message;
  double colliding = 0.0;
  int n = 0;
  for (const StepStats& st : r.step_stats)
    if (st.status == StepStatus::kOk && st.t > 1.5) colliding += st.colliding, ++n;
  ASSERT_GT(n, 0);
  EXPECT_GT(colliding / n, 0.0) << "at rest on the box";
}

// ARKODE at rtol 1e-2 on the hanging sheet ends 0.73 m from the reference
// with +29 J over 1 s; at rtol 1e-4 it is ok.
TEST(BlowUp, ArkodeAtALooseToleranceFailsOnTheHangingSheet) {
  const ParticleSystem sys(BuiltinScene("hanging_sheet"));
  ReferenceOptions loose;
  loose.rtol = 1e-2;
  loose.t_end = sys.scene().t_end;
  loose.frame_dt = sys.scene().frame_dt;
  const RunSummary r = RunArkode(sys, loose);
  EXPECT_EQ(r.status, RunStatus::kEnergyGrowth) << r.message;
  EXPECT_NE(r.message.find("at t = "), std::string::npos) << r.message;
  ReferenceOptions tight = loose;
  tight.rtol = 1e-4;
  const RunSummary ok = RunArkode(sys, tight);
  EXPECT_TRUE(ok.ok()) << ok.message;
}

// A representative subset of the committed scenes' rows at h = h_scene/4
// (0.0025 s), under a minute: one row of each family on every small scene
// (the one-step IMEX, the multistep IMEX and fully implicit BDF(2) with
// Newton, the peers Baraff–Witkin and XPBD). None is flagged. The full
// calibration (every fixed-step row of every scene, the adaptive rows at
// their default tolerances) is in docs/model.md, "Blow-up statuses".
// SBDF(3) is left out of the hanging sheet: it blows up there at every h
// from h/4 to h/16 (docs/notes/work-precision.md), a real instability.
TEST(BlowUp, SceneRowsAtAQuarterOfTheScenesStepAreNotFlagged) {
  const std::vector<std::string> rows = {"sbdf2", "bdf2/newton", "baraff_witkin", "xpbd"};
  for (const char* name : {"swinging_sheet", "hanging_sheet", "wind_sheet", "swinging_box", "round_table",
                           "tablecloth"}) {
    const Scene scene = BuiltinScene(name);
    for (const std::string& label : rows) {
      const MethodRun r = RunRow(scene, label, scene.h / 4.0);
      EXPECT_TRUE(r.ok()) << name << " " << label << ": " << r.status << " " << r.message;
    }
  }
}

}  // namespace
}  // namespace clothbench
