// Obstacle contacts on positions, for the peers that move particles by
// position (XPBD, projective dynamics): the inequality C = d(p) − δ ≥ 0 on
// the signed distance d with zero compliance, and Coulomb friction on the
// tangential displacement (Macklin, Müller, Chentanez, Kim 2014, "Unified
// particle physics for real-time applications", Eq. 24–25) with
// μ_s = μ_k = c_f (docs/model.md §10).
#ifndef CLOTHBENCH_PEERS_POSITION_CONTACTS_H_
#define CLOTHBENCH_PEERS_POSITION_CONTACTS_H_

#include <vector>

#include "collision/obstacle_proximity.h"
#include "collision/self_contact_response.h"
#include "model/particle_system.h"

namespace clothbench {

/// Moves every particle of `p` inside an obstacle's collision area to its
/// border along the distance's direction D, then removes its tangential
/// displacement relative to the obstacle since `x`: all of it while it is
/// below μ (δ − d) (static), otherwise by μ (δ − d) (kinetic).
/// @param sys the model (its obstacles, at their pose at `t_end`)
/// @param proximity the entries of each obstacle at `p` (the position-based
///   peers' adapter to the contact list; one per stepper, Reset with it)
/// @param w inverse masses [1/kg]; particles with w = 0 (fixed) are not moved
/// @param t_end time of the positions `p` [s]
/// @param dt time since `x` [s] (the obstacle's own motion over it is not friction)
/// @param x N×3 positions at the start of the (sub)step [m]
/// @param p N×3 positions at its end [m], updated
/// @param held per particle, nonzero where another response holds it (a
///   contact impulse): projected only from inside the obstacle (d < 0), or nullptr
/// @return the particles found in an obstacle's collision area
int ProjectOntoObstacles(const ParticleSystem& sys, ObstacleProximity* proximity, const Eigen::VectorXd& w,
                         double t_end, double dt, const MatrixN3& x, MatrixN3* p,
                         const std::vector<char>* held = nullptr);

/// The cloth's contact with itself on positions, for the peers that move
/// particles by position inside a step (XPBD): the inequality constraints
/// of Müller, Heidelberger, Hennix, Ratcliff 2007, "Position based
/// dynamics", §4.4 (a point kept on its side of a triangle, at least the
/// thickness δ away), for point–triangle and edge–edge pairs alike,
///   C = s (Σ_k w_k p_k)·n − δ ≥ 0, zero compliance,
/// with (w, n) the pair's closest points and normal at p
/// (collision/self_contact.h, Closest) and s = ±1 its side at the start of
/// the substep: a pair that crossed within the substep is pushed back to
/// the side it came from. The candidates come from the broad phase once per
/// step over the predicted path x₀ → x₀ + h v₀ (Macklin et al. 2019:
/// detection once per step, the constraints in every substep), grown by
/// the thickness and a skin, and again from a substep's start whenever a
/// particle leaves that path by more than the skin. A substep projects only
/// the pairs whose distance at the detection, less twice the largest
/// displacement since (less the mean), is below δ, in the order of that
/// distance (then the pair): deterministic. Inverse-mass weighted, so the
/// projections keep the linear momentum. No allocation once the lists have
/// reached their size.
class PositionSelfContact {
 public:
  /// The skin of a substep's detection as a fraction of the grid spacing:
  /// a particle that leaves the detection's path by more (per coordinate)
  /// is detected again from the substep's start; the pairs looked at are
  /// those of the list kept over steps within δ + 2√3 skins of it.
  static constexpr double kSkinFraction = 0.05;
  /// Gauss–Seidel passes over the pairs per substep, until one projects none.
  static constexpr int kPasses = 8;
  /// A later pass leaves a pair alone within this fraction of the thickness
  /// (a pair the first pass set to δ is not projected again for round-off).
  static constexpr double kSlop = 0.999;

  /// @param system the cloth (grid, masses, fixed particles; must outlive this)
  /// @param thickness δ [m], > 0
  /// @param w inverse masses [1/kg], 0 for fixed particles
  /// @throws std::invalid_argument if thickness ≤ 0
  PositionSelfContact(const ParticleSystem& system, double thickness, const Eigen::VectorXd& w);

  void Reset() { stats_ = SelfContactStats{}; }
  /// Sets the query radius of the detections until the next call from the
  /// largest distance `motion` [m] a particle is predicted to move in the
  /// step: Q = min(kQueryFactor δ, max(kMinQueryFactor δ, 2 motion/γ)). A
  /// particle's bound γ min(Q, …) then stays above twice its predicted
  /// motion, so the cap Q truncates no particle that a larger Q would
  /// leave free, while the pairs listed, and each detection's cost, no
  /// longer grow with δ² when the step moves the cloth less than 20δ/γ.
  void SetStepMotion(double motion);
  /// Starts a step of size h [s] from positions x0 and velocities v0
  /// (N×3 [m], [m/s]): the broad phase over x₀ → x₀ + h v₀.
  void BeginStep(double h, const MatrixN3& x0, const MatrixN3& v0);
  /// Projects the constraints of the substep from x (its start) to p (its
  /// prediction, after the other constraints; N×3 [m], updated), which
  /// runs from the fraction tau0 to tau1 ∈ (tau0, 1] of the step.
  /// @return the pairs projected
  int Project(const MatrixN3& x, double tau0, double tau1, MatrixN3* p);
  const SelfContactStats& stats() const { return stats_; }

 private:
  // The largest motion in the substep of a particle of the first element
  // plus that of one of the second [m].
  double PairMotion(const SelfContactPair& pair) const;
  // The broad phase over x_det → x_end, from the fraction tau of the step.
  void Detect(const MatrixN3& x_det, const MatrixN3& x_end, double tau);

