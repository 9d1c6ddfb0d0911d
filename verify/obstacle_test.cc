// Obstacle geometry, keyframed motion and segment casts (docs/model.md §7,
// thesis §5.1 and §6.2).
//
// 1. Keyframed poses: halfway between two keyframes the translation is the
//    mean and the rotation half the arc; the analytic velocity of a material
//    point equals the central difference of its world position (error
//    O(Δt²) ≈ 1e-10 at Δt = 1e-5 for these O(1) motions: bound 1e-7); before
//    the first and after the last keyframe the pose is held, at rest.
// 2. A moving closed cube mesh (CGAL's data/meshes/cube.off, scaled) and the
//    analytic box under the same keyframes give the same signed distance
//    (1e-12 relative to the box: both are exact for a box) and direction.
// 3. Segment casts: entry points of segments into a box, a sphere and the
//    cube mesh are known in closed form (bisection tolerance 1e-12 of the
//    segment: bound 1e-9 m); a segment whose two ends lie outside a box but
//    whose middle cuts a corner is found; segments that miss give nothing;
//    on an open mesh the normal faces the segment's start.
// 4. The step engine: a particle whose predicted path enters a non-convex
//    mesh (two quads with a gap; the linear prediction misses it) stops
//    above it; a particle that already went through an open sheet in the
//    last step (the sheet jumped into its path) is sent back to the side it
//    came from; a rising keyframed plane lifts a resting cloth at its own
//    speed with no particle deeper than δ/2.
// 5. The distance cull of mesh obstacles (ContactResponse::SetUp): over
//    the avatar drape's impact, static and keyframed, the culled setup
//    builds the same constraints, targets and friction forces bit for bit
//    as the one that queries every particle, with fewer exact queries.
// 6. Guards: a non-finite or blown-up point is never queried (CGAL's exact
//    fallback raises SIGFPE on non-finite input), and XPBD ends a step whose
//    substep turned non-finite before its obstacle queries.
#include <cstdio>
#include <filesystem>
#include <limits>
#include <map>
#include <sstream>

#include <gtest/gtest.h>

#include "verify/test_metrics.h"
#include "collision/obstacle_proximity.h"
#include "model/obstacle.h"
#include "peers/xpbd.h"
#include "results/metrics.h"
#include "solver/contact.h"
#include "solver/run.h"
#include "verify/temp_file.h"
#include "verify/test_scenes.h"

