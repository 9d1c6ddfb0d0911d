// ρ of a plain iteration from its increments (peers/chebyshev.h;
// docs/model.md §10).
//
// 1. A gapped spectrum (the default scene's case: its slowest Gauss–Seidel
//    mode, 0.984, stands apart): a linear iteration with eigenvalues 0.99
//    and 299 spread over [0, 0.95], from a start with every mode excited.
//    After 48 increments the Krylov estimate is within 1 % of 1 − ρ (the
//    Ritz value of an isolated extreme eigenvalue converges like a
//    Chebyshev polynomial of degree 48 on the gap: 1.7e-5 measured), while
//    the increment ratio is still short by more than 4 (1 − ρ) (its error
//    falls like (0.95/0.99)^k, 0.14 at k = 48: 0.9456 measured).
// 2. A dense spectrum (the 10⁴ sheet's case): Gauss–Seidel on the 1D
//    Laplacian tridiag(−1, 2, −1) of size 100, whose spectrum cos²(jπ/101)
//    is known (Young 1971, ch. 5), so ρ = cos²(π/101). Neither estimate
//    has converged after 64 increments (no gap), but the Krylov estimate's
//    error is under a quarter of the ratio's (measured: 4.8e-3 against
//    3.0e-2).
// 3. An iteration that stops moving (increments exactly 0) gives ρ = 0,
//    never a ρ from round-off, and bad shapes are refused.
// 4. ρ is the same to the bit on one and two OpenMP threads, at the
//    sketch's full size (4096 rows, IteratedStepper::kKrylovRhoRows): the
//    threads a busy machine leaves a run change between its repeats, and
//    a ρ that changed with them would change the trajectory (Eigen's own
//    parallel products choose their blocking by the thread count; the
//    build switches them off, EIGEN_DONT_PARALLELIZE).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdint>
#include <numbers>
#include <stdexcept>
#include <vector>

#include <Eigen/Core>

#include "peers/chebyshev.h"
#include "verify/test_scenes.h"

namespace clothbench {
namespace {

// m increments of Gauss–Seidel on tridiag(−1, 2, −1) u = 0 from a start
// with every mode excited (a linear congruential sequence), as columns.
Eigen::MatrixXd GaussSeidelIncrements(int n, int m) {
  Eigen::VectorXd u(n);
  std::uint32_t state = 12345u;
  for (int i = 0; i < n; ++i) {
    state = state * 1664525u + 1013904223u;
    u(i) = static_cast<double>(state >> 8) / 16777216.0 - 0.5;
  }
  Eigen::MatrixXd inc(n, m);
  for (int k = 0; k < m; ++k) {
    const Eigen::VectorXd before = u;
    for (int i = 0; i < n; ++i) u(i) = 0.5 * ((i > 0 ? u(i - 1) : 0.0) + (i + 1 < n ? u(i + 1) : 0.0));
    inc.col(k) = u - before;
  }
  return inc;
}

// The increment ratio of `inc`'s columns' norms (ChebyshevRho without a noise floor).
double IncrementRatio(const Eigen::MatrixXd& inc) {
  std::vector<double> norms;
  for (Eigen::Index k = 0; k < inc.cols(); ++k) norms.push_back(inc.col(k).norm());
  return ChebyshevRho(norms, 0.0);
}

TEST(KrylovRho, FindsAnIsolatedSlowestModeLongBeforeTheIncrementRatio) {
  const int n = 300, m = 48;
  const double rho = 0.99;
  Eigen::VectorXd lambda(n), u(n);
  lambda(0) = rho;
  for (int i = 1; i < n; ++i) lambda(i) = 0.95 * (i - 1) / (n - 2);
  std::uint32_t state = 12345u;
  for (int i = 0; i < n; ++i) {
    state = state * 1664525u + 1013904223u;
    u(i) = static_cast<double>(state >> 8) / 16777216.0 - 0.5;
  }
  Eigen::MatrixXd inc(n, m);  // δ_k = (Λ^{k+1} − Λ^k) u
  for (int k = 0; k < m; ++k)
    for (int i = 0; i < n; ++i) inc(i, k) = (std::pow(lambda(i), k + 1) - std::pow(lambda(i), k)) * u(i);
  const double krylov = KrylovRho(inc, m), ratio = IncrementRatio(inc);
  std::printf("[ rho ] gapped spectrum, %d increments: exact %.6f, Krylov %.8f, increment ratio %.6f\n", m, rho, krylov,
              ratio);
  EXPECT_NEAR(krylov, rho, 0.01 * (1.0 - rho));
  EXPECT_LT(ratio, rho - 4.0 * (1.0 - rho));
}

TEST(KrylovRho, IsCloserThanTheIncrementRatioOnADenseSpectrum) {
  const int n = 100, m = 64;
  const double exact = std::pow(std::cos(std::numbers::pi / (n + 1)), 2);
  const Eigen::MatrixXd inc = GaussSeidelIncrements(n, m);
  const double krylov = KrylovRho(inc, m), ratio = IncrementRatio(inc);
  std::printf("[ rho ] GS on the 1D Laplacian, n = %d, %d increments: exact %.6f, Krylov %.6f, increment ratio %.6f\n",
              n, m, exact, krylov, ratio);
  EXPECT_LT(std::abs(krylov - exact), 0.25 * std::abs(ratio - exact));
  EXPECT_LT(krylov, 1.0);
}

TEST(KrylovRho, AnIterationThatStopsGivesNoRhoAndBadShapesAreRefused) {
  Eigen::MatrixXd inc = Eigen::MatrixXd::Zero(20, 10);
  inc(0, 0) = 1.0;
  inc(1, 1) = 0.5;  // then exactly 0: the pairs before the stop only
  EXPECT_EQ(KrylovRho(inc, 10), 0.0);
  EXPECT_THROW(KrylovRho(inc, 2), std::invalid_argument);
  EXPECT_THROW(KrylovRho(Eigen::MatrixXd::Zero(5, 10), 8), std::invalid_argument);
}

TEST(KrylovRho, IsTheSameOnOneAndTwoThreads) {
  const Eigen::MatrixXd inc = GaussSeidelIncrements(4096, 128);
  double one = 0.0, two = 0.0;
  testing::WithThreads(1, [&] { one = KrylovRho(inc, 128); });
  testing::WithThreads(2, [&] { two = KrylovRho(inc, 128); });
  EXPECT_GT(one, 0.0);
  EXPECT_EQ(one, two);  // to the bit
}

}  // namespace
}  // namespace clothbench
