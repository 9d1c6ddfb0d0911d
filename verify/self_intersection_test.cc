// The count of the cloth's crossing triangle pairs (collision/
// self_intersection.h) on sheets of known shape: a cycloid sheet crosses
// itself along one line exactly when its loop closes (b > 1).
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "collision/self_intersection.h"
#include "collision/edge_projection.h"

namespace clothbench {
namespace {

// An nu × nv sheet whose v-lines follow the cycloid (t − b sin t,
// 1 − b cos t), t ∈ [−2.2, 2.2], in the (y, z)-plane, extruded along x.
// For b = 1.5 the curve crosses itself once, at t = ±1.496 (where
// t = 1.5 sin t); for b = 0.5 it is a graph over y and never does.
MatrixN3 CycloidSheet(int nu, int nv, double b) {
  MatrixN3 x(nu * nv, 3);
  for (int j = 0; j < nv; ++j) {
    const double t = -2.2 + 4.4 * j / (nv - 1);
    for (int i = 0; i < nu; ++i) x.row(i + nu * j) << 0.1 * i, t - b * std::sin(t), 1.0 - b * std::cos(t);
  }
  return x;
}

TEST(SelfIntersection, AFlatOrLooselyCurvedSheetHasNone) {
  const std::vector<std::array<int, 3>> tri = GridTriangles(6, 40).vertices;
  EXPECT_EQ(tri.size(), 2u * 5u * 39u);
  EXPECT_TRUE(SelfIntersections(CycloidSheet(6, 40, 0.0), tri).empty());  // flat: z = 1
  EXPECT_TRUE(SelfIntersections(CycloidSheet(6, 40, 0.5), tri).empty());
}

// The looped sheet's two crossing strips meet along the line x ∈ [0, 0.5]:
// every one of the 5 quad columns has crossing pairs, and each pair lies
// near t = ±1.496 (rows j with |t| within a row spacing, 0.113, of it).
TEST(SelfIntersection, ALoopedSheetCrossesAlongOneLine) {
  const int nu = 6, nv = 40;
  const std::vector<std::array<int, 3>> tri = GridTriangles(nu, nv).vertices;
  const std::vector<std::pair<int, int>> pairs = SelfIntersections(CycloidSheet(nu, nv, 1.5), tri);
  ASSERT_FALSE(pairs.empty());
  std::vector<bool> column(nu - 1, false);
  for (const auto& [a, b] : pairs) {
    EXPECT_LT(a, b);
    for (int k : {a, b}) {
      const int quad = k / 2, j = quad / (nu - 1);
      const double t = -2.2 + 4.4 * (j + 0.5) / (nv - 1);
      EXPECT_NEAR(std::abs(t), 1.496, 0.12) << "triangle " << k;
      column[static_cast<std::size_t>(quad % (nu - 1))] = true;
    }
  }
  for (int c = 0; c < nu - 1; ++c) EXPECT_TRUE(column[static_cast<std::size_t>(c)]) << "column " << c;
}

TEST(SelfIntersection, RefusesATriangleOutsideTheSheet) {
  EXPECT_THROW(SelfIntersections(CycloidSheet(2, 2, 0.0), {{0, 1, 4}}), std::invalid_argument);
}

}  // namespace
}  // namespace clothbench
