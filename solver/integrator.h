// The step engine: IMEX Euler, implicit Euler, SBDF(2), BDF(2) and implicit
// midpoint for the split ODE (3.20), all through the fixed-point loop of
// Alg. 6 with the filtered PCG (docs/model.md §3–6). Every method solves
//   A_α v₁ = b₀ + β h g(t_g, x_g(v₁), v_g(v₁)),  A_α = M + α²h² L_K + αh L_D  (3.24, 3.31)
// with positions x₁ = x̂ + γ h v₁. IMEX methods do one update per step; the
// fully implicit ones iterate to convergence, either with Alg. 6 (a
// simplified Newton method with approximate Jacobian A_α, §3.4.3) or with
// Newton's method on the tangent system J_α (docs/model.md §10, solver/tangent.h).
#ifndef CLOTHBENCH_SOLVER_INTEGRATOR_H_
#define CLOTHBENCH_SOLVER_INTEGRATOR_H_

#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "collision/self_contact_response.h"
#include "model/particle_system.h"
#include "solver/record/run_status.h"
#include "solver/contact.h"
#include "solver/pcg.h"
#include "solver/scheme.h"
#include "solver/tangent.h"

namespace clothbench {

/// The five thesis integrators, the explicit baseline symplectic Euler
/// (semi-implicit Euler: v₁ = v₀ + h M⁻¹ f(t₀, x₀, v₀), x₁ = x₀ + h v₁), and
/// SBDF(3), the third-order IMEX BDF of Ascher, Ruuth & Wetton (1995):
/// BDF3 on the linear part, g extrapolated to third order,
///   x₁ = x̂ + (6/11) h v₁,  A_{6/11} v₁ = M v̂ − (6/11) h L_K x̂ + (6/11) h ĝ,
/// x̂ = (18 x₀ − 9 x₋₁ + 2 x₋₂)/11 (v̂ likewise), ĝ = 3 g₀ − 3 g₋₁ + g₋₂,
/// for three equal steps; it starts with one IMEX midpoint step (two
/// updates of the midpoint rule, local error O(h³)) and one SBDF(2) step,
/// and takes an SBDF(2) step wherever the last three steps differ.
enum class Method { kImexEuler, kImplicitEuler, kSbdf2, kBdf2, kImplicitMidpoint, kSymplecticEuler, kSbdf3 };
/// Every method of the step engine, in the enum's order.
inline constexpr Method kEngineMethods[] = {Method::kImexEuler,        Method::kImplicitEuler,   Method::kSbdf2,
                                            Method::kBdf2,             Method::kImplicitMidpoint, Method::kSymplecticEuler,
                                            Method::kSbdf3};
/// The method's registry name: its scheme's (Scheme::name, solver/schemes/).
std::string_view ToString(Method m);
/// Parses a name ToString gives.
std::optional<Method> MethodFromString(std::string_view s);
/// The five integrators of the thesis' tables (Tables 3.1, 3.2), in their
/// order; the step engine has two more (SBDF(3), symplectic Euler).
const std::vector<Method>& ThesisTableMethods();
/// IMEX methods (IMEX Euler, SBDF(2), SBDF(3)) do exactly one update per
/// step (SBDF(3)'s start step two).
bool IsImex(Method m);
/// Fully implicit methods (implicit Euler, BDF(2), implicit midpoint) iterate
/// with a nonlinear solver (fixed point or Newton).
bool IsFullyImplicit(Method m);

/// Variable-step BDF(2) coefficients for ω = h_n/h_{n−1} (docs/model.md §4, (3.28)–(3.32)):
/// x₁ = c1 x₀ − c2 x₋₁ + c3 h ẋ₁ with c1 = (1+ω)²/(1+2ω), c2 = ω²/(1+2ω),
/// c3 = (1+ω)/(1+2ω); 4/3, 1/3, 2/3 at ω = 1.
struct Bdf2Coefficients {
  explicit Bdf2Coefficients(double omega)
      : c1((1 + omega) * (1 + omega) / (1 + 2 * omega)),
        c2(omega * omega / (1 + 2 * omega)),
        c3((1 + omega) / (1 + 2 * omega)) {}
  double c1, c2, c3;
};

/// Why a step failed. kFixedPointDiverged: the fixed-point iterates of a
/// fully implicit method became non-finite (the iteration diverged);
/// kNonFinite: the step's result itself is not finite (a blow-up).
/// kNoNewtonConvergence, kNewtonDiverged: the same for the Newton iteration.
/// kErrorTestFailed: step_control = "error" and the local error estimate
/// exceeded the tolerance (StepStats::error_norm > 1).
enum class StepStatus {
  kOk,
  kCgFailed,
  kNoFixedPointConvergence,
  kNonFinite,
  kPreconditionerFailed,
  kFixedPointDiverged,
  kNoNewtonConvergence,
  kNewtonDiverged,
  kErrorTestFailed,
  kTimeLimit  ///< the run's wall-clock deadline passed inside the step (model/interrupt.h)
};
std::string_view ToString(StepStatus s);
/// The run's status when a step fails with `s` and cannot be retried
/// (kOk for kOk): the RunStatus of the same name.
RunStatus RunStatusOf(StepStatus s);

/// Statistics of one attempted step (docs/model.md §6).
struct StepStats {
  double t = 0.0;          ///< time at the end of the step [s]
  double h = 0.0;          ///< step size [s]
  int updates = 0;         ///< fixed-point or Newton updates: evaluations of g, each with its linear solve (the last one only checks the residual)
  int cg_iterations = 0;   ///< PCG iterations summed over the updates
  int colliding = 0;       ///< particles constrained by obstacles in this step (Fig. 4.3)
  /// What preconditioned the step's last solve (Preconditioner::ServedBy):
  /// 0 the scene's preconditioner of A_F (factor, hierarchy, IC(0), …),
  /// 1 the contact factors, 2 the prefiltered AMG, 3 the contact factor in
  /// contact frames.
  int preconditioner = 0;
  StepStatus status = StepStatus::kOk;
  double solve_time = 0.0; ///< wall time of the attempt in the step engine [s], setup of A and P included
  double setup_time = 0.0; ///< part of solve_time spent refreshing A_α, J_α and their preconditioners [s]
  PcgStatus pcg_status = PcgStatus::kConverged;  ///< of the last PCG solve (why kCgFailed)
  /// Weighted RMS norm of the local error estimate (≤ 1 passes the error
  /// test); −1 when the stepper does not estimate it.
  double error_norm = -1.0;
  /// Order q of the estimated local error's leading term, O(h^{q+1}): 2 for
  /// BDF(2), 1 for its start step. The controller's exponent is 1/(q+1).
  int error_order = 0;
};

/// A_α = M + α²h² L_K + αh L_D on a fixed pattern, with its preconditioner,
/// recomputed only when α·h changes (docs/model.md §3). The pattern and the
/// preconditioner's symbolic phase (IC(0) pattern, CHOLMOD analysis) are set
/// up once, in the constructor. No allocation after construction, except
/// inside CHOLMOD and hypre when αh changes.
class SystemMatrix {
 public:
  SystemMatrix(const ParticleSystem& system, PreconditionerType type,
               CholeskyOrdering ordering = CholeskyOrdering::kMetis, bool contact_factors = false);
  /// Makes A and P current for the product αh. Returns false if the
  /// preconditioner could not be built.
  bool Update(double alpha_h);
  /// Makes P's contact factors match the constraints of `filter` (after
  /// Update; Preconditioner::AdaptTo). Their time counts as setup.
  /// @return false if a factorisation failed
  bool AdaptTo(const VelocityFilter& filter);
  /// Removes the couplings of the springs that virtual particles split
  /// this step from A (A(a, b) += α²h² s + αh c, both triangles; after
  /// Update, whose αh it uses, and Restore). The preconditioner stays that of
  /// A without them: a change of rank 2 per split spring, which the PCG
  /// absorbs in a few iterations.
  void RemoveCouplings(const std::vector<RemovedCoupling>& couplings);
  /// Restores the values RemoveCouplings and AddToDiagonal changed since
  /// the last Update or Restore: A as Update made it. Once per step, after
  /// Update.
  void Restore();
  /// A(p, p) += value [kg] (after Update and Restore; undone by the next
  /// Restore). The preconditioner stays that of A without it: the PCG
  /// absorbs a diagonal change. No allocation after the first steps.
  void AddToDiagonal(int p, double value);
  /// Factorises the preconditioner again for A as it is now.
  bool Refactorize();
  /// Room for `count` changes between Restores without allocating.
  void ReserveChanges(int count) { removed_.reserve(static_cast<std::size_t>(count)); }
  const SparseMatrix& matrix() const { return a_; }
  const Preconditioner& preconditioner() const { return precond_; }
  /// The prefiltered AMG's frame rule (Preconditioner::set_amg_frames).
  void set_amg_frames(AmgFrames frames) { precond_.set_amg_frames(frames); }
  /// Whether contact factors in contact frames may serve (Preconditioner::set_frame_factors).
  void set_frame_factors(bool on) { precond_.set_frame_factors(on); }
  /// The prefiltered AMG's diagnostics (Preconditioner::set_amg_diagnostics).
  void set_amg_diagnostics(Preconditioner::AmgDiagnostics d) { precond_.set_amg_diagnostics(d); }
  int rebuilds() const { return rebuilds_; }
  /// Wall time [s] of the matrix assembly and the preconditioner's setup:
  /// pattern and symbolic analysis, plus every numeric factorisation (or
  /// AMG setup) so far.
  double setup_seconds() const { return setup_seconds_; }
  /// The part of setup_seconds() spent once, in the constructor: pattern and
  /// symbolic analysis (for "cholesky" the fill-reducing ordering).
  double analysis_seconds() const { return analysis_seconds_; }

