// A solid axis-aligned box (docs/model.md §7): its centre and edge lengths.
// Its 12 edges carry the virtual particles; its surface is 6 faces as 12
// triangles.
#include <algorithm>

#include "collision/shapes/obstacle_shape.h"

namespace clothbench {
namespace {

class Box final : public ObstacleShape {
 public:
  Box(const Vector3& centre, const Vector3& size) : centre_(centre), size_(size) {}
  std::string_view type() const override { return "box"; }
  // Signed distance to the box with half extents e at the centre, and the
  // outward direction of the closest surface point.
  double SignedDistance(const Vector3& point, Vector3* dir) const override {
    const Vector3 p = point - centre_, e = 0.5 * size_;
    const Vector3 q = p.cwiseAbs() - e;
    if (q.maxCoeff() > 0.0) {  // outside: direction to the closest point
      const Vector3 outside = q.cwiseMax(0.0);
      Vector3 d = outside.cwiseProduct(p.cwiseSign());
      const double dist = d.norm();
      *dir = d / dist;
      return dist;
    }
    int k = 0;  // inside: leave through the nearest face
    q.maxCoeff(&k);
    *dir = Vector3::Zero();
    (*dir)(k) = p(k) >= 0.0 ? 1.0 : -1.0;
    return q(k);
  }
  Vector3 anchor() const override { return centre_; }
  void Edges(std::vector<Vector3>* vertices, std::vector<std::array<int, 2>>* edges) const override {
    vertices->clear();
    edges->clear();
    const Vector3 half = 0.5 * size_;
    for (int k = 0; k < 8; ++k)
      vertices->push_back(centre_ + Vector3((k & 1) ? half.x() : -half.x(), (k & 2) ? half.y() : -half.y(),
                                            (k & 4) ? half.z() : -half.z()));
    for (int k = 0; k < 8; ++k)  // the corners that differ in one coordinate
      for (int bit : {1, 2, 4})
        if (!(k & bit)) edges->push_back({k, k | bit});
  }
  void Surface(std::vector<Vector3>* vertices, std::vector<std::array<int, 3>>* triangles) const override {
    std::vector<std::array<int, 2>> edges;
    Edges(vertices, &edges);
    triangles->clear();
    // The corners with bit `axis` equal to `side`, in cyclic order.
    for (int axis : {1, 2, 4})
      for (int side : {0, 1}) {
        const int o1 = axis == 1 ? 2 : 1, o2 = axis == 4 ? 2 : 4, base = side ? axis : 0;
        AddOutwardTriangle(*vertices, centre_, base, base | o1, base | o1 | o2, triangles);
        AddOutwardTriangle(*vertices, centre_, base, base | o1 | o2, base | o2, triangles);
      }
  }

 private:
  Vector3 centre_, size_;
};

}  // namespace

/// Keys: `center` [m], `size` (3 edge lengths in [1e-6, 1e6] m).
std::shared_ptr<const ObstacleShape> ParseBox(ShapeKeys& keys) {
  const Vector3 centre = keys.Centre("center");
  const auto size = keys.Numbers3("size", {0.0, 0.0, 0.0}, true);
  if (!(std::min({size[0], size[1], size[2]}) >= 1e-6) || std::max({size[0], size[1], size[2]}) > 1e6)
    keys.Fail("size", "must be 3 edge lengths in [1e-6, 1e6] m");
  return std::make_shared<const Box>(centre, Vector3(size[0], size[1], size[2]));
}

}  // namespace clothbench
