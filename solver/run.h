// Runs one integrator over a scene's time interval: fixed steps or the
// iteration-count controller, rejected steps retried with a smaller h, and
// frames stored at 0, frame_dt, …, t_end (SPEC §6).
#ifndef CLOTHBENCH_SOLVER_RUN_H_
#define CLOTHBENCH_SOLVER_RUN_H_

#include <optional>
#include <string>
#include <vector>

#include "model/particle_system.h"
#include "model/trajectory.h"
#include "solver/integrator.h"

namespace clothbench {

/// Output times 0, frame_dt, 2 frame_dt, …, t_end [s] (t_end appended if it
/// is not a multiple of frame_dt).
std::vector<double> FrameTimes(double t_end, double frame_dt);

struct RunOptions {
  double h = 0.01;          ///< nominal (fixed) step [s]
  double t_end = 1.0;       ///< [s]
  double frame_dt = 0.01;   ///< [s]
  /// The step control, tolerances and limits; nullptr: the scene's
  /// (system.scene().solver). Must outlive the run.
  const SolverSpec* solver = nullptr;
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

/// Summary of one run by any method: the thesis' integrators and the peers
/// stepped by RunStepper, and the SUNDIALS runs (CVODE, IDA, ARKODE), which
/// fill the same counters from their own (steps = nst, updates = nni,
/// CG iterations = nli, rejected steps = error-test failures = netf) and add
/// `sundials`. Counters −1 = not set (Ceres style).
struct RunSummary {
  std::string integrator;           ///< "cvode", "ida", "arkode", "bdf2_self_convergence"; empty for RunStepper runs
  double h = 0.0;                   ///< fixed step [s] of a self-convergence reference run; 0 otherwise
  bool ok = false;
  std::string status = "not_run";   ///< "ok" or the failure (a StepStatus name)
  std::string message;              ///< why it stopped
  int steps = -1;                   ///< accepted steps
  int rejected_steps = -1;          ///< attempts rejected and retried with a smaller h
  int error_test_failures = -1;     ///< of those, rejected by the local error test (step_control = "error")
  long fixed_point_updates = -1;    ///< linear solves, over all attempts
  long cg_iterations = -1;          ///< PCG iterations, over all attempts
  int matrix_rebuilds = -1;         ///< A_α / preconditioner rebuilds
  double solver_time_in_seconds = -1.0;  ///< time inside the step engine
  /// Wall time of matrix assembly, symbolic analysis and every numeric
  /// factorisation or AMG setup (included in solver_time_in_seconds except
  /// the engine's construction) [s].
  double setup_time_in_seconds = -1.0;
  double wall_time_in_seconds = -1.0;    ///< whole run including frame output
  /// Every attempt, rejected ones included. SUNDIALS runs: every accepted
  /// internal step with t, h, solve_time and error_order = the method order
  /// q; updates, cg_iterations and colliding −1 (not counted per step).
  std::vector<StepStats> step_stats;
  Trajectory trajectory;
  std::optional<SundialsStats> sundials;  ///< SUNDIALS runs only

  /// One line: status, steps, updates, CG iterations, times.
  std::string BriefReport() const;
};

/// Integrates `system` from rest (x = rest positions, v = 0) to t_end.
/// Never throws: invalid options give status "invalid_options"; a numerical
/// failure gives the failing StepStatus, and the trajectory holds the frames
/// reached.
RunSummary RunIntegrator(const ParticleSystem& system, Method method, const RunOptions& options);

/// The same driver for any stepper built on `system` (the peers). Reset to
/// rest here.
RunSummary RunStepper(const ParticleSystem& system, Stepper& stepper, const RunOptions& options);

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_RUN_H_
