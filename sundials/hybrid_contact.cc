// Obstacle contact in continuous time (sundials/hybrid_contact.h).
#include "sundials/hybrid_contact.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace clothbench::internal {

HybridContact::HybridContact(const ParticleSystem& system, double entry_depth)
    : sys_(system), entry_depth_(entry_depth), cull_(system.obstacles(), static_cast<std::size_t>(system.num_particles())) {
  const int n = system.num_particles();
  mode_.assign(static_cast<std::size_t>(n), -1);
  normal_.setZero(n, 3);
  f_work_.setZero(n, 3);
  friction_rate_.setZero(n);
  obstacle_reach_.assign(system.obstacles().size(), 0.0);
  no_roots_.assign(static_cast<std::size_t>(n), 0);
  lambda_queries_.resize(static_cast<std::size_t>(n));
}

double HybridContact::Distance(int k, double t, const Vector3& p, Vector3* n) const {
  return sys_.obstacles()[static_cast<std::size_t>(k)].SignedDistance(t, p, n);
}

int HybridContact::Nearest(double t, const Vector3& p, double* gap) const {
  int best = -1;
  *gap = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < sys_.obstacles().size(); ++k) {
    Vector3 n;
    const double g = Distance(static_cast<int>(k), t, p, &n) - sys_.obstacles()[k].spec().collision_distance;
    if (g < *gap) {
      *gap = g;
      best = static_cast<int>(k);
    }
  }
  return best;
}

double HybridContact::GapBound(int p, const Vector3& x) const {
  double gap = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < sys_.obstacles().size(); ++k) {
    if (!Culls(k)) return -std::numeric_limits<double>::infinity();
    gap = std::min(gap, cull_.Bound(k, static_cast<std::size_t>(p), x) - sys_.obstacles()[k].spec().collision_distance);
  }
  return gap;
}

double HybridContact::Lambda(int k, double t, int p, const Vector3& x, const Vector3& v, const Vector3& f, Vector3* n,
                             Vector3* w, double* distance) const {
  LambdaQueries& q = lambda_queries_[static_cast<std::size_t>(p)];
  if (!(q.k == k && q.t == t && q.x == x && q.v == v)) {
    q.k = -1;  // until it is complete
    const Obstacle& o = sys_.obstacles()[static_cast<std::size_t>(k)];
    q.d = Distance(k, t, x, &q.n);
    const ObstaclePose pose = o.PoseAfter(t);
    const Vector3 u = pose.Velocity(x - q.d * q.n);  // of the closest surface point
    q.w = v - u;
    // Rates along the particle's path by a forward difference: the normal's
    // (curvature and the obstacle's rotation) and the surface velocity's; by
    // a backward difference where a keyframe or frame time follows within
    // the step (the piecewise-linear motion's velocity jumps there: the rate
    // is the one of the motion's piece that holds t).
    const double e = o.SmoothBetween(t, t + kRateStep) ? kRateStep : -kRateStep;
    const Vector3 xe = x + e * v;
    Vector3 ne;
    const double de = Distance(k, t + e, xe, &ne);
    // A deforming mesh's vertex velocities are constant between its frames:
    // its surface velocity changes along the path only (measured against the
    // same rigid motion as keyframes, verify/mesh_sequence_test.cc: its state
    // at t + e, rebuilt from interpolated vertices, gave a turning sphere's
    // drape 2e-2 m off at rtol 1e-4, against 2e-4 m this way).
    const Vector3 ue = (o.shape().deforms() ? pose : o.PoseAt(t + e)).Velocity(xe - de * ne);
    const Vector3 n_rate = (ne - q.n) / e, a_u = (ue - u) / e;
    q.mc = sys_.masses()(p) * (q.n.dot(a_u) - n_rate.dot(q.w));
    q.k = k;
    q.t = t;
    q.x = x;
    q.v = v;
  }
  *n = q.n;
  *w = q.w;
  if (distance) *distance = q.d;
  return q.mc - n->dot(f);
}

