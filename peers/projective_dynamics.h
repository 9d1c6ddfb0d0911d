// Projective dynamics for the model's mass-spring tension (Liu, Bargteil,
// O'Brien, Kavan 2013, "Fast simulation of mass-spring systems", ACM TOG
// 32(6); Bouaziz, Martin, Liu, Kavan, Pauly 2014) with optional Chebyshev
// acceleration (Wang 2015, "A Chebyshev semi-iterative approach for
// accelerating projective and position-based dynamics", ACM TOG 34(6)),
// docs/model.md §10.
//
// Implicit Euler on positions minimises ½‖x − y‖²_M / h² + E(x) with
// y = x₀ + h v₀. A spring's energy ½ s_e (|d| − l_e)², d = x_b − x_a, is
// the minimum over |p_e| = l_e of ½ s_e |d − p_e|²: the local step projects
// each spring, p_e = l_e d/|d|, and the global step solves one constant SPD
// system. In velocities (x = x₀ + h v) that system is A₁ = M + h² L_K + h L_D,
// the thesis' implicit Euler matrix with the linear tension damping, and
// the local step's right-hand side s_e Dᵀ p_e is −F_nl, the explicit part
// of the thesis' tension split (docs/model.md §2.1). Shear, bending, air
// and wind are not springs: PD cannot write them as projections, so they
// enter the same right-hand side at the current iterate. Iteration k is
//   v^{k+1} = A₁⁻¹ (M v₀ − h L_K x₀ + h g(t₁, x₀ + h v^k, v^k)),
// whose fixed point is implicit Euler's for the whole model: on this
// model PD is the thesis' fixed-point iteration of implicit Euler
// (docs/model.md §6), with A₁'s CHOLMOD factor instead of the PCG, a
// fixed iteration count and no convergence test. It starts from the
// inertial guess v⁰ = v₀ + h M⁻¹ f_ext (gravity), as Liu et al. start from y.
//
// Contacts: after the iterations, the positions x₀ + h v are projected out
// of the obstacles with friction (peers/position_contacts.h) and the
// velocity is (x₁ − x₀)/h, as XPBD's. Fixed particles have v = 0.
#ifndef CLOTHBENCH_PEERS_PROJECTIVE_DYNAMICS_H_
#define CLOTHBENCH_PEERS_PROJECTIVE_DYNAMICS_H_

#include <string_view>

#include "model/particle_system.h"
#include "solver/integrator.h"

namespace clothbench {

/// The integrator name used by the executables and result files.
inline constexpr std::string_view kProjectiveDynamicsName = "pd";

/// Chebyshev acceleration of the iteration (Wang 2015, Eq. 10–12): with
/// v̂ the plain iterate from v^k,
///   v^{k+1} = ω_{k+1} (γ (v̂ − v^k) + v^k − v^{k−1}) + v^{k−1},
///   ω = 1 for k < delay, ω = 2/(2 − ρ²) at k = delay, then ω ← 4/(4 − ρ² ω).
struct ChebyshevSettings {
  bool on = false;
  /// Spectral radius of the plain iteration, in [0, 1); 0: measured at the
  /// first step of each h (ProjectiveDynamics::rho()).
  double rho = 0.0;
  double gamma = 1.0;  ///< under-relaxation γ in (0, 1]
  int delay = 1;       ///< plain iterations before ω leaves 1 (Wang's S)
};

/// Projective dynamics with a fixed number of iterations per step.
class ProjectiveDynamics : public Stepper {
 public:
  /// @param system the model (must outlive the stepper)
  /// @param spec its solver settings (the CHOLMOD ordering of A₁'s factor)
  /// @param iterations k ≥ 1 per step
  /// @param chebyshev acceleration (off: plain PD)
  /// @throws std::invalid_argument if iterations < 1 or the Chebyshev
  ///   settings are outside their ranges
  ProjectiveDynamics(const ParticleSystem& system, const SolverSpec& spec, int iterations,
                     ChebyshevSettings chebyshev = {});

  void Reset(double t, const MatrixN3& x, const MatrixN3& v) override;
  /// One step of size h [s]: k iterations, then the obstacles. A₁ is
  /// refactorised only when h changes. stats.updates = k, cg_iterations = 0
  /// (the solves are direct), colliding = particles projected out of an
  /// obstacle. Status kNonFinite (state unchanged) if an iterate is not
  /// finite, kTimeLimit past the run's deadline. No allocation after the
  /// first step of an h.
  StepStats Step(double h) override;
  double t() const override { return t_; }
  void SetTime(double t) override { t_ = t; }
  const MatrixN3& x() const override { return x0_; }
  const MatrixN3& v() const override { return v0_; }
  bool single_update() const override { return true; }
  int matrix_rebuilds() const override { return sm_.rebuilds(); }
  double setup_seconds() const override { return sm_.setup_seconds(); }

  int iterations() const { return iterations_; }
  /// Plain iterations of the measurement of ρ (ChebyshevSettings::rho = 0):
  /// ρ is the geometric mean of ‖v^{k+1} − v^k‖ / ‖v^k − v^{k−1}‖ over the
  /// last half of them, from a copy of the state at the first step of each h
  /// (the step itself is then taken with that ρ; the measurement's time
  /// counts as the step's setup).
  static constexpr int kRhoIterations = 32;
  /// The ρ the acceleration uses (the measured one once a step has run;
  /// 0 before, or without Chebyshev).
  double rho() const { return rho_; }
  /// ‖v^{k+1} − v^k‖ of each iteration of the last step (plain or
  /// accelerated), for measuring the contraction ρ.
  const std::vector<double>& last_increments() const { return increments_; }

 private:
  const ParticleSystem& sys_;
  int iterations_;
  ChebyshevSettings cheb_;
  SystemMatrix sm_;
  double h_ = 0.0;  // h of A₁'s factor (0: none yet)
  double rho_ = 0.0;  // the Chebyshev ρ in use
  // The k iterations of a step from x0_, v0_ into v_, with ρ = rho_ (when
  // accelerated); false if an iterate is not finite, `timed_out` past the
  // run's deadline. Records each increment in increments_.
  bool Iterate(double h, int k, bool accelerate, bool* timed_out);
  double t_ = 0.0;
  Eigen::VectorXd w_;    // inverse masses, 0 for fixed particles
  MatrixN3 f_ext_;       // the constant forces (gravity) [N]
  MatrixN3 x0_, v0_, v_, v_prev_, v_hat_, x_, b0_, b_, g_, lkx_;
  std::vector<double> increments_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_PEERS_PROJECTIVE_DYNAMICS_H_
