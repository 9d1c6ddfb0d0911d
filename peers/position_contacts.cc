// Obstacle contacts on positions (Macklin et al. 2014, Eq. 24–25; docs/model.md §10).
#include "peers/position_contacts.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <stdexcept>

#include "collision/edge_projection.h"

namespace clothbench {

int ProjectOntoObstacles(const ParticleSystem& sys, ObstacleProximity* proximity, const Eigen::VectorXd& w,
                         double t_end, double dt, const MatrixN3& x, MatrixN3* p, const std::vector<char>* held) {
  int colliding = 0;
  const auto& obstacles = sys.obstacles();
  for (std::size_t k = 0; k < obstacles.size(); ++k) {
    const Obstacle& o = obstacles[k];
    const ObstaclePose pose = o.PoseAt(t_end);
    const double delta = o.spec().collision_distance, mu = o.spec().friction;
    for (const ObstacleContact& c : proximity->Find(static_cast<int>(k), pose, *p, w, held)) {
      ++colliding;
      const Vector3& dir = c.normal;
      const double depth = delta - c.distance;
      Vector3 q = p->row(c.particle).transpose() + depth * dir;
      if (mu > 0.0) {
        Vector3 rel = q - x.row(c.particle).transpose();
        if (o.moving()) rel -= pose.Velocity(q - delta * dir) * dt;  // of the surface point below q
        const Vector3 tangential = rel - rel.dot(dir) * dir;
        const double len = tangential.norm();
        if (len < mu * depth)
          q -= tangential;
        else
          q -= tangential * (mu * depth / len);
      }
      p->row(c.particle) = q.transpose();
    }
  }
  return colliding;
}

namespace {
using Clock = std::chrono::steady_clock;
double Since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }
}  // namespace

PositionSelfContact::PositionSelfContact(const ParticleSystem& system, double thickness, const Eigen::VectorXd& w)
    : thickness_(thickness),
      skin_(kSkinFraction * std::min(system.scene().lu(), system.scene().lv())),
      list_(GridSelfContactList(system)),
      w_(w) {
  if (!(thickness > 0.0)) throw std::invalid_argument("PositionSelfContact: thickness must be > 0");
  const int n = system.num_particles();
  for (MatrixN3* m : {&x_det_, &x_end_, &path_}) m->setZero(n, 3);
  moved_.assign(static_cast<std::size_t>(n), 0);
  reach_.assign(static_cast<std::size_t>(n), 0.0);
  step_motion_.assign(static_cast<std::size_t>(n), 0.0);
}

double PositionSelfContact::PairMotion(const SelfContactPair& pair) const {
  const std::size_t first = pair.kind == SelfContactPair::kPointTriangle ? 1 : 2;
  double a = 0.0, b = 0.0;
  for (std::size_t k = 0; k < 4; ++k) {
    const double m = step_motion_[static_cast<std::size_t>(pair.p[k])];
    if (k < first)
      a = std::max(a, m);
    else
      b = std::max(b, m);
  }
  return a + b;
}

void PositionSelfContact::Detect(const MatrixN3& x_det, const MatrixN3& x_end, double tau) {
  const auto start = Clock::now();
  x_det_ = x_det;
  x_end_ = x_end;
  tau_det_ = tau;
  std::fill(reach_.begin(), reach_.end(), 0.0);
  // Every pair that can come within the thickness while each particle
  // stays within the skin (per coordinate, √3 skin in length) of the
  // straight path x_det → x_end: those within δ + 2√3 skin along the path
  // (the list kept over steps, collision/self_contact_list.h).
  const double reach = thickness_ + 2.0 * std::sqrt(3.0) * skin_;
  if (list_.Cover(x_det_, x_end_, reach)) {
    ++stats_.broad_phases;
    stats_.candidates += static_cast<long>(list_.size());
  }
  by_distance_.clear();
  for (std::size_t i = 0; i < list_.size(); ++i)
    if (list_.LowerBound(i) <= reach) by_distance_.push_back({Closest(list_.pairs()[i], x_det_).distance, list_.pairs()[i]});
  std::sort(by_distance_.begin(), by_distance_.end());
  stats_.detection_seconds += Since(start);
}

