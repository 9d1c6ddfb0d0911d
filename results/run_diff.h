// Two result files' runs compared (clothbench_inspect A diff B).
#ifndef CLOTHBENCH_RESULTS_RUN_DIFF_H_
#define CLOTHBENCH_RESULTS_RUN_DIFF_H_

#include <cstdio>
#include <string>

#include "results/run_table.h"

namespace clothbench {

/// Prints, run by run (matched by id), A's and B's e_rms(t_end) [m], its
/// relative change, steps, updates, CG iterations and the solver time ratio
/// B/A, flagging an e_rms relative change above `rtol`, any change of the
/// counts or status, a time ratio outside [1/(1 + time_tolerance),
/// 1 + time_tolerance], and runs in one file only; then "<k> of <n> runs
/// flagged". `path_b` names B in the header line.
/// @return the number of flagged runs
int PrintRunDiff(std::FILE* out, const RunTable& a, const RunTable& b, const std::string& path_b, double rtol,
                 double time_tolerance);

}  // namespace clothbench

#endif  // CLOTHBENCH_RESULTS_RUN_DIFF_H_
