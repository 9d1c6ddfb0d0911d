// What harness/methods.h declares beyond the registry: a row's run, the
// options only some rows read, the scene's step control and the parsing of
// row names.
#include "harness/methods.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <type_traits>

#include <fmt/format.h>

namespace clothbench {

SolverSpec RowMethod::RowSpec(const SolverSpec& spec, const RunContext& ctx) const {
  SolverSpec row_spec = spec;
  const std::optional<PreconditionerType>& best =
      error_control ? entry->best_preconditioner_error : entry->best_preconditioner;
  // A scene's IC(0) is the thesis' setting, kept for --table and the
  // stability maps, and kBestPreconditioner was measured against it. A
  // scene that names another preconditioner chose it for itself (the
  // contact-scale scenes' prefiltered AMG, docs/notes/performance.md
  // "Prefiltered AMG") and keeps it.
  if (best && !ctx.preconditioner_from_cli && spec.preconditioner == PreconditionerType::kIc0)
    row_spec.preconditioner = *best;
  if (entry->best_cg_tolerance && !ctx.cg_tolerance_from_cli) row_spec.cg_tolerance = *entry->best_cg_tolerance;
  if (entry->best_tangent_explicit_terms && !ctx.tangent_terms_from_cli)
    row_spec.tangent_explicit_terms = *entry->best_tangent_explicit_terms;
  return row_spec;
}

MethodRun RowMethod::NotStarted(const Scene& scene, const SolverSpec& spec, double param, const RunContext& ctx,
                                int count, std::string message) const {
  MethodRun row;
  row.status = RunStatus::kNotStarted;
  row.message = std::move(message);
  Identify(scene, RowSpec(spec, ctx), param, count, &row);
  return row;
}

MethodRun RowMethod::Run(const ParticleSystem& sys, const Scene& scene, const SolverSpec& spec, double param,
                         const RunContext& ctx, int count) const {
  const SolverSpec row_spec = RowSpec(spec, ctx);
  // The step loop fills the record's status, counts and times (and the
  // SUNDIALS runs their settings); the row's identity follows.
  MethodRun row;
  const SolverSpec s = Settings(row_spec, param);
  std::unique_ptr<Stepper> stepper;
  if (entry->predict && ctx.refuse_predicted &&
             RefusedByPrediction(PredictOnce(entry->predict, sys, variant), ctx.limits.time_limit_s, &row)) {
    // not started: the record says why, its identity follows
  } else if (entry->make) {
    stepper = entry->make(sys, s, count, variant);
    // Error-controlled rows start at the scene's h; the controller takes over.
    static_cast<RunSummary&>(row) =
        RunStepper(sys, *stepper, {error_control ? scene.h : param, scene.t_end, scene.frame_dt, &s, ctx.limits});
    row.step_control = std::string(ToString(s.step_control));
    if (entry->describe) entry->describe(*stepper, sys, &row);
  } else {
    static_cast<RunSummary&>(row) = entry->integrate(
        sys, {param, -1.0, 5, scene.t_end, scene.frame_dt, ctx.limits}, row_spec, variant, ctx);
    row.step_control = "sundials";
  }
  Identify(scene, row_spec, param, count, &row);
  return row;
}

void RowMethod::Identify(const Scene& scene, const SolverSpec& row_spec, double param, int count,
                         MethodRun* out) const {
  MethodRun& row = *out;
  row.label = label();
  row.integrator = name();
  row.layer = std::string(entry->layer);
  row.step_kind = kind();
  if (fully_implicit()) row.nonlinear_solver = std::string(ToString(solver));
  row.id = RunId(param, count);
  row.h = row.rtol = row.atol = 0.0;
  const StepKindSpec& k = SpecOf(kind());
  if (k.adaptive()) {
    row.rtol = row.atol = param;  // rtol = atol for every adaptive row
    row.numerical_stiffness = scene.NumericalStiffness(scene.h);
  } else {
    row.h = param;
    if (k.counted()) row.*k.count_field = count;
    row.numerical_stiffness = scene.NumericalStiffness(k.count_divides_h ? param / count : param);
  }
  if (uses_pcg()) {
    row.cg_tolerance = row_spec.cg_tolerance;
    row.preconditioner = std::string(ToString(row_spec.preconditioner));
    row.predictor = std::string(ToString(row_spec.predictor));
    row.cg_reference = std::string(ToString(row_spec.cg_reference));
  }
  if (builds_tangent()) row.tangent_terms = row_spec.tangent_explicit_terms ? "all" : "tension";
  if (scene.collision) row.collision_self = scene.collision->self ? "on" : "off";
  if (solver == NonlinearSolver::kNewton) row.newton_jacobian = std::string(ToString(row_spec.newton_jacobian));
  row.threads = KernelThreads();
}

namespace {

// "1e-2,…,1e-7", "1,4": a default list as the help prints it.
template <class T>
std::string ListText(const std::vector<T>& values) {
  const auto one = [](T v) {
    if constexpr (std::is_floating_point_v<T>) {
      const double e = std::log10(v);
      if (v > 0.0 && e == std::round(e)) return fmt::format("1e{}", static_cast<int>(e));
    }
    return fmt::format("{:g}", static_cast<double>(v));
  };
  if (values.size() > 4) return one(values.front()) + ",…," + one(values.back());
  std::string s;
  for (T v : values) s += (s.empty() ? "" : ",") + one(v);
  return s;
}

}  // namespace

std::string DefaultListsText(bool rtols) {
  const std::string base = rtols ? ListText(kDefaultRtols) : ListText(kDefaultIterations);
  std::vector<std::pair<std::string, std::string>> groups;  // list, rows
  for (const MethodEntry& e : Registry())
    for (const RowDefaults& d : e.defaults) {
      if (rtols ? !(SpecOf(e.kind).adaptive() || d.error_row()) : SpecOf(e.kind).count != "iterations") continue;
      const std::string list = rtols ? ListText(d.rtols) : ListText(d.iterations.empty() ? kDefaultIterations : d.iterations);
      const std::string label = std::string(e.name) + (d.modifiers.empty() ? "" : "/") + std::string(d.modifiers);
      if (list == base) continue;
      auto g = std::find_if(groups.begin(), groups.end(), [&](const auto& p) { return p.first == list; });
      if (g == groups.end()) groups.emplace_back(list, label);
      else g->second += ", " + label;
    }
  std::string text = base;
  for (const auto& [list, rows] : groups) text += fmt::format("; {} ({})", list, rows);
  return text;
}

std::string RowsReading(const RowOption& o) {
  std::string labels;
  for (const MethodEntry& e : Registry()) {
    std::vector<std::string> variants = {""};
    for (std::string_view v : e.variants) variants.emplace_back(v);
    for (const NonlinearSolver solver : {NonlinearSolver::kFixedPoint, NonlinearSolver::kNewton})
      for (const bool error_control : {false, true})
        for (const std::string& variant : variants) {
          if ((solver == NonlinearSolver::kNewton && !e.nonlinear_solver) || (error_control && !e.error_control))
            continue;
          const RowMethod m{&e, solver, error_control, variant};
          if (o.reads(m)) labels += (labels.empty() ? "" : ", ") + m.label();
        }
  }
  return fmt::format("{}: {}", o.what, labels.empty() ? std::string("none") : labels);
}

const std::vector<RowOption>& RowOptions() {
  static const std::vector<RowOption> options = [] {
    std::vector<RowOption> o = {
        {"rtol", "--rtols", [](const RowMethod& m) { return SpecOf(m.kind()).adaptive(); }, "adaptive rows"},
        {"substeps", "--substeps", [](const RowMethod& m) { return SpecOf(m.kind()).count == "substeps"; },
         "substepped rows"},
        {"iterations", "--iterations", [](const RowMethod& m) { return SpecOf(m.kind()).count == "iterations"; },
         "iterated rows"},
        {"cg_tolerance", "--cg-tolerance/--cg-tolerances", [](const RowMethod& m) { return m.uses_pcg(); },
         "rows that solve with the PCG"},
        {"preconditioner", "--preconditioner", [](const RowMethod& m) { return m.uses_pcg(); },
         "rows that solve with the PCG"},
        {"nonlinear_solver", "--nonlinear-solver", [](const RowMethod& m) { return m.fully_implicit(); },
         "fully implicit methods"},
        {"tangent_terms", "--tangent-terms", [](const RowMethod& m) { return m.builds_tangent(); },
         "rows that build J_alpha"},
    };
    for (const MethodEntry& e : Registry())
      for (const MethodSetting& setting : e.settings) {
        if (std::any_of(o.begin(), o.end(), [&](const RowOption& r) { return r.field == setting.field; })) continue;
        const std::string field(setting.field);
        o.push_back({field, std::string(setting.option),
                     [field](const RowMethod& m) { return m.setting(field) != nullptr; }, std::string(setting.what)});
      }
    return o;
  }();
  return options;
}

const MethodSetting* FindSetting(std::string_view field) {
  for (const MethodEntry& e : Registry())
    for (const MethodSetting& s : e.settings)
      if (s.field == field) return &s;
  return nullptr;
}

std::string UnusedOption(const std::vector<RowMethod>& rows, const GivenOptions& given) {
  const auto any = [&](auto&& reads) { return std::any_of(rows.begin(), rows.end(), reads); };
  for (const std::string& field : given.fields) {
    const RowOption& o = RowOptionOf(field);
    if (!any(o.reads)) return fmt::format("{}: no row of this run uses it (it applies to {})", o.option, RowsReading(o));
  }
  if (!given.baseline.empty() && !any([&](const RowMethod& m) { return m.label() == given.baseline; })) {
    std::string labels;
    for (const RowMethod& m : rows) labels += (labels.empty() ? "" : ", ") + m.label();
    return fmt::format("--baseline: \"{}\" is not a row of this run ({})", given.baseline, labels);
  }
  return "";
}

void AdoptSceneStepControl(const SolverSpec& spec, std::vector<RowMethod>* rows, bool named, std::string_view option) {
  if (spec.step_control != StepControl::kError) return;
  std::vector<RowMethod> kept;
  for (RowMethod& m : *rows) {
    if (m.entry->error_control) m.error_control = true;
    if (SpecOf(m.kind()).adaptive()) {
      // Default rows: "sbdf2" and "sbdf2/error" are one row here.
      const bool listed = std::any_of(kept.begin(), kept.end(), [&](const RowMethod& k) { return k.label() == m.label(); });
      if (named || !listed) kept.push_back(m);
    } else if (named) {
      throw std::invalid_argument(fmt::format(
          "{}: {} cannot step under the scene's [solver] step_control = \"error\" (it has no error estimate; rows "
          "that have one: {}, and the adaptive {})",
          option, m.label(), MethodNames([](const MethodEntry& e) { return e.error_control; }),
          MethodNames([](const MethodEntry& e) { return SpecOf(e.kind).adaptive(); })));
    }
  }
  *rows = std::move(kept);
}

std::vector<RowMethod> ExpandMethods(const std::vector<std::string>& names, const std::vector<NonlinearSolver>& solvers,
                                     const std::string& option, bool (*runs)(const StepKindSpec&)) {
  std::vector<RowMethod> out;
  for (const std::string& full : names) {
    std::vector<std::string> parts;
    for (std::size_t b = 0;;) {
      const std::size_t e = full.find('/', b);
      parts.push_back(full.substr(b, e == std::string::npos ? std::string::npos : e - b));
      if (e == std::string::npos) break;
      b = e + 1;
    }
    RowMethod r;
    r.entry = FindMethod(parts[0]);
    if (!r.entry)
      throw std::invalid_argument(
          fmt::format("{}: unknown integrator \"{}\" (expected {})", option, full, KnownMethodNames()));
    bool solver_named = false;
    for (std::size_t k = 1; k < parts.size(); ++k) {
      if (r.variant.empty() && std::find(r.entry->variants.begin(), r.entry->variants.end(), parts[k]) !=
                                   r.entry->variants.end()) {
        r.variant = parts[k];
      } else if (parts[k] == "error") {
        if (r.error_control)
          throw std::invalid_argument(fmt::format("{}: \"{}\" names /error twice", option, full));
        if (!r.entry->error_control)
          throw std::invalid_argument(
              fmt::format("{}: \"{}\": only {} run under error control (/error)", option, full,
                          MethodNames([](const MethodEntry& e) { return e.error_control; })));
        r.error_control = true;
      } else if (r.entry->nonlinear_solver) {
        if (solver_named)
          throw std::invalid_argument(fmt::format("{}: \"{}\" names a nonlinear solver twice", option, full));
        r.solver = ParseNonlinearSolver(parts[k], option);
        solver_named = true;
      } else {
        std::string takes;
        for (std::string_view v : r.entry->variants) takes += (takes.empty() ? "" : ", ") + std::string(v);
        if (r.entry->error_control) takes += std::string(takes.empty() ? "" : ", ") + "error";
        throw std::invalid_argument(
            takes.empty() ? fmt::format("{}: \"{}\": {} takes no modifier after '/'", option, full, r.entry->name)
                          : fmt::format("{}: \"{}\": \"{}\" is not a modifier of {} (it takes {})", option, full,
                                        parts[k], r.entry->name, takes));
      }
    }
    if (runs && !runs(SpecOf(r.kind())))
      throw std::invalid_argument(fmt::format("{}: \"{}\" is {}, which this command does not run", option, full,
                                              ToString(r.kind())));
    if (r.fully_implicit() && !solver_named) {
      for (NonlinearSolver s : solvers) {
        r.solver = s;
        out.push_back(r);
      }
    } else {
      out.push_back(r);
    }
  }
  return out;
}

}  // namespace clothbench
