// Cloth at rest without external forces is a solution every step keeps,
// with one update and no rejection. There the right-hand side b = b₀ + βh g
// is the round-off of the cancelling tension terms, and the stopping tests
// relative to ‖b‖ and ‖v‖ alone could never pass: every update needed PCG
// iterations and each step was rejected after max_updates (bdf2 at
// h = 0.01 s: 911 rejected attempts in 1 s; bdf2/newton/error at rtol 1e-3
// on the sheet at the collision distance: 1618 steps and 849 rejections).
// The PCG's threshold has the round-off of b as its floor (solver/pcg.h,
// RoundOffFloor).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "harness/methods.h"
#include "verify/test_rows.h"
#include "model/particle_system.h"
#include "model/scene.h"

namespace clothbench {
namespace {

// A 10×10 sheet of 0.5 m at rest at height z [m], no gravity, the material
// of scenes/thin_plate.toml (stiff tension: h²k/(ρl²) = 292 at h = 0.01 s);
// with `plane`, a plane at z = 0 whose collision distance is 5 mm.
Scene SheetAtRest(double z, bool plane) {
  std::string text = R"(name = "rest"
t_end = 1.0
frame_dt = 0.01
h = 0.01
[grid]
nu = 10
nv = 10
size = [0.5, 0.5]
origin = [-0.25, -0.25, )" + std::to_string(z) + R"(]
u_axis = [1.0, 0.0, 0.0]
v_axis = [0.0, 1.0, 0.0]
[material]
density = 1.0
tension = [9000.0, 9000.0]
tension_damping = 50.0
shear = 10.0
bend = [1.0e-5, 1.0e-5]
[forces]
gravity = [0.0, 0.0, 0.0]
)";
  if (plane)
    text += R"([[obstacle]]
type = "plane"
center = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
collision_distance = 0.005
)";
  return ParseScene(text, "rest_test");
}

using testing::RunRow;

// Fixed steps, from the scene's h to 16 h: t_end/h steps, one update each,
// nothing rejected, and the sheet where it was (to 1e-9 m: the rest state
// moves only by round-off, 1e-12 m measured).
TEST(Rest, FixedStepRowsKeepASheetAtRestWithOneUpdatePerStep) {
  for (const bool plane : {false, true}) {
    const Scene scene = SheetAtRest(0.005, plane);
    for (const std::string label : {"implicit_euler", "bdf2", "implicit_midpoint", "bdf2/newton"}) {
      for (const double h : {0.01, 0.04, 0.16}) {
        const MethodRun r = RunRow(scene, label, h);
        const long steps = static_cast<long>(std::ceil(scene.t_end / h - 1e-9));
        SCOPED_TRACE(label + " h = " + std::to_string(h) + (plane ? " on the plane" : " free"));
        EXPECT_EQ(r.status, RunStatus::kOk) << r.message;
        EXPECT_EQ(r.rejected, 0);
        EXPECT_EQ(r.steps, steps);
        EXPECT_EQ(r.updates, steps);
        const MatrixN3& x0 = r.trajectory.positions.front();
        const MatrixN3& x1 = r.trajectory.positions.back();
        EXPECT_LT((x1 - x0).cwiseAbs().maxCoeff(), 1e-9);
      }
    }
  }
}

// Error control: the step grows to its cap as the error stays at round-off,
// as SBDF(2)'s single update does (7 steps in 1 s on both sheets); the
// fully implicit rows took 1618–1697 steps with 849–982 rejections before.
TEST(Rest, ErrorControlledRowsDoNotChatterAtRest) {
  for (const bool plane : {false, true}) {
    const Scene scene = SheetAtRest(0.005, plane);
    const long sbdf2_steps = RunRow(scene, "sbdf2/error", 1e-3).steps;
    for (const std::string label : {"bdf2/error", "bdf2/newton/error"}) {
      const MethodRun r = RunRow(scene, label, 1e-3);
      SCOPED_TRACE(label + (plane ? " on the plane" : " free"));
      EXPECT_EQ(r.status, RunStatus::kOk) << r.message;
      EXPECT_EQ(r.rejected, 0);
      EXPECT_LE(r.steps, sbdf2_steps);
    }
  }
}

}  // namespace
}  // namespace clothbench
