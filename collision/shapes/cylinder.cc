// A solid cylinder with axis z (docs/model.md §7): the centre of its top,
// its radius and its height below the top (a round table). Its edges for
// the virtual particles are the rims as kCircleSegments-gons and
// kCircleSegments vertical edges; its surface closes the rims by fans to
// their centres and the side by quads between the rims.
#include <cmath>
#include <numbers>

#include "collision/shapes/obstacle_shape.h"

namespace clothbench {
namespace {

class Cylinder final : public ObstacleShape {
 public:
  Cylinder(const Vector3& top, double radius, double height) : top_(top), radius_(radius), height_(height) {}
  std::string_view type() const override { return "cylinder"; }
  double SignedDistance(const Vector3& p, Vector3* dir) const override {
    // Top at top.z, bottom at top.z − height.
    const Vector3 r = p - top_;
    const double rho = std::hypot(r.x(), r.y());
    const Vector3 radial = rho > 1e-15 ? Vector3(r.x() / rho, r.y() / rho, 0.0) : Vector3::UnitX();
    const double dr = rho - radius_;                           // > 0 outside the mantle
    const double dz = std::max(r.z(), -height_ - r.z());       // > 0 above the top / below the bottom
    const bool top = r.z() > -0.5 * height_;
    const Vector3 axial = top ? Vector3::UnitZ() : Vector3(-Vector3::UnitZ());
    if (dr > 0.0 && dz > 0.0) {  // outside near a rim: distance to the rim circle
      const Vector3 d = dr * radial + dz * axial;
      const double dist = d.norm();
      *dir = d / dist;
      return dist;
    }
    if (dr > dz) {
      *dir = radial;
      return dr;
    }
    *dir = axial;
    return dz;
  }
  Vector3 anchor() const override { return top_; }
  void Edges(std::vector<Vector3>* vertices, std::vector<std::array<int, 2>>* edges) const override {
    vertices->clear();
    edges->clear();
    const auto circle = [&](const Vector3& centre) {  // a closed polygon in a z-plane
      const int first = static_cast<int>(vertices->size());
      for (int k = 0; k < kCircleSegments; ++k) {
        const double phi = 2.0 * std::numbers::pi * k / kCircleSegments;
        vertices->push_back(centre + radius_ * Vector3(std::cos(phi), std::sin(phi), 0.0));
        edges->push_back({first + k, first + (k + 1) % kCircleSegments});
      }
      return first;
    };
    const int top = circle(top_);
    const int bottom = circle(top_ - Vector3(0.0, 0.0, height_));
    for (int k = 0; k < kCircleSegments; ++k) edges->push_back({top + k, bottom + k});
  }
  void Surface(std::vector<Vector3>* vertices, std::vector<std::array<int, 3>>* triangles) const override {
    std::vector<std::array<int, 2>> edges;
    Edges(vertices, &edges);
    triangles->clear();
    std::vector<Vector3>& v = *vertices;
    const Vector3 interior = top_ - Vector3(0.0, 0.0, 0.5 * height_);
    const int m = kCircleSegments;
    const int top_centre = static_cast<int>(v.size()), bottom_centre = top_centre + 1;
    v.push_back(top_);
    v.push_back(top_ - Vector3(0.0, 0.0, height_));
    for (int k = 0; k < m; ++k) {
      const int next = (k + 1) % m;
      AddOutwardTriangle(v, interior, top_centre, k, next, triangles);
      AddOutwardTriangle(v, interior, bottom_centre, m + k, m + next, triangles);
      AddOutwardTriangle(v, interior, k, m + k, m + next, triangles);  // the side quad k, m+k, m+next, next
      AddOutwardTriangle(v, interior, k, m + next, next, triangles);
    }
  }

  /// Segments of a rim.
  static constexpr int kCircleSegments = 64;

 private:
  Vector3 top_;
  double radius_, height_;
};

}  // namespace

/// Keys: `center` (the centre of the top [m]), `radius` and `height` in
/// [1e-6, 1e6] m.
std::shared_ptr<const ObstacleShape> ParseCylinder(ShapeKeys& keys) {
  const Vector3 top = keys.Centre("center");
  const double radius = keys.Range("radius", 0.0, 1e-6, 1e6, " m");
  const double height = keys.Range("height", 0.0, 1e-6, 1e6, " m");
  return std::make_shared<const Cylinder>(top, radius, height);
}

}  // namespace clothbench
