// A result file at a glance (clothbench_inspect FILE summary).
#ifndef CLOTHBENCH_RESULTS_FILE_SUMMARY_H_
#define CLOTHBENCH_RESULTS_FILE_SUMMARY_H_

#include <cstdio>

#include "results/result_reader.h"
#include "results/run_table.h"

namespace clothbench {

/// Prints what `f` holds: provenance (schema, date, commit, build, machine),
/// a stress_stability or --table file's groups, a --sizes file's scale
/// verdict, the scene, the reference, the runs' status counts and one line
/// per run (status, steps, updates, CG iterations, solver time, e_rms), and
/// the equal-accuracy table's size. `t` is f's run table (ReadRunTable).
void PrintFileSummary(std::FILE* out, const ResultReader& f, const RunTable& t);

}  // namespace clothbench

#endif  // CLOTHBENCH_RESULTS_FILE_SUMMARY_H_
