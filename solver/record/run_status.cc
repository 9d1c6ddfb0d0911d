#include "solver/record/run_status.h"

#include <array>
#include <utility>

namespace clothbench {
namespace {

constexpr std::array<std::pair<StepKind, std::string_view>, 4> kStepKinds{{
    {StepKind::kFixedStep, "fixed_step"},
    {StepKind::kAdaptive, "adaptive"},
    {StepKind::kSubstepped, "substepped"},
    {StepKind::kIterated, "iterated"},
}};

constexpr std::array<std::pair<RunStatus, std::string_view>, 21> kRunStatuses{{
    {RunStatus::kOk, "ok"},
    {RunStatus::kNotRun, "not_run"},
    {RunStatus::kInvalidOptions, "invalid_options"},
    {RunStatus::kUnsupportedScene, "unsupported_scene"},
    {RunStatus::kCgFailed, "cg_failed"},
    {RunStatus::kNoFixedPointConvergence, "no_fixed_point_convergence"},
    {RunStatus::kFixedPointDiverged, "fixed_point_diverged"},
    {RunStatus::kNoNewtonConvergence, "no_newton_convergence"},
    {RunStatus::kNewtonDiverged, "newton_diverged"},
    {RunStatus::kPreconditionerFailed, "preconditioner_failed"},
    {RunStatus::kErrorTestFailed, "error_test_failed"},
    {RunStatus::kSolverFailed, "solver_failed"},
    {RunStatus::kNonFinite, "non_finite"},
    {RunStatus::kEnergyGrowth, "energy_growth"},
    {RunStatus::kSpeed, "speed"},
    {RunStatus::kPenetration, "penetration"},
    {RunStatus::kTimeLimit, "time_limit"},
    {RunStatus::kStepLimit, "step_limit"},
    {RunStatus::kSelfIntersection, "self_intersection"},
    {RunStatus::kTunnelled, "tunnelled"},
    {RunStatus::kNotStarted, "not_started"},
}};

template <class E, std::size_t N>
std::string_view Text(const std::array<std::pair<E, std::string_view>, N>& table, E e) {
  for (const auto& [value, text] : table)
    if (value == e) return text;
  return "?";
}

template <class E, std::size_t N>
std::optional<E> Parse(const std::array<std::pair<E, std::string_view>, N>& table, std::string_view text) {
  for (const auto& [value, name] : table)
    if (name == text) return value;
  return std::nullopt;
}

}  // namespace

std::string_view ToString(StepKind k) { return Text(kStepKinds, k); }
std::optional<StepKind> ParseStepKind(std::string_view text) { return Parse(kStepKinds, text); }
std::string_view ToString(RunStatus s) { return Text(kRunStatuses, s); }
std::optional<RunStatus> ParseRunStatus(std::string_view text) {
  if (const std::optional<RunStatus> s = Parse(kRunStatuses, text)) return s;
  // A SUNDIALS return flag name (CVodeGetReturnFlagName, IDA…, ARKStep…):
  // "CV_ERR_FAILURE", "IDA_CONV_FAILURE", "ARK_TOO_MUCH_WORK", ….
  const auto ends = [&](std::string_view suffix) {
    return text.size() > suffix.size() && text.substr(text.size() - suffix.size()) == suffix;
  };
  const bool flag = text.rfind("CV_", 0) == 0 || text.rfind("IDA_", 0) == 0 || text.rfind("ARK_", 0) == 0;
  if (!flag) return std::nullopt;
  if (ends("_ERR_FAILURE")) return RunStatus::kErrorTestFailed;
  if (ends("_CONV_FAILURE")) return RunStatus::kNoNewtonConvergence;
  if (ends("_TOO_MUCH_WORK")) return RunStatus::kStepLimit;
  return RunStatus::kSolverFailed;
}

}  // namespace clothbench
