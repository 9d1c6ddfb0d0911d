// The skeleton the iterated peers share (projective dynamics, Vertex Block
// Descent; docs/model.md §10): implicit Euler in velocities, x = x₀ + h v,
// approached by a fixed number of plain iterations v ← G(v) per step from
// an initial guess (InitialGuess), with optional Chebyshev acceleration
// (peers/chebyshev.h) at a ρ measured at the first step of each h, then
// the obstacles on the positions (peers/position_contacts.h) and
// v₁ = (x₁ − x₀)/h. Fixed particles have v = 0.
#ifndef CLOTHBENCH_PEERS_ITERATED_H_
#define CLOTHBENCH_PEERS_ITERATED_H_

#include <string_view>
#include <vector>

#include "collision/obstacle_proximity.h"
#include "model/particle_system.h"
#include "peers/chebyshev.h"
#include "solver/integrator.h"

namespace clothbench {

/// The first iterate of a step.
enum class InitialGuess {
  /// v₀ + h M⁻¹ f_ext: inertia and the constant forces (Liu et al. 2013's y).
  kInertial,
  /// Chen et al. 2024 §3.7's adaptive initialisation: v₀ + h ã_p with
  /// ã_p = clamp(a_p · â_p / |a_p^ext|, 0, 1) a_p^ext, a_p = (v₀ − v₋₁)/h₋₁
  /// the last step's acceleration and a_p^ext = f_ext,p/m_p (gravity);
  /// the inertial guess at the first step after a Reset. As Gaia ships it
  /// (Simulator/Modules/VBD/VBD_BaseMaterial.cpp,
  /// VBDBaseTetMesh::forwardStep, initializationType 6).
  kAdaptive,
  /// The better of kAdaptive's guess and the constant-acceleration
  /// extrapolation v₀ + (h/h₋₁)(v₀ − v₋₁) (the predictor of the thesis'
  /// multistep methods, docs/model.md §5): the one with the smaller
  /// implicit Euler residual ‖M^{-1/2}(M(v − v₀) − h f(t₁, x₀ + h v, v))‖
  /// over the free particles. The extrapolation follows a swinging or
  /// hanging sheet's internal accelerations, which kAdaptive (gravity only)
  /// leaves to the iterations; at an impact or after the obstacle
  /// projection v₋₁ → v₀ jumps and its residual is the larger, so the
  /// adaptive guess is kept. Two force evaluations per step.
  kSafeguardedExtrapolation,
};

/// How a step meets the obstacles.
enum class ObstacleResponse {
  /// After the iterations the positions are projected out of the
  /// obstacles with friction, v = (x₁ − x₀)/h (peers/position_contacts.h).
  kProjection,
  /// The implicit methods' response (solver/contact.h; thesis (4.3), (4.4)):
  /// contacts set up from the step's start, each contact's normal velocity
  /// prescribed in every iterate (the local steps move only in the free
  /// directions), explicit Coulomb friction in the forces, release from
  /// the constraint impulse after the step. The iteration's fixed point is
  /// then the implicit Euler step with the same filter.
  kVelocityFilter,
  /// The stepper's own contact inside its iterations (projective dynamics'
  /// impulses, peers/contact_impulses.h): BeginContacts before the step's
  /// iterations, EndContacts after them.
  kOwn,
};

class IteratedStepper : public Stepper {
 public:
  void Reset(double t, const MatrixN3& x, const MatrixN3& v) override;
  /// The contact response's work (kVelocityFilter on a scene with obstacles), else nullptr.
  const ContactResponse::Work* contact_work() const override {
    return response_ == ObstacleResponse::kVelocityFilter && contacts_.active() ? &contacts_.work() : nullptr;
  }
  /// One step of size h [s]: Prepare when h changes (and ρ measured from
  /// RhoSweeps plain iterations on a copy of the state, if the settings
  /// ask for it and a step extrapolates at all; both count as the step's
  /// setup), k iterations,
  /// then the obstacles. stats.updates = k, cg_iterations = 0, colliding
  /// = particles projected out of an obstacle. Status kNonFinite (state
  /// unchanged) if an iterate is not finite, kTimeLimit past the run's
  /// deadline, Prepare's status if it fails.
  StepStats Step(double h) override;
  double t() const override { return t_; }
  /// A moving fixed particle (w = 0) takes the velocity that ends the step
  /// at its prescribed position; PD moves it to the global step's
  /// right-hand side (a Dirichlet condition).
  bool follows_prescribed_motion() const override { return true; }
  /// Its ContactResponse adds the explicit friction to the iterates' forces.
  bool explicit_friction_only() const override { return true; }
  /// kKrylov: ρ's measurement takes a tenth of the run's sweeps
  /// (RhoSweeps); its sketch is allocated here, before the run.
  void PlanRun(double t_end, double h) override;
  /// The plain sweeps of a ρ measurement. kKrylov: a tenth of the planned
  /// run's sweeps (⌈t_end/h⌉·iterations; PlanRun), at least kKrylovRhoMin
  /// and at most rho_iterations; rho_iterations without a plan.
  /// kIncrementRatio: rho_iterations.
  int RhoSweeps() const;
  static constexpr int kKrylovRhoMin = 32;
  void SetTime(double t) override { t_ = t; }
  const MatrixN3& x() const override { return x0_; }
  const MatrixN3& v() const override { return v0_; }
  bool single_update() const override { return true; }

