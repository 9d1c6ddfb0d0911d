// The sewing phase (solver/sewing.h; docs/model.md §2.9; thesis §6.3): two
// panels placed apart in front of and behind a body are sewn at both sides.
#include <gtest/gtest.h>

#include <string>

#include "collision/cloth_mesh.h"
#include "collision/self_intersection.h"
#include "model/particle_system.h"
#include "solver/sewing.h"

namespace clothbench {
namespace {

// Two 0.4 × 0.3 m panels of 11 × 8 samples, 0.5 m apart (y = ±0.25),
// around a cylinder of radius 0.12 m; their sides meet at x = ±0.2 m.
const char* kPanels = R"(name = "panels"
t_end = 0.2
h = 0.005
frame_dt = 0.1
[[pattern]]
name = "front"
corners = [[0.0, 0.0], [0.4, 0.0], [0.4, 0.3], [0.0, 0.3]]
samples = [11, 8]
origin = [-0.2, 0.25, 1.0]
x_axis = [1.0, 0.0, 0.0]
y_axis = [0.0, 0.0, -1.0]
[[pattern]]
name = "back"
corners = [[0.0, 0.0], [0.4, 0.0], [0.4, 0.3], [0.0, 0.3]]
samples = [11, 8]
origin = [0.2, -0.25, 1.0]
x_axis = [-1.0, 0.0, 0.0]
y_axis = [0.0, 0.0, -1.0]
[[seam]]
a = "front:edge:u1"
b = "back:edge:u0"
[[seam]]
a = "back:edge:u1"
b = "front:edge:u0"
[sewing]
time = 0.5
[material]
density = 0.2
tension = [300.0, 300.0]
tension_damping = 2.0
shear = 5.0
bend = [1e-5, 1e-5]
[[obstacle]]
type = "cylinder"
center = [0.0, 0.0, 1.1]
radius = 0.12
height = 1.1
collision_distance = 0.01
[collision]
self = true
thickness = 0.002
)";

TEST(Sewing, PanelsAreSewnClosedAroundTheBody) {
  Scene s = ParseScene(kPanels, "panels.toml");
  ASSERT_NE(s.cloth, nullptr);
  EXPECT_FALSE(s.cloth->sewn);
  EXPECT_GT(s.cloth->largest_gap, 0.49);  // apart at the start
  EXPECT_THROW(ParticleSystem{s}, SceneError);  // nothing runs before the phase
  const SewingSummary st = Sew(&s);
  ASSERT_TRUE(s.cloth->sewn);
  EXPECT_EQ(st.steps, 100);                          // 0.5 s at h = 0.005 s
  EXPECT_EQ(s.num_particles(), 2 * 11 * 8 - 2 * 8);  // every seam pair one particle
  EXPECT_LE(st.largest_gap, 1e-6);
  const ParticleSystem sys(s);
  // No crossing triangle pair at the sewn start, and the body is inside.
  EXPECT_TRUE(SelfIntersections(sys.rest_positions(), SceneTriangles(s).vertices).empty());
  for (int p = 0; p < sys.num_particles(); ++p)
    EXPECT_GT(sys.rest_positions().row(p).head<2>().norm(), 0.12) << p;
  // Once per scene: a second call takes the sewn cloth from the cache.
  Scene again = ParseScene(kPanels, "panels.toml");
  Sew(&again);
  EXPECT_EQ(again.cloth->start, s.cloth->start);
  // Sewing needs seams; time must be given.
  std::string bad = kPanels;
  bad.replace(bad.find("time = 0.5"), 10, "tine = 0.5");
  EXPECT_THROW(ParseScene(bad, "p.toml"), SceneError);
}

}  // namespace
}  // namespace clothbench
