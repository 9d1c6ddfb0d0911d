// Contact detection against the obstacles (collision/obstacle_contacts.h;
// docs/model.md §7).
#include "collision/obstacle_contacts.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace clothbench {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// The old→new cast of the detection's test 2: a particle whose segment
// x₋₁ → x₀ may cross the obstacle (possible only if d(x₋₁) + d(x₀) ≤
// |x₀ − x₋₁|; for a moving obstacle d(x₋₁) is re-measured at the current
// pose, as the stored `d_old` is at the old pose, where the bound does not
// hold) and whose first crossing leaves x₀ within δ of the surface has
// tunnelled: *d and *d_k become that side's distance and normal. A crossing
// back toward the remembered side (`last_direction` of a contact with the
// same obstacle, or nullptr) is a return, not a tunnel.
bool Tunnelled(const Obstacle& o, const ObstaclePose& pose, const Vector3& x_prev, const Vector3& x0, double d_old,
               double delta, const Vector3* last_direction, double* d, Vector3* d_k) {
  Vector3 unused;
  const double d_prev = o.moving() ? o.SignedDistance(pose, x_prev, &unused) : d_old;
  if (!(d_prev >= 0.0 && (*d < 0.0 || d_prev + *d <= (x0 - x_prev).norm()))) return false;
  const auto hit = o.FirstHit(pose, x_prev, x0);
  if (!hit || (last_direction && hit->normal.dot(*last_direction) < 0.0)) return false;
  const double side = (x0 - hit->point).dot(hit->normal);
  if (!(side < delta)) return false;
  *d = side;
  *d_k = hit->normal;
  return true;
}

}  // namespace

ObstacleDetection::ObstacleDetection(const ParticleSystem& system)
    : sys_(system), cull_(system.obstacles(), static_cast<std::size_t>(system.num_particles())) {
  const std::size_t n = static_cast<std::size_t>(system.num_particles()), n_obs = system.obstacles().size();
  if (n_obs == 0) return;
  poses_.resize(n_obs);
  last_distance_.assign(n * n_obs, 1e300);
}

void ObstacleDetection::Reset() {
  has_step_ = has_prev_ = false;
  std::fill(last_distance_.begin(), last_distance_.end(), 1e300);
  cull_.Reset();
  queries_ = culled_ = 0;
}

void ObstacleDetection::Save() { distance_backup_.assign(last_distance_.begin(), last_distance_.end()); }

void ObstacleDetection::Restore() { std::copy(distance_backup_.begin(), distance_backup_.end(), last_distance_.begin()); }

void ObstacleDetection::set_distance_cull(bool on) { cull_.set_enabled(on); }

void ObstacleDetection::BeginStep(double t0) {
  const auto& obstacles = sys_.obstacles();
  // A new step (not a retry of this one): this step's poses become the previous ones.
  if (has_step_ && t0 != step_t0_) {
    std::swap(prev_poses_, poses_);
    poses_.resize(prev_poses_.size());
    prev_t0_ = step_t0_;
    has_prev_ = true;
  }
  step_t0_ = t0;
  has_step_ = true;
  for (std::size_t k = 0; k < obstacles.size(); ++k) {
    poses_[k] = obstacles[k].PoseAt(t0);
    cull_.Advance(k, poses_[k]);
  }
}

