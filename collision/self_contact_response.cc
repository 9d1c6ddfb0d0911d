// Self-contact response after Bridson, Fedkiw & Anderson 2002, §7
// (self_contact_response.h).
#include "collision/self_contact_response.h"

#include <algorithm>
#include <chrono>
#include <numeric>
#include <stdexcept>
#include <utility>

#include <Eigen/Geometry>
#include <Eigen/QR>

#include "collision/edge_projection.h"
#include "collision/cloth_mesh.h"

namespace clothbench {
namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

// The largest displacement of a particle of the pair's first element (the
// point, the first edge) relative to one of its second (the triangle, the
// second edge) between x0 and x1: with d_k = x1_k − x0_k, the distance of
// the elements' hulls changes by at most max_{i,j} |d_i − d_j| over the
// step (the difference of two convex combinations of the d_k is a convex
// combination of the d_i − d_j). A pair moving together is not tested.
double MotionBound(const SelfContactPair& pair, const MatrixN3& x0, const MatrixN3& x1) {
  const auto move = [&](std::size_t k) {
    return Vector3((x1.row(pair.p[k]) - x0.row(pair.p[k])).transpose());
  };
  const std::size_t first = pair.kind == SelfContactPair::kPointTriangle ? 1 : 2;
  double bound = 0.0;
  for (std::size_t i = 0; i < first; ++i)
    for (std::size_t j = first; j < 4; ++j) bound = std::max(bound, (move(i) - move(j)).norm());
  return bound;
}

}  // namespace

SelfContactList GridSelfContactList(const ParticleSystem& system) {
  const Scene& scene = system.scene();
  return SelfContactList(SceneTriangles(scene).vertices, system.num_particles(),
                         ScenePatches(scene, SelfContactResponse::kPatchCells),
                         SelfContactResponse::kSkinFraction * std::min(scene.lu(), scene.lv()));
}

SelfContactResponse::SelfContactResponse(const ParticleSystem& system, double thickness)
    : sys_(system),
      thickness_(thickness),
      list_(GridSelfContactList(system)) {
  if (!(thickness > 0.0)) throw std::invalid_argument("SelfContactResponse: thickness must be > 0");
  const int n = system.num_particles();
  inverse_mass_.resize(n);
  for (int p = 0; p < n; ++p) inverse_mass_(p) = system.is_fixed(p) ? 0.0 : 1.0 / system.masses()(p);
  nu_.resize(n, 3);
  nu_start_.resize(n, 3);
  x_end_.resize(n, 3);
  parent_.resize(static_cast<std::size_t>(n));
  moved_.assign(static_cast<std::size_t>(n), 0);
  moved_before_.assign(static_cast<std::size_t>(n), 0);
  in_zone_.assign(static_cast<std::size_t>(n), 0);
}

bool SelfContactResponse::Push(const SelfContactPair& pair, const PairGeometry& g, double target, double h,
                               const MatrixN3& x0) {
  Vector3 rel = Vector3::Zero();
  double denom = 0.0;
  for (std::size_t k = 0; k < 4; ++k) {
    rel += g.w[k] * nu_.row(pair.p[k]).transpose();
    denom += g.w[k] * g.w[k] * inverse_mass_(pair.p[k]);
  }
  const double vn = g.n.dot(rel);
  if (!(vn < target) || !(denom > 0.0)) return false;
  const double impulse = (target - vn) / denom;
  for (std::size_t k = 0; k < 4; ++k) {
    const int p = pair.p[k];
    nu_.row(p) += (g.w[k] * inverse_mass_(p) * impulse) * g.n.transpose();
    x_end_.row(p) = x0.row(p) + h * nu_.row(p);
    moved_[static_cast<std::size_t>(p)] = 1;
  }
  end_moved_ = true;
  return true;
}

void SelfContactResponse::Refresh(const MatrixN3& x0) {
  // x_end as the last call saw it: nothing to do.
  if (!end_moved_) return;
  end_moved_ = false;
  if (list_.Cover(x0, x_end_, thickness_)) {
    ++stats_.broad_phases;
    stats_.candidates += static_cast<long>(list_.size());
    stamp_.assign(list_.size(), -1);
    distance0_.resize(list_.size());
    test_all_ = true;
  }
  // A pair whose bound stays above the thickness along x₀ → x_end can
  // neither be within it at x₀ nor touch: it is not looked at.
  near_.clear();
  fresh_.clear();
  for (std::size_t i = 0; i < list_.size(); ++i) {
    if (list_.LowerBound(i) > thickness_) continue;
    near_.push_back(i);
    if (stamp_[i] != step_) fresh_.push_back(i);
  }
  const long n = static_cast<long>(fresh_.size());
#pragma omp parallel for schedule(static) if (n > kParallelPairTests)
  for (long j = 0; j < n; ++j) {
    const std::size_t i = fresh_[static_cast<std::size_t>(j)];
    distance0_[i] = Closest(list_.pairs()[i], x0).distance;
    stamp_[i] = step_;
  }
}

