// Collision response (docs/model.md §7; thesis (4.3), (4.4), §5.1, §2.5).
#include "solver/contact.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "solver/hermite.h"

namespace clothbench {
ContactResponse::ContactResponse(const ParticleSystem& system) : sys_(system), detection_(system) {
  const int n = system.num_particles();
  if (system.obstacles().empty()) return;
  contacts_.assign(static_cast<std::size_t>(n), Contact{});
  detected_.assign(static_cast<std::size_t>(n), ObstacleContact{});
  released_.assign(static_cast<std::size_t>(n), Vector3::Zero());
  frictionless_.assign(static_cast<std::size_t>(n), 0);
  rate_slip_.assign(static_cast<std::size_t>(n), 0.0);
  friction_.setZero(n, 3);
}

void ContactResponse::Reset() {
  for (Contact& c : contacts_) c = Contact{};
  for (Echo& e : echoes_)
    for (MatrixN3* m : {&e.holding, &e.pulling, &e.friction}) m->setZero();
  detection_.Reset();
  seconds_ = 0.0;
  h_ = h_read_ = 0.0;
  accepted_ = true;
  release_tolerance_ = 0.0;
  work_ = Work{};
}

// Collision response (docs/model.md §7; thesis (4.3), (4.4), §5.1). A particle
// is constrained along its collision direction D when ObstacleDetection
// (collision/obstacle_contacts.h) finds it in contact: in an obstacle's
// collision area, tunnelled through it in the last step, or predicted to
// enter it within the step. The target velocity is (4.4)
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
    detection_.Save();
    if (revises()) {
      std::fill(released_.begin(), released_.end(), Vector3::Zero());
      std::fill(frictionless_.begin(), frictionless_.end(), 0);
      std::fill(rate_slip_.begin(), rate_slip_.end(), 0.0);
    }
  } else {
    std::copy(contacts_backup_.begin(), contacts_backup_.end(), contacts_.begin());
    detection_.Restore();
  }
  accepted_ = false;
  Detect(t0, h, x_start, v_start, xm1);
  const int colliding = Respond(h, filter);
  seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return colliding;
}

int ContactResponse::SetUpAgain(VelocityFilter* filter) {
  const auto start = std::chrono::steady_clock::now();
  // The contacts as the step started; detection_ keeps what this step's
  // detection measured (Restore and Detect would measure it again).
  std::copy(contacts_backup_.begin(), contacts_backup_.end(), contacts_.begin());
  const int colliding = Respond(h_, filter);
  seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return colliding;
}

namespace {

// Coulomb friction's impulse μ J_N [N s] from the normal impulse J_N of
// the last step (docs/model.md §2.5), against the tangential velocity v_t
// [m/s] relative to the obstacle. With a slip velocity v_s > 0 [m/s]
// (FrictionLaw::kRegularised) it is scaled by min(1, |v_t|/v_s), the
// regularised Coulomb law.
double FrictionLimit(double normal_impulse, double speed, double slip_velocity) {
  if (speed < slip_velocity) normal_impulse *= speed / slip_velocity;
  return normal_impulse;
}

// The explicit friction force [N] of the impulse `limit` [N s] over a step
// of h [s] against v_t, capped at a|v_t| with a [kg] the mass that the cap
// stops (FrictionCap): friction can stop a sliding particle but not
// reverse it (uncapped, a round-off v_t of 1e-15 m/s got the full μ|f_N|
// and set resting cloth sliding at h μ g per step). *sticks: whether the
// cap holds (the particle's tangential velocity relative to the obstacle
// is stopped in the step).
Vector3 CappedFriction(double limit, double a, const Vector3& vt, double h, bool* sticks) {
  const double speed = vt.norm();
  *sticks = !(a * speed > limit);
  if (!(speed > 0.0)) return Vector3::Zero();
  const double impulse = std::min(limit, a * speed);
  return (-impulse / (h * speed)) * vt;
}

}  // namespace

void ContactResponse::CapFriction(int p, double a) {
  Contact& c = contacts_[static_cast<std::size_t>(p)];
  friction_.row(p) = CappedFriction(c.friction_limit, a, c.slip, h_, &c.sticks).transpose();
}

