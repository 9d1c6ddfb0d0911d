// Deforming obstacles given as a mesh sequence (collision/shapes/mesh_sequence.cc):
// 1. A sequence's state interpolates its frames' vertices linearly in time,
//    with the interpolation's velocity at the surface, and is held outside
//    the frames' times.
// 2. A sphere moved by a known rigid motion (a rise and a turn about a
//    horizontal axis, the turn felt only through friction) and given as a
//    mesh sequence drapes round_table's cloth as the same motion given as
//    rigid keyframes does, within the sequence's interpolation error, for
//    SBDF(2) and CVODE; the motion itself moves the cloth far more.
// 3. A bad sequence is refused naming the file and the rule.
// 4. A run's file stores the moving surface at its frame times.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "model/obstacle.h"
#include "model/particle_system.h"
#include "model/scene.h"
#include "reference/cvode_reference.h"
#include "results/metrics.h"
#include "results/result_reader.h"
#include "solver/integrator.h"
#include "solver/run.h"
#include "temp_file.h"
#include "verify/cli_helpers.h"

namespace clothbench {
namespace {

// A sphere of radius 1 about the origin: an icosahedron subdivided twice
// (162 vertices, 320 triangles, outward).
void UnitSphere(std::vector<Vector3>* x, std::vector<std::array<int, 3>>* t) {
  const double g = (1.0 + std::sqrt(5.0)) / 2.0;
  *x = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0}, {0, -1, g}, {0, 1, g},
        {0, -1, -g}, {0, 1, -g}, {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
  *t = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
        {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
        {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
  for (int level = 0; level < 2; ++level) {
    std::map<std::pair<int, int>, int> middle;
    const auto mid = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      if (auto it = middle.find(key); it != middle.end()) return it->second;
      x->push_back(0.5 * ((*x)[a] + (*x)[b]));
      return middle[key] = static_cast<int>(x->size()) - 1;
    };
    std::vector<std::array<int, 3>> finer;
    for (const auto& [a, b, c] : *t) {
      const int ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
      finer.insert(finer.end(), {{a, ab, ca}, {b, bc, ab}, {c, ca, bc}, {ab, bc, ca}});
    }
    *t = finer;
  }
  for (Vector3& v : *x) v.normalize();
}

std::string Off(const std::vector<Vector3>& x, const std::vector<std::array<int, 3>>& t) {
  std::ostringstream off;
  off.precision(17);
  off << "OFF\n" << x.size() << " " << t.size() << " 0\n";
  for (const Vector3& v : x) off << v.x() << " " << v.y() << " " << v.z() << "\n";
  for (const auto& [a, b, c] : t) off << "3 " << a << " " << b << " " << c << "\n";
  return off.str();
}

// The sphere's rigid motion: its centre c0 + T(t), T piecewise linear
// through the keyframes' translations, and a turn about x through the
// centre by (t/T) `turn` degrees (as the keyframes' slerp gives it).
constexpr double kRadius = 0.3, kT = 0.5;
const Vector3 kCentre(0.0, 0.0, 0.46), kLift(0.0, 0.0, 0.1);

struct Motion {
  std::vector<ObstacleKeyframe> keys;  // translations and the turn, for a mesh anchored at the centre
  double turn = 0.0;                   // [degrees] at kT
  Vector3 Translation(double t) const {
    if (t <= keys.front().t) return keys.front().translate;
    for (std::size_t k = 0; k + 1 < keys.size(); ++k)
      if (t <= keys[k + 1].t) {
        const double s = (t - keys[k].t) / (keys[k + 1].t - keys[k].t);
        return (1.0 - s) * keys[k].translate + s * keys[k + 1].translate;
      }
    return keys.back().translate;
  }
};

// A rise and a 60° turn (the turn felt through friction: a sphere turning
// about its centre keeps its place).
Motion RiseAndTurn() { return {{{0.0, Vector3::Zero(), Vector3::Zero()}, {kT, kLift, Vector3(60.0, 0.0, 0.0)}}, 60.0}; }
// A rise, then a move sideways: piecewise linear, no turn.
Motion RiseThenSideways() {
  return {{{0.0, Vector3::Zero(), Vector3::Zero()}, {0.25, kLift, Vector3::Zero()}, {kT, kLift + Vector3(0.1, 0.0, 0.0), Vector3::Zero()}},
          0.0};
}

Vector3 Moved(const Vector3& unit_vertex, double t, const Motion& m = RiseAndTurn()) {
  const double s = std::min(t / kT, 1.0);
  return kCentre + m.Translation(t) + RotationFromDegrees(Vector3(s * m.turn, 0.0, 0.0)) * (kRadius * unit_vertex);
}

// Frames of `m` every `dt` from 0 to kT, as OFF files removed after the test.
struct SphereFrames {
  std::vector<std::unique_ptr<testing::TempFile>> files;
  std::vector<TimedPath> frames;
};

SphereFrames WriteFrames(double dt, const Motion& m = RiseAndTurn()) {
  std::vector<Vector3> unit;
  std::vector<std::array<int, 3>> tri;
  UnitSphere(&unit, &tri);
  SphereFrames s;
  const int n = static_cast<int>(std::lround(kT / dt));
  for (int k = 0; k <= n; ++k) {
    std::vector<Vector3> x;
    for (const Vector3& u : unit) x.push_back(Moved(u, k * dt, m));
    s.files.push_back(std::make_unique<testing::TempFile>(fmt::format("sphere_{}_{}_{}.off", m.turn, dt, k), Off(x, tri)));
    s.frames.push_back({k * dt, s.files.back()->path()});
  }
  return s;
}

TEST(MeshSequence, InterpolatesItsFramesAndTheirVelocity) {
  const SphereFrames s = WriteFrames(0.1);
  ObstacleSpec spec;
  spec.shape = ShapeFromValues("mesh_sequence", {{"frames", s.frames}});
  const Obstacle o(spec);
  ASSERT_TRUE(o.moving());
  // Halfway between frames 1 and 2 a vertex is the mean of its places
  // (to the files' 17 digits), moving at their difference over 0.1 s: a
  // point 5 cm out from it along its direction is 5 cm from the surface
  // (the vertex is the closest point of the convex mesh) and takes its velocity.
  const Vector3 u = Vector3(0.0, 1.0, (1.0 + std::sqrt(5.0)) / 2.0).normalized();  // a vertex of UnitSphere
  const Vector3 v1 = Moved(u, 0.1), v2 = Moved(u, 0.2), mid = 0.5 * (v1 + v2);
  const Vector3 centre = kCentre + 0.3 * kLift;
  const ObstaclePose pose = o.PoseAt(0.15);
  const Vector3 probe = mid + 0.05 * (mid - centre).normalized();
  Vector3 dir;
  EXPECT_NEAR(o.SignedDistance(pose, probe, &dir), 0.05, 1e-9);
  EXPECT_NEAR((pose.Velocity(probe) - (v2 - v1) / 0.1).norm(), 0.0, 1e-9);
  // Held (and still) before the first and after the last frame.
  const Vector3 out0 = Moved(u, 0.0) + 0.01 * (Moved(u, 0.0) - kCentre).normalized();
  const Vector3 out1 = Moved(u, kT) + 0.01 * (Moved(u, kT) - kCentre - kLift).normalized();
  EXPECT_NEAR(o.SignedDistance(o.PoseAt(-1.0), out0, &dir), 0.01, 1e-9);
  EXPECT_NEAR(o.SignedDistance(o.PoseAt(9.0), out1, &dir), 0.01, 1e-9);
  EXPECT_EQ(o.PoseAt(9.0).Velocity(out1), Vector3::Zero());
  // The motion bound is the largest vertex displacement; the guard's speed
  // the largest vertex speed over a frame interval.
  std::vector<Vector3> unit;
  std::vector<std::array<int, 3>> tri;
  UnitSphere(&unit, &tri);
  double largest = 0.0, fastest = 0.0;
  std::array<double, 5> per_interval{};  // [0, 0.1], …, [0.4, 0.5]
  for (const Vector3& w : unit) {
    largest = std::max(largest, (Moved(w, 0.1) - Moved(w, 0.0)).norm());
    for (int k = 0; k < 5; ++k) {
      const double speed = (Moved(w, 0.1 * (k + 1)) - Moved(w, 0.1 * k)).norm() / 0.1;
      per_interval[static_cast<std::size_t>(k)] = std::max(per_interval[static_cast<std::size_t>(k)], speed);
      fastest = std::max(fastest, speed);
    }
  }
  EXPECT_NEAR(o.MotionBound(o.PoseAt(0.0), o.PoseAt(0.1)), largest, 1e-12);
  EXPECT_NEAR(o.MaxVertexSpeed(), fastest, 1e-9);
  // Within a time span, the speed over the frame intervals that meet it
  // (the files' 17 digits, to 1e-9 m/s): 0 where the mesh is held.
  EXPECT_NEAR(o.MaxVertexSpeedBetween(0.12, 0.18), per_interval[1], 1e-9);
  EXPECT_NEAR(o.MaxVertexSpeedBetween(0.15, 0.35), std::max({per_interval[1], per_interval[2], per_interval[3]}), 1e-9);
  EXPECT_NEAR(o.MaxVertexSpeedBetween(0.1, 0.1), std::max(per_interval[0], per_interval[1]), 1e-9);
  EXPECT_NEAR(o.MaxVertexSpeedBetween(-1.0, kT), fastest, 1e-9);
  EXPECT_EQ(o.MaxVertexSpeedBetween(-1.0, -0.5), 0.0);
  EXPECT_EQ(o.MaxVertexSpeedBetween(kT + 0.1, 9.0), 0.0);
  EXPECT_LT(per_interval[0], per_interval[4]);  // the spans differ: the checks above could fail
}

// round_table's cloth over the sphere, which rises by 0.1 m and turns by
// 60° about x over 0.5 s (friction 0.3 drags the cloth with the turn):
// given as `obstacle`, a sequence or rigid keyframes.
Scene Drape(const ObstacleSpec& obstacle) {
  Scene s = BuiltinScene("round_table");
  s.t_end = kT;
  s.obstacles = {obstacle};
  return s;
}

ObstacleSpec Contact(std::shared_ptr<const ObstacleShape> shape) {
  ObstacleSpec o;
  o.shape = std::move(shape);
  o.collision_distance = 0.01;
  o.friction = 0.3;
  return o;
}

MatrixN3 EndOf(const Scene& s, bool cvode) {
  const ParticleSystem sys(s);
  RunSummary r;
  if (cvode) {
    r = RunCvodeReduced(sys, ReferenceOptions{1e-4, -1.0, 5, s.t_end, s.frame_dt}, s.solver);
  } else {
    StepEngine engine(sys, Method::kSbdf2, s.solver);
    r = RunStepper(sys, engine, {s.h, s.t_end, s.frame_dt});
  }
  EXPECT_TRUE(r.ok()) << r.status << ": " << r.message;
  return r.trajectory.positions.back();
}

// The end of the drape under `m` given as a sequence (frames every `dt`),
// as rigid keyframes, as the keyframes moved by 1e-12 of themselves (the
// run's own amplification of round-off) and held still, for sbdf2 and cvode.
struct Ends {
  double difference, round_off, motion;  // e_rms [m]: sequence − keyframes, keyframes − moved by 1e-12, keyframes − still
};

std::array<Ends, 2> Compare(const Motion& m, double dt) {
  const SphereFrames frames = WriteFrames(dt, m);
  std::vector<Vector3> unit;
  std::vector<std::array<int, 3>> tri;
  UnitSphere(&unit, &tri);
  std::vector<Vector3> x0;  // the sphere about the origin, placed at its centre
  for (const Vector3& u : unit) x0.push_back(kRadius * u);
  const testing::TempFile rest(fmt::format("sphere_rest_{}.off", m.turn), Off(x0, tri));
  // The keyframes turn about the mesh's anchor, its translate: the centre.
  ObstacleSpec rigid = Contact(ShapeFromValues("mesh", {{"path", rest.path()}, {"translate", kCentre}}));
  rigid.keyframes = m.keys;
  ObstacleSpec perturbed = rigid;
  for (ObstacleKeyframe& k : perturbed.keyframes) k.translate *= 1.0 + 1e-12;
  const ObstacleSpec sequence = Contact(ShapeFromValues("mesh_sequence", {{"frames", frames.frames}}));
  const ObstacleSpec still = Contact(ShapeFromValues("mesh", {{"path", rest.path()}, {"translate", kCentre}}));
  std::array<Ends, 2> out{};
  for (const bool cvode : {false, true}) {
    const MatrixN3 b = EndOf(Drape(rigid), cvode);
    out[cvode] = {ErrorRms(EndOf(Drape(sequence), cvode), b), ErrorRms(EndOf(Drape(perturbed), cvode), b),
                  ErrorRms(EndOf(Drape(still), cvode), b)};
    std::printf("%s, turn %g degrees: sequence vs keyframes e_rms %.3g m, keyframes vs keyframes (1 + 1e-12) %.3g m, "
                "keyframes vs still %.3g m\n",
                cvode ? "cvode" : "sbdf2", m.turn, out[cvode].difference, out[cvode].round_off, out[cvode].motion);
  }
  return out;
}

TEST(MeshSequence, MatchesTheSameRigidMotionAsKeyframes) {
  // A piecewise-linear translation whose keyframe times are frame times is
  // the sequence's own interpolation: the same motion to round-off, which
  // each run amplifies as it does a change of its keyframes by 1e-12 of
  // themselves (sbdf2: measured 1.7e-10 m against 7e-11 m; cvode's event
  // location at rtol 1e-4: 1.5e-4 m against 1.0e-4 m). Ten times that,
  // and 1e-6 m of round-off.
  for (const Ends& e : Compare(RiseThenSideways(), 0.05)) {
    EXPECT_LT(e.difference, 1e-6 + 10.0 * e.round_off);
    EXPECT_GT(e.motion, 0.05);  // the motion moves the cloth by centimetres
  }
  // A turn: frames every 0.01 s put a vertex at r = 0.3 m at most
  // r (1 − cos(ωΔt/2)) = 1.6e-5 m inside its arc, and give it the chord's
  // velocity, the rigid one Δt/2 later (its direction 0.01 rad off, 1 % of
  // the surface's 0.63 m/s). On the faceted sphere the normal velocity
  // under the cloth changes at the facets' rate, and friction (0.3) turns
  // the cloth with the surface, so the difference is first order in Δt and
  // amplified by stick and slip: measured 1.3e-3 m (sbdf2) and 1.2e-3 m
  // (cvode, which stops at each frame time and puts the sliding particles
  // back on the δ-surface: HybridContact's "Breaks") at the end. 5e-3 m
  // holds them, 20 times below the motion's effect (0.12 m and 0.27 m).
  for (const Ends& e : Compare(RiseAndTurn(), 0.01)) {
    EXPECT_LT(e.difference, 5e-3);
    EXPECT_GT(e.motion, 20 * 5e-3);
  }
}

// A box [lo, hi] as an OFF mesh (8 vertices, 12 outward triangles).
std::string BoxOff(const Vector3& lo, const Vector3& hi) {
  std::vector<Vector3> x;
  for (int k = 0; k < 8; ++k) x.emplace_back(k & 1 ? hi.x() : lo.x(), k & 2 ? hi.y() : lo.y(), k & 4 ? hi.z() : lo.z());
  const std::vector<std::array<int, 3>> t = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                                             {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  return Off(x, t);
}

// A thin plate (1 cm thick) given as a two-frame sequence sweeps at 5 m/s
// through a hanging sheet with h = 0.01 s: 5 cm per step, five times its
// thickness.
// - Implicit Euler (x₁ = x₀ + h v₁, so the contact's target velocity puts
//   the particle on the moving border) and CVODE (events on the moving
//   surface): no particle is inside the plate at any stored frame, and none
//   crosses it (a particle over the plate's extent that changes sides of
//   its mid-plane between two frames).
// - SBDF(2): its position formula x₁ = x̂ + (2/3) h v₁ lags a particle that
//   the plate starts at 5 m/s by a third of a step's travel (1.5 cm, more
//   than the plate's thickness), so the plate passes it; the blow-up
//   guard, which follows each path relative to the moving plate, ends the
//   run `tunnelled` instead of calling it ok.
TEST(MeshSequence, AFastThinPlateSweepsTheSheetWithoutPassingThrough) {
  const Vector3 lo(-0.5, -0.205, 0.4), hi(1.3, -0.195, 0.8);  // the plate at t = 0, 1 cm thick in y
  const Vector3 travel(0.0, 0.5, 0.0);                          // 5 m/s over 0.1 s
  const testing::TempFile a("plate_a.off", BoxOff(lo, hi)), b("plate_b.off", BoxOff(lo + travel, hi + travel));
  const Scene s = ParseScene(
      "t_end = 0.1\nframe_dt = 0.01\nh = 0.01\n[grid]\nnu = 20\nnv = 20\nsize = [0.76, 0.76]\n"
      "origin = [0.0, 0.0, 0.24]\nu_axis = [1.0, 0.0, 0.0]\nv_axis = [0.0, 0.0, 1.0]\n[material]\ndensity = 1.0\n"
      "tension = [8000.0, 8000.0]\ntension_damping = 0.5\nshear = 10.0\nbend = [1.0e-5, 1.0e-5]\n[forces]\n"
      "gravity = [0.0, 0.0, -9.81]\n[constraints]\nfixed = [\"edge:v1\"]\n[[obstacle]]\ntype = \"mesh_sequence\"\n"
      "frames = [{ t = 0.0, path = \"" + a.path() + "\" }, { t = 0.1, path = \"" + b.path() + "\" }]\n"
      "collision_distance = 0.005\n",
      "plate.toml");
  const ParticleSystem sys(s);
  const Obstacle& plate = sys.obstacles()[0];
  const auto run = [&](int which) {
    if (which == 2) return RunCvodeReduced(sys, ReferenceOptions{1e-4, -1.0, 5, s.t_end, s.frame_dt}, s.solver);
    StepEngine engine(sys, which == 0 ? Method::kImplicitEuler : Method::kSbdf2, s.solver);
    return RunStepper(sys, engine, {s.h, s.t_end, s.frame_dt});
  };
  for (const int which : {0, 2}) {
    const RunSummary r = run(which);
    const char* name = which == 0 ? "implicit_euler" : "cvode";
    ASSERT_TRUE(r.ok()) << name << ": " << r.status << ": " << r.message;
    int crossed = 0;
    const auto& xs = r.trajectory.positions;
    for (std::size_t f = 0; f < xs.size(); ++f) {
      const double t = r.trajectory.times[f];
      EXPECT_EQ(plate.PenetrationOf(plate.PoseAt(t), xs[f]).inside, 0) << name << " at t = " << t;
      if (f == 0) continue;
      const double mid0 = 0.5 * (lo.y() + hi.y()) + 5.0 * r.trajectory.times[f - 1], mid1 = mid0 + 5.0 * (t - r.trajectory.times[f - 1]);
      for (int p = 0; p < xs[f].rows(); ++p) {
        const auto over = [&](const MatrixN3& x) {
          return x(p, 0) > lo.x() && x(p, 0) < hi.x() && x(p, 2) > lo.z() && x(p, 2) < hi.z();
        };
        if (over(xs[f - 1]) && over(xs[f]) && xs[f - 1](p, 1) > mid0 && xs[f](p, 1) < mid1) ++crossed;
      }
    }
    EXPECT_EQ(crossed, 0) << name;
    // The plate met the sheet: its lower part moved with the plate.
    EXPECT_GT(xs.back().col(1).maxCoeff(), 0.25) << name;
  }
  const RunSummary sbdf2 = run(1);
  EXPECT_EQ(sbdf2.status, RunStatus::kTunnelled) << sbdf2.message;
}

// scenes/mesh_sequence_drape.toml: round_table's cloth on a sphere that
// swells, shrinks and rises (eleven frames). SBDF(2) and CVODE end `ok`,
// within 5e-3 m of each other (measured 4.7e-4 m: SBDF(2)'s error at
// h = 0.01 s against CVODE's at rtol 1e-3), and on the sphere: its top is
// at 0.8 m at t = 1 s, and no particle is more than 2δ above it (CVODE
// held particles on a surface whose velocity jumps at each frame until
// they had risen 0.25 m above it, before contacts that drift past δ were
// released and before the rows stopped at the frame times).
TEST(MeshSequence, TheDrapeSceneEndsOnTheSphereForSbdf2AndCvode) {
  const Scene s = LoadScene(std::string(CLOTHBENCH_SCENES_DIR) + "/mesh_sequence_drape.toml");
  const MatrixN3 a = EndOf(s, false), b = EndOf(s, true);
  std::printf("mesh_sequence_drape at t = 1 s: sbdf2 (h = 0.01 s) vs cvode (rtol 1e-3) e_rms %.3g m\n", ErrorRms(a, b));
  EXPECT_LT(ErrorRms(a, b), 5e-3);
  for (const MatrixN3* x : {&a, &b}) EXPECT_LT(x->col(2).maxCoeff(), 0.8 + 2 * 0.01);
}

// The file of a run on a deforming obstacle holds its surface at every
// frame time (the report page and ParaView draw the body where it was):
// /scene/obstacles/0/positions[j] is the sequence's surface at times[j],
// the file passes the reader's validation, and the XDMF file has a grid of
// the obstacle at each of those times.
TEST(MeshSequence, TheResultFileStoresTheMovingSurfaceAtItsFrameTimes) {
  const std::filesystem::path dir = testing::TempDir("clothbench_mesh_sequence_");
  const std::string scene = std::string(CLOTHBENCH_SCENES_DIR) + "/mesh_sequence_drape.toml";
  const std::string out = (dir / "drape.h5").string();
  const testing::Outcome run = testing::RunCommand(
      CLOTHBENCH_BENCH_BINARY,
      "--scene " + scene + " --integrators sbdf2 --t-end 0.05 --reference none --repeat 1 --quiet --out " + out, dir);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const ResultReader f(out);
  EXPECT_NO_THROW(ValidateResultFile(f));
  const std::vector<double> times = f.Doubles("/scene/obstacles/0/times");
  ASSERT_EQ(times.size(), 6u);  // 0, 0.01, …, 0.05: every frame_dt to t_end
  const Obstacle body(LoadScene(scene).obstacles[0]);
  std::vector<Vector3> surface;
  std::vector<std::array<int, 3>> triangles;
  for (std::size_t j = 0; j < times.size(); ++j) {
    EXPECT_NEAR(times[j], 0.01 * static_cast<double>(j), 1e-15);
    body.PoseAt(times[j]).deformed->Surface(&surface, &triangles);
    const MatrixN3 stored = f.Frame("/scene/obstacles/0/positions", j);
    ASSERT_EQ(stored.rows(), static_cast<Eigen::Index>(surface.size()));
    double worst = 0.0;
    for (std::size_t i = 0; i < surface.size(); ++i)
      worst = std::max(worst, (stored.row(static_cast<Eigen::Index>(i)).transpose() - surface[i]).norm());
    EXPECT_EQ(worst, 0.0) << "frame " << j;  // the same doubles, written and read back
  }
  // Between its frames the sphere moves: the first and last stored surfaces differ.
  EXPECT_GT((f.Frame("/scene/obstacles/0/positions", 0) - f.Frame("/scene/obstacles/0/positions", 5)).norm(), 1e-3);
  std::ifstream xdmf(dir / "drape.xdmf");
  std::stringstream text;
  text << xdmf.rdbuf();
  for (std::size_t j = 0; j < times.size(); ++j)
    EXPECT_NE(text.str().find(fmt::format("obstacle_0_{}\"", j)), std::string::npos) << "grid " << j;
}

// A grid above a placeholder obstacle table `keys`; the scene's refusal.
std::string Refusal(const std::string& keys) {
  const std::string grid = "[grid]\nnu = 3\nnv = 3\nsize = [0.1, 0.1]\norigin = [0.0, 0.0, 1.0]\n";
  try {
    const Scene s = ParseScene(grid + "[[obstacle]]\ntype = \"mesh_sequence\"\n" + keys, "seq.toml");
    const ParticleSystem sys(s);  // the files' topology is read with the model
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

TEST(MeshSequence, RefusesABadSequenceNamingTheFileAndTheRule) {
  std::vector<Vector3> unit;
  std::vector<std::array<int, 3>> tri;
  UnitSphere(&unit, &tri);
  const testing::TempFile a("seq_a.off", Off(unit, tri));
  std::vector<std::array<int, 3>> other = tri;
  std::swap(other[0], other[1]);  // the same triangles in another order: another topology
  const testing::TempFile b("seq_b.off", Off(unit, other));
  const auto frame = [](double t, const std::string& path) { return fmt::format("{{ t = {}, path = \"{}\" }}", t, path); };
  EXPECT_EQ(Refusal("frames = [" + frame(0.0, a.path()) + ", " + frame(0.1, "/nonexistent/b.off") + "]\n"),
            "seq.toml: obstacle[0].frames: frame 1: mesh file \"/nonexistent/b.off\" not found");
  EXPECT_EQ(Refusal("frames = [" + frame(0.2, a.path()) + ", " + frame(0.1, a.path()) + "]\n"),
            fmt::format("seq.toml: obstacle[0].frames: frame 1 (\"{}\"): t = 0.1 s must be greater than frame 0's t = "
                        "0.2 s", a.path()));
  const std::string topology = Refusal("frames = [" + frame(0.0, a.path()) + ", " + frame(0.1, b.path()) + "]\n");
  EXPECT_NE(topology.find("seq.toml: obstacle[0].frames: frame 1 (\"" + b.path() + "\""), std::string::npos) << topology;
  EXPECT_NE(topology.find("does not have the topology of frame 0"), std::string::npos) << topology;
  EXPECT_EQ(Refusal("frames = []\n"),
            "seq.toml: obstacle[0].frames: must be a non-empty array of tables { t = s, path = \"file\" }");
  EXPECT_EQ(Refusal("frames = [" + frame(0.0, a.path()) + "]\nkeyframes = [{ t = 0.0 }]\n"),
            "seq.toml: obstacle[0].keyframes: must be absent for a mesh_sequence (it moves by its own frames)");
}

}  // namespace
}  // namespace clothbench
