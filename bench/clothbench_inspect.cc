// clothbench_inspect: reads a bench_integrators result file (schema
// clothbench/2, docs/guide/results-schema.md) and prints what is in it.
//
//   clothbench_inspect FILE.h5 summary              scene, machine, commit, runs
//   clothbench_inspect FILE.h5 table                the table bench_integrators printed
//   clothbench_inspect FILE.h5 runs [--json]        one line (or JSON object) per run
//   clothbench_inspect FILE.h5 work-precision [--error-metric final|l2|max]
//   clothbench_inspect FILE.h5 verdict              the size × target verdict of a --sizes file
//   clothbench_inspect A.h5 diff B.h5 [--rtol R] [--time-tolerance T]
//   clothbench_inspect FILE.h5 export RUN --frame K (--obj OUT | --ply OUT)
//   clothbench_inspect FILE.h5 rerun RUN [--out F]     recompute RUN in-process, compare bit for bit
//   clothbench_inspect FILE.h5 command RUN [--dir D] [--bench PATH]   shell script recomputing RUN
//
// Exit codes: 0; 1 for `diff` when a change is flagged and for `rerun` when
// the recomputed end state differs from the stored one; 2 for bad input (an
// unreadable file, another schema, an unknown run or frame), one line.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "bench/cli_rules.h"
#include "bench/signals.h"
#include "harness/crossings.h"
#include "harness/table_notes.h"
#include "harness/reproduce.h"
#include "results/contained_read.h"
#include "results/mesh_export.h"
#include "results/file_summary.h"
#include "results/run_diff.h"
#include "model/output_file.h"
#include "model/scene.h"
#include "results/result_reader.h"
#include "results/run_records.h"
#include "results/run_table.h"
#include "results/scale_verdict.h"