Vector3 ContactResponse::ReadHold(int p, const Vector3& r, const Vector3& from_start, double release_tolerance) {
  Contact& c = contacts_[static_cast<std::size_t>(p)];
  const Vector3 tangential = from_start - from_start.dot(c.direction) * c.direction;
  const double size = tangential.norm();
  const double mu = sys_.obstacles()[static_cast<std::size_t>(c.obstacle)].spec().friction;
  c.slides = size > mu * std::max(c.impulse, 0.0) + release_tolerance;
  c.hold_direction = size > 0.0 ? Vector3(tangential / size) : Vector3::Zero();
  return r - r.dot(c.direction) * c.direction;
}

void ContactResponse::KeepEchoes(int steps) {
  if (!active()) return;
  const int n = sys_.num_particles();
  echoes_.resize(static_cast<std::size_t>(std::clamp(steps, 1, 2)));
  for (Echo& e : echoes_)
    for (MatrixN3* m : {&e.holding, &e.pulling, &e.friction}) m->setZero(n, 3);
}

// The carry (docs/model.md §7, the contact work): a multistep step's
// momentum change is M(v₁ − v₀) = Σ_F I_F + d₁ M(v₀ − v₋₁) + d₂ M(v₋₁ − v₋₂)
// with I_F = βh F each force's share of the residual; by linearity each
// force's part of it is J_F = I_F + d₁ J_F,₋₁ + d₂ J_F,₋₂, and the J_F of
// all forces sum to M(v₁ − v₀).
void ContactResponse::AddWork(int p, StepImpulses* in, const Vector3& mean, const HistoryCarry& carry) {
  if (!echoes_.empty()) {
    Echo& last = echoes_[0];
    const bool two = echoes_.size() > 1;
    auto carried = [&](Vector3* j, MatrixN3 Echo::*kind) {
      *j += carry.d1 * (last.*kind).row(p).transpose();
      if (two && carry.d2 != 0.0) *j += carry.d2 * (echoes_[1].*kind).row(p).transpose();
      if (two) (echoes_[1].*kind).row(p) = (last.*kind).row(p);
      (last.*kind).row(p) = j->transpose();
    };
    carried(&in->holding, &Echo::holding);
    carried(&in->pulling, &Echo::pulling);
    carried(&in->friction, &Echo::friction);
  }
  work_.holding += in->holding.dot(mean);
  work_.pulling += in->pulling.dot(mean);
  work_.friction += in->friction.dot(mean);
}

void ContactResponse::SetImplicitFriction(const MatrixN3& v1) {
  if (!IsImplicit(friction_law_)) return;
  for (int p = 0; p < sys_.num_particles(); ++p) {
    const Contact& c = contacts_[static_cast<std::size_t>(p)];
    if (c.obstacle < 0 || !(c.friction_damping > 0.0)) continue;
    friction_.row(p) = -c.friction_damping * TangentialSlip(c, v1.row(p).transpose()).transpose();
  }
}

bool ContactResponse::LeavesCone(int p, const Vector3& v1, double relative_tolerance) {
  const Contact& c = contacts_[static_cast<std::size_t>(p)];
  const Vector3 slip = TangentialSlip(c, v1);
  const double speed = slip.norm();
  const double impulse = h_ * c.friction_damping * speed;
  if (friction_law_ == FrictionLaw::kImplicitIterated && speed > kStickVelocity &&
      impulse < c.friction_limit * (1.0 - relative_tolerance)) {
    rate_slip_[static_cast<std::size_t>(p)] = speed;  // still sliding, below μ J_N: the rate from this slip
    return true;
  }
  if (!(impulse > c.friction_limit * (1.0 + relative_tolerance))) return false;
  released_[static_cast<std::size_t>(p)] = -slip / speed;
  return true;
}

bool ContactResponse::StopPushingRelease(int p, const Vector3& v1) {
  const auto i = static_cast<std::size_t>(p);
  const Contact& c = contacts_[i];
  if (!(released_[i].squaredNorm() > 0.0) || frictionless_[i] || c.obstacle < 0) return false;
  if (!(friction_.row(p).dot(TangentialSlip(c, v1).transpose()) > 0.0)) return false;
  frictionless_[i] = 1;
  return true;
}

