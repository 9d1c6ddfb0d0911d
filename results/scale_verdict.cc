// The verdict across sizes (results/scale_verdict.h).
#include "results/scale_verdict.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>

namespace clothbench {

ScaleVerdict BuildScaleVerdict(const std::vector<long>& sizes, const std::vector<EqualAccuracyTable>& tables,
                               const std::vector<std::string>& files) {
  if (tables.size() != sizes.size() || files.size() != sizes.size())
    throw std::invalid_argument(fmt::format("scale verdict: {} sizes, {} tables, {} files", sizes.size(),
                                            tables.size(), files.size()));
  ScaleVerdict v;
  v.sizes = sizes;
  v.result_files = files;
  if (tables.empty()) return v;
  v.targets = tables.front().targets;
  v.metric = tables.front().metric;
  for (const EqualAccuracyTable& t : tables) {
    if (t.targets != v.targets) throw std::invalid_argument("scale verdict: the sizes' targets differ");
    for (const std::string& l : t.labels)
      if (std::find(v.labels.begin(), v.labels.end(), l) == v.labels.end()) v.labels.push_back(l);
  }
  const std::size_t T = v.targets.size(), M = v.labels.size();
  for (const EqualAccuracyTable& t : tables) {
    std::vector<std::vector<std::optional<double>>> cost(T, std::vector<std::optional<double>>(M));
    std::vector<std::vector<bool>> bound(T, std::vector<bool>(M, false));
    std::vector<int> fastest(T, -1), runner(T, -1);
    std::vector<std::optional<double>> margin(T);
    std::vector<bool> tied(T, false), unresolved(T, false);
    std::vector<int> index;  // the table's method k is labels[index[k]]
    for (const std::string& l : t.labels)
      index.push_back(static_cast<int>(std::find(v.labels.begin(), v.labels.end(), l) - v.labels.begin()));
    for (std::size_t j = 0; j < T; ++j) {
      for (std::size_t k = 0; k < t.labels.size(); ++k) {
        const std::size_t m = static_cast<std::size_t>(index[k]);
        cost[j][m] = t.cost[k][j];
        bound[j][m] = k < t.upper_bound.size() && t.upper_bound[k][j];
      }
      unresolved[j] = j < t.unresolved.size() && t.unresolved[j];
      if (j >= t.fastest.size() || t.fastest[j] < 0) continue;
      const std::size_t b = static_cast<std::size_t>(t.fastest[j]);
      fastest[j] = index[b];
      int r = -1;
      for (std::size_t k = 0; k < t.labels.size(); ++k)
        if (k != b && t.cost[k][j] && (r < 0 || *t.cost[k][j] < *t.cost[static_cast<std::size_t>(r)][j]))
          r = static_cast<int>(k);
      if (r < 0) continue;
      runner[j] = index[static_cast<std::size_t>(r)];
      margin[j] = *t.cost[static_cast<std::size_t>(r)][j] / *t.cost[b][j];
      tied[j] = j < t.tied.size() && std::find(t.tied[j].begin(), t.tied[j].end(), r) != t.tied[j].end();
    }
    v.cost.push_back(cost);
    v.upper_bound.push_back(bound);
    v.fastest.push_back(fastest);
    v.runner_up.push_back(runner);
    v.margin.push_back(margin);
    v.tied.push_back(tied);
    v.unresolved.push_back(unresolved);
    v.reference_error_m.push_back(t.reference_error_m);
  }
  return v;
}

namespace {

std::string Joined(const std::vector<std::string>& labels) {
  std::string out;
  for (const std::string& l : labels) out += (out.empty() ? "" : ",") + l;
  return out;
}

std::string LabelOf(const ScaleVerdict& v, int m) {
  return m >= 0 ? v.labels[static_cast<std::size_t>(m)] : std::string();
}

[[noreturn]] void Bad(const ResultReader& f, const std::string& what, const std::string& rule) {
  throw ResultError(fmt::format("{}: /scale_verdict/{}: {}", f.path(), what, rule));
}

}  // namespace

void WriteScaleVerdict(ResultFile& f, const ScaleVerdict& v) {
  const std::string g = "/scale_verdict";
  f.CreateGroup(g);
  f.SetAttribute(g, "labels", Joined(v.labels));
  f.SetAttribute(g, "error_metric", v.metric);
  f.SetAttribute(g, "measure",
                 std::string("per size and target: the fastest method of that size's equal-accuracy table "
                             "(sizes/n<N>/work_precision), the runner-up and margin = runner-up cost / fastest cost; "
                             "cost_s -1 and fastest \"\" where there is no number"));
  const std::size_t S = v.sizes.size(), T = v.targets.size(), M = v.labels.size();
  std::vector<int32_t> sizes(v.sizes.begin(), v.sizes.end());
  f.WriteTable(g + "/sizes", 1, static_cast<int>(S), sizes);
  f.WriteVector(g + "/targets", v.targets, "m");
  std::vector<std::string> fastest, runner;
  std::vector<double> margin, cost;
  std::vector<int32_t> tied, unresolved, bound;
  for (std::size_t s = 0; s < S; ++s)
    for (std::size_t j = 0; j < T; ++j) {
      fastest.push_back(LabelOf(v, v.fastest[s][j]));
      runner.push_back(LabelOf(v, v.runner_up[s][j]));
      margin.push_back(v.margin[s][j].value_or(-1.0));
      tied.push_back(v.tied[s][j] ? 1 : 0);
      unresolved.push_back(v.unresolved[s][j] ? 1 : 0);
      for (std::size_t m = 0; m < M; ++m) {
        cost.push_back(v.cost[s][j][m].value_or(-1.0));
        bound.push_back(v.upper_bound[s][j][m] ? 1 : 0);
      }
    }
  const int rows = static_cast<int>(S), cols = static_cast<int>(T);
  f.WriteStrings(g + "/fastest", rows, cols, fastest);
  f.WriteStrings(g + "/runner_up", rows, cols, runner);
  f.WriteTable(g + "/margin", rows, cols, margin, "");
  f.WriteTable(g + "/tied", rows, cols, tied);
  f.WriteTable(g + "/unresolved", rows, cols, unresolved);
  f.WriteArray3(g + "/cost_s", {S, T, M}, cost, "s");
  f.WriteArray3(g + "/upper_bound", {S, T, M}, bound);
  f.WriteVector(g + "/reference_error_estimate_m", v.reference_error_m, "m");
  f.WriteStrings(g + "/result_files", rows, 1, v.result_files);
}

ScaleVerdict ReadScaleVerdict(const ResultReader& f) {
  const std::string g = "/scale_verdict";
  if (!f.Exists(g)) throw ResultError(fmt::format("{}: no /scale_verdict (not a bench_integrators --sizes file)", f.path()));
  ScaleVerdict v;
  std::stringstream labels(f.String(g, "labels").value_or(""));
  for (std::string l; std::getline(labels, l, ',');) v.labels.push_back(l);
  v.metric = f.String(g, "error_metric").value_or("final");
  for (int32_t n : f.Ints(g + "/sizes")) {
    if (n < 1) Bad(f, "sizes", fmt::format("{} is not a particle count", n));
    v.sizes.push_back(n);
  }
  v.targets = f.Doubles(g + "/targets");
  const std::size_t S = v.sizes.size(), T = v.targets.size(), M = v.labels.size();
  for (double t : v.targets)
    if (!(t > 0.0) || !std::isfinite(t)) Bad(f, "targets", "must be positive and finite");
  const auto shape = [&](const char* d, std::vector<std::size_t> want) {
    if (f.Shape(g + "/" + d) != want) Bad(f, d, fmt::format("shape must be [{}]", fmt::join(want, ", ")));
  };
  shape("fastest", {S, T});
  shape("runner_up", {S, T});
  shape("margin", {S, T});
  shape("tied", {S, T});
  shape("unresolved", {S, T});
  shape("cost_s", {S, T, M});
  shape("upper_bound", {S, T, M});
  shape("reference_error_estimate_m", {S});
  shape("result_files", {S, 1});
  const auto index = [&](const char* d, const std::string& l) {
    if (l.empty()) return -1;
    const auto it = std::find(v.labels.begin(), v.labels.end(), l);
    if (it == v.labels.end()) Bad(f, d, fmt::format("\"{}\" is not in @labels", l));
    return static_cast<int>(it - v.labels.begin());
  };
  const std::vector<std::string> fastest = f.Strings(g + "/fastest"), runner = f.Strings(g + "/runner_up");
  const std::vector<double> margin = f.Doubles(g + "/margin"), cost = f.Doubles(g + "/cost_s"),
                            ref = f.Doubles(g + "/reference_error_estimate_m");
  const std::vector<int32_t> tied = f.Ints(g + "/tied"), unresolved = f.Ints(g + "/unresolved"),
                             bound = f.Ints(g + "/upper_bound");
  for (double c : cost)
    if (!std::isfinite(c) || (c < 0.0 && c != -1.0)) Bad(f, "cost_s", "values must be finite, >= 0 or -1");
  for (double m : margin)
    if (!std::isfinite(m) || (m < 1.0 && m != -1.0)) Bad(f, "margin", "values must be finite, >= 1 or -1");
  for (std::size_t s = 0; s < S; ++s) {
    v.cost.emplace_back(T, std::vector<std::optional<double>>(M));
    v.upper_bound.emplace_back(T, std::vector<bool>(M, false));
    v.fastest.emplace_back(T, -1);
    v.runner_up.emplace_back(T, -1);
    v.margin.emplace_back(T);
    v.tied.emplace_back(T, false);
    v.unresolved.emplace_back(T, false);
    for (std::size_t j = 0; j < T; ++j) {
      const std::size_t c = s * T + j;
      v.fastest[s][j] = index("fastest", fastest[c]);
      v.runner_up[s][j] = index("runner_up", runner[c]);
      if (margin[c] >= 1.0) v.margin[s][j] = margin[c];
      v.tied[s][j] = tied[c] != 0;
      v.unresolved[s][j] = unresolved[c] != 0;
      for (std::size_t m = 0; m < M; ++m) {
        if (cost[c * M + m] >= 0.0) v.cost[s][j][m] = cost[c * M + m];
        v.upper_bound[s][j][m] = bound[c * M + m] != 0;
      }
      if (v.fastest[s][j] >= 0 && !v.cost[s][j][static_cast<std::size_t>(v.fastest[s][j])])
        Bad(f, "fastest", fmt::format("{} at size {} and target {:g} m has no cost_s", fastest[c], v.sizes[s],
                                      v.targets[j]));
    }
  }
  v.reference_error_m = ref;
  v.result_files = f.Strings(g + "/result_files");
  return v;
}

void PrintScaleVerdict(std::FILE* out, const ScaleVerdict& v) {
  const std::string err = v.metric == "final" ? "e_rms" : "e_" + v.metric;
  fmt::print(out,
             "\nScale verdict: the fastest method at each size and target ({} [m]), its solver time and its margin "
             "over the runner-up (runner-up time / fastest time; '≈': within the timing spread)\n",
             err);
  fmt::print(out, "{:>9}", "N");
  for (double t : v.targets) fmt::print(out, " {:>38}", fmt::format("{} {:g} m", err, t));
  fmt::print(out, "\n");
  for (std::size_t s = 0; s < v.sizes.size(); ++s) {
    fmt::print(out, "{:>9}", v.sizes[s]);
    for (std::size_t j = 0; j < v.targets.size(); ++j) {
      const int b = v.fastest[s][j];
      std::string cell = v.unresolved[s][j] ? "unresolved" : "-";
      if (b >= 0) {
        const std::size_t m = static_cast<std::size_t>(b);
        cell = fmt::format("{} {}{:.3g} s", v.labels[m], v.upper_bound[s][j][m] ? "≤" : "", *v.cost[s][j][m]);
        if (v.margin[s][j])
          cell += fmt::format(" {}{:.2f}x {}", v.tied[s][j] ? "≈" : "", *v.margin[s][j], LabelOf(v, v.runner_up[s][j]));
      }
      fmt::print(out, " {:>38}", cell);
    }
    fmt::print(out, "\n");
  }
  for (std::size_t j = 0; j < v.targets.size(); ++j)
    for (std::size_t s = 1; s < v.sizes.size(); ++s)
      if (v.fastest[s][j] >= 0 && v.fastest[s - 1][j] >= 0 && v.fastest[s][j] != v.fastest[s - 1][j])
        fmt::print(out, "at {:g} m the fastest changes between N = {} and {}: {} -> {}{}\n", v.targets[j],
                   v.sizes[s - 1], v.sizes[s], LabelOf(v, v.fastest[s - 1][j]), LabelOf(v, v.fastest[s][j]),
                   v.tied[s - 1][j] || v.tied[s][j] ? " (a tie within the timing spread on one side)" : "");
}

}  // namespace clothbench
