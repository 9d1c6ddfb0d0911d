// Stability map expectations, on the swinging sheet at 8×8
// particles, 200 steps per cell, S = h²k/(ρl²) ∈ {0.1, 1e2, 1e4, 1e8},
// h ∈ {1e-4, 1e-3, 1e-2, 1e-1} s (see solver/stability_map.h for "bounded").
//
// - Symplectic Euler is explicit: its CFL limit for tension is S·λ_max < 4
//   (λ_max ≈ 7.6 for the grid Laplacian), so every cell with S ≥ 1e2 must
//   blow up; at S = 0.1, h = 1e-4 s it is inside both that limit and the
//   explicit damping limit h·c_e·λ_max/m < 2 (0.25 here), so it is bounded.
// - IMEX Euler and SBDF(2) treat the stiff linear tension implicitly: bounded
//   for every S ≥ 1e2 at every h (the explicit shear and bending terms are
//   inside their own limits there).
// - Implicit Euler, BDF(2) and implicit midpoint never blow up: a cell either
//   stays bounded or stops because the fixed-point loop of Alg. 6 fails (it
//   converges only while α²h²s_eλ/m is small, docs/notes/verification.md), which
//   happens at every h for S ≥ 1e4.
#include <gtest/gtest.h>

#include "solver/stability_map.h"

namespace clothbench {
namespace {

const std::vector<double> kH = {1e-4, 1e-3, 1e-2, 1e-1};

TEST(StabilityMap, MatchesTheoryOnSwingingSheet) {
  const Scene scene = StabilityScene(BuiltinScene("swinging_sheet"), 8);
  auto cell = [&](Method m, double h, double s) {
    const StabilityCell c = RunStabilityCell(scene, m, h, s, 200);
    std::printf("[ stability ] %-18s h=%-6g S=%-6g %s\n", std::string(ToString(m)).c_str(), h, s,
                StabilityCellText(c).c_str());
    return c;
  };
  for (double h : kH)
    for (double s : {1e2, 1e4, 1e8}) {
      const StabilityCell c = cell(Method::kSymplecticEuler, h, s);
      EXPECT_TRUE(c.outcome == kEnergyGrowth || c.outcome == kNonFinite) << "h=" << h << " S=" << s;
    }
  EXPECT_EQ(cell(Method::kSymplecticEuler, 1e-4, 0.1).outcome, kBounded);

  for (Method m : {Method::kImexEuler, Method::kSbdf2})
    for (double h : kH)
      for (double s : {1e2, 1e4, 1e8}) EXPECT_EQ(cell(m, h, s).outcome, kBounded) << ToString(m) << " h=" << h << " S=" << s;

  for (Method m : {Method::kImplicitEuler, Method::kBdf2, Method::kImplicitMidpoint})
    for (double h : kH) {
      for (double s : {0.1, 1e2, 1e4, 1e8}) {
        const StabilityCell c = cell(m, h, s);
        EXPECT_NE(c.outcome, kEnergyGrowth) << ToString(m) << " h=" << h << " S=" << s;
        EXPECT_NE(c.outcome, kNonFinite) << ToString(m) << " h=" << h << " S=" << s;
        if (s >= 1e4) {
          EXPECT_TRUE(c.outcome == kNoFixedPoint || c.outcome == kFixedPointDiverged) << ToString(m) << " h=" << h;
        }
      }
    }
}

}  // namespace
}  // namespace clothbench
