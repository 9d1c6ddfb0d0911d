// Force terms (docs/model.md §2): exact Jacobians against central finite differences,
// conservation of momentum, invariance under rigid motions, and bending
// that vanishes on a flat sheet and opposes curvature.
//
// Finite-difference tolerance: central differences with step ε = 1e-6 have
// truncation error O(ε² |f'''|) ≈ 1e-12·|f'''| and round-off
// O(1e-16 |f| / ε) ≈ 1e-10 |f|; relative to the largest Jacobian entry a
// mismatch above 1e-6 therefore means a wrong derivative, not noise.
#include <algorithm>

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>

#include "model/particle_system.h"
#include "verify/test_scenes.h"

namespace clothbench {
namespace {

using Dense = Eigen::MatrixXd;

Dense ToDense(int n3, const std::vector<Triplet>& t) {
  SparseMatrix m(n3, n3);
  m.setFromTriplets(t.begin(), t.end());
  return Dense(m);
}

// Central-difference Jacobian of `force` with respect to x (wrt_x) or v.
template <class F>
Dense FiniteDifference(const MatrixN3& x, const MatrixN3& v, bool wrt_x, F force) {
  const int n = static_cast<int>(x.rows());
  Dense j(3 * n, 3 * n);
  const double eps = 1e-6;
  MatrixN3 fp(n, 3), fm(n, 3);
  for (int p = 0; p < n; ++p)
    for (int c = 0; c < 3; ++c) {
      MatrixN3 xp = x, xm = x, vp = v, vm = v;
      (wrt_x ? xp : vp)(p, c) += eps;
      (wrt_x ? xm : vm)(p, c) -= eps;
      force(xp, vp, &fp);
      force(xm, vm, &fm);
      for (int q = 0; q < n; ++q)
        for (int r = 0; r < 3; ++r) j(3 * q + r, 3 * p + c) = (fp(q, r) - fm(q, r)) / (2 * eps);
    }
  return j;
}

class JacobianTest : public ::testing::TestWithParam<BendModel> {};

TEST_P(JacobianTest, EveryTermMatchesCentralDifferences) {
  // 7×6: the bending terms have interior centres (their row path, AddInterior) and border ones.
  const ParticleSystem sys(testing::AllTermsScene(7, 6, GetParam()));
  MatrixN3 x, v;
  testing::PerturbedState(sys, 7, &x, &v);
  const int n3 = 3 * sys.num_particles();
  const double t = 0.37;
  ASSERT_GE(sys.terms().size(), 7u);  // tension_nonlinear, shear, bend, transverse, gravity, wind, air
  for (const auto& term : sys.terms()) {
    SCOPED_TRACE(std::string(term->name()));
    std::vector<Triplet> tx, tv;
    term->AddJacobian(t, x, v, &tx, &tv);
    auto f = [&](const MatrixN3& xx, const MatrixN3& vv, MatrixN3* out) {
      out->setZero();
      term->AddForce(t, xx, vv, out);
    };
    const Dense jx = ToDense(n3, tx), jv = ToDense(n3, tv);
    const Dense fx = FiniteDifference(x, v, true, f), fv = FiniteDifference(x, v, false, f);
    const double scale = std::max({jx.cwiseAbs().maxCoeff(), jv.cwiseAbs().maxCoeff(), 1e-12});
    EXPECT_LT((jx - fx).cwiseAbs().maxCoeff() / scale, 1e-6);
    EXPECT_LT((jv - fv).cwiseAbs().maxCoeff() / scale, 1e-6);
  }
  // The full force, linear part included.
  std::vector<Triplet> tx, tv;
  sys.ForceJacobian(t, x, v, &tx, &tv);
  auto f = [&](const MatrixN3& xx, const MatrixN3& vv, MatrixN3* out) { sys.Forces(t, xx, vv, out); };
  const Dense jx = ToDense(n3, tx), fx = FiniteDifference(x, v, true, f);
  const Dense jv = ToDense(n3, tv), fv = FiniteDifference(x, v, false, f);
  EXPECT_LT((jx - fx).cwiseAbs().maxCoeff() / jx.cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_LT((jv - fv).cwiseAbs().maxCoeff() / jv.cwiseAbs().maxCoeff(), 1e-6);
}

// The per-particle access of vertex-block methods (ParticleSystem::
// ParticleForce) is row p of the assembled force and block (p, p) of the
// assembled Jacobians, every term included; the particle graph holds every
// off-diagonal block of the Jacobians. The forces are summed in another
// order than Forces' (by the items that write p), so they agree to
// round-off: 1e-12 of the largest force.
TEST_P(JacobianTest, ParticleForceIsTheRowAndDiagonalBlock) {
  const ParticleSystem sys(testing::AllTermsScene(7, 6, GetParam()));
  MatrixN3 x, v, f(sys.num_particles(), 3);
  testing::PerturbedState(sys, 11, &x, &v);
  const int n = sys.num_particles();
  const double t = 0.37;
  sys.Forces(t, x, v, &f);
  std::vector<Triplet> tx, tv;
  sys.ForceJacobian(t, x, v, &tx, &tv);
  const Dense jx = ToDense(3 * n, tx), jv = ToDense(3 * n, tv);
  sys.PrepareParticleForces();
  const double fscale = f.cwiseAbs().maxCoeff();
  const double jscale = std::max(jx.cwiseAbs().maxCoeff(), jv.cwiseAbs().maxCoeff());
  for (int p = 0; p < n; ++p) {
    Vector3 fp;
    Matrix3 dx, dv;
    sys.ParticleForce(t, x, v, p, &fp, &dx, &dv);
    EXPECT_LT((fp - f.row(p).transpose()).cwiseAbs().maxCoeff(), 1e-12 * fscale) << p;
    EXPECT_LT((dx - jx.block<3, 3>(3 * p, 3 * p)).cwiseAbs().maxCoeff(), 1e-12 * jscale) << p;
    EXPECT_LT((dv - jv.block<3, 3>(3 * p, 3 * p)).cwiseAbs().maxCoeff(), 1e-12 * jscale) << p;
  }
  std::vector<int> offsets, neighbours;
  sys.ParticleGraph(&offsets, &neighbours);
  ASSERT_EQ(offsets.size(), static_cast<std::size_t>(n) + 1);
  const auto linked = [&](int p, int q) {
    return std::binary_search(neighbours.begin() + offsets[static_cast<std::size_t>(p)],
                              neighbours.begin() + offsets[static_cast<std::size_t>(p) + 1], q);
  };
  int blocks = 0;
  for (int p = 0; p < n; ++p)
    for (int q = 0; q < n; ++q) {
      if (p == q) continue;
      const bool nonzero = jx.block<3, 3>(3 * p, 3 * q).cwiseAbs().maxCoeff() > 0.0 ||
                           jv.block<3, 3>(3 * p, 3 * q).cwiseAbs().maxCoeff() > 0.0;
      if (!nonzero) continue;
      ++blocks;
      EXPECT_TRUE(linked(p, q) && linked(q, p)) << p << " reads " << q;
    }
  // 378 blocks on this 7×6 sheet, mostly border: at least the four spring
  // neighbours' (p, q) and (q, p) of every particle's edges, 2·(6·6 + 7·5).
  EXPECT_GE(blocks, 2 * (6 * 6 + 7 * 5));
}

INSTANTIATE_TEST_SUITE_P(BendModels, JacobianTest, ::testing::Values(BendModel::kThinPlate, BendModel::kMembrane),
                         [](const auto& param_info) { return std::string(ToString(param_info.param)); });

// The full-tension Jacobian has the closed form of docs/model.md §2.1:
// ∂F_a/∂x_b = s_e[(1 − l_e/|d|) I + (l_e/|d|) d̂d̂ᵀ].
TEST(Tension, FullSpringJacobianHasClosedForm) {
  Scene s;
  s.grid.nu = 2;
  s.grid.nv = 2;
  s.grid.size = {0.5, 0.5};
  s.material.tension = {300.0, 300.0};
  s.forces.gravity.setZero();
  const ParticleSystem sys(s);
  MatrixN3 x = sys.rest_positions(), v = MatrixN3::Zero(4, 3);
  x.row(1) += Eigen::RowVector3d(0.1, 0.05, -0.07);
  std::vector<Triplet> tx, tv;
  sys.ForceJacobian(0.0, x, v, &tx, &tv);
  const Dense j = ToDense(12, tx);
  const Vector3 d = (x.row(1) - x.row(0)).transpose();
  const double len = d.norm(), se = 300.0, le = 0.5;
  const Vector3 dh = d / len;
  const Eigen::Matrix3d expect = se * ((1 - le / len) * Eigen::Matrix3d::Identity() + (le / len) * dh * dh.transpose());
  EXPECT_LT((j.block<3, 3>(0, 3) - expect).norm(), 1e-12 * se);
}

// Internal forces (tension, shear, transverse) conserve linear momentum:
// Σ_p F_p = 0 to round-off. Bending projected onto vertex normals
// (Alg. 3/4) does not, so it is checked separately below.
TEST(InternalForces, SumToZero) {
  Scene s = testing::InternalForcesScene(6, 5);
  const ParticleSystem sys(s);
  MatrixN3 x, v, f(sys.num_particles(), 3);
  testing::PerturbedState(sys, 3, &x, &v, 0.02);
  sys.Forces(0.0, x, v, &f);
  const double scale = f.cwiseAbs().maxCoeff();
  ASSERT_GT(scale, 1e-3);
  EXPECT_LT(f.colwise().sum().norm(), 1e-12 * scale * sys.num_particles());
}

// A rigidly rotated and translated sheet at rest length has zero internal
// force in every term (tension, shear, bending, transverse).
TEST(InternalForces, ZeroForRigidMotionAtRest) {
  for (BendModel bend : {BendModel::kThinPlate, BendModel::kMembrane}) {
    Scene s = testing::AllTermsScene(7, 6, bend);
    s.forces.gravity.setZero();
    s.forces.wind.reset();
    s.forces.air = 0.0;
    const ParticleSystem sys(s);
    const Eigen::Matrix3d rot = Eigen::AngleAxisd(0.7, Vector3(1.0, -2.0, 0.5).normalized()).toRotationMatrix();
    const MatrixN3 x = (sys.rest_positions() * rot.transpose()).rowwise() + Eigen::RowVector3d(0.3, -1.2, 4.0);
    MatrixN3 f(sys.num_particles(), 3);
    sys.Forces(0.0, x, MatrixN3::Zero(sys.num_particles(), 3), &f);
    // Spring forces are s_e·l_e ≈ 10 N in magnitude; cancellation leaves round-off.
    EXPECT_LT(f.cwiseAbs().maxCoeff(), 1e-11) << ToString(bend);
  }
}

// Bending: zero on a flat sheet (any in-plane stretch), restoring on a bump.
TEST(Bending, FlatSheetHasZeroForceAndCurvedSheetRelaxes) {
  for (BendModel bend : {BendModel::kThinPlate, BendModel::kMembrane}) {
    Scene s;
    s.grid.nu = 9;
    s.grid.nv = 8;
    s.grid.size = {0.4, 0.35};
    s.material.tension = {0.0, 0.0};
    s.material.bend = {1e-3, 2e-3};
    s.material.bend_model = bend;
    s.forces.gravity.setZero();
    const ParticleSystem sys(s);
    ASSERT_EQ(sys.terms().size(), 1u);
    const int n = sys.num_particles();
    MatrixN3 x = sys.rest_positions(), f(n, 3);
    const MatrixN3 v = MatrixN3::Zero(n, 3);
    for (int p = 0; p < n; ++p) x(p, 0) += 0.02 * x(p, 0) * x(p, 0);  // in-plane, non-uniform stretch
    sys.ExplicitForces(0.0, x, v, &f);
    EXPECT_LT(f.norm(), 1e-12) << ToString(bend);
    // A smooth bump: the bending force must do negative work against it.
    MatrixN3 bump = MatrixN3::Zero(n, 3);
    for (int j = 0; j < s.grid.nv; ++j)
      for (int i = 0; i < s.grid.nu; ++i)
        bump(s.Index(i, j), 2) = 0.01 * std::sin(M_PI * i / (s.grid.nu - 1)) * std::sin(M_PI * j / (s.grid.nv - 1));
    sys.ExplicitForces(0.0, sys.rest_positions() + bump, v, &f);
    EXPECT_LT((f.array() * bump.array()).sum(), 0.0) << ToString(bend);
    EXPECT_GT(f.norm(), 0.0);
  }
}

// Terms with zero coefficients are not assembled (docs/model.md §2.6).
TEST(ParticleSystem, AssemblesOnlyNeededTerms) {
  Scene s;
  s.material.shear = 0.0;
  s.material.bend = {0.0, 0.0};
  s.forces.gravity.setZero();
  EXPECT_EQ(ParticleSystem(s).TermNames(), std::vector<std::string>({"tension_nonlinear"}));
  s.material.tension_model = TensionModel::kLinear;
  EXPECT_TRUE(ParticleSystem(s).TermNames().empty());
  s.material.tension_damping = 0.0;
  EXPECT_FALSE(ParticleSystem(s).has_tension_damping());
  EXPECT_EQ(ParticleSystem(testing::AllTermsScene()).TermNames(),
            std::vector<std::string>({"tension_nonlinear", "shear", "bend_thin_plate", "transverse", "gravity", "wind", "air"}));
}

// L_K is a weighted graph Laplacian: symmetric, rows sum to zero (docs/model.md §2.1).
TEST(ParticleSystem, LaplacianProperties) {
  const ParticleSystem sys(DefaultScene());
  const Dense lk(sys.stiffness_laplacian());
  EXPECT_LT((lk - lk.transpose()).norm(), 1e-12);
  EXPECT_LT((lk * Eigen::VectorXd::Ones(lk.rows())).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_NEAR(lk(0, 1), -1000.0, 1e-9);  // s_e = k lv/lu = k on a square grid
}

}  // namespace
}  // namespace clothbench
