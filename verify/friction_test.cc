// The friction impulse's cap (model/solver_spec.h, FrictionCap;
// docs/notes/collisions.md, "The friction cap").
//
// 1. scenes/tilted_plane_10k.toml at 20 × 20 particles: the sheet lands on
//    its upper edge on a plane tilted 30° (friction 0.3 < tan 30°, so it
//    slides), folds onto it and slides down. Each row runs at h = 0.0025,
//    0.00125, 0.000625 and 0.0003125 s to t = 0.5 s; d_k is the rms distance
//    between the end positions of the k-th and (k+1)-th h.
//    - The system cap converges there: each d_k is at most 0.7 of the one
//      before, an observed order of at least 0.5 (measured ratios 0.11,
//      0.36 for implicit Euler and 0.16, 0.17 for Baraff–Witkin; contact
//      switches make the order of a non-smooth problem irregular).
//    - The mass cap does not yet: its d_k stay above 1 cm (1.7–2.5 cm
//      measured), so this test tells the two caps apart.
// 2. The cap never reverses a particle: on scenes/round_table.toml, where
//    the cloth comes to rest on the table, SBDF(2) at h = 0.00125 s with the
//    system cap ends with friction work W_friction ≤ 0 (−5.5·10⁻⁵ J
//    measured). A cap at the diagonal entry A_pp instead, which can exceed
//    the impulse that stops the particle in the solve, ended at +4·10⁻⁴ J:
//    friction that feeds the resting cloth.
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
  for (const double h : {0.0025, 0.00125, 0.000625, 0.0003125}) {
    const MethodRun r = testing::RunRow(s, row, h);
    EXPECT_TRUE(r.ok()) << row << " h = " << h << ": " << r.message;
    if (!r.ok() || r.trajectory.positions.empty()) return {};
    const MatrixN3& x = r.trajectory.positions.back();
    if (last.size() > 0) d.push_back(std::sqrt((x - last).rowwise().squaredNorm().mean()));
    last = x;
  }
  return d;
}

TEST(FrictionCap, TheSystemCapConvergesOnALandingSheetAndTheMassCapDoesNotYet) {
  for (const std::string row : {"implicit_euler", "baraff_witkin"}) {
    const std::vector<double> system = EndDistances(FrictionCap::kSystem, row);
    const std::vector<double> mass = EndDistances(FrictionCap::kMass, row);
    ASSERT_EQ(system.size(), 3u) << row;
    ASSERT_EQ(mass.size(), 3u) << row;
    for (std::size_t k = 1; k < system.size(); ++k)
      EXPECT_LE(system[k], 0.7 * system[k - 1]) << row << ": d = " << system[0] << ", " << system[1] << ", " << system[2];
    for (const double d : mass) EXPECT_GT(d, 0.01) << row << ": d = " << mass[0] << ", " << mass[1] << ", " << mass[2];
  }
}

TEST(FrictionCap, TheSystemCapDoesNotFeedRestingCloth) {
  Scene s = LoadScene(std::string(CLOTHBENCH_SCENES_DIR) + "/round_table.toml");
  s.frame_dt = s.t_end;
  s.solver.friction_cap = FrictionCap::kSystem;
  const MethodRun r = testing::RunRow(s, "sbdf2", 0.00125);
  ASSERT_TRUE(r.ok()) << r.message;
  ASSERT_FALSE(r.trajectory.contact_work_friction.empty());
  EXPECT_LE(r.trajectory.contact_work_friction.back(), 0.0);
}

}  // namespace
}  // namespace clothbench
