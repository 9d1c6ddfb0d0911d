// The harness' view of the methods: the registry (harness/registry.cc
// lists each method's row, MethodEntry in solver/method_row.h, defined
// beside the method's code), a row of a run (RowMethod: a method with its
// nonlinear solver, error control and variant), the options only some rows
// read, and the default run's rows. Every row runs through the same call,
// RowMethod::Run, returning the same MethodRun. Nothing here names a method.
//
// Row labels: the name, then "/newton" for a fully implicit method with
// Newton's method, then "/error" for a method under local error control
// (adaptive rows, docs/notes/work-precision.md), then the variant:
// "bdf2/newton/error", "arkode/ark4".
#ifndef CLOTHBENCH_HARNESS_METHODS_H_
#define CLOTHBENCH_HARNESS_METHODS_H_

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <fmt/format.h>

#include "harness/first_run.h"
#include "model/particle_system.h"
#include "model/trajectory.h"
#include "results/metrics.h"
#include "results/result_file.h"
#include "results/run_table.h"
#include "solver/integrator.h"
#include "solver/method_row.h"
#include "solver/run.h"
#include "sundials/sundials_common.h"

namespace clothbench {

/// Every method, in table order: the rows that harness/registry.cc lists.
const std::vector<MethodEntry>& Registry();

/// The default reference (--reference) and the row every equal-accuracy
/// ratio is relative to (--baseline; docs/notes/work-precision.md): the
/// method whose row says MethodEntry::default_reference.
std::string_view DefaultReference();

/// The method of the self-convergence reference (MethodEntry::self_convergence_reference).
const MethodEntry& SelfConvergenceMethod();

/// The thesis method whose step bench_kernels, bench_scaling and
/// contact_replay time (MethodEntry::kernel_benchmark; SBDF(2)).
const MethodEntry& KernelBenchmarkMethod();

/// The method that ran the thesis' experiment `experiment` ("Table 5.1",
/// "Fig. 5.15": MethodEntry::thesis_experiments).
/// @throws std::logic_error if not exactly one method lists it
const MethodEntry& ThesisExperimentMethod(std::string_view experiment);

/// The methods that can be the reference, for messages ("cvode, ida").
inline std::string ReferenceNames();

inline const MethodEntry* FindMethod(std::string_view name) {
  for (const MethodEntry& e : Registry())
    if (e.name == name) return &e;
  return nullptr;
}

inline std::string ReferenceNames() {
  std::string s;
  for (const MethodEntry& e : Registry())
    if (e.reference) {
      s += (s.empty() ? "" : ", ") + std::string(e.name);
      for (std::string_view v : e.variants) s += fmt::format(", {}/{}", e.name, v);
    }
  return s;
}

/// The names of the methods whose row satisfies `pred`, in registry order,
/// for messages ("sbdf2, bdf2").
template <class Pred>
std::string MethodNames(Pred pred) {
  std::string s;
  for (const MethodEntry& e : Registry())
    if (pred(e)) s += (s.empty() ? "" : ", ") + std::string(e.name);
  return s;
}

/// The known names, for messages.
inline std::string KnownMethodNames() {
  return MethodNames([](const MethodEntry&) { return true; });
}

/// One run of one row: the step loop's RunSummary (its record, the
/// attributes the table prints and the result file stores, with the
/// trajectory and step history) and what the caller derives from it against
/// a reference: the record's error, order and energy fields and these.
struct MethodRun : RunSummary {
  std::optional<TrajectoryErrors> err;
  EnergySeries energy;

  StepKind kind() const { return step_kind; }
};

/// One row's method: a registry entry with its nonlinear solver and, for
/// SBDF(2)/BDF(2), error control.
struct RowMethod {
  const MethodEntry* entry = nullptr;
  NonlinearSolver solver = NonlinearSolver::kFixedPoint;
  bool error_control = false;
  /// A method's variant, the last part of its label (MethodEntry::variants):
  /// for arkode "ark4" and "ark5", the IMEX pair of that order (none: the
  /// invocation's --arkode-table); for cvode and ida "klu", KLU on the
  /// first-order Jacobian instead of the reduced solve.
  std::string variant;

