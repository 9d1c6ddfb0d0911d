// contact_replay: saves the state of a scene's run at given times and takes
// steps from a saved state, printing per step what the filtered PCG and its
// contact-aware preconditioner did (docs/notes/performance.md, "Prefiltered AMG").
// At 10⁶ particles a drape takes minutes to reach its resting state; from a
// saved state a preconditioner setting is compared on that state in seconds.
//
//   contact_replay save   --scene S --at T[,T...] --out PREFIX
//   contact_replay replay --scene S --state FILE --steps K
//   (both end with the run's mean cost of a refactorisation and a row change,
//   or of a setup and a V-cycle: PrintCosts)
//   common options: --integrator sbdf2 --preconditioner amg --amg-frames adaptive
//                   --cycle-factor --axis-normals --frames-only (diagnostics of the prefiltered AMG,
//                   Preconditioner::AmgDiagnostics)
//
// `save` runs the scene from rest with fixed steps of its h and writes
// PREFIX_<k>.state after the step that reaches the k-th time (k from 0).
// `replay` starts from a saved state (positions and velocities at its time)
// and takes K steps of the scene's h. A replay forgets the history: SBDF(2)
// and BDF(2) take their start step again and the contact response its
// contact memory (which particles were in contact, their last impulse), so
// the first steps after the restart differ from the saved run's.
//
// A state file (harness/state_file.h) is written by the one writer
// (model/output_file.h; <out>.lock held from before the run, a temporary
// renamed). A state is read only from a regular file of
// exactly the size the scene's N gives, and only for the scene it was saved
// from. Bad input (a scene, option, time or state file that breaks a rule,
// validated as a RunRequest where it is one) is refused before any
// computing with exit 2 and one line naming it; a failed step or write
// exits 1 naming its cause.
#include <zlib.h>

#include <CLI/CLI.hpp>
#include <fmt/core.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "bench/cli_rules.h"
#include "harness/cli_args.h"
#include "harness/output_lock.h"
#include "harness/run_request.h"
#include "harness/state_file.h"
#include "harness/sweep.h"
#include "model/particle_system.h"
#include "model/scene.h"
#include "solver/integrator.h"

