// Stability map cells.
#include "solver/stability_map.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <fmt/format.h>

#include "solver/run.h"

namespace clothbench {

const char* const kStabilityOutcomeCodes =
    "0 bounded, 1 energy_growth, 2 non_finite, 3 cg_failed, 4 no_fixed_point_convergence, 5 fixed_point_diverged, "
    "6 other, 7 no_newton_convergence, 8 newton_diverged, 9 speed, 10 penetration";

Scene StabilityScene(Scene s, int side) {
  const double lu = s.lu(), lv = s.lv();
  s.grid.nu = s.grid.nv = side;
  s.grid.size = {lu * (side - 1), lv * (side - 1)};
  std::vector<int> fixed;
  for (const std::string& spec : s.fixed_specs)
    for (int p : ResolveFixed(spec, side, side, s.source + ": ")) fixed.push_back(p);
  std::sort(fixed.begin(), fixed.end());
  fixed.erase(std::unique(fixed.begin(), fixed.end()), fixed.end());
  s.fixed = fixed;
  s.solver.max_rejections = 0;
  s.solver.max_updates = 30;
  s.solver.cg_max_iterations = 2000;
  s.solver.cg_tolerance = 1e-6;
  return s;
}

StabilityCell RunStabilityCell(Scene scene, Method method, double h, double stiffness, int steps) {
  return RunStabilityCell(
      std::move(scene),
      [method](const ParticleSystem& sys, const SolverSpec& spec) -> std::unique_ptr<Stepper> {
        return std::make_unique<StepEngine>(sys, method, spec);
      },
      h, stiffness, steps);
}

StabilityCell RunStabilityCell(Scene scene, const StepperFactory& make, double h, double stiffness, int steps) {
  const double l = std::max(scene.lu(), scene.lv());
  const double k = stiffness * scene.material.density * l * l / (h * h);
  scene.material.tension = {k, k};
  const ParticleSystem sys(scene);
  const std::unique_ptr<Stepper> stepper = make(sys, scene.solver);
  Stepper& engine = *stepper;
  engine.Reset(0.0, sys.rest_positions(), MatrixN3::Zero(sys.num_particles(), 3));
  const double diag = std::hypot(scene.grid.size[0], scene.grid.size[1]);
  const double e_ref = sys.masses().sum() * scene.forces.gravity.norm() * diag;
  const double e0 = sys.Energies(engine.x(), engine.v()).total();
  ExternalWork external(sys, engine.x(), engine.v());
  // The run's blow-up statuses besides the map's stricter energy bound:
  // speed after every step, penetration at every step's state.
  BlowUpGuard guard(sys, engine.x(), engine.v(), h * steps);
  RunStatus guard_status = RunStatus::kOk;
  std::string guard_message;
  StabilityCell c;
  long updates = 0, cg = 0;
  for (int n = 0; n < steps; ++n) {
    const StepStats st = engine.Step(h);
    updates += st.updates;
    cg += st.cg_iterations;
    if (st.status != StepStatus::kOk) {
      c.outcome = st.status == StepStatus::kNonFinite           ? kNonFinite
                  : st.status == StepStatus::kCgFailed           ? kCgFailed
                  : st.status == StepStatus::kNoFixedPointConvergence ? kNoFixedPoint
                  : st.status == StepStatus::kFixedPointDiverged      ? kFixedPointDiverged
                  : st.status == StepStatus::kNoNewtonConvergence     ? kNoNewton
                  : st.status == StepStatus::kNewtonDiverged          ? kNewtonDiverged
                                                                      : kOtherFailure;
      break;
    }
    ++c.steps;
    const double work = external.Advance(h, engine.t(), engine.x(), engine.v());
    const double excess = (sys.Energies(engine.x(), engine.v()).total() - work - e0) / e_ref;
    if (!std::isfinite(excess)) {
      c.outcome = kNonFinite;
      break;
    }
    c.energy_excess = std::max(c.energy_excess, excess);
    if (excess > 1e-3) {
      c.outcome = kEnergyGrowth;
      break;
    }
    if (!guard.CheckSpeed(engine.t(), engine.v(), &guard_status, &guard_message)) {
      c.outcome = kSpeed;
      break;
    }
    if (!guard.CheckFrame(engine.t(), engine.x(), engine.v(), &guard_status, &guard_message)) {
      c.outcome = guard_status == RunStatus::kPenetration ? kPenetration : kNonFinite;
      break;
    }
  }
  const int attempted = std::max(1, c.steps + (c.outcome == kBounded ? 0 : 1));
  c.updates_per_step = static_cast<double>(updates) / attempted;
  c.cg_per_step = static_cast<double>(cg) / attempted;
  return c;
}

std::string StabilityCellText(const StabilityCell& c) {
  switch (c.outcome) {
    case kBounded: return fmt::format("ok {:.1f}/{:.0f}", c.updates_per_step, c.cg_per_step);
    case kEnergyGrowth: return fmt::format("GROW@{}", c.steps);
    case kNonFinite: return fmt::format("NaN@{}", c.steps);
    case kCgFailed: return fmt::format("CG@{}", c.steps);
    case kNoFixedPoint: return fmt::format("FP@{}", c.steps);
    case kFixedPointDiverged: return fmt::format("FPdiv@{}", c.steps);
    case kNoNewton: return fmt::format("NW@{}", c.steps);
    case kNewtonDiverged: return fmt::format("NWdiv@{}", c.steps);
    case kSpeed: return fmt::format("SPD@{}", c.steps);
    case kPenetration: return fmt::format("PEN@{}", c.steps);
    default: return fmt::format("FAIL@{}", c.steps);
  }
}

}  // namespace clothbench
