// The reference of a sweep (harness/reference.h).
#include "harness/reference.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>

#include <fmt/format.h>

#include "harness/side_by_side.h"

namespace clothbench {

RowMethod ParseReference(const std::string& name, const std::string& option) {
  std::vector<RowMethod> rows;
  try {
    rows = ExpandMethods({name}, {NonlinearSolver::kFixedPoint}, option, [](const StepKindSpec& k) { return k.adaptive(); });
  } catch (const std::invalid_argument&) {
    rows.clear();
  }
  if (rows.size() != 1 || !rows[0].entry->reference || rows[0].error_control)
    throw std::invalid_argument(fmt::format("{}: \"{}\" must be {}", option, name, ReferenceNames()));
  return rows[0];
}

void SetReferenceErrorEstimate(RunSummary* ref, const RunSummary& other, ErrorMetric metric) {
  const std::optional<TrajectoryErrors> e =
      other.ok() ? CompareTrajectories(other.trajectory, ref->trajectory) : std::nullopt;
  if (e && std::isfinite(e->Of(metric))) ref->error_estimate_m = e->Of(metric);
}

RunSummary RunReference(const ParticleSystem& sys, const Scene& scene, const RowMethod& row, double rtol,
                        const RunContext& ctx, ErrorMetric metric, const std::function<void(double rtol)>& started) {
  if (started) started(rtol);
  RunSummary ref = row.Run(sys, scene, scene.solver, rtol, ctx);
  if (!ref.ok()) return ref;
  if (started) started(0.1 * rtol);
  SetReferenceErrorEstimate(&ref, row.Run(sys, scene, scene.solver, 0.1 * rtol, ctx), metric);
  return ref;
}

bool SelfConvergenceIsReference(const ParticleSystem& sys) {
  const auto& collision = sys.scene().collision;
  return (collision && collision->self) || sys.has_prescribed_motion() ||
         std::any_of(sys.obstacles().begin(), sys.obstacles().end(),
                     [](const Obstacle& o) { return o.spec().virtual_particles; });
}

// A tight self-convergence run for obstacle scenes (reference.h):
// BDF(2) at h_ref with CG tolerance 1e-10, the given fixed-point tolerance
// and up to 200 updates per step.
RunSummary SelfConvergenceReference(const Scene& scene, double h_ref, double fixed_point_tolerance) {
  Scene tight = scene;
  tight.solver.cg_tolerance = 1e-10;
  tight.solver.fixed_point_tolerance = fixed_point_tolerance;
  tight.solver.max_updates = 200;
  const ParticleSystem tight_sys(tight);
  const MethodEntry& method = SelfConvergenceMethod();
  const std::unique_ptr<Stepper> stepper = method.make(tight_sys, tight.solver, 1, "");
  RunSummary r = RunStepper(tight_sys, *stepper, {h_ref, scene.t_end, scene.frame_dt});
  r.integrator = r.label = std::string(method.name) + "_self_convergence";
  if (scene.collision) r.collision_self = scene.collision->self ? "on" : "off";
  r.layer = std::string(method.layer);
  r.step_kind = method.kind;
  r.h = h_ref;
  r.cg_tolerance = tight.solver.cg_tolerance;
  return r;
}

RunSummary ContactCrossCheck(const Scene& scene, double h_floor, double wanted, ErrorMetric metric, double* order,
                             const std::function<void(double h)>& started, SideBySide* side,
                             const std::function<void()>& queued) {
  Scene regularised = scene;
  regularised.solver.friction_law = FrictionLaw::kRegularised;
  regularised.solver.predictor = Predictor::kExtrapolate;
  *order = std::numeric_limits<double>::quiet_NaN();
  constexpr int kRefinements = 5;  // from 32 h_floor
  constexpr double kMaxObservedOrder = 3.0, kSafetyFactor = 1.25;
  const auto h_of = [&](int j) { return std::ldexp(h_floor, kRefinements - j); };
  // Every refinement is queued at once: with workers, the next runs while
  // this one is judged, and what is not needed is cancelled.
  SideBySide here(0);
  SideBySide& pool = side ? *side : here;
  std::size_t first = 0;
  for (int j = 0; j <= kRefinements; ++j) {
    const std::size_t i = pool.Submit(
        [&regularised, h = h_of(j)] { return SelfConvergenceReference(regularised, h, kCrossCheckFixedPointTolerance); });
    if (j == 0) first = i;
  }
  if (queued) queued();
  // On every way out (an exception too) the runs not needed are cancelled
  // and waited for: they read `regularised`.
  struct Drain {
    SideBySide& pool;
    std::size_t from, end;
    ~Drain() {
      pool.Cancel(from, end);
      for (std::size_t k = from; k < end; ++k) try {
          (void)pool.Take(k);
        } catch (...) {  // the first exception is already on its way
        }
    }
  } drain{pool, first, first + kRefinements + 1};
  RunSummary runs[3];              // x_4h, x_2h, x_h of the last three
  for (int j = 0; j <= kRefinements; ++j) {
    const double h = h_of(j);
    if (started) started(h);
    RunSummary run = pool.Take(first + static_cast<std::size_t>(j));
    drain.from = first + static_cast<std::size_t>(j) + 1;
    if (!run.ok()) {
      if (j < 1) return run;
      // The last ok run stands, with what stopped the refinement.
      runs[2].message = fmt::format("the run at h = {:g} s ended {}", h, ToString(run.status));
      return std::move(runs[2]);
    }
    runs[0] = std::move(runs[1]);
    runs[1] = std::move(runs[2]);
    runs[2] = std::move(run);
    if (j < 2) continue;
    const std::optional<TrajectoryErrors> e1 = CompareTrajectories(runs[1].trajectory, runs[2].trajectory);
    const std::optional<TrajectoryErrors> e2 = CompareTrajectories(runs[0].trajectory, runs[1].trajectory);
    const double d1 = e1 ? e1->Of(metric) : -1.0, d2 = e2 ? e2->Of(metric) : -1.0;
    runs[2].error_estimate_m = -1.0;
    *order = std::numeric_limits<double>::quiet_NaN();
    if (std::isfinite(d1) && std::isfinite(d2) && d1 >= 0.0 && d2 > d1) {
      *order = std::log2(d2 / d1);
      // An observed order above BDF(2)'s formal order by more than one is
      // the pre-asymptotic range: no estimate, refine (at 10⁴ particles
      // p = 8.2 at h/64 gave d₁ = 1.9e-7 m for an error of 7.7e-6 m). Below
      // it the order is capped at the response's first, and the estimate
      // carries Roache's safety factor of a three-grid study (GCI, F_s = 1.25).
      if (*order > kMaxObservedOrder) continue;
      runs[2].error_estimate_m = kSafetyFactor * (*order >= 1.0 ? d1 : d1 * d1 / (d2 - d1));
      if (runs[2].error_estimate_m <= wanted) break;
    }
  }
  return std::move(runs[2]);
}

namespace {

void Start(const ReferenceTask& t, const std::string& what) {
  if (t.started) t.started(what, t.scene->t_end);
}

// The self-convergence run at h_ref with its own error against the same at
// 2 h_ref (RunRecord::error_estimate_m).
RunSummary SelfConvergenceRun(const ReferenceTask& t) {
  Start(t, fmt::format("reference {} h = {:g} s", SelfConvergenceMethod().name, t.h_ref));
  RunSummary r = SelfConvergenceReference(*t.scene, t.h_ref);
  if (r.ok()) {
    Start(t, fmt::format("reference {} h = {:g} s (self-convergence)", SelfConvergenceMethod().name, 2.0 * t.h_ref));
    SetReferenceErrorEstimate(&r, SelfConvergenceReference(*t.scene, 2.0 * t.h_ref), t.metric);
  }
  return r;
}

// The reference run (task 0): RunReference (the reference row and its
// error estimate at rtol/10). On obstacle scenes the row integrates the
// contact problem in continuous time with event location, and the
// self-convergence run at h_ref is its cross-check (their difference and
// its estimate are stored with the reference); with virtual particles the
// self-convergence run is the reference. With obstacles the reference,
// its estimate run and the cross-check's refinements run side by side on
// kCheckWorkers threads of one kernel thread each: on
// scenes/round_table_10k.toml they took 5 min 20 s, against 7 min 30 s one
// after the other on two kernel threads (docs/notes/collisions.md).
constexpr int kCheckWorkers = 2;

}  // namespace

RunSummary ComputeReference(const ReferenceTask& t, const ParticleSystem& sys, const RunContext& ctx) {
  if (SelfConvergenceIsReference(sys)) return SelfConvergenceRun(t);
  const Scene& scene = *t.scene;
  const RowMethod& row = *t.row;
  RunContext reference_ctx = ctx;
  if (t.time_limit_s > 0.0) reference_ctx.limits.time_limit_s = t.time_limit_s;
  const auto started = [&](double rtol) {
    Start(t, fmt::format("reference {} rtol {:g}{}", row.label(), rtol, rtol < t.rtol ? " (its error estimate)" : ""));
  };
  if (sys.obstacles().empty())
    return RunReference(sys, scene, row, t.rtol, reference_ctx, t.metric, started);
  // With obstacles the reference, its run at rtol/10 and the cross-check's
  // refinement run side by side (harness/side_by_side.h), each on one
  // kernel thread: no table times them, and none needs another's result.
  // Each has its own copy of the model (its terms keep scratch), made
  // before the workers: it outlives them (their destructor cancels and
  // joins a run still going when the reference fails).
  const ParticleSystem estimate_sys(scene);
  SideBySide checks(kCheckWorkers);
  // In the order reference, cross-check refinements, estimate: the
  // refinements are the longest chain (the last alone about twice the
  // reference at 10⁴ particles), the estimate is needed only at the end.
  const std::size_t reference = checks.Submit(
      [&] { return row.Run(sys, scene, scene.solver, t.rtol, reference_ctx); });
  std::size_t estimate = 0;
  const auto queue_estimate = [&] {
    estimate = checks.Submit(
        [&] { return row.Run(estimate_sys, scene, scene.solver, 0.1 * t.rtol, reference_ctx); });
  };
  double order = 0.0;
  // It refines until its estimate resolves the smallest target as the
  // reference must (a tenth of it), down to h_ref.
  const double wanted = t.targets.empty() ? 0.0 : 0.1 * *std::min_element(t.targets.begin(), t.targets.end());
  const auto label = [&](const std::string& what) {
    Start(t, fmt::format("{} (side by side: reference {} rtol {:g} and {:g}, cross-check {})", what, row.label(),
                         t.rtol, 0.1 * t.rtol, SelfConvergenceMethod().name));
  };
  const RunSummary c = ContactCrossCheck(
      scene, t.h_ref, wanted, t.metric, &order,
      [&](double h) { label(fmt::format("cross-check h = {:g} s", h)); }, &checks, queue_estimate);
  label("reference");
  RunSummary r = checks.Take(reference);
  if (!r.ok()) return r;
  label("reference estimate");
  SetReferenceErrorEstimate(&r, checks.Take(estimate), t.metric);
  r.cross_check = fmt::format("{} h = {:g} s, friction_law = regularised, predictor = extrapolate, "
                              "fixed_point_tolerance = {:g} m/s, 1 kernel thread (self-convergence against 2h and 4h{}{})",
                              SelfConvergenceMethod().name, c.h, kCrossCheckFixedPointTolerance,
                              !c.ok()              ? fmt::format(": {}", ToString(c.status))
                              : std::isnan(order) ? ": not in its asymptotic range"
                              : c.error_estimate_m < 0.0
                                  ? fmt::format(", observed order {:.2f}: not in its asymptotic range", order)
                                  : fmt::format(", observed order {:.2f}", order),
                              c.ok() && !c.message.empty() ? "; " + c.message : std::string());
  if (!c.ok()) return r;
  r.cross_check_error_estimate_m = c.error_estimate_m;
  if (const std::optional<TrajectoryErrors> e = CompareTrajectories(c.trajectory, r.trajectory);
      e && std::isfinite(e->Of(t.metric)))
    r.cross_check_difference_m = e->Of(t.metric);
  return r;
}

}  // namespace clothbench
