// Runs one integrator over a scene's time interval: fixed steps or the
// iteration-count controller, rejected steps retried with a smaller h, and
// frames stored at 0, frame_dt, …, t_end (docs/model.md §6).
#ifndef CLOTHBENCH_SOLVER_RUN_H_
#define CLOTHBENCH_SOLVER_RUN_H_

#include <optional>
#include <string>
#include <vector>

#include "model/particle_system.h"
#include "model/run_record.h"
#include "model/trajectory.h"
#include "solver/integrator.h"

namespace clothbench {

/// Output times 0, frame_dt, 2 frame_dt, …, t_end [s] (t_end appended if it
/// is not a multiple of frame_dt).
std::vector<double> FrameTimes(double t_end, double frame_dt);

/// Bounds every run is held to, whatever method steps it (docs/verification.md,
/// "Blow-ups and limits"). A run that reaches one ends with a failure status
/// at that step and keeps the frames it reached.
struct RunLimits {
  /// The most steps a run may take: fixed-step runs asking for more are
  /// refused before computing (bench_integrators), controlled and SUNDIALS
  /// runs that take more (counting rejected attempts; SUNDIALS' mxstep
  /// over the whole run) end with status "step_limit".
  static constexpr double kMaxSteps = kMaxStepsPerRun;  // model/scene.h
  /// Wall-time budget of one run [s] (bench_integrators --time-limit); <= 0:
  /// none. A run past it ends after the current step with "time_limit".
  double time_limit_s = 3600.0;
  long max_steps = static_cast<long>(kMaxSteps);
};

struct RunOptions {
  double h = 0.01;          ///< nominal (fixed) step [s]
  double t_end = 1.0;       ///< [s]
  double frame_dt = 0.01;   ///< [s]
  /// The step control, tolerances and limits; nullptr: the scene's
  /// (system.scene().solver). Must outlive the run.
  const SolverSpec* solver = nullptr;
  RunLimits limits{};
  /// false with `error` naming the field, its value and the rule.
  bool IsValid(std::string* error) const;
};

/// SUNDIALS counters (CVodePrintAllStats / IDAPrintAllStats names) of a run
/// by CVODE, IDA (reference/) or ARKODE (peers/).
struct SundialsStats {
  long nst = -1;      ///< steps
  long nfe = -1;      ///< right-hand side (CVODE), residual (IDA) or explicit f_E (ARKODE) evaluations
  long nfe_i = -1;    ///< implicit f_I evaluations (ARKODE only)
  long nni = -1;      ///< nonlinear (Newton) iterations
  long nli = -1;      ///< linear iterations (0 for the direct KLU solver)
  long netf = -1;     ///< error test failures
  long ncfn = -1;     ///< nonlinear convergence failures
  long nje = -1;      ///< Jacobian evaluations
  long nsetups = -1;  ///< linear solver setups (KLU factorisations)
};

/// One run by any method: its record (model/run_record.h) and what the
/// record is derived from. RunStepper fills the record's status, message,
/// counts and times for the thesis' integrators and the peers; the SUNDIALS
/// runs (CVODE, IDA, ARKODE) fill the same counts from their own (steps =
/// nst, updates = nni, CG iterations = nli, rejected steps = error-test
/// failures = netf), their settings and `sundials`. The row's identity (id,
/// label, parameters) is the caller's (harness MethodRow::Run), the errors
/// and energies are derived against a reference.
struct RunSummary : RunRecord {
  RunSummary() { status = "not_run"; }
  int matrix_rebuilds = -1;         ///< A_α / preconditioner rebuilds; −1: not counted (SUNDIALS)
  /// Every attempt, rejected ones included. SUNDIALS runs: every accepted
  /// internal step with t, h, solve_time and error_order = the method order
  /// q; updates, cg_iterations and colliding −1 (not counted per step).
  std::vector<StepStats> step_stats;
  Trajectory trajectory;
  std::optional<SundialsStats> sundials;  ///< SUNDIALS runs only

  /// One line: status, steps, updates, CG iterations, times.
  std::string BriefReport() const;
};

/// Detects a blow-up at a frame (docs/verification.md, "Blow-ups and
/// limits"): a non-finite state or energy, status "non_finite", or an energy
/// gain E(t) − W_ext(t) − E(0) > kEnergyGrowthFactor · E_ref, status
/// "energy_growth", with E_ref = Σ m (|g| L + 1 m²/s²) [J] (L the sheet's
/// diagonal): a thousand times the energy gravity can release over the sheet
/// plus that of every particle moving at 1 m/s, which no cloth motion of a
/// passive model reaches (a gain of 1e3 E_ref is speeds of ~150 m/s when
/// L = 1 m). W_ext is the work of wind and air drag, integrated over the
/// frames by the trapezoidal rule (as results/metrics.h does). Check does
/// not allocate (it runs inside the step loop).
class BlowUpGuard {
 public:
  static constexpr double kEnergyGrowthFactor = 1e3;
  /// The run's initial state at t = 0: N×3 positions x0 [m] and velocities
  /// v0 [m/s] (finite), whose energy is E(0).
  BlowUpGuard(const ParticleSystem& system, const MatrixN3& x0, const MatrixN3& v0);
  /// Checks the frame at time t [s] with N×3 positions x [m] and velocities v
  /// [m/s]; frames must come in increasing t after 0. Returns true if the
  /// frame is sound, else false with `status` ("non_finite" |
  /// "energy_growth") and a one-line `message` naming t and the values.
  bool Check(double t, const MatrixN3& x, const MatrixN3& v, std::string* status, std::string* message);

 private:
  const ParticleSystem& sys_;
  double e_ref_ = 0.0, e0_ = 0.0, work_ = 0.0, power_ = 0.0, t_prev_ = 0.0;
  MatrixN3 f_ext_;
};

/// Integrates `system` from rest (x = rest positions, v = 0) to t_end.
/// Never throws: invalid options give status "invalid_options"; a numerical
/// failure gives the failing StepStatus, a blow-up "non_finite" or
/// "energy_growth" (BlowUpGuard, at every frame; the state is also checked
/// for finiteness after every step), and the limits "time_limit" or
/// "step_limit"; the trajectory holds the frames reached.
RunSummary RunIntegrator(const ParticleSystem& system, Method method, const RunOptions& options);

/// The same driver for any stepper built on `system` (the peers). Reset to
/// rest here.
RunSummary RunStepper(const ParticleSystem& system, Stepper& stepper, const RunOptions& options);

/// The OpenMP threads the kernels may use (omp_get_max_threads: OMP_NUM_THREADS
/// or the hardware threads), stored with every run.
int KernelThreads();
/// Sets the OpenMP threads of the kernels (omp_set_num_threads), as
/// OMP_NUM_THREADS would: a rerun of a stored run uses the run's count.
/// @param threads ≥ 1
void SetKernelThreads(int threads);

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_RUN_H_
