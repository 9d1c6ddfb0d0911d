// CGAL-backed triangle-mesh distance queries.
#include "collision/shapes/triangle_mesh.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>

#include <CGAL/AABB_face_graph_triangle_primitive.h>
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/IO/polygon_soup_io.h>
#include <CGAL/boost/graph/IO/polygon_mesh_io.h>
#include <CGAL/Polygon_mesh_processing/compute_normal.h>
#include <CGAL/Side_of_triangle_mesh.h>
#include <CGAL/Surface_mesh.h>
#include <Eigen/Geometry>
#include <fmt/format.h>

#include "collision/shapes/escape_control.h"
#include "collision/shapes/obstacle_shape.h"

namespace clothbench {

namespace {
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using Mesh = CGAL::Surface_mesh<Point>;
using Primitive = CGAL::AABB_face_graph_triangle_primitive<Mesh>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;
using Inside = CGAL::Side_of_triangle_mesh<Mesh, Kernel>;
}  // namespace

struct TriangleMesh::Impl {
  Mesh mesh;
  std::unique_ptr<Tree> tree;
  std::unique_ptr<Inside> inside;
  bool closed = false;
};

std::string CheckMeshHeader(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return "cannot be opened";
  in.seekg(0, std::ios::end);
  const double bytes = static_cast<double>(in.tellg());
  in.seekg(0);
  double vertices = -1.0, faces = -1.0;
  const auto trimmed = [](std::string s) {
    while (!s.empty() && (s.back() == '\r' || s.back() == ' ')) s.pop_back();
    return s;
  };
  std::string line;
  std::getline(in, line);
  const std::string first = trimmed(line);
  if (first.rfind("OFF", 0) == 0 || first.rfind("COFF", 0) == 0 || first.rfind("NOFF", 0) == 0) {
    // The counts are on the header line after "OFF" or on the first line
    // that is neither empty nor a comment.
    std::istringstream head(first.substr(first.find("OFF") + 3));
    if (!(head >> vertices >> faces)) {
      while (std::getline(in, line))
        if (const auto b = line.find_first_not_of(" \t\r"); b != std::string::npos && line[b] != '#') break;
      std::istringstream counts(line);
      if (!(counts >> vertices >> faces)) return "an OFF file without vertex and face counts";
    }
  } else if (first == "ply") {
    for (int k = 0; k < 1000 && std::getline(in, line) && trimmed(line) != "end_header"; ++k) {
      std::istringstream words(line);
      std::string element, name;
      double count = 0.0;
      if (words >> element >> name >> count && element == "element") {
        if (name == "vertex") vertices = count;
        if (name == "face") faces = count;
      }
    }
    if (vertices < 0.0 || faces < 0.0) return "a PLY file without vertex and face elements";
  } else {
    return "";  // OBJ and the rest: no counts to check; the reader grows as it reads
  }
  if (!(vertices >= 0.0) || !(faces >= 0.0) || vertices + faces > kMaxMeshElements)
    return fmt::format("announces {:g} vertices and {:g} faces (at most {:g} in all)", vertices, faces,
                       kMaxMeshElements);
  if (6.0 * vertices + 8.0 * faces > bytes)
    return fmt::format("announces {:g} vertices and {:g} faces, more than its {:g} bytes can hold (truncated or a "
                       "damaged header)", vertices, faces, bytes);
  return "";
}

namespace {

// For an OFF file that CGAL's reader refused: the first vertex line that is
// not three finite numbers, or the first face that names a vertex the file
// does not have ("" if none is found, or the file is not OFF).
std::string DiagnoseOff(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  const auto next = [&]() -> bool {  // the next line that is neither empty nor a comment
    while (std::getline(in, line))
      if (const auto b = line.find_first_not_of(" \t\r"); b != std::string::npos && line[b] != '#') return true;
    return false;
  };
  if (!next() || line.find("OFF") == std::string::npos) return "";
  std::istringstream head(line.substr(line.find("OFF") + 3));
  long vertices = -1, faces = -1;
  if (!(head >> vertices >> faces)) {
    if (!next()) return "";
    std::istringstream counts(line);
    if (!(counts >> vertices >> faces)) return "";
  }
  for (long k = 0; k < vertices; ++k) {
    if (!next()) return fmt::format("ends after {} of its {} vertices", k, vertices);
    std::istringstream words(line);
    std::string w[3];
    words >> w[0] >> w[1] >> w[2];
    for (const std::string& x : w) {
      char* end = nullptr;
      const double v = std::strtod(x.c_str(), &end);
      if (x.empty() || *end != '\0' || !std::isfinite(v))
        return fmt::format("vertex {} is not three finite numbers (\"{}\")", k, EscapeControl(line.substr(0, 60)));
    }
  }
  for (long f = 0; f < faces; ++f) {
    if (!next()) return fmt::format("ends after {} of its {} faces", f, faces);
    std::istringstream words(line);
    long count = 0;
    words >> count;
    for (long j = 0; j < count; ++j) {
      long v = -1;
      if (!(words >> v)) return fmt::format("face {} lists fewer than its {} vertices", f, count);
      if (v < 0 || v >= vertices)
        return fmt::format("face {} names vertex {}, but the file has {} vertices", f, v, vertices);
    }
  }
  return "";
}

// Why CGAL's read_polygon_mesh refused `path`, naming the vertex or face:
// the file read as a polygon soup (CGAL::IO::read_polygon_soup), then
// checked for what a polygon mesh cannot hold. Vertices and faces are
// counted from 0 in the file's order.
std::string DiagnoseMesh(const std::string& path) {
  std::vector<Point> points;
  std::vector<std::vector<std::size_t>> polygons;
  if (!CGAL::IO::read_polygon_soup(path, points, polygons)) {
    if (const std::string why = DiagnoseOff(path); !why.empty()) return why;
    return "cannot be parsed as OFF, OBJ, PLY or STL (a syntax error, or an unknown extension)";
  }
  if (polygons.empty()) return "holds no faces";
  for (std::size_t k = 0; k < points.size(); ++k)
    if (!std::isfinite(points[k].x()) || !std::isfinite(points[k].y()) || !std::isfinite(points[k].z()))
      return fmt::format("vertex {} is not finite ({:g}, {:g}, {:g})", k, points[k].x(), points[k].y(), points[k].z());
  std::map<std::vector<std::size_t>, std::size_t> seen;
  std::map<std::pair<std::size_t, std::size_t>, std::vector<std::size_t>> edges;  // undirected edge -> faces
  for (std::size_t f = 0; f < polygons.size(); ++f) {
    const std::vector<std::size_t>& poly = polygons[f];
    if (poly.size() < 3) return fmt::format("face {} has {} vertices (at least 3 needed)", f, poly.size());
    for (std::size_t v : poly)
      if (v >= points.size()) return fmt::format("face {} names vertex {}, but the file has {} vertices", f, v, points.size());
    std::vector<std::size_t> sorted = poly;
    std::sort(sorted.begin(), sorted.end());
    if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end())
      return fmt::format("face {} is degenerate (it names a vertex twice)", f);
    if (const auto [it, fresh] = seen.emplace(sorted, f); !fresh)
      return fmt::format("face {} duplicates face {} (the same vertices)", f, it->second);
    for (std::size_t k = 0; k < poly.size(); ++k) {
      const std::size_t a = poly[k], b = poly[(k + 1) % poly.size()];
      edges[{std::min(a, b), std::max(a, b)}].push_back(f);
    }
  }
  for (const auto& [e, faces] : edges)
    if (faces.size() > 2)
      return fmt::format("edge ({}, {}) is shared by {} faces ({}, {}, {}{}): not manifold", e.first, e.second,
                         faces.size(), faces[0], faces[1], faces[2], faces.size() > 3 ? ", …" : "");
  return "is not a manifold polygon mesh (a vertex joins separate fans of faces, or the faces cannot be oriented "
         "consistently)";
}

}  // namespace

