// Crossings of the cloth with itself (self_intersection.h). All CGAL code
// of it stays here.
#include "collision/self_intersection.h"

#include <algorithm>
#include <iterator>
#include <stdexcept>
#include <string>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>

namespace clothbench {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Mesh = CGAL::Surface_mesh<Kernel::Point_3>;

}  // namespace

std::vector<std::pair<int, int>> SelfIntersections(const MatrixN3& x, const std::vector<std::array<int, 3>>& triangles) {
  Mesh mesh;
  std::vector<Mesh::Vertex_index> vertex(static_cast<std::size_t>(x.rows()));
  for (Eigen::Index p = 0; p < x.rows(); ++p)
    vertex[static_cast<std::size_t>(p)] = mesh.add_vertex(Kernel::Point_3(x(p, 0), x(p, 1), x(p, 2)));
  std::vector<int> triangle_of_face;
  triangle_of_face.reserve(triangles.size());
  for (std::size_t k = 0; k < triangles.size(); ++k) {
    const std::array<int, 3>& t = triangles[k];
    for (int p : t)
      if (p < 0 || p >= x.rows())
        throw std::invalid_argument("SelfIntersections: triangle " + std::to_string(k) + " names particle " +
                                    std::to_string(p) + " of " + std::to_string(x.rows()));
    const Mesh::Face_index f = mesh.add_face(vertex[static_cast<std::size_t>(t[0])],
                                             vertex[static_cast<std::size_t>(t[1])],
                                             vertex[static_cast<std::size_t>(t[2])]);
    if (f == Mesh::null_face())
      throw std::invalid_argument("SelfIntersections: triangle " + std::to_string(k) +
                                  " does not fit a manifold mesh with the ones before it");
    triangle_of_face.push_back(static_cast<int>(k));
  }
  std::vector<std::pair<Mesh::Face_index, Mesh::Face_index>> found;
  CGAL::Polygon_mesh_processing::self_intersections(faces(mesh), mesh, std::back_inserter(found));
  std::vector<std::pair<int, int>> pairs;
  pairs.reserve(found.size());
  for (const auto& [f, g] : found) {
    const int a = triangle_of_face[static_cast<std::size_t>(f.idx())], b = triangle_of_face[static_cast<std::size_t>(g.idx())];
    if (a == b) continue;  // a degenerate triangle
    pairs.emplace_back(std::min(a, b), std::max(a, b));
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  return pairs;
}

}  // namespace clothbench