 private:
  SparseMatrix a_;
  Eigen::VectorXd m_vals_, lk_vals_, ld_vals_;  // M, L_K, L_D on A's pattern
  std::vector<std::pair<int, double>> removed_;  // value positions changed by RemoveCouplings, old values
  Preconditioner precond_;
  double alpha_h_ = -1.0;
  int rebuilds_ = 0;
  bool analyzed_ = false;
  double setup_seconds_ = 0.0;
  double analysis_seconds_ = 0.0;
};

/// FrictionLaw::kImplicit (model/solver_spec.h): whether a step factorises
/// A_α's preconditioner again with its friction rates on the diagonal.
/// Left to the PCG, large rates (a particle friction holds: c up to
/// μ J_N/(h v_ε)) cost it up to ten times the iterations (avatar_drape);
/// at 10⁴ particles a refactorisation can cost more than it saves
/// (docs/notes/collisions.md, "Implicit friction"). Counts, not times, so
/// that a run repeats bit for bit: the CG iterations of the solves of
/// steps with and without a refactorisation (means with weight 1/2 on
/// the latest), and a refactorisation while it saved more than it costs
/// (Preconditioner::RefactorIterations); every kProbeSteps-th step measures
/// the other choice again.
class RefactorChoice {
 public:
  static constexpr long kProbeSteps = 16;
  /// For the next step: refactorise, at a price of `price` CG iterations
  /// (Preconditioner::RefactorIterations)?
  bool Choose(double price) {
    ++steps_;
    if (fresh_ < 0.0) return true;
    if (stale_ < 0.0) return false;
    const bool refactor = stale_ - fresh_ > price;
    return steps_ % kProbeSteps == 0 ? !refactor : refactor;
  }
  /// The CG iterations of a step's solves, with a refactorisation or without.
  void Count(bool refactored, int iterations) {
    double& mean = refactored ? fresh_ : stale_;
    mean = mean < 0.0 ? iterations : 0.5 * (mean + iterations);
  }

