#include "harness/table_notes.h"

#include <cctype>
#include <string>

#include <fmt/format.h>

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

}  // namespace

// Why implicit midpoint ends `penetration` at a large h (docs/notes/collisions.md,
// "Implicit midpoint at the obstacles").
constexpr const char* kMidpointPenetration =
    "implicit_midpoint rows, penetration: the contact response prescribes the normal velocity v1 at the step's end, "
    "and the midpoint rule moves a particle by h (v0 + v1)/2, so an entering particle travels h|<v0, D>|/2 past where "
    "the response aims it; once that exceeds twice the collision distance delta (h > 4 delta/|<v0, D>|) it can end "
    "deeper than delta. A property of the method with this response (docs/notes/collisions.md, \"Implicit midpoint at the "
    "obstacles\").";

// Why SBDF(2) and BDF(2) end `penetration` at a large h with the history
// kept (docs/notes/collisions.md, "BDF(2) at the obstacles").
constexpr const char* kMultistepPenetration =
    "sbdf2/bdf2 rows, penetration: with contact_history = \"keep\" (the default) the multistep formula x1 = (4 x0 - "
    "x-1)/3 + 2h v1/3 carries the last step's displacement on, so in the step after an entry a particle moves about "
    "h|<v0, D>|/3 toward the obstacle whatever v1 the response sets, and it can end deeper than the collision "
    "distance delta once h > 6 delta/|<v0, D>|. A property of the method with this response; contact_history = "
    "\"project\" or \"land\" removes it (docs/notes/collisions.md, \"BDF(2) at the obstacles\").";

// Why VBD ends `penetration` at a large h with few sweeps
// (docs/notes/collisions.md, "VBD at the obstacles").
constexpr const char* kVbdPenetration =
    "vbd rows, penetration: the entry test predicts a particle's path from its velocity at the step's start, and a "
    "VBD iterate that is still far from implicit Euler's solution after its few sweeps can move a particle much "
    "faster than that (on the swinging box at h = 0.01 s and 4 sweeps: 7 cm in one step from 1.9 m/s), past the "
    "test; more sweeps or a smaller h end ok. A property of the method's unconverged iterate "
    "(docs/notes/collisions.md, \"VBD at the obstacles\").";

const RunTableNotes& RegistryTableNotes() {
  static const RunTableNotes notes{
      .legend = "h|rtol: the step of fixed-step rows, rtol = atol of adaptive rows (cvode, ida, arkode, */error), "
                "frame step/substeps of substepped rows (xpbd), step x iterations of iterated rows (pd, vbd).",
      .rows = {{"xpbd", "xpbd rows: updates = substeps (one constraint sweep each); constraints: ",
                "explicit forces in the prediction: "},
               {"pd",
                "pd rows: updates = iterations (each projects the springs, evaluates the other forces at the iterate "
                "and solves with A_1's factor, factorised once per h); projected: ",
                "at the iterate: "},
               {"vbd",
                "vbd rows: updates = iterations (each a sweep of one local Newton step per particle, every term "
                "implicit, the colours of the particle graph in sequence)",
                ""}},
      .after_rows = "cvode/ida/arkode rows: steps = nst, updates = Newton iterations (nni), cg_iters = nli (cvode, "
                    "ida, arkode: our PCG's iterations in the reduced velocity solve; cvode/klu, ida/klu: 0, the "
                    "direct KLU solver).",
      .reference = ReferenceLine,
      .statuses = {{"implicit_midpoint", "penetration", kMidpointPenetration},
                   {"implicit_midpoint/newton", "penetration", kMidpointPenetration},
                   {"sbdf2", "penetration", kMultistepPenetration},
                   {"bdf2", "penetration", kMultistepPenetration},
                   {"bdf2/newton", "penetration", kMultistepPenetration},
                   {"vbd", "penetration", kVbdPenetration},
                   {"vbd/chebyshev", "penetration", kVbdPenetration}},
  };
  return notes;
}

}  // namespace clothbench
