// Collision response (docs/model.md §7; thesis (4.3), (4.4), §5.1, §2.5).
#include "solver/contact.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "solver/hermite.h"

namespace clothbench {
namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
}  // namespace

ContactResponse::ContactResponse(const ParticleSystem& system) : sys_(system) {
  const int n = system.num_particles();
  if (system.obstacles().empty()) return;
  contacts_.assign(static_cast<std::size_t>(n), Contact{});
  poses_.resize(system.obstacles().size());
  last_distance_.assign(static_cast<std::size_t>(n) * system.obstacles().size(), 1e300);
  friction_.setZero(n, 3);
  const std::size_t n_obs = system.obstacles().size();
  for (const Obstacle& o : system.obstacles()) cullable_.push_back(o.mesh() != nullptr);
  cull_anchor_.assign(static_cast<std::size_t>(n) * n_obs, Vector3::Zero());
  cull_distance_.assign(static_cast<std::size_t>(n) * n_obs, -kInf);
  cull_motion_.assign(static_cast<std::size_t>(n) * n_obs, 0.0);
  motion_.assign(n_obs, 0.0);
  last_pose_.resize(n_obs);
  for (std::size_t k = 0; k < n_obs; ++k) last_pose_[k] = system.obstacles()[k].PoseAt(0.0);
}

void ContactResponse::Reset() {
  for (Contact& c : contacts_) c = Contact{};
  std::fill(last_distance_.begin(), last_distance_.end(), 1e300);
  std::fill(cull_distance_.begin(), cull_distance_.end(), -kInf);
  queries_ = culled_ = 0;
  seconds_ = 0.0;
  h_ = h_read_ = 0.0;
  accepted_ = true;
  release_tolerance_ = 0.0;
  work_ = Work{};
}

// Collision response (docs/model.md §7; thesis (4.3), (4.4), §5.1). A particle is
// constrained along a collision direction D when, against some obstacle at
// its pose at t₀ (signed distance d, obstacle velocity v_obs at x₀,
// relative velocity v_rel = v₀ − v_obs):
//   1. it is in the collision area, d < δ (proximity; D = closest-point
//      direction), or was in contact, still pushed and is within 2δ;
//   2. the last step's segment x₋₁ → x₀ entered the obstacle (old→new ray
//      cast): D is the normal of the entered face and d the signed distance
//      to its plane, so a particle that crossed a thin or open part is sent
//      back to the side it came from, not on to the nearest face; a particle
//      in contact also remembers its side (D is flipped if it turns against
//      the last contact direction);
//   3. it is predicted to enter the area within the step: d + h⟨v_rel, D⟩ < δ
//      (exact for convex obstacles, whose d is convex along the path: the
//      linear estimate is a lower bound) or, failing that, the segment
//      x₀ → x₀ + h v_rel enters the obstacle (a cast, for non-convex meshes).
// Segment casts run only where the distance bound allows a hit (d is
// 1-Lipschitz). The same bound culls a mesh obstacle's exact distance
// query: with d_a measured at x_a, d(x₀) ≥ d_a − |x₀ − x_a| − m, m the
// obstacle's motion bound since (Obstacle::MotionBound), and a particle not
// in contact with it whose bound exceeds both δ + h|v_rel| and |x₀ − x₋₁|
// passes none of the tests below (1: d ≥ δ; 2: a crossing needs
// d ≤ |x₀ − x₋₁|; 3: d + h⟨v_rel, D⟩ ≥ δ and d > h|v_rel| + δ), so it is
// skipped and the bound stored as its distance (a lower one only makes the
// cast of the next step's test 2 likelier). The target velocity is (4.4)
// with the obstacle's motion:
//   ⟨v₁, D⟩ = ⟨v_obs, D⟩ + ω_r (δ − d)/h  (in the area),
//   ⟨v₁, D⟩ = ⟨v_obs, D⟩ + (δ − d)/h      (predicted entry),
// for every method: the relative normal velocity is replaced, so contact is
// inelastic. (A target that instead made each method's position formula
// x₁ = x̂ + γ h v₁ land on the border gives ⟨v₁,D⟩ = 2(δ−d)/h − ⟨v₀,D⟩ for
// implicit midpoint: it bounces with its impact speed every step, is
// released and falls through a plane — measured before this choice.)
// Positions are never projected and constraints switch only here, between
// steps, so SBDF(2) and BDF(2) stay consistent. A particle whose holding
// impulse pulled it toward the obstacle in the last step is released,
// unless that contact was a predicted entry (test 3): its pull only says
// that the particle slowed by itself before the border the target aimed it
// at, and it now lies in the area, moving in. Released, a multistep
// method's history carries it on inward unconstrained (BDF(2) moves
// x₁ − x₀ = (x₀ − x₋₁)/3 + 2h v₁/3; measured 1.3δ past the border on the
// swinging box at h = 0.02 s). Kept, the area's target (4.4) holds it, and
// a pull then releases it a step later.
int ContactResponse::SetUp(double t0, double h, const MatrixN3& x_start, const MatrixN3& v_start, const MatrixN3* xm1,
                           VelocityFilter* filter) {
  const auto start = std::chrono::steady_clock::now();
  // Copies into storage of the same size: no allocation after the first.
  if (accepted_) {
    contacts_backup_.assign(contacts_.begin(), contacts_.end());
    distance_backup_.assign(last_distance_.begin(), last_distance_.end());
  } else {
    std::copy(contacts_backup_.begin(), contacts_backup_.end(), contacts_.begin());
    std::copy(distance_backup_.begin(), distance_backup_.end(), last_distance_.begin());
  }
  accepted_ = false;
  const int colliding = Detect(t0, h, x_start, v_start, xm1, filter);
  seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return colliding;
}