void HybridContact::Initialize(double t, const MatrixN3& x, const MatrixN3& v) {
  event_times_.clear();
  mode_changes_ = 0;
  std::fill(mode_.begin(), mode_.end(), -1);
  cull_.Reset();  // a run's roots do not depend on an earlier run's
  for (LambdaQueries& q : lambda_queries_) q.k = -1;
  horizon_ = std::numeric_limits<double>::infinity();
  friction_rate_.setZero();
  if (!active()) return;
  sys_.Forces(t, x, v, &f_work_);
  for (int p = 0; p < sys_.num_particles(); ++p) {
    if (sys_.is_fixed(p)) continue;
    double gap = 0.0;
    const int k = Nearest(t, x.row(p).transpose(), &gap);
    if (k < 0 || gap > 1e-9) continue;
    Vector3 n, w;
    if (Lambda(k, t, p, x.row(p).transpose(), v.row(p).transpose(), f_work_.row(p).transpose(), &n, &w) >=
        -kReleaseAcceleration * sys_.masses()(p)) {
      mode_[static_cast<std::size_t>(p)] = k;
      normal_.row(p) = n.transpose();
    }
  }
}

int HybridContact::Reimpose(double t, MatrixN3* x, MatrixN3* v) const {
  int n_moved = 0;
  for (int p = 0; p < sys_.num_particles(); ++p) {
    const int k = mode_[static_cast<std::size_t>(p)];
    if (k < 0) continue;
    const Obstacle& o = sys_.obstacles()[static_cast<std::size_t>(k)];
    if (!o.moving()) continue;
    Vector3 n;
    const double delta = o.spec().collision_distance;
    const double d = Distance(k, t, x->row(p).transpose(), &n);
    x->row(p) -= (d - delta) * n.transpose();
    const Vector3 u = o.PoseAfter(t).Velocity(x->row(p).transpose() - delta * n);
    v->row(p) -= n.dot(v->row(p).transpose() - u) * n.transpose();
    ++n_moved;
  }
  return n_moved;
}

void HybridContact::OntoSurface(int k, double t, int p, double gap, const Vector3& n, MatrixN3* x,
                                MatrixN3* v) const {
  x->row(p) -= gap * n.transpose();
  const Obstacle& o = sys_.obstacles()[static_cast<std::size_t>(k)];
  const Vector3 u = o.PoseAfter(t).Velocity(x->row(p).transpose() - o.spec().collision_distance * n);  // at the surface
  const double wn = n.dot(v->row(p).transpose() - u);
  if (wn < 0.0) v->row(p) -= wn * n.transpose();
}

int HybridContact::Resettled(double t, MatrixN3* x, MatrixN3* v) {
  int n_moved = 0;
  for (int p = 0; p < sys_.num_particles(); ++p) {
    int& k = mode_[static_cast<std::size_t>(p)];
    if (k < 0) continue;
    Vector3 n;
    const double gap =
        Distance(k, t, x->row(p).transpose(), &n) - sys_.obstacles()[static_cast<std::size_t>(k)].spec().collision_distance;
    if (gap > entry_depth_) {  // moved off the surface: free
      k = -1;
      friction_rate_(p) = 0.0;
      ++mode_changes_;
      ++n_moved;
    } else if (gap < 0.0) {
      OntoSurface(k, t, p, gap, n, x, v);
      ++n_moved;
    }
  }
  return n_moved;
}

Vector3 HybridContact::Friction(int k, int p, double lambda, const Vector3& n, const Vector3& w) {
  const double cf = sys_.obstacles()[static_cast<std::size_t>(k)].spec().friction;
  friction_rate_(p) = 0.0;
  if (!(cf > 0.0 && lambda > 0.0)) return Vector3::Zero();
  const Vector3 wt = w - n.dot(w) * n;
  friction_rate_(p) = cf * lambda / std::max(wt.norm(), kSlipVelocity);
  return -friction_rate_(p) * wt;
}

void HybridContact::AddContactForces(double t, const MatrixN3& x, const MatrixN3& v, MatrixN3* f) {
  for (int p = 0; p < sys_.num_particles(); ++p) {
    const int k = mode_[static_cast<std::size_t>(p)];
    if (k < 0) continue;
    Vector3 n, w;
    const double lambda = Lambda(k, t, p, x.row(p).transpose(), v.row(p).transpose(), f->row(p).transpose(), &n, &w);
    normal_.row(p) = n.transpose();
    f->row(p) += (lambda * n + Friction(k, p, lambda, n, w)).transpose();
  }
}

