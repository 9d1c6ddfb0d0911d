// How a run ended and how its row is parameterised: the two enumerations a
// RunRecord carries from the step loop (solver/, sundials/, peers/) to the
// result file (results/) and the entry points (harness/, python/). They are
// turned into text only where a record is written, printed or read
// (docs/guide/results-schema.md, /runs/<id> attributes `status` and `step_kind`).
#ifndef CLOTHBENCH_SOLVER_RECORD_RUN_STATUS_H_
#define CLOTHBENCH_SOLVER_RECORD_RUN_STATUS_H_

#include <optional>
#include <ostream>
#include <string_view>

#include <fmt/format.h>

namespace clothbench {

/// How a method's rows are parameterised: a list of step sizes h, a list of
/// tolerances rtol, frame steps h each split into substeps, or steps h each
/// with a fixed number of iterations (projective dynamics, VBD).
enum class StepKind { kFixedStep, kAdaptive, kSubstepped, kIterated };

/// "fixed_step", "adaptive", "substepped", "iterated".
std::string_view ToString(StepKind k);
/// The kind named by ToString's text; nullopt for any other text.
std::optional<StepKind> ParseStepKind(std::string_view text);

/// Where a run stopped (docs/guide/results-schema.md, `status`; docs/model.md,
/// "Blow-up statuses"). kOk: it reached t_end. Step failures: the step
/// engine's StepStatus (solver/integrator.h) of the attempt that could not
/// be retried; SUNDIALS' error-test and convergence failures map to
/// kErrorTestFailed and kNoNewtonConvergence, its other failures to
/// kSolverFailed (the message names the flag). Blow-ups: the guard of
/// solver/run.h. Limits: --time-limit (or an interrupt's deadline) and the
/// step budget. kInvalidOptions, kUnsupportedScene: refused before the
/// first step; kNotRun: a record that no run has filled.
enum class RunStatus {
  kOk,
  kNotRun,
  kInvalidOptions,
  kUnsupportedScene,
  kCgFailed,
  kNoFixedPointConvergence,
  kFixedPointDiverged,
  kNoNewtonConvergence,
  kNewtonDiverged,
  kPreconditionerFailed,
  kErrorTestFailed,
  kSolverFailed,
  kNonFinite,
  kEnergyGrowth,
  kSpeed,
  kPenetration,
  kTimeLimit,
  kStepLimit,
  kSelfIntersection,  ///< a stored frame of a run with self-contact has crossing triangle pairs
  kTunnelled,         ///< a particle's path over a step passed through an obstacle
  kNotStarted,        ///< predicted past the time limit or the memory before any computing (last: journals store the number)
};

/// The stored text: "ok", "cg_failed", "energy_growth", … (snake case of the name).
std::string_view ToString(RunStatus s);
/// The status named by ToString's text, or by a SUNDIALS return flag name
/// ("CV_ERR_FAILURE" → kErrorTestFailed, "…_CONV_FAILURE" →
/// kNoNewtonConvergence, "…_TOO_MUCH_WORK" → kStepLimit, any other "CV_",
/// "IDA_" or "ARK_" flag → kSolverFailed); nullopt for any other text.
std::optional<RunStatus> ParseRunStatus(std::string_view text);

/// Streams print the stored text (test failure messages).
inline std::ostream& operator<<(std::ostream& os, StepKind k) { return os << ToString(k); }
inline std::ostream& operator<<(std::ostream& os, RunStatus s) { return os << ToString(s); }

}  // namespace clothbench

/// fmt prints both enumerations as their stored text.
template <>
struct fmt::formatter<clothbench::StepKind> : fmt::formatter<std::string_view> {
  template <class Context>
  auto format(clothbench::StepKind k, Context& ctx) const {
    return fmt::formatter<std::string_view>::format(clothbench::ToString(k), ctx);
  }
};
template <>
struct fmt::formatter<clothbench::RunStatus> : fmt::formatter<std::string_view> {
  template <class Context>
  auto format(clothbench::RunStatus s, Context& ctx) const {
    return fmt::formatter<std::string_view>::format(clothbench::ToString(s), ctx);
  }
};

#endif  // CLOTHBENCH_SOLVER_RECORD_RUN_STATUS_H_
