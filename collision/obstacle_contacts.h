// Contact detection against the obstacles (docs/model.md §7; thesis §4.2,
// (4.3)): per particle, the nearest obstacle it is in contact with at the
// start of a step, as an entry of the contact list (collision/contact_list.h).
// The response (solver/contact.h: the velocity filter's constraints, (4.4)'s
// target, friction, release) reads the list and tells the detection what it
// kept of the last step (ObstacleDetection::Prior).
#ifndef CLOTHBENCH_COLLISION_OBSTACLE_CONTACTS_H_
#define CLOTHBENCH_COLLISION_OBSTACLE_CONTACTS_H_

#include <vector>

#include "collision/contact_list.h"
#include "collision/distance_cull.h"
#include "model/particle_system.h"

namespace clothbench {

/// The detection of docs/model.md §7 against every obstacle of a particle
/// system. A particle is in contact with an obstacle at its pose at t₀
/// (signed distance d, collision distance δ, relative velocity v_rel =
/// v₀ − v_obs) when:
///   1. it is in the collision area, d < δ (D the closest-point
///      direction), or was in contact with it, still pushed and is within 2δ;
///   2. the last step's segment x₋₁ → x₀ entered the obstacle (old→new ray
///      cast): D is the entered face's normal and d the signed distance to
///      its plane, so a particle that crossed a thin or open part goes back
///      to the side it came from; a particle in contact also remembers its
///      side (D is flipped if it turns against the last contact direction);
///   3. it is predicted to enter the area within the step: d + h⟨v_rel, D⟩
///      < δ (exact for convex obstacles, whose d is convex along the path)
///      or, failing that, the segment x₀ → x₀ + h v_rel enters the obstacle
///      (a cast, for non-convex meshes).
/// The contact is the one of least d. Casts run only where the distance
/// bound allows a hit (d is 1-Lipschitz). The same bound culls a mesh
/// obstacle's exact distance query: with d_a measured at x_a, d(x₀) ≥ d_a −
/// |x₀ − x_a| − m, m the obstacle's motion bound since
/// (Obstacle::MotionBound), and a particle not in contact with it whose
/// bound exceeds both δ + h|v_rel| and |x₀ − x₋₁| passes none of the tests
/// (1: d ≥ δ; 2: a crossing needs d ≤ |x₀ − x₋₁|; 3: d + h⟨v_rel, D⟩ ≥ δ and
/// d > h|v_rel| + δ), so it is skipped and the bound stored as its distance.
class ObstacleDetection {
 public:
  /// Allocates the per-particle and per-obstacle state (nothing without obstacles).
  explicit ObstacleDetection(const ParticleSystem& system);

  /// Forgets the distances of the last step (a new run); the query counters restart.
  void Reset();
  /// Keeps the distances of the state an attempt starts from (Save), or
  /// goes back to them (Restore: a rejected attempt). No allocation after the first Save.
  void Save();
  void Restore();

  /// The obstacles' poses at t₀ [s] for this step's Detect, and the mesh
  /// obstacles' motion bounds since the last step.
  void BeginStep(double t0);

  /// What the response kept of particle p's last contact.
  struct Prior {
    int obstacle = -1;                   ///< −1: none
    Vector3 direction = Vector3::Zero(); ///< its collision direction
    /// Released by the response (its holding impulse pulled): no contact
    /// this step, but the distances are still measured.
    bool released = false;
  };
  /// Particle p's contact at the start of a step of h [s] (after BeginStep):
  /// @param x0, v0 its position [m] and velocity [m/s] at t₀
  /// @param x_prev its position one step earlier [m], or nullptr without history
  /// @param event_tolerance ε [m] of event location (0: off): an entry
  ///   further than ε is an event of the step, not a contact
  /// @return true and *contact set if it is in contact
  bool Detect(int p, double h, const Vector3& x0, const Vector3& v0, const Vector3* x_prev, const Prior& prior,
              double event_tolerance, ObstacleContact* contact);

  /// The nearest obstacle to x [m] at t [s]: its index (−1: none), the gap
  /// d − δ [m] and the normal.
  int Nearest(double t, const Vector3& x, double* gap, Vector3* normal) const;
  /// A lower bound of particle p's gap d − δ [m] at x1 from this step's
  /// distances at x0 (static obstacles: d is 1-Lipschitz); −∞ where an
  /// obstacle moves.
  double GapBound(int p, const Vector3& x0, const Vector3& x1) const;
  /// Whether particle p started this step outside every collision area
  /// (its distances at x₀, or their lower bounds, above δ).
  bool StartedOutside(int p) const;

  /// Exact signed-distance queries made and skipped by the cull since Reset.
  long queries() const { return queries_; }
  long culled() const { return culled_; }
  /// Turns the distance cull off (every query exact; for the test that the
  /// cull changes no contact).
  void set_distance_cull(bool on);

 private:
  const ParticleSystem& sys_;
  std::vector<ObstaclePose> poses_;    // of each obstacle at t₀ (per step)
  // Of each moving obstacle at the previous step's t₀, where x₋₁ was: the
  // old→new cast follows the path relative to it (ObstacleSpec::continuous).
  std::vector<ObstaclePose> prev_poses_;
  double step_t0_ = 0.0, prev_t0_ = 0.0;
  bool has_step_ = false, has_prev_ = false;
  std::vector<double> last_distance_;  // N×O: signed distance at x₀ of the last step (x₋₁ now), or a lower bound
  std::vector<double> distance_backup_;
  DistanceCull cull_;  // mesh and skeleton obstacles
  long queries_ = 0, culled_ = 0;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_COLLISION_OBSTACLE_CONTACTS_H_