 private:
  double fresh_ = -1.0, stale_ = -1.0;  // −1: not measured yet
  long steps_ = 0;
};

/// What a stepper that chooses its own internal steps (a SUNDIALS
/// integrator, sundials/sundials_common.h) adds to the run loop
/// (RunStepper). Its Step(h) takes one internal step of its own size and
/// ignores h; the loop neither plans, retries nor controls its steps. A
/// failed Step ends the run (Failure). After the step's checks the loop
/// stores the frames inside the step from its dense output (StateAt),
/// then asks for the step's jumps (EndStep: an event's reaction, its
/// self-contact response), which restart the integrator; a stepper that
/// stops at every frame stores its frames after EndStep instead.
class InternalSteps {
 public:
  virtual ~InternalSteps() = default;
  /// Whether every step ends at the next frame at the latest, and the
  /// frames are the states after EndStep (self-contact corrects the steps).
  virtual bool stops_at_frames() const = 0;
  /// The state at time t [s] inside the last step, before its jumps (dense
  /// output): N×3 x [m], v [m/s]. False with the run's status and message
  /// if the library refuses.
  virtual bool StateAt(double t, MatrixN3* x, MatrixN3* v, RunStatus* status, std::string* message) = 0;
  /// The last step's jumps; false with the run's status and message if a
  /// restart fails.
  virtual bool EndStep(RunStatus* status, std::string* message) = 0;
  /// The run's status and message after a failed Step.
  virtual void Failure(RunStatus* status, std::string* message) const = 0;
  /// W_contact [J] since t = 0 that the blow-up guard's energy balance
  /// counts: the self-contact response's work (its events only remove energy).
  virtual double counted_contact_work() const = 0;
};

/// A one-step-at-a-time integrator of a particle system, as the run driver
/// (solver/run.h) and the stability maps use it: the thesis' methods
/// (StepEngine), the peers (peers/) and the SUNDIALS rows alike.
class Stepper {
 public:
  virtual ~Stepper() = default;
  /// Sets the state at time t [s] (N×3 positions x [m], velocities v [m/s])
  /// and forgets any history.
  virtual void Reset(double t, const MatrixN3& x, const MatrixN3& v) = 0;
  /// Attempts one step of size h [s]; on failure the state is unchanged and
  /// stats.status says why. No allocation.
  virtual StepStats Step(double h) = 0;
  virtual double t() const = 0;
  /// Sets the clock to t [s] without touching the state or the history. The
  /// run driver puts a fixed-step run back on its grid t₀ + n·h after every
  /// step, so that the clock does not drift by the round-off of summing h.
  virtual void SetTime(double t) = 0;
  virtual const MatrixN3& x() const = 0;
  virtual const MatrixN3& v() const = 0;
  /// True if every step does exactly one update (IMEX, linearised methods):
  /// the iteration-count controller then keeps h.
  virtual bool single_update() const = 0;
  /// Rebuilds of the system matrix's preconditioner so far.
  virtual int matrix_rebuilds() const = 0;
  /// Setup time so far [s]: assembly, analysis, factorisations.
  virtual double setup_seconds() const = 0;
  /// Obstacle contact detection time so far [s] (ContactResponse::SetUp);
  /// < 0: a stepper without that response.
  virtual double contact_detection_seconds() const { return -1.0; }
  /// True if Step() estimates its local error (StepStats::error_norm) and
  /// rejects a step whose estimate fails the test: the run driver then
  /// controls h by the error (SolverSpec::step_control = "error").
  virtual bool estimates_error() const { return false; }
  /// Work of the contact response since Reset [J] (ContactResponse::work),
  /// or nullptr if the stepper has no contact response of ours.
  virtual const ContactResponse::Work* contact_work() const { return nullptr; }
  /// If the last step ended at a located contact event whose jumps changed
  /// the state: the state just before them (the trajectory's left limit at
  /// the step's end, N×3 [m], [m/s]), which the frames inside the step
  /// interpolate to. Else false.
  /// Contact events located since Reset (instants at which the contact
  /// set changed under event location), or −1 if the stepper does not
  /// locate them.
  virtual long events() const { return -1; }
  /// Whether CorrectState can replace the state after a step (the
  /// self-contact response, collision/self_contact_response.h, corrects a
  /// step's end). A stepper without it is refused on a scene with
  /// `[collision] self = true` (status unsupported_scene).
  virtual bool corrects_state() const { return false; }
  /// Whether Step moves the fixed particles of `[[constraints.motion]]`
  /// along their prescribed motion (ParticleSystem::ForEachPrescribed). A
  /// stepper without it is refused on such a scene (unsupported_scene).
  virtual bool follows_prescribed_motion() const { return false; }
  /// Whether Step applies the thesis' explicit friction at the obstacles
  /// whatever solver.friction_law says (model/solver_spec.h, FrictionLaw).
  /// Such a stepper is refused on a scene that asks for another law and
  /// has an obstacle with friction (unsupported_scene). Steppers with a
  /// friction of their own (XPBD's constraints, the SUNDIALS rows'
  /// continuous law), which the key does not govern, are not.
  virtual bool explicit_friction_only() const { return false; }
  /// The counters of the stepper's own self-contact on a scene with
  /// `[collision] self = true` (a position-based peer's constraints inside
  /// its step, peers/position_contacts.h), since Reset; nullptr where it
  /// has none (the run's response corrects the step instead, where
  /// corrects_state()).
  virtual const SelfContactStats* own_self_contact() const { return nullptr; }
  /// Replaces the state at t() after an accepted step by (x, v) (N×3 [m],
  /// [m/s]), keeping the history the next step uses (a multistep method's
  /// x₋₁, v₋₁). Only where corrects_state().
  virtual void CorrectState(const MatrixN3& x, const MatrixN3& v) {
    (void)x;
    (void)v;
  }
  virtual bool LeftLimit(const MatrixN3** x, const MatrixN3** v) const {
    (void)x;
    (void)v;
    return false;
  }
  /// Where the stepper chooses its own internal steps: what the run loop
  /// asks of it besides (InternalSteps); nullptr for steppers the loop steps.
  virtual InternalSteps* internal_steps() { return nullptr; }
  /// The run ahead: steps of h [s] to t_end [s] from the next Reset (the
  /// run driver says so before it; an iterated peer sizes its ρ
  /// measurement by it). Default: ignored.
  virtual void PlanRun(double t_end, double h) {
    (void)t_end;
    (void)h;
  }
};

/// Advances the state of a particle system step by step with one of the
/// thesis' methods: the machinery they share (contacts, the velocity
/// system and its preconditioner, the fixed point, Newton, error control,
/// event location) around the method's formula, its Scheme
/// (solver/scheme.h, one file per method in solver/schemes/). Fixed
/// particles are held by the velocity filter (zero velocity).
class StepEngine : public Stepper {
 public:
  /// @param system the model (must outlive the engine)
  /// @param method the integrator
  /// @param solver CG tolerance, preconditioner, update limits, predictor
  StepEngine(const ParticleSystem& system, Method method, const SolverSpec& solver);

