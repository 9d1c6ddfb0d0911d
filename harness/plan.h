// Planning a run from its options: the default rows and each row's list of
// step sizes or tolerances.
#ifndef CLOTHBENCH_HARNESS_PLAN_H_
#define CLOTHBENCH_HARNESS_PLAN_H_

#include <string>
#include <utility>
#include <vector>

#include "harness/methods.h"
#include "model/scene.h"

namespace clothbench {

/// The default run's rows, in table order: the five thesis methods with the
/// scene's nonlinear solver (and each fully implicit one also with Newton,
/// unless `solver_from_cli` or the scene already uses Newton), SBDF(3),
/// Baraff–Witkin, Blender, XPBD, PD and PD with Chebyshev acceleration, the
/// error-controlled SBDF(2) and BDF(2),
/// the three ARKODE pairs, CVODE and CVODE with KLU.
std::vector<std::string> DefaultRowNames(NonlinearSolver scene_solver, bool solver_from_cli);

/// Each row's (h or rtol, substeps or iterations) in run order, and what the memory check needs.
struct RowPlan {
  std::vector<std::vector<std::pair<double, int>>> params;  ///< per method
  std::vector<std::size_t> n_params;                        ///< per method
  double step_records = 0.0;  ///< steps of the fixed-step and substepped rows (all η)
};

/// Plans the rows of `methods`: h decreasing (`hs`, else the method's
/// DefaultRowParams × the scene's h, at most t_end), rtol (`rtols`, else the
/// defaults), substepped rows by their substep h/n decreasing, iterated rows
/// by h decreasing, each h with every count of `iterations` (empty: the
/// row's DefaultParams::iterations, else kDefaultIterations).
/// @param n_eta the number of CG tolerances (rows that use the PCG run once per η)
/// @throws UsageError naming the option if a fixed-step row would need more
///         than kMaxStepsPerRun steps
RowPlan PlanRows(const Scene& scene, const std::vector<RowMethod>& methods, const std::vector<double>& hs,
                 const std::vector<double>& rtols, const std::vector<int>& substeps, const std::vector<int>& iterations,
                 std::size_t n_eta);

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_PLAN_H_
