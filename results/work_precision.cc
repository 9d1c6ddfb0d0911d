#include "results/work_precision.h"

#include <algorithm>
#include <cmath>

namespace clothbench {

std::vector<WorkPoint> CostEnvelope(const std::vector<WorkPoint>& points) {
  std::vector<WorkPoint> p;
  for (const WorkPoint& w : points)
    if (w.cost > 0.0 && w.error > 0.0 && std::isfinite(w.cost) && std::isfinite(w.error)) p.push_back(w);
  std::sort(p.begin(), p.end(), [](const WorkPoint& a, const WorkPoint& b) {
    return a.cost < b.cost || (a.cost == b.cost && a.error < b.error);
  });
  std::vector<WorkPoint> envelope;
  for (const WorkPoint& w : p)  // keep a run only if it is more accurate than every cheaper one
    if (envelope.empty() || w.error < envelope.back().error) envelope.push_back(w);
  return envelope;
}

CostEstimate CostAtError(const std::vector<WorkPoint>& points, double target) {
  CostEstimate c;
  if (!(target > 0.0)) return c;
  const std::vector<WorkPoint> p = CostEnvelope(points);
  if (p.empty()) return c;
  if (p.front().error <= target) {
    c.cost = p.front().cost;
    c.upper_bound = true;
    c.spread = p.front().spread;
    return c;
  }
  for (std::size_t k = 0; k + 1 < p.size(); ++k) {
    const double e1 = p[k].error, e2 = p[k + 1].error;  // e1 > e2
    if (!(e1 > target && target >= e2)) continue;
    const double s = (std::log(target) - std::log(e1)) / (std::log(e2) - std::log(e1));
    c.cost = std::exp(std::log(p[k].cost) + s * (std::log(p[k + 1].cost) - std::log(p[k].cost)));
    c.spread = std::max(p[k].spread, p[k + 1].spread);
    return c;
  }
  return c;
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
    std::vector<bool> bound;
    std::vector<double> spread;
    for (double e : targets) {
      const CostEstimate c = CostAtError(points[m], e);
      row.push_back(c.cost);
      bound.push_back(c.upper_bound);
      spread.push_back(c.spread);
    }
    t.cost.push_back(row);
    t.upper_bound.push_back(bound);
    t.spread.push_back(spread);
    const std::vector<WorkPoint> envelope = CostEnvelope(points[m]);
    t.min_error.push_back(envelope.empty() ? std::nullopt : std::optional(envelope.back().error));
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
    std::vector<int> tied;
    if (best >= 0) {
      const std::size_t b = static_cast<std::size_t>(best);
      for (std::size_t m = 0; m < labels.size(); ++m)
        if (m != b && t.cost[m][j] &&
            *t.cost[m][j] <= *t.cost[b][j] * (1.0 + std::max(t.spread[m][j], t.spread[b][j])))
          tied.push_back(static_cast<int>(m));
    }
    t.tied.push_back(tied);
  }
  return t;
}

void MarkUnresolvedTargets(EqualAccuracyTable* t, double reference_error) {
  t->reference_error_m = reference_error;
  t->unresolved.assign(t->targets.size(), false);
  if (!(reference_error >= 0.0)) return;
  for (std::size_t j = 0; j < t->targets.size(); ++j) {
    if (t->targets[j] >= kResolvedFactor * reference_error) continue;
    t->unresolved[j] = true;
    for (std::size_t m = 0; m < t->labels.size(); ++m) {
      t->cost[m][j].reset();
      t->ratio[m][j].reset();
      t->upper_bound[m][j] = false;
    }
    if (j < t->fastest.size()) t->fastest[j] = -1;
    if (j < t->tied.size()) t->tied[j].clear();
  }
}

}  // namespace clothbench
