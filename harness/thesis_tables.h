// The thesis' Tables 3.1 and 3.2 run beside ours, and the self-convergence
// reference of obstacle scenes.
#ifndef CLOTHBENCH_HARNESS_THESIS_TABLES_H_
#define CLOTHBENCH_HARNESS_THESIS_TABLES_H_

#include <optional>
#include <string>
#include <vector>

#include "harness/sweep.h"
#include "model/scene.h"
#include "solver/run.h"

namespace clothbench {

/// A tight self-convergence run for obstacle scenes: the reference with
/// virtual particles and of the thesis' tables, the cross-check of the
/// event-located reference otherwise (docs/collisions.md, "The contact
/// reference"). BDF(2) at `h_ref` [s] with CG tolerance 1e-10, fixed-point
/// tolerance 1e-12 m/s and up to 200 updates per step.
RunSummary SelfConvergenceReference(const Scene& scene, double h_ref);

/// Runs the thesis' Table 3.1 or 3.2 (`which` = "3.1" | "3.2") once per CG
/// tolerance in `etas`, prints it beside the thesis' numbers and writes
/// `out` (default out/table_3_1.h5 or out/table_3_2.h5); rows dealt over
/// the ranks of `comm`. @return the exit status
/// @throws UsageError if `which` is neither
int RunThesisTable(const std::string& which, std::string out, std::optional<PreconditionerType> preconditioner,
                   std::vector<NonlinearSolver> solvers, std::vector<double> etas, SweepComm& comm);

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_THESIS_TABLES_H_
