// Runs one integrator over a scene's time interval: fixed steps or the
// iteration-count controller, rejected steps retried with a smaller h, and
// frames stored at 0, frame_dt, …, t_end (docs/model.md §6).
#ifndef CLOTHBENCH_SOLVER_RUN_H_
#define CLOTHBENCH_SOLVER_RUN_H_

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "collision/distance_cull.h"
#include "collision/obstacle_proximity.h"
#include "collision/self_contact_response.h"
#include "model/particle_system.h"
#include "solver/record/run_record.h"
#include "model/trajectory.h"
#include "solver/integrator.h"

namespace clothbench {

/// Output times 0, frame_dt, 2 frame_dt, …, t_end [s] (t_end appended if it
/// is not a multiple of frame_dt).
std::vector<double> FrameTimes(double t_end, double frame_dt);

/// Bounds every run is held to, whatever method steps it (docs/notes/verification.md,
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

/// What is known of a run's cost before it starts, from an analysis that
/// does no numerical work (docs/notes/work-precision.md, "Predicting a first
/// run"): the row does not start if either bound exceeds what the run may
/// use (harness/methods.h, RowMethod::Run).
struct FirstRunPrediction {
  double seconds = 0.0;  ///< the wall time [s] of what it cannot avoid (a first factorisation); 0: none
  double bytes = 0.0;    ///< the memory it holds at its peak [B]; 0: none
  std::string source;    ///< how both were obtained, with the numbers they come from
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

/// One run by any method: its record (solver/record/run_record.h) and what the
/// record is derived from. RunStepper fills the record's status, message,
/// counts and times for the thesis' integrators and the peers; the SUNDIALS
/// runs (CVODE, IDA, ARKODE) fill the same counts from their own (steps =
/// nst, updates = nni, CG iterations = nli, rejected steps = error-test
/// failures = netf), their settings and `sundials`. The row's identity (id,
/// label, parameters) is the caller's (harness MethodRow::Run), the errors
/// and energies are derived against a reference.
struct RunSummary : RunRecord {
  RunSummary() { status = RunStatus::kNotRun; }
  int matrix_rebuilds = -1;         ///< A_α / preconditioner rebuilds; −1: not counted (SUNDIALS)
  /// Every attempt, rejected ones included. SUNDIALS runs: every accepted
  /// internal step with t, h, solve_time and error_order = the method order
  /// q; updates, cg_iterations and colliding −1 (not counted per step).
  std::vector<StepStats> step_stats;
  Trajectory trajectory;
  std::optional<SundialsStats> sundials;  ///< SUNDIALS runs only
  /// Runs with `[collision] self = true`: what the self-contact response did.
  std::optional<SelfContactStats> self_contact;

};

/// W_ext(t), the work of the non-conservative external forces (wind, air
/// drag) Σ f_ext·v integrated by the trapezoidal rule over the states it is
/// given [J] (second order, as results/metrics.h integrates it over the
/// frames); 0 for a scene without them, whose states are never evaluated.
/// No allocation after construction.
class ExternalWork {
 public:
  /// From the state at t = 0: N×3 positions x0 [m], velocities v0 [m/s].
  ExternalWork(const ParticleSystem& system, const MatrixN3& x0, const MatrixN3& v0);
  /// Adds the interval of length dt [s] that ends at the state (t, x, v) and
  /// returns W_ext(t) [J].
  double Advance(double dt, double t, const MatrixN3& x, const MatrixN3& v);
  double work() const { return work_; }  ///< W_ext at the last state [J]