void HybridContact::SplitExplicit(double t, const MatrixN3& x, const MatrixN3& v, MatrixN3* fe) const {
  for (int p = 0; p < sys_.num_particles(); ++p) {
    const int k = mode_[static_cast<std::size_t>(p)];
    if (k < 0) continue;
    Vector3 n, w;
    // λ with no force is m c, the constraint's normal acceleration times m.
    const double mc = Lambda(k, t, p, x.row(p).transpose(), v.row(p).transpose(), Vector3::Zero(), &n, &w);
    const Vector3 f = fe->row(p).transpose();
    fe->row(p) = (f - n.dot(f) * n + mc * n).transpose();
  }
}

void HybridContact::SplitImplicit(double t, const MatrixN3& x, const MatrixN3& v, const MatrixN3& fe,
                                  MatrixN3* fi) {
  for (int p = 0; p < sys_.num_particles(); ++p) {
    const int k = mode_[static_cast<std::size_t>(p)];
    if (k < 0) continue;
    Vector3 n, w;
    const Vector3 f = fi->row(p).transpose();
    const double lambda =
        Lambda(k, t, p, x.row(p).transpose(), v.row(p).transpose(), f + fe.row(p).transpose(), &n, &w);
    normal_.row(p) = n.transpose();
    fi->row(p) = (f - n.dot(f) * n + Friction(k, p, lambda, n, w)).transpose();
  }
}

bool HybridContact::any_sliding() const {
  return std::any_of(mode_.begin(), mode_.end(), [](int k) { return k >= 0; });
}

double HybridContact::FreeGap(double t, int p, const Vector3& x, double reach) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const auto up = static_cast<std::size_t>(p);
  double gap = kInf;
  for (std::size_t k = 0; k < sys_.obstacles().size(); ++k) {
    const Obstacle& o = sys_.obstacles()[k];
    const double delta = o.spec().collision_distance;
    const bool culls = reach < kInf && Culls(k);
    double d = culls ? cull_.Bound(k, up, x) : -kInf;
    if (culls && d - delta > kCullMargin * delta + reach + obstacle_reach_[k]) {
      ++culled_;
    } else {
      Vector3 n;
      d = Distance(static_cast<int>(k), t, x, &n);
      cull_.Record(k, up, x, d);
    }
    gap = std::min(gap, d - delta);
  }
  return gap;
}

void HybridContact::Roots(double t, const MatrixN3& x, const MatrixN3& v, const MatrixN3& f, double* g) {
  bool cull = false;  // any obstacle culled, and a finite horizon
  for (std::size_t k = 0; k < sys_.obstacles().size(); ++k) {
    if (!Culls(k)) continue;
    cull = true;
    const Obstacle& o = sys_.obstacles()[k];
    if (o.moving()) cull_.Advance(k, o.PoseAt(t));  // every call
    // Any evaluation paired with this one is within H of t, before or after.
    if (horizon_ < std::numeric_limits<double>::infinity())
      obstacle_reach_[k] = horizon_ * o.MaxVertexSpeedBetween(t - horizon_, t + horizon_);
  }
  cull = cull && horizon_ < std::numeric_limits<double>::infinity();
  for (int p = 0; p < sys_.num_particles(); ++p) {
    if (sys_.is_fixed(p)) {
      g[p] = 1.0;
      continue;
    }
    const int k = mode_[static_cast<std::size_t>(p)];
    if (k < 0) {
      const double h = horizon_;
      const double reach = cull ? 2.0 * (v.row(p).norm() * h + 0.5 * f.row(p).norm() / sys_.masses()(p) * h * h)
                                : std::numeric_limits<double>::infinity();
      g[p] = FreeGap(t, p, x.row(p).transpose(), reach) + entry_depth_;
    } else {
      Vector3 n, w;
      const double m = sys_.masses()(p);
      double d = 0.0;
      const double pushes =
          Lambda(k, t, p, x.row(p).transpose(), v.row(p).transpose(), f.row(p).transpose(), &n, &w, &d) +
          kReleaseAcceleration * m;
      // A particle held on the δ-surface of a moving obstacle whose velocity
      // jumped (a keyframe or frame time: no rate carries the jump) drifts
      // off it; a drift past another δ releases it. Far below that this
      // root is 1e6 times the release threshold, so the force decides.
      const double delta = sys_.obstacles()[static_cast<std::size_t>(k)].spec().collision_distance;
      const double gap = d - delta;
      g[p] = std::min(pushes, kReleaseAcceleration * m * (1.0 + 1e6 * (delta - gap) / delta));
    }
  }
}

}  // namespace clothbench::internal
