// stress_stability: stability maps over numerical stiffness h²k/(ρl²) and
// step size h (thesis §3.4.4).
//
// For every scene, integrator, h and stiffness S the tension modulus is set
// to k = S ρ l²/h² and the sheet (side×side particles, the scene's spacing)
// is integrated from rest for `steps` steps of size h. A cell records:
//   bounded    E(t) − W_ext(t) ≤ E(0) + 1e-3 E_ref at every step, where
//              E_ref = Σ m |g| L (L = sheet diagonal) is the energy gravity can
//              release; a violation is "energy_growth" (a blow-up);
//   failure    the first failed step and why: non_finite, cg_failed,
//              no_fixed_point_convergence (no retries: the map shows where a
//              method stops working at that h);
//   work       fixed-point (or Newton) updates and CG iterations per step.
//
// Cells are independent: under mpirun (or srun) they are dealt round-robin
// over the ranks and rank 0 prints and writes the same file as a serial run;
// every finished cell is appended to <out>.journal, so that an interrupted
// sweep rerun with the same arguments computes only the missing cells
// (harness/sweep.h).
//
//   [mpirun -n K] stress_stability [--scenes LIST] [--integrators LIST] [--nonlinear-solver LIST]
//                    [--stiffness LIST] [--h LIST] [--steps N] [--side N] [--out FILE.h5]
//                    [--max-cells N] [--plot DIR]

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "harness/cli_args.h"
#include "harness/methods.h"
#include "harness/output_lock.h"
#include "harness/plot.h"
#include "harness/run_request.h"
#include "bench/cli_rules.h"
#include "bench/signals.h"
#include "harness/stability_sweep.h"
#include "harness/sweep.h"
#include "model/particle_system.h"
#include "results/result_file.h"
#include "solver/stability_map.h"

