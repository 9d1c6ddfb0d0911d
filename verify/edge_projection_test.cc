// The projection of an obstacle edge onto a cloth face (model/
// edge_projection.h; thesis §5.3) on hand-built cases: an edge across one
// flat face (parallel projection), across two faces that share an edge,
// clipped at the face's plane, wholly below it, and a folded pair of faces
// whose centre of projection is finite. Coordinates are O(1) m, so 1e-12
// is round-off.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>


#include <Eigen/Geometry>

#include "collision/edge_projection.h"
#include "model/obstacle.h"
#include "collision/shapes/triangle_mesh.h"
#include "verify/temp_file.h"

namespace clothbench {
namespace {

constexpr double kTol = 1e-12;

// The unit right triangle in z = 0, normal +z.
ProjectionFace FlatTriangle() {
  ProjectionFace f;
  f.p = {Vector3(0, 0, 0), Vector3(1, 0, 0), Vector3(0, 1, 0)};
  return f;
}

TEST(EdgeProjection, FlatFaceProjectsInParallelAndClipsToTheTriangle) {
  ProjectionFace f = FlatTriangle();
  f.neighbour_normal = {Vector3::UnitZ(), Vector3::UnitZ(), std::nullopt};  // flat neighbours and a border
  const Eigen::Vector4d c = CentreOfProjection(f);
  EXPECT_NEAR(c(3), 0.0, kTol);  // at infinity
  EXPECT_NEAR(std::abs(c(2)), 1.0, kTol);  // along n_f
  // An edge 0.1 m above the face along y = 0.2 from x = −1 to 2: it enters
  // across edge 2 (x = 0) and leaves across edge 1 (x + y = 1).
  const Vector3 x(-1, 0.2, 0.1), y(2, 0.2, 0.1);
  const EdgeProjection e = ProjectEdgeOntoFace(x, y, f, c);
  ASSERT_TRUE(e.hit);
  EXPECT_NEAR((e.v_bar - Vector3(0, 0.2, 0)).norm(), 0.0, kTol);
  EXPECT_NEAR((e.w_bar - Vector3(0.8, 0.2, 0)).norm(), 0.0, kTol);
  EXPECT_EQ(e.v_edge, 2);
  EXPECT_EQ(e.w_edge, 1);
  // Parallel projection: V and W are straight above V̄ and W̄.
  EXPECT_NEAR((e.v - Vector3(0, 0.2, 0.1)).norm(), 0.0, kTol);
  EXPECT_NEAR((e.w - Vector3(0.8, 0.2, 0.1)).norm(), 0.0, kTol);
  EXPECT_NEAR(e.sv, 1.0 / 3.0, kTol);
  EXPECT_NEAR(e.sw, 1.8 / 3.0, kTol);
}

TEST(EdgeProjection, AnEdgeAcrossTwoFacesMeetsAtTheSharedEdge) {
  // The unit square split along its diagonal from (1, 0) to (0, 1).
  ProjectionFace a = FlatTriangle(), b;
  b.p = {Vector3(1, 0, 0), Vector3(1, 1, 0), Vector3(0, 1, 0)};
  a.neighbour_normal[1] = Vector3::UnitZ();
  b.neighbour_normal[2] = Vector3::UnitZ();
  const Vector3 x(-0.5, 0.5, 0.05), y(1.5, 0.6, 0.05);
  const EdgeProjection ea = ProjectEdgeOntoFace(x, y, a, CentreOfProjection(a));
  const EdgeProjection eb = ProjectEdgeOntoFace(x, y, b, CentreOfProjection(b));
  ASSERT_TRUE(ea.hit);
  ASSERT_TRUE(eb.hit);
  EXPECT_EQ(ea.w_edge, 1);  // leaves a across the diagonal …
  EXPECT_EQ(eb.v_edge, 2);  // … and enters b across it, at the same point
  EXPECT_NEAR((ea.w_bar - eb.v_bar).norm(), 0.0, kTol);
  EXPECT_NEAR((ea.w - eb.v).norm(), 0.0, kTol);
  EXPECT_NEAR(ea.sw, eb.sv, kTol);
  EXPECT_NEAR(ea.w_bar.x() + ea.w_bar.y(), 1.0, kTol);  // on the diagonal
}

TEST(EdgeProjection, OnlyThePartAboveTheFaceProjects) {
  const ProjectionFace f = FlatTriangle();
  const Eigen::Vector4d c = CentreOfProjection(f);
  // From 0.1 m below to 0.1 m above, over the face: the kept part starts at
  // the crossing, which is inside the face (not on an edge).
  const Vector3 x(0.1, 0.1, -0.1), y(0.5, 0.1, 0.1);
  const EdgeProjection e = ProjectEdgeOntoFace(x, y, f, c);
  ASSERT_TRUE(e.hit);
  EXPECT_EQ(e.v_edge, -1);
  EXPECT_EQ(e.w_edge, -1);
  EXPECT_NEAR(e.sv, 0.5, kTol);
  EXPECT_NEAR((e.v - Vector3(0.3, 0.1, 0.0)).norm(), 0.0, kTol);
  EXPECT_NEAR((e.w_bar - Vector3(0.5, 0.1, 0.0)).norm(), 0.0, kTol);
  // Wholly below: nothing.
  EXPECT_FALSE(ProjectEdgeOntoFace(Vector3(0.1, 0.1, -0.1), Vector3(0.5, 0.1, -0.2), f, c).hit);
}

TEST(EdgeProjection, FoldedFacesHaveAFiniteCentreAndProjectCentrally) {
  // A face whose three neighbours are folded down by 30° about its edges
  // (a cap over a convex obstacle): the bisecting planes meet below it.
  ProjectionFace f = FlatTriangle();
  const Vector3 n = f.Normal();
  for (int i = 0; i < 3; ++i) {
    const Vector3 e = (f.p[static_cast<std::size_t>((i + 1) % 3)] - f.p[static_cast<std::size_t>(i)]).normalized();
    // Rotating n by +30° about the edge direction e (counter-clockwise
    // about n_f) tips the neighbour's normal away from f: a convex fold.
    f.neighbour_normal[static_cast<std::size_t>(i)] = Eigen::AngleAxisd(std::numbers::pi / 6, e) * n;
  }
  const Eigen::Vector4d c = CentreOfProjection(f);
  ASSERT_GT(std::abs(c(3)), 1e-6);
  const Vector3 cp = c.head<3>() / c(3);
  EXPECT_LT(cp.z(), 0.0);  // below the face
  // C_f lies on each plane S_i (through edge i, normal n_f − n_{f_i}).
  // C_f comes from an SVD null vector divided by its w: round-off of
  // 1e-16 grows by 1/|w| and the O(1) coordinates, so 1e-10 here and for
  // the rays' directions below leaves a wide margin while a wrong centre
  // (off by the face's size) fails by far.
  for (int i = 0; i < 3; ++i) {
    const Vector3 m = (n - *f.neighbour_normal[static_cast<std::size_t>(i)]).normalized();
    EXPECT_NEAR(m.dot(cp - f.p[static_cast<std::size_t>(i)]), 0.0, 1e-10);
  }
  // An edge above the face: its projected end points lie on the rays from
  // C_f through the points of XY they come from (the cross ratio recovers
  // the central projection's preimage), and in the face's plane.
  const Vector3 x(-0.4, 0.3, 0.2), y(1.2, 0.25, 0.3);
  const EdgeProjection e = ProjectEdgeOntoFace(x, y, f, c);
  ASSERT_TRUE(e.hit);
  for (const auto& [bar, point] : {std::pair{e.v_bar, e.v}, std::pair{e.w_bar, e.w}}) {
    EXPECT_NEAR(bar.z(), 0.0, kTol);
    EXPECT_NEAR((bar - cp).normalized().cross((point - cp).normalized()).norm(), 0.0, 1e-10);
  }
  EXPECT_GE(e.v_edge, 0);
  EXPECT_GE(e.w_edge, 0);
  EXPECT_LT(e.sv, e.sw);
}

// The unit cube as a closed OFF mesh (two triangles per side; the bottom
// side's diagonal runs from (0, 0, 0) to (1, 1, 0)).
testing::TempFile UnitCubeOff() {
  std::string off = "OFF\n8 12 0\n";
  for (int k = 0; k < 8; ++k)
    off += std::to_string(k & 1) + " " + std::to_string((k >> 1) & 1) + " " + std::to_string((k >> 2) & 1) + "\n";
  // Outward-oriented triangles: bottom (z = 0) split along 0–3, top, and the four sides.
  off += "3 0 2 3\n3 0 3 1\n3 4 5 7\n3 4 7 6\n3 0 1 5\n3 0 5 4\n"
         "3 2 6 7\n3 2 7 3\n3 0 4 6\n3 0 6 2\n3 1 3 7\n3 1 7 5\n";
  return testing::TempFile("clothbench_cube.off", off);
}

TEST(EdgeProjection, RaysThatCrossAnotherObstacleFaceAreRejected) {
  const testing::TempFile cube = UnitCubeOff();
  const TriangleMesh mesh(cube.path(), 1.0, Vector3::Zero(), Vector3::Zero());
  const auto first_hit = [&](const Vector3& a, const Vector3& b) -> std::optional<double> {
    if (const auto hit = mesh.FirstHit(a, b)) return hit->s;
    return std::nullopt;
  };
  // The bottom diagonal, 0.05 m above a face below the cube (normal +z):
  // the rays up to it meet only the bottom side, at the edge.
  const Vector3 x(0, 0, 0), y(1, 1, 0);
  ProjectionFace below;
  below.p = {Vector3(-1, -1, -0.05), Vector3(2, -1, -0.05), Vector3(-1, 2, -0.05)};
  const EdgeProjection from_below = ProjectEdgeOntoFace(x, y, below, CentreOfProjection(below));
  ASSERT_TRUE(from_below.hit);
  EXPECT_TRUE(RaysReachTheEdge(from_below, first_hit));
  // A face above the cube facing down (normal −z): the same edge is above
  // it by its normal, but the rays down to it cross the top side first:
  // the cloth is on the cube's far side (Fig. 5.9).
  ProjectionFace above;
  above.p = {Vector3(-1, -1, 1.05), Vector3(-1, 2, 1.05), Vector3(2, -1, 1.05)};
  ASSERT_NEAR(above.Normal().z(), -1.0, kTol);
  const EdgeProjection from_above = ProjectEdgeOntoFace(x, y, above, CentreOfProjection(above));
  ASSERT_TRUE(from_above.hit);
  EXPECT_FALSE(RaysReachTheEdge(from_above, first_hit));
}

TEST(EdgeProjection, GridTrianglesKnowTheirNeighbours) {
  const ClothTriangles t = GridTriangles(3, 3);  // 2 × 2 quads, 8 triangles
  ASSERT_EQ(t.vertices.size(), 8u);
  for (std::size_t f = 0; f < t.vertices.size(); ++f)
    for (std::size_t k = 0; k < 3; ++k) {
      const int g = t.across[f][k];
      if (g < 0) continue;
      // The face across edge k holds the same two particles, and points back.
      const int a = t.vertices[f][k], b = t.vertices[f][(k + 1) % 3];
      const auto& tg = t.vertices[static_cast<std::size_t>(g)];
      int back = -1;
      for (std::size_t m = 0; m < 3; ++m)
        if (tg[m] == b && tg[(m + 1) % 3] == a) back = static_cast<int>(m);
      ASSERT_GE(back, 0) << f << " " << k;
      EXPECT_EQ(t.across[static_cast<std::size_t>(g)][static_cast<std::size_t>(back)], static_cast<int>(f));
    }
  int border = 0;
  for (const auto& a : t.across)
    for (int g : a) border += g < 0;
  EXPECT_EQ(border, 8);  // the grid's 8 outer edges, each in one triangle
}

// The thesis' Fig. 5.13: a 4-particle cloth whose particles are all
// outside a box while its plane cuts the box, 0.2 m below the box's top.
// The top's four edges project onto the cloth (parallel: the cloth is
// flat); the two that cross the cloth's diagonal do so in both triangles,
// meeting on it; the vertical edges project to points and give nothing.
TEST(EdgeProjection, TheTopEdgesOfABoxThroughAFourParticleCloth) {
  MatrixN3 x(4, 3);
  x << -1, -1, 0.3, 1, -1, 0.3, -1, 1, 0.3, 1, 1, 0.3;  // grid 2 × 2, particle i + 2 j
  const std::vector<Vector3> v = {{-0.5, -0.2, -0.5}, {0.5, -0.2, -0.5}, {0.5, 0.6, -0.5}, {-0.5, 0.6, -0.5},
                                  {-0.5, -0.2, 0.5},  {0.5, -0.2, 0.5},  {0.5, 0.6, 0.5},  {-0.5, 0.6, 0.5}};
  const std::vector<std::array<int, 2>> edges = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6},
                                                 {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
  // The box's outward direction at the cloth's centroids (inside the box,
  // nearest its top): up.
  const auto outward = [](const Vector3&) { return Vector3(Vector3::UnitZ()); };
  const auto no_block = [](const Vector3&, const Vector3&) { return std::optional<double>(); };
  const std::vector<FaceEdgeHit> hits = ProjectObstacleEdges(x, GridTriangles(2, 2), v, edges, outward, no_block);
  ASSERT_EQ(hits.size(), 6u);
  std::array<int, 12> per_edge{};
  for (const FaceEdgeHit& h : hits) {
    ++per_edge[static_cast<std::size_t>(h.edge)];
    EXPECT_NEAR(h.projection.v_bar.z(), 0.3, kTol);
    EXPECT_NEAR(h.projection.v.z(), 0.5, kTol);
    EXPECT_NEAR((h.projection.v_bar.head<2>() - h.projection.v.head<2>()).norm(), 0.0, kTol);
  }
  // y = −0.2 (edge 4) and x = 0.5 (edge 5) cross the diagonal x = y.
  EXPECT_EQ(per_edge, (std::array<int, 12>{0, 0, 0, 0, 2, 2, 1, 1, 0, 0, 0, 0}));
  for (const FaceEdgeHit& a : hits)
    for (const FaceEdgeHit& b : hits)
      if (a.edge == b.edge && a.face < b.face) {
        const double gap = std::min((a.projection.w_bar - b.projection.v_bar).norm(),
                                    (a.projection.v_bar - b.projection.w_bar).norm());
        EXPECT_NEAR(gap, 0.0, kTol) << "edge " << a.edge;
      }
}

// The obstacles' edge sets (Obstacle::Edges): a box's 12 edges of its
// three lengths, a cylinder's rims on its circles, a geodesic sphere's
// edges on the sphere (its surface outward), a mesh's triangle edges once
// each, all moved by the pose.
TEST(ObstacleEdges, EveryTypeGivesItsEdgesAtItsPose) {
  std::vector<Vector3> v;
  std::vector<std::array<int, 2>> e;
  ObstacleSpec box;
  const Vector3 box_size(0.2, 0.4, 0.8);
  box.shape = ShapeFromValues("box", {{"center", Vector3(1, 2, 3)}, {"size", box_size}});
  Obstacle(box).Edges(ObstaclePose{}, &v, &e);
  ASSERT_EQ(v.size(), 8u);
  ASSERT_EQ(e.size(), 12u);
  std::array<int, 3> lengths{};
  for (const auto& [a, b] : e) {
    const double len = (v[static_cast<std::size_t>(a)] - v[static_cast<std::size_t>(b)]).norm();
    for (int k = 0; k < 3; ++k) lengths[static_cast<std::size_t>(k)] += std::abs(len - box_size(k)) < kTol;
  }
  EXPECT_EQ(lengths, (std::array<int, 3>{4, 4, 4}));

  ObstacleSpec cylinder;
  cylinder.shape = ShapeFromValues("cylinder", {{"center", Vector3(0, 0, 0.7)}, {"radius", 0.5}, {"height", 0.7}});
  Obstacle(cylinder).Edges(ObstaclePose{}, &v, &e);
  constexpr int kN = 64;  // the rims' segments (collision/shapes/cylinder.cc)
  ASSERT_EQ(v.size(), static_cast<std::size_t>(2 * kN));
  EXPECT_EQ(e.size(), static_cast<std::size_t>(3 * kN));
  for (const Vector3& p : v) {
    EXPECT_NEAR(std::hypot(p.x(), p.y()), 0.5, kTol);
    EXPECT_TRUE(std::abs(p.z() - 0.7) < kTol || std::abs(p.z()) < kTol);
  }

  ObstacleSpec sphere;
  const Vector3 sphere_centre(0, 0, 1);
  sphere.shape = ShapeFromValues("sphere", {{"center", sphere_centre}, {"radius", 0.3}});
  ObstaclePose moved;  // 0.5 m along x
  moved.identity = false;
  moved.translation = Vector3(0.5, 0, 0);
  moved.anchor = sphere_centre;
  Obstacle(sphere).Edges(moved, &v, &e);
  // The geodesic sphere after 3 subdivisions: V = 10·4³ + 2, E = 30·4³.
  EXPECT_EQ(v.size(), 642u);
  EXPECT_EQ(e.size(), 1920u);
  for (const Vector3& p : v) EXPECT_NEAR((p - Vector3(0.5, 0, 1)).norm(), 0.3, kTol);
  // Its surface: closed (every edge in two triangles), outward.
  std::vector<Vector3> sv;
  std::vector<std::array<int, 3>> st;
  Obstacle(sphere).Surface(&sv, &st);
  EXPECT_EQ(sv.size(), 642u);  // the edges' vertices, once
  ASSERT_EQ(st.size(), 1280u);
  for (const auto& t : st) {
    const Vector3 a = sv[static_cast<std::size_t>(t[0])], b = sv[static_cast<std::size_t>(t[1])],
                  c = sv[static_cast<std::size_t>(t[2])];
    EXPECT_GT((b - a).cross(c - a).dot((a + b + c) / 3.0 - sphere_centre), 0.0);
  }

  const testing::TempFile cube = UnitCubeOff();
  ObstacleSpec mesh;
  mesh.shape = ShapeFromValues("mesh", {{"path", cube.path()}});
  Obstacle(mesh).Edges(ObstaclePose{}, &v, &e);
  EXPECT_EQ(v.size(), 8u);
  EXPECT_EQ(e.size(), 18u);  // 12 sides and 6 diagonals, 12 triangles' 36 half-edges
}

}  // namespace
}  // namespace clothbench
