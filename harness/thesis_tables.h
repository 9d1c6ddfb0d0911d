// The thesis' Tables 3.1 and 3.2 run beside ours.
#ifndef CLOTHBENCH_HARNESS_THESIS_TABLES_H_
#define CLOTHBENCH_HARNESS_THESIS_TABLES_H_

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "harness/sweep.h"
#include "harness/reference.h"
#include "model/scene.h"
#include "results/metrics.h"
#include "solver/run.h"

namespace clothbench {

/// Runs the thesis' Table 3.1 or 3.2 (`which` = "3.1" | "3.2") once per CG
/// tolerance in `etas`, prints it beside the thesis' numbers and writes
/// `out` (default out/table_3_1.h5 or out/table_3_2.h5); rows dealt over
/// the ranks of `comm`. @return the exit status
/// @throws UsageError if `which` is neither
int RunThesisTable(const std::string& which, std::string out, std::optional<PreconditionerType> preconditioner,
                   std::vector<NonlinearSolver> solvers, std::vector<double> etas, SweepComm& comm);

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_THESIS_TABLES_H_
