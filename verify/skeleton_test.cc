// A body driven by motion capture (collision/shapes/skeleton.cc) on the CMU
// clip 01_01.bvh that scripts/setup installs (assimp-testmodels):
// 1. Its bones stay rigid: every bone's length is the same at every frame
//    (forward kinematics composes rotations and the joints' offsets).
// 2. Its root follows the file's root channel, placed by scale, rotate and
//    translate, at the clip time start + time_scale · t.
// 3. A surface point moves with its bone's ends, the chord velocity
//    between frames; the distance is a union of capsules.
// 4. A skeleton file without frames, or a missing one, is refused naming
//    the file and the rule.
// 5. HeldAt(spec, t), the body that the sewing pre-phase dresses, is the
//    pose at t held still: of the skeleton and of a keyframed rigid turn.
// 6. scenes/mocap_dress.toml: the dress is sewn outside the body in its
//    first pose, and worn while the body moves without a crossing pair or
//    a particle deeper than the collision distance inside it.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "model/obstacle.h"
#include "model/particle_system.h"
#include "model/scene.h"
#include "solver/integrator.h"
#include "solver/run.h"
#include "solver/sewing.h"
#include "temp_file.h"

namespace clothbench {
namespace {

const std::string kClip = "/usr/share/assimp/models/BVH/01_01.bvh";

// The file's root position (its first three channels) at frame k, and its frame time [s].
Vector3 RootInFile(int k, double* frame_time = nullptr) {
  std::ifstream in(kClip);
  std::string line;
  while (std::getline(in, line) && line.rfind("Frame Time:", 0) != 0) {
  }
  if (frame_time) *frame_time = std::stod(line.substr(11));
  for (int i = 0; i <= k; ++i) std::getline(in, line);
  std::istringstream values(line);
  Vector3 x;
  values >> x.x() >> x.y() >> x.z();
  return x;
}

// The root at clip time τ [s]: linear between the file's frames.
Vector3 RootAt(double tau) {
  double dt = 0.0;
  RootInFile(0, &dt);
  const int k = static_cast<int>(std::floor(tau / dt));
  const double lambda = tau / dt - k;
  return (1.0 - lambda) * RootInFile(k) + lambda * RootInFile(k + 1);
}

ObstacleSpec Body(double scale, double time_scale, double start, const Vector3& rotate, const Vector3& translate) {
  ObstacleSpec o;
  o.shape = ShapeFromValues("skeleton", {{"path", kClip},
                                         {"scale", scale},
                                         {"time_scale", time_scale},
                                         {"start", start},
                                         {"radius", 0.06},
                                         {"radii", std::vector<std::pair<std::string, double>>{{"Head", 0.1}}},
                                         {"rotate", rotate},
                                         {"translate", translate}});
  return o;
}

TEST(Skeleton, BonesStayRigidAndTheRootFollowsTheFile) {
  ASSERT_TRUE(std::ifstream(kClip).good()) << kClip << " missing: run scripts/setup (assimp-testmodels)";
  // CMU units to m (0.056: a thigh of 7.1 units is 0.4 m), y up turned to z up.
  const double scale = 0.056;
  const Vector3 rotate(90.0, 0.0, 0.0), translate(0.1, 0.2, 0.0);
  const Obstacle body(Body(scale, 2.0, 1.0, rotate, translate));  // clip time 1 + 2t
  ASSERT_TRUE(body.moving());
  std::vector<Vector3> v0, v1;
  std::vector<std::array<int, 3>> t;
  // Clip time 1 + 2t: t = 0 is 1 s into the clip, t = 0.5 s is 2 s; before
  // the clip's start (t < -0.5 s) its first frame holds.
  for (const auto& [time, tau] : {std::pair{0.0, 1.0}, std::pair{0.5, 2.0}, std::pair{-3.0, 0.0}}) {
    const ObstaclePose pose = body.PoseAt(time);
    ASSERT_TRUE(pose.deformed);
    // The root (Hips) is an end of the capsules of the bones that leave it:
    // 0.06 m deep, to Assimp's single precision (6e-8 of 20 units · 0.056 m).
    const Vector3 root = RotationFromDegrees(rotate) * (scale * RootAt(tau)) + translate;
    Vector3 dir;
    EXPECT_NEAR(pose.deformed->SignedDistance(root, &dir), -0.06, 1e-6) << "t = " << time;
  }
  // Rigid bones: the surface is the capsules' surfaces one after another,
  // each with a capsule's vertex count and its two poles last (capsule.cc),
  // |pole_a − pole_b| = the bone's length + 2 radii, the same at every frame.
  std::vector<Vector3> one;
  ShapeFromValues("capsule", {{"a", Vector3::Zero()}, {"b", Vector3::UnitX()}, {"radius", 0.1}})->Surface(&one, &t);
  const std::size_t per = one.size();
  body.PoseAt(0.0).deformed->Surface(&v0, &t);
  body.PoseAt(0.5).deformed->Surface(&v1, &t);
  ASSERT_EQ(v0.size(), v1.size());
  ASSERT_EQ(v0.size() % per, 0u);
  const std::size_t bones = v0.size() / per;
  EXPECT_GT(bones, 20u);  // CMU's 31 joints and end sites, less the zero offsets
  double worst = 0.0, moved = 0.0;
  for (std::size_t b = 0; b < bones; ++b) {
    const std::size_t pa = b * per + per - 2, pb = pa + 1;
    worst = std::max(worst, std::abs((v0[pa] - v0[pb]).norm() - (v1[pa] - v1[pb]).norm()));
    moved = std::max(moved, (v0[pa] - v1[pa]).norm());
  }
  // The same bone lengths to Assimp's single precision (6e-8 of a bone's
  // length in file units, 1e-7 m here) [m].
  EXPECT_LT(worst, 1e-6);
  EXPECT_GT(moved, 0.05);  // while the body moved
  // The clip's speed bound: the fastest joint, in scene time (time_scale 2).
  EXPECT_GT(body.MaxVertexSpeed(), 0.0);
  // Between frames a surface point moves with its bone's ends; over one
  // frame (1/240 s of scene time) the distance of a fixed point changes by
  // at most the joints' largest displacement.
  const double dt = 1.0 / 240.0;
  const ObstaclePose a = body.PoseAt(0.25), b = body.PoseAt(0.25 + dt);
  const Vector3 p = RotationFromDegrees(rotate) * (scale * RootAt(1.5)) + translate + Vector3(0.0, 0.3, 0.0);
  Vector3 da, db;
  const double sa = body.SignedDistance(a, p, &da), sb = body.SignedDistance(b, p, &db);
  EXPECT_LE(std::abs(sa - sb), body.MotionBound(a, b) + 1e-12);
  EXPECT_LE(a.Velocity(p).norm(), body.MaxVertexSpeed() + 1e-9);
  EXPECT_LE(a.Velocity(p).norm(), body.MaxVertexSpeedBetween(0.25, 0.25 + dt) + 1e-9);
  // The clip's first frame is a T-pose (CMU's, before the motion): its
  // jump to the second frame is the clip's fastest, at clip time 0, which
  // the scene passed at t = -0.5 s; from t = 0 on the body is slower.
  EXPECT_LT(body.MaxVertexSpeedBetween(0.0, 1.0), 0.5 * body.MaxVertexSpeed());
}

std::string Refusal(const std::string& path) {
  const std::string grid = "[grid]\nnu = 3\nnv = 3\nsize = [0.1, 0.1]\norigin = [0.0, 0.0, 5.0]\n";
  try {
    const Scene s = ParseScene(grid + "[[obstacle]]\ntype = \"skeleton\"\npath = \"" + path + "\"\nscale = 0.056\n", "body.toml");
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

TEST(Skeleton, RefusesAFileWithoutFramesOrMissing) {
  std::ifstream in(kClip);
  std::stringstream text;
  text << in.rdbuf();
  const std::string head = text.str().substr(0, text.str().find("MOTION"));
  const testing::TempFile none("no_frames.bvh", head + "MOTION\nFrames: 0\nFrame Time: .0083333\n");
  EXPECT_EQ(Refusal(none.path()),
            "body.toml: obstacle[0].path: BVH file \"" + none.path() + "\" has no motion frames (Frames: 0)");
  const testing::TempFile cut("no_motion.bvh", head);
  EXPECT_EQ(Refusal(cut.path()), "body.toml: obstacle[0].path: BVH file \"" + cut.path() +
                                     "\" has no motion frames (no MOTION section with a Frames: line)");
  EXPECT_EQ(Refusal("/nonexistent/walk.bvh"),
            "body.toml: obstacle[0].path: BVH file \"/nonexistent/walk.bvh\" not found or not a regular file");
}


// The obstacle held in its pose at t: the same signed distances as the moving
// obstacle at t, at every later time, for the skeleton (its state at t) and
// for a box on keyframes turning about two axes (one keyframe whose Euler
// angles give the interpolated rotation).
TEST(Skeleton, HeldAtIsThePoseAtThatTimeHeldStill) {
  ObstacleSpec box;
  box.shape = ShapeFromValues("box", {{"center", Vector3(0.1, 0.0, 0.5)}, {"size", Vector3(0.4, 0.2, 0.1)}});
  box.keyframes = {ObstacleKeyframe{0.0, Vector3::Zero(), Vector3::Zero()},
                   ObstacleKeyframe{1.0, Vector3(0.2, -0.1, 0.3), Vector3(30.0, -50.0, 120.0)}};
  const std::vector<std::pair<ObstacleSpec, double>> cases = {
      {Body(0.056, 1.0, 0.5, Vector3(90.0, 0.0, 180.0), Vector3(0.53, 1.03, 0.0)), 0.0}, {box, 0.37}};
  for (const auto& [spec, t] : cases) {
    const Obstacle moving(spec), held(HeldAt(spec, t));
    const ObstaclePose at = moving.PoseAt(t);
    ObstacleSpec still = spec;  // the scene key `held`: in its pose at t = 0
    still.held = true;
    const Obstacle at_rest(still);
    Vector3 e0, e1;
    const Vector3 probe(0.3, -0.2, 1.3);
    if (spec.shape->deforms()) EXPECT_FALSE(at_rest.moving());  // its state at 0: a still shape
    EXPECT_NEAR(at_rest.SignedDistance(1.0, probe, &e1), moving.SignedDistance(0.0, probe, &e0), 1e-12) << spec.type();
    for (const double later : {0.0, t, 0.8, 5.0})
      for (const Vector3& p : {Vector3(0.0, 0.0, 1.0), Vector3(0.3, -0.2, 1.3), Vector3(-0.1, 0.4, 0.4)}) {
        Vector3 d0, d1;
        // The same query, up to the Euler angles' round trip (1e-15 rad
        // on distances of 1 m) [m].
        EXPECT_NEAR(held.SignedDistance(later, p, &d1), moving.SignedDistance(at, p, &d0), 1e-12)
            << spec.type() << " held at " << t << ", queried at " << later;
      }
    Vector3 d;
    const Vector3 q(0.3, -0.2, 1.3);
    EXPECT_GT(std::abs(moving.SignedDistance(0.8, q, &d) - moving.SignedDistance(at, q, &d)), 1e-3)
        << spec.type() << ": the moving obstacle moves after " << t;
  }
}

// The distance culls' speed bound (Obstacle::MaxVertexSpeedBetween) on
// scenes/mocap_dress.toml's body: the clip's fastest interval is its
// T-pose's jump to the motion, at clip time 0 (t = -0.5 s with start =
// 0.5), which the scene's run from t = 0 never reaches; over the run the
// joints move at a small part of that speed, and so does the blow-up
// guard's speed bound.
TEST(Skeleton, TheCullsSpeedBoundLeavesOutTheClipsTPose) {
  Scene s = LoadScene(std::string(CLOTHBENCH_SCENES_DIR) + "/mocap_dress.toml");
  const Obstacle body(s.obstacles.at(0));
  const double clip = body.MaxVertexSpeed(), run = body.MaxVertexSpeedBetween(0.0, s.t_end);
  const double first = body.MaxVertexSpeedBetween(-0.5, -0.5 + 1e-4);  // the first interval only
  std::printf("[ speed ] mocap_dress' joints: %.2f m/s over the clip, %.2f m/s from its first frame to its second, "
              "%.2f m/s over t = 0 to %g s\n", clip, first, run, s.t_end);
  EXPECT_EQ(first, clip);
  EXPECT_GT(run, 0.0);
  EXPECT_LT(run, 0.1 * clip);
  // The blow-up guard's speed bound takes the body's speed over the run:
  // v_bound = sqrt(2 g H) + 1 m/s + 3.9 m/s with H = the dress' 1 m height
  // + ½ g t_end² = 20.6 m, 25 m/s, so a particle at 60 m/s is past 2 v_bound
  // (with the T-pose's 84 m/s it would pass, under 2 · 105 m/s) and one at
  // 30 m/s is not.
  Sew(&s);
  const ParticleSystem sys(s);
  const int n = sys.num_particles();
  BlowUpGuard guard(sys, sys.rest_positions(), MatrixN3::Zero(n, 3), s.t_end);
  MatrixN3 v = MatrixN3::Zero(n, 3);
  RunStatus status = RunStatus::kOk;
  std::string message;
  v(n / 2, 0) = 30.0;
  EXPECT_TRUE(guard.CheckSpeed(0.5, v, &status, &message)) << message;
  v(n / 2, 0) = 60.0;
  EXPECT_FALSE(guard.CheckSpeed(0.5, v, &status, &message));
  EXPECT_EQ(status, RunStatus::kSpeed) << message;
}

// The sewn dress lies outside the body at t = 0 (every particle's signed
// distance positive: the sewing phase's contact keeps it out of the body
// held in that pose), and SBDF(2) at the scene's h wears it through the
// crouch (0.6 s) with 0 crossing pairs at every frame and no particle deeper
// than δ inside the body at any frame (the run guard's check: status ok).
TEST(Skeleton, TheMocapDressIsSewnOutsideTheBodyAndWornThroughItsMotion) {
  Scene s = LoadScene(std::string(CLOTHBENCH_SCENES_DIR) + "/mocap_dress.toml");
  Sew(&s);
  s.t_end = 0.6;
  const ParticleSystem sys(s);
  const Obstacle& body = sys.obstacles()[0];
  ASSERT_TRUE(body.moving());
  const ObstaclePose rest = body.PoseAt(0.0);
  double closest = 1e300;
  for (int p = 0; p < sys.num_particles(); ++p) {
    Vector3 d;
    closest = std::min(closest, body.SignedDistance(rest, sys.rest_positions().row(p).transpose(), &d));
  }
  EXPECT_GT(closest, 0.0);
  StepEngine engine(sys, Method::kSbdf2, s.solver);
  const RunSummary r = RunStepper(sys, engine, {s.h, s.t_end, s.frame_dt});
  EXPECT_TRUE(r.ok()) << r.status << ": " << r.message;
  EXPECT_LT(r.penetration_ratio, 1.0);
  ASSERT_EQ(r.trajectory.crossing_pairs.size(), r.trajectory.times.size());
  for (std::size_t k = 0; k < r.trajectory.crossing_pairs.size(); ++k)
    EXPECT_EQ(r.trajectory.crossing_pairs[k], 0) << "t = " << r.trajectory.times[k];
  // The body moved under the dress: its root dropped into the crouch.
  EXPECT_GT(body.MotionBound(rest, body.PoseAt(s.t_end)), 0.05);
}

}  // namespace
}  // namespace clothbench
