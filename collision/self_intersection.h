// Crossings of the cloth with itself: pairs of the grid's triangles that
// intersect other than in an edge or vertex they share (CGAL's
// Polygon_mesh_processing::self_intersections). The measure of cloth that
// passed through itself, whatever the method's self-contact response.
#ifndef CLOTHBENCH_COLLISION_SELF_INTERSECTION_H_
#define CLOTHBENCH_COLLISION_SELF_INTERSECTION_H_

#include <array>
#include <utility>
#include <vector>

#include "model/types.h"

namespace clothbench {

/// The pairs (a, b), a < b, of `triangles` (indices into the rows of x;
/// the cloth's: GridTriangles(nu, nv).vertices, collision/edge_projection.h)
/// that intersect each other beyond what they share, sorted. Triangles
/// with a zero area are reported by CGAL with themselves and skipped.
/// @param x N×3 positions [m]
/// @throws std::invalid_argument if a triangle names a row outside x
std::vector<std::pair<int, int>> SelfIntersections(const MatrixN3& x, const std::vector<std::array<int, 3>>& triangles);

}  // namespace clothbench

#endif  // CLOTHBENCH_COLLISION_SELF_INTERSECTION_H_
