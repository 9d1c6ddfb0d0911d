// Closed-form Jacobians (model/force_terms.cc, solver/tangent.cc;
// docs/model.md "Closed-form Jacobians") against the AutoDiff oracle.
//
// Tolerance 1e-12 relative to the largest entry of the term's Jacobian: the
// closed forms and forward-mode AutoDiff evaluate the same derivative with
// different operation orders, so they differ by round-off, a few ulps of
// the largest intermediate products (~1e-15 relative); a wrong or missing
// block is O(1) relative. The central-difference check of the same closed
// forms is in force_test.cc and tangent_test.cc.
#include <algorithm>
#include <string>

#include <gtest/gtest.h>
#include <omp.h>

#include <fmt/format.h>

#include "solver/tangent.h"
#include "verify/test_scenes.h"

namespace clothbench {
namespace {

using testing::MaxAbs;
using testing::ToSparse;

// max |closed − AD| / max |AD| for ∂g/∂x and ∂g/∂v of every term of `sys`.
void ExpectClosedFormEqualsAutoDiff(const ParticleSystem& sys, const MatrixN3& x, const MatrixN3& v,
                                    const std::string& what) {
  const int n3 = 3 * sys.num_particles();
  for (const auto& term : sys.terms()) {
    std::vector<Triplet> cx, cv, ax, av;
    term->AddJacobian(0.37, x, v, &cx, &cv);
    term->AddJacobianAutoDiff(0.37, x, v, &ax, &av);
    const SparseMatrix dx = ToSparse(n3, cx) - ToSparse(n3, ax), dv = ToSparse(n3, cv) - ToSparse(n3, av);
    const double scale_x = MaxAbs(ToSparse(n3, ax)), scale_v = MaxAbs(ToSparse(n3, av));
    if (scale_x > 0.0) {
      EXPECT_LE(MaxAbs(dx) / scale_x, 1e-12) << what << ' ' << term->name() << " d/dx";
    }
    if (scale_v > 0.0) {
      EXPECT_LE(MaxAbs(dv) / scale_v, 1e-12) << what << ' ' << term->name() << " d/dv";
    } else {
      EXPECT_EQ(MaxAbs(ToSparse(n3, cv)), 0.0) << what << ' ' << term->name();
    }
    if (term->name() != "gravity") {
      EXPECT_GT(scale_x + scale_v, 0.0) << what << ' ' << term->name();
    }
  }
}

// Every term of the all-terms sheet, both bending models, two states.
TEST(ClosedFormJacobian, EqualsAutoDiffOnEveryTerm) {
  for (BendModel bend : {BendModel::kThinPlate, BendModel::kMembrane}) {
    const ParticleSystem sys(testing::AllTermsScene(6, 5, bend));
    ASSERT_EQ(sys.terms().size(), 7u);
    for (unsigned seed : {3u, 11u}) {
      MatrixN3 x, v;
      testing::PerturbedState(sys, seed, &x, &v, 0.02);
      ExpectClosedFormEqualsAutoDiff(sys, x, v, fmt::format("{} seed {}", ToString(bend), seed));
    }
  }
}

// Every term on a curvilinear pattern (docs/model.md §2.7): a trapezoid
// with a curved hem, so that no two stencils share their rest geometry.
TEST(ClosedFormJacobian, EqualsAutoDiffOnACurvilinearPattern) {
  const PatternSpec p = testing::CurvedPanel();
  for (BendModel bend : {BendModel::kThinPlate, BendModel::kMembrane}) {
    Scene s = testing::AllTermsScene(7, 6, bend);
    SetCurvilinearCloth(&s, p, SamplePattern(p));
    const ParticleSystem sys(s);
    ASSERT_EQ(sys.terms().size(), 7u);
    MatrixN3 x, v;
    testing::PerturbedState(sys, 13, &x, &v, 0.02);
    ExpectClosedFormEqualsAutoDiff(sys, x, v, fmt::format("curvilinear {}", ToString(bend)));
  }
}

// Every builtin scene with its own material, at 9×8 particles, in a
// perturbed state (obstacles play no part in the force Jacobian).
TEST(ClosedFormJacobian, EqualsAutoDiffOnEveryScene) {
  for (const char* name : {"swinging_sheet", "hanging_sheet", "wind_sheet", "tablecloth", "round_table",
                           "swinging_box", "avatar_drape", "large_sheet"}) {
    Scene s = BuiltinScene(name);
    s.grid.nu = 9;
    s.grid.nv = 8;
    s.fixed.clear();
    s.obstacles.clear();
    const ParticleSystem sys(s);
    MatrixN3 x, v;
    testing::PerturbedState(sys, 5, &x, &v, 0.01);
    ExpectClosedFormEqualsAutoDiff(sys, x, v, name);
  }
}

// J_α without clamp or symmetrisation equals M − αh ∂f/∂v − α²h² ∂f/∂x
// assembled from the AutoDiff triplets and the Laplacians.
TEST(ClosedFormJacobian, TangentSystemEqualsAutoDiffAssembly) {
  for (BendModel bend : {BendModel::kThinPlate, BendModel::kMembrane}) {
    const ParticleSystem sys(testing::AllTermsScene(7, 6, bend));
    MatrixN3 x, v;
    testing::PerturbedState(sys, 9, &x, &v, 0.02);
    const double t = 0.37, alpha_h = 2.0 / 3.0 * 0.01;
    TangentSystem ts(sys, {TangentProjection::kNone, true, false});
    ts.Update(t, x, v, alpha_h);
    const int n = sys.num_particles(), n3 = 3 * n;
    std::vector<Triplet> jx, jv;
    for (int col = 0; col < n; ++col)
      for (SparseMatrix::InnerIterator it(sys.stiffness_laplacian(), col); it; ++it)
        for (int c = 0; c < 3; ++c) jx.emplace_back(3 * static_cast<int>(it.row()) + c, 3 * col + c, -it.value());
    for (int col = 0; col < n; ++col)
      for (SparseMatrix::InnerIterator it(sys.damping_laplacian(), col); it; ++it)
        for (int c = 0; c < 3; ++c) jv.emplace_back(3 * static_cast<int>(it.row()) + c, 3 * col + c, -it.value());
    for (const auto& term : sys.terms()) term->AddJacobianAutoDiff(t, x, v, &jx, &jv);
    SparseMatrix ref = -(alpha_h * alpha_h) * ToSparse(n3, jx) - alpha_h * ToSparse(n3, jv);
    for (int k = 0; k < n3; ++k) ref.coeffRef(k, k) += sys.masses()(k / 3);
    EXPECT_LE(MaxAbs(SparseMatrix(ts.matrix() - ref)) / MaxAbs(ref), 1e-12) << ToString(bend);

    // The Jacobian products of the last Update against the same triplets.
    MatrixN3 u, w, out = MatrixN3::Zero(n, 3), expect = MatrixN3::Zero(n, 3);
    testing::PerturbedState(sys, 13, &u, &w);
    ts.AddJacobianProducts(0.3, u, -0.7, w, &out);
    const SparseMatrix kx = ToSparse(n3, jx), kv = ToSparse(n3, jv);
    MatrixN3R ur = u, wr = w, er(n, 3);
    Eigen::Map<Eigen::VectorXd>(er.data(), n3) = 0.3 * (kx * Eigen::Map<const Eigen::VectorXd>(ur.data(), n3)) -
                                                 0.7 * (kv * Eigen::Map<const Eigen::VectorXd>(wr.data(), n3));
    expect = er;
    EXPECT_LE((out - expect).cwiseAbs().maxCoeff() / expect.cwiseAbs().maxCoeff(), 1e-12) << ToString(bend);
  }
}

// The threaded assembly (colours of ≥ 2048 centres) gives J_α and the
// Jacobian products bit for bit as one thread does.
TEST(ClosedFormJacobian, BitIdenticalAcrossThreadCounts) {
  const ParticleSystem sys(testing::AllTermsScene(200, 150));
  MatrixN3 x, v;
  testing::PerturbedState(sys, 7, &x, &v);
  TangentSystem a(sys, {TangentProjection::kClamp, true, true}), b(sys, {TangentProjection::kClamp, true, true});
  const int n = sys.num_particles();
  MatrixN3 pa = MatrixN3::Zero(n, 3), pb = MatrixN3::Zero(n, 3);
  testing::WithThreads(1, [&] {
    a.Update(0.3, x, v, 0.01);
    a.AddJacobianProducts(1e-4, v, 1e-2, v, &pa);
  });
  testing::WithThreads(2, [&] {
    b.Update(0.3, x, v, 0.01);
    b.AddJacobianProducts(1e-4, v, 1e-2, v, &pb);
  });
  ASSERT_EQ(a.matrix().nonZeros(), b.matrix().nonZeros());
  const Eigen::Map<const Eigen::VectorXd> va(a.matrix().valuePtr(), a.matrix().nonZeros()),
      vb(b.matrix().valuePtr(), b.matrix().nonZeros());
  EXPECT_EQ((va - vb).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((pa - pb).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_GT(pa.norm(), 0.0);
}

}  // namespace
}  // namespace clothbench
