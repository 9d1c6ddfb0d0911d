// The table bench_integrators prints, from a RunTable.
#include "results/run_table.h"

#include <algorithm>
#include <cctype>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

namespace clothbench {

const std::vector<SceneField>& SceneRecordFields() {
  using T = RunTable;
  using W = SceneField::When;
  static const std::vector<SceneField> fields = {
      {"name", &T::scene_name},
      {"source", &T::scene_source},
      {"n_particles", &T::n_particles},
      {"n_fixed", &T::n_fixed},
      {"t_end", &T::t_end},
      {"frame_dt", &T::frame_dt},
      {"frames", &T::frames},
      {"explicit_terms", &T::explicit_terms},
      {"h", &T::h},
      {"numerical_stiffness", &T::numerical_stiffness},
      {"solver_cg_tolerance", &T::cg_tolerance},
      {"solver_cg_reference", &T::cg_reference},
      {"solver_preconditioner", &T::preconditioner},
      {"solver_predictor", &T::predictor},
      {"solver_amg_frames", &T::amg_frames, W::kNonEmpty},
      {"solver_max_updates", &T::max_updates},
      {"solver_cholesky_ordering", &T::cholesky_ordering, W::kStepEngine},
      {"solver_contact_factors", &T::contact_factors, W::kStepEngine},
      {"solver_tangent_projection", &T::tangent_projection, W::kStepEngine},
      {"solver_newton_jacobian", &T::newton_jacobian, W::kStepEngine},
      {"solver_contact_history", &T::contact_history, W::kStepEngineNonEmpty},
      {"solver_friction_law", &T::friction_law, W::kStepEngineNonEmpty},
      {"solver_friction_cap", &T::friction_cap, W::kStepEngineNonEmpty},
      {"solver_controller_updates", &T::controller_updates, W::kStepEngine},
      {"solver_cg_max_iterations", &T::cg_max_iterations, W::kStepEngine},
      {"solver_max_rejections", &T::max_rejections, W::kStepEngine},
      {"solver_fixed_point_tolerance", &T::fixed_point_tolerance, W::kStepEngine},
      {"solver_step_factor", &T::step_factor, W::kStepEngine},
      {"solver_h_min", &T::h_min, W::kStepEngine},
      {"solver_h_max", &T::h_max, W::kStepEngine},
  };
  return fields;
}

const std::vector<RecordField>& RunRecordFields() {
  using R = RunRecord;
  using S = Stored;
  static const std::vector<RecordField> fields = {
      {"integrator", &R::integrator},
      {"label", &R::label},
      {"layer", &R::layer},
      {"step_kind", &R::step_kind},
      {"nonlinear_solver", &R::nonlinear_solver, S::kNonEmpty},
      {"rtol", &R::rtol, S::kStepParameter},
      {"h", &R::h, S::kStepParameter},
      {"substeps", &R::substeps, S::kStepCount},
      {"iterations", &R::iterations, S::kStepCount},
      {"tangent_terms", &R::tangent_terms, S::kNonEmpty},
      {"collision_self", &R::collision_self, S::kNonEmpty},
      {"preconditioner", &R::preconditioner, S::kNonEmpty},
      {"step_control", &R::step_control, S::kNonEmpty},
      {"predictor", &R::predictor, S::kNonEmpty},
      {"cg_reference", &R::cg_reference, S::kNonEmpty},
      {"newton_jacobian", &R::newton_jacobian, S::kNonEmpty},
      {"atol", &R::atol, S::kPositive},
      {"threads", &R::threads, S::kPositive},
      {"threads_fewest", &R::threads_fewest, S::kPositive},
      {"error_test_failures", &R::error_test_failures, S::kNonNegative},
      {"status", &R::status},
      {"message", &R::message, S::kNonEmpty},
      {"steps", &R::steps},
      {"fixed_point_updates", &R::updates},
      {"cg_iterations", &R::cg_iterations},
      {"rejected_steps", &R::rejected},
      {"cg_unconverged_steps", &R::cg_unconverged, S::kPositive},
      {"events", &R::events, S::kNonNegative},
      {"solver_time_s", &R::solver_time_s},
      {"repeats", &R::repeats},
      {"solver_time_s_median", &R::solver_time_s_median},
      {"solver_time_s_max", &R::solver_time_s_max},
      {"setup_time_s", &R::setup_time_s, S::kNonNegative},
      {"contact_detection_time_s", &R::contact_detection_time_s, S::kNonNegative},
      {"wall_time_s", &R::wall_time_s},
      {"numerical_stiffness", &R::numerical_stiffness},
      {"cg_tolerance", &R::cg_tolerance, S::kPositive},
      {"energy_gain_ratio", &R::energy_gain_ratio, S::kNonNegative},
      {"speed_ratio", &R::speed_ratio, S::kNonNegative},
      {"penetration_ratio", &R::penetration_ratio, S::kNonNegative},
      {"error_estimate_m", &R::error_estimate_m, S::kNonNegative},
      {"cross_check", &R::cross_check, S::kNonEmpty},
      {"cross_check_error_estimate_m", &R::cross_check_error_estimate_m, S::kNonNegative},
      {"cross_check_difference_m", &R::cross_check_difference_m, S::kNonNegative},
      {"error_final_m", &R::error_final_m, S::kSet, true},
      {"error_l2_m", &R::error_l2_m, S::kSet, true},
      {"error_max_m", &R::error_max_m, S::kSet, true},
      {"error_final_mps", &R::error_final_mps, S::kSet, true},
      {"error_l2_mps", &R::error_l2_mps, S::kSet, true},
      {"error_max_mps", &R::error_max_mps, S::kSet, true},
      {"error_mean_m", &R::error_mean_m, S::kSet, true},
      {"observed_order", &R::observed_order, S::kSet, true},
      {"energy_rate_W", &R::energy_rate_W, S::kSet, true},
      {"contact_power_W", &R::contact_power_W, S::kSet, true},
  };
  return fields;
}
const std::vector<std::string>& SundialsCounterNames() {
  static const std::vector<std::string> names = {"nst", "nfe", "nfe_i", "nni", "nli", "netf", "ncfn", "nje", "nsetups"};
  return names;
}

bool IsMethodAttributeName(const std::string& name) {
  if (name == "error_rms_m") return false;  // files before error_final_m
  for (const RecordField& field : RunRecordFields())
    if (name == field.name) return false;
  const std::vector<std::string>& counters = SundialsCounterNames();
  return std::find(counters.begin(), counters.end(), name) == counters.end();
}

namespace {

std::string Sci(double v) { return fmt::format("{:.3e}", v); }

std::string JoinCommaSpace(const std::string& comma_separated) {
  std::string out;
  for (char c : comma_separated) {
    out += c;
    if (c == ',') out += ' ';
  }
  return out;
}

}  // namespace

// The run table's error column and the equal-accuracy header for an error
// metric ("final", "l2", "max"; results/metrics.h ErrorMetric).
std::string ErrorColumn(const std::string& metric) { return metric == "final" ? "e_rms_m" : "e_" + metric + "_m"; }
std::string ErrorName(const std::string& metric) {
  return metric == "l2" ? "e_l2 (rms over the frames of e_rms)"
         : metric == "max" ? "e_max (max over the frames of e_rms)"
                           : "e_rms(t_end)";
}

void PrintRunTable(std::FILE* out, const RunTable& t, const RunTableNotes& notes) {
  fmt::print(out, "scene {} ({}): N = {} particles, {} fixed, t_end = {:g} s, explicit terms: {}\n", t.scene_name,
             t.scene_source, t.n_particles, t.n_fixed, t.t_end, JoinCommaSpace(t.explicit_terms));
  fmt::print(out,
             "solver: cg_tolerance {:g} ({}), preconditioner {}, max_updates {}, predictor {}, numerical stiffness "
             "h^2 k/(rho l^2) = {:.3g} at h = {:g} s\n",
             t.cg_tolerance, t.cg_reference, t.preconditioner, t.max_updates, t.predictor, t.numerical_stiffness, t.h);
  // Rows whose preconditioner is not the scene's (solver/method_row.h: each
  // method at its best), grouped by preconditioner in row order.
  std::vector<std::pair<std::string, std::vector<std::string>>> other;  // preconditioner, its labels
  for (const RunRecord& r : t.runs) {
    if (r.preconditioner.empty() || r.preconditioner == t.preconditioner) continue;
    auto it = std::find_if(other.begin(), other.end(), [&](const auto& o) { return o.first == r.preconditioner; });
    if (it == other.end()) it = other.insert(other.end(), {r.preconditioner, {}});
    if (std::find(it->second.begin(), it->second.end(), r.label) == it->second.end()) it->second.push_back(r.label);
  }
  for (const auto& [pre, labels] : other)
    fmt::print(out, "preconditioner {} (each method's best, solver/method_row.h) in rows: {}\n", pre,
               fmt::join(labels, ", "));
  // The same for the CG tolerance (a row's own η, not a --cg-tolerances sweep).
  std::vector<std::pair<double, std::vector<std::string>>> other_eta;  // η, its labels
  for (const RunRecord& r : t.runs) {
    if (!(r.cg_tolerance > 0.0) || r.cg_tolerance == t.cg_tolerance || r.label.find(" eta=") != std::string::npos)
      continue;
    auto it = std::find_if(other_eta.begin(), other_eta.end(), [&](const auto& o) { return o.first == r.cg_tolerance; });
    if (it == other_eta.end()) it = other_eta.insert(other_eta.end(), {r.cg_tolerance, {}});
    if (std::find(it->second.begin(), it->second.end(), r.label) == it->second.end()) it->second.push_back(r.label);
  }
  std::vector<std::string> tension_only;  // rows whose J_α leaves out the explicit terms' Jacobians
  for (const RunRecord& r : t.runs)
    if (r.tangent_terms == "tension" && std::find(tension_only.begin(), tension_only.end(), r.label) == tension_only.end())
      tension_only.push_back(r.label);
  if (!tension_only.empty())
    fmt::print(out, "J_alpha of tension and mass only (tangent_terms, solver/method_row.h) in rows: {}\n",
               fmt::join(tension_only, ", "));
  for (const auto& [eta, labels] : other_eta)
    fmt::print(out, "cg_tolerance {:g} (each method's best, solver/method_row.h) in rows: {}\n", eta,
               fmt::join(labels, ", "));
  if (t.reference && notes.reference) fmt::print(out, "{}\n", notes.reference(*t.reference, ErrorName(t.error_metric)));
  else
    fmt::print(out, "reference: none (error columns empty)\n");
  // The contact power column only where a run has one (scenes with obstacles).
  bool contact = false;
  for (const RunRecord& r : t.runs) contact = contact || r.contact_power_W.has_value();
  fmt::print(out, "\n{:<24} {:>10} {:>7} {:>8} {:>9} {:>10} {:>9} {:>8} {:>11} {:>7} {:>11}{}  {}\n", "integrator",
             "h|rtol", "steps", "updates", "cg_iters", "solver_s", "spread", "setup_s", ErrorColumn(t.error_metric),
             "order", "dE/dt_W", contact ? fmt::format(" {:>11}", "P_contact_W") : "", "status");
  std::string last;
  for (const RunRecord& r : t.runs) {
    if (!last.empty() && last != r.label) fmt::print(out, "\n");
    last = r.label;
    const StepKindSpec& kind = SpecOf(r.step_kind);
    std::string hcol = fmt::format("{:g}", kind.adaptive() ? r.rtol : r.h);
    if (kind.counted()) hcol += fmt::format("{}{}", kind.count_separator, r.*kind.count_field);
    const std::string contact_col =
        !contact ? "" : fmt::format(" {:>11}", r.ok() && r.contact_power_W ? Sci(*r.contact_power_W) : "");
    fmt::print(out, "{:<24} {:>10} {:>7} {:>8} {:>9} {:>10.3f} {:>9} {:>8} {:>11} {:>7} {:>11}{}  {}\n", r.label, hcol,
               r.steps, r.updates, r.cg_iterations, r.solver_time_s,
               r.repeats > 1 ? fmt::format("{:.0f}%/{}", 100.0 * r.TimeSpread(), r.repeats) : "",
               r.setup_time_s >= 0 ? fmt::format("{:.3f}", r.setup_time_s) : "",
               r.Error(t.error_metric) ? Sci(*r.Error(t.error_metric)) : "", r.observed_order ? fmt::format("{:.2f}", *r.observed_order) : "",
               r.ok() && r.energy_rate_W ? Sci(*r.energy_rate_W) : "", contact_col, r.status);
    if (r.ok() && r.rejected > 0)
      fmt::print(out, "{:<24} ({} rejected attempts retried with smaller h{})\n", "", r.rejected,
                 r.error_test_failures > 0 ? fmt::format(", {} by the error test", r.error_test_failures) : "");
    if (r.cg_unconverged > 0)
      fmt::print(out, "{:<24} ({} steps kept an unconverged CG solve at the iteration cap)\n", "", r.cg_unconverged);
    if (!r.ok() && !r.message.empty()) fmt::print(out, "{:<24} ({})\n", "", r.message);
  }
  if (!notes.legend.empty()) fmt::print(out, "\n{}\n", notes.legend);
  fmt::print(out,
             "order: observed order between consecutive rows, against h (h/substeps); adaptive rows against their "
             "mean step t_end/steps.\n");
  // The first run of an integrator says what its rows' columns mean.
  for (const RunTableNotes::Row& note : notes.rows)
    for (const RunRecord& r : t.runs)
      if (r.integrator == note.integrator) {
        fmt::print(out, "{}{}", note.text, r.MethodText("constraints"));
        const std::string terms = r.MethodText("explicit_terms");
        if (!note.terms.empty()) fmt::print(out, "; {}{}", note.terms, terms.empty() ? "none" : terms);
        fmt::print(out, ".\n");
        break;
      }
  if (!notes.after_rows.empty()) fmt::print(out, "{}\n", notes.after_rows);
  for (const RunTableNotes::StatusNote& note : notes.statuses)
    if (std::any_of(t.runs.begin(), t.runs.end(),
                    [&](const RunRecord& r) { return r.label == note.integrator && ToString(r.status) == note.status; }))
      fmt::print(out, "{}\n", note.text);
  fmt::print(out,
             "solver_s: the least of the run's timings; spread: (max - min)/min over them / their number (the first "
             "computes the trajectory, the others reproduce it bit for bit).\n");
  fmt::print(out,
             "setup_s: assembly of A_alpha, symbolic analysis and every factorisation / AMG setup of the "
             "preconditioner.\n");
  fmt::print(out,
             "dE/dt_W: (E(t_end) - E(0) - W_ext - W_contact)/t_end, energy gained (> 0) or dissipated (< 0) beyond "
             "external work and the contact response's work.\n");
  if (contact)
    fmt::print(out,
               "P_contact_W: W_contact/t_end, the work of the contact response (constraint impulses and friction; "
               "empty: the method has no contact response of ours).\n");
  fmt::print(out, "machine: {}, {} hardware threads, {}, {} build, commit {}\n", t.host, t.hardware_threads,
             t.compiler, t.build_type, t.git_commit);
}

EqualAccuracyTable WorkPrecisionOf(const std::vector<const RunRecord*>& runs, const std::vector<double>& targets,
                                   const std::string& baseline, std::string_view metric, double reference_error) {
  std::vector<std::string> labels;
  std::vector<std::vector<WorkPoint>> points;
  for (const RunRecord* r : runs) {
    auto it = std::find(labels.begin(), labels.end(), r->label);
    if (it == labels.end()) {
      labels.push_back(r->label);
      points.emplace_back();
      it = labels.end() - 1;
    }
    if (const std::optional<double> e = r->Error(metric); r->ok() && e)
      points[static_cast<std::size_t>(it - labels.begin())].push_back({r->solver_time_s, *e, r->TimeSpread()});
  }
  EqualAccuracyTable t = BuildEqualAccuracyTable(labels, points, targets, baseline);
  t.metric = std::string(metric);
  MarkUnresolvedTargets(&t, reference_error);
  return t;
}

void PrintWorkPrecision(std::FILE* out, const EqualAccuracyTable& t) {
  fmt::print(out,
             "\nEqual accuracy: solver time [s] at {} = target on each method's lower envelope of (error, "
             "time) runs, interpolated log-log between adjacent envelope runs (never extrapolated; '≤': its cheapest "
             "run already meets the target; '- (min e)': no run reaches it, e the smallest error; '- (failed)': no run "
             "ended ok); x = ratio to the baseline {}\n",
             ErrorName(t.metric), t.reference.empty() ? "(none)" : t.reference);
  const auto unresolved = [&](std::size_t j) { return j < t.unresolved.size() && t.unresolved[j]; };
  fmt::print(out, "{:<28}", "method");
  for (std::size_t j = 0; j < t.targets.size(); ++j)
    fmt::print(out, " {:>22}", fmt::format("{} {:g} m{}", t.metric == "final" ? "e_rms" : "e_" + t.metric,
                                           t.targets[j], unresolved(j) ? "*" : ""));
  fmt::print(out, "\n");
  for (std::size_t m = 0; m < t.labels.size(); ++m) {
    fmt::print(out, "{:<28}", t.labels[m]);
    for (std::size_t j = 0; j < t.targets.size(); ++j) {
      std::string cell = m < t.min_error.size() && t.min_error[m] ? fmt::format("- (min {:.1e} m)", *t.min_error[m])
                         : m < t.min_error.size()                ? std::string("- (failed)")
                                                                 : std::string("-");
      if (unresolved(j)) cell = "unresolved*";
      if (t.cost[m][j]) {
        const bool bound = m < t.upper_bound.size() && t.upper_bound[m][j];
        cell = t.ratio[m][j] ? fmt::format("{}{:.3f} s ({:.2f}x)", bound ? "≤ " : "", *t.cost[m][j], *t.ratio[m][j])
                             : fmt::format("{}{:.3f} s", bound ? "≤ " : "", *t.cost[m][j]);
      }
      fmt::print(out, " {:>22}", cell);
    }
    fmt::print(out, "\n");
  }
  fmt::print(out, "{:<28}", "fastest");
  for (std::size_t j = 0; j < t.targets.size(); ++j)
    fmt::print(out, " {:>22}", t.fastest[j] >= 0 ? t.labels[static_cast<std::size_t>(t.fastest[j])] : "-");
  fmt::print(out, "\n");
  // Methods the timings cannot rank against the fastest (within their spread).
  for (std::size_t j = 0; j < t.targets.size() && j < t.tied.size(); ++j) {
    if (t.tied[j].empty()) continue;
    std::vector<std::string> names;
    for (int m : t.tied[j]) names.push_back(t.labels[static_cast<std::size_t>(m)]);
    fmt::print(out, "tied with the fastest at {:g} m (within the timing spread): {}\n", t.targets[j],
               fmt::join(names, ", "));
  }
  if (!t.stop_reasons.empty()) {
    fmt::print(out, "sweep to the targets, why each method stopped:\n");
    for (const std::string& r : t.stop_reasons) fmt::print(out, "  {}\n", r);
  }
  if (std::any_of(t.unresolved.begin(), t.unresolved.end(), [](bool u) { return u; }))
    fmt::print(out, "*: below {:g}x the reference's error estimate ({:.1e} m): the reference cannot rank the methods "
               "there, so no cost is given\n", kResolvedFactor, t.reference_error_m);
}

}  // namespace clothbench
