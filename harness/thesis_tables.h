// The thesis' Tables 3.1 and 3.2 run beside ours, and the self-convergence
// reference of obstacle scenes.
#ifndef CLOTHBENCH_HARNESS_THESIS_TABLES_H_
#define CLOTHBENCH_HARNESS_THESIS_TABLES_H_

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "harness/sweep.h"
#include "model/scene.h"
#include "results/metrics.h"
#include "solver/run.h"

namespace clothbench {

class SideBySide;  // harness/side_by_side.h

/// A tight self-convergence run for obstacle scenes: the reference with
/// virtual particles and of the thesis' tables, the cross-check of the
/// event-located reference otherwise (docs/notes/collisions.md, "The contact
/// reference"). BDF(2) at `h_ref` [s] with CG tolerance 1e-10, fixed-point
/// tolerance `fixed_point_tolerance` [m/s] (max |Δv| of the last update) and
/// up to 200 updates per step, the scene's predictor.
RunSummary SelfConvergenceReference(const Scene& scene, double h_ref, double fixed_point_tolerance = 1e-12);

/// The cross-check's fixed-point tolerance [m/s]. A step's velocities then
/// differ from the exact fixed point by about 1e-9 m/s, its positions by h
/// times that, which adds up to about t_end · 1e-9 m over a run: a
/// hundredth of the smallest estimate measured (7e-7 m, docs/notes/collisions.md).
/// At 10⁴ particles it halves the updates per step against 1e-12 m/s.
inline constexpr double kCrossCheckFixedPointTolerance = 1e-9;

/// The cross-check of an event-located contact reference (docs/notes/collisions.md,
/// "The contact reference"): SelfConvergenceReference with the friction law
/// of the contact problem in continuous time (FrictionLaw::kRegularised;
/// the thesis' explicit law converges to another one), the extrapolating
/// predictor (thesis (3.32)) and fixed-point tolerance 1e-9 m/s
/// (kCrossCheckFixedPointTolerance), and its error
/// estimate (RunSummary::error_estimate_m [m]) by Richardson extrapolation
/// with the observed order: with d₁ = E(x_h, x_2h) and d₂ = E(x_2h, x_4h) in
/// `metric`, the observed order is p = log2(d₂/d₁) and the error of x_h
/// at most F_s d₁/(2^q − 1) with q = min(p, 1) and F_s = 1.25, the Grid
/// Convergence Index of a three-grid study (Roache, *Verification and
/// Validation in Computational Science and Engineering*, 1998, §5.4, with
/// the order capped at the contact response's first, docs/notes/collisions.md
/// "Orders with contacts": on the round table an accidental p = 4.4 at
/// h/32 estimated a tenth of the error). With d₂ ≤ d₁, or p > 3 (BDF(2)'s
/// formal order plus one), the runs are not in their asymptotic range and
/// the estimate is unknown.
/// It runs at 32 h_floor, 16 h_floor, … and stops at the first h whose
/// estimate is at most `wanted` [m], or at h_floor [s]; the returned run is
/// the last, with its estimate (−1 if unknown) and *order = p (NaN if
/// unknown). Each run costs half the next, so the refinement costs at most
/// twice the last run. A finer run that fails ends the refinement: the
/// last ok run is returned, its `message` naming the failed h and status.
/// @param started called with each run's h before it is waited for (progress), or empty
/// @param side the runs go to its workers (each level queued at once, those
///   not needed cancelled), or without it one after the other on this thread
/// @param queued called once the levels are queued (to queue other runs
///   behind them), or empty
RunSummary ContactCrossCheck(const Scene& scene, double h_floor, double wanted, ErrorMetric metric, double* order,
                             const std::function<void(double h)>& started = {}, SideBySide* side = nullptr,
                             const std::function<void()>& queued = {});

/// Runs the thesis' Table 3.1 or 3.2 (`which` = "3.1" | "3.2") once per CG
/// tolerance in `etas`, prints it beside the thesis' numbers and writes
/// `out` (default out/table_3_1.h5 or out/table_3_2.h5); rows dealt over
/// the ranks of `comm`. @return the exit status
/// @throws UsageError if `which` is neither
int RunThesisTable(const std::string& which, std::string out, std::optional<PreconditionerType> preconditioner,
                   std::vector<NonlinearSolver> solvers, std::vector<double> etas, SweepComm& comm);

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_THESIS_TABLES_H_
