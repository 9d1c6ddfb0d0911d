// bench_integrators: integrates a cloth scene with the thesis' integrators at
// several step sizes and with SUNDIALS CVODE, prints one table (steps,
// updates, CG iterations, solver time, e_rms at t_end, observed order) and
// stores everything in HDF5 (docs/model.md §9).
//
//   bench_integrators [--scene FILE.toml] [--integrators LIST] [--h LIST] [--t-end T]
//                     [--reference cvode|cvode/klu|ida|ida/klu|none] [--out FILE.h5] [--rtols LIST] [--substeps LIST]
//                     [--cg-tolerance ETA] [--work-precision] ... (--help lists every option)

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "bench/cli_rules.h"
#include "bench/signals.h"
#include "harness/bench_options.h"
#include "harness/bench_sweep.h"
#include "harness/cli_args.h"
#include "harness/memory_check.h"
#include "harness/methods.h"
#include "harness/output_lock.h"
#include "harness/plan.h"
#include "harness/plot.h"
#include "harness/run_request.h"
#include "harness/sweep.h"
#include "harness/thesis_tables.h"
#include "harness/virtual_tables.h"
#include "model/particle_system.h"
#include "solver/run.h"

namespace clothbench {
namespace {

// --sizes: one target sweep per size, then the verdict; every size planned
// (and refused) before the first computes. `lock` holds the verdict's
// output lock to the exit. @throws UsageError
int RunSizesCommand(const CLI::App& app, Options& o, const std::vector<NonlinearSolver>& solvers,
                    const std::vector<double>& etas, SweepComm& comm, int argc, char** argv,
                    std::optional<OutputLock>* lock) {
  std::vector<long> sizes;
  for (double n : ParsePositiveList(o.sizes_arg, "--sizes")) {
    if (n != std::floor(n) || n < 4 || n > kMaxParticles)
      throw UsageError(fmt::format("--sizes: {:g} must be a whole number of particles from 4 to {:g}", n,
                                   kMaxParticles));
    if (!sizes.empty() && n <= static_cast<double>(sizes.back()))
      throw UsageError(fmt::format("--sizes: {:g} must be larger than the size before it ({})", n, sizes.back()));
    sizes.push_back(static_cast<long>(n));
  }
  for (const char* option : {"--series", "--max-runs"})
    if (app.count(option)) throw UsageError(fmt::format("{}: cannot be combined with --sizes", option));
  // Each size is a sweep to the targets: the options it refuses, named as --sizes'.
  for (const char* option : {"--h", "--rtols", "--substeps", "--iterations"})
    if (app.count(option))
      throw UsageError(fmt::format("{}: --sizes sweeps each size to the targets and chooses the runs itself", option));
  if (o.reference == "none") throw UsageError("--reference none: --sizes needs the reference's errors at each size");
  o.sweep_to_targets = true;
  const std::string verdict_out =
      o.out.empty() ? fmt::format("out/{}_sizes.h5", SceneOfOptions(app, o).name) : o.out;
  if (std::filesystem::path(verdict_out).extension() != ".h5")
    throw UsageError(fmt::format("--out: \"{}\" must end in .h5 with --sizes (the sizes' files are named after "
                                 "it)", EscapeControl(verdict_out)));
  std::vector<BenchRun> runs;
  std::set<int> seen;
  const auto history = std::make_shared<SizeHistory>();
  for (long n : sizes) {
    Options size_options = o;
    Scene refined = SceneOfOptions(app, o, n);
    if (!seen.insert(refined.num_particles()).second)
      throw UsageError(fmt::format("--sizes: {} gives the same {}×{} grid as a size before it", n,
                                   refined.grid.nu, refined.grid.nv));
    size_options.out = std::filesystem::path(verdict_out)
                           .replace_extension(fmt::format("n{}.h5", refined.num_particles()))
                           .string();
    size_options.plot_dir.clear();  // the verdict's plot; scripts/plot draws a size's file
    runs.push_back(PlanBench(app, size_options, solvers, etas, comm, argc, argv, n));
    runs.back().keep_journal = true;
    runs.back().size_history = history;
  }
  ProbeOnRoot(comm, [&] {
    if (!o.plot_dir.empty() && !PlotDirWritable(o.plot_dir))
      throw UsageError(fmt::format("--plot: \"{}\" is not a writable folder", EscapeControl(o.plot_dir)));
    if (o.report) CheckReportTarget(verdict_out);
  });
  lock->emplace(verdict_out, comm);
  std::vector<std::unique_ptr<OutputLock>> size_locks;
  for (const BenchRun& r : runs) size_locks.push_back(std::make_unique<OutputLock>(r.out, comm));
  SetWatchdogNote(fmt::format("the finished runs stay in the sizes' journals ({}.journal, …): the same command "
                              "resumes from them", EscapeControl(runs.front().out)));
  return comm.RootStatus(RunSizes(runs, sizes, verdict_out, o.plot_dir, comm, o.report));
}

int Main(int argc, char** argv) {
  const std::vector<std::string> command(argv, argv + argc);  // before MPI_Init may edit argv
  SweepComm comm(&argc, &argv);
  CLI::App app{"clothbench: integrators of implicit cloth simulation against a SUNDIALS CVODE reference"};
  Options o;
  AddOptions(app, o);
  [[maybe_unused]] auto& [scene_path, integrators_arg, h_arg, reference, out, rtols_arg, t_end, ref_rtol, cg_tolerance,
                          time_limit, time_budget, repeat, series, table, preconditioner, frames_mode, nonlinear_arg,
                          plot_dir, tangent_terms, baseline, error_metric, method_settings, targets_arg, cg_tolerances_arg,
                          substeps_arg, iterations_arg, work_precision_only, quiet, max_runs, sweep_to_targets, sizes_arg, self_contact_arg, report, start_predicted] = o;
  try {
    app.parse(argc, argv);
    RefuseEmptyValues(app);
  } catch (const CLI::CallForHelp& e) {
    return comm.root() ? app.exit(e) : 0;
  } catch (const CLI::ParseError& e) {
    if (comm.root()) fmt::print(stderr, "bench_integrators: {}\n", EscapeControl(e.what()));
    return 2;
  }
  InstallInterruptHandlers();
  StartInterruptWatchdog("bench_integrators");
  // A run inside one library call past its --time-limit: a serial process
  // restarts the command; an MPI rank cannot, and exits 75.
  WatchOverruns(comm.mpi() ? std::vector<std::string>{} : command);
  // Every rank refuses the same input; rank 0 says so.
  const auto refuse = [&comm](const std::string& what) {
    if (comm.root()) fmt::print(stderr, "bench_integrators: {}\n", EscapeControl(what));
    return 2;
  };

  std::optional<OutputLock> lock;  // on <out>.lock, from before the first computation to the exit
  try {
    std::vector<NonlinearSolver> solvers;
    try {
      if (app.count("--nonlinear-solver"))
        for (const std::string& n : SplitList(nonlinear_arg, "--nonlinear-solver")) solvers.push_back(ParseNonlinearSolver(n, "--nonlinear-solver"));
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
    std::vector<double> etas;
    if (app.count("--cg-tolerances")) {
      etas = ParsePositiveList(cg_tolerances_arg, "--cg-tolerances");
      for (double e : etas)
        if (!(e < 1.0)) throw UsageError(fmt::format("--cg-tolerances: {:g} must be in (0, 1)", e));
    }
    if (!table.empty()) {
      // --table runs the thesis' own rows: options that choose rows or runs would be ignored.
      std::string ignored;
      for (const CLI::Option* option : app.get_options())
        if (option->count() > 0 && !std::set<std::string>{"--table", "--out", "--preconditioner", "--nonlinear-solver",
                                                     "--cg-tolerances", "--quiet"}.count(option->get_name()))
          ignored += (ignored.empty() ? "" : ", ") + option->get_name();
      if (!ignored.empty()) throw UsageError(fmt::format("--table: cannot be combined with {}", ignored));
      if (table == "5.1" || table == "5.15") {
        // Chapter 5 (virtual particles): serial runs of the thesis' scenes.
        if (app.count("--preconditioner") || app.count("--nonlinear-solver") || app.count("--cg-tolerances"))
          throw UsageError(fmt::format("--table {}: runs the scenes as they are (no --preconditioner, "
                                       "--nonlinear-solver or --cg-tolerances)", table));
        if (out.empty()) out = table == "5.1" ? "out/table_5_1.h5" : "out/fig_5_15.h5";
        lock.emplace(out, comm);
        ProbeOnRoot(comm, [&out] { CheckOutputPaths(out); });
        if (!comm.root()) return 0;
        return table == "5.1" ? RunTable51(out) : RunFig515(out);
      }
      if (out.empty()) out = fmt::format("out/table_{}.h5", table == "3.1" ? "3_1" : "3_2");
      if (table == "3.1" || table == "3.2") lock.emplace(out, comm);
      return comm.RootStatus(RunThesisTable(table, out,
                            app.count("--preconditioner") ? std::optional(ParsePreconditioner(preconditioner, "--preconditioner"))
                                                          : std::nullopt,
                            solvers, etas, comm));
    }
    if (app.count("--sizes")) return RunSizesCommand(app, o, solvers, etas, comm, argc, argv, &lock);
    const BenchRun run = PlanBench(app, o, solvers, etas, comm, argc, argv);
    lock.emplace(run.out, comm);
    SetWatchdogNote(fmt::format("the finished runs stay in {}.journal: the same command resumes from them",
                                EscapeControl(run.out)));
    return comm.RootStatus(RunBench(run, comm));
  } catch (const UsageError& e) {
    return refuse(e.what());
  } catch (const SceneError& e) {
    return refuse(e.what());
  } catch (const SweepJournal::Mismatch& e) {
    return refuse(e.what());
  } catch (const Interrupted& e) {
    InterruptHandled();
    const bool journal = comm.root() && RecordJournal::KeepIfFinishedWork(out + ".journal");
    if (lock) lock->Release();
    if (comm.root())
      fmt::print(stderr, "bench_integrators: interrupted by {}; no result file written{}\n", SignalName(e.signal),
                 journal ? ", finished runs kept in " + EscapeControl(out) + ".journal: the same command resumes from them"
                         : "");
    comm.Abort(128 + e.signal);
  } catch (const std::bad_alloc&) {
    if (lock) lock->Release();
    fmt::print(stderr, "bench_integrators: out of memory although the run fitted the memory estimate; no result file "
                       "written (use --frames ends|none or fewer rows)\n");
    comm.Abort(1);
  } catch (const std::exception& e) {
    const bool journal = comm.root() && RecordJournal::KeepIfFinishedWork(out + ".journal");
    if (lock) lock->Release();
    fmt::print(stderr, "bench_integrators: {}{}{}\n", comm.mpi() ? fmt::format("rank {}: ", comm.rank()) : "",
               EscapeControl(e.what()),
               journal ? "; finished runs kept in " + EscapeControl(out) + ".journal: the same command resumes from them"
                       : "");
    comm.Abort(1);
  }
}

}  // namespace
}  // namespace clothbench

int main(int argc, char** argv) { return clothbench::Main(argc, argv); }