  int iterations() const { return iterations_; }
  /// The ρ the acceleration uses (the measured one once a step has run;
  /// 0 before, or without Chebyshev).
  double rho() const { return rho_; }
  /// Plain iterations of the ρ measurements since construction.
  int rho_sweeps() const { return rho_sweeps_; }
  /// ‖v^{k+1} − v^k‖ of each iteration of the last step (plain or
  /// accelerated), for measuring the contraction ρ.
  const std::vector<double>& last_increments() const { return increments_; }

 protected:
  /// @param name the row's name, for the error messages
  /// @param rho_iterations plain iterations of the measurement of ρ
  ///   (kKrylov: the most, RhoSweeps)
  /// @throws std::invalid_argument if iterations < 1 or the Chebyshev
  ///   settings are outside their ranges
  /// @param initial_guess the first iterate of each step
  /// @param response how the step meets the obstacles
  /// @param rho_estimate how ρ is measured: kIncrementRatio from
  ///   rho_iterations increments' norms; kKrylov from RhoSweeps
  ///   increments' sketches, 0 if one is at round-off before
  IteratedStepper(const ParticleSystem& system, std::string_view name, int iterations, ChebyshevSettings chebyshev,
                  int rho_iterations, InitialGuess initial_guess,
                  ObstacleResponse response = ObstacleResponse::kProjection,
                  RhoEstimate rho_estimate = RhoEstimate::kIncrementRatio);
  /// kKrylov: the sketch keeps at most this many coordinates of each
  /// increment, a strided selection of the free particles' coordinates
  /// (the slow modes are smooth over the sheet). The default scene keeps
  /// all its 1,200; on a 10⁴ sheet, where 96 sweeps leave the estimate
  /// unconverged, 4,286 of 30,000 coordinates give 0.9981 and half of
  /// them 0.9991 (the selection then matters at the 1e-3 level).
  static constexpr int kKrylovRhoRows = 4096;
  /// Called when h changes, before ρ is measured (a factorisation); its
  /// status ends the step unless kOk.
  virtual StepStatus Prepare(double /*h*/) { return StepStatus::kOk; }
  /// Called at the start of each step's iterations, after v_ is the
  /// initial guess (the constant part of a right-hand side).
  virtual void BeginIterations(double /*h*/) {}
  /// One plain iteration v_ ← G(v_) at t₁ = t + h, in place; x_ is not
  /// kept (the iteration sets x_ = x₀ + h v_ itself where it reads it).
  virtual void Iteration(double h) = 0;
  /// Called after each iteration, after the Chebyshev update of v_ (a
  /// stepper's own self-contact bounds the iterate here).
  virtual void AfterIteration(double /*h*/) {}
  /// kOwn: the step's contact list, before ρ's measurement and the
  /// iterations of a step of h [s]. @return the listed contacts
  virtual int BeginContacts(double /*h*/) { return 0; }
  /// kOwn: after the iterations, with x_ = x₀ + h v_ (both may be
  /// corrected: a fail-safe). @return the contacts that acted
  virtual int EndContacts(double /*h*/) { return 0; }
  /// The first iterate of InitialGuess::kInertial, v₀ + h M⁻¹ f_ext, into *v (N×3 [m/s]).
  void InertialVelocity(double h, MatrixN3* v) const { v->noalias() = v0_ + h * (w_.asDiagonal() * f_ext_); }
  /// kVelocityFilter, kOwn: the positions one step earlier (N×3 [m]), or
  /// nullptr at the first step after a Reset.
  const MatrixN3* previous_positions() const { return have_history_ ? &xm1_ : nullptr; }
  /// The obstacles' entries at a step's end (kProjection and the
  /// fail-safe of kOwn; collision/obstacle_proximity.h), Reset with the stepper.
  ObstacleProximity* proximity() { return &proximity_; }
  /// Time of the ρ measurements so far [s].
  double rho_seconds() const { return rho_seconds_; }

