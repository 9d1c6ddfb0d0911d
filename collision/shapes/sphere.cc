// A solid sphere (docs/model.md §7). Its edges for the virtual particles are
// a geodesic sphere's: the icosahedron's faces split kIcosphereLevels times
// into four (642 vertices, 1,920 edges, 1,280 triangles), whose centres lie
// at most 0.3 % of the radius inside the sphere (the thesis' ball had
// 1,227 edges). A latitude–longitude net would crowd its meridians at the
// pole, where a cloth dropped onto the ball lands.
#include <cmath>
#include <map>

#include "collision/shapes/obstacle_shape.h"

namespace clothbench {
namespace {

constexpr int kIcosphereLevels = 3;

// Counter-clockwise seen from outside.
void Icosphere(const Vector3& centre, double radius, std::vector<Vector3>* vertices,
               std::vector<std::array<int, 3>>* faces) {
  const double g = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Vector3> unit = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0}, {0, -1, g}, {0, 1, g},
                               {0, -1, -g}, {0, 1, -g}, {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
  for (Vector3& v : unit) v.normalize();
  std::vector<std::array<int, 3>> f = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9},  {5, 11, 4},
                                       {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4},  {3, 4, 2},   {3, 2, 6},  {3, 6, 8},
                                       {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (int level = 0; level < kIcosphereLevels; ++level) {
    std::map<std::pair<int, int>, int> middle;
    const auto mid = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      const auto [it, fresh] = middle.try_emplace(key, static_cast<int>(unit.size()));
      if (fresh) unit.push_back((unit[static_cast<std::size_t>(a)] + unit[static_cast<std::size_t>(b)]).normalized());
      return it->second;
    };
    std::vector<std::array<int, 3>> next;
    for (const auto& t : f) {
      const int ab = mid(t[0], t[1]), bc = mid(t[1], t[2]), ca = mid(t[2], t[0]);
      next.push_back({t[0], ab, ca});
      next.push_back({t[1], bc, ab});
      next.push_back({t[2], ca, bc});
      next.push_back({ab, bc, ca});
    }
    f.swap(next);
  }
  for (const Vector3& u : unit) vertices->push_back(centre + radius * u);
  faces->insert(faces->end(), f.begin(), f.end());
}

class Sphere final : public ObstacleShape {
 public:
  Sphere(const Vector3& centre, double radius) : centre_(centre), radius_(radius) {}
  std::string_view type() const override { return "sphere"; }
  double SignedDistance(const Vector3& p, Vector3* dir) const override {
    const Vector3 r = p - centre_;
    const double len = r.norm();
    *dir = len > 1e-15 ? Vector3(r / len) : Vector3::UnitZ();
    return len - radius_;
  }
  Vector3 anchor() const override { return centre_; }
  void Surface(std::vector<Vector3>* vertices, std::vector<std::array<int, 3>>* triangles) const override {
    vertices->clear();
    triangles->clear();
    Icosphere(centre_, radius_, vertices, triangles);
  }

 private:
  Vector3 centre_;
  double radius_;
};

}  // namespace

/// Keys: `center` [m], `radius` in [1e-6, 1e6] m (below 1e-6 m, the grid
/// spacing's floor, the polyhedron collapses to coinciding vertices).
std::shared_ptr<const ObstacleShape> ParseSphere(ShapeKeys& keys) {
  const Vector3 centre = keys.Centre("center");
  const double radius = keys.Range("radius", 0.0, 1e-6, 1e6, " m");
  return std::make_shared<const Sphere>(centre, radius);
}

}  // namespace clothbench