int SelfContactResponse::CollisionPass(double h, const MatrixN3& x0, bool apply, std::vector<int>* colliding) {
  const double tolerance = kCcdToleranceFraction * thickness_;
  // Which pairs touch along x₀ → x_end, all tested on the same x_end (in
  // parallel: each test reads only), then handled one by one in the pairs'
  // order, so that the result does not depend on the threads.
  // Only the pairs whose particles moved since their last test can have
  // changed (all of them after a broad phase).
  const auto& pairs = list_.pairs();
  const long n = static_cast<long>(near_.size());
  touching_.assign(near_.size(), 0);
  moved_before_.swap(moved_);
  std::fill(moved_.begin(), moved_.end(), 0);
  const bool all = test_all_;
  test_all_ = false;
  // A pass after the first tests only the pairs with a particle moved since
  // (few): its threshold counts an eighth of the list.
  const bool parallel = (all ? n : n / 8) > kParallelPairTests;
#pragma omp parallel for schedule(dynamic, 1024) if (parallel)
  for (long i = 0; i < n; ++i) {
    const std::size_t k = near_[static_cast<std::size_t>(i)];
    const auto& p = pairs[k].p;
    if (!all && !(moved_before_[static_cast<std::size_t>(p[0])] | moved_before_[static_cast<std::size_t>(p[1])] |
                  moved_before_[static_cast<std::size_t>(p[2])] | moved_before_[static_cast<std::size_t>(p[3])]))
      continue;
    // A pair further apart at x₀ than its particles move cannot touch.
    if (distance0_[k] - MotionBound(pairs[k], x0, x_end_) > tolerance) continue;
    double theta = 0.0;
    PairGeometry g;
    touching_[static_cast<std::size_t>(i)] = FirstCoplanarContact(pairs[k], x0, x_end_, tolerance, &theta, &g);
  }
  acting_.clear();
  for (std::size_t i = 0; i < near_.size(); ++i)
    if (touching_[i]) acting_.push_back(near_[i]);
  SortActing();
  int count = 0;
  for (std::size_t k : acting_) {
    const SelfContactPair& pair = pairs[k];
    double theta = 0.0;
    PairGeometry g;
    if (apply) {
      // Again on x_end as the impulses before it in this pass left it.
      if (!FirstCoplanarContact(pair, x0, x_end_, tolerance, &theta, &g)) continue;
      ++count;
      if (Push(pair, g, 0.0, h, x0)) ++stats_.collisions;
    } else {
      ++count;
      colliding->insert(colliding->end(), pair.p.begin(), pair.p.end());
    }
  }
  return count;
}

void SelfContactResponse::SortActing() {
  std::sort(acting_.begin(), acting_.end(),
            [&](std::size_t a, std::size_t b) { return list_.pairs()[a] < list_.pairs()[b]; });
}

int SelfContactResponse::Find(int p) {
  while (parent_[static_cast<std::size_t>(p)] != p) {
    parent_[static_cast<std::size_t>(p)] = parent_[static_cast<std::size_t>(parent_[static_cast<std::size_t>(p)])];
    p = parent_[static_cast<std::size_t>(p)];
  }
  return p;
}