  std::string name() const { return std::string(entry->name); }
  StepKind kind() const { return error_control ? ToleranceKind() : entry->kind; }
  /// "bdf2", "bdf2/newton", "sbdf2/error", "baraff_witkin".
  std::string label() const {
    std::string s = name();
    if (solver == NonlinearSolver::kNewton) s += "/newton";
    if (error_control) s += "/error";
    if (!variant.empty()) s += "/" + variant;
    return s;
  }
  /// The label as an HDF5 group-name part ("bdf2_newton").
  std::string id() const {
    std::string s = label();
    for (char& c : s)
      if (c == '/') c = '_';
    return s;
  }
  /// The id of this row's run at `param` (h [s] or rtol) and `count`
  /// (substeps or iterations): "bdf2_newton_h0.01", "xpbd_h0.01_n4",
  /// "pd_chebyshev_h0.01_k16", "cvode_rtol0.0001" (a sweep over CG
  /// tolerances appends "_eta<η>").
  std::string RunId(double param, int count) const {
    const StepKindSpec& k = SpecOf(kind());
    std::string run_id = fmt::format("{}_{}{:g}", id(), k.param, param);
    if (k.counted()) run_id += fmt::format("_{}{}", k.count_id, count);
    return run_id;
  }
  bool fully_implicit() const { return entry->nonlinear_solver; }
  /// The method's setting `field` if this row reads it (MethodSetting::reads), else nullptr.
  const MethodSetting* setting(std::string_view field) const {
    for (const MethodSetting& s : entry->settings)
      if (s.field == field && (!s.reads || s.reads(variant))) return &s;
    return nullptr;
  }
  /// Whether the method's linear solves use the PCG (and so the CG tolerance η).
  bool uses_pcg() const { return entry->pcg && variant != "klu"; }
  /// Whether the row builds the 3N×3N tangent system J_α.
  bool builds_tangent() const {
    return (entry->tangent && variant != "klu") || solver == NonlinearSolver::kNewton;
  }
  /// `spec` with this row's nonlinear solver and, under error control, the
  /// step control and tolerance `rtol` (= atol).
  SolverSpec Settings(SolverSpec spec, double rtol = 0.0) const {
    spec.nonlinear_solver = solver;
    if (error_control) {
      spec.step_control = StepControl::kError;
      spec.rtol = rtol;
      spec.atol = 0.0;
    }
    return spec;
  }
  /// A stepper for fixed-step rows and the stability maps, with the scene's
  /// solver settings and this row's nonlinear solver; nullptr for adaptive
  /// methods that SUNDIALS steps.
  std::unique_ptr<Stepper> Make(const ParticleSystem& sys, const SolverSpec& spec) const {
    return entry->make ? entry->make(sys, Settings(spec), 1, variant) : nullptr;
  }

  /// Runs `sys` from rest to scene.t_end. `param` is h [s] for fixed-step,
  /// substepped and iterated rows (the frame step, split into `count`
  /// substeps, or with `count` iterations) and rtol (= atol) for adaptive
  /// ones; `spec` the solver settings (the scene's, with the invocation's
  /// overrides). Never throws for a numerical failure (see RunRecord::status).
  MethodRun Run(const ParticleSystem& sys, const Scene& scene, const SolverSpec& spec, double param,
                const RunContext& ctx, int count = 1) const;

  /// The run Run would give, not started: status kNotStarted, `message`
  /// (why), and the row's identity and settings as Run fills them.
  MethodRun NotStarted(const Scene& scene, const SolverSpec& spec, double param, const RunContext& ctx, int count,
                       std::string message) const;

