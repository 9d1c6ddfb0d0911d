// A method's row as the registry lists it (harness/registry.cc): how the
// method is stepped and built, the settings it reads, its default
// parameters and the notes its table rows print. Each method defines its
// row beside its code (solver/schemes/<method>.cc, peers/<method>.cc,
// reference/<method>_reference.cc), so that a new method is its files and
// one registry line (docs/guide/extending.md, "Adding a method").
#ifndef CLOTHBENCH_SOLVER_METHOD_ROW_H_
#define CLOTHBENCH_SOLVER_METHOD_ROW_H_

#include <memory>
#include <optional>
#include <string_view>
#include <utility>
#include <vector>

#include "model/particle_system.h"
#include "solver/record/run_record.h"
#include "solver/integrator.h"
#include "solver/run.h"

namespace clothbench {

struct ReferenceOptions;  // sundials/sundials_common.h: a SUNDIALS run's tolerances and limits
struct RunContext;        // sundials/sundials_common.h: the invocation's settings the rows read

/// The parameters of one default row when the command line gives none
/// (docs/notes/work-precision.md: each row's runs bracket e_rms = 1e-3 m
/// on the default scene where that fits the default run's time budget).
struct RowDefaults {
  /// The row's label after the method's name ("" for the plain row,
  /// "newton", "error", "newton/error", "chebyshev", "ark4", "klu").
  std::string_view modifiers = {};
  std::vector<double> h_factors = {};  ///< fixed-step and substepped rows: h = factor × scene h
  std::vector<double> rtols = {};      ///< adaptive rows (and a method's rows under a scene's error control)
  std::vector<int> iterations = {};    ///< iterated rows without --iterations (empty: the harness' counts)
  /// The Newton row of a fully implicit method, listed beside its
  /// fixed-point row unless the command line names the nonlinear solver or
  /// the scene already uses Newton.
  bool newton_variant = false;
  /// Whether it is a row under error control ("error", "newton/error"):
  /// adaptive, parameterised by rtol.
  bool error_row() const { return modifiers == "error" || modifiers.ends_with("/error"); }
};

/// Why a run of a row ended with a status that belongs to the method: the
/// run table prints `text` once if some run of `label` ended with `status`
/// (a RunStatus name).
struct StatusNote {
  std::string_view label = {}, status = {}, text = {};
};

/// One row of a thesis table that the method ran, with the thesis' own
/// counts and time (docs/notes/thesis-tables.md prints ours beside them).
struct ThesisTableRow {
  std::string_view table;  ///< "3.1" or "3.2"
  std::string_view scene;  ///< "tablecloth" or "dress"
  double k = -1.0, d = -1.0;  ///< tension stiffness [N/m] and damping [N·s/m]; < 0: the scene's
  long updates = 0, cg = 0;   ///< the thesis' Jacobian updates and CG iterations
  double time_s = -1.0;       ///< the thesis' time [s] (R10000, 180 MHz); < 0: not given
};

/// A setting that only a method's rows read (the ARKODE table, CVODE's
/// setup knobs), declared by the method: the command line's option, a run
/// request's field, Python's keyword and a rerun's reading come from this
/// declaration alone, and the method reads the given value from
/// RunContext::Setting (docs/guide/extending.md, "A method's own setting").
struct MethodSetting {
  std::string_view field;   ///< request field and Python keyword ("arkode_table")
  std::string_view option;  ///< bench_integrators' option ("--arkode-table")
  std::string_view help;    ///< the option's help, before the rows that read it
  std::string_view what;    ///< the rows that read it, in words ("arkode rows without a variant")
  /// "" if `value` is valid, else the rule it breaks, one line naming the
  /// value (the caller names the field). Called before anything is computed.
  std::string (*check)(const std::string& value) = nullptr;
  /// Whether the method's row with `variant` ("" for the plain row) reads
  /// it; nullptr: every row of the method.
  bool (*reads)(std::string_view variant) = nullptr;
  /// The run attribute that stores the value a run used, which a rerun
  /// reads back into the field ("butcher_table").
  std::string_view attribute = {};
};

struct MethodEntry {
  std::string_view name;
  StepKind kind = StepKind::kFixedStep;
  std::string_view layer;         ///< "solver", "peers" or "reference"
  bool nonlinear_solver = false;  ///< takes fixed_point | newton (fully implicit thesis methods)
  bool error_control = false;     ///< may run adaptively as "<name>/error" (SBDF(2), BDF(2))
  bool collisions = false;        ///< has a collision response (docs/model.md §7)
  bool pcg = false;               ///< solves with the filtered PCG (so the CG tolerance η applies)
  bool tangent = false;           ///< always holds the 3N×3N tangent system J_α (memory check)
  bool sparse_jacobian = false;   ///< holds a 6N×6N Jacobian and its KLU factor (memory check)
  /// Fixed-step, substepped and iterated methods (and error-controlled
  /// SBDF(2)/BDF(2)): the stepper on `sys` with settings `spec`, `count`
  /// substeps or iterations per step for substepped and iterated ones, and
  /// the row's `variant` ("chebyshev"); nullptr for the SUNDIALS-stepped ones.
  std::unique_ptr<Stepper> (*make)(const ParticleSystem& sys, const SolverSpec& spec, int count,
                                   std::string_view variant) = nullptr;
  /// SUNDIALS-stepped adaptive methods: one run at `o.rtol` of the row's
  /// `variant` with the invocation's `ctx`; the run fills its record's
  /// method settings (the ARKODE table). nullptr otherwise.
  RunSummary (*integrate)(const ParticleSystem& sys, const ReferenceOptions& o, const SolverSpec& spec,
                          std::string_view variant, const RunContext& ctx) = nullptr;
  /// What a run on `sys` for the row's `variant` cannot avoid in time and
  /// memory, known before it starts (FirstRunPrediction, solver/run.h);
  /// nullptr or zeros: none. A row predicted past --time-limit or the
  /// available memory is not started (harness/first_run.h).
  FirstRunPrediction (*predict)(const ParticleSystem& sys, std::string_view variant) = nullptr;
  /// Whether the method can be the reference (--reference NAME,
  /// clothbench.reference(): RunReference), the tight run every row's error
  /// is measured against.
  bool reference = false;
  /// Whether it is the default reference and the default baseline of the
  /// equal-accuracy ratios (--reference, --baseline): one method only.
  bool default_reference = false;
  /// The fixed-step method of the self-convergence reference, used where
  /// the reference method cannot run the scene (self-contact, virtual
  /// particles; harness/reference.h): one method only.
  bool self_convergence_reference = false;
  /// The thesis method whose step the kernel benchmarks time and
  /// contact_replay takes by default (bench/): one method only.
  bool kernel_benchmark = false;
  /// Variants a row may name after a '/' ("arkode/ark4", "cvode/klu").
  std::vector<std::string_view> variants = {};
  /// The settings only this method's rows read (MethodSetting).
  std::vector<MethodSetting> settings = {};
  /// Fills what a row's record says about the stepper beyond the registry
  /// (xpbd: the terms it solves as constraints and those it applies
  /// explicitly); nullptr: nothing.
  void (*describe)(const Stepper& stepper, const ParticleSystem& sys, RunRecord* record) = nullptr;
  /// The preconditioner that measures best for this method's fixed-step,
  /// substepped and SUNDIALS rows, used instead of a scene's IC(0) (the
  /// thesis' setting) unless --preconditioner names one; a scene that names
  /// any other preconditioner keeps it (the measurement is in
  /// kBestPreconditioner's comment); nullopt: the scene's.
  std::optional<PreconditionerType> best_preconditioner = std::nullopt;
  /// The same for its error-controlled rows ("/error"), whose step changes
  /// and refactorises the preconditioner nearly every step.
  std::optional<PreconditionerType> best_preconditioner_error = std::nullopt;
  /// The CG tolerance η that measures best for this method, used instead of
  /// the scene's solver.cg_tolerance unless the command line names one
  /// (the measurement is beside the entry); nullopt: the scene's.
  std::optional<double> best_cg_tolerance = std::nullopt;
  /// The same for SolverSpec::tangent_explicit_terms (whether the explicit
  /// terms' Jacobians enter J_α) where the method holds J_α.
  std::optional<bool> best_tangent_explicit_terms = std::nullopt;
  /// The method's rows in the default run, in table order, with their
  /// parameters (the measurements beside each entry). Empty: none.
  std::vector<RowDefaults> defaults = {};
  /// A note the run table prints once, for the first run of this method:
  /// `table_note` followed by the run's constraints and, if
  /// `table_note_terms` is not empty, "; <terms><its explicit terms>".
  std::string_view table_note = {};
  std::string_view table_note_terms = {};
  /// Statuses that belong to the method, with why (the run table's notes).
  std::vector<StatusNote> status_notes = {};
  /// The thesis' table rows this method ran (Tables 3.1 and 3.2), in the
  /// thesis' order within the method; the tables list methods in the
  /// registry's order.
  std::vector<ThesisTableRow> thesis_rows = {};
  /// The thesis' experiments that ran this method alone ("Table 5.1":
  /// implicit Euler; "Fig. 5.15": SBDF(2)); each names one method.
  std::vector<std::string_view> thesis_experiments = {};
};

/// The default run's preconditioner for every method that uses the PCG:
/// CHOLMOD's factor of A_α (for the Newton, Baraff–Witkin and SUNDIALS rows
/// the preconditioner of their tangent system). The thesis' IC(0) stays the
/// scenes' setting, used by --table and the stability maps.
///
/// Measured on the default scene (400 particles): the default run three
/// times with each of `--preconditioner ic0`, `cholesky`, `jacobi` (and
/// once with `amg`, slower than IC(0) for every method), each method's
/// solver time summed over its rows, the least of the three runs. Against
/// IC(0), the factor takes 0.75× for sbdf2, 0.90× sbdf3, 0.92× imex_euler,
/// 0.99× implicit_euler, 0.82× bdf2, 0.85× implicit_midpoint, 0.68×/0.80×/
/// 0.78× their Newton rows, 0.68× bdf2/newton/error, 0.66× baraff_witkin,
/// 0.92× cvode, 0.92–0.95× the arkode rows (and 0.96× for ida, run alone
/// twice with `--integrators ida`); 3×3 block Jacobi was never the
/// fastest. The one exception is sbdf2/error: 1.111 s against 0.977 s with
/// IC(0) (each change of h refactorises, and at 400 particles IC(0) is the
/// cheaper factorisation), so it keeps the scene's. Rows without the PCG
/// (blender, xpbd, cvode/klu) varied by 1–3 % between these runs, the
/// timing noise of the minimum. At 10⁴–10⁶ particles the factor wins for
/// SBDF(2) by 10–30× (docs/notes/performance.md, bench_scaling), and it is the
/// large_sheet scene's own setting.
/// Without contacts "auto" is that factor; in contact it chooses between the
/// factor with contact factors and the prefiltered AMG (docs/notes/performance.md,
/// "The contact policy").
inline constexpr PreconditionerType kBestPreconditioner = PreconditionerType::kAuto;

/// MethodEntry::make of the thesis' methods: the step engine with the
/// scheme of M (solver/scheme.h).
template <Method M>
std::unique_ptr<Stepper> MakeEngine(const ParticleSystem& sys, const SolverSpec& spec, int /*count*/,
                                    std::string_view /*variant*/) {
  return std::make_unique<StepEngine>(sys, M, spec);
}

/// The default run's tolerances of an adaptive row: rtol = atol = 1e-2 … 1e-7.
inline const std::vector<double> kDefaultRtols = {1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7};

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_METHOD_ROW_H_