  /// Sets the state at time t [s] with N×3 positions x [m] and velocities v
  /// [m/s] and forgets the history (multistep methods restart: SBDF(2) with
  /// IMEX Euler, BDF(2) with implicit Euler, docs/model.md §4).
  void Reset(double t, const MatrixN3& x, const MatrixN3& v) override;

  /// Attempts one step of size h [s]. On success the state advances; on
  /// failure it is unchanged and stats.status says why. No allocation.
  StepStats Step(double h) override;

  double t() const override { return t_; }
  void SetTime(double t) override { t_ = t; }
  const MatrixN3& x() const override { return x0_; }
  const MatrixN3& v() const override { return v0_; }
  bool single_update() const override { return scheme_.imex(); }
  /// SBDF(2) and BDF(2) with step_control = "error".
  bool estimates_error() const override { return error_control_; }
  int matrix_rebuilds() const override { return sysmat_.rebuilds(); }
  const ContactResponse::Work* contact_work() const override {
    return contacts_.active() ? &contacts_.work() : nullptr;
  }
  double setup_seconds() const override { return sysmat_.setup_seconds() + tangent_setup_seconds_; }
  double contact_detection_seconds() const override { return contacts_.setup_seconds(); }
  long events() const override { return event_location_ ? events_ : -1; }
  bool corrects_state() const override { return true; }
  bool follows_prescribed_motion() const override { return true; }
  /// The explicit terms at the old end state are recomputed (g₀). A
  /// multistep formula's past velocities move with the correction's jump
  /// v − v₀, so that v̂ = Σ a_k v₋ₖ (Σ a_k = 1) carries it once: left as
  /// they were, the formula read the jump as an acceleration and repeated
  /// a share of it in every later step (BDF(2): c2 = 1/3 of it, then a
  /// third of that, in all Δv/2 more; SBDF(3) 5Δv/6). The positions are
  /// kept: a correction moves x₀ with its step's mean velocity (the
  /// self-contact response, collision/self_contact_response.h), which the
  /// position formula then continues.
  void CorrectState(const MatrixN3& x, const MatrixN3& v) override {
    if (past_ > 0) {
      vm1_ += v - v0_;
      if (vm2_.rows() > 0) vm2_ += v - v0_;
    }
    x0_ = x;
    v0_ = v;
    have_g0_ = false;
  }
  bool LeftLimit(const MatrixN3** x, const MatrixN3** v) const override {
    if (!jumped_) return false;
    *x = &x_left_;
    *v = &v_left_;
    return true;
  }
  Method method() const { return method_; }
  const ParticleSystem& system() const { return sys_; }
  /// out = L x with L = L_K (or L_D if `damping`) less this step's removed
  /// couplings (the schemes' stages, solver/scheme.h).
  void LinearProduct(bool damping, const MatrixN3& x, MatrixN3* out) const;
  const SystemMatrix& system_matrix() const { return sysmat_; }
  /// Whether contact factors in contact frames may serve (SystemMatrix::set_frame_factors).
  void set_frame_factors(bool on) { sysmat_.set_frame_factors(on); }
  /// The prefiltered AMG's diagnostics (Preconditioner::set_amg_diagnostics).
  void set_amg_diagnostics(Preconditioner::AmgDiagnostics d) { sysmat_.set_amg_diagnostics(d); }
  /// Residual of the last PCG solve, ‖S(b − A v)‖₂.
  double last_residual() const { return last_pcg_.residual_norm; }
  /// Whether the fully implicit method iterates with Newton (J_α).
  bool newton() const { return tangent_ != nullptr; }

