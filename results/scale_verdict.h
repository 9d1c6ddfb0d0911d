// The verdict across sizes (bench_integrators --sizes, docs/notes/work-precision.md
// "The size axis"): per particle count and target error, the fastest method
// of that size's equal-accuracy table, its margin over the runner-up, and
// every method's cost; stored as /scale_verdict (docs/guide/results-schema.md).
#ifndef CLOTHBENCH_RESULTS_SCALE_VERDICT_H_
#define CLOTHBENCH_RESULTS_SCALE_VERDICT_H_

#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include "results/result_file.h"
#include "results/result_reader.h"
#include "results/work_precision.h"

namespace clothbench {

struct ScaleVerdict {
  std::vector<long> sizes;          ///< particles nu·nv of each size, increasing
  std::vector<double> targets;      ///< [m], the error metric's
  std::string metric = "final";     ///< the error norm of the targets
  std::vector<std::string> labels;  ///< every method of any size, in order of first appearance
  /// [size][target][method] solver time [s] at the target (the size's
  /// EqualAccuracyTable); nothing where the method has no number.
  std::vector<std::vector<std::vector<std::optional<double>>>> cost;
  std::vector<std::vector<std::vector<bool>>> upper_bound;  ///< [size][target][method] cost is "≤"
  std::vector<std::vector<int>> fastest;    ///< [size][target] index into labels, −1: none
  std::vector<std::vector<int>> runner_up;  ///< [size][target] the next cheapest, −1: none
  /// [size][target] the runner-up's cost over the fastest's (≥ 1); nothing
  /// without a runner-up.
  std::vector<std::vector<std::optional<double>>> margin;
  std::vector<std::vector<bool>> tied;        ///< [size][target] the runner-up is within the timing spread
  std::vector<std::vector<bool>> unresolved;  ///< [size][target] below 10× the reference's error estimate
  std::vector<double> reference_error_m;      ///< per size; −1: not known
  std::vector<std::string> result_files;      ///< per size: its bench_integrators file, relative to the verdict's folder
};

/// The verdict of the equal-accuracy tables `tables` (one per size, the
/// same targets and metric), taken as they are: the fastest of each is
/// its table's, the runner-up the cheapest other method with a number.
/// @param sizes particles per size, increasing; @param files per size
/// @throws std::invalid_argument if the sizes, tables and files differ in
///   count or the tables' targets differ
ScaleVerdict BuildScaleVerdict(const std::vector<long>& sizes, const std::vector<EqualAccuracyTable>& tables,
                               const std::vector<std::string>& files);

/// Writes /scale_verdict: datasets sizes [S] int32, targets [T] m, fastest
/// and runner_up [S, T] labels ("" none), cost_s [S, T, M] s (−1: no
/// number), upper_bound [S, T, M], margin [S, T] (−1: none), tied and
/// unresolved [S, T], reference_error_estimate_m [S] (−1: unknown),
/// result_files [S, 1]; attributes labels (comma-separated), error_metric.
void WriteScaleVerdict(ResultFile& file, const ScaleVerdict& v);

/// Reads /scale_verdict. @throws ResultError naming the dataset if a shape,
/// label or value breaks the schema.
ScaleVerdict ReadScaleVerdict(const ResultReader& file);

/// The size × target table: per cell the fastest method, its cost and its
/// margin over the runner-up ("≈" when tied within the timing spread),
/// then the sizes at which the fastest changes.
void PrintScaleVerdict(std::FILE* out, const ScaleVerdict& v);

}  // namespace clothbench

#endif  // CLOTHBENCH_RESULTS_SCALE_VERDICT_H_
