// The records of a result file in both directions (docs/guide/results-schema.md):
// a run's attributes (RunRecordFields), the scene's and the equal-accuracy
// table's, written through ResultFile and read back through ResultReader,
// so that one file states the schema of each record for the writer and the
// reader alike.
#include "results/run_records.h"

#include <sstream>
#include <stdexcept>
#include <type_traits>
#include <variant>

#include <fmt/format.h>

namespace clothbench {
RunRecord ReadRunRecord(const ResultReader& f, const std::string& g, const std::string& id) {
  RunRecord r;
  r.id = id;
  for (const RecordField& field : RunRecordFields()) {
    const std::string name = field.name;
    std::visit(
        [&](auto member) {
          using T = std::remove_reference_t<decltype(r.*member)>;
          if constexpr (std::is_same_v<T, std::string>) {
            if (auto v = f.String(g, name)) r.*member = *v;
          } else if constexpr (std::is_same_v<T, long>) {
            if (auto v = f.Long(g, name)) r.*member = *v;
          } else if constexpr (std::is_same_v<T, double>) {
            if (auto v = f.Double(g, name)) r.*member = *v;
          } else if constexpr (std::is_same_v<T, StepKind> || std::is_same_v<T, RunStatus>) {
            const std::optional<std::string> text = f.String(g, name);
            if (!text) return;
            std::optional<T> v;
            if constexpr (std::is_same_v<T, StepKind>) v = ParseStepKind(*text);
            else v = ParseRunStatus(*text);
            if (!v)
              throw ResultError(fmt::format("{}: {} attribute {} = \"{}\" is not one of the schema's values "
                                            "(docs/guide/results-schema.md)",
                                            f.path(), g, name, *text));
            r.*member = *v;
          } else {
            r.*member = f.Double(g, name);
          }
        },
        field.member);
  }
  // One timing stores no spread (files before solver_time_s_median: the same).
  if (!f.Double(g, "solver_time_s_median")) r.solver_time_s_median = r.solver_time_s;
  if (!f.Double(g, "solver_time_s_max")) r.solver_time_s_max = r.solver_time_s;
  if (!r.error_final_m) r.error_final_m = f.Double(g, "error_rms_m");  // files before error_final_m
  for (auto& [name, value] : f.Attributes(g))
    if (IsMethodAttributeName(name)) r.method_attributes.emplace_back(name, std::move(value));
  return r;
}

RunTable ReadRunTable(const ResultReader& f) {
  RunTable t;
  const auto str = [&](const std::string& o, const std::string& n) { return f.String(o, n).value_or(""); };
  t.schema = str("/", "schema");
  t.created = str("/", "created");
  t.git_commit = str("/", "git_commit");
  t.host = str("/", "host");
  t.compiler = str("/", "compiler");
  t.build_type = str("/", "build_type");
  t.hardware_threads = f.Long("/", "hardware_threads").value_or(0);
  t.error_metric = f.String("/", "error_metric").value_or("final");
  for (const SceneField& field : SceneRecordFields())
    std::visit(
        [&](auto member) {
          using T = std::remove_reference_t<decltype(t.*member)>;
          if constexpr (std::is_same_v<T, std::string>) t.*member = str("/scene", field.name);
          else if constexpr (std::is_same_v<T, long>) t.*member = f.Long("/scene", field.name).value_or(0);
          else t.*member = f.Double("/scene", field.name).value_or(0.0);
        },
        field.member);
  if (f.Exists("/reference")) t.reference = ReadRunRecord(f, "/reference", "reference");
  for (const std::string& id : f.Children("/runs")) t.runs.push_back(ReadRunRecord(f, "/runs/" + id, id));
  if (f.Exists("/work_precision/targets")) {
    EqualAccuracyTable w;
    w.targets = f.Doubles("/work_precision/targets");
    w.reference = str("/work_precision", "baseline");
    w.metric = f.String("/work_precision", "error_metric").value_or("final");
    std::stringstream labels(str("/work_precision", "labels"));  // comma-separated
    for (std::string label; std::getline(labels, label, ',');) w.labels.push_back(label);
    const std::vector<double> cost = f.Doubles("/work_precision/solver_time");
    const std::vector<double> ratio = f.Doubles("/work_precision/ratio");
    const std::vector<int32_t> bound =
        f.Exists("/work_precision/upper_bound") ? f.Ints("/work_precision/upper_bound") : std::vector<int32_t>{};
    const std::vector<double> min_error =
        f.Exists("/work_precision/min_error") ? f.Doubles("/work_precision/min_error") : std::vector<double>{};
    const std::size_t cols = w.targets.size();
    if (cost.size() != w.labels.size() * cols || ratio.size() != cost.size() ||
        (!bound.empty() && bound.size() != cost.size()) || (!min_error.empty() && min_error.size() != w.labels.size()))
      throw ResultError(fmt::format("{}: /work_precision: {} labels × {} targets but {} cells", f.path(),
                                    w.labels.size(), cols, cost.size()));
    for (std::size_t m = 0; m < w.labels.size(); ++m) {
      w.cost.emplace_back();
      w.ratio.emplace_back();
      w.upper_bound.emplace_back();
      for (std::size_t j = 0; j < cols; ++j) {
        const double c = cost[m * cols + j], q = ratio[m * cols + j];
        w.cost.back().push_back(c >= 0.0 ? std::optional(c) : std::nullopt);
        w.ratio.back().push_back(q >= 0.0 ? std::optional(q) : std::nullopt);
        w.upper_bound.back().push_back(!bound.empty() && bound[m * cols + j] != 0);
      }
      w.min_error.push_back(!min_error.empty() && min_error[m] > 0.0 ? std::optional(min_error[m]) : std::nullopt);
    }
    w.reference_error_m = f.Double("/work_precision", "reference_error_estimate_m").value_or(-1.0);
    if (const std::optional<std::string> lines = f.String("/work_precision", "stop_reasons")) {
      std::stringstream in(*lines);
      for (std::string line; std::getline(in, line);) w.stop_reasons.push_back(line);
    }
    if (f.Exists("/work_precision/unresolved")) {
      const std::vector<int32_t> unresolved = f.Ints("/work_precision/unresolved");
      if (unresolved.size() != cols)
        throw ResultError(fmt::format("{}: /work_precision/unresolved: {} entries, {} targets", f.path(),
                                      unresolved.size(), cols));
      for (int32_t u : unresolved) w.unresolved.push_back(u != 0);
    }
    for (int32_t k : f.Ints("/work_precision/fastest")) {
      if (k < -1 || k >= static_cast<int32_t>(w.labels.size()))
        throw ResultError(fmt::format("{}: /work_precision/fastest: {} is not a label index (-1 … {})", f.path(), k,
                                      static_cast<long>(w.labels.size()) - 1));
      w.fastest.push_back(k);
    }
    if (w.fastest.size() != cols)
      throw ResultError(fmt::format("{}: /work_precision/fastest: {} entries, {} targets", f.path(), w.fastest.size(),
                                    cols));
    if (f.Exists("/work_precision/tied")) {
      const std::vector<int32_t> tied = f.Ints("/work_precision/tied");
      if (tied.size() != cost.size())
        throw ResultError(fmt::format("{}: /work_precision/tied: {} cells, {} expected", f.path(), tied.size(), cost.size()));
      for (std::size_t j = 0; j < cols; ++j) {
        w.tied.emplace_back();
        for (std::size_t m = 0; m < w.labels.size(); ++m)
          if (tied[j * w.labels.size() + m]) w.tied.back().push_back(static_cast<int>(m));
      }
    }
    t.work_precision = std::move(w);
  }
  return t;
}

void WriteRunRecord(ResultFile& f, const std::string& g, const RunRecord& record) {
  RunRecord r = record;
  if (r.repeats <= 1) r.solver_time_s_median = r.solver_time_s_max = r.solver_time_s;
  for (const RecordField& field : RunRecordFields()) {
    std::visit(
        [&](auto member) {
          const auto& v = r.*member;
          using T = std::remove_cvref_t<decltype(v)>;
          bool store = true;
          switch (field.stored) {
            case Stored::kAlways: break;
            case Stored::kStepParameter: store = SpecOf(r.step_kind).param == field.name; break;
            case Stored::kStepCount: store = SpecOf(r.step_kind).count == field.name; break;
            default:
              if constexpr (std::is_same_v<T, std::string>) store = !v.empty();
              else if constexpr (std::is_same_v<T, StepKind> || std::is_same_v<T, RunStatus>) store = true;
              else if constexpr (std::is_same_v<T, std::optional<double>>) store = v.has_value();
              else store = field.stored == Stored::kPositive ? v > 0 : v >= 0;
          }
          if (!store) return;
          if constexpr (std::is_same_v<T, std::optional<double>>) f.SetAttribute(g, field.name, *v);
          else if constexpr (std::is_same_v<T, StepKind> || std::is_same_v<T, RunStatus>)
            f.SetAttribute(g, field.name, std::string(ToString(v)));
          else f.SetAttribute(g, field.name, v);
        },
        field.member);
  }
  for (const auto& attribute : r.method_attributes) {
    const std::string& name = attribute.first;
    if (!IsMethodAttributeName(name))
      throw std::logic_error(fmt::format("{}: method attribute {} repeats a field's name", g, name));
    std::visit([&](const auto& v) { f.SetAttribute(g, name, v); }, attribute.second);
  }
}

void WriteSceneRecord(ResultFile& f, const RunTable& t) {
  using W = SceneField::When;
  for (const SceneField& field : SceneRecordFields())
    std::visit(
        [&](auto member) {
          const auto& v = t.*member;
          const bool engine = field.stored == W::kStepEngine || field.stored == W::kStepEngineNonEmpty;
          if (engine && t.cholesky_ordering.empty()) return;
          if constexpr (std::is_same_v<std::remove_cvref_t<decltype(v)>, std::string>)
            if ((field.stored == W::kNonEmpty || field.stored == W::kStepEngineNonEmpty) && v.empty()) return;
          f.SetAttribute("/scene", field.name, v);
        },
        field.member);
}

void WriteWorkPrecision(ResultFile& f, const EqualAccuracyTable& t, const std::string& g) {
  f.CreateGroup(g);
  f.SetAttribute(g, "baseline", t.reference);
  f.SetAttribute(g, "error_metric", t.metric);
  f.SetAttribute(g, "measure",
                 std::string("solver_time_s at e_rms(t_end) = target on each method's lower envelope of (error, "
                             "solver_time_s) runs, log-log interpolation between adjacent envelope runs; upper_bound 1: "
                             "the cheapest run already meets the target (cost <= that run's); -1 where no run reaches "
                             "the target (min_error: the smallest error reached, -1 if every run failed)"));
  f.WriteVector(g + "/targets", t.targets, "m");
  std::string labels;
  for (const std::string& l : t.labels) labels += (labels.empty() ? "" : ",") + l;
  f.SetAttribute(g, "labels", labels);
  const int rows = static_cast<int>(t.labels.size()), cols = static_cast<int>(t.targets.size());
  std::vector<double> cost, ratio, min_error;
  std::vector<int32_t> bound;
  for (std::size_t m = 0; m < static_cast<std::size_t>(rows); ++m) {
    for (std::size_t j = 0; j < static_cast<std::size_t>(cols); ++j) {
      cost.push_back(t.cost[m][j].value_or(-1.0));
      ratio.push_back(t.ratio[m][j].value_or(-1.0));
      bound.push_back(m < t.upper_bound.size() && t.upper_bound[m][j] ? 1 : 0);
    }
    min_error.push_back(m < t.min_error.size() && t.min_error[m] ? *t.min_error[m] : -1.0);
  }
  f.WriteTable(g + "/solver_time", rows, cols, cost, "s");
  f.WriteTable(g + "/ratio", rows, cols, ratio, "");
  f.WriteTable(g + "/upper_bound", rows, cols, bound);
  f.WriteVector(g + "/min_error", min_error, "m");
  // unresolved [T]: 1 where the target is below 10× the reference's error
  // estimate (no cost given there); the estimate itself, −1 if unknown.
  std::vector<int32_t> unresolved;
  for (std::size_t j = 0; j < static_cast<std::size_t>(cols); ++j)
    unresolved.push_back(j < t.unresolved.size() && t.unresolved[j] ? 1 : 0);
  f.WriteTable(g + "/unresolved", 1, cols, unresolved);
  f.SetAttribute(g, "reference_error_estimate_m", t.reference_error_m);
  if (!t.stop_reasons.empty()) {  // --sweep-to-targets: one line per method
    std::string lines;
    for (const std::string& r : t.stop_reasons) lines += (lines.empty() ? "" : "\n") + r;
    f.SetAttribute(g, "stop_reasons", lines);
  }
  // tied [T, M]: 1 where the method is tied with the fastest at the target.
  std::vector<int32_t> tied(static_cast<std::size_t>(cols) * static_cast<std::size_t>(rows), 0);
  for (std::size_t j = 0; j < t.tied.size(); ++j)
    for (int m : t.tied[j]) tied[j * static_cast<std::size_t>(rows) + static_cast<std::size_t>(m)] = 1;
  f.WriteTable(g + "/tied", cols, rows, tied);
  std::vector<int32_t> fastest(t.fastest.begin(), t.fastest.end());
  f.WriteTable(g + "/fastest", 1, cols, fastest);
}

}  // namespace clothbench
