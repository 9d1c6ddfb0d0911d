// The per-particle velocity filter S of the filtered PCG (docs/model.md §5,
// thesis (4.3); Baraff & Witkin 1998, §5.3): how the implicit methods read
// their constraints — fixed particles and contacts — as prescribed
// velocities along constrained directions.
#ifndef CLOTHBENCH_SOLVER_VELOCITY_FILTER_H_
#define CLOTHBENCH_SOLVER_VELOCITY_FILTER_H_

#include <array>
#include <vector>

#include "model/particle_system.h"
#include "model/types.h"

namespace clothbench {

/// Per-particle velocity filter S_p = I − Σ c cᵀ with prescribed velocities
/// along the constrained directions (docs/model.md §5). A fixed particle constrains all
/// three directions. Without constraints the projection is skipped entirely
/// (docs/model.md §2.6).
class VelocityFilter {
 public:
  /// Constrains all three directions of particle p to velocity `target` [m/s].
  void Fix(int p, const Vector3& target = Vector3::Zero());
  /// Constrains particle p along unit direction `dir` to ⟨v,dir⟩ = target [m/s].
  /// Directions of one particle are orthonormalised.
  void Constrain(int p, const Vector3& dir, double target);
  /// Sets the target velocity [m/s] of particle p, fixed by Fix. @throws
  /// std::logic_error if p has no fixed entry.
  void SetFixedTarget(int p, const Vector3& target);
  void Clear() {
    for (const Entry& e : entries_)
      if (static_cast<std::size_t>(e.particle) < slot_.size()) slot_[static_cast<std::size_t>(e.particle)] = -1;
    entries_.clear();
  }
  /// Reserves room for n constrained particles, particles 0 … n−1 (no
  /// allocation afterwards; Fix and Constrain then find a particle's entry
  /// in O(1)).
  void Reserve(int n) {
    entries_.reserve(static_cast<std::size_t>(n));
    slot_.assign(static_cast<std::size_t>(n), -1);
  }
  bool empty() const { return entries_.empty(); }
  /// Calls f(particle, count, dirs) for every constrained particle: `count`
  /// constrained directions (3: fixed), orthonormal in dirs' first columns.
  template <class F>
  void ForEachConstraint(F&& f) const {
    for (const Entry& e : entries_) f(e.particle, e.count, e.dirs);
  }
  /// Calls f(particle, count, dirs, targets) for every constrained
  /// particle, with its prescribed velocities along dirs' first `count`
  /// columns [m/s] writable (StepEngine's ContactHistory::kLand).
  template <class F>
  void ForEachTarget(F&& f) {
    for (Entry& e : entries_) f(e.particle, e.count, e.dirs, e.targets);
  }
  int size() const { return static_cast<int>(entries_.size()); }
  /// v ← S v. @tparam M MatrixN3 or MatrixN3R.
  template <class M>
  void Project(M* v) const;
  /// ‖S b‖₂ without a copy of b: ‖b‖² less the constrained components'
  /// squares, Σ_p Σ_k (d_k·b_p)² (one pass over b, then the entries).
  template <class M>
  double ProjectedNorm(const M& b) const;
  /// v ← S v + (I − S) z: imposes the prescribed components.
  template <class M>
  void Impose(M* v) const;

 private:
  struct Entry {
    int particle;
    int count;                 // number of constrained directions (3: fixed)
    Eigen::Matrix3d dirs;      // orthonormal directions in the first `count` columns
    Vector3 targets;           // prescribed velocity along each direction
  };
  std::vector<Entry> entries_;
  std::vector<int> slot_;  // entry index of each particle, −1: none (after Reserve)
  Entry* Find(int p);
};

/// Sets the targets of the moving fixed particles of `system`
/// (`[[constraints.motion]]`) in `filter` to their prescribed velocities at
/// t [s]: the velocity the step's solve holds them at. Their entries must
/// have been made by Fix. No allocation.
void PrescribeFixedTargets(const ParticleSystem& system, double t, VelocityFilter* filter);

/// A step's end for the fixed particles: at rest, x₁ = x₀ exactly (a
/// multistep formula would let them drift by round-off); moving, x₁ and v₁
/// their prescribed position and velocity at t₁ [s]. N×3 [m], [m/s].
void HoldFixed(const ParticleSystem& system, double t1, const MatrixN3& x0, MatrixN3* x1, MatrixN3* v1);

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_VELOCITY_FILTER_H_
