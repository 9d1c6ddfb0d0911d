// ρ of a plain iteration from sketches of its increments (peers/chebyshev.h;
// docs/model.md §10).
#include "peers/chebyshev.h"

#include <algorithm>
#include <complex>
#include <stdexcept>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/SVD>

namespace clothbench {

double KrylovRho(const Eigen::MatrixXd& sketch, int m) {
  if (m < 3 || m > sketch.cols() || sketch.rows() < m)
    throw std::invalid_argument("KrylovRho: needs 3 <= m <= columns <= rows of the sketch");
  // X = [δ_0 … δ_{m−2}], Y = [δ_1 … δ_{m−1}], each pair scaled by 1/‖δ_j‖.
  Eigen::MatrixXd x = sketch.leftCols(m - 1), y = sketch.middleCols(1, m - 1);
  int n = m - 1;
  for (int j = 0; j < n; ++j) {
    const double norm = x.col(j).norm();
    if (!(norm > 0.0)) {  // the iteration stopped moving: the pairs before it only
      n = j;
      break;
    }
    x.col(j) /= norm;
    y.col(j) /= norm;
  }
  if (n < 2) return 0.0;
  const Eigen::BDCSVD<Eigen::MatrixXd> svd(x.leftCols(n), Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Eigen::VectorXd& s = svd.singularValues();
  int r = 0;
  while (r < s.size() && s(r) > 1e-6 * s(0)) ++r;
  if (r == 0) return 0.0;
  const Eigen::MatrixXd u = svd.matrixU().leftCols(r);
  // Ã = Uᵀ Y V Σ⁻¹: G on the span of the increments.
  const Eigen::MatrixXd a = u.transpose() * y.leftCols(n) * svd.matrixV().leftCols(r) * s.head(r).cwiseInverse().asDiagonal();
  const Eigen::EigenSolver<Eigen::MatrixXd> eig(a);
  if (eig.info() != Eigen::Success) return 0.0;
  const Eigen::VectorXcd lambda = eig.eigenvalues();
  const Eigen::MatrixXcd w = eig.eigenvectors();  // unit columns
  // Each mode's amplitude in the last increment in use.
  const Eigen::VectorXd last = y.col(n - 1).normalized();
  const Eigen::VectorXcd amplitude = w.fullPivLu().solve((u.transpose() * last).cast<std::complex<double>>());
  const double largest = amplitude.cwiseAbs().maxCoeff();
  double rho = 0.0;
  for (int i = 0; i < r; ++i)
    if (std::abs(lambda(i)) < 1.0 && std::abs(amplitude(i)) >= 0.01 * largest) rho = std::max(rho, std::abs(lambda(i)));
  return rho;
}

}  // namespace clothbench
