// The equal-accuracy table's interpolation (results/work_precision.h) on
// synthetic points with known answers.
#include <gtest/gtest.h>

#include <cmath>

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
    const auto c = CostAtError(p, target);
    ASSERT_TRUE(c.has_value()) << target;
    EXPECT_NEAR(*c, 1e-3 / std::sqrt(target), 1e-12 * *c) << target;
  }
}

TEST(WorkPrecision, NeverExtrapolates) {
  const std::vector<WorkPoint> p = PowerLaw({1e-1, 1e-2});
  EXPECT_FALSE(CostAtError(p, 2e-1).has_value());
  EXPECT_FALSE(CostAtError(p, 5e-3).has_value());
  EXPECT_FALSE(CostAtError({}, 1e-2).has_value());
  EXPECT_FALSE(CostAtError({{1.0, 1e-2}}, 1e-3).has_value());
}

TEST(WorkPrecision, FirstBracketingPairInRunOrderAndInvalidPointsSkipped) {
  // Errors not monotone: 1e-2 → 1e-4 → 1e-3. The first consecutive pair that
  // brackets 1e-3 is (1e-2, 1e-4), at costs (1, 100): log-log midpoint 10.
  const std::vector<WorkPoint> p = {{1.0, 1e-2}, {-1.0, 5e-3}, {100.0, 1e-4}, {1000.0, 1e-3}};
  const auto c = CostAtError(p, 1e-3);
  ASSERT_TRUE(c.has_value());
  EXPECT_NEAR(*c, 10.0, 1e-12);
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
  EXPECT_FALSE(t.cost[0][0].has_value());
  EXPECT_FALSE(t.ratio[2][0].has_value());  // cvode does not bracket 1e-1
  EXPECT_EQ(t.fastest[0], 2);
  EXPECT_EQ(t.fastest[1], 0);
}

}  // namespace
}  // namespace clothbench
