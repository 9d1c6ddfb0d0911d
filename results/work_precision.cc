#include "results/work_precision.h"

#include <cmath>

namespace clothbench {

std::optional<double> CostAtError(const std::vector<WorkPoint>& points, double target) {
  if (!(target > 0.0)) return std::nullopt;
  std::vector<WorkPoint> p;
  for (const WorkPoint& w : points)
    if (w.cost > 0.0 && w.error > 0.0 && std::isfinite(w.cost) && std::isfinite(w.error)) p.push_back(w);
  for (std::size_t k = 0; k + 1 < p.size(); ++k) {
    const double e1 = p[k].error, e2 = p[k + 1].error;
    if (!((e1 >= target && target >= e2) || (e1 <= target && target <= e2))) continue;
    if (e1 == e2) return std::min(p[k].cost, p[k + 1].cost);
    const double s = (std::log(target) - std::log(e1)) / (std::log(e2) - std::log(e1));
    return std::exp(std::log(p[k].cost) + s * (std::log(p[k + 1].cost) - std::log(p[k].cost)));
  }
  return std::nullopt;
}

EqualAccuracyTable BuildEqualAccuracyTable(const std::vector<std::string>& labels,
                                           const std::vector<std::vector<WorkPoint>>& points,
                                           const std::vector<double>& targets, const std::string& reference) {
  EqualAccuracyTable t;
  t.targets = targets;
  t.labels = labels;
  t.reference = reference;
  int ref = -1;
  for (std::size_t m = 0; m < labels.size(); ++m)
    if (!reference.empty() && labels[m] == reference) ref = static_cast<int>(m);
  for (std::size_t m = 0; m < labels.size(); ++m) {
    std::vector<std::optional<double>> row;
    for (double e : targets) row.push_back(CostAtError(points[m], e));
    t.cost.push_back(row);
  }
  for (std::size_t m = 0; m < labels.size(); ++m) {
    std::vector<std::optional<double>> row;
    for (std::size_t j = 0; j < targets.size(); ++j) {
      if (ref >= 0 && t.cost[m][j] && t.cost[static_cast<std::size_t>(ref)][j])
        row.push_back(*t.cost[m][j] / *t.cost[static_cast<std::size_t>(ref)][j]);
      else
        row.push_back(std::nullopt);
    }
    t.ratio.push_back(row);
  }
  for (std::size_t j = 0; j < targets.size(); ++j) {
    int best = -1;
    for (std::size_t m = 0; m < labels.size(); ++m)
      if (t.cost[m][j] && (best < 0 || *t.cost[m][j] < *t.cost[static_cast<std::size_t>(best)][j]))
        best = static_cast<int>(m);
    t.fastest.push_back(best);
  }
  return t;
}

}  // namespace clothbench
