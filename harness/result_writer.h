// Turning a sweep's rows into the printed table, the HDF5 result file
// (docs/guide/results-schema.md), the Fig. 4.3 series and the equal-accuracy
// table.
#ifndef CLOTHBENCH_HARNESS_RESULT_WRITER_H_
#define CLOTHBENCH_HARNESS_RESULT_WRITER_H_

#include <optional>
#include <string>
#include <vector>

#include "harness/methods.h"
#include "model/particle_system.h"
#include "results/run_table.h"
#include "results/work_precision.h"

namespace clothbench {

/// Fills what each row's record derives from its trajectory: the energies
/// and dE/dt, and against `ref` (if given) the errors and the observed order
/// between consecutive rows of one label (against h/substeps; adaptive rows
/// against their mean step t_end/steps; none between two rows with the same
/// step). @param rows in table order
/// @param metric the error norm of the observed orders
void CompareToReference(const ParticleSystem& sys, const RunSummary* ref, double t_end, ErrorMetric metric,
                        std::vector<MethodRun>* rows);

/// The table's content as plain data: what is printed and what the file
/// stores, so that clothbench_inspect can print it again. `rows` have been
/// through CompareToReference (their records carry errors and energies).
/// @param ref the reference run, if any; @param wp the equal-accuracy table, if any
RunTable MakeRunTable(const Scene& scene, const ParticleSystem& sys, const std::optional<RunSummary>& ref,
                      const std::vector<MethodRun>& rows,
                      const std::string& frames_mode, const EqualAccuracyTable* wp, ErrorMetric metric);

/// Writes the result file `path` (atomically: a temporary file renamed on
/// Commit) with the scene, the reference, every row and `table`'s records.
/// @throws std::runtime_error if the file cannot be written
void WriteResults(const std::string& path, const Scene& scene, const ParticleSystem& sys,
                  const std::optional<RunSummary>& ref, const std::vector<MethodRun>& rows, const RunTable& table,
                  long mpi_ranks);

/// Fig. 4.3: per-step CG iterations and colliding particles as CSV at
/// `path`, and a summary printed on stdout.
/// @throws std::runtime_error if `path` cannot be written
void WriteSeries(const std::string& path, const std::vector<MethodRun>& rows);

/// The reference's record as /reference stores it: id "reference" and the
/// numerical stiffness h²k/(ρl²) at its step (a self-convergence run's h,
/// else the scene's h). Its run filled the rest.
void NameReference(const Scene& scene, RunRecord* ref);

/// A run's step history as the file's /runs/<id>/step_stats rows
/// (results/result_file.h StepRecord): every attempt, rejected ones included.
std::vector<StepRecord> StepRecords(const RunSummary& run);

/// A SUNDIALS run's method order q per step (/runs/<id>/method_order).
std::vector<double> MethodOrders(const RunSummary& run);

/// The equal-accuracy table (docs/notes/work-precision.md) of the rows at the
/// error `targets` [m] of `metric`, with ratios to the row labelled `baseline`
/// (--baseline; DefaultReference() by default); targets below 10× the
/// reference's error estimate `reference_error` [m] (negative: not known)
/// unresolved.
EqualAccuracyTable WorkPrecision(const std::vector<MethodRun>& rows, const std::vector<double>& targets,
                                 const std::string& baseline, ErrorMetric metric, double reference_error);

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_RESULT_WRITER_H_