namespace {

// The old→new cast of the detection's step 2 (ContactResponse::Detect): a
// particle whose segment x₋₁ → x₀ may cross the obstacle (possible only if
// d(x₋₁) + d(x₀) ≤ |x₀ − x₋₁|; for a moving obstacle d(x₋₁) is re-measured
// at the current pose, as the stored `d_old` is at the old pose, where the
// bound does not hold) and whose first crossing leaves x₀ within δ of the
// surface has tunnelled: *d and *d_k become that side's distance and
// normal. A crossing back toward the remembered side (`last_direction` of a
// contact with the same obstacle, or nullptr) is a return, not a tunnel.
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

// Coulomb friction's force [N] on a particle of mass m [kg] in contact
// along `dir`, from the normal impulse `normal_impulse` = μ J_N [N s] of the
// last step (docs/model.md §2.5), explicit, against the tangential part of
// the velocity v_rel relative to the obstacle [m/s]. Its impulse is capped at
// m|v_t|: friction can stop a sliding particle but never reverse it
// (uncapped, a round-off v_t of 1e-15 m/s got the full μ|f_N| and set
// resting cloth sliding at h μ g per step).
// With a slip velocity v_s > 0 [m/s] (FrictionLaw::kRegularised) the
// impulse is scaled by min(1, |v_t|/v_s), the regularised Coulomb law.
// *sticks: whether the cap holds (the particle's tangential velocity
// relative to the obstacle is stopped in the step).
Vector3 CoulombFriction(double normal_impulse, double m, const Vector3& v_rel, const Vector3& dir, double h,
                        double slip_velocity, bool* sticks) {
  const Vector3 vt = v_rel - v_rel.dot(dir) * dir;
  const double speed = vt.norm();
  if (speed < slip_velocity) normal_impulse *= speed / slip_velocity;
  *sticks = !(m * speed > normal_impulse);
  if (!(speed > 0.0)) return Vector3::Zero();
  const double impulse = std::min(normal_impulse, m * speed);
  return (-impulse / (h * speed)) * vt;
}

}  // namespace

