// Work-precision at equal accuracy (docs/work-precision.md): the cost of
// each method at a target error, interpolated between its runs.
#ifndef CLOTHBENCH_RESULTS_WORK_PRECISION_H_
#define CLOTHBENCH_RESULTS_WORK_PRECISION_H_

#include <optional>
#include <string>
#include <vector>

namespace clothbench {

/// One run of a method: its cost (solver time [s]) and its error (e_rms at
/// t_end [m]).
struct WorkPoint {
  double cost = 0.0;
  double error = 0.0;
};

/// The cost at error `target`, interpolated log-log between the first two
/// consecutive points (in the given order, e.g. h or rtol decreasing) whose
/// errors bracket the target: log c = log c₁ + (log e* − log e₁)
/// (log c₂ − log c₁)/(log e₂ − log e₁). Never extrapolates: nothing if no
/// consecutive pair brackets the target. Points with a non-positive cost or
/// error are skipped.
std::optional<double> CostAtError(const std::vector<WorkPoint>& points, double target);

/// The equal-accuracy table: per method (row) and target (column) the
/// interpolated cost, the ratio to the reference method's cost at the same
/// target, and the fastest method per target.
struct EqualAccuracyTable {
  std::vector<double> targets;                          ///< [m]
  std::vector<std::string> labels;                      ///< one per method
  std::vector<std::vector<std::optional<double>>> cost; ///< [method][target] solver time [s]
  std::vector<std::vector<std::optional<double>>> ratio;///< cost / the reference method's cost
  std::vector<int> fastest;                             ///< per target: method index, −1 if none brackets it
  std::string reference;                                ///< the label the ratios are relative to (may be absent)
};

/// @param labels  method labels; points[k] are the runs of labels[k]
/// @param reference the label the ratio is relative to ("cvode"); empty or
///                  absent: no ratios
EqualAccuracyTable BuildEqualAccuracyTable(const std::vector<std::string>& labels,
                                           const std::vector<std::vector<WorkPoint>>& points,
                                           const std::vector<double>& targets, const std::string& reference);

}  // namespace clothbench

#endif  // CLOTHBENCH_RESULTS_WORK_PRECISION_H_
