// What a result file says about a bench_integrators run, as plain data:
// provenance, scene, reference, one RunRecord per row and the
// equal-accuracy table. bench_integrators fills it from its runs and prints
// it; clothbench_inspect reads it back from the file (result_reader.h) and
// prints it with the same function, so `clothbench_inspect FILE table`
// reproduces the printed table from the file alone. Schema:
// docs/guide/results-schema.md.
#ifndef CLOTHBENCH_RESULTS_RUN_TABLE_H_
#define CLOTHBENCH_RESULTS_RUN_TABLE_H_

#include <cstdio>
#include <optional>
#include <functional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "solver/record/run_record.h"
#include "results/work_precision.h"

namespace clothbench {

/// The schema written by this build (root attribute "schema").
inline constexpr const char* kResultSchema = "clothbench/2";

/// When a writer stores a RunRecord field (absent ones read back as the
/// field's default in RunRecord{}).
enum class Stored {
  kAlways,
  kNonEmpty,     ///< strings: when not empty
  kPositive,     ///< numbers: when > 0
  kNonNegative,  ///< numbers: when ≥ 0 (−1 means "not applicable")
  kStepParameter,  ///< only where the row's step kind names it its parameter (h or rtol; SpecOf)
  kStepCount,      ///< only where the row's step kind names it its count (substeps or iterations)
  kSet,          ///< optionals: when they hold a value (no NaN is ever written)
};

/// One field of a RunRecord: its name (the /runs/<id> attribute, the key
/// of the Python module's dicts), the member and when it is stored.
struct RecordField {
  const char* name;
  std::variant<std::string RunRecord::*, double RunRecord::*, long RunRecord::*,
               std::optional<double> RunRecord::*, StepKind RunRecord::*, RunStatus RunRecord::*>
      member;
  Stored stored = Stored::kAlways;
  /// Derived against a reference on rank 0 (errors, order, energies): not
  /// part of what a rank sends or the journal keeps.
  bool derived = false;
};

/// Every field of a RunRecord except its id (the group's name), in the
/// order files list them: the one list the writer, the reader, the journal
/// codec and the Python module iterate (docs/guide/results-schema.md).
const std::vector<RecordField>& RunRecordFields();

/// The SUNDIALS counters a run group also holds as attributes (nst, nfe,
/// nfe_i, nni, nli, netf, ncfn, nje, nsetups: CVodePrintAllStats' names),
/// which are neither fields of the record nor method attributes.
const std::vector<std::string>& SundialsCounterNames();

/// Whether `name` may name a method attribute (RunRecord::method_attributes):
/// not a field of RunRecordFields(), a SUNDIALS counter or a name older
/// files used for a field (error_rms_m).
bool IsMethodAttributeName(const std::string& name);

/// True if `reference` (RunTable::reference) is a fixed-step
/// self-convergence run (a fixed-step run of one of the thesis' methods at a
/// fraction of the scene's smallest step) rather than an adaptive run at an rtol.
inline bool IsSelfConvergence(const RunRecord& reference) { return !SpecOf(reference.step_kind).adaptive(); }


/// Everything the printed table shows.
struct RunTable {
  // Provenance (root attributes).
  std::string schema = kResultSchema, created, git_commit, host, compiler, build_type;
  long hardware_threads = 0;
  // Scene (/scene attributes).
  std::string scene_name, scene_source, explicit_terms;  ///< explicit_terms: comma-separated
  std::string frames;                                    ///< the --frames mode
  long n_particles = 0, n_fixed = 0;
  double t_end = 0.0, frame_dt = 0.0;
  double h = 0.0;                    ///< the scene's nominal step [s]
  double numerical_stiffness = 0.0;  ///< h²k/(ρl²) at h
  // The scene's solver settings (/scene attributes solver_*).
  double cg_tolerance = 0.0;
  std::string cg_reference, preconditioner, predictor;
  std::string amg_frames;  ///< the prefiltered AMG's frames (SolverSpec::amg_frames); empty in older files
  long max_updates = 0;
  // The scene's other solver settings (model/solver_spec.h), stored so that
  // a file names every setting its runs used; cholesky_ordering is empty in
  // files written before they were stored (then none of them is written).
  std::string cholesky_ordering, contact_factors;  ///< contact_factors: "true" | "false"
  std::string tangent_projection, newton_jacobian;
  std::string contact_history;  ///< "keep" | "restart" | "project" | "land"; empty in files written before it was stored
  std::string friction_law;  ///< "explicit" | "regularised"; empty in files written before it was stored
  std::string friction_cap;  ///< "mass" | "system" | "stiction"; empty in files written before it was stored
  std::string controller_updates;  ///< "low,high" fixed-point updates of the iteration controller
  long cg_max_iterations = 0, max_rejections = 0;
  double fixed_point_tolerance = 0.0, step_factor = 0.0, h_min = 0.0, h_max = 0.0;

