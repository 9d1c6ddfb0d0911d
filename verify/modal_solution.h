// Exact solution of a linear particle system (zero-rest-length springs,
// proportional damping L_D = c L_K, constant gravity, fixed particles), used
// by the temporal-order and error-estimate tests. On the free particles,
//   M u'' + c L u' + L u = M g,   u = x − x_rest,
// with L = L_ff. With u_p = L⁻¹ M g and M^{-1/2} L M^{-1/2} = Q Λ Qᵀ, the
// modal coordinates q = Qᵀ M^{1/2} (u − u_p) obey q_k'' + c λ_k q_k' + λ_k q_k = 0:
// every mode is underdamped (c λ_k < 2√λ_k here) and
//   q_k(t) = e^{−σt}(q0 cos ω_d t + (q0' + σ q0)/ω_d sin ω_d t),
//   σ = c λ_k / 2, ω_d = √(λ_k − σ²).
#ifndef CLOTHBENCH_VERIFY_MODAL_SOLUTION_H_
#define CLOTHBENCH_VERIFY_MODAL_SOLUTION_H_

#include <cmath>
#include <vector>

#include <Eigen/Dense>

#include "model/particle_system.h"

namespace clothbench::testing {

class LinearModalFlow {
 public:
  /// @param sys a linear scene (tension_model = "linear", only gravity, L_D = c L_K)
  explicit LinearModalFlow(const ParticleSystem& sys) : sys_(sys) {
    for (int p = 0; p < sys.num_particles(); ++p)
      if (!sys.is_fixed(p)) free_.push_back(p);
    const int nf = static_cast<int>(free_.size());
    const Eigen::MatrixXd lk(sys.stiffness_laplacian());
    lff_.resize(nf, nf);
    sqm_.resize(nf);
    for (int a = 0; a < nf; ++a) {
      sqm_(a) = std::sqrt(sys.masses()(free_[a]));
      for (int b = 0; b < nf; ++b) lff_(a, b) = lk(free_[a], free_[b]);
    }
    const Scene& s = sys.scene();
    c_ = s.material.tension_damping / s.material.tension[0];
    eig_.compute(sqm_.cwiseInverse().asDiagonal() * lff_ * sqm_.cwiseInverse().asDiagonal());
  }

  /// Exact state at time t [s] of the flow starting at (x0, v0) (N×3 [m],
  /// [m/s], fixed particles at rest) at t = 0.
  void Flow(const MatrixN3& x0, const MatrixN3& v0, double t, MatrixN3* x, MatrixN3* v) const {
    const int nf = static_cast<int>(free_.size());
    *x = x0;
    *v = v0;
    const Eigen::MatrixXd& q = eig_.eigenvectors();
    for (int col = 0; col < 3; ++col) {
      const Eigen::VectorXd mg = sqm_.cwiseProduct(sqm_) * sys_.scene().forces.gravity(col);
      const Eigen::VectorXd up = lff_.ldlt().solve(mg);
      Eigen::VectorXd u0(nf), du0(nf);
      for (int a = 0; a < nf; ++a) {
        u0(a) = x0(free_[a], col) - sys_.rest_positions()(free_[a], col);
        du0(a) = v0(free_[a], col);
      }
      const Eigen::VectorXd q0 = q.transpose() * sqm_.cwiseProduct(u0 - up);
      const Eigen::VectorXd dq0 = q.transpose() * sqm_.cwiseProduct(du0);
      Eigen::VectorXd qt(nf), dqt(nf);
      for (int k = 0; k < nf; ++k) {
        const double lam = eig_.eigenvalues()(k), sigma = 0.5 * c_ * lam, wd = std::sqrt(lam - sigma * sigma);
        const double a = q0(k), b = (dq0(k) + sigma * q0(k)) / wd;
        const double e = std::exp(-sigma * t), cs = std::cos(wd * t), sn = std::sin(wd * t);
        qt(k) = e * (a * cs + b * sn);
        dqt(k) = e * (-sigma * (a * cs + b * sn) + wd * (-a * sn + b * cs));
      }
      const Eigen::VectorXd u = up + sqm_.cwiseInverse().cwiseProduct(q * qt);
      const Eigen::VectorXd du = sqm_.cwiseInverse().cwiseProduct(q * dqt);
      for (int a = 0; a < nf; ++a) {
        (*x)(free_[a], col) = sys_.rest_positions()(free_[a], col) + u(a);
        (*v)(free_[a], col) = du(a);
      }
    }
  }

 private:
  const ParticleSystem& sys_;
  std::vector<int> free_;
  Eigen::MatrixXd lff_;
  Eigen::VectorXd sqm_;
  double c_ = 0.0;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig_;
};

}  // namespace clothbench::testing

#endif  // CLOTHBENCH_VERIFY_MODAL_SOLUTION_H_
