// Properties of the discrete model and the step engine:
// momentum conservation by internal forces, invariance under placement
// (rotation + translation) and under particle order (transposing the grid),
// and bit-for-bit reproducibility (also in integrator_test.cc).
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include "solver/run.h"
#include "verify/test_metrics.h"
#include "verify/test_scenes.h"

namespace clothbench {
namespace {

Scene SmallSheet() {
  Scene s = DefaultScene();
  s.grid.nu = 8;
  s.grid.nv = 6;
  s.grid.size = {0.28, 0.20};
  s.fixed = {s.Index(0, 5), s.Index(7, 5)};
  s.t_end = 0.05;
  s.frame_dt = 0.01;
  s.solver.cg_tolerance = 1e-12;
  s.solver.max_updates = 200;
  return s;
}

// A free sheet (no fixed particles, no gravity) with tension, shear and
// transverse forces: Σ F_internal = 0 and 1ᵀL = 0, so every method keeps
// P = Σ m v up to the CG residual (‖r‖ ≤ 1e-13 ‖b‖ per solve). Bending is
// left out: its projection onto vertex normals (Alg. 3/4) is not
// momentum-conserving. Bound: 1e-10 of Σ m|v|.
TEST(Properties, InternalForcesConserveMomentum) {
  Scene s = testing::InternalForcesScene(6, 5);
  s.solver.cg_tolerance = 1e-13;
  s.solver.max_updates = 200;
  const ParticleSystem sys(s);
  MatrixN3 x, v;
  testing::PerturbedState(sys, 11, &x, &v, 0.005);
  for (Method m : testing::EngineMethods()) {
    StepEngine e(sys, m, s.solver);
    e.Reset(0.0, x, v);
    const Eigen::RowVector3d p0 = sys.masses().transpose() * v;
    const double scale = (sys.masses().asDiagonal() * v).rowwise().norm().sum();
    for (int k = 0; k < 20; ++k) ASSERT_EQ(e.Step(2e-4).status, StepStatus::kOk) << ToString(m);
    const Eigen::RowVector3d p1 = sys.masses().transpose() * e.v();
    EXPECT_LT((p1 - p0).norm(), 1e-10 * scale) << ToString(m) << ": ΔP = " << (p1 - p0);
  }
}

// Rotating and translating the scene (origin, axes, gravity) rotates and
// translates the trajectory. The solver sees different round-off, so PCG may
// stop at a different iterate within its tolerance η = 1e-12: the bound
// 1e-9 m (sheet size 0.28 m) allows η·cond(A) with cond(A) ≲ 1e3.
TEST(Properties, PlacementInvariance) {
  const Scene s = SmallSheet();
  const Eigen::Matrix3d rot = Eigen::AngleAxisd(1.1, Vector3(0.3, -1.0, 0.6).normalized()).toRotationMatrix();
  const Vector3 shift(5.0, -3.0, 12.0);
  Scene moved = s;
  moved.grid.origin = rot * s.grid.origin + shift;
  moved.grid.u_axis = rot * s.grid.u_axis;
  moved.grid.v_axis = rot * s.grid.v_axis;
  moved.forces.gravity = rot * s.forces.gravity;
  const ParticleSystem a(s), b(moved);
  for (Method m : testing::EngineMethods()) {
    const RunSummary ra = RunIntegrator(a, m, {0.001, s.t_end, s.frame_dt});
    const RunSummary rb = RunIntegrator(b, m, {0.001, s.t_end, s.frame_dt});
    ASSERT_TRUE(ra.ok() && rb.ok()) << ToString(m);
    const MatrixN3 expect = (ra.trajectory.positions.back() * rot.transpose()).rowwise() + shift.transpose();
    const double diff = (rb.trajectory.positions.back() - expect).cwiseAbs().maxCoeff();
    std::printf("[ placement ] %-18s max |x' - (R x + T)| = %.2e m\n", std::string(ToString(m)).c_str(), diff);
    EXPECT_LT(diff, 1e-9) << ToString(m);
  }
}

// Transposing the grid (u ↔ v, nu ↔ nv, k_u ↔ k_v, B_u ↔ B_v) renumbers the
// particles, (i, j) → (j, i), and changes the IC(0) ordering, but not the
// physics: the trajectories agree within the PCG tolerance (same bound).
TEST(Properties, ParticleOrderInvariance) {
  Scene s = SmallSheet();
  s.material.tension = {1000.0, 700.0};
  s.material.bend = {1e-5, 2e-5};
  Scene t = s;
  t.grid.nu = s.grid.nv;
  t.grid.nv = s.grid.nu;
  t.grid.size = {s.grid.size[1], s.grid.size[0]};
  t.grid.u_axis = s.grid.v_axis;
  t.grid.v_axis = s.grid.u_axis;
  t.material.tension = {s.material.tension[1], s.material.tension[0]};
  t.material.bend = {s.material.bend[1], s.material.bend[0]};
  t.fixed.clear();
  for (int p : s.fixed) t.fixed.push_back(t.Index(p / s.grid.nu, p % s.grid.nu));
  std::sort(t.fixed.begin(), t.fixed.end());
  const ParticleSystem a(s), b(t);
  for (Method m : testing::EngineMethods()) {
    const RunSummary ra = RunIntegrator(a, m, {0.001, s.t_end, s.frame_dt});
    const RunSummary rb = RunIntegrator(b, m, {0.001, s.t_end, s.frame_dt});
    ASSERT_TRUE(ra.ok() && rb.ok()) << ToString(m);
    double diff = 0.0;
    for (int j = 0; j < s.grid.nv; ++j)
      for (int i = 0; i < s.grid.nu; ++i)
        diff = std::max(diff, (ra.trajectory.positions.back().row(s.Index(i, j)) -
                               rb.trajectory.positions.back().row(t.Index(j, i)))
                                  .cwiseAbs()
                                  .maxCoeff());
    std::printf("[ particle order ] %-18s max diff = %.2e m\n", std::string(ToString(m)).c_str(), diff);
    EXPECT_LT(diff, 1e-9) << ToString(m);
  }
}

}  // namespace
}  // namespace clothbench
