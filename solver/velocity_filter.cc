// The velocity filter S (velocity_filter.h).
#include "solver/velocity_filter.h"

#include <algorithm>
#include <stdexcept>

namespace clothbench {

VelocityFilter::Entry* VelocityFilter::Find(int p) {
  const auto k = static_cast<std::size_t>(p);
  if (k < slot_.size()) return slot_[k] >= 0 ? &entries_[static_cast<std::size_t>(slot_[k])] : nullptr;
  for (Entry& e : entries_)  // without Reserve: linear search
    if (e.particle == p) return &e;
  return nullptr;
}

void VelocityFilter::Fix(int p, const Vector3& target) {
  if (static_cast<std::size_t>(p) < slot_.size()) slot_[static_cast<std::size_t>(p)] = size();
  entries_.push_back({p, 3, Eigen::Matrix3d::Identity(), target});
}

void VelocityFilter::SetFixedTarget(int p, const Vector3& target) {
  Entry* e = Find(p);
  if (!e || e->count != 3) throw std::logic_error("VelocityFilter::SetFixedTarget: particle is not fixed");
  e->targets = target;
}

void PrescribeFixedTargets(const ParticleSystem& system, double t, VelocityFilter* filter) {
  if (!system.has_prescribed_motion()) return;
  system.ForEachPrescribed(t, [&](int p, const Vector3&, const Vector3& v) { filter->SetFixedTarget(p, v); });
}

void HoldFixed(const ParticleSystem& system, double t1, const MatrixN3& x0, MatrixN3* x1, MatrixN3* v1) {
  for (int p : system.fixed()) x1->row(p) = x0.row(p);
  system.Prescribe(t1, x1, v1);
}

// A particle's entry is found through slot_ in O(1). A linear search made
// the contact setup quadratic in the number of contacts (bench_scaling,
// 30 % patch at 10⁶ particles: 157 s per SBDF(2) step before, 20 s after).
void VelocityFilter::Constrain(int p, const Vector3& dir, double target) {
  if (Entry* found = Find(p)) {
    Entry& e = *found;
    if (e.count == 3) return;
    Vector3 d = dir;
    for (int k = 0; k < e.count; ++k) d -= e.dirs.col(k).dot(d) * e.dirs.col(k);
    if (d.norm() < 1e-12) return;
    e.dirs.col(e.count) = d.normalized();
    e.targets(e.count) = target;
    ++e.count;
    return;
  }
  if (static_cast<std::size_t>(p) < slot_.size()) slot_[static_cast<std::size_t>(p)] = size();
  Entry e{p, 1, Eigen::Matrix3d::Zero(), Vector3::Zero()};
  e.dirs.col(0) = dir.normalized();
  e.targets(0) = target;
  entries_.push_back(e);
}

template <class M>
void VelocityFilter::Project(M* v) const {
  for (const Entry& e : entries_) {
    if (e.count == 3) {
      v->row(e.particle).setZero();
      continue;
    }
    Vector3 x = v->row(e.particle).transpose();
    for (int k = 0; k < e.count; ++k) x -= e.dirs.col(k).dot(x) * e.dirs.col(k);
    v->row(e.particle) = x.transpose();
  }
}

template <class M>
void VelocityFilter::Impose(M* v) const {
  for (const Entry& e : entries_) {
    if (e.count == 3) {
      v->row(e.particle) = e.targets.transpose();  // dirs = I
      continue;
    }
    Vector3 x = v->row(e.particle).transpose();
    for (int k = 0; k < e.count; ++k) x += (e.targets(k) - e.dirs.col(k).dot(x)) * e.dirs.col(k);
    v->row(e.particle) = x.transpose();
  }
}

template <class M>
double VelocityFilter::ProjectedNorm(const M& b) const {
  double sq = b.squaredNorm();
  for (const Entry& e : entries_) {
    const Vector3 x = b.row(e.particle).transpose();
    if (e.count == 3) {
      sq -= x.squaredNorm();
      continue;
    }
    // The directions are orthonormal: the removed part's square is Σ_k (d_k·x)².
    for (int k = 0; k < e.count; ++k) sq -= e.dirs.col(k).dot(x) * e.dirs.col(k).dot(x);
  }
  return std::sqrt(std::max(sq, 0.0));
}

template double VelocityFilter::ProjectedNorm(const MatrixN3&) const;
template double VelocityFilter::ProjectedNorm(const MatrixN3R&) const;
template void VelocityFilter::Project(MatrixN3*) const;
template void VelocityFilter::Project(MatrixN3R*) const;
template void VelocityFilter::Impose(MatrixN3*) const;
template void VelocityFilter::Impose(MatrixN3R*) const;

}  // namespace clothbench