void ContactResponse::Detect(double t0, double h, const MatrixN3& x_start, const MatrixN3& v_start,
                             const MatrixN3* xm1) {
  detection_.BeginStep(t0);
  for (int p = 0; p < sys_.num_particles(); ++p) {
    ObstacleContact& contact = detected_[static_cast<std::size_t>(p)];
    if (sys_.is_fixed(p)) {
      contact.particle = -1;
      continue;
    }
    const Contact& c = contacts_[static_cast<std::size_t>(p)];
    // Release below −η‖S_F b‖ only (within the PCG's residual a holding
    // impulse is round-off), and not after a predicted entry (SetUp).
    const ObstacleDetection::Prior prior{c.obstacle, c.direction,
                                         c.obstacle >= 0 && !c.entry && c.impulse < -release_tolerance_};
    const Vector3 x0 = x_start.row(p).transpose(), v0 = v_start.row(p).transpose();
    Vector3 x_prev;
    if (xm1) x_prev = xm1->row(p).transpose();
    const bool found = detection_.Detect(p, h, x0, v0, xm1 ? &x_prev : nullptr, prior, event_tolerance_, &contact);
    contact.particle = found ? p : -1;
  }
}

int ContactResponse::Respond(double h, VelocityFilter* filter) {
  // The impulses read last are over the last accepted step, h_read_.
  const double impulse_scale = h_read_ > 0.0 && h_read_ != h ? h / h_read_ : 1.0;
  h_ = h;
  filter->Clear();
  for (int p : sys_.fixed()) filter->Fix(p);
  friction_.setZero();
  int count = 0;
  const auto& obstacles = sys_.obstacles();
  for (int p = 0; p < sys_.num_particles(); ++p) {
    Contact& c = contacts_[static_cast<std::size_t>(p)];
    if (sys_.is_fixed(p)) continue;
    const bool was = c.obstacle >= 0;
    // Released: the last stiction hold exceeded μ J_N, or in this step a
    // hold did or the implicit friction left its cone (ReviseHolds).
    const Vector3 released = released_[static_cast<std::size_t>(p)];
    const bool slide = (c.held && c.slides) || released.squaredNorm() > 0.0;
    const bool held_before = c.held;              // at rest on the obstacle at this step's start
    const bool was_held = c.held && !c.slides;  // and the last hold stayed within it
    const double slip_before = c.last_slip;
    c.last_slip = std::numeric_limits<double>::infinity();
    const double last_impulse = c.impulse;
    c.obstacle = -1;
    c.sticks = c.entry = c.held = c.slides = false;
    c.friction_limit = 0.0;
    c.friction_damping = 0.0;
    const ObstacleContact& contact = detected_[static_cast<std::size_t>(p)];
    if (contact.particle < 0) continue;
    const Obstacle& o = obstacles[static_cast<std::size_t>(contact.obstacle)];
    const Vector3& dir = contact.normal;
    c.obstacle = contact.obstacle;
    c.entry = !contact.inside;
    c.direction = dir;
    c.v_obstacle = contact.v_obstacle;
    // (4.4)'s target; under event location no correction, whose velocity
    // grows as 1/h (ApplyJumps instead).
    const double correction = event_tolerance_ > 0.0 ? 0.0 : o.spec().collision_distance - contact.distance;
    const double target_velocity =
        contact.v_obstacle.dot(dir) + (contact.inside ? o.spec().relaxation * correction : correction) / h;
    ++count;
    // Coulomb friction from the last step's normal impulse (FrictionLimit, CappedFriction).
    const double mu = o.spec().friction;
    // The last step's normal force J_hold/h₋₁ over this step: J_hold h/h₋₁.
    const double normal_impulse = impulse_scale == 1.0 ? last_impulse : last_impulse * impulse_scale;
    if (mu > 0.0 && was && last_impulse > 0.0) {
      c.slip = contact.v_rel - contact.v_rel.dot(dir) * dir;
      c.friction_limit = FrictionLimit(mu * normal_impulse, c.slip.norm(),
                                       friction_law_ == FrictionLaw::kRegularised ? kSlipVelocity : 0.0);
      const Vector3 along = released.squaredNorm() > 0.0 ? released : c.hold_direction;
      if (IsImplicit(friction_law_) && !(released.squaredNorm() > 0.0)) {
        // Coulomb's force at v₁ with its rate lagged (FrictionLaw::kImplicit):
        // −c_p (v₁ − u)_t in the solve, nothing explicit; once it left the
        // cone in this step (LeavesCone), μ J_N against the slip below.
        // FrictionLaw::kImplicitIterated: in a solve again, from the last
        // solve's slip of a contact that slid below μ J_N (LeavesCone).
        const double rate_slip = rate_slip_[static_cast<std::size_t>(p)];
        c.friction_damping = c.friction_limit / (h * std::max(rate_slip > 0.0 ? rate_slip : c.slip.norm(), kStickVelocity));
      } else if (slide && (held_before || IsImplicit(friction_law_) || along.dot(c.slip) < 0.0)) {
        // Stiction, after a hold beyond the cone that held it at rest or
        // against its slip, and the implicit friction beyond its cone: μ J_N
        // along the hold's impulse (against the solve's slip), which stops
        // less than the hold did.
        friction_.row(p) = (c.friction_limit / h) * along.transpose();
      } else {  // the thesis' capped friction against the slip (also after a hold that pushed along it)
        friction_.row(p) = CappedFriction(c.friction_limit, sys_.masses()(p), c.slip, h, &c.sticks).transpose();
        // Held again after a hold within μ J_N; from sliding, held once
        // friction could stop it, unless it slides faster than a step ago:
        // then the other forces outpull friction, and a hold would only be
        // released again.
        c.held = stiction_ && !slide && c.sticks && (was_held || c.slip.norm() <= slip_before);
      }
      c.last_slip = c.slip.norm();
    }
    if (frictionless_[static_cast<std::size_t>(p)]) friction_.row(p).setZero();
    if (c.held) {  // stiction: held at the obstacle's velocity, (4.4) along the normal
      friction_.row(p).setZero();
      const Vector3 tangential = contact.v_obstacle - contact.v_obstacle.dot(dir) * dir;
      filter->Fix(p, tangential + target_velocity * dir);
    } else {
      filter->Constrain(p, dir, target_velocity);  // (4.4)
    }
  }
  return count;
}

