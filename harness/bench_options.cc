#include "harness/bench_options.h"

#include <cmath>
#include <filesystem>
#include <set>

#include <fmt/format.h>

#include "harness/cli_args.h"
#include "harness/memory_check.h"
#include "harness/output_lock.h"
#include "harness/plan.h"
#include "harness/plot.h"
#include "harness/run_request.h"
#include "harness/reference.h"
#include "harness/thesis_tables.h"
#include "model/particle_system.h"
#include "solver/run.h"

namespace clothbench {
namespace {


// A --sweep-to-targets run's --time-limit when the command gives none [s]:
// the sweep's runs are chosen by error, and a method whose next run takes
// longer is stopped there with reason time_limit.
constexpr double kSweepTimeLimit = 30.0;

// The methods' own settings whose option was given, {field, value}: each
// planned run's request checks those its row reads (RunRequest::settings).
std::vector<std::pair<std::string, std::string>> GivenSettings(const CLI::App& app, const Options& o) {
  std::vector<std::pair<std::string, std::string>> given;
  for (const RowOption& row_option : RowOptions()) {
    const MethodSetting* setting = FindSetting(row_option.field);
    if (setting && app.count(std::string(setting->option)))
      given.emplace_back(row_option.field, o.method_settings.at(row_option.field));
  }
  return given;
}

// The options only some rows read that the command line gives (UnusedOption).
GivenOptions GivenOf(const CLI::App& app, const std::string& baseline,
                     const std::vector<std::pair<std::string, std::string>>& settings) {
  GivenOptions given{{}, app.count("--baseline") ? EscapeControl(baseline) : ""};
  const std::pair<const char*, bool> harness_options[] = {
      {"rtol", app.count("--rtols") > 0},
      {"substeps", app.count("--substeps") > 0},
      {"iterations", app.count("--iterations") > 0},
      {"cg_tolerance", app.count("--cg-tolerance") + app.count("--cg-tolerances") > 0},
      {"preconditioner", app.count("--preconditioner") > 0},
      {"nonlinear_solver", app.count("--nonlinear-solver") > 0},
      {"tangent_terms", app.count("--tangent-terms") > 0}};
  for (const auto& [field, given_option] : harness_options)
    if (given_option) given.fields.emplace_back(field);
  for (const auto& setting : settings) given.fields.push_back(setting.first);
  return given;
}

}  // namespace

void AddOptions(CLI::App& app, Options& o) {
  [[maybe_unused]] auto& [scene_path, integrators_arg, h_arg, reference, out, rtols_arg, t_end, ref_rtol, cg_tolerance,
                          time_limit, time_budget, repeat, series, table, preconditioner, frames_mode, nonlinear_arg,
                          plot_dir, tangent_terms, baseline, error_metric, method_settings, targets_arg, cg_tolerances_arg,
                          substeps_arg, iterations_arg, work_precision_only, quiet, max_runs, sweep_to_targets, sizes_arg, self_contact_arg, report, start_predicted] = o;
  app.add_option("--scene", scene_path,
                 "scene file (TOML) or built-in name (swinging_sheet, hanging_sheet, wind_sheet); default swinging_sheet");
  std::string default_rows;
  for (const DefaultRow& d : DefaultRows()) default_rows += (default_rows.empty() ? "" : ", ") + std::string(d.label);
  app.add_option("--integrators", integrators_arg,
                 fmt::format("comma-separated rows of the methods {}; a fully implicit method may name its nonlinear "
                             "solver (/newton, /fixed_point), a method under error control /error, a variant its name "
                             "(/ark4, /ark5: ARKODE's IMEX pairs of order 4 and 5; /klu: KLU on the first-order system "
                             "instead of the reduced PCG solve) (default: {}; the Newton rows only beside the scene's "
                             "fixed-point solver)",
                             KnownMethodNames(), default_rows));
  app.add_option("--nonlinear-solver", nonlinear_arg,
                 "comma-separated fixed_point,newton: one row per solver for the fully implicit methods (default: "
                 "the scene's solver.nonlinear_solver); also for --table");
  app.add_option("--h", h_arg,
                 "comma-separated step sizes [s] of every fixed-step row and frame steps of the substepped rows "
                 "(default: per method, multiples of the scene's h chosen so that the default scene's runs bracket "
                 "e_rms = 1e-3 m; docs/notes/work-precision.md)");
  app.add_option("--t-end", t_end, "end time [s] (default: the scene's t_end)");
  app.add_option("--reference", reference,
                 fmt::format("the reference: {} (without /klu: the reduced velocity solve; /klu: KLU on the "
                             "first-order Jacobian) or none (default {})",
                             ReferenceNames(), DefaultReference()));
  app.add_option("--reference-rtol", ref_rtol, "rtol (= atol) of the reference (default 1e-10)");
  app.add_option("--rtols", rtols_arg,
                 fmt::format("rtol (= atol) list of the {} (default: {})", RowsReading(RowOptionOf("rtol")),
                             DefaultListsText(true)));
  app.add_option("--substeps", substeps_arg,
                 fmt::format("comma-separated substeps per frame step of the {}: one row per h and value (default "
                             "1,4,16,64)",
                             RowsReading(RowOptionOf("substeps"))));
  app.add_option("--iterations", iterations_arg,
                 fmt::format("comma-separated iterations per step of the {}: one row per h and value (default: {})",
                             RowsReading(RowOptionOf("iterations")), DefaultListsText(false)));
  for (const RowOption& row_option : RowOptions())  // the methods' own settings (MethodEntry::settings)
    if (const MethodSetting* setting = FindSetting(row_option.field))
      app.add_option(std::string(setting->option), method_settings[row_option.field],
                     fmt::format("{} ({})", setting->help, RowsReading(row_option)));
  app.add_option("--targets", targets_arg, "e_rms targets [m] of the equal-accuracy table (default 1e-2,1e-3,1e-4)");
  app.add_option("--cg-tolerances", cg_tolerances_arg,
                 "comma-separated CG tolerances: every method that uses the PCG runs once per value (a second "
                 "axis of the work-precision table)");
  app.add_flag("--work-precision", work_precision_only,
               "print only the equal-accuracy table (it is also printed under the default table)");
  app.add_option("--cg-tolerance", cg_tolerance, "override the scene's solver.cg_tolerance (PCG stop ‖r‖ ≤ η‖Sb‖)");
  app.add_option("--preconditioner", preconditioner,
                 "override the scene's solver.preconditioner: auto | ic0 | cholesky | amg | jacobi | none");
  app.add_option("--error-metric", error_metric,
                 "the error of the e_rms column, the observed orders, the equal-accuracy table and the plots: final "
                 "(e_rms at t_end; the default without obstacles) | l2 (rms over the frames; the default on scenes with "
                 "obstacles, whose contact events are not smooth) | max (max over the frames)");
  app.add_option("--baseline", baseline,
                 fmt::format("the row the equal-accuracy ratios are relative to (default {})", DefaultReference()));
  app.add_option("--tangent-terms", tangent_terms,
                 "J_alpha's terms in every row that builds it: all | tension (tension and mass only); default: the "
                 "scene's solver.tangent_explicit_terms, and each method's measured best (its row, solver/method_row.h)");
  app.add_option("--frames", frames_mode,
                 "which frames the file keeps (errors and energies always use every frame_dt): default: positions "
                 "every frame_dt for the reference and each method's first row, at t = 0 and t_end for the other "
                 "rows, velocities at t = 0 and t_end | all: positions and velocities every frame_dt | positions: "
                 "positions every frame_dt, velocities at the ends | ends: only t = 0 and t_end are computed and "
                 "kept (errors and energies at the ends) | none: no frame datasets (errors at t_end still computed)");
  app.add_option("--series", series,
                 "write every step (t, h, updates, CG iterations, colliding particles) as CSV to FILE and print the "
                 "impact / resting-contact summary (thesis Fig. 4.3)");
  app.add_option("--table", table,
                 "print the thesis' Table 3.1 or 3.2 beside ours with e_rms against a self-convergence reference, "
                 "once per --cg-tolerances value; 5.1: the cost of the virtual particles on the thesis' three "
                 "examples; 5.15: Fig. 5.15's coarse drape with virtual particles against fine drapes (and write HDF5)");
  app.add_option("--out", out, "result file (default: out/<scene>.h5)");
  app.add_option("--repeat", repeat, "timings per run: the least is reported, with the spread (default: 3 for runs "
                 "under 2 s, 1 above, within --time-budget)")->check(CLI::Range(1, 1000));
  app.add_option("--time-budget", time_budget, "wall time [s] all repetitions after a run's first may take together "
                 "(default 15; ignored with --repeat)")->check(CLI::Range(0.0, 1e6));
  app.add_option("--max-runs", max_runs,
                 "compute at most N runs (the reference counts as one) not yet in <out>.journal/, then stop with exit "
                 "status 75 and keep the journal; rerun the same command to continue")
      ->check(CLI::Range(1L, 1000000000L));
  app.add_option("--time-limit", time_limit,
                 "wall-time budget of each run [s] (default 3600): a run past it ends with status time_limit and the "
                 "other rows still run and are written; with --sweep-to-targets or --sizes: 30, the reference's 3600)");
  app.add_flag("--sweep-to-targets", sweep_to_targets,
               "choose each method's h, substeps or rtol run by run from its errors against the reference until its "
               "runs bracket every --targets value, it fails, reaches --time-limit or stalls (instead of the fixed "
               "lists; docs/notes/work-precision.md)");
  app.add_option("--self-contact", self_contact_arg,
                 "on | off: override the scene's collision.self (on: with its [collision] thickness, or 1e-3 m on a "
                 "scene without the table; off: no response, the crossing pairs still counted at every stored frame; "
                 "docs/notes/collisions.md, \"Self-contact\")");
  app.add_option("--sizes", sizes_arg,
                 "comma-separated particle counts, increasing: the scene's grid refined to about N particles each "
                 "(sheet size, material per unit length and area, forces, constraints and t_end kept; "
                 "docs/model.md, \"Resolution\"), a --sweep-to-targets run per size with its own result file "
                 "(<out stem>.n<N>.h5), then the verdict across sizes in --out (default out/<scene>_sizes.h5, "
                 "/scale_verdict; clothbench_inspect FILE verdict)");
  app.add_flag("--quiet", quiet, "no progress line on stderr (it is shown only when stderr is a terminal and a run takes "
                                 "more than 2 s)");
  app.add_option("--plot", plot_dir,
                 "after writing the results, draw them into DIR with scripts/plot (work-precision, observed order, "
                 "energy, Fig. 4.3 on obstacle scenes; PNG and SVG)");
  app.add_flag("--start-predicted", start_predicted,
               "start every run, also one whose first run is predicted past --time-limit or 80 % of the available "
               "memory, and the finer rungs of a row after one of its runs ended time_limit (by default such a run "
               "is stored not_started with the reason; docs/notes/work-precision.md, \"Predicting a first run\")");
  app.add_flag("--report", report,
               "after writing the results, write one self-contained HTML page beside the result file (<stem>.html; "
               "with --sizes also the verdict's) with scripts/report: scene, settings, tables, work-precision, "
               "convergence, energy and CG plots, the commands that rerun each run (scripts/bench passes it)");
}

// The scene of the invocation: --scene (or the default), with --t-end,
// --frames, --cg-tolerance, --preconditioner and --tangent-terms applied and
// --time-limit, --repeat and --time-budget checked, by the rules of every
// entry point (RunRequest::SweepScene).
// @throws UsageError or SceneError, one line
// @param size --sizes: the grid refined to about this many particles (RefineGrid) before the overrides
Scene SceneOfOptions(const CLI::App& app, const Options& o, std::optional<long> size) {
  RunRequest q;
  q.names = FieldNames::kOption;
  q.scene = o.scene_path.empty() ? DefaultScene() : LoadSceneOrBuiltin(o.scene_path);
  if (size) q.scene = RefineGrid(q.scene, *size);
  if (app.count("--t-end")) q.t_end = o.t_end;
  q.frames = o.frames_mode;
  if (app.count("--cg-tolerance")) q.cg_tolerance = o.cg_tolerance;
  if (app.count("--preconditioner")) q.preconditioner = o.preconditioner;
  if (app.count("--tangent-terms")) q.tangent_terms = o.tangent_terms;
  if (app.count("--self-contact")) q.self_contact = o.self_contact;
  q.time_limit = o.time_limit;
  if (o.repeat > 0) q.repeat = o.repeat;
  q.time_budget = o.time_budget;
  return q.SweepScene();
}


// Validates everything before anything is computed, on every rank (rank 0
// probes the file system and the memory): the scene and its overrides, the
// rows and each planned run as a RunRequest, the output paths.
// @param solvers, etas parsed --nonlinear-solver and --cg-tolerances (may be empty)
// @param size --sizes: this size's refined grid (SceneOfOptions)
// @throws UsageError or SceneError, one line
BenchRun PlanBench(const CLI::App& app, Options& o, std::vector<NonlinearSolver> solvers, std::vector<double> etas,
                   SweepComm& comm, int argc, char** argv, std::optional<long> size) {
  [[maybe_unused]] auto& [scene_path, integrators_arg, h_arg, reference, out, rtols_arg, t_end, ref_rtol, cg_tolerance,
                          time_limit, time_budget, repeat, series, table, preconditioner, frames_mode, nonlinear_arg,
                          plot_dir, tangent_terms, baseline, error_metric, method_settings, targets_arg, cg_tolerances_arg,
                          substeps_arg, iterations_arg, work_precision_only, quiet, max_runs, sweep_to_targets, sizes_arg, self_contact_arg, report, start_predicted] = o;
  if (sweep_to_targets && !app.count("--time-limit")) time_limit = kSweepTimeLimit;
  Scene scene = SceneOfOptions(app, o, size);
  if (app.count("--integrators") && integrators_arg.empty())
    throw UsageError("--integrators: empty list \"\" (name rows, or leave the option out for the default rows)");
  std::optional<RowMethod> reference_row;
  if (reference != "none") {
    try {
      reference_row = ParseReference(reference, "--reference");
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string(e.what()) + " or none");
    }
  }
  CheckTolerance(ref_rtol, "--reference-rtol");
  const std::vector<std::pair<std::string, std::string>> settings = GivenSettings(app, o);
  const std::vector<std::string> names =
      integrators_arg.empty() ? DefaultRowNames(scene.solver.nonlinear_solver, app.count("--nonlinear-solver") > 0)
                              : SplitList(integrators_arg, "--integrators");
  if (solvers.empty()) solvers = {scene.solver.nonlinear_solver};
  std::vector<RowMethod> methods;
  try {
    methods = ExpandMethods(names, solvers, "--integrators");
    // "sbdf2" under a scene's error control is sbdf2/error; named rows without error control are refused.
    AdoptSceneStepControl(scene.solver, &methods, !integrators_arg.empty());
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  for (std::size_t a = 0; a < methods.size(); ++a)
    for (std::size_t b = 0; b < a; ++b)
      if (methods[a].label() == methods[b].label())
        throw UsageError(fmt::format("--integrators: {} is listed twice (with --nonlinear-solver newton, a fully "
                                     "implicit method's name also names its /newton row)",
                                     methods[a].label()));
  const std::string unused = UnusedOption(methods, GivenOf(app, baseline, settings));
  if (!unused.empty()) throw UsageError(unused);
  const std::vector<double> targets = ParsePositiveList(targets_arg, "--targets");
  for (double e : targets)
    if (e > 1e6)  // the farthest a scene's coordinates reach (model/scene.h): no error can be larger
      throw UsageError(fmt::format("--targets: {:g} m must be at most 1e6 m", e));
  if (!app.count("--error-metric")) error_metric = std::string(ToString(DefaultErrorMetric(scene)));
  const std::optional<ErrorMetric> metric = ParseErrorMetric(error_metric);
  if (!metric)
    throw UsageError(fmt::format("--error-metric: \"{}\" must be final, l2 or max", EscapeControl(error_metric)));
  if (etas.empty()) etas = {scene.solver.cg_tolerance};
  std::vector<double> hs = h_arg.empty() ? std::vector<double>{} : ParsePositiveList(h_arg, "--h");  // h ≤ t_end: the request's rule
  const std::vector<double> rtols =
      app.count("--rtols") ? ParseTolerances(rtols_arg, "--rtols") : std::vector<double>{};
  std::vector<int> substeps;
  for (double n : ParsePositiveList(substeps_arg, "--substeps")) {
    if (n != std::floor(n) || n > 1e6)
      throw UsageError(fmt::format("--substeps: {:g} must be a whole number from 1 to 1e6", n));
    substeps.push_back(static_cast<int>(n));
  }
  std::vector<int> iterations;  // empty: each iterated row's default counts (PlanRows)
  if (app.count("--iterations"))
  for (double k : ParsePositiveList(iterations_arg, "--iterations")) {
    if (k != std::floor(k) || k > 1e6)
      throw UsageError(fmt::format("--iterations: {:g} must be a whole number from 1 to 1e6", k));
    iterations.push_back(static_cast<int>(k));
  }
  if (sweep_to_targets) {
    for (const char* option : {"--h", "--rtols", "--substeps", "--iterations"})
      if (app.count(option))
        throw UsageError(fmt::format("{}: --sweep-to-targets chooses the runs itself", option));
    if (etas.size() > 1) throw UsageError("--cg-tolerances: --sweep-to-targets runs one CG tolerance");
    if (reference == "none") throw UsageError("--reference none: --sweep-to-targets needs the reference's errors");
    if (max_runs > 0) throw UsageError("--max-runs: --sweep-to-targets does not stop early (the journal resumes it)");
    if (comm.size() > 1)
      throw UsageError("--sweep-to-targets: it chooses each run from the errors of the one before; run it on one "
                       "rank (without mpirun)");
  }
  const RowPlan plan = PlanRows(scene, methods, hs, rtols, substeps, iterations, etas.size());
  // Every planned run as a request, by the rules every entry point shares
  // (harness/run_request.h); the options only some rows read were checked
  // by UnusedOption above.
  for (std::size_t k = 0; k < methods.size(); ++k)
    for (const auto& [param, n] : plan.params[k]) {
      RunRequest q;
      q.scene = scene;
      q.method = methods[k].label();
      q.names = FieldNames::kOption;
      q.SetStep(SpecOf(methods[k].kind()), param, n);
      for (const auto& setting : settings)
        if (methods[k].setting(setting.first)) q.settings.push_back(setting);
      q.time_limit = time_limit;
      if (repeat > 0) q.repeat = repeat;
      q.time_budget = time_budget;
      q.Validate();
    }
  if (out.empty()) out = fmt::format("out/{}.h5", scene.name);
  ProbeOnRoot(comm, [&] {
    CheckMemory(scene, methods, plan.n_params, etas.size(), reference_row, plan.step_records, out);
    if (!plot_dir.empty() && !PlotDirWritable(plot_dir))
      throw UsageError(fmt::format("--plot: \"{}\" is not a writable folder", EscapeControl(plot_dir)));
    if (report) CheckReportTarget(out);
    if (!series.empty())  // a probe, before computing: not the result file, its XDMF nor its --report page
      CheckWritableFile(series, "--series", {out, std::filesystem::path(out).replace_extension(".xdmf").string(),
                                             report ? ReportPageOf(out) : std::string()});
  });

  BenchRun run{scene, methods, plan, etas, targets, baseline, *metric, repeat, time_budget, hs, reference_row,
               ref_rtol, out, plot_dir, series, frames_mode, JournalKey(argc, argv, scene), work_precision_only,
               quiet, app.count("--preconditioner") > 0,
               app.count("--cg-tolerance") + app.count("--cg-tolerances") > 0, app.count("--tangent-terms") > 0,
               time_limit, max_runs, settings, sweep_to_targets, /*keep_journal=*/false,
               report, /*size_history=*/nullptr, start_predicted};
  run.reference_time_limit = app.count("--time-limit") ? time_limit : RunLimits().time_limit_s;
  return run;
}

}  // namespace clothbench
