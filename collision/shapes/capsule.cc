// A solid capsule (docs/model.md §7): the points within `radius` of the
// segment from `a` to `b`, a limb of a body made of one capsule per bone.
// Its signed distance is the distance to the segment less the radius. Its
// surface, whose edges serve the virtual particles, is a cylinder of
// kSegments-gons between the two hemispheres' equators, each hemisphere
// kRings rings of latitude closed by a fan at its pole; every vertex lies
// on the capsule.
#include <algorithm>
#include <cmath>
#include <numbers>

#include "collision/shapes/obstacle_shape.h"

namespace clothbench {
namespace {

class Capsule final : public ObstacleShape {
 public:
  Capsule(const Vector3& a, const Vector3& b, double radius) : a_(a), b_(b), radius_(radius) {}
  std::string_view type() const override { return "capsule"; }
  double SignedDistance(const Vector3& p, Vector3* dir) const override {
    const Vector3 ab = b_ - a_;
    const double s = std::clamp((p - a_).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    const Vector3 r = p - (a_ + s * ab);
    const double len = r.norm();
    // On the axis (len 0) any direction normal to it is the closest one.
    *dir = len > 1e-15 ? Vector3(r / len) : Normal();
    return len - radius_;
  }
  Vector3 anchor() const override { return 0.5 * (a_ + b_); }
  void Surface(std::vector<Vector3>* vertices, std::vector<std::array<int, 3>>* triangles) const override {
    vertices->clear();
    triangles->clear();
    const Vector3 e = (b_ - a_).normalized(), u = Normal(), w = e.cross(u);
    std::vector<Vector3>& v = *vertices;
    // Ring k = 0 … 2 kRings − 1: the hemisphere at a from near its pole to
    // its equator, then the one at b from its equator to near its pole.
    for (int k = 0; k < 2 * kRings; ++k) {
      const bool at_a = k < kRings;
      const double theta = 0.5 * std::numbers::pi * (at_a ? k + 1 : 2 * kRings - k) / kRings;  // from the pole
      const Vector3 centre = (at_a ? a_ : b_) + (at_a ? -1.0 : 1.0) * radius_ * std::cos(theta) * e;
      for (int j = 0; j < kSegments; ++j) {
        const double phi = 2.0 * std::numbers::pi * j / kSegments;
        v.push_back(centre + radius_ * std::sin(theta) * (std::cos(phi) * u + std::sin(phi) * w));
      }
    }
    const int pole_a = static_cast<int>(v.size()), pole_b = pole_a + 1, last = (2 * kRings - 1) * kSegments;
    v.push_back(a_ - radius_ * e);
    v.push_back(b_ + radius_ * e);
    const Vector3 interior = anchor();
    for (int j = 0; j < kSegments; ++j) {
      const int next = (j + 1) % kSegments;
      AddOutwardTriangle(v, interior, pole_a, j, next, triangles);
      AddOutwardTriangle(v, interior, pole_b, last + j, last + next, triangles);
      for (int k = 0; k + 1 < 2 * kRings; ++k) {  // the quad between rings k and k + 1
        const int r0 = k * kSegments, r1 = r0 + kSegments;
        AddOutwardTriangle(v, interior, r0 + j, r1 + j, r1 + next, triangles);
        AddOutwardTriangle(v, interior, r0 + j, r1 + next, r0 + next, triangles);
      }
    }
  }

  /// Segments of a ring, rings of latitude of a hemisphere.
  static constexpr int kSegments = 32, kRings = 6;

 private:
  // A unit vector normal to the axis.
  Vector3 Normal() const {
    const Vector3 e = (b_ - a_).normalized();
    const Vector3 other = std::abs(e.x()) < 0.9 ? Vector3::UnitX() : Vector3::UnitY();
    return (other - other.dot(e) * e).normalized();
  }
  Vector3 a_, b_;
  double radius_;
};

}  // namespace

/// Keys: `a` and `b` (the segment's ends [m], at least 1e-6 m apart: a
/// single point is a sphere) and `radius` in [1e-6, 1e6] m.
std::shared_ptr<const ObstacleShape> ParseCapsule(ShapeKeys& keys) {
  const Vector3 a = keys.Centre("a"), b = keys.Centre("b");
  if (!((b - a).norm() >= 1e-6)) keys.Fail("b", "must be at least 1e-6 m from a (a single point is a sphere)");
  const double radius = keys.Range("radius", 0.0, 1e-6, 1e6, " m");
  return std::make_shared<const Capsule>(a, b, radius);
}

}  // namespace clothbench
