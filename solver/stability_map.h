// Stability map cells (thesis §3.4.4): one integrator at one
// step size h and one numerical stiffness S = h²k/(ρl²), run from rest for a
// fixed number of steps with no retries.
#ifndef CLOTHBENCH_SOLVER_STABILITY_MAP_H_
#define CLOTHBENCH_SOLVER_STABILITY_MAP_H_

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "solver/integrator.h"

namespace clothbench {

/// What happened in a cell.
enum StabilityOutcome : int32_t {
  kBounded = 0,             ///< E(t) − W_ext(t) ≤ E(0) + 1e-3 E_ref at every step
  kEnergyGrowth = 1,        ///< that bound was violated: a blow-up
  kNonFinite = 2,           ///< a non-finite state
  kCgFailed = 3,            ///< PCG did not converge in cg_max_iterations
  kNoFixedPoint = 4,        ///< fixed point not converged in max_updates
  kFixedPointDiverged = 5,  ///< fixed-point iterates became non-finite
  kOtherFailure = 6,
  kNoNewton = 7,            ///< Newton not converged in max_updates
  kNewtonDiverged = 8,      ///< Newton iterates became non-finite
  kSpeed = 9,               ///< a particle faster than the run's speed bound (BlowUpGuard)
  kPenetration = 10         ///< a particle deeper than δ inside an obstacle (BlowUpGuard)
};
/// "0 bounded, 1 energy_growth, …" for the HDF5 attribute.
extern const char* const kStabilityOutcomeCodes;

struct StabilityCell {
  int32_t outcome = kBounded;
  int32_t steps = 0;               ///< steps completed
  double updates_per_step = 0.0;   ///< fixed-point updates per attempted step
  double cg_per_step = 0.0;        ///< CG iterations per attempted step
  double energy_excess = 0.0;      ///< max over completed steps of (E − W_ext − E(0))/E_ref (finite)
};

/// The scene resized to side×side particles with its spacing, fixed specs
/// re-resolved, and the map's solver settings: no retries, max_updates 30,
/// cg_max_iterations 2000, cg_tolerance 1e-6.
Scene StabilityScene(Scene scene, int side);

/// Runs one cell: tension k = S ρ l²/h² (l = max(lu, lv)), `steps` steps of
/// size h from rest. E_ref = Σ m |g| L with L the sheet diagonal.
StabilityCell RunStabilityCell(Scene scene, Method method, double h, double stiffness, int steps);

/// Builds the stepper of a cell on the cell's system and solver settings.
using StepperFactory = std::function<std::unique_ptr<Stepper>(const ParticleSystem&, const SolverSpec&)>;
/// The same cell for any stepper (the Newton variants, the peers).
StabilityCell RunStabilityCell(Scene scene, const StepperFactory& make, double h, double stiffness, int steps);

/// Short text for a printed map: "ok U/C", "GROW@n", "NaN@n", "CG@n", "FP@n",
/// "FPdiv@n", "NW@n" (Newton not converged), "NWdiv@n", "SPD@n" (speed),
/// "PEN@n" (penetration).
std::string StabilityCellText(const StabilityCell& c);

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_STABILITY_MAP_H_
