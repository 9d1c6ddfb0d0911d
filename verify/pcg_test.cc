// Filtered PCG (docs/model.md §5, Alg. 7) against a dense direct solve.
// Reference: with constrained directions C (orthonormal columns) and free
// directions F = complement, the solution of S(Âv − b) = 0, (I−S)v = z is
// v = F y + C z_c with (FᵀÂF) y = Fᵀ(b − Â C z_c), solved densely by LDLᵀ.
// Tolerance: PCG stops at ‖r‖ ≤ 1e-13 ‖Sb‖; the solution error is at most
// cond(A)·1e-13 ≈ 1e-10 relative for these matrices (cond ≲ 1e3), so 1e-8
// leaves margin while catching any projection error (which is O(1)).
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include "solver/integrator.h"
#include "solver/pcg.h"
#include "verify/test_scenes.h"

namespace clothbench {
namespace {

struct Problem {
  SparseMatrix a;
  MatrixN3 b;
};

Problem MakeProblem(const ParticleSystem& sys, double h) {
  SystemMatrix sm(sys, PreconditionerType::kNone);
  EXPECT_TRUE(sm.Update(h));
  Problem p{sm.matrix(), MatrixN3::Zero(sys.num_particles(), 3)};
  for (int i = 0; i < sys.num_particles(); ++i)
    p.b.row(i) = Vector3(std::sin(1.0 + i), std::cos(0.3 * i), 0.1 * i - 1.0).transpose() * 1e-2;
  return p;
}

// Dense reference for constraints given as (particle, direction, target).
MatrixN3 DenseSolve(const Problem& pr, const std::vector<std::tuple<int, Vector3, double>>& cons) {
  const int n = static_cast<int>(pr.a.rows());
  const Eigen::MatrixXd ad(pr.a);
  Eigen::MatrixXd a3 = Eigen::MatrixXd::Zero(3 * n, 3 * n);  // A ⊗ I₃
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) a3.block<3, 3>(3 * i, 3 * j) = ad(i, j) * Eigen::Matrix3d::Identity();
  Eigen::VectorXd b3(3 * n);
  for (int p = 0; p < n; ++p) b3.segment<3>(3 * p) = pr.b.row(p).transpose();
  // Orthonormal constrained basis per particle.
  Eigen::MatrixXd cmat = Eigen::MatrixXd::Zero(3 * n, 0);
  Eigen::VectorXd zc(0);
  std::vector<Eigen::Matrix3d> per(static_cast<std::size_t>(n), Eigen::Matrix3d::Zero());
  std::vector<int> count(static_cast<std::size_t>(n), 0);
  for (auto& [p, d, target] : cons) {
    Vector3 dd = d;
    for (int k = 0; k < count[p]; ++k) dd -= per[p].col(k).dot(dd) * per[p].col(k);
    dd.normalize();
    per[p].col(count[p]++) = dd;
    cmat.conservativeResize(3 * n, cmat.cols() + 1);
    cmat.col(cmat.cols() - 1).setZero();
    cmat.col(cmat.cols() - 1).segment<3>(3 * p) = dd;
    zc.conservativeResize(zc.size() + 1);
    zc(zc.size() - 1) = target;
  }
  // Free basis: orthonormal complement of span(C).
  Eigen::MatrixXd f;
  if (cmat.cols() == 0) {
    f = Eigen::MatrixXd::Identity(3 * n, 3 * n);
  } else {
    Eigen::FullPivHouseholderQR<Eigen::MatrixXd> qr(cmat);
    Eigen::MatrixXd q = qr.matrixQ();
    f = q.rightCols(3 * n - cmat.cols());
  }
  const Eigen::VectorXd vc = cmat.cols() ? Eigen::VectorXd(cmat * zc) : Eigen::VectorXd::Zero(3 * n);
  const Eigen::VectorXd y = (f.transpose() * a3 * f).ldlt().solve(f.transpose() * (b3 - a3 * vc));
  const Eigen::VectorXd v = f * y + vc;
  MatrixN3 out(n, 3);
  for (int p = 0; p < n; ++p) out.row(p) = v.segment<3>(3 * p).transpose();
  return out;
}

class PcgTest : public ::testing::TestWithParam<PreconditionerType> {};

TEST_P(PcgTest, MatchesDenseSolveWithAndWithoutConstraints) {
  const ParticleSystem sys(testing::AllTermsScene(6, 5));
  const Problem pr = MakeProblem(sys, 0.01);
  Preconditioner pre(GetParam());
  pre.Analyze(pr.a);
  ASSERT_TRUE(pre.Factorize(pr.a));
  PcgWorkspace work(sys.num_particles());
  const PcgOptions opts{1e-13, 1000};

  // 1. No constraints.
  {
    VelocityFilter none;
    MatrixN3 v = MatrixN3::Zero(sys.num_particles(), 3);
    const PcgSummary s = FilteredPcg(pr.a, pr.b, none, pre, opts, &v, &work);
    ASSERT_EQ(s.status, PcgStatus::kConverged);
    const MatrixN3 ref = DenseSolve(pr, {});
    EXPECT_LT((v - ref).norm() / ref.norm(), 1e-8);
  }
  // 2. Two fixed particles (zero and non-zero target), a one-direction and a
  //    two-direction constraint with non-zero targets.
  {
    VelocityFilter f;
    std::vector<std::tuple<int, Vector3, double>> cons;
    f.Fix(0);
    for (int c = 0; c < 3; ++c) cons.emplace_back(0, Vector3::Unit(c), 0.0);
    const Vector3 target(0.1, -0.2, 0.3);
    f.Fix(7, target);
    for (int c = 0; c < 3; ++c) cons.emplace_back(7, Vector3::Unit(c), target(c));
    const Vector3 d1 = Vector3(1.0, 2.0, 2.0).normalized();
    f.Constrain(12, d1, 0.05);
    cons.emplace_back(12, d1, 0.05);
    const Vector3 d2 = Vector3(0.0, 0.0, 1.0), d3 = Vector3(1.0, 1.0, 0.0).normalized();
    f.Constrain(20, d2, -0.1);
    f.Constrain(20, d3, 0.2);
    cons.emplace_back(20, d2, -0.1);
    cons.emplace_back(20, d3, 0.2);
    MatrixN3 v = MatrixN3::Constant(sys.num_particles(), 3, 0.3);  // a guess violating the constraints
    const PcgSummary s = FilteredPcg(pr.a, pr.b, f, pre, opts, &v, &work);
    ASSERT_EQ(s.status, PcgStatus::kConverged);
    const MatrixN3 ref = DenseSolve(pr, cons);
    EXPECT_LT((v - ref).norm() / ref.norm(), 1e-8);
    EXPECT_LT((v.row(7).transpose() - target).norm(), 1e-14);  // imposed exactly
    EXPECT_NEAR(v.row(12).dot(d1), 0.05, 1e-14);
  }
}

INSTANTIATE_TEST_SUITE_P(Preconditioners, PcgTest,
                         ::testing::Values(PreconditionerType::kNone, PreconditionerType::kJacobi,
                                           PreconditionerType::kIc0, PreconditionerType::kCholesky,
                                           PreconditionerType::kAmg),
                         [](const auto& param_info) { return std::string(ToString(param_info.param)); });

// IC(0) on a chain (tridiagonal A) has no fill-in, so it is the exact
// Cholesky factor and PCG converges in one iteration.
TEST(IncompleteCholesky0, ExactOnTridiagonal) {
  Scene s;
  s.grid.nu = 30;
  s.grid.nv = 2;
  s.material.tension = {100.0, 0.0};
  s.fixed = {};
  const ParticleSystem sys(s);
  SystemMatrix sm(sys, PreconditionerType::kIc0);
  ASSERT_TRUE(sm.Update(0.01));
  MatrixN3 b = MatrixN3::Random(sys.num_particles(), 3), v = MatrixN3::Zero(sys.num_particles(), 3);
  PcgWorkspace work(sys.num_particles());
  const PcgSummary r = FilteredPcg(sm.matrix(), b, VelocityFilter(), sm.preconditioner(), {1e-12, 100}, &v, &work);
  EXPECT_EQ(r.status, PcgStatus::kConverged);
  EXPECT_EQ(r.iterations, 1);
}

// IC(0) must beat Jacobi on the 2-D grid (it is the thesis' choice).
TEST(IncompleteCholesky0, FewerIterationsThanJacobi) {
  const ParticleSystem sys(DefaultScene());
  int iters[2];
  int k = 0;
  for (PreconditionerType t : {PreconditionerType::kJacobi, PreconditionerType::kIc0}) {
    SystemMatrix sm(sys, t);
    ASSERT_TRUE(sm.Update(0.01));
    MatrixN3 b = MatrixN3::Ones(sys.num_particles(), 3), v = MatrixN3::Zero(sys.num_particles(), 3);
    PcgWorkspace work(sys.num_particles());
    iters[k++] = FilteredPcg(sm.matrix(), b, VelocityFilter(), sm.preconditioner(), {1e-8, 1000}, &v, &work).iterations;
  }
  EXPECT_LT(iters[1], iters[0]);
}

}  // namespace
}  // namespace clothbench
