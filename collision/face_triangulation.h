// The constrained Delaunay triangulation of one cloth face with the points
// inserted into it (thesis §5.3: the topology of the virtual particles,
// computed there with Shewchuk's Triangle; here CGAL's
// Constrained_Delaunay_triangulation_2). All CGAL code of it stays in
// face_triangulation.cc.
#ifndef CLOTHBENCH_COLLISION_FACE_TRIANGULATION_H_
#define CLOTHBENCH_COLLISION_FACE_TRIANGULATION_H_

#include <array>
#include <vector>

#include <Eigen/Core>

namespace clothbench {

/// Triangulates the points (2D, in the face's plane [m]; the face's three
/// corners first, then points on its edges and inside it) with the
/// segments `constraints` (index pairs) as edges of the result. The
/// constraints must include the face's boundary, corner to corner through
/// the points on each edge in order: only the triangles inside it are
/// returned (round-off puts points on an edge slightly off it). Where two
/// constraints cross, the crossing is added as a new point at the end of
/// `points`. Equal points are one vertex, numbered by the first.
/// @param points in: the points; out: with the crossings appended
/// @param triangles overwritten: counter-clockwise index triples into points
void TriangulateFace(std::vector<Eigen::Vector2d>* points, const std::vector<std::array<int, 2>>& constraints,
                     std::vector<std::array<int, 3>>* triangles);

}  // namespace clothbench

#endif  // CLOTHBENCH_COLLISION_FACE_TRIANGULATION_H_
