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
//   stress_stability [--scenes LIST] [--integrators LIST] [--nonlinear-solver LIST]
//                    [--stiffness LIST] [--h LIST] [--steps N] [--side N] [--out FILE.h5]
#include <cmath>
#include <cstdint>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "bench/methods.h"
#include "bench/plot.h"
#include "bench/signals.h"
#include "model/particle_system.h"
#include "results/result_file.h"
#include "solver/stability_map.h"

namespace clothbench {
namespace {

std::vector<std::string> Split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(item);
  return out;
}

std::vector<double> ParseList(const std::string& s, const std::string& opt) {
  std::vector<double> out;
  for (const std::string& item : Split(s)) {
    std::size_t pos = 0;
    double v = 0.0;
    try {
      v = std::stod(item, &pos);
    } catch (...) {
      pos = 0;
    }
    if (pos != item.size() || !(v > 0.0) || !std::isfinite(v))
      throw std::invalid_argument(fmt::format("{}: \"{}\" is not a positive number", opt, item));
    out.push_back(v);
  }
  return out;
}

int Main(int argc, char** argv) {
  CLI::App app{"clothbench stability maps over numerical stiffness and step size"};
  std::string scenes_arg = "hanging_sheet,swinging_sheet", integrators_arg, stiffness_arg = "0.1,1,1e2,1e4,1e6,1e8",
              h_arg = "1e-4,1e-3,1e-2,1e-1", out = "results/stress_stability.h5", nonlinear_arg = "fixed_point",
              plot_dir;
  int steps = 200, side = 10;
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
  app.add_option("--out", out, "result file");
  app.add_option("--plot", plot_dir, "after writing the results, draw the maps into DIR with scripts/plot (PNG, SVG)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    fmt::print(stderr, "stress_stability: {}\n", e.what());
    return 2;
  }
  InstallInterruptHandlers();
  try {
    std::vector<std::string> names;
    if (integrators_arg.empty()) {
      for (Method m : AllMethods()) names.emplace_back(ToString(m));
      names.emplace_back(ToString(Method::kSymplecticEuler));
    } else {
      names = Split(integrators_arg);
    }
    std::vector<NonlinearSolver> solvers;
    for (const std::string& n : Split(nonlinear_arg)) solvers.push_back(ParseNonlinearSolver(n, "--nonlinear-solver"));
    const std::vector<RowMethod> methods = ExpandMethods(names, solvers, "--integrators", {StepKind::kFixedStep});
    const std::vector<double> stiff = ParseList(stiffness_arg, "--stiffness"), hs = ParseList(h_arg, "--h");
    std::vector<Scene> scenes;
    for (const std::string& name : Split(scenes_arg)) {
      scenes.push_back(StabilityScene(LoadSceneOrBuiltin(name), side));
    }

    if (!plot_dir.empty()) CheckPlotDir(plot_dir);
    ResultFile f(out);
    WriteProvenance(f);
    f.CreateGroup("/stress");
    f.WriteVector("/stress/stiffness", stiff, "");
    f.WriteVector("/stress/h", hs, "s");
    f.SetAttribute("/stress", "steps", static_cast<long>(steps));
    f.SetAttribute("/stress", "side", static_cast<long>(side));
    f.SetAttribute("/stress", "outcome_codes", std::string(kStabilityOutcomeCodes));
    f.SetAttribute("/stress", "bounded_margin", std::string("E(t) - W_ext(t) <= E(0) + 1e-3 sum(m)|g| diag"));
    const int nh = static_cast<int>(hs.size()), ns = static_cast<int>(stiff.size());
    for (const Scene& scene : scenes) {
      fmt::print("\n{} ({}×{} particles, {} steps per cell, max_updates 30, cg_tolerance 1e-6, no retries)\n",
                 scene.name, side, side, steps);
      fmt::print("cells: ok U/C = bounded, U updates and C CG iterations per step; at step n: GROW@n energy growth, "
                 "NaN@n non-finite state, CG@n PCG failed, FP@n fixed point not converged in 30 updates, FPdiv@n fixed "
                 "point diverged, NW@n Newton not converged in 30 updates, NWdiv@n Newton diverged\n");
      for (const RowMethod& m : methods) {
        std::vector<int32_t> outcome, done;
        std::vector<double> upd, cgs, excess;
        fmt::print("\n{:<24} {:>8}", m.label(), "h \\ S");
        for (double s : stiff) fmt::print(" {:>12g}", s);
        fmt::print("\n");
        for (double h : hs) {
          fmt::print("{:<24} {:>8g}", "", h);
          for (double s : stiff) {
            ThrowIfInterrupted();  // between cells; unwinding removes the .tmp
            const StabilityCell c = RunStabilityCell(
                scene, [&m](const ParticleSystem& sys, const SolverSpec& spec) { return m.Make(sys, spec); }, h, s,
                steps);
            outcome.push_back(c.outcome);
            done.push_back(c.steps);
            upd.push_back(c.updates_per_step);
            cgs.push_back(c.cg_per_step);
            excess.push_back(c.energy_excess);
            fmt::print(" {:>12}", StabilityCellText(c));
          }
          fmt::print("\n");
        }
        const std::string g = fmt::format("/stress/{}/{}", scene.name, m.id());
        f.CreateGroup(g);
        f.WriteTable(g + "/outcome", nh, ns, outcome);
        f.WriteTable(g + "/steps_completed", nh, ns, done);
        f.WriteTable(g + "/updates_per_step", nh, ns, upd, "");
        f.WriteTable(g + "/cg_per_step", nh, ns, cgs, "");
        f.WriteTable(g + "/energy_excess", nh, ns, excess, "");
      }
    }
    f.Commit();
    fmt::print("\nmachine: {}, {} hardware threads, {}, commit {}\nresults: {}\n", HostName(),
               std::thread::hardware_concurrency(), CompilerId(), GitCommit(), out);
    if (!plot_dir.empty()) Plot("stress_stability", out, plot_dir);
    return 0;
  } catch (const SceneError& e) {
    fmt::print(stderr, "stress_stability: {}\n", e.what());
    return 2;
  } catch (const std::invalid_argument& e) {
    fmt::print(stderr, "stress_stability: {}\n", e.what());
    return 2;
  } catch (const Interrupted& e) {
    fmt::print(stderr, "stress_stability: interrupted by {}; no result file written\n", SignalName(e.signal));
    return 128 + e.signal;
  } catch (const std::exception& e) {
    fmt::print(stderr, "stress_stability: {}\n", e.what());
    return 1;
  }
}

}  // namespace
}  // namespace clothbench

int main(int argc, char** argv) { return clothbench::Main(argc, argv); }
