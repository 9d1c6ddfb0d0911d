// CGAL's constrained Delaunay triangulation of a cloth face (thesis §5.3).
#include "collision/face_triangulation.h"

#include <algorithm>

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

namespace clothbench {

namespace {
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using VertexBase = CGAL::Triangulation_vertex_base_with_info_2<int, Kernel>;
// Face info: the nesting level of the domain marking (−1: not reached).
using FaceInfo = CGAL::Triangulation_face_base_with_info_2<int, Kernel>;
using FaceBase = CGAL::Constrained_triangulation_face_base_2<Kernel, FaceInfo>;
using Tds = CGAL::Triangulation_data_structure_2<VertexBase, FaceBase>;
// Exact predicates with constructed intersections: crossing constraints
// get a new vertex instead of an exception.
using Cdt = CGAL::Constrained_Delaunay_triangulation_2<Kernel, Tds, CGAL::Exact_predicates_tag>;
}  // namespace

void TriangulateFace(std::vector<Eigen::Vector2d>* points, const std::vector<std::array<int, 2>>& constraints,
                     std::vector<std::array<int, 3>>* triangles) {
  triangles->clear();
  Cdt cdt;
  std::vector<Cdt::Vertex_handle> handle;
  handle.reserve(points->size());
  for (std::size_t k = 0; k < points->size(); ++k) {
    const Eigen::Vector2d& p = (*points)[k];
    handle.push_back(cdt.insert(Cdt::Point(p.x(), p.y())));
  }
  // Vertex info: 1 + the first index inserted at it (equal points share
  // it); 0 for a vertex that the constraints add (a crossing).
  for (auto v = cdt.finite_vertices_begin(); v != cdt.finite_vertices_end(); ++v) v->info() = 0;
  for (std::size_t k = handle.size(); k-- > 0;) handle[k]->info() = static_cast<int>(k) + 1;
  std::vector<Cdt::Vertex_handle> known(handle);
  std::sort(known.begin(), known.end());
  for (const auto& c : constraints) {
    const auto a = handle[static_cast<std::size_t>(c[0])], b = handle[static_cast<std::size_t>(c[1])];
    if (a != b) cdt.insert_constraint(a, b);
  }
  for (auto v = cdt.finite_vertices_begin(); v != cdt.finite_vertices_end(); ++v)
    if (!std::binary_search(known.begin(), known.end(), Cdt::Vertex_handle(v))) {
      points->emplace_back(v->point().x(), v->point().y());
      v->info() = static_cast<int>(points->size());
    }
  // The face's inside: the triangles reached from outside by crossing the
  // boundary once (CGAL's mark_domains: nesting levels counted across
  // constrained edges). Points on the face's edges are not exactly on them
  // after round-off; the boundary constraints keep the slivers between them
  // and the straight edge outside.
  for (auto f = cdt.all_faces_begin(); f != cdt.all_faces_end(); ++f) f->info() = -1;
  std::vector<Cdt::Face_handle> frontier{cdt.infinite_face()}, next;
  cdt.infinite_face()->info() = 0;
  for (int level = 0; !frontier.empty(); ++level) {
    next.clear();
    while (!frontier.empty()) {
      const Cdt::Face_handle f = frontier.back();
      frontier.pop_back();
      for (int i = 0; i < 3; ++i) {
        const Cdt::Face_handle g = f->neighbor(i);
        if (g->info() >= 0) continue;
        if (cdt.is_constrained(Cdt::Edge(f, i))) {
          next.push_back(g);
        } else {
          g->info() = level;
          frontier.push_back(g);
        }
      }
    }
    for (const Cdt::Face_handle& g : next)
      if (g->info() < 0) {
        g->info() = level + 1;
        frontier.push_back(g);
      }
  }
  for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f)
    if (f->info() % 2 == 1)
      triangles->push_back({f->vertex(0)->info() - 1, f->vertex(1)->info() - 1, f->vertex(2)->info() - 1});
}

}  // namespace clothbench