void PositionSelfContact::BeginStep(double h, const MatrixN3& x0, const MatrixN3& v0) {
  ++stats_.steps;
  path_.noalias() = x0 + h * v0;
  Detect(x0, path_, 0.0);
}

int PositionSelfContact::Project(const MatrixN3& x, double tau0, double tau1, MatrixN3* p) {
  // Where the detection's straight path is at tau1; a particle further
  // than the skin from it (per coordinate) may meet a pair the list lacks:
  // the broad phase again, from the substep's start along its motion.
  path_ = x_det_ + ((tau1 - tau_det_) / (1.0 - tau_det_)) * (x_end_ - x_det_);
  if ((*p - path_).cwiseAbs().maxCoeff() > skin_) {
    path_ = x + ((1.0 - tau0) / (tau1 - tau0)) * (*p - x);
    Detect(x, path_, tau0);
  }
  const auto start = Clock::now();
  // Each particle's largest displacement since the detection, less the
  // mean, over the substeps so far: a pair's distance has fallen by at most
  // the largest of its first element's plus the largest of its second's.
  path_ = *p - x_det_;
  const Vector3 c = path_.colwise().mean().transpose();
  const int n = static_cast<int>(reach_.size());
  double most = 0.0;
  for (int q = 0; q < n; ++q) {
    reach_[static_cast<std::size_t>(q)] =
        std::max(reach_[static_cast<std::size_t>(q)], (path_.row(q) - c.transpose()).norm());
    most = std::max(most, reach_[static_cast<std::size_t>(q)]);
  }
  const double limit = thickness_ + 2.0 * most;
  // Each particle's motion in the substep.
  for (int q = 0; q < n; ++q) step_motion_[static_cast<std::size_t>(q)] = (p->row(q) - x.row(q)).norm();
  // The pairs in reach, each with its normal at the substep's start: a pair
  // that crossed in the substep is pushed back to it. A later pass tests
  // only the pairs with a particle that the pass before or this one moved.
  std::size_t active = 0;
  while (active < by_distance_.size() && by_distance_[active].first < limit) ++active;
  start_normal_.resize(active);
  in_reach_.resize(active);
  int projected = 0;
  for (int pass = 0; pass < kPasses; ++pass) {
    for (int q : moved_list_) moved_[static_cast<std::size_t>(q)] = 2;  // moved in the pass before
    int this_pass = 0;
    for (std::size_t i = 0; i < active; ++i) {
      const SelfContactPair& pair = by_distance_[i].second;
      if (pass == 0) {
        const std::size_t first = pair.kind == SelfContactPair::kPointTriangle ? 1 : 2;
        double a = 0.0, b = 0.0;
        for (std::size_t k = 0; k < 4; ++k) (k < first ? a : b) = std::max(k < first ? a : b, reach_[static_cast<std::size_t>(pair.p[k])]);
        in_reach_[i] = by_distance_[i].first - (a + b) < thickness_;
        if (!in_reach_[i]) continue;
        start_normal_[i].setZero();  // computed where first needed
      } else if (!in_reach_[i] || !std::any_of(pair.p.begin(), pair.p.end(), [&](int q) {
                   return moved_[static_cast<std::size_t>(q)] != 0;
                 })) {
        continue;
      }
      // Apart by more than the thickness, and by more than the pair's
      // relative motion in the substep (so it did not cross): no projection.
      // The boxes' distance bounds the elements' (Ericson 2005, §5.1.3).
      if (ElementBoxGap(pair, *p) >= std::max(thickness_, PairMotion(pair))) continue;
      const PairGeometry g = Closest(pair, *p);
      if (start_normal_[i].isZero(0.0)) start_normal_[i] = Closest(pair, x).n;
      const double side = g.n.dot(start_normal_[i]) >= 0.0 ? 1.0 : -1.0;
      if (side * g.distance >= (pass == 0 ? 1.0 : kSlop) * thickness_) continue;
      double denom = 0.0;
      for (std::size_t k = 0; k < 4; ++k) denom += g.w[k] * g.w[k] * w_(pair.p[k]);
      if (!(denom > 0.0)) continue;
      const double lambda = (thickness_ - side * g.distance) / denom;  // −C / Σ w_k² m_k⁻¹
      const Vector3 normal = side * g.n;
      for (std::size_t k = 0; k < 4; ++k) {
        const int q = pair.p[k];
        if (w_(q) == 0.0) continue;
        p->row(q) += (lambda * g.w[k] * w_(q)) * normal.transpose();
        if (moved_[static_cast<std::size_t>(q)] != 1) {
          if (moved_[static_cast<std::size_t>(q)] == 0) moved_list_.push_back(q);
          moved_[static_cast<std::size_t>(q)] = 1;
        }
      }
      ++this_pass;
    }
    // The particles moved in this pass become the next pass' "moved before".
    std::size_t keep = 0;
    for (int q : moved_list_) {
      if (moved_[static_cast<std::size_t>(q)] == 1) {
        moved_list_[keep++] = q;
      } else {
        moved_[static_cast<std::size_t>(q)] = 0;
      }
    }
    moved_list_.resize(keep);
    projected += this_pass;
    if (this_pass == 0) break;
  }
  for (int q : moved_list_) moved_[static_cast<std::size_t>(q)] = 0;
  moved_list_.clear();
  stats_.projections += projected;
  stats_.response_seconds += Since(start);
  return projected;
}

