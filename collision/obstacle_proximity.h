// The position-based peers' adapter to the obstacles (docs/notes/collisions.md,
// "Detection and the contact list"): the particles of a set of positions
// inside an obstacle's collision area, as entries of the contact list
// (collision/contact_list.h). XPBD reads it every substep, projective
// dynamics after its iterations; they project the entries' positions onto
// the constraint C = d(p) − δ ≥ 0 (peers/position_contacts.h).
//
// The detection's distance cull (collision/distance_cull.h) makes a
// substep's query cheap: a particle whose lower bound d_a − |p − x_a| − m is
// at least δ is not in the area and is skipped without a query. The cull is exact: the entries
// are those of querying every particle, bit for bit.
#ifndef CLOTHBENCH_COLLISION_OBSTACLE_PROXIMITY_H_
#define CLOTHBENCH_COLLISION_OBSTACLE_PROXIMITY_H_

#include <vector>

#include "collision/contact_list.h"
#include "collision/distance_cull.h"
#include "model/particle_system.h"

namespace clothbench {

class ObstacleProximity {
 public:
  /// Allocates the per-particle state of the mesh obstacles (nothing without
  /// obstacles). @param system the model (must outlive this)
  explicit ObstacleProximity(const ParticleSystem& system);

  /// Forgets the measured distances (a new run); the counters restart.
  void Reset();

  /// Obstacle k's entries at positions p: every particle i with w_i ≠ 0 and
  /// d(p_i) < δ_k at the obstacle's pose at t, or d(p_i) < 0 where
  /// held[i] ≠ 0 (another response holds it), in increasing i. An entry's
  /// normal is the distance's direction D (away from the obstacle) and its
  /// distance d, both at p_i; v_obstacle is 0 and inside true.
  /// The queries run in parallel (OpenMP); the list is the same for any
  /// thread count. No allocation once the list has reached its size.
  /// @param k obstacle index into ParticleSystem::obstacles()
  /// @param pose its pose at t (Obstacle::PoseAt)
  /// @param p N×3 positions [m]
  /// @param w N inverse masses [1/kg]; 0: fixed, never an entry
  /// @param held N flags or nullptr (none held)
  /// @return the entries, valid until the next call
  const std::vector<ObstacleContact>& Find(int k, const ObstaclePose& pose, const MatrixN3& p,
                                           const Eigen::VectorXd& w, const std::vector<char>* held);

  /// Obstacle::PenetrationOf of obstacle k at `pose` for the N×3 positions
  /// x [m] (the deepest particle inside, the depths and the particles within
  /// δ/2), with the same cull: a particle whose bound is at least δ/2 adds
  /// nothing and is not queried. Bit for bit Obstacle::PenetrationOf's
  /// result. Calls for a sequence of states (frames) keep their anchors.
  Penetration PenetrationOf(int k, const ObstaclePose& pose, const MatrixN3& x);

  /// Exact signed-distance queries made and skipped by the cull since Reset.
  long queries() const { return queries_; }
  long culled() const { return culled_; }
  /// Turns the distance cull off (every query exact; for the test that the
  /// cull changes no entry).
  void set_distance_cull(bool on);

 private:
  const ParticleSystem& sys_;
  // Particle i's signed distance at q [m] (its direction into direction_[i]),
  // or +∞ without a query where its bound exceeds skip_above (−∞: never).
  double Query(const Obstacle& o, std::size_t k, int i, const ObstaclePose& pose, const Vector3& q, double skip_above,
               long* queries, long* culled);

  std::vector<ObstacleContact> found_;
  std::vector<char> hit_;  // per particle: an entry of this call
  std::vector<double> distance_;
  std::vector<Vector3> direction_;
  DistanceCull cull_;  // mesh and skeleton obstacles
  long queries_ = 0, culled_ = 0;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_COLLISION_OBSTACLE_PROXIMITY_H_