  /// The step's explicit contact forces (Coulomb friction) [N], N×3, or
  /// nullptr where there are none (kProjection, or no obstacle).
  const MatrixN3* contact_forces() const {
    return response_ == ObstacleResponse::kVelocityFilter && contacts_.active() ? &contacts_.friction() : nullptr;
  }
  /// Particle p's local Newton step from its velocity vp [m/s] with the
  /// residual r [kg m/s] of its row and that row's Jacobian j [kg]: vp −
  /// j⁻¹ r, or, where the velocity filter constrains p, the step that sets
  /// the constrained components to their targets and solves j's row in
  /// the free directions only. False (vp unchanged) if the solved block is
  /// singular (below 1e-12 of its scale).
  bool LocalStep(int p, const Matrix3& j, const Vector3& r, Vector3* vp) const;

  const ParticleSystem& sys_;
  double t_ = 0.0;
  Eigen::VectorXd w_;  // inverse masses, 0 for fixed particles
  MatrixN3 x0_, v0_, v_, x_;

 private:
  int iterations_;
  ChebyshevSettings cheb_;
  int rho_iterations_;
  double h_ = 0.0;    // h of the last step (0: none yet)
  double rho_ = 0.0;  // the Chebyshev ρ in use
  double rho_seconds_ = 0.0;
  int rho_sweeps_ = 0;
  long planned_sweeps_ = 0;  // PlanRun's sweeps of the run (0: no plan)
  int rho_measure_ = 0;      // the sweeps of the measurement under way
  RhoEstimate rho_estimate_;
  std::vector<Eigen::Index> sketch_index_;  // kKrylov: the coordinates (of MatrixN3's data) the sketch keeps
  Eigen::MatrixXd sketch_;                  // kKrylov: column k the sketch of the k-th increment
  // ρ's measurement after plain iteration k (0-based) of its run: records
  // the increment and returns true once ρ is known (rho_ set), false to go on.
  bool MeasureRhoAfter(int k, double h);
  MatrixN3 f_ext_;    // the constant forces (gravity) [N]
  MatrixN3 v_start_, v_prev_;
  InitialGuess initial_guess_;
  MatrixN3 v_last_;           // kAdaptive, kSafeguardedExtrapolation: v at the start of the last step
  double h_last_step_ = 0.0;  // its h; 0: no step since the Reset
  MatrixN3 v_guess_, x_guess_, f_guess_;  // the extrapolation and the residuals' buffers
  ObstacleResponse response_;
  ContactResponse contacts_;              // kVelocityFilter
  ObstacleProximity proximity_;           // kProjection, kOwn's fail-safe
  VelocityFilter filter_;                 // kVelocityFilter: the step's fixed particles and contacts
  std::vector<int> constraint_;           // kVelocityFilter: per particle, its contact's index in constraints_ (−1: none)
  struct LocalConstraint {
    int count;        // constrained directions (1 or 2)
    Matrix3 dirs;     // orthonormal, in the first `count` columns
    Vector3 targets;  // prescribed velocity along each [m/s]
  };
  std::vector<LocalConstraint> constraints_;
  MatrixN3 xm1_;              // kVelocityFilter, kOwn: positions one step earlier ((4.4)'s history, the tunnelling test)
  bool have_history_ = false;
  // kVelocityFilter: the step's contacts from x0_, v0_ (ContactResponse::SetUp); returns the colliding count.
  int SetUpContacts(double h);
  // kVelocityFilter: reads the constraint impulses after the iterations (ContactResponse::ReadImpulses).
  void ReadContactImpulses(double h);
  // The first iterate of a step into v_ (InitialGuess); `rho_start`: the
  // start of ρ's measurement, perturbed so that every mode is excited.
  void StartIterate(double h, bool rho_start);
  // ‖M^{-1/2} r(v)‖² of the implicit Euler residual r(v) = M(v − v₀) −
  // h f(t + h, x₀ + h v, v) over the free particles.
  double ResidualNorm2(double h, const MatrixN3& v);
  std::vector<double> increments_;
  // The k iterations of a step from x0_, v0_ into v_, with ρ = rho_ when
  // accelerated; false if an iterate is not finite, `timed_out` past the
  // run's deadline. `rho_start`: ρ's measurement (StartIterate).
  bool Iterate(double h, int k, bool accelerate, bool rho_start, bool* timed_out);
};

}  // namespace clothbench

#endif  // CLOTHBENCH_PEERS_ITERATED_H_
