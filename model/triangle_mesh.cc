// CGAL-backed triangle-mesh distance queries.
#include "model/triangle_mesh.h"

#include <cmath>
#include <stdexcept>

#include <CGAL/AABB_face_graph_triangle_primitive.h>
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/boost/graph/IO/polygon_mesh_io.h>
#include <CGAL/Polygon_mesh_processing/compute_normal.h>
#include <CGAL/Side_of_triangle_mesh.h>
#include <CGAL/Surface_mesh.h>
#include <Eigen/Geometry>
#include <fmt/format.h>

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

TriangleMesh::TriangleMesh(const std::string& path, double scale, const Vector3& rotate_deg, const Vector3& translate)
    : impl_(std::make_unique<Impl>()) {
  if (!CGAL::IO::read_polygon_mesh(path, impl_->mesh) || impl_->mesh.number_of_faces() == 0)
    throw std::runtime_error(fmt::format("cannot read a polygon mesh from \"{}\"", path));
  if (!CGAL::is_triangle_mesh(impl_->mesh))
    throw std::runtime_error(fmt::format("\"{}\" is not a triangle mesh", path));
  const double d2r = M_PI / 180.0;
  const Eigen::Matrix3d rot = (Eigen::AngleAxisd(rotate_deg.z() * d2r, Vector3::UnitZ()) *
                               Eigen::AngleAxisd(rotate_deg.y() * d2r, Vector3::UnitY()) *
                               Eigen::AngleAxisd(rotate_deg.x() * d2r, Vector3::UnitX()))
                                  .toRotationMatrix();
  for (auto v : impl_->mesh.vertices()) {
    const Point& p = impl_->mesh.point(v);
    const Vector3 q = rot * (scale * Vector3(p.x(), p.y(), p.z())) + translate;
    impl_->mesh.point(v) = Point(q.x(), q.y(), q.z());
  }
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

int TriangleMesh::num_vertices() const { return static_cast<int>(impl_->mesh.number_of_vertices()); }
int TriangleMesh::num_faces() const { return static_cast<int>(impl_->mesh.number_of_faces()); }
bool TriangleMesh::closed() const { return impl_->closed; }

}  // namespace clothbench
