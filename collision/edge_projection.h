// The projection of an obstacle edge onto a cloth face, the geometric core
// of the thesis' collision-adaptive virtual particles (thesis §5.3,
// Figs. 5.6–5.8; docs/model.md, "Virtual particles").
//
// Each cloth triangle f = (P1, P2, P3) with unit normal n_f has a centre of
// projection C_f, the intersection of three planes S_i, one through each
// edge of f. S_i contains the edge and has the normal
// (n_f − n_{f_i})/‖n_f − n_{f_i}‖, with n_{f_i} the normal of the face
// across that edge: it bisects the dihedral angle's complement, so the S_i
// of neighbouring faces coincide and the volumes above the faces tile the
// space above the cloth. Where the normals agree (a flat neighbourhood) or
// there is no neighbour (the cloth's border) that normal is undefined and
// S_i is its limit, the plane through the edge that contains n_f (normal
// e × n_f). C_f is kept in homogeneous coordinates: when the three planes
// meet at infinity (all three contain n_f, the flat cloth) C_f is the
// direction n_f and the projection is parallel, along n_f.
//
// An edge XY penetrates where its height h = ⟨n_f, Z − P1⟩ is positive; a
// part below the face is clipped off at h = 0. The kept segment is
// projected centrally from C_f onto the plane of f and clipped to the
// triangle; a clipped endpoint V̄ is mapped back to the point V of XY by
// the cross ratio, which a central projection preserves:
// ratio(X, Y, V) / ratio(X, Y, A) = ratio(X̄, Ȳ, V̄) / ratio(X̄, Ȳ, Ā) with
// A = (X + Y)/2 and ratio(X, Y, Z) = α/β for Z = αX + βY.
#ifndef CLOTHBENCH_COLLISION_EDGE_PROJECTION_H_
#define CLOTHBENCH_COLLISION_EDGE_PROJECTION_H_

#include <algorithm>
#include <array>
#include <optional>
#include <type_traits>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "model/types.h"