namespace {

// The sum of the two largest of four non-negative numbers.
double TwoLargest(const std::array<double, 4>& a) {
  double first = std::max(a[0], a[1]), second = std::min(a[0], a[1]);
  for (std::size_t k = 2; k < 4; ++k) {
    if (a[k] > first) {
      second = first;
      first = a[k];
    } else if (a[k] > second) {
      second = a[k];
    }
  }
  return first + second;
}

}  // namespace

VbdSelfContact::VbdSelfContact(const ParticleSystem& system, double thickness)
    : sys_(system),
      thickness_(thickness),
      query_(kQueryFactor * thickness),
      list_(GridSelfContactList(system)) {
  if (!(thickness > 0.0)) throw std::invalid_argument("VbdSelfContact: thickness must be > 0");
  constexpr double kG0 = 9.81;  // m/s², the weight's scale
  stiffness_ = kStiffness * system.masses().mean() * kG0 / thickness;
  const int n = system.num_particles();
  x_det_.setZero(n, 3);
  bound_.assign(static_cast<std::size_t>(n), 0.0);
  offsets_.assign(static_cast<std::size_t>(n) + 1, 0);
}

void VbdSelfContact::SetStepMotion(double motion) {
  query_ = std::min(kQueryFactor * thickness_, std::max(kMinQueryFactor * thickness_, 2.0 * motion / kRelaxation));
}

