// Shared parts of the SUNDIALS-driven methods, the references (CVODE, IDA)
// and the ARKODE peer (docs/model.md §8): options, counters, results, the
// integrator as a stepper of the one run loop (RunFrames), the
// sparse-matrix copy and the reduced velocity solve.
#ifndef CLOTHBENCH_SUNDIALS_SUNDIALS_COMMON_H_
#define CLOTHBENCH_SUNDIALS_SUNDIALS_COMMON_H_

#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <sundials/sundials_linearsolver.h>

#include "collision/virtual_particles.h"
#include "model/particle_system.h"
#include "solver/integrator.h"
#include "solver/pcg.h"
#include "solver/tangent.h"
#include "solver/run.h"

namespace clothbench {

struct ReferenceOptions {
  double rtol = 1e-10;     ///< relative tolerance
  double atol = -1.0;      ///< absolute tolerance [m, m/s]; < 0: atol = rtol
  int max_order = 5;       ///< BDF order limit (1..5)
  double t_end = 1.0;      ///< [s]
  double frame_dt = 0.01;  ///< [s]
  /// Wall time and internal steps (mxstep over the whole run): status
  /// "time_limit" or "step_limit" when reached.
  RunLimits limits{};
  double AbsoluteTolerance() const { return atol > 0.0 ? atol : rtol; }
};

/// The settings of one invocation that its rows read (the command line's
/// or a run request's): the limits every row runs under, whether the
/// invocation named the settings a row's best values would otherwise
/// replace (MethodEntry::best_preconditioner, …), and the methods' own
/// settings as given.
struct RunContext {
  RunLimits limits{};  ///< wall time and steps of every row (--time-limit)
  /// True if the command line named the preconditioner (--preconditioner):
  /// it then holds for every row, MethodEntry::best_preconditioner included.
  bool preconditioner_from_cli = false;
  /// True if the command line named the CG tolerance (--cg-tolerance or
  /// --cg-tolerances): it then holds for every row, MethodEntry::best_cg_tolerance
  /// included.
  bool cg_tolerance_from_cli = false;
  /// True if the command line named J_α's terms (--tangent-terms): they then
  /// hold for every row, MethodEntry::best_tangent_explicit_terms included.
  bool tangent_terms_from_cli = false;
  /// Whether a row predicted past the limits is not started
  /// (MethodEntry::predict; false: --start-predicted).
  bool refuse_predicted = true;
  /// The methods' own settings as given, {field, value} (MethodSetting,
  /// solver/method_row.h), each checked by its method's rule and given
  /// only to a row that reads it.
  std::vector<std::pair<std::string, std::string>> settings = {};
  /// The value given for `field`, or nullopt: the method's own default.
  std::optional<std::string> Setting(std::string_view field) const {
    for (const auto& [f, v] : settings)
      if (f == field) return v;
    return std::nullopt;
  }
};

/// The run table's note on the SUNDIALS rows' counts (SummariseCounters).
inline constexpr std::string_view kSundialsCountsNote =
    "SUNDIALS rows: steps = nst, updates = Newton iterations (nni), cg_iters = nli (rows with the reduced "
    "velocity solve: our PCG's iterations; /klu rows: 0, the direct KLU solver).";

namespace internal {

/// A SUNDIALS integrator's counter getters (CVodeGetNumSteps, …; IDA's,
/// ARKStep's), in SundialsStats' order nst, nfe, nni, nli, netf, ncfn,
/// nje, nsetups.
using CounterGetter = int (*)(void*, long*);
struct CounterGetters {
  CounterGetter nst, nfe, nni, nli, netf, ncfn, nje, nsetups;
};
/// Adds the counters since the integrator's last (re)initialisation to
/// `st` (they restart at its ReInit, after every contact event); a counter
/// still −1 in `st` starts from 0.
void AddCounters(void* mem, const CounterGetters& get, SundialsStats* st);

/// Copies the SUNDIALS counters `res->sundials` into the record's:
/// steps = nst, updates = nni, cg_iterations = nli, rejected =
/// error_test_failures = netf.
void SummariseCounters(RunSummary* res);

class ReducedTangent;

/// The end of every SUNDIALS run (CVODE, IDA, ARKODE), after its frames:
/// `counters` (the integrator's own, summed over its restarts) become
/// res->sundials, with the reduced velocity solve's PCG iterations (nli)
/// and Jacobian evaluations (nje) where `tangent` is given; then the
/// contact events (`events`, the hybrid contact's event times, or nullptr
/// without obstacle contact), the setup time `setup_s` [s], the record's
/// counts (SummariseCounters) and the wall time since `wall_start`.
/// @param tangent the reduced solve's tangent, or nullptr (KLU; ARKODE's
///        nli is its own counter)
void FinishRun(const SundialsStats& counters, const ReducedTangent* tangent, const std::vector<double>* events,
               double setup_s, std::chrono::steady_clock::time_point wall_start, RunSummary* res);

/// The record's identity of a SUNDIALS run as the reference it is: the
/// `integrator` ("cvode", "ida", "arkode"), its `layer` ("reference",
/// "peers"), step_kind "adaptive", rtol and atol from `options`, step
/// control "sundials". A row that runs it names itself over these.
void NameSundialsRun(const char* integrator, const char* layer, const ReferenceOptions& options, RunSummary* res);

/// True (res's status unsupported_scene and its message set) if the scene
/// moves fixed particles (`[[constraints.motion]]`): the SUNDIALS
/// right-hand sides hold fixed particles at rest, so their trajectory would
/// be another problem's. Checked by every SUNDIALS entry before it computes.
bool RefusesPrescribedMotion(const ParticleSystem& system, RunSummary* res);

/// The thesis' virtual particles (collision/virtual_particles.h) under a
/// SUNDIALS integrator, as the thesis' methods have them: the topology of
/// each internal step's initial state, held through the step's stages,
/// Newton iterations and root functions. A topology change is a jump of
/// the force between steps, which the next steps' error test sees
/// (docs/notes/collisions.md, "Virtual particles under SUNDIALS").
/// StartVirtualParticles forgets the last run's topology and sets that of
/// the rest state at t = 0 (call it before the integrator's first
/// evaluation); the run loop updates it after every step. Nothing without
/// virtual particles.
inline void StartVirtualParticles(const ParticleSystem& sys) {
  if (VirtualParticles* vp = VirtualParticles::Of(sys)) {
    vp->Clear();
    vp->Update(0.0, sys.rest_positions());
  }
}

/// Calls of one SUNDIALS integrator: what its stepper in the run loop asks (RunFrames).
struct OneStepDriver {
  /// Takes one internal step towards t_end; returns the flag, sets t.
  std::function<int(double* t)> step;
  /// Positions and velocities at time tf inside the last step (dense output).
  std::function<int(double tf, MatrixN3* x, MatrixN3* v)> state_at;
  /// Positions and velocities at the current time.
  std::function<void(MatrixN3* x, MatrixN3* v)> current_state;
  std::function<void(double* h, int* order)> last_step;
  std::function<std::string(int flag)> flag_name;
  /// Called when `step` returns a root (flag 2: CV_ROOT_RETURN,
  /// IDA_ROOT_RETURN, ARK_ROOT_RETURN), `root` true, or stops at a break
  /// of a moving obstacle's motion (Obstacle::NextBreak), `at_break` true,
  /// after the frames up to t are stored: applies the events
  /// (HybridContact::ApplyEvents) and restarts the integrator. Returns its
  /// flag (< 0: the run fails with it). Empty: no obstacle contact.
  std::function<int(double t, bool root, bool at_break)> on_event;
  /// Restarts the integrator at time t from the N×3 state (x [m], v [m/s])
  /// that the self-contact response made of the last step's end: a jump of
  /// the state, restarted as an event's, with the obstacle contact made
  /// consistent first (HybridContact::AfterCorrection). Returns its flag
  /// (< 0: the run fails with it). Needed on a scene with `[collision]
  /// self = true`.
  std::function<int(double t, const MatrixN3& x, const MatrixN3& v)> restart;
  /// Sets the time the next steps stop at (CVodeSetStopTime and its
  /// kin); with self-contact every frame is a step's end, so that a stored
  /// frame is a corrected state, not the uncorrected step's interpolant.
  std::function<int(double t_stop)> stop_at;
};

/// Runs the integrator behind `d` as a stepper of the one run loop
/// (solver/run.h, RunStepper, through InternalSteps): one internal step at
/// a time (the Debian build has no monitoring), storing the step history
/// and the frames 0, frame_dt, …, t_end from its dense output. On a scene with
/// `[collision] self = true` the self-contact response
/// (collision/self_contact_response.h) corrects every internal step's end,
/// as it corrects the fixed-step methods', with Δt the larger of the step
/// and the scene's h; a corrected state restarts the integrator
/// (OneStepDriver::restart), and the steps stop at every frame
/// (OneStepDriver::stop_at; docs/notes/collisions.md, "Self-contact under
/// SUNDIALS"). With obstacle contact the steps also stop at every break of
/// a moving obstacle's motion (OneStepDriver::on_event). Every stored
/// frame's crossing pairs are counted on a scene with `[collision]`.
/// `error` holds the message of the SUNDIALS error handler, if any. Every frame passes the
/// BlowUpGuard (a failing one is not kept: status "non_finite" or
/// "energy_growth"); options.limits end the run with "time_limit" or
/// "step_limit".
void RunFrames(const OneStepDriver& d, const ParticleSystem& system, const ReferenceOptions& options,
               const std::string& error, RunSummary* res);

/// The free degrees of freedom of a particle system as a SUNDIALS state
/// y = [x_free; v_free] (6·N_free entries; fixed particles are not
/// unknowns and stay at rest), used by the CVODE reference and ARKODE.
class FreeDofMap {
 public:
  explicit FreeDofMap(const ParticleSystem& system);
  int num_free() const { return static_cast<int>(free_.size()); }
  int size() const { return 6 * num_free(); }
  /// Flat particle index of free particle k.
  int particle(int k) const { return free_[static_cast<std::size_t>(k)]; }
  /// Free index of particle p, −1 if p is fixed.
  int free_index(int p) const { return free_index_[static_cast<std::size_t>(p)]; }
  /// y from N×3 positions [m] and velocities [m/s].
  void ToY(const MatrixN3& x, const MatrixN3& v, double* y) const;
  /// N×3 positions from y, fixed particles at rest.
  void PositionsFromY(const double* y, MatrixN3* x) const;
  /// N×3 velocities from y, fixed particles 0.
  void VelocitiesFromY(const double* y, MatrixN3* v) const;
  /// The x and v halves of a vector over y (a residual, a correction) as
  /// N×3 arrays with zero rows for fixed particles. No allocation (x, v N×3).
  void SplitY(const double* y, MatrixN3* x, MatrixN3* v) const;

