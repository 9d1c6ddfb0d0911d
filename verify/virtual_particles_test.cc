// The thesis' virtual particles (§5.2–5.4; collision/virtual_particles.h).
//
// 1. The rest lengths of a split spring sum to its rest length (§5.4), and
//    each virtual particle lies on the obstacle edge it came from and on
//    the cloth edge it was inserted into (its projection).
// 2. Fig. 5.5: the 2 × 2 cloth of scenes/virtual_box.toml falls past the
//    beam when the obstacle has no virtual particles (its particles miss
//    the beam: after 2 s all four are below the beam's bottom, z < −0.2 m),
//    and hangs over it with them, for every thesis integrator: every
//    particle stays above the bottom, and the cloth's edges, through their
//    virtual particles, do not enter the beam (depth ≤ 1e-9 m: the virtual
//    particles lie on the beam's edges, so the polyline touches the
//    surface; round-off of the edge's end points is 1e-16 m). The faces of
//    the refined mesh (constrained Delaunay, the projected beam edges as
//    constraints) do not enter it either (same bound).
// 4. The round table: the refined mesh stays outside; a keyframed beam
//    carries the cloth (below).
// 5. A second run on the same system repeats the first bit for bit.
// 6. The triangulation of a face keeps its constraints, covers the face
//    with counter-clockwise triangles and adds the crossing of two
//    constraints (exact here: 1e-15).
// 3. A scene whose obstacle asks for virtual particles but never meets the
//    cloth runs bit for bit as the same scene without them: the extra
//    term adds nothing, and the engine's products are unchanged.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "collision/face_triangulation.h"
#include "collision/virtual_particles.h"
#include "model/particle_system.h"
#include "solver/run.h"
#include "verify/test_scenes.h"

