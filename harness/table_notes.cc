#include "harness/table_notes.h"

#include <cctype>
#include <string>

#include <fmt/format.h>

#include "harness/methods.h"

namespace clothbench {
namespace {

// "cvode" -> "CVODE": the SUNDIALS package's own spelling.
std::string Upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

// An obstacle scene's cross-check of the event-located reference
// (RunRecord::cross_check), or "" without one.
std::string CrossCheckLine(const RunRecord& ref, const std::string& error_name) {
  if (ref.cross_check.empty()) return "";
  const auto m = [](double v) { return v >= 0.0 ? fmt::format("{:.3e} m", v) : std::string("-"); };
  std::string verdict;
  if (ref.cross_check_difference_m >= 0.0 && ref.cross_check_error_estimate_m >= 0.0 && ref.error_estimate_m >= 0.0)
    verdict = ref.cross_check_difference_m <= ref.cross_check_error_estimate_m + ref.error_estimate_m
                  ? ", within the sum of the estimates"
                  : ", more than the sum of the estimates (docs/notes/collisions.md, \"The contact reference\")";
  return fmt::format("\ncross-check: {} {}, its own estimate {}; {} between the two references: {}{}",
                     "BDF(2) with the thesis' response at", ref.cross_check, m(ref.cross_check_error_estimate_m),
                     error_name, m(ref.cross_check_difference_m), verdict);
}

std::string ReferenceLine(const RunRecord& ref, const std::string& error_name) {
  if (IsSelfConvergence(ref))
    return fmt::format(
        "reference: self-convergence, BDF(2) at h = {:g} s (h_min/32), cg_tolerance 1e-10, fixed-point tolerance "
        "1e-12 m/s ({}): {} steps, {:.2f} s; its self-convergence: e_l2 against BDF(2) at 2h = {}",
        ref.h,
        ref.collision_self == "on"
            ? "the scene has self-contact, which the SUNDIALS rows take as a correction between steps, not as located events"
            : "the scene has virtual particles, whose edge contacts the event-located SUNDIALS rows do not have",
        ref.steps, ref.wall_time_s,
        ref.error_estimate_m >= 0.0 ? fmt::format("{:.3e} m", ref.error_estimate_m) : "-");
  return fmt::format(
      "reference: {} BDF/Newton, {}, rtol = atol = {:g}: {} steps, {:.2f} s{}, dE/dt = {}; its error estimate: {} "
      "against rtol/10 = {}",
      Upper(ref.integrator),
      ref.label.find("/klu") != std::string::npos
          ? std::string("KLU on the first-order Jacobian")
          : fmt::format("the reduced velocity solve ({} PCG)",
                        ref.preconditioner.empty() ? std::string("-") : ref.preconditioner),
      ref.rtol, ref.steps, ref.wall_time_s,
      ref.cross_check.empty() ? std::string()
                              : fmt::format(" (beside its checks, {} kernel thread{})", ref.threads, ref.threads == 1 ? "" : "s"),
      ref.energy_rate_W ? fmt::format("{:.3e} W", *ref.energy_rate_W) : "-",
      error_name, ref.error_estimate_m >= 0.0 ? fmt::format("{:.3e} m", ref.error_estimate_m) : "-") +
         CrossCheckLine(ref, error_name);
}

// The methods of step kind `kind`, "cvode, ida, arkode", in registry order;
// for adaptive rows also "*/error" if a method runs under error control.
std::string NamesOf(StepKind kind) {
  std::string names = MethodNames([kind](const MethodEntry& e) { return e.kind == kind; });
  const bool error_rows = !MethodNames([](const MethodEntry& e) { return e.error_control; }).empty();
  if (kind == ToleranceKind() && error_rows) names += (names.empty() ? "" : ", ") + std::string("*/error");
  return names;
}

// "h|rtol: " and each step kind's words from its record (StepKindSpec::legend),
// with its methods after all but the plain step sizes.
std::string Legend() {
  std::string legend = "h|rtol:";
  for (std::size_t k = 0; k < std::size(kAllStepKinds); ++k) {
    const StepKindSpec& spec = SpecOf(kAllStepKinds[k]);
    legend += fmt::format("{} {}", k == 0 ? "" : ",", spec.legend);
    if (!spec.plain()) legend += " (" + NamesOf(spec.kind) + ")";
  }
  return legend + ".";
}

}  // namespace

const RunTableNotes& RegistryTableNotes() {
  static const RunTableNotes notes = [] {
    RunTableNotes n{
      .legend = Legend(),
      .rows = {},
      .after_rows = std::string(kSundialsCountsNote),
      .reference = ReferenceLine,
      .statuses = {},
    };
    // Each method's own notes (MethodEntry::table_note, status_notes), in registry order.
    for (const MethodEntry& e : Registry()) {
      if (!e.table_note.empty())
        n.rows.push_back({std::string(e.name), std::string(e.table_note), std::string(e.table_note_terms)});
      for (const StatusNote& note : e.status_notes)
        n.statuses.push_back({std::string(note.label), std::string(note.status), std::string(note.text)});
    }
    return n;
  }();
  return notes;
}

}  // namespace clothbench
