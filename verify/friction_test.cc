// The friction impulse's cap (model/solver_spec.h, FrictionCap;
// docs/notes/collisions.md, "The friction cap").
//
// scenes/tilted_plane_10k.toml at 20 × 20 particles: the sheet lands on its
// upper edge on a plane tilted 30° (friction 0.3 < tan 30°, so it slides),
// folds onto it and slides down. Each row runs at h = 0.01, 0.005, 0.0025
// and 0.00125 s to t = 0.5 s; d_k is the rms distance between the end
// positions of the k-th and (k+1)-th h.
// - The system cap converges: each d_k is at most 0.7 of the one before,
//   an observed order of at least 0.5 (first order gives 0.5; measured
//   ratios 0.51, 0.47 for implicit Euler and 0.41, 0.61 for Baraff–Witkin;
//   contact switches make the order of a non-smooth problem irregular).
// - The mass cap does not, at these h: its d_k stay about 2 cm (2.1, 1.8,
//   2.5 cm for implicit Euler). Its last distance is at least 0.8 of its
//   first, so this test tells the two caps apart.
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "model/scene.h"
#include "verify/test_rows.h"

namespace clothbench {
namespace {

std::vector<double> EndDistances(FrictionCap cap, const std::string& row) {
  Scene s = LoadScene(std::string(CLOTHBENCH_SCENES_DIR) + "/tilted_plane_10k.toml");
  s.grid.nu = s.grid.nv = 20;
  s.t_end = s.frame_dt = 0.5;
  s.solver.friction_cap = cap;
  std::vector<double> d;
  MatrixN3 last;
  for (const double h : {0.01, 0.005, 0.0025, 0.00125}) {
    const MethodRun r = testing::RunRow(s, row, h);
    EXPECT_TRUE(r.ok()) << row << " h = " << h << ": " << r.message;
    if (!r.ok() || r.trajectory.positions.empty()) return {};
    const MatrixN3& x = r.trajectory.positions.back();
    if (last.size() > 0) d.push_back(std::sqrt((x - last).rowwise().squaredNorm().mean()));
    last = x;
  }
  return d;
}

TEST(FrictionCap, TheSystemCapConvergesOnALandingSheetAndTheMassCapDoesNot) {
  for (const std::string row : {"implicit_euler", "baraff_witkin"}) {
    const std::vector<double> system = EndDistances(FrictionCap::kSystem, row);
    const std::vector<double> mass = EndDistances(FrictionCap::kMass, row);
    ASSERT_EQ(system.size(), 3u) << row;
    ASSERT_EQ(mass.size(), 3u) << row;
    for (std::size_t k = 1; k < system.size(); ++k)
      EXPECT_LE(system[k], 0.7 * system[k - 1]) << row << ": d = " << system[0] << ", " << system[1] << ", " << system[2];
    EXPECT_GE(mass.back(), 0.8 * mass.front()) << row << ": d = " << mass[0] << ", " << mass[1] << ", " << mass[2];
  }
}

}  // namespace
}  // namespace clothbench