 private:
  StepStats StepImpl(double h);
  /// g = the explicit terms at (t, x, v) as this engine splits them: with
  /// the couplings the virtual particles remove added back (their matrix
  /// has them removed, RemovedCoupling).
  void EngineExplicitForces(double t, const MatrixN3& x, const MatrixN3& v, MatrixN3* g) const;
  /// The formula this step takes (Scheme::ForStep: the start steps of the
  /// multistep methods).
  const Scheme& StepScheme(double h) const;
  /// Sets x̂, v̂, x̂_g and b₀ of `scheme` at step h (ω = h/h₋₁) and returns
  /// its coefficients (thesis (3.22)–(3.36)).
  StageCoefficients PrepareStage(const Scheme& scheme, double h, double omega);
  /// g₀ = g(t₀, x₀, v₀) if not yet evaluated, and the explicit terms g of
  /// the step (Scheme::Extrapolate).
  void ExplicitTerms(const Scheme& scheme, double omega);
  /// The fixed-point loop (Alg. 6) from the predictor v₁ with `scheme`'s
  /// updates: returns true when converged; on failure st->status says why.
  bool FixedPointIterate(double h, const StageCoefficients& c, const Scheme& scheme, bool fixed_only_norm,
                         PcgOptions pcg_opts, StepStats* st);
  /// One attempt at a step of size h: the contacts, the stage and its
  /// solve, x₁. Commits nothing. @return the step's statistics with its status
  StepStats Solve(double h);
  /// Solve, again while the active set releases stiction's holds or the
  /// implicit friction leaves its cone (ContactResponse::ReviseHolds), at
  /// most ContactResponse::kHoldRevisions more times.
  StepStats SolveHolding(double h);
  /// Row p of A v₁ − b of the solve just done [kg m/s] (A symmetric: row p is column p).
  Vector3 ResidualRow(int p) const;
  /// The error test, the contact impulses and the commit of the solved
  /// step (x1_, v1_). @return st with its status
  StepStats FinishStep(double h, StepStats st);
  /// Newton's method for v₁ (docs/model.md §10): F(v) = A_α v − b₀ − βh g(t_g, x_g(v), v_g(v)),
  /// J_α δ = −F on the free directions. Returns true when converged; on
  /// failure st->status says why.
  bool NewtonIterate(double h, double alpha, double beta, double gamma_g, double t_g, bool midpoint,
                     bool fixed_only_norm, StepStats* st);
  StepStats ExplicitStep(double h, StepStats st);
  /// Accepts (x1_, v1_) as the new state if finite; shifts the history.
  bool Commit(double h);
  /// Local error estimate of the step just solved (x1_, v1_), weighted RMS
  /// norm against rtol/atol (docs/notes/work-precision.md); `order` gets the
  /// estimate's order q (local error O(h^{q+1})).
  double ErrorNorm(double h, int* order);
  const ParticleSystem& sys_;
  Method method_;
  const Scheme& scheme_;  // method_'s formula (SchemeOf)
  SolverSpec opts_;
  SystemMatrix sysmat_;
  Eigen::VectorXd friction_diagonal_;   // FrictionLaw::kImplicit: h c_p [kg] of this step (N; empty under the other laws)
  bool friction_diagonal_set_ = false;  // whether any is nonzero
  bool revising_ = false;               // a solve again of the same step (SolveHolding)
  HistoryCarry carry_;                  // of the step's formula, for the contact work (ReadImpulses)
  bool friction_step_ = false;          // this step's first solve has friction rates, or the last step had
  bool refactored_ = false;             // and its preconditioner was factorised again with them
  RefactorChoice refactor_choice_;
  VelocityFilter filter_;
  ContactResponse contacts_;
  PcgWorkspace work_;
  // Newton (nonlinear_solver = "newton" on a fully implicit method only).
  std::unique_ptr<TangentSystem> tangent_;
  TangentPreconditioner tangent_pre_;
  TangentPcgWorkspace tangent_work_;
  MatrixN3R vr_, br_;
  double tangent_setup_seconds_ = 0.0;