void VbdSelfContact::Detect(const MatrixN3& x) {
  const auto start = Clock::now();
  x_det_ = x;
  // The pairs within Q at x: those of the list kept over steps
  // (collision/self_contact_list.h) whose bound is within Q.
  if (list_.Cover(x, x, query_)) {
    ++stats_.broad_phases;
    stats_.candidates += static_cast<long>(list_.size());
  }
  // The pairs within Q, with their distances in the bounds; the list is
  // sorted once filtered (the pairs' order, deterministic: the sorted list
  // of every pair within Q restricted to those kept).
  listed_.clear();
  std::fill(bound_.begin(), bound_.end(), query_);
  for (std::size_t i = 0; i < list_.size(); ++i) {
    if (list_.LowerBound(i) >= query_) continue;
    const SelfContactPair& pair = list_.pairs()[i];
    const double d = Closest(pair, x).distance;
    if (!(d < query_)) continue;
    listed_.push_back({pair, d});
    for (int q : pair.p) bound_[static_cast<std::size_t>(q)] = std::min(bound_[static_cast<std::size_t>(q)], d);
  }
  for (double& b : bound_) b *= kRelaxation;
  // The pairs that can come closer than δ before the next detection: every
  // particle stays within its bound of x_det, and a pair's distance (of a
  // point to a triangle, or of two edges, by convex weights) changes by at
  // most the largest bound of each side, at most the sum of the two
  // largest of its four. A pair farther than δ by more than that never
  // acts (AddForce skips it), so it is left out of every sweep: the forces
  // are those of the whole list, bit for bit, at a fraction of the cost
  // (OGC's per-vertex bounds, Chen et al. 2025, bound the contact set as
  // they bound the motion).
  std::erase_if(listed_, [&](const ListedPair& l) {
    std::array<double, 4> b;
    for (std::size_t k = 0; k < 4; ++k) b[k] = bound_[static_cast<std::size_t>(l.pair.p[k])];
    return !(l.distance - TwoLargest(b) < thickness_);
  });
  std::sort(listed_.begin(), listed_.end(),
            [](const ListedPair& u, const ListedPair& w) { return u.pair < w.pair; });
  // Each particle's pairs (CSR).
  std::fill(offsets_.begin(), offsets_.end(), 0);
  for (const ListedPair& l : listed_)
    for (int q : l.pair.p) ++offsets_[static_cast<std::size_t>(q) + 1];
  for (std::size_t q = 0; q + 1 < offsets_.size(); ++q) offsets_[q + 1] += offsets_[q];
  incident_.resize(static_cast<std::size_t>(offsets_.back()));
  fill_.assign(offsets_.begin(), offsets_.end() - 1);
  for (std::size_t i = 0; i < listed_.size(); ++i)
    for (std::size_t k = 0; k < 4; ++k)
      incident_[static_cast<std::size_t>(fill_[static_cast<std::size_t>(listed_[i].pair.p[k])]++)] =
          static_cast<int>(4 * i + k);
  stats_.detection_seconds += Since(start);
}

void VbdSelfContact::AddForce(int p, const MatrixN3& x, Vector3* f, Matrix3* k) const {
  for (int e = offsets_[static_cast<std::size_t>(p)]; e < offsets_[static_cast<std::size_t>(p) + 1]; ++e) {
    const int item = incident_[static_cast<std::size_t>(e)];
    const ListedPair& listed = listed_[static_cast<std::size_t>(item / 4)];
    const SelfContactPair& pair = listed.pair;
    // Its particles' motion since x_det so far: a pair still farther than δ
    // by more than the two largest is not within δ (the bound of Detect with
    // the motion made instead of the motion allowed), and is skipped.
    std::array<double, 4> moved;
    for (std::size_t c = 0; c < 4; ++c) moved[c] = (x.row(pair.p[c]) - x_det_.row(pair.p[c])).norm();
    if (listed.distance - TwoLargest(moved) >= thickness_) continue;
    const PairGeometry g = Closest(pair, x);
    if (!(g.distance < thickness_)) continue;
    const double w = g.w[static_cast<std::size_t>(item % 4)];
    // OGC's two-stage activation (Chen et al. 2025, eq. 18): quadratic down
    // to τ = δ/2, then −k_c' log d with k_c' = k_c τ (δ − τ) (C¹ at τ), whose
    // force k_c'/d grows without bound: a quadratic's force stops at k_c δ,
    // and pressed harder the pair's distance only shrinks geometrically
    // under the bounds, down to round-off (measured on the twisted strip).
    const double tau = 0.5 * thickness_;
    double magnitude, curvature;
    if (g.distance >= tau) {
      magnitude = stiffness_ * (thickness_ - g.distance);
      curvature = stiffness_;
    } else {
      const double barrier = stiffness_ * tau * (thickness_ - tau);
      const double d = std::max(g.distance, 1e-12 * thickness_);
      magnitude = barrier / d;
      curvature = barrier / (d * d);
    }
    *f += (magnitude * w) * g.n;
    *k += (curvature * w * w) * (g.n * g.n.transpose());
  }
}

bool VbdSelfContact::Truncate(int p, Vector3* xp) const {
  const Vector3 d = *xp - x_det_.row(p).transpose();
  const double len = d.norm(), b = bound_[static_cast<std::size_t>(p)];
  if (!(len > b)) return false;
  *xp = x_det_.row(p).transpose() + (b / len) * d;
  return true;
}

}  // namespace clothbench
