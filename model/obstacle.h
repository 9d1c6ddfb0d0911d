// Static analytic obstacles for collision response (SPEC §7, thesis ch. 4):
// plane, sphere, box and cylinder (a round table is a cylinder with a top).
// Each gives the signed distance of a point and the collision direction D
// (outward normal of the closest surface point).
#ifndef CLOTHBENCH_MODEL_OBSTACLE_H_
#define CLOTHBENCH_MODEL_OBSTACLE_H_

#include <memory>
#include <string>
#include <vector>

#include "model/types.h"

namespace clothbench {

enum class ObstacleType { kPlane, kSphere, kBox, kCylinder, kMesh };

class TriangleMesh;

/// An obstacle as written in a scene (`[[obstacle]]`).
struct ObstacleSpec {
  ObstacleType type = ObstacleType::kPlane;
  Vector3 center = Vector3::Zero();          ///< plane: a point on it; sphere/box: centre; cylinder: centre of the top
  Vector3 normal = Vector3::UnitZ();         ///< plane normal (unit)
  double radius = 0.0;                       ///< sphere, cylinder [m]
  Vector3 size = Vector3::Zero();            ///< box edge lengths [m] (axis-aligned)
  double height = 0.0;                       ///< cylinder height below its top [m] (axis z)
  double collision_distance = 0.01;          ///< δ, thickness of the collision area [m]
  double friction = 0.0;                     ///< Coulomb coefficient c_f (SPEC §2.5)
  double relaxation = 0.5;                   ///< ω_r in (4.4), 0 < ω_r ≤ 1
  // Triangle meshes (OFF/OBJ/PLY through CGAL): x ↦ R(scale·x) + translate.
  std::string path;                          ///< resolved mesh file
  double scale = 1.0;
  Vector3 rotate = Vector3::Zero();          ///< degrees about x, then y, then z
  Vector3 translate = Vector3::Zero();       ///< [m]
};

std::string_view ToString(ObstacleType t);

class Obstacle {
 public:
  /// Loads the mesh of a mesh obstacle. @throws std::runtime_error for an
  /// unreadable mesh file.
  explicit Obstacle(const ObstacleSpec& spec);
  /// Signed distance [m] of p to the surface (negative inside) and the unit
  /// outward direction D at the closest surface point.
  double SignedDistance(const Vector3& p, Vector3* direction) const;
  const ObstacleSpec& spec() const { return spec_; }

 private:
  ObstacleSpec spec_;
  std::shared_ptr<const TriangleMesh> mesh_;  // kMesh only (shared by copies)
};

}  // namespace clothbench

#endif  // CLOTHBENCH_MODEL_OBSTACLE_H_
