// bench_integrators' command line: its options as given, their
// registration with CLI11, and the planning that turns them into a
// validated BenchRun (every rule checked before anything is computed).
#ifndef CLOTHBENCH_HARNESS_BENCH_OPTIONS_H_
#define CLOTHBENCH_HARNESS_BENCH_OPTIONS_H_

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "harness/bench_sweep.h"
#include "harness/methods.h"
#include "harness/sweep.h"
#include "model/scene.h"

namespace clothbench {

/// The command line's values, as given (validated by PlanBench).
struct Options {
  std::string scene_path, integrators_arg, h_arg, reference = std::string(DefaultReference()), out, rtols_arg;
  double t_end = 0.0, ref_rtol = 1e-10, cg_tolerance = 0.0, time_limit = RunLimits().time_limit_s, time_budget = 15.0;
  int repeat = 0;
  std::string series, table, preconditioner, frames_mode = "default", nonlinear_arg, plot_dir;
  std::string tangent_terms, baseline = std::string(DefaultReference()), error_metric = "final";
  /// The methods' own settings (MethodSetting), their option's value by field;
  /// only those whose option was given are read.
  std::map<std::string, std::string> method_settings;
  std::string targets_arg = "1e-2,1e-3,1e-4", cg_tolerances_arg, substeps_arg = "1,4,16,64", iterations_arg = "1,4,16,64";
  bool work_precision_only = false, quiet = false;
  long max_runs = 0;
  bool sweep_to_targets = false;
  std::string sizes_arg;
  std::string self_contact;  ///< --self-contact on | off (RunRequest::self_contact)
  bool report = false;       ///< --report: the result file's HTML page (scripts/report)
  bool start_predicted = false;  ///< --start-predicted: start rows predicted past the limits (harness/first_run.h)
};

/// Registers every option of bench_integrators on `app`, into `o`.
void AddOptions(CLI::App& app, Options& o);

/// The scene the options name (--scene, a built-in name or a file), with
/// --t-end applied, refined to `size` particles if given (--sizes).
/// @throws SceneError, UsageError
Scene SceneOfOptions(const CLI::App& app, const Options& o, std::optional<long> size = std::nullopt);

/// Validates every option and plans the runs: rows, parameters, the
/// reference, targets and output, each by the rules every entry point
/// shares (harness/run_request.h), the memory and the output paths probed
/// on rank 0. `size`: the particle count of a --sizes sweep.
/// @throws UsageError, SceneError (one line naming the option or key)
BenchRun PlanBench(const CLI::App& app, Options& o, std::vector<NonlinearSolver> solvers, std::vector<double> etas,
                   SweepComm& comm, int argc, char** argv, std::optional<long> size = std::nullopt);

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_BENCH_OPTIONS_H_
