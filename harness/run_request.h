// One run of one row, as every entry point asks for it: the scene, the row
// by its registry name, h or rtol, substeps, the solver options a user may
// override, the frames kept, the limits and the reference it is compared
// with. The Python module's run() and reference(), the rerun of a stored
// run (clothbench_inspect … rerun / command) and contact_replay build one
// and call Validate() or Resolve() before anything is computed, so that
// they refuse the same input with the same line; bench_integrators and
// stress_stability validate each planned run through it too. The rules
// (docs/guide/scenes.md "Limits"):
//  - method: a registry row ("bdf2/newton", "arkode/ark4"), runnable on the
//    scene's step control;
//  - h [s]: fixed-step, substepped and iterated rows only, finite, > 0,
//    ≤ t_end, and t_end/h ≤ kMaxStepsPerRun; rtol: adaptive rows only, in
//    [kMinRelativeTolerance, 1); substeps: substepped rows only, 1 … 10⁶;
//    iterations: iterated rows only, 1 … 10⁶;
//  - cg_tolerance in (0, 1) and preconditioner: rows that solve with the
//    PCG; tangent_terms "all" | "tension": rows that build J_α; a
//    method's own setting (MethodSetting: arkode_table, cvode_setting):
//    the rows that read it, by its method's rule (an option no row reads
//    is refused, not ignored);
//  - t_end in (0, 1e6] s with t_end/frame_dt ≤ kMaxFramesPerRun; frames
//    default | all | positions | ends | none;
//  - threads 0 (as the process has them) or 1 … kMaxThreads; time_limit in
//    (0, 1e7] s; repeat 1 … 1000; time_budget in [0, 1e6] s;
//  - reference_scene: if set, the SceneHash of the scene the reference was
//    computed on, which must be this request's.
// Each refusal is one line "<field>: <value> <rule>", the field named as
// the entry point names it (Python keywords or command-line options).
#ifndef CLOTHBENCH_HARNESS_RUN_REQUEST_H_
#define CLOTHBENCH_HARNESS_RUN_REQUEST_H_

#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "harness/methods.h"
#include "model/scene.h"

namespace clothbench {

/// The most OpenMP threads a request may ask for.
inline constexpr long kMaxThreads = 1024;

/// Refuses an OMP_NUM_THREADS the runs would store and their reruns refuse:
/// each of its comma-separated counts must be a whole number from 1 to
/// kMaxThreads (OpenMP would read "1025" as 1025 threads and
/// "99999999999" as an overflowed int). Unset is fine. Called by every
/// request's validation (threads = 0: the process' own count).
/// @throws UsageError "OMP_NUM_THREADS: \"…\" must be …"
void CheckThreadEnvironment();

/// How refusals name a request's fields: Python keywords ("t_end") or
/// bench_integrators options ("--t-end").
enum class FieldNames { kKeyword, kOption };

/// A stable hash (FNV-1a 64, hex) of what a reference depends on: the scene
/// text, t_end and frame_dt. A reference computed on one scene is refused
/// for another (RunRequest::reference_scene).
std::string SceneHash(const Scene& scene);

/// The run a validated RunRequest resolves to: the scene with t_end and
/// frames applied, the row, its solver settings and context, and h or rtol.
struct ResolvedRun {
  Scene scene;
  RowMethod row;
  SolverSpec spec;   ///< the scene's solver settings with the request's overrides
  RunContext ctx;
  double param = 0.0;  ///< h [s] (fixed-step, substepped, iterated) or rtol (adaptive)
  int count = 1;       ///< substeps (substepped rows) or iterations per step (iterated rows)
};

struct RunRequest {
  Scene scene;         ///< as loaded, before t_end and frames are applied
  std::string method;  ///< registry row label
  std::optional<double> h, rtol;
  std::optional<long> substeps, iterations;
  std::optional<double> cg_tolerance;
  std::optional<std::string> preconditioner, tangent_terms;
  /// The methods' own settings, {field, value} (MethodSetting::field:
  /// "arkode_table", "cvode_setting"), each refused unless the row reads it.
  std::vector<std::pair<std::string, std::string>> settings;
  /// "on" | "off": overrides the scene's collision.self ("on" on a scene
  /// without [collision] adds it with the default thickness, checked
  /// against the grid as the scene's own; "off" keeps the crossing count).
  std::optional<std::string> self_contact;
  std::optional<double> t_end;  ///< overrides the scene's t_end [s]
  std::string frames = "default";
  long threads = 0;
  double time_limit = RunLimits().time_limit_s;  ///< wall-time budget of the run [s]
  std::optional<long> repeat;
  double time_budget = 30.0;
  std::optional<std::string> reference_scene;  ///< SceneHash of the reference's scene
  FieldNames names = FieldNames::kKeyword;
  /// Fields an entry point names otherwise than `names` says
  /// (contact_replay: {"method", "--integrator"}).
  std::vector<std::pair<std::string, std::string>> renamed;

  /// @throws UsageError (a std::invalid_argument), one line naming the
  ///   field, its value and the rule, for the first field that breaks one
  void Validate() const;
  /// The run this request asks for. @throws UsageError as Validate()
  ResolvedRun Resolve() const;
  /// The scene of a sweep over many rows (bench_integrators): `scene` with
  /// t_end and frames applied and the values of cg_tolerance,
  /// preconditioner, tangent_terms, time_limit, repeat and time_budget
  /// checked by the rules Resolve() applies, the solver options set; method,
  /// h, rtol, substeps and iterations are not read (each planned row resolves its own).
  /// @throws UsageError as Validate()
  Scene SweepScene() const;
  /// The name of `field` (a keyword) as this request's entry point spells it.
  std::string Field(std::string_view field) const;
  /// Sets a row's step as its step kind names it: h or rtol to `param`,
  /// and its count (substeps or iterations), if the kind has one, to `count`.
  void SetStep(const StepKindSpec& kind, double param, long count) {
    (kind.adaptive() ? rtol : h) = param;
    if (kind.counted()) (kind.count == "substeps" ? substeps : iterations) = count;
  }
};

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_RUN_REQUEST_H_