int ContactResponse::Detect(double t0, double h, const MatrixN3& x_start, const MatrixN3& v_start, const MatrixN3* xm1,
                            VelocityFilter* filter) {
  const bool have_history = xm1 != nullptr;
  // The impulses read last are over the last accepted step, h_read_.
  const double impulse_scale = h_read_ > 0.0 && h_read_ != h ? h / h_read_ : 1.0;
  h_ = h;
  filter->Clear();
  for (int p : sys_.fixed()) filter->Fix(p);
  friction_.setZero();
  int count = 0;
  const auto& obstacles = sys_.obstacles();
  const std::size_t n_obs = obstacles.size();
  for (std::size_t k = 0; k < n_obs; ++k) {
    poses_[k] = obstacles[k].PoseAt(t0);
    if (cullable_[k] && obstacles[k].moving()) {
      motion_[k] += obstacles[k].MotionBound(last_pose_[k], poses_[k]);
      last_pose_[k] = poses_[k];
    }
  }
  for (int p = 0; p < sys_.num_particles(); ++p) {
    Contact& c = contacts_[static_cast<std::size_t>(p)];
    if (sys_.is_fixed(p)) continue;
    const bool was = c.obstacle >= 0;
    // Release below −η‖S_F b‖ only (within the PCG's residual a holding
    // impulse is round-off), and not after a predicted entry (SetUp).
    const bool released = was && !c.entry && c.impulse < -release_tolerance_;
    const double last_impulse = c.impulse;
    const int last_obstacle = c.obstacle;
    const Vector3 last_direction = c.direction;
    c.obstacle = -1;
    c.sticks = c.entry = false;
    const Vector3 x0 = x_start.row(p).transpose(), v0 = v_start.row(p).transpose();
    double best = 1e300, target_velocity = 0.0;
    Vector3 dir = Vector3::Zero(), best_v_rel = Vector3::Zero();
    for (std::size_t k = 0; k < n_obs; ++k) {
      const Obstacle& o = obstacles[k];
      const ObstaclePose& pose = poses_[k];
      const double delta = o.spec().collision_distance;
      const bool same_contact = was && static_cast<int>(k) == last_obstacle;
      const std::size_t pk = static_cast<std::size_t>(p) * n_obs + k;
      double& d_stored = last_distance_[pk];
      const Vector3 v_obs = o.moving() ? pose.Velocity(x0) : Vector3::Zero();
      const Vector3 v_rel = v0 - v_obs;
      if (cullable_[k] && !same_contact) {
        const double bound =
            cull_distance_[pk] - (x0 - cull_anchor_[pk]).norm() - (motion_[k] - cull_motion_[pk]);
        const double moved = have_history ? (x0 - xm1->row(p).transpose()).norm() : 0.0;
        if (bound > std::max(delta + h * v_rel.norm(), moved)) {
          d_stored = bound;
          ++culled_;
          continue;
        }
      }
      Vector3 d_k;
      double d = o.SignedDistance(pose, x0, &d_k);
      ++queries_;
      if (cullable_[k]) {
        cull_anchor_[pk] = x0;
        cull_distance_[pk] = std::isfinite(d) ? d : -kInf;
        cull_motion_[pk] = motion_[k];
      }
      // Side memory: a particle in contact that now finds the obstacle's
      // direction turned against its contact direction has crossed a thin or
      // open part (an open mesh's distance is unsigned): it is behind the
      // surface, d < 0, on the side it came from.
      if (same_contact && d_k.dot(last_direction) < 0.0) {
        d = -d;
        d_k = -d_k;
      }
      const double d_old = d_stored;  // at x₋₁ (+inf after Reset)
      d_stored = d;
      if (released) continue;
      // 2. Old→new cast (Tunnelled).
      const bool tunnelled = have_history && d_old < 1e300 &&
                             Tunnelled(o, pose, xm1->row(p).transpose(), x0, d_old, delta,
                                       same_contact ? &last_direction : nullptr, &d, &d_k);
      // 1. Proximity, with hysteresis: a contact that still pushed
      // (J_hold ≥ 0) is kept while d < 2δ. A multistep method's history
      // carries a resting particle slightly past the border, and dropping it
      // there makes the sheet fall and re-enter (measured: BDF(2) released
      // all 400 particles of a flat cloth every 7 steps).
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
      // Event location: an entry further than ε is an event of the step
      // (Crossing), not a constraint of it.
      if (event_tolerance_ > 0.0 && !inside && d - delta > event_tolerance_) entering = false;
      if ((inside || entering) && d < best) {
        best = d;
        c.entry = !inside;
        dir = d_k;
        best_v_rel = v_rel;
        c.obstacle = static_cast<int>(k);
        // Event location: no (4.4) correction, whose velocity grows as 1/h (ApplyJumps instead).
        const double correction = event_tolerance_ > 0.0 ? 0.0 : delta - d;
        target_velocity = v_obs.dot(d_k) + (inside ? o.spec().relaxation * correction : correction) / h;
      }
    }
    if (c.obstacle < 0) continue;
    c.direction = dir;
    filter->Constrain(p, dir, target_velocity);  // (4.4)
    // Coulomb friction from the last step's normal impulse (CoulombFriction).
    const double mu = obstacles[static_cast<std::size_t>(c.obstacle)].spec().friction;
    // The last step's normal force J_hold/h₋₁ over this step: J_hold h/h₋₁.
    const double normal_impulse = impulse_scale == 1.0 ? last_impulse : last_impulse * impulse_scale;
    if (mu > 0.0 && was && last_impulse > 0.0)
      friction_.row(p) = CoulombFriction(mu * normal_impulse, sys_.masses()(p), best_v_rel, dir, h,
                                         friction_law_ == FrictionLaw::kRegularised ? kSlipVelocity : 0.0, &c.sticks)
                             .transpose();
    ++count;
  }
  return count;
}

