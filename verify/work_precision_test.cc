// The equal-accuracy table's interpolation (results/work_precision.h) on
// synthetic points with known answers.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "model/trajectory.h"
#include "results/metrics.h"
#include "results/work_precision.h"

namespace clothbench {
namespace {

// cost = 1e-3 · e^(−1/2): a power law is a straight line in log-log, so
// the interpolation between any two of its points is exact (to round-off).
std::vector<WorkPoint> PowerLaw(const std::vector<double>& errors) {
  std::vector<WorkPoint> p;
  for (double e : errors) p.push_back({1e-3 / std::sqrt(e), e});
  return p;
}

TEST(WorkPrecision, LogLogInterpolationIsExactOnAPowerLaw) {
  const std::vector<WorkPoint> p = PowerLaw({1e-1, 1e-2, 1e-3, 1e-4});
  for (double target : {5e-2, 1e-2, 3e-3, 2e-4}) {
    const CostEstimate c = CostAtError(p, target);
    ASSERT_TRUE(c.cost.has_value()) << target;
    EXPECT_FALSE(c.upper_bound);
    EXPECT_NEAR(*c.cost, 1e-3 / std::sqrt(target), 1e-12 * *c.cost) << target;
  }
}

TEST(WorkPrecision, NeverExtrapolatesButBoundsFromAbove) {
  const std::vector<WorkPoint> p = PowerLaw({1e-1, 1e-2});
  // The cheapest run (e = 1e-1) already meets 2e-1: at most its cost.
  const CostEstimate above = CostAtError(p, 2e-1);
  ASSERT_TRUE(above.cost.has_value());
  EXPECT_TRUE(above.upper_bound);
  EXPECT_EQ(*above.cost, p[0].cost);
  EXPECT_FALSE(CostAtError(p, 5e-3).cost.has_value());  // below every run: no number
  EXPECT_FALSE(CostAtError({}, 1e-2).cost.has_value());
  EXPECT_FALSE(CostAtError({{1.0, 1e-2}}, 1e-3).cost.has_value());
}

TEST(WorkPrecision, EnvelopeDropsDominatedRunsAndInvalidPoints) {
  // Errors not monotone in run order: 1e-2 → 1e-4 → 1e-3. The run at
  // (1000 s, 1e-3) is dominated by (100 s, 1e-4); the envelope is
  // (1, 1e-2), (100, 1e-4), and 1e-3 lies at their log-log midpoint: 10 s.
  const std::vector<WorkPoint> p = {{1.0, 1e-2}, {-1.0, 5e-3}, {100.0, 1e-4}, {1000.0, 1e-3}};
  const std::vector<WorkPoint> envelope = CostEnvelope(p);
  ASSERT_EQ(envelope.size(), 2u);
  EXPECT_EQ(envelope[1].cost, 100.0);
  const CostEstimate c = CostAtError(p, 1e-3);
  ASSERT_TRUE(c.cost.has_value());
  EXPECT_NEAR(*c.cost, 10.0, 1e-12);
}

TEST(WorkPrecision, ACheaperMoreAccurateRunWins) {
  // Fixed-point BDF(2)'s pattern: cost falls as h shrinks, because the
  // fixed point needs fewer updates. The cheapest run (0.572 s) is also the
  // most accurate, so every target it meets is "≤ 0.572 s".
  const std::vector<WorkPoint> p = {{1.587, 2.3e-4}, {0.811, 1.1e-4}, {0.600, 4e-5}, {0.572, 1.4e-5}};
  ASSERT_EQ(CostEnvelope(p).size(), 1u);
  const CostEstimate c = CostAtError(p, 1e-4);
  ASSERT_TRUE(c.cost.has_value());
  EXPECT_TRUE(c.upper_bound);
  EXPECT_EQ(*c.cost, 0.572);
}

// The invariant the table promises: no run is both cheaper than the reported
// cost and at or below the target; a method with a run at or below the
// target reports a number; one without reports none.
TEST(WorkPrecision, NoRunBeatsTheReportedCost) {
  unsigned state = 12345u;
  const auto uniform = [&state]() {
    state = state * 1664525u + 1013904223u;
    return static_cast<double>(state >> 8) / static_cast<double>(1u << 24);
  };
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<WorkPoint> p;
    const int n = 1 + trial % 7;
    for (int k = 0; k < n; ++k) p.push_back({std::pow(10.0, -2.0 + 3.0 * uniform()), std::pow(10.0, -6.0 + 5.0 * uniform())});
    for (double target : {1e-2, 1e-3, 1e-4, 1e-5}) {
      const CostEstimate c = CostAtError(p, target);
      const bool reachable = std::any_of(p.begin(), p.end(), [&](const WorkPoint& w) { return w.error <= target; });
      ASSERT_EQ(c.cost.has_value(), reachable) << trial << " " << target;
      if (!c.cost) continue;
      for (const WorkPoint& w : p)
        EXPECT_FALSE(w.cost < *c.cost * (1.0 - 1e-12) && w.error <= target) << trial << " " << target;
    }
  }
}

TEST(WorkPrecision, TableRatiosAndFastest) {
  const std::vector<std::string> labels = {"a", "cvode", "b"};
  const std::vector<std::vector<WorkPoint>> pts = {
      {{1.0, 1e-2}, {4.0, 1e-4}},     // a: 2.0 s at 1e-3
      {{2.0, 1e-2}, {8.0, 1e-4}},     // cvode: 4.0 s at 1e-3
      {{0.5, 1e-1}, {0.6, 5e-2}}};    // b: brackets only 1e-1
  const EqualAccuracyTable t = BuildEqualAccuracyTable(labels, pts, {1e-1, 1e-3}, "cvode");
  ASSERT_TRUE(t.cost[0][1].has_value());
  EXPECT_NEAR(*t.cost[0][1], 2.0, 1e-12);
  EXPECT_NEAR(*t.ratio[0][1], 0.5, 1e-12);
  EXPECT_NEAR(*t.ratio[1][1], 1.0, 1e-12);
  // a and cvode already meet 1e-1 with their cheapest run: upper bounds.
  EXPECT_TRUE(t.upper_bound[0][0] && t.upper_bound[1][0]);
  EXPECT_NEAR(*t.ratio[0][0], 0.5, 1e-12);
  EXPECT_FALSE(t.cost[2][1].has_value());  // b never reaches 1e-3
  EXPECT_NEAR(*t.min_error[2], 5e-2, 1e-15);
  EXPECT_EQ(t.fastest[0], 2);  // b: 0.5 s ≤ a's 1.0 s bound at 1e-1
  EXPECT_EQ(t.fastest[1], 0);
}

// A target below 10× the reference's error estimate is unresolved: its
// costs, ratios and fastest are cleared; the others are kept.
TEST(WorkPrecision, TargetsBelowTenTimesTheReferenceErrorAreUnresolved) {
  const std::vector<std::string> labels = {"a", "cvode"};
  const std::vector<std::vector<WorkPoint>> pts = {{{1.0, 1e-2}, {4.0, 1e-8}}, {{2.0, 1e-2}, {8.0, 1e-8}}};
  EqualAccuracyTable t = BuildEqualAccuracyTable(labels, pts, {1e-3, 1e-7}, "cvode");
  ASSERT_TRUE(t.cost[0][1].has_value() && t.fastest[1] == 0);
  MarkUnresolvedTargets(&t, 2e-8);  // 10× = 2e-7: 1e-7 is below it, 1e-3 is not
  EXPECT_EQ(t.unresolved, (std::vector<bool>{false, true}));
  EXPECT_TRUE(t.cost[0][0].has_value());
  EXPECT_EQ(t.fastest[0], 0);
  EXPECT_FALSE(t.cost[0][1].has_value() || t.cost[1][1].has_value() || t.ratio[0][1].has_value());
  EXPECT_EQ(t.fastest[1], -1);
  MarkUnresolvedTargets(&t, -1.0);  // unknown estimate: nothing marked
  EXPECT_EQ(t.unresolved, (std::vector<bool>{false, false}));
}

// The three error norms over frames (results/metrics.h) on a 3-frame,
// 1-particle trajectory with known offsets 0, 3, 4 m: final 4 m, max 4 m,
// l2 sqrt((0 + 9 + 16)/3) m; the velocities' offsets 1, 1, 2 m/s likewise.
TEST(WorkPrecision, ErrorNormsOverFrames) {
  Trajectory run, ref;
  for (double dx : {0.0, 3.0, 4.0}) {
    MatrixN3 x = MatrixN3::Zero(1, 3);
    ref.positions.push_back(x);
    x(0, 0) = dx;
    run.positions.push_back(x);
  }
  for (double dv : {1.0, 1.0, 2.0}) {
    MatrixN3 v = MatrixN3::Zero(1, 3);
    ref.velocities.push_back(v);
    v(0, 1) = dv;
    run.velocities.push_back(v);
  }
  const std::optional<TrajectoryErrors> e = CompareTrajectories(run, ref);
  ASSERT_TRUE(e.has_value());
  EXPECT_DOUBLE_EQ(e->Of(ErrorMetric::kFinal), 4.0);
  EXPECT_DOUBLE_EQ(e->Of(ErrorMetric::kMax), 4.0);
  EXPECT_DOUBLE_EQ(e->Of(ErrorMetric::kL2), std::sqrt(25.0 / 3.0));
  EXPECT_DOUBLE_EQ(*e->v_rms_at_end, 2.0);
  EXPECT_DOUBLE_EQ(*e->v_rms_l2, std::sqrt(6.0 / 3.0));
  EXPECT_DOUBLE_EQ(*e->v_rms_max, 2.0);
  run.velocities.pop_back();  // velocities not kept for every frame: positions only
  EXPECT_FALSE(CompareTrajectories(run, ref)->v_rms_at_end.has_value());
  EXPECT_EQ(ParseErrorMetric("l2"), ErrorMetric::kL2);
  EXPECT_FALSE(ParseErrorMetric("rms").has_value());
}

// Two methods whose costs differ by less than their timing spread are tied:
// the table names the fastest and the ties, not a ranking it cannot make.
TEST(WorkPrecision, TiesWithinTheTimingSpread) {
  const std::vector<std::string> labels = {"a", "b", "c"};
  const std::vector<std::vector<WorkPoint>> pts = {{{1.00, 1e-4, 0.10}},   // 1.00 s, spread 10 %
                                                   {{1.05, 1e-4, 0.02}},   // 5 % dearer: within a's spread
                                                   {{1.20, 1e-4, 0.05}}};  // 20 % dearer: ranked
  const EqualAccuracyTable t = BuildEqualAccuracyTable(labels, pts, {1e-3}, "");
  EXPECT_EQ(t.fastest[0], 0);
  ASSERT_EQ(t.tied[0].size(), 1u);
  EXPECT_EQ(t.tied[0][0], 1);
  EXPECT_DOUBLE_EQ(t.spread[1][0], 0.02);
}

}  // namespace
}  // namespace clothbench