TriangleMesh::TriangleMesh(const std::string& path, double scale, const Vector3& rotate_deg, const Vector3& translate)
    : impl_(std::make_unique<Impl>()) {
  if (!CGAL::IO::read_polygon_mesh(path, impl_->mesh) || impl_->mesh.number_of_faces() == 0)
    throw std::runtime_error(fmt::format("\"{}\": {}", path, DiagnoseMesh(path)));
  if (!CGAL::is_triangle_mesh(impl_->mesh))
    throw std::runtime_error(fmt::format("\"{}\" is not a triangle mesh", path));
  const Eigen::Matrix3d rot = RotationFromDegrees(rotate_deg);
  for (auto v : impl_->mesh.vertices()) {
    const Point& p = impl_->mesh.point(v);
    const Vector3 q = rot * (scale * Vector3(p.x(), p.y(), p.z())) + translate;
    // Placed vertices beyond 1e6 m (or non-finite ones in the file) would
    // overflow the distance queries' squared lengths.
    if (!q.allFinite() || q.cwiseAbs().maxCoeff() > 1e6)
      throw std::runtime_error(fmt::format("\"{}\": a vertex placed at ({:g}, {:g}, {:g}) is not finite or beyond "
                                           "1e6 m (check the file, scale and translate)",
                                           path, q.x(), q.y(), q.z()));
    impl_->mesh.point(v) = Point(q.x(), q.y(), q.z());
  }
  impl_->tree = std::make_unique<Tree>(faces(impl_->mesh).first, faces(impl_->mesh).second, impl_->mesh);
  impl_->tree->accelerate_distance_queries();
  impl_->closed = CGAL::is_closed(impl_->mesh);
  if (impl_->closed) impl_->inside = std::make_unique<Inside>(*impl_->tree);
}