 private:
  const ParticleSystem& sys_;
  std::vector<int> free_, free_index_;
};

/// A SUNDIALS error handler (CVErrHandlerFn, IDAErrHandlerFn,
/// ARKErrHandlerFn) that stores "<module> <function> (flag <code>): <msg>"
/// in the std::string passed as its user data.
void StoreErrorMessage(int code, const char* module, const char* function, char* msg, void* error_string);

/// Records the first failing setup call in `res`: status = the flag's
/// RunStatus (ParseRunStatus of its name, `flag_name`:
/// CVodeGetReturnFlagName, …), message = the error handler's
/// text `error` or "<call> failed with <flag>". Returns flag >= 0.
bool CheckFlag(int flag, const char* call, char* (*flag_name)(long int), const std::string& error,
               RunSummary* res);

/// What a matrix-free custom linear solver does (NewCustomLinearSolver).
struct CustomSolverHooks {
  /// x = (I − γJ)⁻¹ b approximately: b, x the package's vectors; w its
  /// error weights (nullptr until it sets them) and tol its tolerance on
  /// ‖w ∘ residual‖₂. Returns a SUNLS_* flag.
  std::function<int(const double* b, double* x, const double* w, double tol)> solve;
  std::function<int()> iterations;   ///< of the last solve
  std::function<double()> residual;  ///< of the last solve
};

/// A custom SUNLinearSolver of type SUNLINEARSOLVER_ITERATIVE without a
/// matrix, for CVODE and ARKODE: the package's linear-solver interface
/// (CVLS, ARKLS) hands it its preconditioner-setup wrapper, which its setup
/// calls (so a user preconditioner setup set with CVodeSetPreconditioner or
/// ARKStepSetPreconditioner sees the package's jok and γ), and its error
/// weights (setscalingvectors); the solve and counters are `hooks`'. The
/// package's ATimes and preconditioner solve are not used. `like` (a state
/// vector) gives the zero residual vector IDALS requires of iterative
/// solvers (its `resid`); nullptr leaves that operation out. nullptr if
/// SUNDIALS cannot allocate it.
SUNLinearSolver NewCustomLinearSolver(SUNContext ctx, CustomSolverHooks hooks, N_Vector like = nullptr);

/// Wraps a direct SUNLinearSolver (KLU) so that the wall time of its
/// setups (symbolic analysis and numeric factorisations) is added to
/// `*seconds`; every other operation is forwarded. Takes ownership of
/// `inner`. nullptr if SUNDIALS cannot allocate it.
SUNLinearSolver NewTimedLinearSolver(SUNContext ctx, SUNLinearSolver inner, double* seconds);

/// The hooks of a reduced solve `s` (Solve(γ, b, x, w, tol) → PcgStatus,
/// last_iterations(), last_residual()) with γ from `current_gamma(&γ)`
/// (false: the package could not say).
template <class ReducedSolve, class CurrentGamma>
CustomSolverHooks ReducedSolveHooks(ReducedSolve* s, CurrentGamma current_gamma) {
  CustomSolverHooks hooks;
  hooks.solve = [s, current_gamma](const double* b, double* x, const double* w, double tol) {
    double gamma = 0.0;
    if (!current_gamma(&gamma)) return static_cast<int>(SUNLS_PACKAGE_FAIL_UNREC);
    // A CG failure is recoverable: the package retries with a new setup or a smaller step.
    return s->Solve(gamma, b, x, w, tol) == PcgStatus::kConverged ? static_cast<int>(SUNLS_SUCCESS)
                                                                   : static_cast<int>(SUNLS_CONV_FAIL);
  };
  hooks.iterations = [s] { return s->last_iterations(); };
  hooks.residual = [s] { return s->last_residual(); };
  return hooks;
}

/// The tangent system J_γ = M − γ ∂f/∂v − γ² ∂f/∂x of a reduced
/// SUNDIALS Newton solve (CVODE's and IDA's rows; docs/model.md "CVODE's
/// reduced solve"): the closed-form, clamped and symmetrised tangent, the
/// scene's preconditioner (refactorised at the package's setups only), the
/// fixed particles' filter, and the filtered PCG with its counters.
class ReducedTangent {
 public:
  ReducedTangent(const ParticleSystem& sys, const SolverSpec& spec);
  /// A setup: the Jacobian at (t, x, v) if `evaluate` (else J follows γ
  /// with the last one), and the preconditioner of J_γ. Returns 0, or 1
  /// (recoverable) if the preconditioner could not be built.
  int Setup(double t, const MatrixN3& x, const MatrixN3& v, double gamma, bool evaluate);
  /// J_γ dv = b by the filtered PCG (fixed particles' dv = 0), the matrix
  /// at `gamma`, the preconditioner of the last setup. @param dv N×3
  /// row-major, overwritten. No allocation.
  PcgStatus Solve(double gamma, const MatrixN3R& b, const PcgOptions& options, MatrixN3R* dv);
  /// The same with `filter` in place of the fixed particles' (it holds
  /// them and the contacts' prescribed components) and J_γ + γ diag(rate)
  /// (`rate` N values [kg/s], the hybrid contact's friction rates).
  PcgStatus Solve(double gamma, const MatrixN3R& b, const PcgOptions& options, MatrixN3R* dv,
                  const VelocityFilter& filter, const Eigen::VectorXd& rate);
  /// out += cx ∂f/∂x u + cv ∂f/∂v w (the last Jacobian).
  void AddJacobianProducts(double cx, const MatrixN3& u, double cv, const MatrixN3& w, MatrixN3* out) const {
    tangent_.AddJacobianProducts(cx, u, cv, w, out);
  }
  int last_iterations() const { return last_iterations_; }
  long total_iterations() const { return total_iterations_; }
  double last_residual() const { return last_residual_; }
  long jacobian_evaluations() const { return jacobian_evaluations_; }
  /// Construction, Jacobian evaluations and preconditioner setups [s].
  double setup_seconds() const;

