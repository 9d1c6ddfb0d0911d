// Work-precision at equal accuracy (docs/notes/work-precision.md): the cost of
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
  double spread = 0.0;  ///< (max − min)/min of the run's repeated timings; 0 for one
};

/// The lower envelope of a method's runs: the runs no other run dominates
/// (none is at most as costly and at most as wrong, and better in one), in
/// order of increasing cost and so of strictly decreasing error. Points with
/// a non-positive or non-finite cost or error are left out.
std::vector<WorkPoint> CostEnvelope(const std::vector<WorkPoint>& points);

/// A method's cost at a target error.
struct CostEstimate {
  /// The cost [s]; nothing if no run reaches the target.
  std::optional<double> cost;
  /// True if the cheapest run already meets the target: `cost` is then that
  /// run's cost, an upper bound of the cost at the target ("≤ t s").
  bool upper_bound = false;
  /// The timing spread of the envelope runs the cost comes from (the larger
  /// of the two bracketing runs'; the cheapest run's for a bound).
  double spread = 0.0;
};

/// The cost at error `target`, read off CostEnvelope(points): interpolated
/// log-log between the two adjacent envelope points whose errors bracket the
/// target, log c = log c₁ + (log e* − log e₁)(log c₂ − log c₁)/(log e₂ − log e₁);
/// the cheapest run's cost as an upper bound if that run meets the target
/// already; nothing if no run reaches it. Never extrapolates.
CostEstimate CostAtError(const std::vector<WorkPoint>& points, double target);

/// The equal-accuracy table: per method (row) and target (column) the
/// envelope cost, the ratio to the baseline method's cost at the same
/// target, and the fastest method per target.
struct EqualAccuracyTable {
  std::vector<double> targets;                          ///< [m]
  std::vector<std::string> labels;                      ///< one per method
  std::vector<std::vector<std::optional<double>>> cost; ///< [method][target] solver time [s]
  std::vector<std::vector<bool>> upper_bound;           ///< [method][target] cost is "≤" (CostEstimate)
  std::vector<std::vector<std::optional<double>>> ratio;///< cost / the baseline's cost
  std::vector<int> fastest;                             ///< per target: method index, −1 if none reaches it
  std::vector<std::vector<double>> spread;              ///< [method][target] timing spread of the cost
  /// Per target: the other methods tied with the fastest, those whose cost
  /// exceeds the fastest's by no more than the larger of their two timing
  /// spreads (the timings cannot rank them).
  std::vector<std::vector<int>> tied;
  /// Per method: its smallest error over the valid runs [m] (why a target
  /// has no cost); nothing if no run is valid (all failed).
  std::vector<std::optional<double>> min_error;
  std::string reference;                                ///< the baseline label the ratios are relative to (may be absent)
  std::string metric = "final";                         ///< the error norm of the targets (results/metrics.h ErrorMetric)
  /// The reference's own error estimate in `metric` [m] (RunRecord::
  /// error_estimate_m); −1: not known.
  double reference_error_m = -1.0;
  /// Per target: below kResolvedFactor × reference_error_m, where the
  /// reference cannot rank the methods: no cost, ratio or fastest is given.
  std::vector<bool> unresolved;
  /// --sweep-to-targets: per method, "label: why its sweep stopped (n runs)";
  /// empty for a sweep over fixed lists.
  std::vector<std::string> stop_reasons;
};

/// A target is resolved by the reference only from this many times its error estimate on.
inline constexpr double kResolvedFactor = 10.0;

/// Sets t->reference_error_m and marks the targets below kResolvedFactor ×
/// it unresolved, clearing their costs, ratios, fastest and ties. A
/// negative `reference_error` [m] marks none.
void MarkUnresolvedTargets(EqualAccuracyTable* t, double reference_error);

/// @param labels  method labels; points[k] are the runs of labels[k]
/// @param reference the baseline label the ratios are relative to
///                  (a row label); empty or absent: no ratios
EqualAccuracyTable BuildEqualAccuracyTable(const std::vector<std::string>& labels,
                                           const std::vector<std::vector<WorkPoint>>& points,
                                           const std::vector<double>& targets, const std::string& reference);

}  // namespace clothbench

#endif  // CLOTHBENCH_RESULTS_WORK_PRECISION_H_