double ContactResponse::Crossing(double t0, double h, const MatrixN3& x0, const MatrixN3& v0, const MatrixN3& x1,
                                 const MatrixN3& v1) const {
  double theta = 1.0;
  for (int p = 0; p < sys_.num_particles(); ++p) {
    if (sys_.is_fixed(p) || contacts_[static_cast<std::size_t>(p)].obstacle >= 0) continue;
    const Vector3 a = x0.row(p).transpose(), b = x1.row(p).transpose();
    if (detection_.GapBound(p, a, b) >= -event_tolerance_) continue;
    double gap1 = 0.0, gap0 = 0.0;
    Vector3 n;
    if (detection_.Nearest(t0 + h, b, &gap1, &n) < 0 || gap1 >= -event_tolerance_) continue;
    detection_.Nearest(t0, a, &gap0, &n);
    if (!(gap0 > 0.0)) continue;  // started inside (released): not an entry
    const Vector3 va = v0.row(p).transpose(), vb = v1.row(p).transpose();
    double lo = 0.0, hi = 1.0;  // gap(lo) > 0 ≥ gap(hi)
    while (hi - lo > 1e-12) {
      const double mid = 0.5 * (lo + hi);
      double g = 0.0;
      const HermiteWeights w = HermitePositionWeights(mid, h);
      detection_.Nearest(t0 + mid * h, w.x0 * a + w.v0 * va + w.x1 * b + w.v1 * vb, &g, &n);
      (g > 0.0 ? lo : hi) = mid;
    }
    theta = std::min(theta, hi);
  }
  return theta;
}

int ContactResponse::ApplyJumps(double t, MatrixN3* x, MatrixN3* v) {
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
    if (!detection_.StartedOutside(p)) continue;
    double gap = 0.0;
    Vector3 n;
    const int k = detection_.Nearest(t, x1, &gap, &n);
    if (k < 0 || gap >= event_tolerance_) continue;
    const ObstaclePose pose = sys_.obstacles()[static_cast<std::size_t>(k)].PoseAt(t);
    const Obstacle& o = sys_.obstacles()[static_cast<std::size_t>(k)];
    // The velocity of the closest surface point, δ + gap behind x₁ along n.
    const Vector3 u = o.moving() ? pose.Velocity(x1 - (o.spec().collision_distance + gap) * n) : Vector3::Zero();
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