 private:
  TangentSystem tangent_;
  std::unique_ptr<SystemMatrix> laplacian_;  // "cholesky", "amg", "auto": A_γ's preconditioner
  TangentPreconditioner pre_;
  VelocityFilter filter_;
  TangentPcgWorkspace work_;
  int last_iterations_ = 0;
  long total_iterations_ = 0, jacobian_evaluations_ = 0;
  double last_residual_ = 0.0, setup_seconds_ = 0.0;
};

/// The PCG stop that meets a SUNDIALS iterative tolerance for a reduced
/// velocity solve: the package asks for ‖w ∘ res‖₂ < tol over y = [x; v]
/// (free DOFs, `map`); the x rows are solved exactly and the v rows'
/// residual is M⁻¹ times the PCG's, so ‖res_PCG‖₂ ≤ tol / max_v(w/m)
/// suffices. Returns `fallback` (the scene's η) when w is nullptr or tol ≤ 0.
PcgOptions PcgStopForTolerance(const FreeDofMap& map, const Eigen::VectorXd& masses, const double* w, double tol,
                               const PcgOptions& fallback);
/// The same stop from the largest factor s_i w_i between the PCG's residual
/// and the package's weighted one (‖res_PCG‖₂ ≤ tol / max_i s_i w_i).
PcgOptions PcgStopForTolerance(double max_scaled_weight, double tol, const PcgOptions& fallback);

/// Copies a compressed-column Eigen matrix into a SUNDIALS CSC matrix
/// (reallocating if needed). Returns 0 or −1.
int CopyToSunSparse(const SparseMatrix& j, void* sun_matrix);

}  // namespace internal
}  // namespace clothbench

#endif  // CLOTHBENCH_SUNDIALS_SUNDIALS_COMMON_H_
