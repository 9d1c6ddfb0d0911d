// The reference of a sweep, in one place (docs/notes/work-precision.md, "The
// reference"; docs/notes/collisions.md, "The contact reference"): which run
// it is on a scene (the reference row, or the self-convergence run with
// self-contact, virtual particles or moving fixed particles), the row a
// name gives, the run with its error estimate, the tight self-convergence
// run and the cross-check of an event-located contact reference. Every door
// (bench_integrators, --table, clothbench.reference()) takes it from here.
#ifndef CLOTHBENCH_HARNESS_REFERENCE_H_
#define CLOTHBENCH_HARNESS_REFERENCE_H_

#include <functional>
#include <string>
#include <vector>

#include "harness/methods.h"
#include "model/particle_system.h"
#include "model/scene.h"
#include "results/metrics.h"
#include "solver/run.h"

namespace clothbench {

/// The reference row a name gives (--reference, clothbench.reference()):
/// "cvode" or "ida" (the reduced velocity solve with the PCG), "cvode/klu" or
/// "ida/klu" (KLU on the first-order Jacobian).
/// @throws std::invalid_argument naming `option` for any other name
RowMethod ParseReference(const std::string& name, const std::string& option);

/// Sets ref->error_estimate_m to the error `metric` between the reference
/// and `other`, the same method at a 10× tighter rtol or twice the step
/// (left −1 if `other` failed or the frames do not pair) [m].
void SetReferenceErrorEstimate(RunSummary* ref, const RunSummary& other, ErrorMetric metric);

/// The reference run (docs/notes/work-precision.md, "The reference"): `row` at
/// rtol = atol = `rtol`, run as the row of that label is (RowMethod::Run: its
/// best preconditioner, the context's limits), and its error estimate:
/// the same row at rtol/10, and error_estimate_m the error `metric` of the
/// reference against it [m] (−1 if that run fails or reaches no frame
/// pairing). Both doors (bench_integrators --reference,
/// clothbench.reference()) call this.
/// @param started called with the rtol before each of the two runs (progress)
RunSummary RunReference(const ParticleSystem& sys, const Scene& scene, const RowMethod& row, double rtol,
                               const RunContext& ctx, ErrorMetric metric,
                               const std::function<void(double rtol)>& started = {});

/// Whether a scene's reference is the self-convergence run: with virtual
/// particles, whose edge contacts the hybrid system of the SUNDIALS rows
/// does not have (sundials/hybrid_contact.h), with self-contact, which it
/// takes as a correction between steps (the fixed-step methods' response),
/// not as located events, and with moving fixed particles, which its
/// right-hand side holds at rest. Otherwise the reference row (CVODE's
/// event-located contact) is the reference.
bool SelfConvergenceIsReference(const ParticleSystem& sys);

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

/// What a sweep's reference is computed from.
struct ReferenceTask {
  const Scene* scene = nullptr;     ///< the scene (its t_end, solver settings)
  const RowMethod* row = nullptr;   ///< the reference row (ParseReference)
  double rtol = 1e-10;              ///< its rtol = atol
  double h_ref = 0.0;               ///< the self-convergence run's step [s]
  double time_limit_s = 0.0;        ///< > 0: the reference's own --time-limit [s]
  ErrorMetric metric = ErrorMetric::kFinal;
  std::vector<double> targets;      ///< the sweep's e_rms targets [m]
  /// Progress: called with what starts and the run's t_end [s], or empty.
  std::function<void(const std::string& what, double t_end)> started;
};

/// The reference of a sweep (the journal's task 0). With self-contact,
/// virtual particles or moving fixed particles (SelfConvergenceIsReference):
/// the self-convergence run at h_ref with its error against the same at
/// 2 h_ref. Without obstacles: RunReference. With obstacles: the reference
/// row, its run at rtol/10 and the cross-check's refinements
/// (ContactCrossCheck, until its estimate resolves a tenth of the smallest
/// target, down to h_ref) side by side on two workers of one kernel thread
/// each; the cross-check's settings, difference and estimate are stored
/// with the reference (RunRecord::cross_check, …).
RunSummary ComputeReference(const ReferenceTask& task, const ParticleSystem& sys, const RunContext& ctx);

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_REFERENCE_H_
