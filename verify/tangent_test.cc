// The tangent system J_α = M − αh ∂f/∂v − α²h² ∂f/∂x (solver/tangent.h;
// docs/model.md §2.1, §10).
// 1. Without the clamp, J_α equals M − αh ∂f/∂v − α²h² ∂f/∂x with ∂f from
//    central differences of the total force (every term). Tolerance: the
//    central-difference truncation error is O(ε² f''') with ε = 1e-6 m
//    (1e-6 m/s), ~1e-12 relative, and its round-off ~1e-16·|f|/ε ≈ 1e-10·|f|;
//    1e-6 of the largest entry leaves margin and catches any wrong block
//    (O(1) relative).
// 2. The clamp changes only compressed springs' blocks.
// 3. On the thesis' scenes, in a deformed state (0.2 s of SBDF(2)), J_α with
//    the clamp and tension only is symmetric (to 1e-12 relative) and
//    positive definite (a sparse Cholesky factorisation succeeds); the other
//    combinations are recorded as test properties.
#include <gtest/gtest.h>

#include <Eigen/SparseCholesky>

#include <fmt/format.h>

#include "solver/integrator.h"
#include "solver/tangent.h"
#include "verify/test_scenes.h"

namespace clothbench {
namespace {

TEST(TangentSystem, MatchesCentralDifferencesWithoutClamp) {
  const ParticleSystem sys(testing::AllTermsScene(5, 4));
  MatrixN3 x, v;
  testing::PerturbedState(sys, 3, &x, &v, 0.02);
  const double t = 0.37, alpha_h = 0.7 * 0.01;
  TangentSystem ts(sys, {TangentProjection::kNone, true});
  ts.Update(t, x, v, alpha_h);
  const Eigen::MatrixXd j(ts.matrix());
  const int n = sys.num_particles();
  Eigen::MatrixXd ref = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  for (int k = 0; k < 3 * n; ++k) ref(k, k) = sys.masses()(k / 3);
  MatrixN3 fp(n, 3), fm(n, 3);
  const double eps = 1e-6;
  for (int p = 0; p < n; ++p)
    for (int c = 0; c < 3; ++c) {
      for (int which = 0; which < 2; ++which) {  // 0: ∂/∂x, 1: ∂/∂v
        MatrixN3 xp = x, xm = x, vp = v, vm = v;
        (which == 0 ? xp : vp)(p, c) += eps;
        (which == 0 ? xm : vm)(p, c) -= eps;
        sys.Forces(t, xp, vp, &fp);
        sys.Forces(t, xm, vm, &fm);
        const double scale = which == 0 ? -alpha_h * alpha_h : -alpha_h;
        for (int q = 0; q < n; ++q)
          for (int r = 0; r < 3; ++r) ref(3 * q + r, 3 * p + c) += scale * (fp(q, r) - fm(q, r)) / (2 * eps);
      }
    }
  const double tol = 1e-6 * ref.cwiseAbs().maxCoeff();
  EXPECT_LT((j - ref).cwiseAbs().maxCoeff(), tol);
}

TEST(TangentSystem, ClampChangesOnlyCompressedSprings) {
  Scene s = testing::AllTermsScene(5, 4);
  const ParticleSystem sys(s);
  const MatrixN3 v = MatrixN3::Zero(sys.num_particles(), 3);
  TangentSystem clamp(sys, {TangentProjection::kClamp, false}), none(sys, {TangentProjection::kNone, false});
  // Stretched by 1 %: no spring compressed, the two agree exactly.
  const MatrixN3 stretched = 1.01 * sys.rest_positions();
  clamp.Update(0.0, stretched, v, 0.01);
  none.Update(0.0, stretched, v, 0.01);
  EXPECT_EQ((Eigen::MatrixXd(clamp.matrix()) - Eigen::MatrixXd(none.matrix())).cwiseAbs().maxCoeff(), 0.0);
  // Compressed by 1 %: the exact transverse factor is negative and differs.
  const MatrixN3 compressed = 0.99 * sys.rest_positions();
  clamp.Update(0.0, compressed, v, 0.01);
  none.Update(0.0, compressed, v, 0.01);
  EXPECT_GT((Eigen::MatrixXd(clamp.matrix()) - Eigen::MatrixXd(none.matrix())).cwiseAbs().maxCoeff(), 0.0);
}

// Symmetric and positive definite with the clamp (tension only) on every
// thesis scene in a deformed state; the Cholesky factorisation is the test
// of definiteness.
TEST(TangentSystem, ClampedTensionIsSymmetricPositiveDefiniteOnThesisScenes) {
  for (const char* name : {"swinging_sheet", "hanging_sheet", "wind_sheet", "tablecloth", "round_table",
                           "swinging_box", "avatar_drape"}) {
    const Scene scene = BuiltinScene(name);
    const ParticleSystem sys(scene);
    StepEngine engine(sys, Method::kSbdf2, scene.solver);
    engine.Reset(0.0, sys.rest_positions(), MatrixN3::Zero(sys.num_particles(), 3));
    for (int k = 0; k < 20; ++k) ASSERT_EQ(engine.Step(scene.h).status, StepStatus::kOk) << name;
    for (bool explicit_terms : {false, true})
      for (TangentProjection proj : {TangentProjection::kClamp, TangentProjection::kNone}) {
        TangentSystem ts(sys, {proj, explicit_terms});
        ts.Update(engine.t(), engine.x(), engine.v(), scene.h);
        const SparseMatrix& j = ts.matrix();
        const SparseMatrix jt = j.transpose();
        const double asym = (j - jt).norm() / j.norm();
        Eigen::SimplicialLLT<SparseMatrix> llt(0.5 * (j + jt));
        const bool pd = llt.info() == Eigen::Success;
        RecordProperty(fmt::format("{}_{}_{}", name, proj == TangentProjection::kClamp ? "clamp" : "none",
                                   explicit_terms ? "all_terms" : "tension"),
                       fmt::format("asymmetry {:.2e}, {}", asym, pd ? "positive definite" : "not positive definite"));
        if (proj == TangentProjection::kClamp && !explicit_terms) {
          EXPECT_LT(asym, 1e-12) << name;
          EXPECT_TRUE(pd) << name;
        }
      }
  }
}

// TangentProduct must give y = J x bit for bit as Eigen's sparse product
// does (the same terms in the same order: the reproducibility the PCG and
// the thread-count tests rely on), on J's block pattern and on a matrix
// without it.
TEST(TangentSystem, ProductIsBitIdenticalToEigen) {
  const ParticleSystem sys(testing::AllTermsScene(9, 7));
  MatrixN3 x, v;
  testing::PerturbedState(sys, 5, &x, &v, 0.02);
  TangentSystem ts(sys, {TangentProjection::kClamp, true, true});
  ts.Update(0.3, x, v, 0.01);
  const int n = sys.num_particles();
  MatrixN3R u = MatrixN3R::Random(n, 3), y(n, 3);
  const Eigen::Map<const Eigen::VectorXd> uf(u.data(), 3 * n);
  const Eigen::Map<const Eigen::VectorXd> yf(y.data(), 3 * n);

  TangentProduct(ts.matrix(), u, &y);
  const Eigen::VectorXd expected = ts.matrix() * uf;
  EXPECT_EQ((yf - expected).cwiseAbs().maxCoeff(), 0.0);

  // Drop the pair (1, 0), (0, 1): still symmetric (the kernels read column
  // j as row j), no longer the block pattern.
  SparseMatrix scalar = ts.matrix();
  scalar.prune([](Eigen::Index r, Eigen::Index c, double) { return !(r + c == 1); });
  TangentProduct(scalar, u, &y);
  const Eigen::VectorXd expected_scalar = scalar * uf;
  EXPECT_EQ((yf - expected_scalar).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_NE((expected_scalar - expected).cwiseAbs().maxCoeff(), 0.0);  // the dropped entry mattered
}

}  // namespace
}  // namespace clothbench
