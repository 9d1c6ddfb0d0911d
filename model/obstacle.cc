// Signed distances of the analytic obstacles (SPEC §7).
#include "model/obstacle.h"

#include "model/triangle_mesh.h"

#include <algorithm>
#include <cmath>

namespace clothbench {

std::string_view ToString(ObstacleType t) {
  switch (t) {
    case ObstacleType::kPlane: return "plane";
    case ObstacleType::kSphere: return "sphere";
    case ObstacleType::kBox: return "box";
    case ObstacleType::kCylinder: return "cylinder";
    case ObstacleType::kMesh: return "mesh";
  }
  return "?";
}

namespace {

// Signed distance of p to an axis-aligned box with half extents e at the
// origin, and the outward direction of the closest surface point.
double BoxDistance(const Vector3& p, const Vector3& e, Vector3* dir) {
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

}  // namespace

Obstacle::Obstacle(const ObstacleSpec& spec) : spec_(spec) {
  if (spec.type == ObstacleType::kMesh)
    mesh_ = std::make_shared<const TriangleMesh>(spec.path, spec.scale, spec.rotate, spec.translate);
}

double Obstacle::SignedDistance(const Vector3& p, Vector3* dir) const {
  const ObstacleSpec& s = spec_;
  switch (s.type) {
    case ObstacleType::kMesh:
      return mesh_->SignedDistance(p, dir);
    case ObstacleType::kPlane:
      *dir = s.normal;
      return (p - s.center).dot(s.normal);
    case ObstacleType::kSphere: {
      const Vector3 r = p - s.center;
      const double len = r.norm();
      *dir = len > 1e-15 ? Vector3(r / len) : Vector3::UnitZ();
      return len - s.radius;
    }
    case ObstacleType::kBox:
      return BoxDistance(p - s.center, 0.5 * s.size, dir);
    case ObstacleType::kCylinder: {
      // Solid cylinder, axis z, top at center.z, bottom at center.z − height.
      const Vector3 r = p - s.center;
      const double rho = std::hypot(r.x(), r.y());
      const Vector3 radial = rho > 1e-15 ? Vector3(r.x() / rho, r.y() / rho, 0.0) : Vector3::UnitX();
      const double dr = rho - s.radius;                           // > 0 outside the mantle
      const double dz = std::max(r.z(), -s.height - r.z());       // > 0 above the top / below the bottom
      const bool top = r.z() > -0.5 * s.height;
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
  }
  *dir = Vector3::UnitZ();
  return 1e300;
}

}  // namespace clothbench