bool ObstacleDetection::Detect(int p, double h, const Vector3& x0, const Vector3& v0, const Vector3* x_prev,
                               const Prior& prior, double event_tolerance, ObstacleContact* contact) {
  const auto& obstacles = sys_.obstacles();
  const std::size_t n_obs = obstacles.size();
  const bool was = prior.obstacle >= 0;
  double best = 1e300;
  bool found = false;
  for (std::size_t k = 0; k < n_obs; ++k) {
    const Obstacle& o = obstacles[k];
    const ObstaclePose& pose = poses_[k];
    const double delta = o.spec().collision_distance;
    const bool same_contact = was && static_cast<int>(k) == prior.obstacle;
    const std::size_t pk = static_cast<std::size_t>(p) * n_obs + k;
    double& d_stored = last_distance_[pk];
    // The relative speed bounds the cull: a rigid motion's velocity at x₀,
    // a deforming shape's largest vertex speed within the step (its
    // velocity at x₀ would cost the closest-point query the cull saves).
    // The contact takes the velocity at the closest surface point once the
    // distance is known.
    Vector3 v_obs = o.moving() && !pose.deformed ? pose.Velocity(x0) : Vector3::Zero();
    Vector3 v_rel = v0 - v_obs;
    const double rel_speed = pose.deformed ? v0.norm() + o.MaxVertexSpeedBetween(step_t0_, step_t0_ + h) : v_rel.norm();
    if (cull_.culls(k) && !same_contact) {
      const double bound = cull_.Bound(k, static_cast<std::size_t>(p), x0);
      const double moved = x_prev ? (x0 - *x_prev).norm() : 0.0;
      if (bound > std::max(delta + h * rel_speed, moved)) {
        d_stored = bound;
        ++culled_;
        continue;
      }
    }
    Vector3 d_k;
    double d = o.SignedDistance(pose, x0, &d_k);
    ++queries_;
    cull_.Record(k, static_cast<std::size_t>(p), x0, d);
    // Side memory: a particle in contact that now finds the obstacle's
    // direction turned against its contact direction has crossed a thin or
    // open part (an open mesh's distance is unsigned): it is behind the
    // surface, d < 0, on the side it came from.
    if (same_contact && d_k.dot(prior.direction) < 0.0) {
      d = -d;
      d_k = -d_k;
    }
    const double d_old = d_stored;  // at x₋₁ (+inf after Reset)
    d_stored = d;
    if (prior.released) continue;
    if (o.moving() && std::abs(d) < kInf) {  // the surface point's velocity (docs/model.md §7)
      v_obs = pose.Velocity(x0 - d * d_k);
      v_rel = v0 - v_obs;
    }
    // 2. Old→new cast (Tunnelled).
    // Continuous detection against a moving obstacle: x₋₁ where its motion
    // carried it since the previous step's start, so the cast follows the
    // path relative to the obstacle (a particle it swept past is on it).
    const Vector3 from = x_prev && has_prev_ && o.moving() && o.spec().continuous
                             ? o.Carried(prev_poses_[k], pose, *x_prev, step_t0_ - prev_t0_)
                             : (x_prev ? *x_prev : x0);
    const bool tunnelled = x_prev && d_old < 1e300 &&
                           Tunnelled(o, pose, from, x0, d_old, delta, same_contact ? &prior.direction : nullptr,
                                     &d, &d_k);
    // 1. Proximity, with hysteresis: a contact that still pushed is kept
    // while d < 2δ. A multistep method's history carries a resting particle
    // slightly past the border, and dropping it there makes the sheet fall
    // and re-enter (measured: BDF(2) released all 400 particles of a flat
    // cloth every 7 steps).
    const bool kept = same_contact && d < 2.0 * delta;
    const bool inside = d < delta || kept || tunnelled;
    // 3. Predicted entry.
    bool entering = d + h * v_rel.dot(d_k) < delta;
    if (!inside && !entering && d <= h * v_rel.norm() + delta) {
      if (const auto hit = o.FirstHit(pose, x0, x0 + h * v_rel)) {
        d_k = hit->normal;
        d = (x0 - hit->point).dot(hit->normal);
        entering = true;
      }
    }
    // Event location: an entry further than ε is an event of the step, not a contact.
    if (event_tolerance > 0.0 && !inside && d - delta > event_tolerance) entering = false;
    if ((inside || entering) && d < best) {
      best = d;
      found = true;
      *contact = ObstacleContact{p, static_cast<int>(k), d_k, d, v_obs, v_rel, inside};
    }
  }
  return found;
}

int ObstacleDetection::Nearest(double t, const Vector3& x, double* gap, Vector3* normal) const {
  int best = -1;
  *gap = kInf;
  for (std::size_t k = 0; k < sys_.obstacles().size(); ++k) {
    const Obstacle& o = sys_.obstacles()[k];
    Vector3 n;
    const double g = o.SignedDistance(t, x, &n) - o.spec().collision_distance;
    if (g < *gap) {
      *gap = g;
      *normal = n;
      best = static_cast<int>(k);
    }
  }
  return best;
}

double ObstacleDetection::GapBound(int p, const Vector3& x0, const Vector3& x1) const {
  const std::size_t n_obs = sys_.obstacles().size();
  const double moved = (x1 - x0).norm();
  double bound = kInf;
  for (std::size_t k = 0; k < n_obs; ++k) {
    const Obstacle& o = sys_.obstacles()[k];
    if (o.moving()) return -kInf;
    const double d = last_distance_[static_cast<std::size_t>(p) * n_obs + k];
    bound = std::min(bound, d - moved - o.spec().collision_distance);
  }
  return bound;
}

bool ObstacleDetection::StartedOutside(int p) const {
  const std::size_t n_obs = sys_.obstacles().size();
  bool outside = true;
  for (std::size_t k = 0; k < n_obs; ++k)
    outside = outside &&
              last_distance_[static_cast<std::size_t>(p) * n_obs + k] > sys_.obstacles()[k].spec().collision_distance;
  return outside;
}

}  // namespace clothbench
