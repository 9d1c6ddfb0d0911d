// Contact detection against the obstacles (collision/obstacle_contacts.h;
// docs/model.md §7), particle by particle, on a sphere of radius 0.25 m
// centred at (0, 0, 0.5) with δ = 0.01 m, at h = 0.01 s. The expected
// distances are the sphere's closed-form signed distance |x − c| − r, so
// they hold to round-off (1e-12 m).
// 1. Test 1 (proximity): a particle 5 mm above the top is in contact along
//    +z, inside the area, d = 5 mm.
// 2. Test 3 (predicted entry): 3 cm above the top falling at 4 m/s (d +
//    h⟨v, D⟩ = −1 cm < δ) it is a predicted entry (not inside); at rest
//    there it is no contact.
// 3. Hysteresis: at d = 1.5 δ a particle that was in contact with the sphere
//    is kept; one that was not, is not. A released particle is no contact
//    even inside the area, but its distance is still measured (the next
//    step's test 2 reads it).
// 4. Test 2 (old→new cast): a particle that was 2 cm above the top and is
//    now 1 cm above the bottom, inside (it crossed the top in the last
//    step), is sent back to the side it came from: D = +z (the entered
//    face's normal) and d = −0.49 m to the top's plane, where proximity
//    alone would push it out through the bottom (D = −z, d = −0.01 m).
// 5. Nearest, GapBound, StartedOutside: the gap d − δ at a point, the
//    1-Lipschitz bound from the step's distances, and whether the particle
//    started outside every area.
#include <gtest/gtest.h>

#include <cmath>

#include "collision/obstacle_contacts.h"
#include "model/particle_system.h"
#include "model/scene.h"

namespace clothbench {
namespace {

constexpr double kH = 0.01, kDelta = 0.01, kTop = 0.75;

Scene SphereScene() {
  return ParseScene(R"(name = "sphere_contacts"
t_end = 0.1
h = 0.01
[grid]
nu = 3
nv = 3
size = [0.2, 0.2]
origin = [-0.1, -0.1, 0.8]
u_axis = [1.0, 0.0, 0.0]
v_axis = [0.0, 1.0, 0.0]
[material]
density = 1.0
tension = [100.0, 100.0]
[[obstacle]]
type = "sphere"
center = [0.0, 0.0, 0.5]
radius = 0.25
collision_distance = 0.01
)",
                    "obstacle_contacts_test");
}

struct Fixture {
  Scene scene = SphereScene();
  ParticleSystem sys{scene};
  ObstacleDetection det{sys};
  Fixture() { det.BeginStep(0.0); }
  bool Detect(const Vector3& x0, const Vector3& v0, const Vector3* x_prev, ObstacleDetection::Prior prior,
              ObstacleContact* c, int p = 0) {
    return det.Detect(p, kH, x0, v0, x_prev, prior, 0.0, c);
  }
};

TEST(ObstacleDetection, ProximityAndPredictedEntry) {
  Fixture f;
  ObstacleContact c;
  ASSERT_TRUE(f.Detect(Vector3(0, 0, kTop + 0.005), Vector3::Zero(), nullptr, {}, &c));
  EXPECT_EQ(c.particle, 0);
  EXPECT_EQ(c.obstacle, 0);
  EXPECT_TRUE(c.inside);
  EXPECT_NEAR(c.distance, 0.005, 1e-12);
  EXPECT_NEAR((c.normal - Vector3::UnitZ()).norm(), 0.0, 1e-12);

  ASSERT_TRUE(f.Detect(Vector3(0, 0, kTop + 0.03), Vector3(0, 0, -4.0), nullptr, {}, &c, 1));
  EXPECT_FALSE(c.inside);  // predicted: 0.03 − 0.04 < δ
  EXPECT_NEAR(c.distance, 0.03, 1e-12);
  EXPECT_NEAR((c.v_rel - Vector3(0, 0, -4.0)).norm(), 0.0, 1e-12);
  EXPECT_FALSE(f.Detect(Vector3(0, 0, kTop + 0.03), Vector3::Zero(), nullptr, {}, &c, 2));
}

TEST(ObstacleDetection, HysteresisReleaseAndTheOldNewCast) {
  Fixture f;
  ObstacleContact c;
  const Vector3 x(0, 0, kTop + 1.5 * kDelta);
  const ObstacleDetection::Prior was{0, Vector3::UnitZ(), false};
  EXPECT_TRUE(f.Detect(x, Vector3::Zero(), nullptr, was, &c, 0));  // kept below 2δ
  EXPECT_FALSE(f.Detect(x, Vector3::Zero(), nullptr, {}, &c, 1));  // not in contact before: d ≥ δ
  const ObstacleDetection::Prior released{0, Vector3::UnitZ(), true};
  EXPECT_FALSE(f.Detect(Vector3(0, 0, kTop + 0.002), Vector3::Zero(), nullptr, released, &c, 2));
  EXPECT_FALSE(f.det.StartedOutside(2));  // its distance (2 mm < δ) was measured

  // Test 2: from 2 cm above the top to 1 cm above the bottom in the last step.
  const Vector3 before(0, 0, kTop + 0.02), after(0, 0, 0.26);
  ASSERT_FALSE(f.Detect(before, Vector3::Zero(), nullptr, {}, &c, 3));  // stores d(x₋₁) = 2 cm
  f.det.BeginStep(kH);
  ASSERT_TRUE(f.Detect(after, Vector3::Zero(), &before, {}, &c, 3));
  EXPECT_TRUE(c.inside);
  EXPECT_NEAR((c.normal - Vector3::UnitZ()).norm(), 0.0, 1e-12);
  EXPECT_NEAR(c.distance, 0.26 - kTop, 1e-12);
  ASSERT_TRUE(f.Detect(after, Vector3::Zero(), nullptr, {}, &c, 5));  // without the history: proximity
  EXPECT_NEAR((c.normal + Vector3::UnitZ()).norm(), 0.0, 1e-12);
  EXPECT_NEAR(c.distance, -0.01, 1e-12);
}

TEST(ObstacleDetection, NearestGapBoundAndStartedOutside) {
  Fixture f;
  ObstacleContact c;
  double gap = 0.0;
  Vector3 n;
  EXPECT_EQ(f.det.Nearest(0.0, Vector3(0.5, 0, 0.5), &gap, &n), 0);
  EXPECT_NEAR(gap, 0.25 - kDelta, 1e-12);
  EXPECT_NEAR((n - Vector3::UnitX()).norm(), 0.0, 1e-12);
  const Vector3 x0(0, 0, kTop + 0.1);
  EXPECT_FALSE(f.Detect(x0, Vector3::Zero(), nullptr, {}, &c, 4));
  EXPECT_TRUE(f.det.StartedOutside(4));
  // From d = 0.1 m, a move of 3 cm leaves at least 0.1 − 0.03 − δ = 0.06 m of gap.
  EXPECT_NEAR(f.det.GapBound(4, x0, x0 + Vector3(0.03, 0, 0)), 0.06, 1e-12);
  EXPECT_EQ(f.det.queries(), 1);
  EXPECT_EQ(f.det.culled(), 0);  // an analytic sphere is never culled
}

}  // namespace
}  // namespace clothbench