 private:
  const ParticleSystem& sys_;
  MatrixN3 f_ext_;
  double work_ = 0.0, power_ = 0.0;
};

/// Detects a blow-up by the physics of the scene (docs/model.md, "Blow-up
/// statuses"). With M the cloth's mass, g gravity, H the drop height (the
/// initial state's extent along g plus the sheet's diagonal L when
/// particles are fixed; without fixed particles, the extent plus the free
/// fall ½|g|t_end² over the run) and K(0) the initial kinetic energy, a run
/// fails
///  - after any step (Check), with "non_finite": a non-finite state or
///    energy; "energy_growth": the energy balance's gain E(t) − E(0) −
///    W_ext(t) − W_contact(t) > kEnergyGainFactor · E_scale, E_scale =
///    M(|g|H + ½ (1 m/s)²) + K(0) [J] (W_ext: work of wind and air drag,
///    ExternalWork; W_contact: the collision response's work, the
///    stepper's own count); "speed": max_p |v_p| > kSpeedFactor ·
///    v_bound, v_bound = sqrt(2|g|H) + 1 m/s + max_p |v_p(0)| + the wind's largest
///    speed + the moving obstacles' largest surface speed within reach of
///    the cloth over the run (a deforming shape's: its vertices' within
///    [0, t_end]), at most kMaxObstacleSpeed [m/s] (the energy balance only where it is closed: a method
///    that does not count its contact work is not checked on it on a scene
///    with obstacles);
///  - at a stored frame (CheckFrame), with "penetration": a particle more
///    than its obstacle's collision distance δ inside a solid obstacle
///    (signed distance < −δ; open meshes have no inside).
/// The message names t, the quantity and its bound. Neither check
/// allocates for analytic obstacles (they run inside the step loop).
/// The ceiling of a keyframed obstacle's share of the speed bound [m/s]:
/// faster than any body or prop that cloth is simulated on (a sprinter's
/// limb moves at about 10 m/s, a car in a crash test at 15–25 m/s), so
/// that an obstacle keyframed at 10⁴ m/s cannot lift the bound to where
/// cloth flung at kilometres per second is still `ok`.
inline constexpr double kMaxObstacleSpeed = 100.0;

class BlowUpGuard {
 public:
  static constexpr double kEnergyGainFactor = 1.0;
  static constexpr double kSpeedFactor = 2.0;
  /// The run's initial state at t = 0: N×3 positions x0 [m] and velocities
  /// v0 [m/s] (finite), whose energy is E(0); t_end [s] the run's end.
  BlowUpGuard(const ParticleSystem& system, const MatrixN3& x0, const MatrixN3& v0, double t_end);
  /// Checks the state after a step at time t [s]: N×3 positions x [m],
  /// velocities v [m/s], the external work W_ext(t) [J] (ExternalWork) and
  /// the contact work W_contact(t) [J] done since t = 0, or nothing for a
  /// method that does not count it (XPBD's positional projection): on a
  /// scene with obstacles its energy balance is not closed and is not
  /// checked (speed and penetration still are). Returns true if the state
  /// is sound, else false with `status` ("non_finite" | "energy_growth" |
  /// "speed") and a one-line `message` naming t, the quantity and the bound.
  bool Check(double t, const MatrixN3& x, const MatrixN3& v, double external_work, std::optional<double> contact_work,
             RunStatus* status, std::string* message);
  /// The speed check alone (part of Check), for a caller with its own
  /// energy bound (the stability maps): false with status "speed".
  bool CheckSpeed(double t, const MatrixN3& v, RunStatus* status, std::string* message);
  /// Leaves the energy balance unchecked also on a scene without obstacles:
  /// the stepper's contact with itself does work it does not count (a
  /// position-based peer's self-contact projections).
  void OpenBalance() { open_balance_ = true; }
  /// Checks a stored frame at time t [s] with N×3 positions x [m] and
  /// velocities v [m/s]: false with status "non_finite", or "penetration"
  /// against the obstacles and a message naming the particle, its depth,
  /// the obstacle and t.
  bool CheckFrame(double t, const MatrixN3& x, const MatrixN3& v, RunStatus* status, std::string* message);
  /// Checks the straight path of every particle over a step from N×3
  /// positions x0 [m] at t0 [s] to x1 [m] at t1 [s]: false with status
  /// "tunnelled" and a message naming the particle, the obstacle and the
  /// step if a particle started outside an obstacle and ends outside it on
  /// the other side, its path having entered the solid (the segment test
  /// of the collision response, Obstacle::FirstHit, against the obstacle
  /// at t1). A distance can keep its sign when a particle crosses a thin
  /// obstacle within one step, so no root finding or frame check sees it.
  /// Paths that start or end inside (contact, penetration) are left to
  /// the response and CheckFrame. By the 1-Lipschitz distance, a particle
  /// with d(x0) + d(x1) > |x1 − x0| cannot have entered and is skipped;
  /// mesh and skeleton obstacles are culled as the detection culls them
  /// (collision/distance_cull.h). No allocation.
  bool CheckPath(double t0, const MatrixN3& x0, double t1, const MatrixN3& x1, RunStatus* status,
                 std::string* message);
  /// The margins of the states and frames checked so far into `record`
  /// (RunRecord::energy_gain_ratio, speed_ratio, penetration_ratio).
  void StoreMargins(RunRecord* record) const;

 private:
  const ParticleSystem& sys_;
  ObstacleProximity proximity_;  // CheckFrame's penetration, culled over the frames
  DistanceCull path_cull_;       // CheckPath's distances, culled over the steps
  double e_scale_ = 0.0, v_bound_ = 0.0, e0_ = 0.0;
  bool open_balance_ = false;
  double gain_ratio_ = -1.0, speed_ratio_ = -1.0, depth_ratio_ = -1.0;  // largest so far; −1: not measured
};

/// Integrates `system` from rest (x = rest positions, v = 0) to t_end.
/// Never throws: invalid options give status "invalid_options"; a numerical
/// failure gives the failing StepStatus, a blow-up "non_finite" or
/// "energy_growth" (BlowUpGuard, at every frame; the state is also checked
/// for finiteness after every step), and the limits "time_limit" or
/// "step_limit"; the trajectory holds the frames reached.
RunSummary RunIntegrator(const ParticleSystem& system, Method method, const RunOptions& options);

/// The message of a run that reached --time-limit `limit_s` [s] at time t
/// [s] after `steps` step attempts (the fixed-step and SUNDIALS drivers').
std::string TimeLimitMessage(double limit_s, double t, long steps);

/// The crossing triangle pairs of the cloth at a stored frame (N×3
/// positions x [m] at time t [s]; `triangles` the cloth's, SceneTriangles)
/// appended to sum's trajectory.crossing_pairs. With the self-contact
/// response on (`self_contact`), a crossing ends the run: false, with
/// status self_intersection and a message naming t, the count and the first
/// pair (the frame is kept).
bool CountCrossings(const std::vector<std::array<int, 3>>& triangles, const MatrixN3& x, double t, bool self_contact,
                    RunSummary* sum);

/// The same driver for any stepper built on `system` (the peers, and the
/// SUNDIALS rows through InternalSteps). Reset to rest here.
RunSummary RunStepper(const ParticleSystem& system, Stepper& stepper, const RunOptions& options);
/// The same into `sum`, whose other fields (names, settings) it keeps.
void RunStepper(const ParticleSystem& system, Stepper& stepper, const RunOptions& options, RunSummary* sum);

/// The OpenMP threads the kernels may use (omp_get_max_threads: OMP_NUM_THREADS
/// or the hardware threads), stored with every run.
int KernelThreads();
/// Sets the OpenMP threads of the kernels (omp_set_num_threads), as
/// OMP_NUM_THREADS would: a rerun of a stored run uses the run's count.
/// @param threads ≥ 1
void SetKernelThreads(int threads);

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_RUN_H_