namespace clothbench {

/// A cloth triangle and the normals of its neighbours across its edges.
struct ProjectionFace {
  std::array<Vector3, 3> p;  ///< vertices P1, P2, P3 [m], counter-clockwise about n_f
  /// Unit normal of the face across edge i (from p[i] to p[(i + 1) % 3]);
  /// none on the cloth's border.
  std::array<std::optional<Vector3>, 3> neighbour_normal;
  /// n_f = (P2 − P1) × (P3 − P1) / ‖…‖.
  Vector3 Normal() const;
};

/// The centre of projection C_f of `f` in homogeneous coordinates (c, w):
/// the point c/w when w ≠ 0, the direction c (= ±n_f up to scale) when the
/// planes S_i meet at infinity (w = 0 within round-off). Unit length.
Eigen::Vector4d CentreOfProjection(const ProjectionFace& f);

/// Where an edge's projection lies in a face: the clipped segment V̄W̄ in
/// the face and the points V, W of the edge it comes from.
struct EdgeProjection {
  bool hit = false;       ///< false: no part of the edge projects into the face from above it
  Vector3 v_bar, w_bar;   ///< endpoints of the clipped projection, in the face's plane [m]
  Vector3 v, w;           ///< the points of the edge XY they are projections of [m]
  double sv = 0.0, sw = 0.0;  ///< their parameters on XY (Z = (1 − s) X + s Y), sv ≤ sw
  /// The face edge (0, 1, 2: from p[i] to p[i + 1]) each projected
  /// endpoint lies on, −1 if it is inside the face (an end of the kept
  /// segment, e.g. an obstacle vertex through the cloth).
  int v_edge = -1, w_edge = -1;
};

/// Projects the obstacle edge XY onto face `f` from `centre`
/// (CentreOfProjection(f)), §5.3: heights, clipping at height 0, central
/// projection onto the face's plane, clipping to the triangle, the cross
/// ratio back onto XY. A kept point on the far side of C_f (its ray does
/// not reach the plane forwards) does not project.
/// @param x, y the edge's end points [m]
EdgeProjection ProjectEdgeOntoFace(const Vector3& x, const Vector3& y, const ProjectionFace& f,
                                   const Eigen::Vector4d& centre);
/// The same with the face's normal n = f.Normal() computed once by the
/// caller (one face against many edges).
EdgeProjection ProjectEdgeOntoFace(const Vector3& x, const Vector3& y, const ProjectionFace& f,
                                   const Eigen::Vector4d& centre, const Vector3& n);

/// The rejection of Fig. 5.9: a projection stands only if the rays from
/// its points V̄, W̄ in the face back to V, W on the obstacle edge meet no
/// other obstacle face first (else the cloth lies on the obstacle's far
/// side of that edge). `first_hit(a, b)` is the obstacle's first
/// intersection with the segment a → b as a fraction of it (nothing if
/// none), e.g. TriangleMesh::FirstHit's `s`; a hit within 1e-9 of the
/// ray's end is the edge itself. False if `e` has no hit.
template <class FirstHit>
bool RaysReachTheEdge(const EdgeProjection& e, const FirstHit& first_hit) {
  if (!e.hit) return false;
  for (const auto& [from, to] : {std::pair{e.v_bar, e.v}, std::pair{e.w_bar, e.w}}) {
    const std::optional<double> s = first_hit(from, to);
    if (s && *s < 1.0 - 1e-9) return false;
  }
  return true;
}

/// The cloth's triangles on its nu × nv grid (particle i + nu j): each
/// quad (i, j), (i+1, j), (i+1, j+1), (i, j+1) split along its diagonal
/// from (i, j) to (i+1, j+1) into two triangles counter-clockwise about
/// u × v, and for each triangle the one across each of its edges (edge k
/// runs from vertex k to vertex k + 1; −1 on the cloth's border).
struct ClothTriangles {
  std::vector<std::array<int, 3>> vertices;
  std::vector<std::array<int, 3>> across;
};
/// @throws std::invalid_argument if nu or nv is below 2
ClothTriangles GridTriangles(int nu, int nv);

/// A standing projection of obstacle edge `edge` onto cloth face `face`.
struct FaceEdgeHit {
  int face = 0, edge = 0;
  /// The face's particles in the order of projection.p (the face as
  /// oriented away from the obstacle): EdgeProjection::v_edge = k is the
  /// cloth edge from vertices[k] to vertices[(k + 1) % 3].
  std::array<int, 3> vertices{};
  EdgeProjection projection;
};

/// Every standing projection of the obstacle's edges onto the cloth at
/// positions x (§5.3). Each face is oriented away from the obstacle, its
/// normal turned to agree with outward(centroid) (or outward(face index,
/// centroid)), the direction from the obstacle toward the face's centroid
/// (the signed distance's D), so that
/// a positive height is an obstacle part through the cloth; its
/// neighbours' normals are turned the same way. A face and an edge are
/// paired only if their boxes, the face's grown by its longest side, meet:
/// an obstacle edge through the cloth is within about a cloth spacing of
/// it, as the particles themselves are kept outside. Rays are checked with
/// RaysReachTheEdge(first_hit). `candidates(box, visit)` calls visit(e)
/// for (at least) every edge e whose box may meet `box`, each once (a
/// spatial index; the overload without it visits every edge).
/// @param x N×3 cloth positions [m]
/// @param vertices obstacle vertices [m]; @param edges pairs of indices into them
/// @param normal scratch, one per face; @param hits overwritten (their
///        capacity is kept: no allocation once it suffices)
template <class Outward, class FirstHit, class Candidates>
void ProjectObstacleEdges(const MatrixN3& x, const ClothTriangles& cloth, const std::vector<Vector3>& vertices,
                          const std::vector<std::array<int, 2>>& edges, const Outward& outward,
                          const FirstHit& first_hit, const Candidates& candidates, std::vector<Vector3>* normal,
                          std::vector<FaceEdgeHit>* hits) {
  const std::size_t nf = cloth.vertices.size();
  normal->resize(nf);
  hits->clear();
  Eigen::AlignedBox3d all;
  for (const Vector3& v : vertices) all.extend(v);
  for (std::size_t f = 0; f < nf; ++f) {
    const auto& t = cloth.vertices[f];
    const Vector3 a = x.row(t[0]).transpose(), b = x.row(t[1]).transpose(), c = x.row(t[2]).transpose();
    Vector3 n = (b - a).cross(c - a).normalized();
    const Vector3 centroid = (a + b + c) / 3.0;
    Vector3 out;
    if constexpr (std::is_invocable_v<Outward, std::size_t, Vector3>)
      out = outward(f, centroid);
    else
      out = outward(centroid);
    if (n.dot(out) < 0.0) n = -n;
    (*normal)[f] = n;
  }
  for (std::size_t f = 0; f < nf; ++f) {
    const auto& t = cloth.vertices[f];
    ProjectionFace face;
    std::array<int, 3> order = t;
    for (std::size_t k = 0; k < 3; ++k) face.p[k] = x.row(t[k]).transpose();
    Eigen::AlignedBox3d box;
    for (const Vector3& p : face.p) box.extend(p);
    const double grow = std::max({(face.p[1] - face.p[0]).norm(), (face.p[2] - face.p[1]).norm(),
                                  (face.p[0] - face.p[2]).norm()});
    box.min().array() -= grow;
    box.max().array() += grow;
    if (!box.intersects(all)) continue;
    const bool flipped = (face.p[1] - face.p[0]).cross(face.p[2] - face.p[0]).dot((*normal)[f]) < 0.0;
    std::array<int, 3> across = cloth.across[f];
    if (flipped) {  // counter-clockwise about the turned normal: reverse, and the edges with it
      std::swap(face.p[1], face.p[2]);
      std::swap(order[1], order[2]);
      across = {across[2], across[1], across[0]};
    }
    for (std::size_t k = 0; k < 3; ++k)
      if (across[k] >= 0) face.neighbour_normal[k] = (*normal)[static_cast<std::size_t>(across[k])];
    const Eigen::Vector4d centre = CentreOfProjection(face);
    const Vector3 face_normal = face.Normal();
    candidates(box, [&](std::size_t e) {
      const Vector3& ex = vertices[static_cast<std::size_t>(edges[e][0])];
      const Vector3& ey = vertices[static_cast<std::size_t>(edges[e][1])];
      Eigen::AlignedBox3d edge_box(ex);
      edge_box.extend(ey);
      if (!box.intersects(edge_box)) return;
      const EdgeProjection pr = ProjectEdgeOntoFace(ex, ey, face, centre, face_normal);
      if (RaysReachTheEdge(pr, first_hit)) hits->push_back({static_cast<int>(f), static_cast<int>(e), order, pr});
    });
  }
}

/// The same over every edge (no spatial index).
template <class Outward, class FirstHit>
void ProjectObstacleEdges(const MatrixN3& x, const ClothTriangles& cloth, const std::vector<Vector3>& vertices,
                          const std::vector<std::array<int, 2>>& edges, const Outward& outward,
                          const FirstHit& first_hit, std::vector<Vector3>* normal, std::vector<FaceEdgeHit>* hits) {
  const auto every = [&](const Eigen::AlignedBox3d&, const auto& visit) {
    for (std::size_t e = 0; e < edges.size(); ++e) visit(e);
  };
  ProjectObstacleEdges(x, cloth, vertices, edges, outward, first_hit, every, normal, hits);
}

/// The same, returning the hits (tests, one-off calls).
template <class Outward, class FirstHit>
std::vector<FaceEdgeHit> ProjectObstacleEdges(const MatrixN3& x, const ClothTriangles& cloth,
                                              const std::vector<Vector3>& vertices,
                                              const std::vector<std::array<int, 2>>& edges, const Outward& outward,
                                              const FirstHit& first_hit) {
  std::vector<Vector3> normal;
  std::vector<FaceEdgeHit> hits;
  ProjectObstacleEdges(x, cloth, vertices, edges, outward, first_hit, &normal, &hits);
  return hits;
}

}  // namespace clothbench

#endif  // CLOTHBENCH_COLLISION_EDGE_PROJECTION_H_
