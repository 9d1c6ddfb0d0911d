#include "results/run_diff.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <vector>

#include <fmt/format.h>

namespace clothbench {
namespace {

// A value or "-" (not stored).
std::string Opt(const std::optional<double>& v) { return v ? fmt::format("{:.3e}", *v) : "-"; }

// Relative change (b − a)/|a|; 0 if both are 0, infinite if only a is.
double Relative(double a, double b) {
  if (a == b) return 0.0;
  return a == 0.0 ? INFINITY : (b - a) / std::fabs(a);
}

}  // namespace

int PrintRunDiff(std::FILE* out, const RunTable& a, const RunTable& b, const std::string& path_b, double rtol,
                 double time_tolerance) {
  std::map<std::string, const RunRecord*> in_b;
  for (const RunRecord& r : b.runs) in_b[r.id] = &r;
  std::set<std::string> in_a;
  int flagged = 0;
  fmt::print(out, "comparing {} (commit {}) with {} (commit {}); flags: e_rms relative change > {:g}, any change in "
             "steps, updates or CG iterations, solver time ratio outside [1/{:g}, {:g}], status changes, runs in one "
             "file only\n",
             a.scene_name, a.git_commit, path_b, b.git_commit, rtol, 1.0 + time_tolerance, 1.0 + time_tolerance);
  fmt::print(out, "{:<36} {:>11} {:>11} {:>10} {:>13} {:>15} {:>17} {:>8}  {}\n", "run", "e_rms A", "e_rms B", "rel",
             "steps", "updates", "cg_iters", "time B/A", "flags");
  for (const RunRecord& ra : a.runs) {
    in_a.insert(ra.id);
    const auto it = in_b.find(ra.id);
    if (it == in_b.end()) {
      fmt::print(out, "{:<36} only in A\n", ra.id);
      ++flagged;
      continue;
    }
    const RunRecord& rb = *it->second;
    std::vector<std::string> flags;
    std::string rel = "-";
    if (ra.error_final_m && rb.error_final_m) {
      const double d = Relative(*ra.error_final_m, *rb.error_final_m);
      rel = fmt::format("{:+.2e}", d);
      if (!(std::fabs(d) <= rtol)) flags.push_back("e_rms");
    } else if (ra.error_final_m.has_value() != rb.error_final_m.has_value()) {
      flags.push_back("e_rms");
    }
    if (ra.status != rb.status) flags.push_back(fmt::format("status {}→{}", ra.status, rb.status));
    if (ra.steps != rb.steps) flags.push_back("steps");
    if (ra.updates != rb.updates) flags.push_back("updates");
    if (ra.cg_iterations != rb.cg_iterations) flags.push_back("cg_iters");
    const double ratio = ra.solver_time_s > 0.0 ? rb.solver_time_s / ra.solver_time_s : 1.0;
    if (ratio > 1.0 + time_tolerance || ratio < 1.0 / (1.0 + time_tolerance)) flags.push_back("time");
    std::string joined;
    for (const std::string& s : flags) joined += (joined.empty() ? "" : ",") + s;
    fmt::print(out, "{:<36} {:>11} {:>11} {:>10} {:>13} {:>15} {:>17} {:>8.2f}  {}\n", ra.id, Opt(ra.error_final_m),
               Opt(rb.error_final_m), rel, fmt::format("{}→{}", ra.steps, rb.steps),
               fmt::format("{}→{}", ra.updates, rb.updates), fmt::format("{}→{}", ra.cg_iterations, rb.cg_iterations),
               ratio, joined);
    if (!flags.empty()) ++flagged;
  }
  for (const RunRecord& rb : b.runs)
    if (!in_a.count(rb.id)) {
      fmt::print(out, "{:<36} only in B\n", rb.id);
      ++flagged;
    }
  fmt::print(out, "{} of {} runs flagged\n", flagged, std::max(a.runs.size(), b.runs.size()));
  return flagged;
}


}  // namespace clothbench
