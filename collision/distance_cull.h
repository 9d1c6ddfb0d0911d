// The distance cull of mesh and skeleton obstacles (docs/model.md §7),
// which the detection (collision/obstacle_contacts.h), the position-based
// peers' adapter (collision/obstacle_proximity.h), the blow-up guard's
// path check (solver/run.h) and the SUNDIALS rows' root functions
// (sundials/hybrid_contact.h) share: a mesh obstacle's distance is
// 1-Lipschitz (signed for a closed mesh, unsigned for an open one), and so
// is a skeleton's (a minimum of capsules' distances), so with d_a measured
// at x_a and the obstacle's motion bound m since (Obstacle::MotionBound; a
// skeleton's: its joints' largest displacement), d(x) ≥ d_a − |x − x_a| − m.
// A caller skips the exact query where that bound already decides its test.
// The analytic shapes cost less to query than to cull.
#ifndef CLOTHBENCH_COLLISION_DISTANCE_CULL_H_
#define CLOTHBENCH_COLLISION_DISTANCE_CULL_H_

#include <cmath>
#include <cstddef>
#include <limits>
#include <vector>

#include "model/obstacle.h"
#include "model/types.h"

namespace clothbench {

class DistanceCull {
 public:
  /// Per particle and obstacle one anchor (none yet); every mesh and skeleton obstacle culled.
  /// @param obstacles the model's obstacles (must outlive this); @param n particles
  DistanceCull(const std::vector<Obstacle>& obstacles, std::size_t n) : obstacles_(&obstacles), n_(n) {
    const std::size_t n_obs = obstacles.size();
    for (const Obstacle& o : obstacles) culled_.push_back(Cullable(o));
    motion_.assign(n_obs, 0.0);
    for (const Obstacle& o : obstacles) last_pose_.push_back(o.PoseAt(0.0));
    anchor_.assign(n * n_obs, Vector3::Zero());
    distance_.assign(n * n_obs, -kNone);
    anchor_motion_.assign(n * n_obs, 0.0);
  }

  /// Forgets the anchors (a new run).
  void Reset() { std::fill(distance_.begin(), distance_.end(), -kNone); }
  /// Whether obstacle o's queries are culled: a mesh (still, keyframed or a
  /// sequence) or a deforming shape (a skeleton).
  static bool Cullable(const Obstacle& o) { return o.mesh() != nullptr || o.shape().deforms(); }
  /// Turns the cull of every cullable obstacle on or off (off: every query exact).
  void set_enabled(bool on) {
    for (std::size_t k = 0; k < culled_.size(); ++k) culled_[k] = on && Cullable((*obstacles_)[k]);
  }
  /// Whether obstacle k is culled.
  bool culls(std::size_t k) const { return culled_[k] != 0; }
  /// Adds obstacle k's motion bound from its last pose to `pose` (a moving mesh).
  void Advance(std::size_t k, const ObstaclePose& pose) {
    const Obstacle& o = (*obstacles_)[k];
    if (culled_[k] && o.moving()) {
      motion_[k] += o.MotionBound(last_pose_[k], pose);
      last_pose_[k] = pose;
    }
  }
  /// The lower bound of particle p's distance to obstacle k at x [m]
  /// (−∞ without an anchor).
  double Bound(std::size_t k, std::size_t p, const Vector3& x) const {
    const std::size_t at = k * n_ + p;
    return distance_[at] - (x - anchor_[at]).norm() - (motion_[k] - anchor_motion_[at]);
  }
  /// Makes particle p's exact distance d [m] at x [m] its anchor for obstacle k
  /// (if k is culled).
  void Record(std::size_t k, std::size_t p, const Vector3& x, double d) {
    if (!culled_[k]) return;
    const std::size_t at = k * n_ + p;
    anchor_[at] = x;
    distance_[at] = std::isfinite(d) ? d : -kNone;
    anchor_motion_[at] = motion_[k];
  }

 private:
  static constexpr double kNone = std::numeric_limits<double>::infinity();
  const std::vector<Obstacle>* obstacles_;
  std::size_t n_;
  std::vector<char> culled_;
  std::vector<double> motion_;  // per obstacle: the motion bound accumulated over the calls
  std::vector<ObstaclePose> last_pose_;
  // Per obstacle and particle: the point of the last exact query, its
  // distance (−∞: none) and the obstacle's accumulated motion bound then.
  std::vector<Vector3> anchor_;
  std::vector<double> distance_, anchor_motion_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_COLLISION_DISTANCE_CULL_H_