namespace clothbench {
namespace {

Scene BoxScene(bool virtual_particles) {
  Scene s = LoadScene(std::string(CLOTHBENCH_SCENES_DIR) + "/virtual_box.toml");
  s.obstacles.at(0).virtual_particles = virtual_particles;
  return s;
}

// The deepest point [m] inside `o` of the segment a → b (sampled at 1/64).
double DeepestPoint(const Obstacle& o, const Vector3& a, const Vector3& b) {
  double deepest = 0.0;
  Vector3 d;
  for (int k = 0; k <= 64; ++k) deepest = std::max(deepest, -o.SignedDistance(0.0, a + (b - a) * (k / 64.0), &d));
  return deepest;
}

TEST(VirtualParticles, RestLengthsSumToTheEdgesAndPointsLieOnBothEdges) {
  Scene s = BoxScene(true);
  const ParticleSystem sys(s);
  VirtualParticles* vp = VirtualParticles::Of(sys);
  ASSERT_NE(vp, nullptr);
  // The flat cloth 2 cm below the beam's top (z = 0.2 m): the beam's top
  // edges pass through both v-springs and the diagonal.
  MatrixN3 x = sys.rest_positions();
  x.col(2).setConstant(0.18);
  vp->Update(0.0, x);
  ASSERT_EQ(vp->removed_couplings().size(), 2u);  // the two v-springs
  ASSERT_EQ(vp->virtual_springs().size(), 4u);
  for (const RemovedCoupling& c : vp->removed_couplings()) {
    double sum = 0.0;
    for (const VirtualSpring& side : vp->virtual_springs())
      if (side.spring == c.spring) sum += side.rest;
    // Σ r_j over the two ends plus the middle segment's share (the part
    // between the beam's edges, which exerts no force) is the rest length.
    const auto on_edge = [&](const VirtualParticle& p) { return p.a == std::min(c.a, c.b) && p.b == std::max(c.a, c.b); };
    std::vector<Vector3> points;
    for (const VirtualParticle& p : vp->particles())
      if (on_edge(p)) points.push_back(p.x);
    ASSERT_EQ(points.size(), 2u);
    const Vector3 xa = x.row(c.a).transpose(), xb = x.row(c.b).transpose();
    const double total = (points[0] - xa).norm() + (points[1] - points[0]).norm() + (xb - points[1]).norm();
    const double middle = sys.springs()[static_cast<std::size_t>(c.spring)].rest_length * (points[1] - points[0]).norm() / total;
    EXPECT_NEAR(sum + middle, sys.springs()[static_cast<std::size_t>(c.spring)].rest_length, 1e-12);
  }
  Vector3 d;
  for (const VirtualParticle& p : vp->particles()) {
    // On the beam's surface (its top edges) and, in x and y, on the cloth
    // edge it was inserted into (the projection is vertical here).
    EXPECT_NEAR(sys.obstacles()[0].SignedDistance(0.0, p.x, &d), 0.0, 1e-12);
    EXPECT_NEAR(p.x.z(), 0.2, 1e-12);
    if (p.a < 0) continue;
    const Vector3 bar = (1.0 - p.s) * x.row(p.a).transpose() + p.s * x.row(p.b).transpose();
    EXPECT_NEAR((bar - p.x).head<2>().norm(), 0.0, 1e-12);
  }
}

class VirtualBox : public ::testing::TestWithParam<Method> {};

TEST_P(VirtualBox, FallsThroughWithoutAndHangsOverTheBeamWith) {
  for (const bool on : {false, true}) {
    const Scene s = BoxScene(on);
    const ParticleSystem sys(s);
    const RunSummary r = RunIntegrator(sys, GetParam(), {s.h, s.t_end, s.frame_dt});
    ASSERT_TRUE(r.ok()) << r.status << ": " << r.message;
    const MatrixN3& x = r.trajectory.positions.back();
    if (!on) {
      EXPECT_LT(x.col(2).maxCoeff(), -0.2) << "without virtual particles the cloth falls past the beam";
      continue;
    }
    EXPECT_GT(x.col(2).minCoeff(), -0.2) << "held by the virtual particles";
    VirtualParticles* vp = VirtualParticles::Of(sys);
    vp->Update(s.t_end, x);
    ASSERT_EQ(vp->removed_couplings().size(), 2u);
    const Obstacle& beam = sys.obstacles()[0];
    // Every cloth edge as the polyline through its virtual particles.
    for (const Spring& spring : sys.springs()) {
      std::vector<Vector3> line{x.row(spring.a).transpose()};
      std::vector<const VirtualParticle*> on_edge;
      for (const VirtualParticle& p : vp->particles())
        if (p.a == std::min(spring.a, spring.b) && p.b == std::max(spring.a, spring.b)) on_edge.push_back(&p);
      std::sort(on_edge.begin(), on_edge.end(), [](const VirtualParticle* l, const VirtualParticle* m) { return l->s < m->s; });
      if (spring.a > spring.b) std::reverse(on_edge.begin(), on_edge.end());
      for (const VirtualParticle* p : on_edge) line.push_back(p->x);
      line.push_back(x.row(spring.b).transpose());
      for (std::size_t k = 0; k + 1 < line.size(); ++k)
        EXPECT_LE(DeepestPoint(beam, line[k], line[k + 1]), 1e-9) << "spring " << spring.a << "-" << spring.b;
    }
    // The faces of the refined mesh (the triangulation with the projected
    // beam edges as constraints), sampled on a barycentric grid of step 1/16.
    std::vector<std::array<int, 3>> faces;
    vp->RefinedMesh(x, &faces);
    EXPECT_GT(faces.size(), 2u);
    const auto at = [&](int i) {
      const int n = sys.num_particles();
      return i < n ? Vector3(x.row(i).transpose()) : vp->particles()[static_cast<std::size_t>(i - n)].x;
    };
    double deepest = 0.0;
    Vector3 d;
    for (const auto& f : faces)
      for (int i = 0; i <= 16; ++i)
        for (int j = 0; i + j <= 16; ++j) {
          const Vector3 p = at(f[0]) + (at(f[1]) - at(f[0])) * (i / 16.0) + (at(f[2]) - at(f[0])) * (j / 16.0);
          deepest = std::max(deepest, -beam.SignedDistance(0.0, p, &d));
        }
    EXPECT_LE(deepest, 1e-9) << "a face of the refined mesh enters the beam";
  }
}

// A keyframed beam (rising 0.3 m from t = 0.5 s to 2 s) carries the cloth
// up: its virtual particles move with the beam and have its velocity. The
// particles hang about 0.3 m below the ridge at the end (0.35 m of spring
// on each side, swinging in): the mean height rises by more than 0.05 m
// from t = 0.5 s (measured 0.08–0.13 m, SBDF(2), BDF(2), implicit Euler),
// where without the motion it falls (by 0.02 m and more, the fixed beam).
TEST(VirtualParticles, AKeyframedBeamCarriesTheClothWithIt) {
  Scene s = BoxScene(true);
  ObstacleKeyframe rest, up;
  rest.t = 0.5;
  up.t = 2.0;
  up.translate = Vector3(0.0, 0.0, 0.3);
  s.obstacles[0].keyframes = {rest, up};
  const ParticleSystem sys(s);
  const RunSummary r = RunIntegrator(sys, Method::kSbdf2, {s.h, s.t_end, 0.5});
  ASSERT_TRUE(r.ok()) << r.status << ": " << r.message;
  ASSERT_EQ(r.trajectory.times.size(), 5u);  // 0, 0.5, 1, 1.5, 2
  const double z_start = r.trajectory.positions[1].col(2).mean(), z_end = r.trajectory.positions[4].col(2).mean();
  EXPECT_GT(z_end, z_start + 0.05);
  VirtualParticles* vp = VirtualParticles::Of(sys);
  vp->Update(1.0, r.trajectory.positions[2]);  // mid-motion (after the last keyframe the beam rests)
  ASSERT_FALSE(vp->particles().empty());
  for (const VirtualParticle& p : vp->particles()) EXPECT_NEAR(p.v.z(), 0.2, 1e-12) << "the beam's velocity";
}

// The round table (Fig. 5.14): after 1 s of SBDF(2) the faces of the
// refined mesh stay outside the table's polyhedron, whose rim chords lie
// inside the cylinder by at most r (1 − cos(π/64)) = 0.36 mm: that is the
// bound against the analytic cylinder (+1e-9 m). The base mesh's faces,
// cut by the rim, lie deeper (measured 22.9 mm), so the check can fail.
TEST(VirtualParticles, TheRefinedMeshStaysOutsideTheRoundTable) {
  const Scene s = LoadScene(std::string(CLOTHBENCH_SCENES_DIR) + "/virtual_round_table.toml");
  const ParticleSystem sys(s);
  const RunSummary r = RunIntegrator(sys, Method::kSbdf2, {s.h, s.t_end, s.t_end});
  ASSERT_TRUE(r.ok()) << r.status << ": " << r.message;
  const MatrixN3& x = r.trajectory.positions.back();
  VirtualParticles* vp = VirtualParticles::Of(sys);
  vp->Update(s.t_end, x);
  std::vector<std::array<int, 3>> refined;
  vp->RefinedMesh(x, &refined);
  const Obstacle& table = sys.obstacles()[0];
  const int n = sys.num_particles();
  const auto deepest = [&](const std::vector<std::array<int, 3>>& faces) {
    const auto at = [&](int i) {
      return i < n ? Vector3(x.row(i).transpose()) : vp->particles()[static_cast<std::size_t>(i - n)].x;
    };
    double depth = 0.0;
    Vector3 d;
    for (const auto& f : faces)
      for (int i = 0; i <= 16; ++i)
        for (int j = 0; i + j <= 16; ++j)
          depth = std::max(depth, -table.SignedDistance(0.0, at(f[0]) + (at(f[1]) - at(f[0])) * (i / 16.0) +
                                                                 (at(f[2]) - at(f[0])) * (j / 16.0), &d));
    return depth;
  };
  const double sagitta = 0.3 * (1.0 - std::cos(std::numbers::pi / 64  /* collision/shapes/cylinder.cc */));
  const double refined_depth = deepest(refined), base_depth = deepest(vp->triangles().vertices);
  std::printf("deepest point inside the table: base mesh %.3g m, refined %.3g m\n", base_depth, refined_depth);
  EXPECT_GT(vp->particles().size(), 0u);
  EXPECT_LE(refined_depth, sagitta + 1e-9);
  EXPECT_GT(base_depth, 2.0 * sagitta);
}

// The virtual particles are per-step state of the model: a second run on
// the same system starts without the first's (SBDF(2) under error control
// evaluates the forces at its start for the error estimate's slope).
TEST(VirtualParticles, ASecondRunOnTheSameSystemRepeatsTheFirstBitForBit) {
  Scene s = BoxScene(true);
  s.solver.step_control = StepControl::kError;
  s.solver.rtol = 1e-3;
  const ParticleSystem sys(s);
  const RunSummary a = RunIntegrator(sys, Method::kSbdf2, {s.h, s.t_end, s.frame_dt});
  const RunSummary b = RunIntegrator(sys, Method::kSbdf2, {s.h, s.t_end, s.frame_dt});
  EXPECT_EQ(a.steps, b.steps);
  EXPECT_TRUE(a.trajectory.positions.back() == b.trajectory.positions.back());
}

TEST(FaceTriangulation, KeepsTheConstraintAndCoversTheTriangle) {
  // A right triangle with a point on each leg, joined by a constraint that
  // cuts off the corner at the origin: 3 triangles, area 1/2, one of them
  // the corner (points 3, 4 and corner 0).
  std::vector<Eigen::Vector2d> points{{0, 0}, {1, 0}, {0, 1}, {0.5, 0}, {0, 0.5}};
  std::vector<std::array<int, 3>> triangles;
  const std::vector<std::array<int, 2>> boundary{{0, 3}, {3, 1}, {1, 2}, {2, 4}, {4, 0}};
  std::vector<std::array<int, 2>> constraints = boundary;
  constraints.push_back({3, 4});
  TriangulateFace(&points, constraints, &triangles);
  ASSERT_EQ(triangles.size(), 3u);
  double area = 0.0;
  bool corner = false;
  for (const auto& t : triangles) {
    const Eigen::Vector2d a = points[t[1]] - points[t[0]], b = points[t[2]] - points[t[0]];
    const double doubled = a.x() * b.y() - a.y() * b.x();
    EXPECT_GT(doubled, 0.0) << "counter-clockwise";
    area += 0.5 * doubled;
    std::array<int, 3> sorted = t;
    std::sort(sorted.begin(), sorted.end());
    corner = corner || sorted == std::array<int, 3>{0, 3, 4};
  }
  EXPECT_NEAR(area, 0.5, 1e-15);
  EXPECT_TRUE(corner);
  // Two crossing constraints add their crossing as a point.
  std::vector<Eigen::Vector2d> cross{{0, 0}, {1, 0}, {0, 1}, {0.5, 0}, {0, 0.5}, {0.25, 0}, {0.25, 0.75}};
  TriangulateFace(&cross, {{0, 5}, {5, 3}, {3, 1}, {1, 6}, {6, 2}, {2, 4}, {4, 0}, {3, 4}, {5, 6}}, &triangles);
  ASSERT_EQ(cross.size(), 8u);
  EXPECT_NEAR(cross[7].x(), 0.25, 1e-15);
  EXPECT_NEAR(cross[7].y(), 0.25, 1e-15);
}

INSTANTIATE_TEST_SUITE_P(ThesisIntegrators, VirtualBox,
                         ::testing::Values(Method::kImexEuler, Method::kImplicitEuler, Method::kSbdf2, Method::kBdf2,
                                           Method::kImplicitMidpoint),
                         [](const ::testing::TestParamInfo<Method>& p) { return std::string(ToString(p.param)); });

TEST(VirtualParticles, AnObstacleThatNeverMeetsTheClothChangesNothing) {
  Scene off = BoxScene(false);
  // virtual_box.toml's beam, 10 m below the cloth.
  off.obstacles[0].shape = ShapeFromValues("box", {{"center", Vector3(0.0, 0.0, -10.0)}, {"size", Vector3(2.0, 0.3, 0.4)}});
  off.t_end = 0.5;                                     // 1.2 m of fall: never near it
  Scene on = off;
  on.obstacles[0].virtual_particles = true;
  for (const Method m : {Method::kSbdf2, Method::kBdf2}) {
    const ParticleSystem a(off), b(on);
    const RunSummary ra = RunIntegrator(a, m, {off.h, off.t_end, off.frame_dt});
    const RunSummary rb = RunIntegrator(b, m, {on.h, on.t_end, on.frame_dt});
    ASSERT_TRUE(ra.ok() && rb.ok());
    EXPECT_TRUE(ra.trajectory.positions.back() == rb.trajectory.positions.back()) << ToString(m);
    EXPECT_EQ(ra.cg_iterations, rb.cg_iterations);
  }
}

}  // namespace
}  // namespace clothbench
