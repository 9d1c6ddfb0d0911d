#include "results/file_summary.h"

#include <map>
#include <vector>

#include <fmt/format.h>

#include "results/scale_verdict.h"

namespace clothbench {
namespace {

// A value or "-" (not stored).
std::string Opt(const std::optional<double>& v) { return v ? fmt::format("{:.3e}", *v) : "-"; }

// Scenes with obstacles or [collision]: the deepest particle inside an
// obstacle over every run's stored frames, in collision distances δ
// (penetration_ratio; a run past 1 ends `penetration`), and the most
// crossing triangle pairs of the cloth at a stored frame
// (/runs/<id>/crossing_pairs). Nothing when no run stores either.
void PrintContactChecks(std::FILE* out, const ResultReader& f, const RunTable& t) {
  double deepest = -1.0;
  long crossings = -1;
  std::string deepest_run, crossing_run;
  for (const RunRecord& r : t.runs) {
    if (r.penetration_ratio > deepest) {
      deepest = r.penetration_ratio;
      deepest_run = r.id;
    }
    const std::string pairs = "/runs/" + r.id + "/crossing_pairs";
    if (!f.Exists(pairs)) continue;
    for (const int32_t n : f.Ints(pairs)) {
      if (n > crossings) {
        crossings = n;
        crossing_run = r.id;
      }
    }
  }
  if (deepest >= 0.0)
    fmt::print(out, "deepest penetration over the runs' stored frames: {:.3f} δ ({})\n", deepest, deepest_run);
  if (crossings == 0)
    fmt::print(out, "crossing triangle pairs: 0 at every stored frame of every run that stores them\n");
  else if (crossings > 0)
    fmt::print(out, "crossing triangle pairs: up to {} at a stored frame ({})\n", crossings, crossing_run);
}

}  // namespace

void PrintFileSummary(std::FILE* out, const ResultReader& f, const RunTable& t) {
  fmt::print(out, "file: {}\n", f.path());
  fmt::print(out, "schema {}, written {} by commit {} ({} build, {})\n", t.schema, t.created, t.git_commit, t.build_type,
             t.compiler);
  fmt::print(out, "machine: {}, {} hardware threads\n", t.host, t.hardware_threads);
  // stress_stability and --table files: their groups and what each holds.
  for (const char* top : {"/stress", "/table"}) {
    if (!f.Exists(top)) continue;
    const std::vector<std::string> children = f.Children(top);
    fmt::print(out, "{}: {}\n", top, top == std::string("/stress") ? "stability maps (stress_stability)"
                                                              : f.String(top, "name").value_or("thesis table"));
    for (const std::string& c : children) {
      const std::vector<std::string> sub = f.Children(std::string(top) + "/" + c);
      std::string list;
      for (const std::string& s : sub) list += (list.empty() ? "" : ", ") + s;
      fmt::print(out, "  {}{}\n", c, list.empty() ? "" : ": " + list);
    }
  }
  if (f.Exists("/scale_verdict")) {
    const ScaleVerdict v = ReadScaleVerdict(f);
    std::string sizes;
    for (long n : v.sizes) sizes += (sizes.empty() ? "" : ", ") + std::to_string(n);
    fmt::print(out, "scale verdict (bench_integrators --sizes): N = {}; {} methods × {} targets; each size's runs in "
               "{} (clothbench_inspect FILE verdict)\n",
               sizes, v.labels.size(), v.targets.size(), fmt::join(v.result_files, ", "));
  }
  if (!f.Exists("/scene")) return;
  fmt::print(out, "scene {} ({}): N = {} particles, {} fixed, t_end = {:g} s, frame_dt = {:g} s, frames kept: {}\n",
             t.scene_name, t.scene_source, t.n_particles, t.n_fixed, t.t_end, t.frame_dt,
             t.frames.empty() ? "-" : t.frames);
  if (t.reference)
    fmt::print(out, "reference: {}{}: {} steps, {:.2f} s\n", t.reference->label,
               IsSelfConvergence(*t.reference) ? fmt::format(" at h = {:g} s", t.reference->h)
                                                                   : fmt::format(" rtol {:g}", t.reference->rtol),
               t.reference->steps, t.reference->wall_time_s);
  else
    fmt::print(out, "reference: none\n");
  std::map<std::string, int> status;
  for (const RunRecord& r : t.runs) ++status[std::string(ToString(r.status))];
  std::string counts;
  for (const auto& [s, n] : status) counts += fmt::format("{}{} {}", counts.empty() ? "" : ", ", n, s);
  fmt::print(out, "runs: {}{}\n", t.runs.size(), counts.empty() ? "" : " (" + counts + ")");
  fmt::print(out, "{:<36} {:<10} {:>7} {:>8} {:>9} {:>10} {:>11}\n", "run", "status", "steps", "updates", "cg_iters",
             "solver_s", "e_rms_m");
  for (const RunRecord& r : t.runs)
    fmt::print(out, "{:<36} {:<10} {:>7} {:>8} {:>9} {:>10.3f} {:>11}\n", r.id, r.status, r.steps, r.updates,
               r.cg_iterations, r.solver_time_s, Opt(r.error_final_m));
  PrintContactChecks(out, f, t);
  if (t.work_precision)
    fmt::print(out, "work_precision: {} methods × {} targets\n", t.work_precision->labels.size(),
               t.work_precision->targets.size());
}

}  // namespace clothbench
