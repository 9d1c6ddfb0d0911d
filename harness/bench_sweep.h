// The sweep of bench_integrators: the reference and every planned row, dealt
// over the MPI ranks and journalled, then the table, the equal-accuracy
// table and the result file.
#ifndef CLOTHBENCH_HARNESS_BENCH_SWEEP_H_
#define CLOTHBENCH_HARNESS_BENCH_SWEEP_H_

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "harness/methods.h"
#include "harness/plan.h"
#include "harness/run_codec.h"
#include "harness/sweep.h"
#include "model/scene.h"
#include "results/work_precision.h"

namespace clothbench {

/// --sizes: each method's runs at the sizes swept so far, per rung of its
/// ladder, for predicting its start at the next size (RunTargetSweep).
struct SizeHistory {
  struct Start {
    long particles;      ///< the size's particle count
    double wall_time_s;  ///< the start's wall time [s] (its time limit where it ended time_limit)
    bool ok;             ///< whether it ended ok
    bool predicted = false;  ///< not run: wall_time_s is its prediction
    bool timed_out = false;  ///< ended time_limit: wall_time_s is at least its limit
  };
  /// per "<row label>@<rung>" (0 the ladder's start, −1 the next cheaper, 1 the next finer), in size order
  std::map<std::string, std::vector<Start>> runs;
};

/// The wall time [s] of a method's run at `particles`, predicted from its
/// runs of the same rung at smaller sizes (those of `starts` at fewer
/// particles; a prediction at this size is ignored): the last one's wall time scaled by
/// (particles / its particles)^p, p the exponent between the last two
/// starts (at least 1: no method's start costs less than linearly in N), 1
/// with only one. A start that ended time_limit counts with its limit, a
/// lower bound of its cost; one that failed sooner (a blow-up) with the
/// time it ran, which underestimates and so never stops a method wrongly.
/// 0 (no prediction) without any start.
double PredictedStartTime(const std::vector<SizeHistory::Start>& starts, long particles);

/// Everything a bench_integrators run needs, validated by the caller.
struct BenchRun {
  Scene scene;                     ///< with the command line's overrides (t_end, η, preconditioner, frames)
  std::vector<RowMethod> methods;  ///< the rows, in table order
  RowPlan plan;                    ///< each method's h/rtol list (PlanRows)
  std::vector<double> etas;        ///< CG tolerances (rows that use the PCG run once per value)
  std::vector<double> targets;     ///< e_rms targets of the equal-accuracy table [m]
  std::string baseline;            ///< the row label the equal-accuracy ratios are relative to (--baseline)
  ErrorMetric error_metric = ErrorMetric::kFinal;  ///< --error-metric
  /// Timings per run (--repeat); 0: 3 for runs whose first timing is under
  /// 2 s, 1 above (DiffEqDevTools' rule).
  int repeat = 0;
  double time_budget = 15.0;  ///< wall time [s] all repetitions after the first may take (--time-budget)
  std::vector<double> hs;          ///< --h (empty: defaults); sets the self-convergence reference's h
  std::optional<RowMethod> reference;  ///< the reference row (ParseReference; none: --reference none)
  double ref_rtol = 1e-10;
  std::string out, plot_dir, series;  ///< result file; --plot folder and --series CSV (empty: none)
  std::string frames_mode;            ///< --frames
  std::string journal_key;            ///< the journal's key (the scene and the command's arguments)
  bool work_precision_only = false, quiet = false, preconditioner_from_cli = false, cg_tolerance_from_cli = false,
       tangent_terms_from_cli = false;
  double time_limit = 0.0;  ///< wall-time budget of each run [s]
  long max_runs = 0;        ///< > 0: compute at most this many runs, then exit kExitPartial
  /// The methods' own settings as given, {field, value} (RunContext::settings).
  std::vector<std::pair<std::string, std::string>> settings;
  /// --sweep-to-targets: each method's h, substeps or rtol chosen run by run
  /// until its runs bracket every target (RunBench; docs/notes/work-precision.md).
  bool sweep_to_targets = false;
  /// Keep <out>.journal after the file is written (--sizes: removed once
  /// the verdict is written, so that a rerun finds every finished size).
  bool keep_journal = false;
  /// --report: the result file's HTML page beside it (<stem>.html,
  /// scripts/report) once the file is written.
  bool report = false;
  /// --sizes: the starts at the smaller sizes, shared by the sizes' runs
  /// (nullptr: a single size).
  std::shared_ptr<SizeHistory> size_history;
  /// --start-predicted: start rows predicted past the limits (harness/first_run.h).
  bool start_predicted = false;
  /// The reference's wall-time budget [s]: --time-limit if the command gave
  /// one, else RunLimits' default (the 30 s a sweep's runs default to is
  /// not the reference's: at 10⁵ particles it needs minutes).
  double reference_time_limit = 0.0;
};

/// Times run `r` again with `run_again` until it has `repeat` timings (0:
/// DiffEqDevTools' rule, 3 if its first solver time is under 2 s, else 1,
/// each started only while its first run's wall time fits `*budget` [s],
/// which the repetitions use up). Keeps the least solver time in
/// solver_time_s, the median and largest, and the count in repeats.
/// @throws std::runtime_error naming the run if a repetition does not
///   reproduce the first run's end state bit for bit
void RepeatTimings(MethodRun* r, int repeat, double* budget, const std::function<MethodRun()>& run_again);

/// Runs the sweep on this rank's share of the tasks; rank 0 assembles,
/// prints the tables and writes `b.out` (and its XDMF, the series and the
/// plots). @return 0, 1 if the reference failed, kExitPartial after
/// --max-runs. @throws Interrupted on SIGINT/SIGTERM, std::runtime_error on
/// an unreadable journal record or an unwritable file.
/// @param wp if given, set to the equal-accuracy table written (rank 0)
int RunBench(const BenchRun& b, SweepComm& comm, EqualAccuracyTable* wp = nullptr);

/// The wall time [s] a --sweep-to-targets refinement will take, from the
/// last run's `last_s` [s] and, for an adaptive row, the run's before it
/// `before_s` [s] (≤ 0: none or not ok): twice `last_s` where the
/// refinement doubles the steps, substeps or iterations; for an adaptive row
/// (rtol / 10) `last_s` times the last refinement's growth (at least 1).
/// 0 (no prediction) without the runs it needs. The sweep does not start a
/// run predicted past --time-limit, which would cost the whole limit and
/// end time_limit (docs/notes/work-precision.md, "Sweeps driven by the targets").
double PredictedWallTime(StepKind kind, double last_s, double before_s);

/// --sizes (docs/notes/work-precision.md, "The size axis"): RunBench for each of
/// `runs` (one per size, increasing, each on its refined scene with its own
/// result file and journal), then the verdict file `out`: per size
/// /sizes/n<N> (its scene text, result file name and work_precision) and
/// /scale_verdict (results/scale_verdict.h), printed and, with `plot_dir`,
/// drawn. @return 0, or the first size's non-zero RunBench status (no
/// verdict then; the finished sizes' journals are kept for a rerun)
/// @throws as RunBench, and std::runtime_error if `out` cannot be written
/// With `report`, the verdict's page too (each size's page: BenchRun::report).
int RunSizes(const std::vector<BenchRun>& runs, const std::vector<long>& sizes, const std::string& out,
             const std::string& plot_dir, SweepComm& comm, bool report = false);

/// bench_integrators' journal key: the run records' format (RunRecordFormat),
/// the scene's text and the command's arguments, except those that change
/// no result (--max-runs, --plot, --quiet), so that a rerun of the same
/// command, sliced or not, by the same build finds its journal, and another
/// build whose records differ is refused it.
inline std::string JournalKey(int argc, char** argv, const Scene& scene) {
  std::string key = fmt::format("bench_integrators journal 7 format={} scene={} args=", Fnv1a64(RunRecordFormat()),
                                Fnv1a64(scene.toml));
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--max-runs" || a == "--plot") {
      ++i;
      continue;
    }
    if (a.rfind("--max-runs=", 0) == 0 || a.rfind("--plot=", 0) == 0 || a == "--quiet") continue;
    key += EscapeControl(a) + " ";
  }
  return key;
}

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_BENCH_SWEEP_H_