namespace clothbench {
namespace {

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

std::string JsonString(const std::string& s) {
  std::string out = "\"";
  for (unsigned char c : s) {
    if (c == '"' || c == '\\') out += '\\', out += static_cast<char>(c);
    else if (c < 0x20) out += fmt::format("\\u{:04x}", c);
    else out += static_cast<char>(c);
  }
  return out + "\"";
}

std::string JsonValue(const AttributeValue& v) {
  if (const auto* s = std::get_if<std::string>(&v)) return JsonString(*s);
  if (const auto* l = std::get_if<long>(&v)) return std::to_string(*l);
  const double d = std::get<double>(v);
  return std::isfinite(d) ? fmt::format("{:.17g}", d) : "null";
}

std::string Opt(const std::optional<double>& v, const char* format = "{:.3e}") {
  return v ? fmt::format(fmt::runtime(format), *v) : "-";
}

void PrintRuns(const ResultReader& f, const RunTable& t, bool json) {
  if (!json) {
    for (const RunRecord& r : t.runs)
      fmt::print("{} label={} status={} steps={} updates={} cg_iterations={} solver_time_s={:.6g} e_rms_m={}\n", r.id,
                 r.label, r.status, r.steps, r.updates, r.cg_iterations, r.solver_time_s, Opt(r.error_final_m, "{:.6e}"));
    return;
  }
  // Every scalar attribute of every run, plus its id and stored frames.
  fmt::print("[");
  for (std::size_t k = 0; k < t.runs.size(); ++k) {
    const std::string g = "/runs/" + t.runs[k].id;
    fmt::print("{}\n  {{\"id\": {}", k ? "," : "", JsonString(t.runs[k].id));
    for (const auto& [name, value] : f.Attributes(g)) fmt::print(", {}: {}", JsonString(name), JsonValue(value));
    for (const char* frames : {"positions", "positions_ends"})
      if (f.Exists(g + "/" + frames)) fmt::print(", \"{}_frames\": {}", frames, f.Shape(g + "/" + frames)[0]);
    fmt::print("}}");
  }
  fmt::print("\n]\n");
}

void Export(const ResultReader& f, const std::string& run, long frame, const std::string& obj, const std::string& ply) {
  const std::string& path = obj.empty() ? ply : obj;
  const ExportedFrame e =
      ExportFrame(f, run, frame, obj.empty() ? MeshFormat::kPly : MeshFormat::kObj, path, obj.empty() ? "--ply" : "--obj");
  fmt::print("{}: run {} frame {} (t = {:g} s), {} vertices, {} quads\n", path, run, frame, e.t, e.vertices, e.quads);
}

// `rerun`: recomputes a stored run in-process and says whether its end state
// equals the stored one bit for bit. @return 0 if it does (or the file
// keeps no end state and the counts agree), 1 otherwise
int Rerun(const ResultReader& f, const RunTable& t, const std::string& id, const std::string& out) {
  InstallInterruptHandlers();
  const RerunOutcome o = RerunStored(f, t, id, out);
  const RunRecord& r = o.run;
  fmt::print("rerun {}: status {}, {} steps, {} updates, {} CG iterations, solver time {:.3f} s{}\n", EscapeControl(id),
             r.status, r.steps, r.updates, r.cg_iterations, r.solver_time_s,
             o.counts_equal ? " (counts as stored)" : " (stored counts differ)");
  if (!out.empty()) fmt::print("written: {}\n", EscapeControl(out));
  if (!o.end_state_kept) {
    fmt::print("the file keeps no end state of the run (--frames none): counts {}\n",
               o.counts_equal ? "equal" : "differ");
    return o.counts_equal ? 0 : 1;
  }
  if (o.bit_for_bit && o.counts_equal) {
    fmt::print("end state at t_end equals the stored one bit for bit\n");
    return 0;
  }
  fmt::print("end state differs from the stored one: positions by up to {:.3e} m, velocities by up to {:.3e} m/s "
             "(the same build and thread count reproduce a run bit for bit)\n",
             o.max_dx, o.max_dv);
  return 1;
}

// The command line: the file, the subcommand chosen and its options.
struct Args {
  std::string file, other, run, obj, ply, metric, rerun, rerun_out, crossing_run;
  bool json = false;
  long frame = 0;
  double rtol = 1e-6, time_tolerance = 0.5;
  ReproduceOptions reproduce;
  CLI::App *summary = nullptr, *table = nullptr, *runs = nullptr, *diff = nullptr, *exp = nullptr, *wp = nullptr,
           *command = nullptr, *rerun_app = nullptr, *verdict = nullptr, *crossings = nullptr;
};

void AddSubcommands(CLI::App& app, Args* a) {
  app.require_subcommand(1);
  app.add_option("file", a->file, "result file (.h5)")->required();
  a->summary = app.add_subcommand("summary", "scene, machine, commit, runs with status and counts, contact checks");
  a->table = app.add_subcommand("table", "the table bench_integrators printed, from the file alone");
  a->runs = app.add_subcommand("runs", "one line per run");
  a->runs->add_flag("--json", a->json, "every attribute of every run as a JSON array");
  a->diff = app.add_subcommand("diff", "per run, the change in e_rms, steps, updates, CG iterations and solver "
                                       "time against a second file; exit 1 if a change is flagged");
  a->diff->add_option("other", a->other, "the second result file (B)")->required();
  a->diff->add_option("--rtol", a->rtol,
                      "flag relative e_rms changes above this (default 1e-6: runs are deterministic, so a rebuild of "
                      "the same code gives the same e_rms to the last bits; changed summation order moves it by ~1e-12)");
  a->diff->add_option("--time-tolerance", a->time_tolerance,
                      "flag solver-time ratios B/A outside [1/(1+T), 1+T] (default 0.5: repeated runs on a shared "
                      "2-core VM differ by up to ~30 %)");
  a->exp = app.add_subcommand("export", "one stored frame of a run as a mesh (OBJ or PLY, quads)");
  a->exp->add_option("run", a->run, "run id (clothbench_inspect FILE runs) or \"reference\"")->required();
  a->exp->add_option("--frame", a->frame, "index of the stored frame (default 0)");
  CLI::Option* o_obj = a->exp->add_option("--obj", a->obj, "write Wavefront OBJ");
  CLI::Option* o_ply = a->exp->add_option("--ply", a->ply, "write ASCII PLY");
  o_obj->excludes(o_ply);
  a->wp = app.add_subcommand("work-precision", "the equal-accuracy table, from the stored runs under an error "
                                               "norm of choice (same targets and baseline)");
  a->wp->add_option("--error-metric", a->metric, "final | l2 | max (default: the file's)");
  a->verdict = app.add_subcommand("verdict", "the verdict of a bench_integrators --sizes file: per size and target "
                                             "the fastest method, its solver time and its margin over the runner-up");
  a->command = app.add_subcommand("command", "a shell script that writes the file's scene text to a scene file "
                                             "and runs bench_integrators with exactly the settings of RUN");
  a->command->add_option("run", a->rerun, "run id (clothbench_inspect FILE runs)")->required();
  a->command->add_option("--dir", a->reproduce.dir, "folder for the scene file and the result (default rerun-RUN)");
  a->command->add_option("--bench", a->reproduce.bench,
                         "bench_integrators to call (default: the one next to this executable)");
  a->crossings = app.add_subcommand("self-intersections", "per stored frame of RUN, the cloth's crossing triangle pairs (exit 1 if any)");
  a->crossings->add_option("run", a->crossing_run, "run id (clothbench_inspect FILE runs) or \"reference\"")->required();
  a->rerun_app = app.add_subcommand(
      "rerun", "recompute RUN in-process from the file's scene text and stored settings (validated as a run request), "
               "with its thread count, and compare its end state with the stored one bit for bit; exit 1 if it differs");
  a->rerun_app->add_option("run", a->rerun, "run id (clothbench_inspect FILE runs)")->required();
  a->rerun_app->add_option("--out", a->rerun_out, "also write the recomputed run as the only run of this result file");
}

// `work-precision`: the equal-accuracy table under the chosen error norm.
void PrintWorkPrecisionAs(const RunTable& t, const std::string& file, std::string metric) {
  if (!t.work_precision)
    throw UsageError(fmt::format("work-precision: {} has no /work_precision (written with --reference none)", file));
  if (metric.empty()) metric = t.error_metric;
  if (metric != "final" && metric != "l2" && metric != "max")
    throw UsageError(fmt::format("--error-metric: \"{}\" must be final, l2 or max", metric));
  std::vector<const RunRecord*> records;
  for (const RunRecord& r : t.runs) records.push_back(&r);
  fmt::print("# {}: written {} by commit {}; errors: {}\n", file, t.created, t.git_commit, metric);
  // The reference's error estimate is in the file's metric: known for that one only.
  const double reference_error =
      t.reference && metric == t.error_metric ? t.reference->error_estimate_m : -1.0;
  PrintWorkPrecision(stdout, WorkPrecisionOf(records, t.work_precision->targets, t.work_precision->reference, metric,
                                             reference_error));
}

// `command`: the script; bench_integrators next to this executable unless --bench names one.
void PrintCommand(const ResultReader& f, const RunTable& t, const Args& a) {
  ReproduceOptions reproduce = a.reproduce;
  if (reproduce.dir.empty()) reproduce.dir = "rerun-" + a.rerun;
  if (a.command->count("--bench") == 0) {
    std::error_code ec;
    const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
    if (!ec) reproduce.bench = (self.parent_path() / "bench_integrators").string();
  }
  try {
    fmt::print("{}", ReproduceScript(f, t, a.rerun, reproduce));
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
}

// The chosen subcommand on the file, read whole first in a child process (a
// damaged file that crashes the HDF5 library is refused, exit 2, instead
// of taking this process down). @return the exit code
int RunSubcommand(const Args& a) {
  if (!(a.rtol >= 0.0) || !(a.time_tolerance >= 0.0))
    throw UsageError("diff: --rtol and --time-tolerance must be non-negative numbers");
  CheckReadableInChild(a.file);
  if (a.diff->parsed()) CheckReadableInChild(a.other);
  const ResultReader f(a.file);
  const RunTable t = ValidateResultFile(f);
  if (a.summary->parsed()) {
    PrintFileSummary(stdout, f, t);
  } else if (a.table->parsed()) {
    if (t.runs.empty() && !f.Exists("/runs"))
      throw UsageError(fmt::format("table: {} has no /runs (not a bench_integrators run table)", a.file));
    fmt::print("# {}: written {} by commit {}\n", a.file, t.created, t.git_commit);
    PrintRunTable(stdout, t, RegistryTableNotes());
    if (t.work_precision) PrintWorkPrecision(stdout, *t.work_precision);
  } else if (a.runs->parsed()) {
    PrintRuns(f, t, a.json);
  } else if (a.diff->parsed()) {
    const ResultReader g(a.other);
    return PrintRunDiff(stdout, t, ValidateResultFile(g), a.other, a.rtol, a.time_tolerance) > 0 ? 1 : 0;
  } else if (a.exp->parsed()) {
    Export(f, a.run, a.frame, a.obj, a.ply);
  } else if (a.wp->parsed()) {
    PrintWorkPrecisionAs(t, a.file, a.metric);
  } else if (a.verdict->parsed()) {
    if (!f.Exists("/scale_verdict"))
      throw UsageError(fmt::format("verdict: {} has no /scale_verdict (written by bench_integrators --sizes)", a.file));
    fmt::print("# {}: written {} by commit {}\n", a.file, t.created, t.git_commit);
    PrintScaleVerdict(stdout, ReadScaleVerdict(f));
  } else if (a.rerun_app->parsed()) {
    return Rerun(f, t, a.rerun, a.rerun_out);
  } else if (a.command->parsed()) {
    PrintCommand(f, t, a);
  } else if (a.crossings->parsed()) {
    InstallInterruptHandlers();
    return PrintSelfIntersections(stdout, f, a.crossing_run) > 0 ? 1 : 0;
  }
  return 0;
}

int Main(int argc, char** argv) {
  CLI::App app{"clothbench_inspect: print, compare and export bench_integrators result files (HDF5)"};
  Args a;
  AddSubcommands(app, &a);
  try {
    app.parse(argc, argv);
    RefuseEmptyValues(app);
    if (a.exp->parsed() && a.obj.empty() && a.ply.empty())
      throw CLI::ValidationError("export: one of --obj or --ply is required");
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    fmt::print(stderr, "clothbench_inspect: {}\n", e.what());
    return 2;
  }
  const std::string& file = a.file;
  try {
    return RunSubcommand(a);
  } catch (const UsageError& e) {
    fmt::print(stderr, "clothbench_inspect: {}\n", EscapeControl(e.what()));
    return 2;
  } catch (const std::invalid_argument& e) {  // a refused request (harness/run_request.h)
    fmt::print(stderr, "clothbench_inspect: {}\n", EscapeControl(e.what()));
    return 2;
  } catch (const Interrupted& e) {
    fmt::print(stderr, "clothbench_inspect: interrupted by {}; nothing written\n", SignalName(e.signal));
    return 128 + e.signal;
  } catch (const ResultError& e) {
    fmt::print(stderr, "clothbench_inspect: {}\n", EscapeControl(e.what()));
    return 2;
  } catch (const SceneError& e) {  // rerun: the stored scene (or its mesh) is refused
    fmt::print(stderr, "clothbench_inspect: {}\n", EscapeControl(e.what()));
    return 2;
  } catch (const std::bad_alloc&) {
    fmt::print(stderr, "clothbench_inspect: {}: out of memory while reading it\n", EscapeControl(file));
    return 1;
  } catch (const std::exception& e) {
    fmt::print(stderr, "clothbench_inspect: {}: {}\n", EscapeControl(file), EscapeControl(e.what()));
    return 1;
  }
}

}  // namespace
}  // namespace clothbench

int main(int argc, char** argv) { return clothbench::Main(argc, argv); }