  double t_ = 0.0;
  MatrixN3 x0_, v0_;             // current state
  MatrixN3 xm1_, vm1_, gm1_;     // previous state and g there (multistep)
  double h_prev_ = 0.0;
  // Accepted steps since the last restart (Reset, a changed contact set),
  // capped at 2: the past states the multistep formulas and the error
  // estimate have.
  int past_ = 0;
  bool virtual_before_ = false;  // the last step had virtual particles
  // ContactHistory::kRestart: which particles the obstacles constrained in
  // this step and the previous one (allocated once, multistep methods only).
  std::vector<char> in_contact_, in_contact_prev_;
  bool ContactSetChanged();
  void ProjectContactHistory();                // ContactHistory::kProject
  void LandContactTargets(double h, double gamma);  // ContactHistory::kLand
  bool have_g0_ = false;         // g0_ holds g(t0, x0, v0)
  bool error_control_ = false;   // SBDF(2)/BDF(2) with step_control = "error"
  bool event_location_ = false;  // error control on a scene with obstacles
  /// Entries closer than this fraction of the absolute tolerance happen in
  /// the step instead of ending it (as HybridContact's entry depth).
  static constexpr double kEventToleranceFraction = 1e-2;
  /// Under event location the PCG tolerance is at most this fraction of rtol.
  static constexpr double kCgToleranceFraction = 1e-3;
  /// Solves per step with event location, the last one accepting the
  /// crossings left (within the interpolant's error of the step's end).
  static constexpr int kLocationPasses = 4;
  void StartSlope();             // a_init_ after a contact event
  bool event_step_ = false;      // this step restarted at a contact event (StartSlope; counted at Commit)
  bool jumped_ = false;          // the last step ended with entries (LeftLimit)
  long events_ = 0;              // accepted steps that began with a changed contact set
  MatrixN3 x_left_, v_left_;     // its state before them
  // Error control and two-step formulas: (x₋₂, v₋₂) and the step before
  // h_prev_; error control only: v̇ = M⁻¹f at the last Reset.
  MatrixN3 xm2_, vm2_, a_init_;
  double h_prev2_ = 0.0;
  // Formulas that extrapolate g from two past values: g₋₂.
  MatrixN3 gm2_;

  // Scratch, allocated once.
  MatrixN3 g0_, g_, b0_, b_, xhat_, vhat_, xg0_, vg_, xg_, v1_, x1_, tmp_, vprev_;
  PcgSummary last_pcg_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_INTEGRATOR_H_