namespace clothbench {
namespace {

// One line per step: what the step and the preconditioner did.
void PrintStep(const StepEngine& engine, const StepStats& st, const ContactFactorStats& before,
               double contact_seconds_before) {
  const ContactFactorStats& now = engine.system_matrix().preconditioner().contact_stats();
  const long setups = now.refactorizations - before.refactorizations;
  fmt::print("{:8.4f} {:8d} {:8d} {:9.4f} {:9.4f} {:7d} {:7d} {:7d} {:7d} {:8d} {:>8} {:9.4f}\n", st.t, st.cg_iterations,
             st.colliding, st.solve_time, st.setup_time, setups, now.modifications - before.modifications,
             now.frame_setups[0] - before.frame_setups[0], now.frame_setups[1] - before.frame_setups[1],
             now.off_axis, setups > 0 && std::isfinite(now.cycle_factor) ? fmt::format("{:.4f}", now.cycle_factor) : "-",
             engine.contact_detection_seconds() - contact_seconds_before);
  std::fflush(stdout);
}

void PrintHeader() {
  fmt::print("# t [s], CG iterations, constrained particles, step [s], setup [s], and the preconditioner's\n"
             "# setups, finest-level updates, setups in nearest-axis and in spread frames during the step,\n"
             "# and, for the prefiltered AMG, the contacts off every axis (by more than acos(kFrameSnap)) and\n"
             "# the V-cycle factor of the step's last setup (--cycle-factor; -: not measured), and the\n"
             "# collision detection's wall time in the step [s] (part of the step's)\n");
}

int Fail(const std::string& line) {
  std::fprintf(stderr, "contact_replay: %s\n", line.c_str());
  return 2;
}

// The command line of both subcommands.
struct Args {
  std::string scene, integrator = std::string(KernelBenchmarkMethod().name), preconditioner, frames, prefix, state;
  std::string at_arg;     ///< --at as given: a comma-separated list
  std::vector<double> at;  ///< --at, parsed (ParsePositiveList: no empty item)
  int steps = 0;
  Preconditioner::AmgDiagnostics diagnostics;
  CLI::App *save = nullptr, *replay = nullptr;
  CLI::App* chosen() const { return save->parsed() ? save : replay; }
};

void AddOptions(CLI::App& app, Args* a) {
  app.require_subcommand(1);
  a->save = app.add_subcommand("save", "run the scene from rest and save its state at --at times");
  a->replay = app.add_subcommand("replay", "take --steps steps from a saved state");
  for (CLI::App* sub : {a->save, a->replay}) {
    sub->add_option("--scene", a->scene, "scene file or built-in scene name")->required();
    sub->add_option("--integrator", a->integrator, "a thesis integrator that solves with the PCG")->capture_default_str();
    sub->add_option("--preconditioner", a->preconditioner, "override the scene's preconditioner");
    sub->add_option("--amg-frames", a->frames, "override the scene's amg_frames (adaptive, nearest_axis, spread)");
    sub->add_flag("--cycle-factor", a->diagnostics.cycle_factor,
                  "measure each prefiltered AMG setup's V-cycle factor (40 cycles on K e = 0)");
    sub->add_flag("--axis-normals", a->diagnostics.axis_normals,
                  "diagnostic: build the prefiltered hierarchy for the contact normals rounded to their nearest "
                  "axis (not the system the PCG solves)");
    sub->add_flag("--frames-only", a->diagnostics.frames_only,
                  "diagnostic: build the prefiltered hierarchy for A_alpha without constraints in the contact frames "
                  "(not the system the PCG solves)");
  }
  a->save->add_option("--at", a->at_arg, "times [s], within (0, t_end], comma-separated")->required();
  a->save->add_option("--out", a->prefix, "output prefix: PREFIX_<k>.state")->required();
  a->replay->add_option("--state", a->state, "a state file written by save")->required();
  a->replay->add_option("--steps", a->steps, "steps to take")->required()->check(CLI::Range(1, 1000000));
}

// The scene and the row, validated as every entry point validates a run
// (harness/run_request.h): a thesis integrator's row (StepEngine) at the
// scene's h. @throws UsageError or SceneError, one line
ResolvedRun ResolveRun(const Args& a) {
  Scene scene = LoadSceneOrBuiltin(a.scene);
  if (a.chosen()->count("--amg-frames")) scene.solver.amg_frames = ParseAmgFrames(a.frames, "--amg-frames");
  std::vector<RowMethod> rows;
  try {
    rows = ExpandMethods({a.integrator}, {scene.solver.nonlinear_solver}, "--integrator");
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  // The step engine's rows that solve with the PCG (the registry's solver/ layer).
  const auto replays = [](const MethodEntry& e) { return e.layer == "solver" && e.pcg; };
  if (rows.size() != 1 || !replays(*rows.front().entry) || !SpecOf(rows.front().kind()).plain())
    throw UsageError(fmt::format("--integrator {}: not one of {} (with /newton or /fixed_point where they take one)",
                                 EscapeControl(a.integrator), MethodNames(replays)));
  RunRequest q;
  q.scene = scene;
  q.method = a.integrator;
  q.h = scene.h;
  if (a.chosen()->count("--preconditioner")) q.preconditioner = a.preconditioner;
  q.names = FieldNames::kOption;
  q.renamed = {{"method", "--integrator"}, {"h", "--scene's h"}};
  return q.Resolve();
}

// One step to t_next, printed. @return false (after one line on stderr) if it failed
bool StepTo(StepEngine& engine, double h, double t_next) {
  const ContactFactorStats before = engine.system_matrix().preconditioner().contact_stats();
  const double contact_before = engine.contact_detection_seconds();
  const StepStats st = engine.Step(h);
  if (st.status != StepStatus::kOk) {
    std::fprintf(stderr, "contact_replay: the step to t = %.4f s failed (%s)\n", t_next,
                 std::string(ToString(st.status)).c_str());
    return false;
  }
  engine.SetTime(t_next);
  PrintStep(engine, st, before, contact_before);
  return true;
}

// `save`'s outputs, locked before the run (the locks held to the exit).
struct SaveOutputs {
  std::vector<std::string> paths;
  std::vector<std::unique_ptr<OutputLock>> locks;
};

// Checks the --at times and locks each output. @throws UsageError
SaveOutputs PrepareSave(const Args& a, const Scene& scene) {
  SaveOutputs out;
  for (std::size_t k = 0; k < a.at.size(); ++k) {
    if (!(a.at[k] > 0.0 && a.at[k] <= scene.t_end) || (k > 0 && a.at[k] <= a.at[k - 1]))
      throw UsageError(fmt::format("--at {}: times must increase within (0, t_end = {}]", a.at[k], scene.t_end));
    out.paths.push_back(fmt::format("{}_{}.state", a.prefix, k));
    out.locks.push_back(std::make_unique<OutputLock>(out.paths.back(), /*journal_folder=*/false, "--out"));
  }
  return out;
}

// Reads the saved state and checks that --steps end by t_end. @throws UsageError
State PrepareReplay(const Args& a, const ParticleSystem& system) {
  const Scene& scene = system.scene();
  std::string why;
  const std::optional<State> start = ReadState(a.state, scene, system.num_particles(), &why);
  if (!start) throw UsageError(fmt::format("--state {}: {}", EscapeControl(a.state), why));
  if (start->t + a.steps * scene.h > scene.t_end * (1.0 + 1e-12))
    throw UsageError(fmt::format("--steps {}: from t = {} s with h = {} s they end past t_end = {} s", a.steps,
                                 start->t, scene.h, scene.t_end));
  return *start;
}

// What the contact-aware preconditioner's choices cost over the run: the
// measured break-even of kModifyRowsPerSqrtN and kSetupVCycles
// (docs/notes/performance.md, "Contact factors", "Prefiltered AMG").
void PrintCosts(const StepEngine& engine, int num_particles) {
  const ContactFactorStats& c = engine.system_matrix().preconditioner().contact_stats();
  const double root_n = std::sqrt(static_cast<double>(num_particles));
  if (c.v_cycles > 0 && c.refactorizations > 0) {
    const double setup = c.refactor_seconds / static_cast<double>(c.refactorizations);
    const double cycle = c.v_cycle_seconds / static_cast<double>(c.v_cycles);
    fmt::print("# prefiltered AMG: {} setups, mean {:.4g} s; {} V-cycles, mean {:.4g} s: a setup costs {:.1f} V-cycles "
               "(kSetupVCycles = {})\n",
               c.refactorizations, setup, c.v_cycles, cycle, setup / cycle, Preconditioner::kSetupVCycles);
  } else if (c.refactorizations > 0 && c.modifications > 0) {
    const double refactor = c.refactor_seconds / static_cast<double>(c.refactorizations);
    const double row = c.modify_seconds / static_cast<double>(c.modifications);
    fmt::print("# contact factors: {} refactorisations, mean {:.4g} s; {} row changes, mean {:.4g} s: break-even {:.0f} "
               "rows = {:.2f} sqrt(N) (kModifyRowsPerSqrtN = {})\n",
               c.refactorizations, refactor, c.modifications, row, refactor / row, refactor / row / root_n,
               Preconditioner::kModifyRowsPerSqrtN);
  }
}

// `save`: the run from rest, a state written after the step that reaches
// each time. @return the exit code
int Save(const Args& a, const ParticleSystem& system, const SaveOutputs& outputs, StepEngine& engine) {
  const Scene& scene = system.scene();
  const double h = scene.h;
  PrintHeader();
  engine.Reset(0.0, system.rest_positions(), MatrixN3::Zero(system.num_particles(), 3));
  std::size_t next = 0;
  for (long k = 1; next < a.at.size(); ++k) {
    const double t_next = static_cast<double>(k) * h;
    if (!StepTo(engine, h, t_next)) return 1;
    if (t_next < a.at[next] - 1e-9 * h) continue;
    try {
      WriteFileAtomically(outputs.paths[next], EncodeState(scene, State{engine.t(), engine.x(), engine.v()}), "--out");
    } catch (const std::exception& e) {
      std::fprintf(stderr, "contact_replay: %s\n", EscapeControl(e.what()).c_str());
      return 1;
    }
    fmt::print("# saved t = {:.4f} s to {}\n", engine.t(), outputs.paths[next]);
    ++next;
  }
  PrintCosts(engine, system.num_particles());
  return 0;
}

// `replay`: --steps steps from the saved state. @return the exit code
int Replay(const Args& a, const ParticleSystem& system, const State& start, StepEngine& engine) {
  const double h = system.scene().h;
  PrintHeader();
  engine.Reset(start.t, start.x, start.v);
  for (int k = 1; k <= a.steps; ++k)
    if (!StepTo(engine, h, start.t + k * h)) return 1;
  PrintCosts(engine, system.num_particles());
  return 0;
}

}  // namespace
}  // namespace clothbench

int main(int argc, char** argv) {
  using namespace clothbench;
  CLI::App app{"contact_replay: save a scene's state at given times, take steps from a saved state"};
  Args a;
  AddOptions(app, &a);
  try {
    app.parse(argc, argv);
    RefuseEmptyValues(app);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    return Fail(e.what());
  }
  ResolvedRun run;
  try {
    if (a.save->parsed()) a.at = ParsePositiveList(a.at_arg, "--at");
    run = ResolveRun(a);
  } catch (const SceneError& e) {
    return Fail(e.what());
  } catch (const std::invalid_argument& e) {  // UsageError
    return Fail(e.what());
  }
  const ParticleSystem system(run.scene);
  // Everything that can be refused is, before the engine is built.
  SaveOutputs outputs;
  State start;
  try {
    if (a.save->parsed()) outputs = PrepareSave(a, system.scene());
    else start = PrepareReplay(a, system);
  } catch (const UsageError& e) {
    return Fail(e.what());
  }
  StepEngine engine(system, *MethodFromString(run.row.name()), run.row.Settings(run.spec));
  engine.set_amg_diagnostics(a.diagnostics);
  return a.save->parsed() ? Save(a, system, outputs, engine) : Replay(a, system, start, engine);
}
