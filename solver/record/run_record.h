// The record of one run, as plain data shared by every layer from the step
// loop (solver/) to the result file (results/) and the entry points
// (harness/, python/).
#ifndef CLOTHBENCH_SOLVER_RECORD_RUN_RECORD_H_
#define CLOTHBENCH_SOLVER_RECORD_RUN_RECORD_H_

#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

#include "solver/record/run_status.h"

namespace clothbench {

/// A value that one method alone stores about its run: text, a count or a number.
using MethodValue = std::variant<std::string, long, double>;

/// One run of one row: the attributes of /runs/<id> (docs/guide/results-schema.md),
/// the one record of a run from the step loop to the file and to Python.
/// The step loop fills its status, counts and times (solver RunSummary
/// extends it with the trajectory and the step history), the harness fills
/// the row's identity and, against a reference, the errors and energies; the
/// journal codec sends it, the writer writes it (results/run_table.h lists
/// its fields once, RunRecordFields) and the reader reads it back.
struct RunRecord {
  std::string id;            ///< group name under /runs
  std::string label;         ///< row label ("bdf2/newton", "xpbd", "cvode")
  std::string integrator;    ///< registry name ("bdf2")
  std::string layer;         ///< "solver", "peers", "reference"
  StepKind step_kind = StepKind::kFixedStep;
  std::string nonlinear_solver;  ///< fully implicit thesis methods; else empty
  std::string preconditioner;    ///< rows that use the PCG: the preconditioner they ran with; else empty
  std::string tangent_terms;     ///< rows that build J_α: "all" or "tension" (its terms); else empty
  std::string collision_self;    ///< scenes with [collision]: "on" or "off" (collision.self as run); else empty
  double h = 0.0;            ///< fixed-step and iterated: the step [s]; substepped: the frame step [s]
  double rtol = 0.0;         ///< adaptive rows: rtol = atol
  long substeps = 0;         ///< substepped rows: substeps per frame step
  long iterations = 0;       ///< iterated rows (pd, vbd): iterations per step
  double cg_tolerance = 0.0; ///< η of the PCG; 0 if the method has none
  /// The settings the run used (not the scene's where the row overrides them):
  /// step_control "fixed" | "iterations" | "error" (our steppers) or
  /// "sundials" (SUNDIALS' own controller); predictor and cg_reference (rows
  /// with the PCG); newton_jacobian "refresh" | "frozen" (Newton rows).
  std::string step_control, predictor, cg_reference, newton_jacobian;
  /// What one method alone says about its run, by attribute name in the
  /// order set (its registry row's `describe`, or its run; each method's
  /// row documents its own, docs/guide/results-schema.md): the result file
  /// stores each as an attribute of /runs/<id> under its name, and the
  /// reader reads every attribute that is not a field of the record back
  /// into this list. The names never repeat a field's.
  std::vector<std::pair<std::string, MethodValue>> method_attributes;
  /// Sets the method attribute `name` to `value`, replacing an earlier value.
  void SetMethodAttribute(const std::string& name, MethodValue value) {
    for (auto& [n, v] : method_attributes)
      if (n == name) {
        v = std::move(value);
        return;
      }
    method_attributes.emplace_back(name, std::move(value));
  }
  /// The text attribute `name`, or "" if the run has none or it is not text.
  std::string MethodText(std::string_view name) const {
    for (const auto& [n, v] : method_attributes)
      if (n == name && std::holds_alternative<std::string>(v)) return std::get<std::string>(v);
    return "";
  }
  double atol = 0.0;         ///< adaptive rows: atol (= rtol unless set)
  long threads = 0;          ///< OpenMP threads of the kernels
  /// The fewest threads a step ran on: below `threads` where other
  /// processes kept cores busy (solver/thread_budget.h; the same bits, other
  /// timings); 0: not recorded.
  long threads_fewest = 0;
  RunStatus status = RunStatus::kOk;  ///< where the run stopped
  std::string message;       ///< failure message (empty when ok)
  long steps = 0, updates = 0, cg_iterations = 0, rejected = 0;
  long error_test_failures = -1;  ///< adaptive rows; −1: not applicable
  long cg_unconverged = 0;        ///< accepted steps that kept an unconverged CG solve (blender)
  /// Adaptive rows with event location on scenes with obstacles: the
  /// contact events located (instants at which particles enter or leave
  /// the δ-surface: SUNDIALS' roots, sundials/hybrid_contact.h; for
  /// sbdf2/error and bdf2/error the accepted steps that began with a
  /// changed contact set); −1: not applicable.
  long events = -1;
  /// Solver time [s]: the least over the `repeats` timings of the run (the
  /// first computes the trajectory, the others reproduce it bit for bit).
  double solver_time_s = 0.0, wall_time_s = 0.0;
  double solver_time_s_median = 0.0, solver_time_s_max = 0.0;  ///< over the repeats
  long repeats = 1;
  /// (max − min)/min of the solver time over the repeats; 0 for one timing.
  double TimeSpread() const {
    return repeats > 1 && solver_time_s > 0.0 ? (solver_time_s_max - solver_time_s) / solver_time_s : 0.0;
  }
  double setup_time_s = -1.0;     ///< < 0: not measured
  /// The part of solver_time_s spent detecting obstacle contacts and setting
  /// up their constraints (ContactResponse::SetUp: the distance queries,
  /// casts and culls of every step) [s]; < 0: not measured (rows without
  /// that response).
  double contact_detection_time_s = -1.0;
  double numerical_stiffness = 0.0;  ///< h²k/(ρl²) at this row's (sub)step
  std::optional<double> error_final_m;   ///< e_rms at t_end against the reference [m]
  std::optional<double> error_l2_m;      ///< root mean square over the frames of e_rms [m]
  std::optional<double> error_max_m;     ///< largest e_rms over the frames [m]
  std::optional<double> error_mean_m;    ///< mean particle distance at t_end [m]
  /// The same three for the velocities [m/s].
  std::optional<double> error_final_mps, error_l2_mps, error_max_mps;
  /// The position error of `metric` ("final", "l2", "max") [m], if measured.
  std::optional<double> Error(std::string_view metric) const {
    return metric == "l2" ? error_l2_m : metric == "max" ? error_max_m : error_final_m;
  }
  std::optional<double> observed_order;  ///< against the previous row of the label
  /// The blow-up guard's margins over the run (docs/model.md, "Blow-up
  /// statuses"; −1: not measured): the largest energy gain over E_scale
  /// (not measured where the energy balance is not closed), the largest
  /// particle speed over v_bound, the deepest particle inside an obstacle
  /// at a frame over its collision distance δ. A run fails above 1, 2 and 1.
  double energy_gain_ratio = -1.0, speed_ratio = -1.0, penetration_ratio = -1.0;
  /// A reference's own error estimate [m] in the table's error metric:
  /// against the same SUNDIALS row at rtol/10 (RunReference), or, for a
  /// self-convergence reference, against the same method at twice its step;
  /// −1: not measured.
  double error_estimate_m = -1.0;
  /// A reference's cross-check on obstacle scenes (docs/notes/collisions.md, "The
  /// contact reference"): the fixed-step self-convergence run it was
  /// compared with (empty: none), that run's own error estimate [m] and its
  /// difference from the reference [m], both in the table's error metric
  /// (−1: not measured).
  std::string cross_check;
  double cross_check_error_estimate_m = -1.0, cross_check_difference_m = -1.0;
  std::optional<double> energy_rate_W;   ///< (E(t_end) − E(0) − W_ext − W_contact)/t_end [W]
  std::optional<double> contact_power_W; ///< W_contact(t_end)/t_end [W], if the method has our contact response