TriangleMesh::TriangleMesh(const std::vector<Vector3>& vertices, const std::vector<std::array<int, 3>>& triangles)
    : impl_(std::make_unique<Impl>()) {
  std::vector<Mesh::Vertex_index> index;
  index.reserve(vertices.size());
  for (const Vector3& v : vertices) index.push_back(impl_->mesh.add_vertex(Point(v.x(), v.y(), v.z())));
  for (const auto& t : triangles)
    if (impl_->mesh.add_face(index.at(static_cast<std::size_t>(t[0])), index.at(static_cast<std::size_t>(t[1])),
                             index.at(static_cast<std::size_t>(t[2]))) == Mesh::null_face())
      throw std::runtime_error(fmt::format("triangle ({}, {}, {}) cannot be added to the mesh (not manifold)", t[0],
                                           t[1], t[2]));
  impl_->tree = std::make_unique<Tree>(faces(impl_->mesh).first, faces(impl_->mesh).second, impl_->mesh);
  impl_->tree->accelerate_distance_queries();
  impl_->closed = CGAL::is_closed(impl_->mesh);
  if (impl_->closed) impl_->inside = std::make_unique<Inside>(*impl_->tree);
}

TriangleMesh::~TriangleMesh() = default;

double TriangleMesh::SignedDistance(const Vector3& p, Vector3* direction) const {
  const Point q(p.x(), p.y(), p.z());
  const auto [closest, face] = impl_->tree->closest_point_and_primitive(q);
  const Vector3 c(closest.x(), closest.y(), closest.z());
  const Vector3 diff = p - c;
  const double dist = diff.norm();
  bool is_inside = false;
  if (impl_->closed) is_inside = (*impl_->inside)(q) == CGAL::ON_BOUNDED_SIDE;
  if (dist > 1e-12) {
    *direction = (is_inside ? -diff : diff) / dist;
  } else {
    const auto n = CGAL::Polygon_mesh_processing::compute_face_normal(face, impl_->mesh);
    *direction = Vector3(n.x(), n.y(), n.z());
  }
  return is_inside ? -dist : dist;
}

std::optional<SegmentHit> TriangleMesh::FirstHit(const Vector3& a, const Vector3& b) const {
  const Vector3 ab = b - a;
  const double len = ab.norm();
  if (len <= 0.0) return std::nullopt;
  const Kernel::Ray_3 ray(Point(a.x(), a.y(), a.z()), Point(b.x(), b.y(), b.z()));
  const auto res = impl_->tree->first_intersection(ray);
  if (!res) return std::nullopt;
  Vector3 q;
  if (const Point* p = boost::get<Point>(&res->first)) {
    q = Vector3(p->x(), p->y(), p->z());
  } else if (const auto* seg = boost::get<Kernel::Segment_3>(&res->first)) {  // ray in the face's plane
    const Point& p0 = seg->source();
    const Point& p1 = seg->target();
    const Vector3 q0(p0.x(), p0.y(), p0.z()), q1(p1.x(), p1.y(), p1.z());
    q = (q0 - a).squaredNorm() <= (q1 - a).squaredNorm() ? q0 : q1;
  } else {
    return std::nullopt;
  }
  const double s = (q - a).dot(ab) / (len * len);
  if (s > 1.0) return std::nullopt;
  const auto n = CGAL::Polygon_mesh_processing::compute_face_normal(res->second, impl_->mesh);
  Vector3 normal(n.x(), n.y(), n.z());
  if (normal.dot(ab) > 0.0) normal = -normal;
  return SegmentHit{std::clamp(s, 0.0, 1.0), q, normal};
}

int TriangleMesh::num_vertices() const { return static_cast<int>(impl_->mesh.number_of_vertices()); }
bool TriangleMesh::closed() const { return impl_->closed; }

int TriangleMesh::ClosestFace(const Vector3& p, Vector3* closest) const {
  const auto [c, face] = impl_->tree->closest_point_and_primitive(Point(p.x(), p.y(), p.z()));
  *closest = Vector3(c.x(), c.y(), c.z());
  return static_cast<int>(face.idx());  // faces are never removed: the index is the face's rank (Export)
}

void TriangleMesh::Export(std::vector<double>* vertices, std::vector<int32_t>* triangles) const {
  vertices->clear();
  triangles->clear();
  std::vector<int32_t> index(impl_->mesh.num_vertices(), -1);  // descriptor → dense index
  int32_t next = 0;
  for (auto v : impl_->mesh.vertices()) {
    const Point& p = impl_->mesh.point(v);
    vertices->insert(vertices->end(), {p.x(), p.y(), p.z()});
    index[v.idx()] = next++;
  }
  for (auto f : impl_->mesh.faces())
    for (auto v : CGAL::vertices_around_face(impl_->mesh.halfedge(f), impl_->mesh)) triangles->push_back(index[v.idx()]);
}

}  // namespace clothbench
