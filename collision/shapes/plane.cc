// An infinite plane: a point on it and its unit normal (docs/model.md §7).
// The cloth's side is where the normal points; it has no edges for the
// virtual particles.
#include "collision/shapes/obstacle_shape.h"

namespace clothbench {
namespace {

class Plane final : public ObstacleShape {
 public:
  Plane(const Vector3& point, const Vector3& normal) : point_(point), normal_(normal) {}
  std::string_view type() const override { return "plane"; }
  double SignedDistance(const Vector3& p, Vector3* dir) const override {
    *dir = normal_;
    return (p - point_).dot(normal_);
  }
  Vector3 anchor() const override { return point_; }
  bool has_edges() const override { return false; }
  void Edges(std::vector<Vector3>* vertices, std::vector<std::array<int, 2>>* edges) const override {
    vertices->clear();
    edges->clear();
  }
  void Surface(std::vector<Vector3>* vertices, std::vector<std::array<int, 3>>* triangles) const override {
    vertices->clear();
    triangles->clear();
  }

 private:
  Vector3 point_, normal_;
};

}  // namespace

/// Keys: `center` (a point on the plane [m]), `normal` (non-zero; normalised).
std::shared_ptr<const ObstacleShape> ParsePlane(ShapeKeys& keys) {
  const Vector3 point = keys.Centre("center");
  Vector3 normal = keys.Vec3("normal", Vector3::UnitZ());
  if (normal.norm() < 1e-12) keys.Fail("normal", "must be a non-zero vector");
  normal.normalize();
  return std::make_shared<const Plane>(point, normal);
}

}  // namespace clothbench
