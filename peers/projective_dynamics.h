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
// Contacts (ContactModel::kImpulses, the default): impulses in the
// global step's right-hand side, refined in every local step (Ly, Jouve,
// Bertails-Descoubes 2020; peers/contact_impulses.h) against the obstacles
// with Coulomb friction and, with `[collision] self = true`, between the
// cloth's point–triangle and edge–edge pairs; A₁ and its factor stay.
// The particles the step's list missed, and listed ones that end inside an
// obstacle (the impulses unconverged), are projected out of the obstacles
// after the iterations, and the run's self-contact response corrects the
// step's end: the fail-safes. kProjection: after the iterations, the
// positions x₀ + h v are projected out of the obstacles with friction
// (peers/position_contacts.h) and the velocity is (x₁ − x₀)/h, as XPBD's.
// Fixed particles have v = 0.
#ifndef CLOTHBENCH_PEERS_PROJECTIVE_DYNAMICS_H_
#define CLOTHBENCH_PEERS_PROJECTIVE_DYNAMICS_H_

#include <optional>
#include <string_view>

#include "model/particle_system.h"
#include "peers/contact_impulses.h"
#include "peers/iterated.h"
#include "solver/integrator.h"

namespace clothbench {

/// The integrator name used by the executables and result files.
inline constexpr std::string_view kProjectiveDynamicsName = "pd";

/// Projective dynamics with a fixed number of iterations per step
/// (peers/iterated.h: the step, Chebyshev and the obstacles).
class ProjectiveDynamics : public IteratedStepper {
 public:
  /// How a step meets obstacles and, with `[collision] self = true`, itself.
  enum class ContactModel {
    /// Ly et al. 2020's impulses in the global step (peers/contact_impulses.h),
    /// with the fail-safes after the step.
    kImpulses,
    /// The positions projected out of the obstacles after the iterations
    /// (peers/position_contacts.h), and the run's self-contact response.
    kProjection,
  };
  /// @param system the model (must outlive the stepper)
  /// @param spec its solver settings (the CHOLMOD ordering of A₁'s factor)
  /// @param iterations k ≥ 1 per step
  /// @param chebyshev acceleration (off: plain PD)
  /// @param contact the contact response
  /// @throws std::invalid_argument if iterations < 1 or the Chebyshev
  ///   settings are outside their ranges
  ProjectiveDynamics(const ParticleSystem& system, const SolverSpec& spec, int iterations,
                     ChebyshevSettings chebyshev = {}, ContactModel contact = ContactModel::kImpulses);

  /// A₁ is refactorised only when h changes (status
  /// kPreconditionerFailed if it cannot be); the solves are direct. No
  /// allocation after the first step of an h.
  int matrix_rebuilds() const override { return sm_.rebuilds(); }
  double setup_seconds() const override { return sm_.setup_seconds() + rho_seconds(); }
  /// Plain iterations of the measurement of ρ (ChebyshevSettings::rho = 0):
  /// ChebyshevRho of them, from a copy of the state at the first step of
  /// each h.
  static constexpr int kRhoIterations = kChebyshevRhoIterations;
  /// Self-contact (`[collision] self = true`): kImpulses' pairs inside the
  /// iterations; the run's response of Bridson et al. 2002 then corrects
  /// each step's end (collision/self_contact_response.h), as for
  /// Baraff–Witkin: kImpulses' fail-safe, kProjection's only response. The
  /// next step starts from the corrected state (the inertial guess keeps
  /// no history).
  bool corrects_state() const override { return true; }
  void CorrectState(const MatrixN3& x, const MatrixN3& v) override {
    x0_ = x;
    v0_ = v;
  }
  void Reset(double t, const MatrixN3& x, const MatrixN3& v) override;
  /// kImpulses: the work of the impulses and of the fail-safe projection.
  const ContactResponse::Work* contact_work() const override {
    return impulses_ ? &impulses_->work() : nullptr;
  }
  /// kImpulses with `[collision] self = true`: its pairs' counters (the
  /// run's response, the fail-safe, adds its own); else nullptr.
  const SelfContactStats* own_self_contact() const override {
    return impulses_ && impulses_->self_contact() ? &impulses_->self_stats() : nullptr;
  }

 private:
  StepStatus Prepare(double h) override;
  void BeginIterations(double h) override;
  void Iteration(double h) override;
  int BeginContacts(double h) override;
  int EndContacts(double h) override;
  SystemMatrix sm_;
  std::optional<ContactImpulses> impulses_;  // kImpulses on a scene with obstacles or self-contact
  MatrixN3 guess_;                            // kImpulses: the first iterate (after the step: x before the fail-safe)
  MatrixN3 b0_, b_, g_, lkx_;
  MatrixN3 moving_v_, coupling_;  // moving fixed particles: their step velocity V and A V
};

/// pd/chebyshev's acceleration (Wang 2015). ρ is measured in each run, at
/// the first step of each h (ProjectiveDynamics::kRhoIterations plain
/// iterations), because it depends on the scene: on the default scene at
/// h = 0.01 s the plain iteration contracts by 0.9101 per iteration at
/// t = 0.3 s (test PdChebyshev.RhoOfThePlainIteration). γ and the delay
/// were measured there with ρ fixed at 0.91: the rms difference of the
/// final positions to implicit_euler/newton after 0.5 s, with 4 / 8 / 16 /
/// 32 iterations, is 1.7e-2 / 3.9e-3 / 7.1e-4 / – m for plain PD; with
/// γ = 1, delay 1: 6.0e-2 / 3.3e-3 / 3.4e-4 / 6.6e-7; γ = 0.9, delay 2:
/// 3.9e-3 / 3.9e-3 / 2.4e-5 / 1.6e-6; γ = 1, delay 4: 1.7e-2 / 1.8e-3 /
/// 2.9e-5 / 9.1e-7 (ρ = 0.85 and 0.95 were no better at 16). γ = 0.9 with
/// delay 2 is the only setting better than plain PD at every count.
inline constexpr ChebyshevSettings kPdChebyshev{.on = true, .rho = 0.0, .gamma = 0.9, .delay = 2};

}  // namespace clothbench

#endif  // CLOTHBENCH_PEERS_PROJECTIVE_DYNAMICS_H_