  /// The reference the e_rms column is measured against (/reference): the
  /// same record as a row's, its errors and order empty.
  std::optional<RunRecord> reference;
  /// The error norm of the e_rms column, the observed orders and the
  /// equal-accuracy table: "final", "l2" or "max" (--error-metric).
  std::string error_metric = "final";
  std::vector<RunRecord> runs;  ///< in run order
  std::optional<EqualAccuracyTable> work_precision;
};

/// One attribute of /scene: its name, the RunTable member and when it is
/// stored. kStepEngine: the step engine's settings, written when
/// cholesky_ordering is set (files before them hold none); kNonEmpty:
/// strings only when not empty. Absent attributes read back as the
/// member's default (empty, 0).
struct SceneField {
  enum class When { kAlways, kNonEmpty, kStepEngine, kStepEngineNonEmpty };
  const char* name;
  std::variant<std::string RunTable::*, long RunTable::*, double RunTable::*> member;
  When stored = When::kAlways;
  /// The key under which the Python module's dicts show it: the name
  /// without its "solver_" prefix.
  std::string_view key() const {
    const std::string_view n(name);
    return n.rfind("solver_", 0) == 0 ? n.substr(7) : n;
  }
};

/// Every /scene attribute in file order: the one list the writer
/// (WriteSceneRecord), the reader (ReadRunTable) and the Python module's
/// `read_results()["scene"]` iterate (docs/guide/results-schema.md).
const std::vector<SceneField>& SceneRecordFields();

/// What the lines under a run table say about each kind of row and about
/// the reference: written by the method registry (harness/table_notes.h),
/// so that the results layer names no method.
struct RunTableNotes {
  /// The legend of the h|rtol column (printed after the runs, if not empty).
  std::string legend;
  /// A note printed once, for the first run whose integrator is `integrator`:
  /// `text` followed by the run's constraints and, if `terms` is not empty,
  /// "; <terms><the run's explicit terms, or none>".
  struct Row {
    std::string integrator, text, terms;
  };
  std::vector<Row> rows;
  /// Lines printed after the rows' notes (the adaptive rows' counts).
  std::string after_rows;
  /// The reference line for a reference run and the error metric's name
  /// (ErrorName); empty function: no reference line.
  std::function<std::string(const RunRecord& reference, const std::string& error_name)> reference;
  /// A note printed once, if some run of `integrator` ended with `status`
  /// (RunStatus name): why that status belongs to the method.
  struct StatusNote {
    std::string integrator, status, text;
  };
  std::vector<StatusNote> statuses;
};

/// The name of an error metric ("final", "l2", "max") in the tables' text.
std::string ErrorName(const std::string& metric);

/// Prints the run table exactly as bench_integrators prints it: the scene,
/// solver and reference lines, one line per run, the footnotes (`notes`)
/// and the machine line.
void PrintRunTable(std::FILE* out, const RunTable& table, const RunTableNotes& notes = {});

/// The equal-accuracy table of `runs` (docs/notes/work-precision.md): per row
/// label, in order of first appearance, the (solver time, error, timing
/// spread) of its ok runs that have an error of `metric` ("final", "l2",
/// "max"), against `targets` [m], ratios to `baseline` (a label; empty: none);
/// targets below 10× `reference_error` [m] (the reference's error estimate in
/// `metric`; negative: not known) unresolved (MarkUnresolvedTargets).
EqualAccuracyTable WorkPrecisionOf(const std::vector<const RunRecord*>& runs, const std::vector<double>& targets,
                                   const std::string& baseline, std::string_view metric, double reference_error);

/// Prints the equal-accuracy table (docs/notes/work-precision.md).
void PrintWorkPrecision(std::FILE* out, const EqualAccuracyTable& table);

}  // namespace clothbench

#endif  // CLOTHBENCH_RESULTS_RUN_TABLE_H_