namespace clothbench {
namespace {

const Vector3 kMovingBoxCentre(0.2, 0.1, 0.3);

ObstacleSpec MovingBoxSpec() {
  ObstacleSpec box;
  box.shape = ShapeFromValues("box", {{"center", kMovingBoxCentre}, {"size", Vector3(1.0, 1.0, 1.0)}});
  box.keyframes = {{0.5, Vector3::Zero(), Vector3::Zero()},
                   {1.5, Vector3(0.4, -0.2, 0.1), Vector3(10.0, -20.0, 60.0)},
                   {2.0, Vector3(0.4, 0.3, 0.0), Vector3(0.0, 0.0, 90.0)}};
  return box;
}

// The registry (collision/shapes/registry.cc) is the only place that knows
// the shapes: a scene names every registered type in its refusal of an
// unknown one, each registered type parses from its own keys, a shape
// reads only its own keys, and the same rules hold for shapes built in code.
TEST(ObstacleShapes, TheRegistryNamesAndParsesEveryShape) {
  const std::vector<std::string_view> types = ObstacleShapeTypes();
  ASSERT_EQ(types.size(), 8u);
  const std::string grid = "[grid]\nnu = 3\nnv = 3\nsize = [0.1, 0.1]\norigin = [0.0, 0.0, 1.0]\n";
  try {
    ParseScene(grid + "[[obstacle]]\ntype = \"cone\"\n", "cone.toml");
    ADD_FAILURE() << "an unknown type was accepted";
  } catch (const SceneError& e) {
    EXPECT_EQ(std::string(e.what()), "cone.toml: obstacle[0].type: must be \"plane\", \"sphere\", \"box\", "
                                     "\"cylinder\", \"capsule\", \"mesh\", \"mesh_sequence\" or \"skeleton\" (got \"cone\")");
  }
  const std::string cube = std::string(CLOTHBENCH_DATA_DIR) + "/meshes/cube.off";
  const std::map<std::string_view, std::string> keys = {
      {"plane", "center = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 2.0]"},
      {"sphere", "center = [0.0, 0.0, 0.0]\nradius = 0.2"},
      {"box", "center = [0.0, 0.0, 0.0]\nsize = [0.2, 0.2, 0.2]"},
      {"cylinder", "center = [0.0, 0.0, 0.0]\nradius = 0.2\nheight = 0.1"},
      {"capsule", "a = [0.0, 0.0, 0.0]\nb = [0.1, 0.0, 0.0]\nradius = 0.2"},
      {"mesh", "path = \"" + cube + "\"\nscale = 0.1"},
      {"mesh_sequence", "frames = [{ t = 0.0, path = \"" + cube + "\" }, { t = 1.0, path = \"" + cube + "\" }]\nscale = 0.1"},
      // A CMU clip (scripts/setup: assimp-testmodels) shrunk to 3e-5 m about the origin.
      {"skeleton", "path = \"/usr/share/assimp/models/BVH/01_01.bvh\"\nscale = 1e-6\nradius = 1e-4"}};
  for (std::string_view type : types) {
    ASSERT_TRUE(keys.count(type)) << type;
    const Scene s = ParseScene(grid + "[[obstacle]]\ntype = \"" + std::string(type) + "\"\n" + keys.at(type) + "\n",
                               "shapes.toml");
    ASSERT_EQ(s.obstacles.size(), 1u);
    EXPECT_EQ(s.obstacles[0].type(), type);
    // Every shape is below the cloth (z = 1 m), and says so in its distance.
    const Obstacle o(s.obstacles[0]);
    Vector3 d;
    EXPECT_GT(o.SignedDistance(0.0, Vector3(0.0, 0.0, 1.0), &d), 0.5) << type;
    // The skeleton's 3e-5 m spread turns its direction by up to 3e-5.
    EXPECT_NEAR(d.z(), 1.0, type == "skeleton" ? 1e-4 : 1e-12) << type;
  }
  // A key of another shape is unknown to this one.
  EXPECT_THROW(ParseScene(grid + "[[obstacle]]\ntype = \"sphere\"\nradius = 0.2\nheight = 0.1\n", "s.toml"),
               SceneError);
  EXPECT_THROW(ShapeFromValues("sphere", {{"radius", 0.2}, {"height", 0.1}}), std::invalid_argument);
  EXPECT_THROW(ShapeFromValues("sphere", {{"radius", -0.2}}), std::invalid_argument);
  EXPECT_THROW(ShapeFromValues("plane", {{"normal", Vector3::Zero()}}), std::invalid_argument);
  EXPECT_EQ(ShapeFromValues("box", {{"size", Vector3(1.0, 2.0, 3.0)}})->type(), "box");
}

// The capsule (collision/shapes/capsule.cc): its signed distance against
// the brute-force distance to 40,001 points of its segment less the
// radius (spacing 1e-5 m: the sampled minimum is within spacing²/(8 d) ≤
// 1.3e-10 m of the true one at d ≥ 0.1 m, so 1e-9 m), its direction
// against central differences of the distance (step 1e-6 m: error
// O(step²/d) ≈ 1e-11, so 1e-6), its entry point along a ray, its surface
// (every vertex on the capsule to round-off, closed: V − E + F = 2 with
// every edge in two triangles, each facing away from the axis) and its
// refusals.
TEST(ObstacleShapes, CapsuleDistanceDirectionAndSurface) {
  const Vector3 a(0.1, -0.2, 0.3), b(0.5, 0.1, 0.2);
  const double radius = 0.1;
  const auto shape = ShapeFromValues("capsule", {{"a", a}, {"b", b}, {"radius", radius}});
  std::srand(11);
  for (int trial = 0; trial < 200; ++trial) {
    const Vector3 p = 0.5 * (a + b) + 0.6 * Vector3::Random();
    double brute = std::numeric_limits<double>::infinity();
    for (int k = 0; k <= 40000; ++k) brute = std::min(brute, (p - (a + (b - a) * (k / 40000.0))).norm());
    if (brute < 0.1) continue;  // the tolerance above holds from 0.1 m
    Vector3 dir;
    const double d = shape->SignedDistance(p, &dir);
    EXPECT_NEAR(d, brute - radius, 1e-9) << p.transpose();
    Vector3 grad;
    for (int i = 0; i < 3; ++i) {
      Vector3 dummy;
      const Vector3 step = 1e-6 * Vector3::Unit(i);
      grad(i) = (shape->SignedDistance(p + step, &dummy) - shape->SignedDistance(p - step, &dummy)) / 2e-6;
    }
    EXPECT_NEAR((grad - dir).norm(), 0.0, 1e-6) << p.transpose();
  }
  // A ray straight down onto the middle of the axis enters where its
  // distance to the axis line, z sin θ (θ between the axis and the
  // vertical), is the radius.
  const Vector3 mid = 0.5 * (a + b);
  const auto hit = shape->FirstHit(mid + Vector3(0.0, 0.0, 1.0), mid - Vector3(0.0, 0.0, 1.0));
  ASSERT_TRUE(hit.has_value());
  const Vector3 entry = mid + Vector3(0.0, 0.0, 1.0) + hit->s * Vector3(0.0, 0.0, -2.0);
  const double sin_theta = std::sqrt(1.0 - std::pow((b - a).normalized().z(), 2));
  EXPECT_NEAR(entry.z(), mid.z() + radius / sin_theta, 1e-9);
  std::vector<Vector3> v;
  std::vector<std::array<int, 3>> t;
  shape->Surface(&v, &t);
  ASSERT_FALSE(t.empty());
  Vector3 dummy;
  for (const Vector3& x : v) EXPECT_NEAR(shape->SignedDistance(x, &dummy), 0.0, 1e-12);
  std::map<std::pair<int, int>, int> edges;
  for (const auto& tri : t) {
    for (int k = 0; k < 3; ++k) ++edges[std::minmax(tri[static_cast<std::size_t>(k)], tri[static_cast<std::size_t>((k + 1) % 3)])];
    const Vector3 p0 = v[static_cast<std::size_t>(tri[0])], p1 = v[static_cast<std::size_t>(tri[1])],
                  p2 = v[static_cast<std::size_t>(tri[2])];
    const Vector3 centroid = (p0 + p1 + p2) / 3.0;
    const double s = std::clamp((centroid - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
    EXPECT_GT((p1 - p0).cross(p2 - p0).dot(centroid - (a + s * (b - a))), 0.0);
  }
  for (const auto& [edge, count] : edges) EXPECT_EQ(count, 2) << edge.first << "-" << edge.second;
  EXPECT_EQ(static_cast<long>(v.size()) - static_cast<long>(edges.size()) + static_cast<long>(t.size()), 2);
  EXPECT_THROW(ShapeFromValues("capsule", {{"a", a}, {"b", a}, {"radius", radius}}), std::invalid_argument);
  EXPECT_THROW(ShapeFromValues("capsule", {{"a", a}, {"b", b}, {"radius", 0.0}}), std::invalid_argument);
}

TEST(ObstacleMotion, KeyframedPoseAndVelocity) {
  const Obstacle box(MovingBoxSpec());
  ASSERT_TRUE(box.moving());
  // Halfway through the last segment: translation (0.4, 0.05, 0.05).
  const ObstaclePose mid = box.PoseAt(1.75);
  EXPECT_NEAR((mid.translation - Vector3(0.4, 0.05, 0.05)).norm(), 0.0, 1e-14);
  // The half rotation applied twice is the whole relative rotation.
  const Eigen::Matrix3d r0 = RotationFromDegrees(Vector3(10.0, -20.0, 60.0));
  const Eigen::Matrix3d r1 = RotationFromDegrees(Vector3(0.0, 0.0, 90.0));
  const Eigen::Matrix3d half = mid.rotation * r0.transpose();
  EXPECT_NEAR((half * half - r1 * r0.transpose()).norm(), 0.0, 1e-12);
  // Material-point velocity vs central differences of its world position.
  const Vector3 x_placed(0.5, -0.3, 0.8);
  for (double t : {0.7, 1.2, 1.6, 1.9}) {
    const double dt = 1e-5;
    const ObstaclePose p = box.PoseAt(t);
    const Vector3 fd = (box.PoseAt(t + dt).ToWorld(x_placed) - box.PoseAt(t - dt).ToWorld(x_placed)) / (2 * dt);
    EXPECT_NEAR((p.Velocity(p.ToWorld(x_placed)) - fd).norm(), 0.0, 1e-7) << "t = " << t;
  }
  // Held before the first and after the last keyframe, at rest.
  for (double t : {0.0, 0.5, 2.0, 3.0}) {
    const ObstaclePose p = box.PoseAt(t);
    EXPECT_EQ(p.linear_velocity.norm() + p.angular_velocity.norm(), 0.0) << "t = " << t;
  }
  EXPECT_NEAR((box.PoseAt(3.0).rotation - r1).norm(), 0.0, 1e-14);
  EXPECT_TRUE(box.PoseAt(0.2).rotation.isIdentity(1e-15));
}

TEST(ObstacleMotion, MovingMeshCubeMatchesAnalyticBox) {
  const std::string cube = std::string(CLOTHBENCH_DATA_DIR) + "/meshes/cube.off";  // [-1, 1]³
  ASSERT_TRUE(std::filesystem::exists(cube)) << cube << " missing: run scripts/setup";
  const ObstacleSpec box_spec = MovingBoxSpec();
  ObstacleSpec mesh_spec = box_spec;
  mesh_spec.shape = ShapeFromValues("mesh", {{"path", cube}, {"scale", 0.5}, {"translate", kMovingBoxCentre}});
  const Obstacle box(box_spec), mesh(mesh_spec);
  std::srand(7);
  int compared = 0;
  for (double t : {0.0, 0.8, 1.5, 1.8, 2.5}) {
    for (int i = 0; i < 200; ++i) {
      const Vector3 p = kMovingBoxCentre + 1.2 * Vector3::Random();
      Vector3 db, dm;
      const double sb = box.SignedDistance(t, p, &db);
      const double sm = mesh.SignedDistance(t, p, &dm);
      ASSERT_NEAR(sb, sm, 1e-12 * (1.0 + std::abs(sb))) << "t = " << t << " p = " << p.transpose();
      // Directions agree where the closest point is unique (away from the
      // box's medial surfaces inside and its edges outside).
      if (sb > 1e-3 || sb < -1e-3) {
        const Vector3 q = box.PoseAt(t).ToPlaced(p) - kMovingBoxCentre;
        Vector3 sorted = q.cwiseAbs();
        std::sort(sorted.data(), sorted.data() + 3);
        if (sb > 0.0 || sorted(2) - sorted(1) > 1e-3) {
          EXPECT_NEAR((db - dm).norm(), 0.0, 1e-9);
          ++compared;
        }
      }
    }
  }
  EXPECT_GT(compared, 500);
}

// An OFF file of quads in the plane z = 0: each [x0, x1] × [-1, 1]
// (testing::TempFile: per process, removed after the test).
testing::TempFile WriteQuadsOff(const std::string& name, const std::vector<std::pair<double, double>>& spans) {
  std::ostringstream off;
  off << "OFF\n" << 4 * spans.size() << " " << 2 * spans.size() << " 0\n";
  for (auto [x0, x1] : spans) off << x0 << " -1 0\n" << x1 << " -1 0\n" << x1 << " 1 0\n" << x0 << " 1 0\n";
  for (std::size_t q = 0; q < spans.size(); ++q) {
    const std::size_t b = 4 * q;
    off << "3 " << b << " " << b + 1 << " " << b + 2 << "\n3 " << b << " " << b + 2 << " " << b + 3 << "\n";
  }
  return testing::TempFile(name, off.str());
}

TEST(ObstacleCast, FirstHitAnalyticAndMesh) {
  const ObstaclePose rest;
  ObstacleSpec box_spec;
  box_spec.shape = ShapeFromValues("box", {{"size", Vector3(2, 2, 2)}});
  const Obstacle box(box_spec);
  auto hit = box.FirstHit(rest, Vector3(0.2, 0.1, 3.0), Vector3(0.2, 0.1, -3.0));
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->s, 2.0 / 6.0, 1e-9);
  EXPECT_NEAR((hit->normal - Vector3::UnitZ()).norm(), 0.0, 1e-12);
  // Both ends outside, the middle cuts the corner region: x + y = 1.8.
  hit = box.FirstHit(rest, Vector3(1.3, 0.5, 0.0), Vector3(0.5, 1.3, 0.0));
  ASSERT_TRUE(hit);
  EXPECT_NEAR((hit->point - Vector3(1.0, 0.8, 0.0)).norm(), 0.0, 1e-9);
  EXPECT_NEAR((hit->normal - Vector3::UnitX()).norm(), 0.0, 1e-9);
  EXPECT_FALSE(box.FirstHit(rest, Vector3(1.6, 0.5, 0.0), Vector3(0.5, 1.6, 0.0)));  // x + y = 2.1 misses
  EXPECT_FALSE(box.FirstHit(rest, Vector3(0.0, 0.0, 0.5), Vector3(0.0, 0.0, 3.0)));  // starts inside

  ObstacleSpec sphere_spec;
  sphere_spec.shape = ShapeFromValues("sphere", {{"center", Vector3(1, 1, 1)}, {"radius", 0.5}});
  hit = Obstacle(sphere_spec).FirstHit(rest, Vector3(1, 1, 1) + Vector3(-2, 0.3, 0), Vector3(1, 1, 1) + Vector3(2, 0.3, 0));
  ASSERT_TRUE(hit);
  EXPECT_NEAR((hit->point - Vector3(1, 1, 1) - Vector3(-0.4, 0.3, 0)).norm(), 0.0, 1e-9);
  EXPECT_NEAR((hit->normal - Vector3(-0.8, 0.6, 0)).norm(), 0.0, 1e-9);

  ObstacleSpec cube_spec;
  cube_spec.shape = ShapeFromValues("mesh", {{"path", std::string(CLOTHBENCH_DATA_DIR) + "/meshes/cube.off"}});
  const Obstacle cube(cube_spec);
  hit = cube.FirstHit(rest, Vector3(1.3, 0.5, 0.0), Vector3(0.5, 1.3, 0.0));
  ASSERT_TRUE(hit);
  EXPECT_NEAR((hit->point - Vector3(1.0, 0.8, 0.0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((hit->normal - Vector3::UnitX()).norm(), 0.0, 1e-12);
  EXPECT_FALSE(cube.FirstHit(rest, Vector3(1.3, 0.5, 0.0), Vector3(1.1, 0.7, 0.0)));  // stops short

  ObstacleSpec sheet_spec;  // open: unsigned distance, normal faces the start
  const auto sheet_off = WriteQuadsOff("clothbench_sheet.off", {{-1.0, 1.0}});
  sheet_spec.shape = ShapeFromValues("mesh", {{"path", sheet_off.path()}});
  const Obstacle sheet(sheet_spec);
  hit = sheet.FirstHit(rest, Vector3(0.2, 0.3, -0.5), Vector3(0.2, 0.3, 0.5));
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->s, 0.5, 1e-12);
  EXPECT_NEAR((hit->normal + Vector3::UnitZ()).norm(), 0.0, 1e-12);
}

// A tiny 2×2 sheet (1 mm) moving rigidly: no internal forces, so every
// particle moves like a point mass.
Scene PointScene(const std::string& mesh_path) {
  Scene s;
  s.name = "points";
  s.grid.nu = s.grid.nv = 2;
  s.grid.size = {1e-3, 1e-3};
  s.material.tension = {1e-3, 1e-3};  // numerical stiffness h²k/(ρl²) = 0.1 at h = 0.01 s
  s.forces.gravity = Vector3::Zero();
  ObstacleSpec o;
  o.shape = ShapeFromValues("mesh", {{"path", mesh_path}});
  o.collision_distance = 0.01;
  o.relaxation = 0.5;
  s.obstacles.push_back(o);
  return s;
}

TEST(ObstacleCast, PredictedPathIntoANonConvexMeshIsStopped) {
  // Quads at x ≤ −0.1 and x ≥ 0.1. A particle above the left edge moving
  // fast to the right: its closest point is on the left quad, and the linear
  // prediction d + h⟨v, D⟩ = 0.058 + 0.465 m says it stays clear, but its
  // path x₀ → x₀ + h v crosses the right quad at x = 0.13 m.
  const auto gap_off = WriteQuadsOff("clothbench_gap.off", {{-1.0, -0.1}, {0.1, 1.0}});
  Scene s = PointScene(gap_off.path());
  const ParticleSystem sys(s);
  for (Method m : testing::EngineMethods()) {
    StepEngine engine(sys, m, s.solver);
    MatrixN3 x = sys.rest_positions();
    x.rowwise() += Vector3(-0.05, 0.0, 0.03).transpose() - x.row(0);
    MatrixN3 v(4, 3);
    v.rowwise() = Vector3(60.0, 0.0, -10.0).transpose();
    engine.Reset(0.0, x, v);
    const StepStats st = engine.Step(0.01);
    ASSERT_EQ(st.status, StepStatus::kOk) << ToString(m);
    EXPECT_EQ(st.colliding, 4) << ToString(m);
    // The cast gives D = +z and d = 0.03 m (the hit plane), so (4.4) sets
    // v₁_z = (δ − d)/h = −2 m/s (the first step of SBDF(2)/BDF(2) is IMEX
    // or implicit Euler). Euler steps then land on the border z = δ = 0.01,
    // not at z = −0.07 below the quad. Implicit midpoint's trapezoidal
    // position x₁ = x₀ + (h/2)(v₀ + v₁) overshoots to 0.03 + 0.005(−10 − 2)
    // = −0.03 m on the impact step: the velocity target cannot stop it
    // within the step (and a position target would bounce, see
    // ContactResponse::SetUp); the old→new cast brings it back (next test).
    // SBDF(3)'s first step is the midpoint rule (docs/model.md, "SBDF(3)").
    EXPECT_NEAR(engine.v().col(2).maxCoeff(), -2.0, 1e-9) << ToString(m);
    EXPECT_NEAR(engine.v().col(2).minCoeff(), -2.0, 1e-9) << ToString(m);
    const bool midpoint_start = m == Method::kImplicitMidpoint || m == Method::kSbdf3;
    const double z_expected = midpoint_start ? -0.03 : 0.01;
    EXPECT_NEAR(engine.x().col(2).minCoeff(), z_expected, 1e-9) << ToString(m);
  }
}

TEST(ObstacleCast, ParticleThatWentThroughASheetIsSentBack) {
  // An open sheet at z = 0 that is far away (z = −10) until t = 5 ms and
  // then in place: in the first step the particle falls from z = 0.03 to
  // −0.07 unhindered, so at the second step it is below the sheet, where the
  // unsigned distance points down. The old→new cast finds the face it went
  // through and turns it back; the side memory keeps it on that side. After
  // 20 more steps every method has it above the sheet (multistep histories
  // carry the fall's momentum, so SBDF(2)/BDF(2) need a few steps more).
  const auto sheet_off = WriteQuadsOff("clothbench_sheet.off", {{-1.0, 1.0}});
  Scene s = PointScene(sheet_off.path());
  s.obstacles[0].keyframes = {{0.005, Vector3(0, 0, -10), Vector3::Zero()},
                              {0.0050001, Vector3::Zero(), Vector3::Zero()}};
  const ParticleSystem sys(s);
  for (Method m : testing::EngineMethods()) {
    StepEngine engine(sys, m, s.solver);
    MatrixN3 x = sys.rest_positions();
    x.rowwise() += Vector3(0.2, 0.1, 0.03).transpose() - x.row(0);
    MatrixN3 v = MatrixN3::Zero(4, 3);
    v.col(2).setConstant(-10.0);
    engine.Reset(0.0, x, v);
    ASSERT_EQ(engine.Step(0.01).status, StepStatus::kOk);
    ASSERT_LT(engine.x().col(2).maxCoeff(), -0.05) << ToString(m);  // went through
    for (int k = 0; k < 20; ++k) ASSERT_EQ(engine.Step(0.01).status, StepStatus::kOk) << ToString(m);
    std::printf("[ tunnel ] %-18s z after 21 steps %.4f m (border δ = 0.01)\n", std::string(ToString(m)).c_str(),
                engine.x().col(2).minCoeff());
    EXPECT_GT(engine.x().col(2).minCoeff(), 0.0) << ToString(m);
  }
}

TEST(ObstacleMotion, RisingPlaneLiftsTheCloth) {
  // The tablecloth resting 5 mm above a plane at z = 0.7 m; the plane rises
  // 0.1 m between t = 0.2 and 0.6 s (0.25 m/s) and stops. The cloth must
  // ride on it: at t_end it rests on the raised border (z = 0.81 m, within
  // 1 mm: the relaxation ω_r = 0.5 closes the lag of the rise within a few
  // steps) and no particle is ever deeper than δ/2 below the moving plane.
  Scene s = testing::TableclothOnPlane(0.8);
  ObstacleSpec& plane = s.obstacles[0];
  plane.keyframes = {{0.2, Vector3::Zero(), Vector3::Zero()}, {0.6, Vector3(0, 0, 0.1), Vector3::Zero()}};
  const ParticleSystem sys(s);
  for (Method m : testing::EngineMethods()) {
    const RunSummary r = RunIntegrator(sys, m, {s.h, s.t_end, s.frame_dt});
    ASSERT_TRUE(r.ok()) << testing::Brief(r);
    const PenetrationSeries p = ComputePenetration(sys, r.trajectory);
    const double depth = testing::MaxDepthAfter(p, r.trajectory.times, 0.0);
    const double z_err = (r.trajectory.positions.back().col(2).array() - 0.81).abs().maxCoeff();
    std::printf("[ rising ] %-18s max depth %.2e m, |z - 0.81| at t_end %.2e m, colliding %d\n",
                std::string(ToString(m)).c_str(), depth, z_err, r.step_stats.back().colliding);
    EXPECT_LT(depth, 0.5 * plane.collision_distance) << ToString(m);
    EXPECT_LT(z_err, 1e-3) << ToString(m);
    EXPECT_EQ(r.step_stats.back().colliding, sys.num_particles()) << ToString(m);
  }
}

// A non-finite state inside a substep ends the step as non_finite before an
// obstacle query sees it; a mesh obstacle's queries (CGAL) with non-finite
// or blown-up points return "far, no hit" without computing. Before these
// guards, such a point went into CGAL's exact fallback, where GMP raises
// SIGFPE on non-finite input.
TEST(ObstacleGuard, NonFiniteStateNeverReachesTheMeshObstacle) {
  Scene s = BuiltinScene("swinging_sheet");
  ObstacleSpec o;
  o.shape = ShapeFromValues("mesh", {{"path", std::string(CLOTHBENCH_DATA_DIR) + "/meshes/cube.off"}});
  o.collision_distance = 0.01;
  s.obstacles.push_back(o);
  const ParticleSystem sys(s);
  const Obstacle& cube = sys.obstacles()[0];
  const double nan = std::nan(""), inf = std::numeric_limits<double>::infinity();
  for (const Vector3& p : {Vector3(nan, 0.5, 0.5), Vector3(0.5, inf, 0.5), Vector3(0.5, 0.5, -1e300),
                           Vector3(2e9, 0.0, 0.0)}) {
    Vector3 dir;
    EXPECT_EQ(cube.SignedDistance(0.0, p, &dir), inf) << p.transpose();
    EXPECT_FALSE(cube.FirstHit(cube.PoseAt(0.0), Vector3(0.5, 0.5, 2.0), p)) << p.transpose();
  }
  for (int n : {1, 8}) {
    Xpbd xpbd(sys, n);
    MatrixN3 v = MatrixN3::Zero(sys.num_particles(), 3);
    v(5, 2) = nan;  // a blown-up velocity of one free particle
    xpbd.Reset(0.0, sys.rest_positions(), v);
    const StepStats st = xpbd.Step(s.h);
    EXPECT_EQ(st.status, StepStatus::kNonFinite) << n << " substeps";
    EXPECT_EQ(xpbd.t(), 0.0);  // the step was not taken
  }
}


// The constraints of a filter in a comparable form: per constrained
// particle its count, directions and targets.
std::vector<double> FilterEntries(VelocityFilter* f) {
  std::vector<double> out;
  f->ForEachTarget([&](int p, int count, const Eigen::Matrix3d& dirs, const Vector3& targets) {
    out.push_back(p);
    out.push_back(count);
    for (int k = 0; k < count; ++k) {
      for (int r = 0; r < 3; ++r) out.push_back(dirs(r, k));
      out.push_back(targets(k));
    }
  });
  return out;
}

// The distance cull's scenes: the sheet falling onto the avatar, still,
// keyframed (turning and sliding under it), or in its place the body of
// scenes/mocap_dress.toml, capsules on the CMU clip that scripts/setup
// installs, 10 cm higher and jumping under it; or without gravity, the
// sheet held 2 cm above that body's head while the body crouches and
// rises through it at about 2 m/s at t = 1.3 s: the sheet's own motion
// does not bring it within reach, the body's speed does.
enum class CullCase { kStill, kKeyframed, kSkeleton, kRising };
constexpr CullCase kCullCases[] = {CullCase::kStill, CullCase::kKeyframed, CullCase::kSkeleton, CullCase::kRising};
const char* Name(CullCase c) {
  constexpr const char* kNames[] = {"static", "keyframed", "skeleton", "rising skeleton"};
  return kNames[static_cast<int>(c)];
}

Scene CullScene(CullCase c) {
  Scene s = LoadScene(std::string(CLOTHBENCH_SCENES_DIR) + "/avatar_drape.toml");
  if (c == CullCase::kKeyframed)
    s.obstacles[0].keyframes = {{0.0, Vector3::Zero(), Vector3::Zero()},
                                {0.6, Vector3(0.05, -0.03, 0.02), Vector3(0.0, 0.0, 20.0)}};
  if (c == CullCase::kSkeleton || c == CullCase::kRising)
    s.obstacles[0].shape = testing::MocapBody(Vector3(0.53, 0.93, c == CullCase::kRising ? 0.27 : 0.1));
  if (c == CullCase::kRising) s.forces.gravity.setZero();
  return s;
}

// SBDF(2) on CullScene, from rest.
struct CullRun {
  explicit CullRun(CullCase c) : scene(CullScene(c)), sys(scene), engine(sys, Method::kSbdf2, scene.solver) {
    engine.Reset(0.0, sys.rest_positions(), MatrixN3::Zero(sys.num_particles(), 3));
  }
  Scene scene;
  ParticleSystem sys;
  StepEngine engine;
};

// The detection with its distance cull sets up the same contacts, filter
// targets and friction, bit for bit, as with every distance queried, on
// each of CullScene's bodies.
TEST(DistanceCull, SameContactsAsExactQueries) {
  for (const CullCase c : kCullCases) {
    CullRun run(c);
    const Scene& s = run.scene;
    const ParticleSystem& sys = run.sys;
    StepEngine& engine = run.engine;
    const int n = sys.num_particles();
    ContactResponse culled(sys), exact(sys);
    exact.set_distance_cull(false);
    VelocityFilter fa, fb;
    fa.Reserve(n);
    fb.Reserve(n);
    MatrixN3 xm1;
    const double h = s.h;
    int most = 0;
    // 1 s: the fall and the sheet draped on the head; 1.5 s for the body that rises through the sheet.
    for (int step = 0; step < (c == CullCase::kRising ? 150 : 100); ++step) {
      const MatrixN3 x0 = engine.x(), v0 = engine.v();
      const MatrixN3* hist = step > 0 ? &xm1 : nullptr;
      const int na = culled.SetUp(engine.t(), h, x0, v0, hist, &fa);
      const int nb = exact.SetUp(engine.t(), h, x0, v0, hist, &fb);
      ASSERT_EQ(na, nb) << "step " << step << " (" << Name(c) << ")";
      ASSERT_EQ(FilterEntries(&fa), FilterEntries(&fb)) << "step " << step << " (" << Name(c) << ")";
      ASSERT_TRUE(culled.friction() == exact.friction()) << "step " << step << " (" << Name(c) << ")";
      most = std::max(most, na);
      ASSERT_EQ(engine.Step(h).status, StepStatus::kOk);
      // The same impulses read into both (an upward push, the weight's size).
      const auto residual = [&](int p) { return Vector3(0.0, 0.0, 9.81 * h * sys.masses()(p)); };
      culled.ReadImpulses(residual, v0, engine.v(), v0, 0.0);
      exact.ReadImpulses(residual, v0, engine.v(), v0, 0.0);
      xm1 = x0;
    }
    // 3 % of the sheet rests on the avatar's head; up to 19 and 10 of its
    // 1296 particles at once touch the jumping and the rising skeleton.
    const bool skeleton = c == CullCase::kSkeleton || c == CullCase::kRising;
    EXPECT_GT(most, skeleton ? n / 200 : n / 50) << Name(c) << ": the sheet must reach the body";
    // The cull must skip most queries of the fall (most particles far from
    // the body most of the time); exact counts them all.
    EXPECT_EQ(exact.culled_queries(), 0);
    EXPECT_LT(culled.distance_queries(), exact.distance_queries() / 2) << Name(c);
    std::printf("[ cull ] %s: %ld exact queries of %ld, up to %d contacts\n", Name(c), culled.distance_queries(),
                exact.distance_queries(), most);
  }
}

// The position-based peers' adapter (collision/obstacle_proximity.h) with
// its distance cull finds the same entries, bit for bit, as querying every
// particle: along a trajectory of the sheet falling onto the avatar, static
// and keyframed, and onto a jumping skeleton (CullScene), with positions
// pushed toward the body between the calls as
// a substep's projection would, and with half the particles held; and its
// penetration of each state is Obstacle::PenetrationOf's.
TEST(DistanceCull, ThePositionAdapterFindsWhatExactQueriesFind) {
  // The adapter's bound takes no speed (it queries the positions it is
  // given): the rising body adds nothing here.
  for (const CullCase c : {CullCase::kStill, CullCase::kKeyframed, CullCase::kSkeleton}) {
    CullRun run(c);
    const int n = run.sys.num_particles();
    ObstacleProximity culled(run.sys), exact(run.sys);
    exact.set_distance_cull(false);
    Eigen::VectorXd w = run.sys.masses().cwiseInverse();
    for (int p : run.sys.fixed()) w(p) = 0.0;
    std::vector<char> held(static_cast<std::size_t>(n));
    for (int p = 0; p < n; p += 2) held[static_cast<std::size_t>(p)] = 1;
    const auto same = [](const std::vector<ObstacleContact>& a, const std::vector<ObstacleContact>& b) {
      if (a.size() != b.size()) return false;
      for (std::size_t k = 0; k < a.size(); ++k)
        if (a[k].particle != b[k].particle || a[k].distance != b[k].distance || a[k].normal != b[k].normal)
          return false;
      return true;
    };
    std::size_t most = 0;
    for (int step = 0; step < 100; ++step) {  // 1 s: the fall and the sheet draped on the head
      for (int sub = 0; sub < 2; ++sub) {  // two substeps' positions, the second 2 mm further down
        MatrixN3 p = run.engine.x();
        p.col(2).array() -= 0.002 * sub;
        const double t = run.engine.t() + 0.5 * (sub + 1) * run.scene.h;
        const ObstaclePose pose = run.sys.obstacles()[0].PoseAt(t);
        const std::vector<char>* h = sub % 2 ? &held : nullptr;
        const std::vector<ObstacleContact> a = culled.Find(0, pose, p, w, h);
        ASSERT_TRUE(same(a, exact.Find(0, pose, p, w, h))) << "step " << step << " substep " << sub << " " << Name(c);
        most = std::max(most, a.size());
      }
      // The guard's and the writer's penetration, culled, against every query.
      const ObstaclePose pose = run.sys.obstacles()[0].PoseAt(run.engine.t());
      const Penetration a = culled.PenetrationOf(0, pose, run.engine.x());
      const Penetration b = run.sys.obstacles()[0].PenetrationOf(pose, run.engine.x());
      ASSERT_TRUE(a.max_depth == b.max_depth && a.deepest == b.deepest && a.depth_sum == b.depth_sum &&
                  a.inside == b.inside && a.close == b.close)
          << "step " << step << " " << Name(c);
      ASSERT_EQ(run.engine.Step(run.scene.h).status, StepStatus::kOk);
    }
    // The sheet reaches the head: 31 of its 1296 particles at once within
    // δ on the static avatar, 23 on the moving one, 13 on the skeleton.
    EXPECT_GT(most, static_cast<std::size_t>(n / 100)) << Name(c) << ": the sheet must reach the body";
    EXPECT_EQ(exact.culled(), 0);
    // Most particles are far from the body most of the time: the cull must
    // skip at least half the queries.
    EXPECT_LT(culled.queries(), exact.queries() / 2) << Name(c);
    std::printf("[ cull ] positions, %s: %ld exact queries of %ld, up to %zu entries\n", Name(c), culled.queries(),
                exact.queries(), most);
  }
}

// A retried or shortened step sets its contacts up again from the state
// of the last accepted step (ContactResponse::SetUp): the tablecloth lies
// inside the collision area of a plane, sliding at 0.1 m/s, with the
// holding impulses of its weight read after a step of h = 0.01 s. The
// friction is the last step's normal force times μ: the same force for a
// retry at h/2 (μ J h/h₋₁ over h; the relative 1e-12 is the round-off of
// that product), and bit for bit the same contacts and forces when h comes
// back. Before, a retry found every impulse zeroed by the failed attempt
// (no friction, no release), and a step of another size applied μ J over it.
TEST(ObstacleContacts, RetriedStepStartsFromTheLastAcceptedContacts) {
  const Scene s = testing::TableclothOnPlane(0.1);
  const ParticleSystem sys(s);
  const int n = sys.num_particles();
  ContactResponse contacts(sys);
  VelocityFilter filter;
  filter.Reserve(n);
  const MatrixN3 x = sys.rest_positions();
  MatrixN3 v = MatrixN3::Zero(n, 3);
  v.col(0).setConstant(0.1);
  const double h = 0.01;
  ASSERT_GT(contacts.SetUp(0.0, h, x, v, nullptr, &filter), n / 2);
  const auto residual = [&](int p) { return Vector3(0.0, 0.0, 9.81 * h * sys.masses()(p)); };
  contacts.ReadImpulses(residual, v, v, v, 0.0);
  const int count = contacts.SetUp(h, h, x, v, &x, &filter);
  const MatrixN3 first = contacts.friction();
  ASSERT_GT(first.norm(), 0.0);
  EXPECT_EQ(contacts.SetUp(h, 0.5 * h, x, v, &x, &filter), count);
  EXPECT_LT((contacts.friction() - first).norm(), 1e-12 * first.norm());
  EXPECT_EQ(contacts.SetUp(h, h, x, v, &x, &filter), count);
  EXPECT_TRUE(contacts.friction() == first);
}

}  // namespace
}  // namespace clothbench
