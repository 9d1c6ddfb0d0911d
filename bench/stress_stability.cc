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
#include "harness/sweep.h"
#include "model/particle_system.h"
#include "results/result_file.h"
#include "solver/stability_map.h"

namespace clothbench {
namespace {

// One cell of the sweep, in the order of the printed maps.
struct CellSpec {
  std::size_t scene, method;
  double h, stiffness;
};

// What the sweep maps: scenes × rows × h × stiffness, and the cell settings.
struct SweepPlan {
  std::vector<Scene> scenes;
  std::vector<RowMethod> methods;
  std::vector<double> stiff, hs;
  int steps = 200, side = 10;
  std::vector<CellSpec> cells;  ///< in the order of the printed maps
  std::string key;              ///< the journal's key: every argument that changes a cell's result
};

// Every cell's result (summed onto rank 0).
struct CellResults {
  explicit CellResults(std::size_t n) : outcome(n, 0), done(n, 0), upd(n, 0.0), cgs(n, 0.0), excess(n, 0.0) {}
  std::vector<int32_t> outcome, done;
  std::vector<double> upd, cgs, excess;
};

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
    for (Method m : AllMethods()) names.emplace_back(ToString(m));
    names.emplace_back(ToString(Method::kSbdf3));
    names.emplace_back(ToString(Method::kSymplecticEuler));
  } else {
    names = SplitList(integrators_arg, "--integrators");
  }
  std::vector<NonlinearSolver> solvers;
  for (const std::string& n : SplitList(nonlinear_arg, "--nonlinear-solver"))
    solvers.push_back(ParseNonlinearSolver(n, "--nonlinear-solver"));
  p.methods = ExpandMethods(names, solvers, "--integrators", {StepKind::kFixedStep});
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

// The cells not yet in the journal (at most `max_cells`, 0: all), dealt
// round-robin over the ranks, each appended to the journal when done; the
// journalled ones taken from it on rank 0; everything summed onto rank 0.
// @return the results, and in *partial whether --max-cells left cells out
CellResults ComputeCells(const SweepPlan& p, SweepJournal& journal, long max_cells, SweepComm& comm, bool* partial) {
  const std::size_t n = p.cells.size();
  CellResults r(n);
  std::vector<std::size_t> missing;
  for (std::size_t k = 0; k < n; ++k) {
    const auto it = journal.done().find(static_cast<long>(k));
    if (it == journal.done().end()) {
      missing.push_back(k);
    } else if (comm.root()) {  // summed onto rank 0: only rank 0 contributes journalled cells
      r.outcome[k] = it->second.outcome;
      r.done[k] = it->second.steps;
      r.upd[k] = it->second.updates;
      r.cgs[k] = it->second.cg;
      r.excess[k] = it->second.excess;
    }
  }
  // Rank 0's list for every rank: the ranks read the journal after one
  // barrier, and rank 0 may append its first cells before another rank
  // has read it; a rank with a shorter list would deal the cells
  // differently (cells computed twice, others never).
  {
    std::vector<long> list(missing.begin(), missing.end());
    comm.Broadcast(&list);
    missing.assign(list.begin(), list.end());
  }
  const std::size_t to_compute =
      max_cells > 0 ? std::min(missing.size(), static_cast<std::size_t>(max_cells)) : missing.size();
  if (comm.root() && (missing.size() < n || comm.size() > 1 || to_compute < missing.size()))
    fmt::print("{} of {} cells from {}; computing {} on {} rank{}\n", n - missing.size(), n, journal.path(),
               to_compute, comm.size(), comm.size() > 1 ? "s" : "");
  for (std::size_t j = 0; j < to_compute; ++j) {
    if (!comm.Owns(j)) continue;
    ThrowIfInterrupted();  // between cells; the journal keeps the finished ones
    const std::size_t k = missing[j];
    const CellSpec& cs = p.cells[k];
    const RowMethod& m = p.methods[cs.method];
    const StabilityCell c = RunStabilityCell(
        p.scenes[cs.scene], [&m](const ParticleSystem& sys, const SolverSpec& spec) { return m.Make(sys, spec); },
        cs.h, cs.stiffness, p.steps);
    r.outcome[k] = c.outcome;
    r.done[k] = c.steps;
    r.upd[k] = c.updates_per_step;
    r.cgs[k] = c.cg_per_step;
    r.excess[k] = c.energy_excess;
    journal.Append(static_cast<long>(k), {c.outcome, c.steps, c.updates_per_step, c.cg_per_step, c.energy_excess});
  }
  comm.SumToRoot(&r.outcome);
  comm.SumToRoot(&r.done);
  comm.SumToRoot(&r.upd);
  comm.SumToRoot(&r.cgs);
  comm.SumToRoot(&r.excess);
  if (comm.root() && to_compute < missing.size())
    fmt::print("stopped after {} cells (--max-cells): {} of {} done; rerun the same command to continue ({})\n",
               to_compute, n - missing.size() + to_compute, n, journal.path());
  *partial = to_compute < missing.size();
  return r;
}

// Prints the maps and writes the result file `out` (rank 0).
void WriteMaps(const SweepPlan& p, const CellResults& r, const std::string& out, const SweepComm& comm) {
  const std::vector<double>& stiff = p.stiff;
  const std::vector<double>& hs = p.hs;
  const int steps = p.steps, side = p.side;
  const std::vector<int32_t>& outcome = r.outcome;
  const std::vector<int32_t>& done = r.done;
  const std::vector<double>& upd = r.upd;
  const std::vector<double>& cgs = r.cgs;
  const std::vector<double>& excess = r.excess;
  ResultFile f(out);
  WriteProvenance(f);
  f.SetAttribute("/", "mpi_ranks", static_cast<long>(comm.size()));
  f.CreateGroup("/stress");
  f.WriteVector("/stress/stiffness", stiff, "");
  f.WriteVector("/stress/h", hs, "s");
  f.SetAttribute("/stress", "steps", static_cast<long>(steps));
  f.SetAttribute("/stress", "side", static_cast<long>(side));
  f.SetAttribute("/stress", "outcome_codes", std::string(kStabilityOutcomeCodes));
  f.SetAttribute("/stress", "bounded_margin", std::string("E(t) - W_ext(t) <= E(0) + 1e-3 sum(m)|g| diag"));
  const int nh = static_cast<int>(hs.size()), ns = static_cast<int>(stiff.size());
  const std::size_t per_map = hs.size() * stiff.size();
  std::size_t k0 = 0;  // first cell of the current map
  for (const Scene& scene : p.scenes) {
    fmt::print("\n{} ({}×{} particles, {} steps per cell, max_updates 30, cg_tolerance 1e-6, no retries)\n",
               scene.name, side, side, steps);
    fmt::print("cells: ok U/C = bounded, U updates and C CG iterations per step; at step n: GROW@n energy growth, "
               "NaN@n non-finite state, CG@n PCG failed, FP@n fixed point not converged in 30 updates, FPdiv@n fixed "
               "point diverged, NW@n Newton not converged in 30 updates, NWdiv@n Newton diverged, SPD@n a particle "
               "faster than twice the speed bound, PEN@n a particle deeper than delta inside an obstacle "
               "(docs/model.md, \"Blow-up statuses\")\n");
    for (const RowMethod& m : p.methods) {
      fmt::print("\n{:<24} {:>8}", m.label(), "h \\ S");
      for (double s : stiff) fmt::print(" {:>12g}", s);
      fmt::print("\n");
      for (std::size_t i = 0; i < hs.size(); ++i) {
        fmt::print("{:<24} {:>8g}", "", hs[i]);
        for (std::size_t j = 0; j < stiff.size(); ++j) {
          const std::size_t k = k0 + i * stiff.size() + j;
          StabilityCell c;
          c.outcome = outcome[k];
          c.steps = done[k];
          c.updates_per_step = upd[k];
          c.cg_per_step = cgs[k];
          fmt::print(" {:>12}", StabilityCellText(c));
        }
        fmt::print("\n");
      }
      const auto slice = [&](const auto& v) {
        using T = typename std::decay_t<decltype(v)>::value_type;
        return std::vector<T>(v.begin() + static_cast<std::ptrdiff_t>(k0),
                              v.begin() + static_cast<std::ptrdiff_t>(k0 + per_map));
      };
      const std::string g = fmt::format("/stress/{}/{}", scene.name, m.id());
      f.CreateGroup(g);
      f.WriteTable(g + "/outcome", nh, ns, slice(outcome));
      f.WriteTable(g + "/steps_completed", nh, ns, slice(done));
      f.WriteTable(g + "/updates_per_step", nh, ns, slice(upd), "");
      f.WriteTable(g + "/cg_per_step", nh, ns, slice(cgs), "");
      f.WriteTable(g + "/energy_excess", nh, ns, slice(excess), "");
      k0 += per_map;
    }
  }
  f.Commit();
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
                 "default: the five thesis methods and symplectic_euler; also baraff_witkin, and NAME/newton for the "
                 "fully implicit methods");
  app.add_option("--nonlinear-solver", nonlinear_arg,
                 "fixed_point,newton: one map per solver for implicit_euler, bdf2 and implicit_midpoint (default "
                 "fixed_point)");
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
