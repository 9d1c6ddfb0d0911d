// The entries of a step's contact list (docs/notes/collisions.md): what the
// detections of collision/ produce and the responses read. Obstacle
// contacts come from ObstacleDetection (collision/obstacle_contacts.h), one
// per particle in contact; self-contact pairs from SelfContactDetector
// (collision/self_contact.h).
#ifndef CLOTHBENCH_COLLISION_CONTACT_LIST_H_
#define CLOTHBENCH_COLLISION_CONTACT_LIST_H_

#include <array>

#include "model/types.h"

namespace clothbench {

/// A particle against an obstacle at the start of a step: the nearest of
/// the obstacles it is in contact with (docs/model.md §7: in the collision
/// area, tunnelled through it in the last step, or predicted to enter it
/// within the step).
struct ObstacleContact {
  int particle = -1;
  int obstacle = -1;                   ///< index into ParticleSystem::obstacles()
  Vector3 normal = Vector3::Zero();    ///< collision direction D (unit), away from the obstacle
  double distance = 0.0;               ///< d [m]: signed distance along D at x₀ (negative: inside)
  Vector3 v_obstacle = Vector3::Zero();  ///< the obstacle's velocity at x₀ [m/s] (0 if it is static)
  Vector3 v_rel = Vector3::Zero();     ///< the particle's velocity relative to it [m/s]
  bool inside = false;                 ///< in the area (or tunnelled); false: a predicted entry
};

/// One pair of cloth elements that share no particle. kPointTriangle:
/// p = {point, a, b, c}; kEdgeEdge: p = {a, b, c, d}, the edges a–b and c–d.
struct SelfContactPair {
  enum Kind : int { kPointTriangle = 0, kEdgeEdge = 1 };
  Kind kind = kPointTriangle;
  std::array<int, 4> p{};
  friend bool operator<(const SelfContactPair& l, const SelfContactPair& r) {
    return l.kind != r.kind ? l.kind < r.kind : l.p < r.p;
  }
  friend bool operator==(const SelfContactPair& l, const SelfContactPair& r) { return l.kind == r.kind && l.p == r.p; }
};

}  // namespace clothbench

#endif  // CLOTHBENCH_COLLISION_CONTACT_LIST_H_
