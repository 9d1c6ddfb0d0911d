// Triangle-mesh obstacles through CGAL (docs/model.md §7): OFF/OBJ/PLY input
// (CGAL::IO::read_polygon_mesh), a rigid placement (scale, rotation,
// translation), closest-point queries on CGAL's AABB tree, and the inside
// test of CGAL::Side_of_triangle_mesh for the sign of the distance. All CGAL
// code stays in triangle_mesh.cc.
#ifndef CLOTHBENCH_COLLISION_SHAPES_TRIANGLE_MESH_H_
#define CLOTHBENCH_COLLISION_SHAPES_TRIANGLE_MESH_H_

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "collision/shapes/obstacle_shape.h"

namespace clothbench {

/// The largest mesh obstacle [vertices + faces]: far above any garment or
/// avatar mesh, far below what would exhaust the memory of the distance tree.
inline constexpr double kMaxMeshElements = 1e8;

/// Checks the header of a mesh file before it is read: for OFF and PLY the
/// announced vertex and face counts must be at most kMaxMeshElements and
/// fit the file (at least 6 bytes per vertex and 8 per face, the shortest
/// ASCII lines), so a damaged header cannot make the reader allocate for
/// 2·10⁹ vertices. @return empty if the header is plausible, else the rule
/// it breaks (for the caller's message naming the scene key).
std::string CheckMeshHeader(const std::string& path);

class TriangleMesh {
 public:
  /// Loads `path` and places it: x ↦ R (scale · x) + translate, with R from
  /// `rotate_deg` (rotations about x, then y, then z, in degrees).
  /// @throws std::runtime_error naming the file if it cannot be read or is
  ///         not a triangle mesh.
  TriangleMesh(const std::string& path, double scale, const Vector3& rotate_deg, const Vector3& translate);
  /// A mesh from its vertices [m] and counter-clockwise (outward) index
  /// triangles, e.g. Obstacle::Surface of an analytic obstacle.
  /// @throws std::runtime_error if a triangle is degenerate or not
  ///         manifold (CGAL cannot add it)
  TriangleMesh(const std::vector<Vector3>& vertices, const std::vector<std::array<int, 3>>& triangles);
  ~TriangleMesh();
  TriangleMesh(const TriangleMesh&) = delete;
  TriangleMesh& operator=(const TriangleMesh&) = delete;

  /// Signed distance [m] (negative inside a closed mesh) and the unit
  /// direction D from the closest surface point toward the outside.
  double SignedDistance(const Vector3& p, Vector3* direction) const;
  /// The first intersection of the segment a → b [m] with the mesh (CGAL's
  /// AABB-tree ray cast, kept if within the segment), or nothing. The
  /// normal is the hit face's, turned toward a.
  std::optional<SegmentHit> FirstHit(const Vector3& a, const Vector3& b) const;
  /// The face closest to p [m] (its index in Export's triangles) and the
  /// closest point on it [m].
  int ClosestFace(const Vector3& p, Vector3* closest) const;
  int num_vertices() const;
  /// The placed mesh: vertices [V, 3] row-major [m] and triangles [T, 3]
  /// row-major 0-based vertex indices, e.g. for /scene/obstacles/<k> in
  /// result files.
  void Export(std::vector<double>* vertices, std::vector<int32_t>* triangles) const;
  bool closed() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_COLLISION_SHAPES_TRIANGLE_MESH_H_