void SelfContactResponse::RigidZones(double h, const MatrixN3& x0, const std::vector<int>& colliding) {
  for (std::size_t k = 0; k < colliding.size(); k += 4) {
    for (std::size_t j = 0; j < 4; ++j) in_zone_[static_cast<std::size_t>(colliding[k + j])] = 1;
    const int root = Find(colliding[k]);
    for (std::size_t j = 1; j < 4; ++j) {
      const int other = Find(colliding[k + j]);
      if (other != root) parent_[static_cast<std::size_t>(other)] = root;
    }
  }
  // Members grouped by zone, in particle order within each.
  std::vector<std::pair<int, int>> members;
  for (int p = 0; p < sys_.num_particles(); ++p)
    if (in_zone_[static_cast<std::size_t>(p)]) members.emplace_back(Find(p), p);
  std::sort(members.begin(), members.end());
  for (std::size_t begin = 0; begin < members.size();) {
    std::size_t end = begin;
    while (end < members.size() && members[end].first == members[begin].first) ++end;
    bool fixed = false;
    double mass = 0.0;
    Vector3 centre = Vector3::Zero(), momentum = Vector3::Zero();
    for (std::size_t k = begin; k < end; ++k) {
      const int p = members[k].second;
      fixed = fixed || inverse_mass_(p) == 0.0;
      const double m = sys_.masses()(p);
      mass += m;
      centre += m * x0.row(p).transpose();
      momentum += m * nu_.row(p).transpose();
    }
    Vector3 v_centre = Vector3::Zero(), omega = Vector3::Zero();
    if (!fixed) {
      centre /= mass;
      v_centre = momentum / mass;
      Vector3 angular = Vector3::Zero();
      Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();
      for (std::size_t k = begin; k < end; ++k) {
        const int p = members[k].second;
        const double m = sys_.masses()(p);
        const Vector3 r = x0.row(p).transpose() - centre;
        angular += m * r.cross(nu_.row(p).transpose() - v_centre);
        inertia += m * (r.squaredNorm() * Eigen::Matrix3d::Identity() - r * r.transpose());
      }
      // A zone on one line has a singular inertia: the least-norm ω.
      omega = inertia.completeOrthogonalDecomposition().solve(angular);
    }
    for (std::size_t k = begin; k < end; ++k) {
      const int p = members[k].second;
      const Vector3 r = x0.row(p).transpose() - centre;
      const Vector3 velocity = fixed ? Vector3::Zero() : Vector3(v_centre + omega.cross(r));
      nu_.row(p) = velocity.transpose();
      x_end_.row(p) = x0.row(p) + h * nu_.row(p);
      moved_[static_cast<std::size_t>(p)] = 1;
    }
    end_moved_ = true;
    begin = end;
  }
}

int SelfContactResponse::Respond(double h, const MatrixN3& x0, MatrixN3* x1, MatrixN3* v1) {
  const auto start = Clock::now();
  double detection = 0.0;
  ++stats_.steps;
  nu_ = (*x1 - x0) / h;
  nu_start_ = nu_;
  x_end_ = *x1;
  const long pushed_before = stats_.repulsions + stats_.collisions + stats_.zone_passes;
  // 1. Repulsion from the pairs within the thickness at x₀.
  auto t = Clock::now();
  ++step_;
  test_all_ = true;
  end_moved_ = true;
  Refresh(x0);
  detection += Since(t);
  acting_.clear();
  for (std::size_t k : near_)
    if (distance0_[k] < thickness_) acting_.push_back(k);
  SortActing();
  for (std::size_t k : acting_) {
    const PairGeometry g = Closest(list_.pairs()[k], x0);
    if (Push(list_.pairs()[k], g, kRepulsion * (thickness_ - g.distance) / h, h, x0)) ++stats_.repulsions;
  }
  // 2. Collision impulses, Gauss–Seidel in the pairs' order.
  int left = -1;
  for (int pass = 0; pass < kImpulsePasses && left != 0; ++pass) {
    t = Clock::now();
    Refresh(x0);
    left = CollisionPass(h, x0, true, nullptr);
    detection += Since(t);
  }
  // 3. Rigid impact zones for what is left.
  if (left != 0) {
    std::iota(parent_.begin(), parent_.end(), 0);
    std::fill(in_zone_.begin(), in_zone_.end(), 0);
    for (int pass = 0; pass <= kZonePasses; ++pass) {
      t = Clock::now();
      Refresh(x0);
      colliding_.clear();
      left = CollisionPass(h, x0, false, &colliding_);
      detection += Since(t);
      if (left == 0 || pass == kZonePasses) break;
      RigidZones(h, x0, colliding_);
      ++stats_.zone_passes;
    }
  }
  if (left != 0) ++stats_.unresolved_steps;
  if (stats_.repulsions + stats_.collisions + stats_.zone_passes != pushed_before) {
    const double before = sys_.Energies(*x1, *v1).total();
    nu_ -= nu_start_;  // Δν
    *x1 += h * nu_;
    *v1 += nu_;
    stats_.work += sys_.Energies(*x1, *v1).total() - before;
  }
  stats_.detection_seconds += detection;
  stats_.response_seconds += Since(start) - detection;
  return left;
}

}  // namespace clothbench
