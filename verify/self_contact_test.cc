// Self-contact detection and response (collision/self_contact.h,
// self_contact_response.h) on configurations whose answer is known: closest
// points and coplanarity instants in closed form, the broad phase against a
// brute-force check of every pair, and the response on two layers that
// cross each other in one step without it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>

#include "collision/self_contact_list.h"
#include "collision/self_contact_response.h"
#include "collision/self_intersection.h"
#include "collision/edge_projection.h"
#include "model/particle_system.h"

namespace clothbench {
namespace {

MatrixN3 Points(std::initializer_list<Vector3> rows) {
  MatrixN3 x(static_cast<Eigen::Index>(rows.size()), 3);
  Eigen::Index k = 0;
  for (const Vector3& r : rows) x.row(k++) = r.transpose();
  return x;
}

// The relative position Σ w_k x_k of a pair's weights.
Vector3 Relative(const SelfContactPair& pair, const PairGeometry& g, const MatrixN3& x) {
  Vector3 r = Vector3::Zero();
  for (std::size_t k = 0; k < 4; ++k) r += g.w[k] * x.row(pair.p[k]).transpose();
  return r;
}

TEST(SelfContact, ClosestPointsOfAPointAndATriangleAndOfTwoEdges) {
  // Triangle in z = 0; a point 0.3 above its interior point (0.25, 0.25).
  const MatrixN3 x = Points({{0.25, 0.25, 0.3}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  const SelfContactPair pt{SelfContactPair::kPointTriangle, {0, 1, 2, 3}};
  const PairGeometry g = Closest(pt, x);
  // Exact up to round-off of a few operations on numbers of order 1.
  EXPECT_NEAR(g.distance, 0.3, 1e-15);
  EXPECT_NEAR(g.n.z(), 1.0, 1e-15);
  EXPECT_NEAR(g.w[1], -0.5, 1e-15);  // −(1 − 0.25 − 0.25)
  EXPECT_NEAR(g.w[2], -0.25, 1e-15);
  EXPECT_NEAR(g.w[3], -0.25, 1e-15);
  // Beyond the edge from (1,0,0) to (0,1,0): the closest point is on it.
  const MatrixN3 y = Points({{1, 1, 0}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  EXPECT_NEAR(Closest(pt, y).distance, std::sqrt(0.5), 1e-15);
  // Two skew edges: x-axis segment at z = 0, y-direction segment at z = 0.2
  // through (0.4, ·): closest at s = 0.4, t = 0.5, distance 0.2.
  const MatrixN3 e = Points({{0, 0, 0}, {1, 0, 0}, {0.4, -1, 0.2}, {0.4, 1, 0.2}});
  const SelfContactPair ee{SelfContactPair::kEdgeEdge, {0, 1, 2, 3}};
  const PairGeometry h = Closest(ee, e);
  EXPECT_NEAR(h.distance, 0.2, 1e-15);
  EXPECT_NEAR(h.w[1], 0.4, 1e-15);
  EXPECT_NEAR(h.w[3], -0.5, 1e-15);
  EXPECT_NEAR(h.n.z(), -1.0, 1e-15);  // from the second edge to the first
  EXPECT_NEAR((Relative(ee, h, e) - h.distance * h.n).norm(), 0.0, 1e-15);
}

TEST(SelfContact, CoplanarInstantOfAPointThroughATriangleAndOfCrossingEdges) {
  const SelfContactPair pt{SelfContactPair::kPointTriangle, {0, 1, 2, 3}};
  const MatrixN3 x0 = Points({{0.2, 0.2, 0.3}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  MatrixN3 x1 = x0;
  x1(0, 2) = -0.1;  // through the plane at θ = 0.3/0.4 = 0.75
  double theta = 0.0;
  PairGeometry g;
  ASSERT_TRUE(FirstCoplanarContact(pt, x0, x1, 1e-9, &theta, &g));
  // Bisection to 1e-15 of the step.
  EXPECT_NEAR(theta, 0.75, 1e-14);
  EXPECT_NEAR(g.n.z(), 1.0, 1e-15);  // against the relative motion (−z)
  // The same motion beside the triangle (x = y = 0.8, outside it): none.
  MatrixN3 b0 = x0, b1 = x1;
  b0.row(0) << 0.8, 0.8, 0.3;
  b1.row(0) << 0.8, 0.8, -0.1;
  EXPECT_FALSE(FirstCoplanarContact(pt, b0, b1, 1e-9, &theta, &g));
  // A tilting triangle: its plane z = c_z y turns about the x-axis as c_z
  // runs from −0.5 to 0.5 and meets the point at rest at c_z = 0.2.
  const SelfContactPair tilt{SelfContactPair::kPointTriangle, {0, 1, 2, 3}};
  const MatrixN3 r0 = Points({{0.1, 0.5, 0.1}, {0, 0, 0}, {1, 0, 0}, {0, 1, -0.5}});
  MatrixN3 r1 = r0;
  r1.row(3) << 0, 1, 0.5;  // c_z = −0.5 + θ = 0.2: θ = 0.7
  ASSERT_TRUE(FirstCoplanarContact(tilt, r0, r1, 1e-9, &theta, &g));
  EXPECT_NEAR(theta, 0.7, 1e-14);
  // Edges crossing: a y-edge at z = 0.1 drops to z = −0.1 through the x-edge.
  const SelfContactPair ee{SelfContactPair::kEdgeEdge, {0, 1, 2, 3}};
  const MatrixN3 e0 = Points({{0, 0, 0}, {1, 0, 0}, {0.5, -1, 0.1}, {0.5, 1, 0.1}});
  MatrixN3 e1 = e0;
  e1(2, 2) = e1(3, 2) = -0.1;
  ASSERT_TRUE(FirstCoplanarContact(ee, e0, e1, 1e-9, &theta, &g));
  EXPECT_NEAR(theta, 0.5, 1e-14);
  EXPECT_NEAR(g.w[1], 0.5, 1e-12);
  // Moved along x past the first edge's end (x = 1.5): parallel planes meet, no contact.
  MatrixN3 f0 = e0, f1 = e1;
  for (MatrixN3* m : {&f0, &f1}) (*m)(2, 0) = (*m)(3, 0) = 1.5;
  EXPECT_FALSE(FirstCoplanarContact(ee, f0, f1, 1e-9, &theta, &g));
}

// A sheet of side × side particles (spacing l = 0.6/(side − 1)) folded into a
// hairpin along v: two layers `gap` apart that move toward each other over
// the step, by `move` at their free ends and less toward the fold, in
// proportion to the depth: they end crossing each other along a line.
Scene HairpinScene(int side, double thickness) {
  Scene s = DefaultScene();
  s.grid.nu = s.grid.nv = side;
  s.grid.size = {0.6, 0.6};
  s.fixed.clear();
  s.fixed_specs.clear();
  s.collision = SelfCollisionSpec{true, thickness};
  return s;
}
void Hairpin(const ParticleSystem& sys, double gap, double move, MatrixN3* x0, MatrixN3* x1) {
  const Scene& s = sys.scene();
  const double radius = 0.5 * gap, arc = std::numbers::pi * radius, leg = 0.5 * (0.6 - arc);
  x0->resize(sys.num_particles(), 3);
  for (int j = 0; j < s.grid.nv; ++j) {
    const double along = 0.6 * j / (s.grid.nv - 1);
    double y = 0.0, z = 0.0;
    if (along < leg) {
      y = -radius, z = -(leg - along);
    } else if (along < leg + arc) {
      y = -radius * std::cos((along - leg) / radius), z = radius * std::sin((along - leg) / radius);
    } else {
      y = radius, z = -(along - leg - arc);
    }
    for (int i = 0; i < s.grid.nu; ++i) x0->row(s.Index(i, j)) << 0.6 * i / (s.grid.nu - 1), y, z;
  }
  *x1 = *x0;
  for (int p = 0; p < sys.num_particles(); ++p)
    if (std::abs((*x0)(p, 1)) >= radius * (1.0 - 1e-12))
      (*x1)(p, 1) -= std::copysign(move * -(*x0)(p, 2) / leg, (*x0)(p, 1));
}

// Every pair of elements that share no particle, checked directly.
std::vector<SelfContactPair> AllPairs(const SelfContactDetector& d) {
  std::vector<SelfContactPair> all;
  const int n = [&] {
    int m = 0;
    for (const auto& t : d.triangles()) m = std::max({m, t[0], t[1], t[2]});
    return m + 1;
  }();
  for (int p = 0; p < n; ++p)
    for (const auto& t : d.triangles())
      if (p != t[0] && p != t[1] && p != t[2]) all.push_back({SelfContactPair::kPointTriangle, {p, t[0], t[1], t[2]}});
  for (std::size_t a = 0; a < d.edges().size(); ++a)
    for (std::size_t b = a + 1; b < d.edges().size(); ++b) {
      const auto &e = d.edges()[a], &f = d.edges()[b];
      if (e[0] != f[0] && e[0] != f[1] && e[1] != f[0] && e[1] != f[1])
        all.push_back({SelfContactPair::kEdgeEdge, {e[0], e[1], f[0], f[1]}});
    }
  return all;
}

// Checks that `candidates` holds every pair of `detector`'s elements that is
// within `thickness` at x0 or touches along x0 → x1; counts them.
void ExpectCoverage(const SelfContactDetector& detector, std::vector<SelfContactPair> candidates, const MatrixN3& x0,
                    const MatrixN3& x1, double thickness, long* near, long* touching) {
  std::sort(candidates.begin(), candidates.end());
  EXPECT_EQ(std::adjacent_find(candidates.begin(), candidates.end()), candidates.end());  // each pair once
  *near = *touching = 0;
  for (const SelfContactPair& pair : AllPairs(detector)) {
    double theta = 0.0;
    PairGeometry g;
    const bool close = Closest(pair, x0).distance < thickness;
    const bool touches = FirstCoplanarContact(pair, x0, x1, 1e-3 * thickness, &theta, &g);
    if (!close && !touches) continue;
    *near += close;
    *touching += touches;
    EXPECT_TRUE(std::binary_search(candidates.begin(), candidates.end(), pair))
        << "pair kind " << pair.kind << " {" << pair.p[0] << ", " << pair.p[1] << ", " << pair.p[2] << ", " << pair.p[3] << "}";
  }
}

// A 10 × 10 hairpin whose layers, 0.3 l apart, close by up to 0.8 l over
// the step x0 → x1, with a thickness of 0.1 l.
class SelfContactHairpin : public ::testing::Test {
 protected:
  static constexpr int side = 10;
  const double l = 0.6 / (side - 1), thickness = 0.1 * l;
  const ParticleSystem sys{HairpinScene(side, thickness)};
  MatrixN3 x0, x1;
  void SetUp() override { Hairpin(sys, 0.3 * l, 0.4 * l, &x0, &x1); }
};

TEST_F(SelfContactHairpin, BroadPhaseHoldsEveryPairThatTouchesOrComesWithinTheMargin) {
  std::vector<std::array<int, 3>> triangles = GridTriangles(side, side).vertices, reversed = triangles;
  std::reverse(reversed.begin(), reversed.end());
  // In either order of the triangles (other owners, another report order).
  for (const auto* tri : {&triangles, &reversed}) {
    SelfContactDetector detector(*tri, sys.num_particles());
    // 3 edges per quad less the shared ones: 3·9·9 + 9 + 9 = 261 edges.
    EXPECT_EQ(detector.edges().size(), 261u);
    std::vector<SelfContactPair> candidates;
    detector.Candidates(x0, x1, thickness, &candidates);
    long near = 0, touching = 0;
    ExpectCoverage(detector, candidates, x0, x1, thickness, &near, &touching);
    // The layers, 0.3 l apart, close by up to 0.8 l: the facing pairs
    // deeper than 0.375 of the legs touch.
    EXPECT_GT(touching, 100);
    EXPECT_EQ(near, 0);  // 0.3 l > thickness at x0, and in-plane pairs are ≥ l/√2 apart
    // The layers also sliding past each other, 2 l each way along x: more
    // pairs touch, and all are held.
    MatrixN3 sheared = x1;
    for (int p = 0; p < sys.num_particles(); ++p) sheared(p, 0) += x0(p, 1) < 0.0 ? 2.0 * l : -2.0 * l;
    detector.Candidates(x0, sheared, thickness, &candidates);
    long sheared_touching = 0;
    ExpectCoverage(detector, candidates, x0, sheared, thickness, &near, &sheared_touching);
    EXPECT_GT(sheared_touching, 100);
  }
}

// Patches of grid quads as CGAL's boxes (GridPatches) give the same
// candidate pairs as one box per triangle: the triangle pairs come from
// within each patch and from the reported patch pairs.
TEST_F(SelfContactHairpin, PatchesGiveTheSameCandidatesAsTriangles) {
  const std::vector<std::array<int, 3>> triangles = GridTriangles(side, side).vertices;
  SelfContactDetector single(triangles, sys.num_particles());
  std::vector<SelfContactPair> expected;
  single.Candidates(x0, x1, thickness, &expected);
  std::sort(expected.begin(), expected.end());
  ASSERT_GT(expected.size(), 100u);
  for (int cells : {1, 2, 3, 9}) {  // 3 leaves partial patches at the border (9 quads a side)
    SelfContactDetector patched(triangles, sys.num_particles(), GridPatches(side, side, cells));
    std::vector<SelfContactPair> got;
    patched.Candidates(x0, x1, thickness, &got);
    std::sort(got.begin(), got.end());
    EXPECT_EQ(got, expected) << cells << " × " << cells << " patches";
  }
  EXPECT_THROW(SelfContactDetector(triangles, sys.num_particles(), std::vector<int>(3, 0)), std::invalid_argument);
}

// The list kept over steps (collision/self_contact_list.h) on the hairpin
// closing over 20 steps while it turns by half a radian about x and slides
// along it: at every step's two ends every pair within the reach is listed
// (each pair once) and its bound is at most its distance there; the list
// is kept over steps and rebuilt as the cloth moves.
TEST_F(SelfContactHairpin, ListKeptOverStepsHoldsEveryPairWithinReach) {
  const std::vector<std::array<int, 3>> triangles = GridTriangles(side, side).vertices;
  const double reach = thickness, skin = 0.25 * l;
  SelfContactList list(triangles, sys.num_particles(), GridPatches(side, side, 2), skin);
  const SelfContactDetector all_of(triangles, sys.num_particles());
  const std::vector<SelfContactPair> all = AllPairs(all_of);
  constexpr int kSteps = 20;
  const auto at = [&](int k) {
    const double s = static_cast<double>(k) / kSteps, angle = 0.5 * s;
    const Eigen::Matrix3d turn = Eigen::AngleAxisd(angle, Vector3::UnitX()).toRotationMatrix();
    MatrixN3 x = (x0 + s * (x1 - x0)) * turn.transpose();
    x.col(0).array() += 0.1 * s;
    return x;
  };
  long within = 0;
  for (int k = 0; k < kSteps; ++k) {
    const MatrixN3 a = at(k), b = at(k + 1);
    list.Cover(a, b, reach);
    std::vector<std::pair<SelfContactPair, std::size_t>> listed;
    for (std::size_t i = 0; i < list.size(); ++i) listed.push_back({list.pairs()[i], i});
    std::sort(listed.begin(), listed.end(), [](const auto& u, const auto& w) { return u.first < w.first; });
    for (std::size_t i = 1; i < listed.size(); ++i) EXPECT_FALSE(listed[i - 1].first == listed[i].first);
    for (const SelfContactPair& pair : all) {
      const double da = Closest(pair, a).distance, db = Closest(pair, b).distance;
      if (std::min(da, db) > reach) continue;
      ++within;
      const auto it = std::lower_bound(listed.begin(), listed.end(), pair,
                                       [](const auto& u, const SelfContactPair& w) { return u.first < w; });
      ASSERT_TRUE(it != listed.end() && it->first == pair) << "step " << k << ", pair kind " << pair.kind;
      // The bound holds at both ends (round-off of the distances aside).
      EXPECT_LE(list.LowerBound(it->second), std::min(da, db) + 1e-12) << "step " << k;
    }
  }
  EXPECT_GT(within, 100);  // the layers come within the reach: the check is not empty
  EXPECT_GT(list.builds(), 1);
  EXPECT_LT(list.builds(), kSteps);
  EXPECT_THROW(list.Cover(x0, x1, 0.0), std::invalid_argument);
  EXPECT_THROW(SelfContactList(triangles, sys.num_particles(), {}, skin), std::invalid_argument);
}

TEST_F(SelfContactHairpin, ListKeptOverStepsFollowsARigidTurnAndCoversAStepFasterThanItsSkin) {
  const std::vector<std::array<int, 3>> triangles = GridTriangles(side, side).vertices;
  const double reach = thickness, skin = 0.25 * l;
  SelfContactList list(triangles, sys.num_particles(), GridPatches(side, side, 2), skin);
  // The hairpin turns as a whole by 1 rad about a skew axis in 20 steps
  // while moving 0.4 m: its far ends move 15 mm a step, and by 0.3 m in
  // all, ten times D − reach = 2R = 33 mm. Distances do not change, so
  // the rigid motions fitted to the patches keep the first list (with
  // Q = I it was built in every step).
  const Vector3 axis = Vector3(1.0, 1.0, 0.5).normalized();
  const auto at = [&](int k) {
    const Eigen::Matrix3d turn = Eigen::AngleAxisd(0.05 * k, axis).toRotationMatrix();
    MatrixN3 x = x0 * turn.transpose();
    x.col(0).array() += 0.02 * k;
    return x;
  };
  for (int k = 0; k < 20; ++k) list.Cover(at(k), at(k + 1), reach);
  EXPECT_EQ(list.builds(), 1);
  // Then a step that closes legs 1.5 l apart (D = 0.6 l) by up to 3 l,
  // twelve times the skin, through each other: the pairs that come within
  // the reach anywhere along it are listed, and their bounds hold at both
  // ends (without the pairs over the path, this fails).
  MatrixN3 a, b;
  Hairpin(sys, 1.5 * l, 3.0 * l, &a, &b);
  list.Cover(a, b, reach);
  EXPECT_GE(list.builds(), 2);
  const SelfContactDetector all_of(triangles, sys.num_particles());
  long within = 0;
  for (const SelfContactPair& pair : AllPairs(all_of)) {
    double nearest = std::numeric_limits<double>::infinity();
    for (int t = 0; t <= 16; ++t) nearest = std::min(nearest, Closest(pair, a + (t / 16.0) * (b - a)).distance);
    if (nearest > reach) continue;
    ++within;
    const auto& pairs = list.pairs();
    const auto it = std::find(pairs.begin(), pairs.end(), pair);
    ASSERT_TRUE(it != pairs.end()) << "pair kind " << pair.kind;
    const std::size_t i = static_cast<std::size_t>(it - pairs.begin());
    // The bound holds at both ends (round-off of the distances aside).
    EXPECT_LE(list.LowerBound(i), std::min(Closest(pair, a).distance, Closest(pair, b).distance) + 1e-12);
  }
  EXPECT_GT(within, 100);  // the legs pass through each other's reach
}

TEST(SelfContact, BroadPhaseLeavesOutASheetThatSlidesAsAWhole) {
  // The whole hairpin moved 3 l along x over the step: its boxes sweep
  // over 3 spacings, but no two elements move relative to each other, so
  // the candidates are those within the margin at x0, as at rest.
  const int side = 10;
  const double l = 0.6 / (side - 1), thickness = 0.1 * l;
  const ParticleSystem sys(HairpinScene(side, thickness));
  MatrixN3 x0, x1;
  Hairpin(sys, 0.3 * l, 0.0, &x0, &x1);
  SelfContactDetector detector(GridTriangles(side, side).vertices, sys.num_particles());
  std::vector<SelfContactPair> still, sliding;
  detector.Candidates(x0, x0, thickness, &still);
  MatrixN3 moved = x0;
  moved.col(0).array() += 3.0 * l;
  detector.Candidates(x0, moved, thickness, &sliding);
  long near = 0, touching = 0;
  ExpectCoverage(detector, sliding, x0, moved, thickness, &near, &touching);
  EXPECT_EQ(touching, 0);
  // Without the relative-motion test (an unbounded slack) each element
  // also meets those 3 spacings along x.
  std::vector<SelfContactPair> unpruned;
  detector.Candidates(x0, moved, thickness, &unpruned, 1e3);
  std::printf("[ slide ] candidates at rest %zu, sliding %zu, sliding without the test %zu\n", still.size(),
              sliding.size(), unpruned.size());
  // Measured: 658 at rest, 1619 sliding, 5854 without the test. The
  // sliding element boxes are longer, so more element pairs of the same
  // triangle pairs pass their box test.
  EXPECT_GT(still.size(), 0u);
  EXPECT_LE(sliding.size(), 3 * still.size());
  EXPECT_LT(3 * sliding.size(), unpruned.size());
}

// The 12×12 hairpin's step of 5 ms: layers 0.3 l apart, closing by 0.4 l
// at the free ends, thickness 0.1 l.
struct HairpinStep {
  static constexpr int kSide = 12;
  static constexpr double kL = 0.6 / (kSide - 1), kThickness = 0.1 * kL, kH = 0.005;
  ParticleSystem sys{HairpinScene(kSide, kThickness)};
  MatrixN3 x0, x1;
  HairpinStep() { Hairpin(sys, 0.3 * kL, 0.4 * kL, &x0, &x1); }
};

TEST(SelfContact, ResponseStopsTwoLayersFromCrossingAndKeepsMomentum) {
  const HairpinStep step;
  const ParticleSystem& sys = step.sys;
  const MatrixN3 &x0 = step.x0, &x1 = step.x1;
  const int side = HairpinStep::kSide;
  const double thickness = HairpinStep::kThickness, h = HairpinStep::kH;
  const std::vector<std::array<int, 3>> triangles = GridTriangles(side, side).vertices;
  // Without a response the layers pass through each other.
  ASSERT_FALSE(SelfIntersections(x1, triangles).empty());
  MatrixN3 x = x1, v = (x1 - x0) / h;
  const MatrixN3 v_before = v;
  SelfContactResponse response(sys, thickness);
  EXPECT_EQ(response.Respond(h, x0, &x, &v), 0);
  EXPECT_TRUE(SelfIntersections(x, triangles).empty());
  // x = x0 + h v̄ still (the mean velocity's correction moves both).
  EXPECT_LT((x - x0 - h * v).cwiseAbs().maxCoeff(), 1e-15);
  // No pair touches along the corrected path.
  SelfContactDetector detector(triangles, sys.num_particles());
  for (const SelfContactPair& pair : AllPairs(detector)) {
    double theta = 0.0;
    PairGeometry g;
    EXPECT_FALSE(FirstCoplanarContact(pair, x0, x, 1e-3 * thickness, &theta, &g));
  }
  // Impulses in pairs of equal and opposite momentum, no fixed particle:
  // Σ m Δv = 0 to round-off (|m v| ~ 1e-3 kg m/s, 1e-16 relative per impulse).
  const Vector3 dp = (v - v_before).transpose() * sys.masses();
  EXPECT_LT(dp.norm(), 1e-15);
  const SelfContactStats& st = response.stats();
  EXPECT_GT(st.collisions, 0);
  EXPECT_EQ(st.unresolved_steps, 0);
  // The layers' closing kinetic energy is removed (inelastic): W_self < 0.
  EXPECT_LT(st.work, 0.0);
}

}  // namespace
}  // namespace clothbench