  double thickness_, skin_;
  SelfContactList list_;
  Eigen::VectorXd w_;
  SelfContactStats stats_;
  MatrixN3 x_det_, x_end_, path_;  // the detection's start and predicted end
  double tau_det_ = 0.0;                       // fraction of the step at the detection
  std::vector<double> reach_;                  // per particle: largest displacement since the detection, less the mean [m]
  std::vector<std::pair<double, SelfContactPair>> by_distance_;  // candidates by distance at x_det
  std::vector<Vector3> start_normal_;  // a substep's pairs in reach: their normal at its start (0: not yet known)
  std::vector<double> step_motion_;  // per particle: its motion in the substep [m]
  std::vector<char> in_reach_;   // a substep's pairs: whether their distance can be below the thickness
  std::vector<char> moved_;      // per particle: 1 moved in this pass, 2 in the pass before, 0 neither
  std::vector<int> moved_list_;  // the particles with moved_ ≠ 0
};

/// The cloth's contact with itself as VBD ships it (Chen, Liu, Yang, Yuksel
/// 2024, "Vertex Block Descent": a contact energy inside the local steps;
/// Chen et al. 2025, "Offset Geometric Contact": per-vertex conservative
/// displacement bounds; as in Warp's warp/sim/integrator_vbd.py,
/// compute_particle_conservative_bound and apply_conservative_bound_truncation):
///  - detection at x_det (the step's start, and again after a sweep that
///    truncated a particle) of the point–triangle and edge–edge pairs
///    within the query radius Q = kQueryFactor δ (no topological filter
///    beyond pairs that share a particle: with Warp's filter of grid
///    neighbours the pile crossed itself at t = 0.85 s);
///  - each particle's bound b_p = γ min(Q, the distance of every listed
///    pair it belongs to at x_det), γ = kRelaxation < 1/2: while every
///    particle stays within b_p of x_det, no pair's distance falls below
///    (1 − 2γ) of what it was, so no pair crosses;
///  - the energy of each listed pair closer than δ, OGC's two-stage
///    activation (Chen et al. 2025, eq. 18): ½ k_c (δ − d)² down to
///    τ = δ/2, below it −k_c' log d with k_c' = k_c τ (δ − τ); its force
///    on particle k is k_c (δ − d) w_k n (then k_c'/d w_k n) and its
///    stiffness k_c w_k² n nᵀ (then k_c'/d² w_k² n nᵀ) in that particle's
///    local Newton step, with k_c = kStiffness m̄ g₀/δ
///    (m̄ the mean particle mass, g₀ = 9.81 m/s²: the penalty holds
///    kStiffness layers' weight within the thickness).
/// A local step that would take particle p beyond b_p is truncated to it.
class VbdSelfContact {
 public:
  static constexpr double kRelaxation = 0.45;  ///< γ (Warp: 0.45; OGC: below 1/2)
  static constexpr double kQueryFactor = 20.0;  ///< Q / δ at most
  static constexpr double kMinQueryFactor = 2.0;  ///< Q / δ at least
  static constexpr double kStiffness = 100.0;  ///< layers whose weight the penalty holds within δ

  /// @param system the cloth (grid, masses, fixed particles; must outlive this)
  /// @param thickness δ [m], > 0
  /// @throws std::invalid_argument if thickness ≤ 0
  VbdSelfContact(const ParticleSystem& system, double thickness);

  void Reset() { stats_ = SelfContactStats{}; }
  /// Sets the query radius of the detections until the next call from the
  /// largest distance `motion` [m] a particle is predicted to move in the
  /// step: Q = min(kQueryFactor δ, max(kMinQueryFactor δ, 2 motion/γ)). A
  /// particle's bound γ min(Q, …) then stays above twice its predicted
  /// motion, so the cap Q truncates no particle that a larger Q would
  /// leave free, while the pairs listed, and each detection's cost, no
  /// longer grow with δ² when the step moves the cloth less than 20δ/γ.
  void SetStepMotion(double motion);
  /// The pairs within Q at x (N×3 [m]), the particles' bounds, and x as x_det.
  void Detect(const MatrixN3& x);
  /// Adds the penalty force [N] on particle p at positions x to *f and its
  /// stiffness −∂f/∂x_p [N/m] to *k.
  void AddForce(int p, const MatrixN3& x, Vector3* f, Matrix3* k) const;
  /// Moves *xp [m], particle p's new position, back onto its bound around
  /// x_det if beyond it. @return whether it did
  bool Truncate(int p, Vector3* xp) const;
  /// b_p [m]: how far particle p may move from x_det (after Detect).
  double bound(int p) const { return bound_[static_cast<std::size_t>(p)]; }
  SelfContactStats& stats() { return stats_; }
  const SelfContactStats& stats() const { return stats_; }

 private:
  const ParticleSystem& sys_;
  double thickness_, query_, stiffness_;
  SelfContactList list_;
  SelfContactStats stats_;
  MatrixN3 x_det_;
  std::vector<double> bound_;           // b_p [m]
  struct ListedPair {
    SelfContactPair pair;
    double distance;  // at x_det [m]
  };
  std::vector<ListedPair> listed_;  // the pairs that can act before the next detection, in the pairs' order
  std::vector<int> offsets_, incident_;  // per particle: its pairs (index·4 + slot) in listed_
  std::vector<int> fill_;                // scratch of Detect
};

}  // namespace clothbench

#endif  // CLOTHBENCH_PEERS_POSITION_CONTACTS_H_
