// The records of a result file, written and read by one schema
// (docs/guide/results-schema.md): the run table, a run's attributes, the scene's
// and the equal-accuracy table's (results/run_records.cc).
#ifndef CLOTHBENCH_RESULTS_RUN_RECORDS_H_
#define CLOTHBENCH_RESULTS_RUN_RECORDS_H_

#include <string>

#include "results/result_file.h"
#include "results/result_reader.h"
#include "results/run_table.h"
#include "results/work_precision.h"

namespace clothbench {

/// The table of a bench_integrators result file (see RunTable). A file
/// without /runs (stress_stability, --table files) gives an empty run list.
RunTable ReadRunTable(const ResultReader& file);

/// Writes the attributes of one run group /runs/<id> that RunTable holds.
void WriteRunRecord(ResultFile& file, const std::string& group, const RunRecord& run);
/// The record WriteRunRecord wrote to `group` ("/runs/<id>" or
/// "/reference"), with `id`; missing attributes keep RunRecord's defaults
/// (status then empty).
RunRecord ReadRunRecord(const ResultReader& file, const std::string& group, const std::string& id);
/// Writes the /scene attributes and solver settings that RunTable holds
/// (the group must exist).
void WriteSceneRecord(ResultFile& file, const RunTable& table);
/// Writes the group `group` (/work_precision; /sizes/n<N>/work_precision in
/// a --sizes verdict file): targets, labels, solver_time, ratio, fastest
/// (−1 where a cell is empty).
void WriteWorkPrecision(ResultFile& file, const EqualAccuracyTable& table,
                        const std::string& group = "/work_precision");

}  // namespace clothbench

#endif  // CLOTHBENCH_RESULTS_RUN_RECORDS_H_
