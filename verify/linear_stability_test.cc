// Linear stability: on a single damped spring, the step
// engine reproduces each method's exact amplification matrix.
//
// Scene: a 2×2 grid with three fixed particles and one free particle p tied
// by zero-rest-length springs (tension_model = "linear") to two fixed
// neighbours at rest: each coordinate obeys y' = J y with y = (x − x_eq, v),
//   J = [[0, 1], [−k/m, −c/m]],  k = s_u + s_v,  c = c_u + c_v.
// With g ≡ 0 every method is linear and one step is y₁ = R y₀ with
//   implicit/IMEX Euler   R = (I − hJ)⁻¹                               (3.21)
//   implicit midpoint     R = (I − hJ/2)⁻¹ (I + hJ/2)                  (3.26)
// and BDF(2)/SBDF(2) y₁ = (I − c3 hJ)⁻¹ (c1 y₀ − c2 y₋₁)               (3.30).
// One free particle makes A_α effectively 1×1 on the free DOFs, so PCG is
// exact after one iteration and the only error is round-off. We require
// |y₁ − R y₀| ≤ 1e-12 |y_init| per step, relative to the initial state: at
// hω = 1000 the state decays by ~1e3 per step and soon lies below the
// round-off of the absolute positions (x ≈ 0.05 m, ulp ≈ 1e-17 m), so a bound
// relative to the decayed state would measure round-off, not the method.
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include "solver/integrator.h"

namespace clothbench {
namespace {

struct SpringSetup {
  Scene scene;
  int p = 3;  // the free particle (1,1)
  double k = 0.0, c = 0.0, m = 0.0;
};

SpringSetup MakeSpring(double stiffness, double damping) {
  SpringSetup s;
  Scene& sc = s.scene;
  sc.grid.nu = sc.grid.nv = 2;
  sc.grid.size = {0.1, 0.1};
  sc.material.tension = {stiffness, stiffness};
  sc.material.tension_model = TensionModel::kLinear;
  sc.material.tension_damping = damping;
  sc.material.shear = 0.0;
  sc.material.bend = {0.0, 0.0};
  sc.forces.gravity.setZero();
  sc.fixed = {0, 1, 2};
  sc.solver.cg_tolerance = 1e-15;
  s.k = 2 * stiffness;  // two springs, s_e = k·l/l
  s.c = 2 * damping;
  s.m = sc.material.density * 0.1 * 0.1;
  return s;
}

// x_eq of the free particle: the mean of its two fixed neighbours.
Eigen::Matrix2d JacobianOf(const SpringSetup& s) {
  Eigen::Matrix2d j;
  j << 0.0, 1.0, -s.k / s.m, -s.c / s.m;
  return j;
}

class AmplificationTest : public ::testing::TestWithParam<Method> {};

TEST_P(AmplificationTest, StepMatchesStabilityFunction) {
  const Method method = GetParam();
  for (double hw : {0.1, 1.0, 10.0, 1000.0}) {     // h ω from non-stiff to very stiff
    for (double zeta : {0.0, 0.05, 2.0}) {          // undamped, light, overdamped
      SpringSetup s = MakeSpring(100.0, 0.0);
      const double omega = std::sqrt(s.k / s.m);
      s.scene.material.tension_damping = zeta * std::sqrt(s.k * s.m);  // c = 2ζ√(km), two springs
      s.c = 2 * s.scene.material.tension_damping;
      const ParticleSystem sys(s.scene);
      const double h = hw / omega;
      const Eigen::Matrix2d j = JacobianOf(s), id = Eigen::Matrix2d::Identity();
      const Vector3 xeq = 0.5 * (sys.rest_positions().row(1) + sys.rest_positions().row(2)).transpose();

      MatrixN3 x = sys.rest_positions(), v = MatrixN3::Zero(4, 3);
      x.row(s.p) = (xeq + Vector3(0.01, -0.02, 0.03)).transpose();
      v.row(s.p) = Vector3(0.5, 0.2, -0.4).transpose();
      StepEngine e(sys, method, s.scene.solver);
      e.Reset(0.0, x, v);
      // State per coordinate c: y = (x − x_eq, v).
      auto state = [&](const StepEngine& en, int c) {
        return Eigen::Vector2d(en.x()(s.p, c) - xeq(c), en.v()(s.p, c));
      };
      Eigen::Vector2d prev[3], cur[3], older[3];
      double initial = 0.0;
      for (int c = 0; c < 3; ++c) {
        cur[c] = state(e, c);
        initial = std::max(initial, cur[c].norm());
      }
      for (int n = 0; n < 4; ++n) {
        for (int c = 0; c < 3; ++c) prev[c] = cur[c];
        ASSERT_EQ(e.Step(h).status, StepStatus::kOk);
        for (int c = 0; c < 3; ++c) {
          cur[c] = state(e, c);
          Eigen::Vector2d expect;
          switch (method) {
            case Method::kImexEuler:
            case Method::kImplicitEuler:
              expect = (id - h * j).lu().solve(prev[c]);
              break;
            case Method::kImplicitMidpoint:
              expect = (id - 0.5 * h * j).lu().solve((id + 0.5 * h * j) * prev[c]);
              break;
            default:
              break;
          }
          // Multistep methods start with an implicit Euler step (docs/model.md §4).
          if (method == Method::kSbdf2 || method == Method::kBdf2) {
            if (n == 0) {
              expect = (id - h * j).lu().solve(prev[c]);
            } else {
              const Bdf2Coefficients b(1.0);
              expect = (id - b.c3 * h * j).lu().solve(b.c1 * prev[c] - b.c2 * older[c]);
            }
            older[c] = prev[c];
          }
          EXPECT_LT((cur[c] - expect).norm() / initial, 1e-12)
              << ToString(method) << " hω=" << hw << " ζ=" << zeta << " step " << n << " coord " << c;
        }
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Integrators, AmplificationTest, ::testing::ValuesIn(ThesisTableMethods()),
                         [](const auto& param_info) { return std::string(ToString(param_info.param)); });

// Spectral radius of one-step amplification at hω → ∞ (ζ = 0): implicit
// Euler is L-stable (→ 0), implicit midpoint is not (|R| = 1). Printed for
// docs/notes/verification.md.
TEST(AmplificationTest, StiffLimit) {
  SpringSetup s = MakeSpring(100.0, 0.0);
  const Eigen::Matrix2d j = JacobianOf(s), id = Eigen::Matrix2d::Identity();
  const double h = 1e4 / std::sqrt(s.k / s.m);
  const double rho_ie = (id - h * j).inverse().eigenvalues().cwiseAbs().maxCoeff();
  const double rho_mp = ((id - 0.5 * h * j).inverse() * (id + 0.5 * h * j)).eigenvalues().cwiseAbs().maxCoeff();
  std::printf("[ stiff limit ] h*omega = 1e4: rho(R_implicit_euler) = %.3e, rho(R_midpoint) = %.6f\n", rho_ie, rho_mp);
  EXPECT_LT(rho_ie, 1e-3);
  EXPECT_NEAR(rho_mp, 1.0, 1e-12);
}

}  // namespace
}  // namespace clothbench