 private:
  // The settings the row runs with: `spec` with the row's measured best
  // preconditioner, CG tolerance and tangent terms where the command line
  // left them.
  SolverSpec RowSpec(const SolverSpec& spec, const RunContext& ctx) const;
  // The row's identity (label, id, h or rtol, count, settings) into *row.
  void Identify(const Scene& scene, const SolverSpec& row_spec, double param, int count, MethodRun* row) const;
};

/// An option that only some rows read: its request field (RunRequest,
/// Python keyword), its command-line option, which rows read it and those
/// rows in words (the labels follow from the registry: RowsReading). The
/// one table that both the request's rules (a run of a row that does not
/// read a given option is refused) and UnusedOption (a bench option that
/// no row of the invocation reads is refused) consult.
struct RowOption {
  std::string field;
  std::string option;
  std::function<bool(const RowMethod&)> reads;
  std::string what;
};
/// The harness' own options, then each method's settings (MethodEntry::settings,
/// one entry per field) in the registry's order.
const std::vector<RowOption>& RowOptions();
/// "adaptive rows: arkode, arkode/ark4, …": `o.what` and the labels of the
/// registry's rows that read `o` (every method with each nonlinear solver,
/// error control and variant it takes).
std::string RowsReading(const RowOption& o);
/// The RowOptions() entry of request field `field`. @throws std::logic_error for another name.
inline const RowOption& RowOptionOf(std::string_view field) {
  for (const RowOption& o : RowOptions())
    if (field == o.field) return o;
  throw std::logic_error(fmt::format("no row option {}", field));
}

/// The command-line options that only some rows read that were given, by
/// request field (RowOptions()), and --baseline.
struct GivenOptions {
  std::vector<std::string> fields;  ///< "rtol", "cg_tolerance", "arkode_table", …
  std::string baseline;  ///< --baseline ROW; empty: not given
};

/// The method setting declared for request field `field` (the first method
/// that declares it), or nullptr if no method does.
const MethodSetting* FindSetting(std::string_view field);

/// The default lists of the registry's rows for the help: rtol lists of
/// the adaptive rows (`rtols`) or iteration counts of the iterated rows,
/// the harness' own first and then the rows with their own:
/// "1e-2,…,1e-7; 1e-2,…,1e-6 (arkode, arkode/ark4); 1e-3,…,1e-6 (arkode/ark5)".
std::string DefaultListsText(bool rtols);

/// The first given option that no row of `rows` reads (or a --baseline
/// that names no row), as "--rtols: no row
/// of this run uses it (it applies to …)"; empty if every given option is
/// used. An option nobody reads would otherwise be ignored silently.
std::string UnusedOption(const std::vector<RowMethod>& rows, const GivenOptions& given);

/// Under a scene whose [solver] step_control is "error", the rows of the
/// methods that run under error control (sbdf2, bdf2) are their "/error"
/// rows: adaptive, labelled so, at --rtols or by default at the scene's
/// rtol (PlanRows). Without this a "sbdf2" row would step under error
/// control yet be listed, labelled and parameterised by h. The SUNDIALS
/// rows keep their own error control. A fixed-step or substepped row
/// without error control cannot run such a scene: named on the command line
/// (`named`) it is refused before anything is computed; among the default
/// rows it is left out (and a default row that becomes one already listed).
/// @throws std::invalid_argument naming the row and the scene key
void AdoptSceneStepControl(const SolverSpec& spec, std::vector<RowMethod>* rows, bool named,
                           std::string_view option = "--integrators");

/// A row's default parameters when the command line gives none: step sizes
/// as multiples of the scene's h (fixed-step rows; frame steps of
/// substepped rows) and tolerances rtol (adaptive rows), from the method's
/// row (MethodEntry::defaults, with the measurements that justify them).
struct DefaultParams {
  std::vector<double> h_factors;  ///< fixed-step and substepped rows: h = factor × scene h
  std::vector<double> rtols;      ///< adaptive rows
  std::vector<int> iterations;    ///< iterated rows without --iterations (empty: kDefaultIterations)
};

/// The iteration counts of an iterated row without --iterations, unless
/// its DefaultParams name its own.
inline const std::vector<int> kDefaultIterations = {1, 4, 16, 64};

/// One row of the default run, in table order, with its parameters.
struct DefaultRow {
  std::string label;
  DefaultParams params;
  /// The Newton row of a fully implicit method, listed beside its
  /// fixed-point row unless the command line names the nonlinear solver or
  /// the scene already uses Newton (then the row above it is the Newton row).
  bool newton_variant = false;
};

/// The default run's rows (plan.h: DefaultRowNames) and their parameters:
/// every method's MethodEntry::defaults in registry order, the fixed-step,
/// substepped and iterated rows first, then the adaptive ones.
const std::vector<DefaultRow>& DefaultRows();

inline DefaultParams DefaultRowParams(const RowMethod& m) {
  const std::string label = m.label();
  for (const DefaultRow& d : DefaultRows())
    if (d.label == label) return d.params;
  return {{1.0, 1.0 / 2, 1.0 / 4, 1.0 / 8}, {1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7}, {}};
}

/// Parses "fixed_point" | "newton". @throws std::invalid_argument naming `option`.
inline NonlinearSolver ParseNonlinearSolver(const std::string& s, const std::string& option) {
  for (NonlinearSolver n : {NonlinearSolver::kFixedPoint, NonlinearSolver::kNewton})
    if (s == ToString(n)) return n;
  throw std::invalid_argument(fmt::format("{}: \"{}\" must be fixed_point or newton", option, s));
}

/// One RowMethod per name; a fully implicit method without a solver in its
/// name gives one row per solver in `solvers` (in that order). A name may
/// carry modifiers: "bdf2/newton", "sbdf2/error", "bdf2/newton/error".
/// @param runs if given, whether the caller can run a step kind (rows of
///             other kinds are refused, naming `option`)
/// @throws std::invalid_argument for an unknown name, solver or modifier.
std::vector<RowMethod> ExpandMethods(const std::vector<std::string>& names, const std::vector<NonlinearSolver>& solvers,
                                     const std::string& option, bool (*runs)(const StepKindSpec&) = nullptr);

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_METHODS_H_