namespace clothbench {
namespace {

// Validates the arguments (every rank the same) and lays out the cells.
// @throws UsageError, SceneError or std::invalid_argument, one line
SweepPlan PlanSweep(const CLI::App& app, const std::string& scenes_arg, const std::string& integrators_arg,
                    const std::string& nonlinear_arg, const std::string& stiffness_arg, const std::string& h_arg,
                    int steps, int side) {
  SweepPlan p;
  p.steps = steps;
  p.side = side;
  std::vector<std::string> names;
  if (app.count("--integrators") && integrators_arg.empty())
    throw UsageError("--integrators: empty list \"\" (name rows, or leave the option out for the default rows)");
  if (integrators_arg.empty()) {
    // The thesis' integrators (the registry's solver/ layer), in registry order.
    for (const MethodEntry& e : Registry())
      if (e.layer == "solver") names.emplace_back(e.name);
  } else {
    names = SplitList(integrators_arg, "--integrators");
  }
  std::vector<NonlinearSolver> solvers;
  for (const std::string& n : SplitList(nonlinear_arg, "--nonlinear-solver"))
    solvers.push_back(ParseNonlinearSolver(n, "--nonlinear-solver"));
  p.methods = ExpandMethods(names, solvers, "--integrators", [](const StepKindSpec& k) { return k.plain(); });
  for (std::size_t a = 0; a < p.methods.size(); ++a)
    for (std::size_t b = 0; b < a; ++b)
      if (p.methods[a].label() == p.methods[b].label())
        throw std::invalid_argument(fmt::format("--integrators: {} is listed twice", p.methods[a].label()));
  p.stiff = ParsePositiveList(stiffness_arg, "--stiffness");
  p.hs = ParsePositiveList(h_arg, "--h");
  for (const std::string& name : SplitList(scenes_arg, "--scenes")) {
    p.scenes.push_back(StabilityScene(LoadSceneOrBuiltin(name), side));
    for (std::size_t b = 0; b + 1 < p.scenes.size(); ++b)
      if (p.scenes[b].name == p.scenes.back().name)
        throw std::invalid_argument(fmt::format("--scenes: scene \"{}\" is listed twice", p.scenes.back().name));
  }
  // Each (scene, row, h) as a run of `steps` steps, by the rules every
  // entry point shares (harness/run_request.h).
  for (const Scene& sc : p.scenes)
    for (const RowMethod& m : p.methods)
      for (double h : p.hs) {
        RunRequest q;
        q.scene = sc;
        q.method = m.label();
        q.h = h;
        q.t_end = steps * h;
        q.names = FieldNames::kOption;
        q.renamed = {{"t_end", "--steps x --h"}};
        q.Validate();
      }
  for (std::size_t sc = 0; sc < p.scenes.size(); ++sc)
    for (std::size_t m = 0; m < p.methods.size(); ++m)
      for (double h : p.hs)
        for (double st : p.stiff) p.cells.push_back({sc, m, h, st});
  p.key = fmt::format("steps={} side={} stiffness=", steps, side);
  for (double st : p.stiff) p.key += fmt::format("{:a},", st);
  p.key += " h=";
  for (double h : p.hs) p.key += fmt::format("{:a},", h);
  p.key += " integrators=";
  for (const RowMethod& m : p.methods) p.key += m.label() + ",";
  p.key += " scenes=";
  for (const Scene& sc : p.scenes) p.key += fmt::format("{}:{},", sc.name, Fnv1a64(sc.toml));
  return p;
}

int Main(int argc, char** argv) {
  SweepComm comm(&argc, &argv);
  CLI::App app{"clothbench stability maps over numerical stiffness and step size"};
  std::string scenes_arg = "hanging_sheet,swinging_sheet", integrators_arg, stiffness_arg = "0.1,1,1e2,1e4,1e6,1e8",
              h_arg = "1e-4,1e-3,1e-2,1e-1", out = "out/stress_stability.h5", nonlinear_arg = "fixed_point",
              plot_dir;
  int steps = 200, side = 10;
  long max_cells = 0;
  app.add_option("--scenes", scenes_arg, "built-in scene names or files (default hanging_sheet,swinging_sheet)");
  app.add_option("--integrators", integrators_arg,
                 fmt::format("default: the thesis' methods ({}); also any other fixed-step row, and NAME/newton for "
                             "the fully implicit methods",
                             MethodNames([](const MethodEntry& e) { return e.layer == "solver"; })));
  app.add_option("--nonlinear-solver", nonlinear_arg,
                 fmt::format("fixed_point,newton: one map per solver for {} (default fixed_point)",
                             MethodNames([](const MethodEntry& e) { return e.nonlinear_solver; })));
  app.add_option("--stiffness", stiffness_arg, "numerical stiffness values h^2 k/(rho l^2)");
  app.add_option("--h", h_arg, "step sizes [s]");
  app.add_option("--steps", steps, "steps per cell (default 200)")->check(CLI::Range(1, 1000000));
  app.add_option("--side", side, "particles per side (default 10; spacing from the scene)")->check(CLI::Range(3, 200));
  app.add_option("--out", out, "result file; finished cells are journalled in <out>.journal until it is complete");
  app.add_option("--max-cells", max_cells,
                 "compute at most N cells not yet in the journal, then stop with exit status 75 and keep the journal "
                 "(a sweep in slices, e.g. under a batch time limit); rerun the same command to continue")
      ->check(CLI::Range(1L, 1000000000L));
  app.add_option("--plot", plot_dir, "after writing the results, draw the maps into DIR with scripts/plot (PNG, SVG)");
  try {
    app.parse(argc, argv);
    RefuseEmptyValues(app);
  } catch (const CLI::CallForHelp& e) {
    return comm.root() ? app.exit(e) : 0;
  } catch (const CLI::ParseError& e) {
    if (comm.root()) fmt::print(stderr, "stress_stability: {}\n", EscapeControl(e.what()));
    return 2;
  }
  InstallInterruptHandlers();
  // Every rank validates the same arguments and reaches the same verdict;
  // rank 0 alone prints.
  const auto refuse = [&comm](const std::string& what) {
    if (comm.root()) fmt::print(stderr, "stress_stability: {}\n", EscapeControl(what));
    return 2;
  };
  std::optional<OutputLock> lock;
  try {
    const SweepPlan plan = PlanSweep(app, scenes_arg, integrators_arg, nonlinear_arg, stiffness_arg, h_arg, steps, side);
    if (!plot_dir.empty()) CheckPlotDir(plot_dir);
    lock.emplace(out, comm, false);  // <out>.lock, held to the exit; the journal is a file
    SweepJournal journal(out + ".journal", plan.key, plan.cells.size(), comm);
    if (comm.root() && journal.rejected() > 0)
      fmt::print(stderr, "stress_stability: {}: {} cell line{} failed the check (checksum or range); computing {} again\n",
                 journal.path(), journal.rejected(), journal.rejected() > 1 ? "s" : "", journal.rejected() > 1 ? "them" : "it");
    bool partial = false;
    const CellResults results = ComputeCells(plan, journal, max_cells, comm, &partial);
    if (!comm.root()) return comm.RootStatus(0);
    if (partial) return comm.RootStatus(kExitPartial);
    WriteMaps(plan, results, out, comm);
    journal.Remove();
    fmt::print("\nmachine: {}, {} hardware threads, {} MPI rank{}, {}, commit {}\nresults: {}\n", HostName(),
               std::thread::hardware_concurrency(), comm.size(), comm.size() > 1 ? "s" : "", CompilerId(), GitCommit(),
               out);
    if (!plot_dir.empty()) Plot("stress_stability", out, plot_dir);
    return comm.RootStatus(0);
  } catch (const SceneError& e) {
    return refuse(e.what());
  } catch (const std::invalid_argument& e) {
    return refuse(e.what());
  } catch (const SweepJournal::Mismatch& e) {
    return refuse(e.what());
  } catch (const Interrupted& e) {
    // A journal without a finished cell is removed; one with cells is kept
    // for the same command to resume from.
    const bool journal = comm.root() && SweepJournal::KeepIfFinishedWork(out + ".journal");
    if (lock) lock->Release();
    if (comm.root())
      fmt::print(stderr, "stress_stability: interrupted by {}; no result file written{}\n", SignalName(e.signal),
                 journal ? fmt::format(", finished cells kept in {}.journal: the same command resumes from them",
                                       EscapeControl(out))
                         : "");
    comm.Abort(128 + e.signal);
  } catch (const std::exception& e) {
    // The result file's temporary is gone (ResultFile); the journal keeps
    // the finished cells, so that the same command, once the cause is
    // removed (a full disk), writes the file without computing them again.
    const bool journal = comm.root() && SweepJournal::KeepIfFinishedWork(out + ".journal");
    if (lock) lock->Release();
    fmt::print(stderr, "stress_stability: {}{}{}\n", comm.mpi() ? fmt::format("rank {}: ", comm.rank()) : "",
               EscapeControl(e.what()),
               journal ? fmt::format("; finished cells kept in {}.journal: the same command resumes from them",
                                     EscapeControl(out))
                       : "");
    comm.Abort(1);
  }
}

}  // namespace
}  // namespace clothbench

int main(int argc, char** argv) { return clothbench::Main(argc, argv); }