int ContactResponse::NearestObstacle(double t, const Vector3& x, double* gap, Vector3* normal) const {
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

// The lower bound of the gap d − δ of particle p at x1 from the setup's
// distances at x0 (static obstacles: d is 1-Lipschitz); −∞ where an
// obstacle moves.
double ContactResponse::GapBound(int p, const Vector3& x0, const Vector3& x1) const {
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

double ContactResponse::Crossing(double t0, double h, const MatrixN3& x0, const MatrixN3& v0, const MatrixN3& x1,
                                 const MatrixN3& v1) const {
  double theta = 1.0;
  for (int p = 0; p < sys_.num_particles(); ++p) {
    if (sys_.is_fixed(p) || contacts_[static_cast<std::size_t>(p)].obstacle >= 0) continue;
    const Vector3 a = x0.row(p).transpose(), b = x1.row(p).transpose();
    if (GapBound(p, a, b) >= -event_tolerance_) continue;
    double gap1 = 0.0, gap0 = 0.0;
    Vector3 n;
    if (NearestObstacle(t0 + h, b, &gap1, &n) < 0 || gap1 >= -event_tolerance_) continue;
    NearestObstacle(t0, a, &gap0, &n);
    if (!(gap0 > 0.0)) continue;  // started inside (released): not an entry
    const Vector3 va = v0.row(p).transpose(), vb = v1.row(p).transpose();
    double lo = 0.0, hi = 1.0;  // gap(lo) > 0 ≥ gap(hi)
    while (hi - lo > 1e-12) {
      const double mid = 0.5 * (lo + hi);
      double g = 0.0;
      const HermiteWeights w = HermitePositionWeights(mid, h);
      NearestObstacle(t0 + mid * h, w.x0 * a + w.v0 * va + w.x1 * b + w.v1 * vb, &g, &n);
      (g > 0.0 ? lo : hi) = mid;
    }
    theta = std::min(theta, hi);
  }
  return theta;
}

int ContactResponse::ApplyJumps(double t, MatrixN3* x, MatrixN3* v) {
  const std::size_t n_obs = sys_.obstacles().size();
  int jumps = 0;
  double work = 0.0;
  for (int p = 0; p < sys_.num_particles(); ++p) {
    Contact& c = contacts_[static_cast<std::size_t>(p)];
    if (sys_.is_fixed(p)) continue;
    const Vector3 x1 = x->row(p).transpose();
    if (c.obstacle >= 0) {
      // A contact drifted off the δ-surface by more than ε: back onto it.
      const Obstacle& o = sys_.obstacles()[static_cast<std::size_t>(c.obstacle)];
      Vector3 n;
      const double gap = o.SignedDistance(t, x1, &n) - o.spec().collision_distance;
      if (std::abs(gap) > event_tolerance_ && n.dot(c.direction) > 0.0) {
        x->row(p) -= gap * n.transpose();
        ++jumps;
      }
      continue;
    }
    // Started outside: d at x₀ (or its lower bound) − δ > 0 against every obstacle.
    bool outside = true;
    for (std::size_t k = 0; k < n_obs; ++k)
      outside = outside && last_distance_[static_cast<std::size_t>(p) * n_obs + k] >
                               sys_.obstacles()[k].spec().collision_distance;
    if (!outside) continue;
    double gap = 0.0;
    Vector3 n;
    const int k = NearestObstacle(t, x1, &gap, &n);
    if (k < 0 || gap >= event_tolerance_) continue;
    const ObstaclePose pose = sys_.obstacles()[static_cast<std::size_t>(k)].PoseAt(t);
    const Vector3 u = sys_.obstacles()[static_cast<std::size_t>(k)].moving() ? pose.Velocity(x1) : Vector3::Zero();
    const double wn = n.dot(v->row(p).transpose() - u);
    if (gap >= 0.0 && wn >= 0.0) continue;  // near, but leaving
    x->row(p) -= gap * n.transpose();  // onto the δ-surface
    if (wn < 0.0) {
      // The impulse −m wₙ n over the mean velocity: −m wₙ (wₙ/2 + ⟨u, n⟩).
      const double m = sys_.masses()(p);
      work += -m * wn * (0.5 * wn + u.dot(n));
      v->row(p) -= wn * n.transpose();
    }
    c.obstacle = k;
    c.direction = n;
    c.impulse = 0.0;
    ++jumps;
  }
  work_.holding += work;
  return jumps;
}

}  // namespace clothbench