  bool ok() const { return status == RunStatus::kOk; }
};

/// A step kind as data: what its rows' parameter and count are called in
/// requests, records, options, run ids and the table. Every place that
/// treats the kinds differently reads this record instead of naming a kind.
struct StepKindSpec {
  StepKind kind;
  /// The parameter: "h" (a step [s]) or "rtol" (rtol = atol of an adaptive
  /// row); the request's and record's field, and the run id's prefix
  /// ("bdf2_h0.01", "cvode_rtol0.0001").
  std::string_view param;
  /// The count besides h: "substeps" (per frame step) or "iterations" (per
  /// step), or empty; its request and record field, its option
  /// ("--substeps") and its word in progress lines.
  std::string_view count;
  long RunRecord::*count_field;  ///< &RunRecord::substeps, &RunRecord::iterations or nullptr
  char count_id;                 ///< the run id's count prefix: "_n4" (substeps), "_k16" (iterations)
  char count_separator;          ///< the table's h|rtol column: "0.01/4", "0.01x16"
  std::string_view progress_separator;  ///< progress lines: "h = 0.01 s/4", "h = 0.01 s x16"
  bool count_divides_h;          ///< substeps: each takes h/count
  /// The table legend's words for the h|rtol column of its rows: "the step
  /// of fixed-step rows", "rtol = atol of adaptive rows", …
  std::string_view legend;
  bool adaptive() const { return param == "rtol"; }
  bool counted() const { return count_field != nullptr; }
  /// Rows given by a list of step sizes alone (no tolerance, no count).
  bool plain() const { return !adaptive() && !counted(); }
};

/// The record of `kind`.
inline const StepKindSpec& SpecOf(StepKind kind) {
  static const StepKindSpec kSpecs[] = {
      {StepKind::kFixedStep, "h", "", nullptr, 0, 0, "", false, "the step of fixed-step rows"},
      {StepKind::kAdaptive, "rtol", "", nullptr, 0, 0, "", false, "rtol = atol of adaptive rows"},
      {StepKind::kSubstepped, "h", "substeps", &RunRecord::substeps, 'n', '/', "/", true,
       "frame step/substeps of substepped rows"},
      {StepKind::kIterated, "h", "iterations", &RunRecord::iterations, 'k', 'x', " x", false,
       "step x iterations of iterated rows"},
  };
  static_assert(static_cast<int>(StepKind::kFixedStep) == 0 && static_cast<int>(StepKind::kAdaptive) == 1 &&
                static_cast<int>(StepKind::kSubstepped) == 2 && static_cast<int>(StepKind::kIterated) == 3);
  return kSpecs[static_cast<int>(kind)];
}

/// Every step kind, in the order of the table's legend.
inline constexpr StepKind kAllStepKinds[] = {StepKind::kFixedStep, StepKind::kAdaptive, StepKind::kSubstepped,
                                             StepKind::kIterated};

/// The kind of a row that its error estimate steps (rtol rows: the
/// adaptive SUNDIALS rows and the thesis' methods under error control).
inline StepKind ToleranceKind() { return StepKind::kAdaptive; }

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_RECORD_RUN_RECORD_H_
