// Projective dynamics (Liu et al. 2013; Chebyshev: Wang 2015; docs/model.md §10).
#include "peers/projective_dynamics.h"

#include <chrono>
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

#include "model/interrupt.h"
#include "peers/position_contacts.h"

namespace clothbench {

ProjectiveDynamics::ProjectiveDynamics(const ParticleSystem& system, const SolverSpec& spec, int iterations,
                                       ChebyshevSettings chebyshev)
    : sys_(system),
      iterations_(iterations),
      cheb_(chebyshev),
      sm_(system, PreconditionerType::kCholesky, spec.cholesky_ordering) {
  if (iterations < 1) throw std::invalid_argument(fmt::format("pd: iterations = {} must be at least 1", iterations));
  if (cheb_.on && !(cheb_.rho >= 0.0 && cheb_.rho < 1.0 && cheb_.gamma > 0.0 && cheb_.gamma <= 1.0 && cheb_.delay >= 1))
    throw std::invalid_argument(fmt::format("pd/chebyshev: rho = {} must be in [0, 1), gamma = {} in (0, 1], delay = {} "
                                            "at least 1",
                                            cheb_.rho, cheb_.gamma, cheb_.delay));
  const int n = system.num_particles();
  w_ = system.masses().cwiseInverse();
  for (int p : system.fixed()) w_(p) = 0.0;
  f_ext_.setZero(n, 3);
  for (const auto& term : system.terms())
    if (const MatrixN3* f = term->constant_force()) f_ext_ += *f;
  for (MatrixN3* m : {&x0_, &v0_, &v_, &v_prev_, &v_hat_, &x_, &b0_, &b_, &g_, &lkx_}) m->setZero(n, 3);
  increments_.reserve(static_cast<std::size_t>(std::max(iterations, kRhoIterations)));
}

void ProjectiveDynamics::Reset(double t, const MatrixN3& x, const MatrixN3& v) {
  t_ = t;
  x0_ = x;
  v0_ = v;
  for (int p : sys_.fixed()) v0_.row(p).setZero();
}

bool ProjectiveDynamics::Iterate(double h, int k_max, bool accelerate, bool* timed_out) {
  const Eigen::VectorXd& mass = sys_.masses();
  const double t1 = t_ + h;
  // The constant part of the right-hand side, M v₀ − h L_K x₀, and the
  // inertial guess v₀ + h M⁻¹ f_ext.
  SymmetricProduct(sys_.stiffness_laplacian(), x0_, &lkx_);
  b0_.noalias() = mass.asDiagonal() * v0_;
  b0_ -= h * lkx_;
  v_.noalias() = v0_ + h * (w_.asDiagonal() * f_ext_);
  v_prev_ = v_;
  increments_.clear();
  double omega = 1.0;
  for (int k = 0; k < k_max; ++k) {
    if (DeadlinePassed()) {
      *timed_out = true;
      return false;
    }
    // Local step (F_nl is the springs' projection) and the other forces at
    // the iterate; global step with A₁'s factor. Fixed rows stay 0.
    x_.noalias() = x0_ + h * v_;
    sys_.ExplicitForces(t1, x_, v_, &g_);
    b_.noalias() = b0_ + h * g_;
    for (int p : sys_.fixed()) b_.row(p).setZero();
    sm_.preconditioner().Apply(b_, &v_hat_);
    if (!v_hat_.allFinite()) return false;
    if (accelerate && k >= cheb_.delay) {
      omega = k == cheb_.delay ? 2.0 / (2.0 - rho_ * rho_) : 4.0 / (4.0 - rho_ * rho_ * omega);
      // v^{k+1} = ω (γ (v̂ − v^k) + v^k − v^{k−1}) + v^{k−1}, in place:
      // v_hat_ ← v^{k+1}, v_prev_ ← v^k.
      v_hat_ = omega * (cheb_.gamma * (v_hat_ - v_) + v_ - v_prev_) + v_prev_;
    }
    increments_.push_back((v_hat_ - v_).norm());
    v_prev_.swap(v_);
    v_.swap(v_hat_);
  }
  return true;
}

StepStats ProjectiveDynamics::Step(double h) {
  const auto start = std::chrono::steady_clock::now();
  StepStats st;
  st.t = t_ + h;
  st.h = h;
  st.updates = iterations_;
  const auto finish = [&](StepStatus status) {
    st.status = status;
    st.solve_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return st;
  };
  bool timed_out = false;
  if (h != h_) {  // A₁ and its factor, cached while h is constant
    const auto t0 = std::chrono::steady_clock::now();
    if (!sm_.Update(h)) return finish(StepStatus::kPreconditionerFailed);
    h_ = h;
    rho_ = cheb_.rho;
    if (cheb_.on && cheb_.rho == 0.0) {
      // ρ measured on this step's plain iteration (the state is not changed).
      if (!Iterate(h, kRhoIterations, /*accelerate=*/false, &timed_out))
        return finish(timed_out ? StepStatus::kTimeLimit : StepStatus::kNonFinite);
      double log_sum = 0.0;
      int count = 0;
      for (std::size_t k = kRhoIterations / 2; k < increments_.size(); ++k)
        if (increments_[k - 1] > 0.0 && increments_[k] > 0.0) {
          log_sum += std::log(increments_[k] / increments_[k - 1]);
          ++count;
        }
      // A plain iteration that has converged to round-off, or does not
      // contract, gives no usable ρ: ρ = 0 keeps ω = 1, and only γ's
      // under-relaxation acts.
      const double rho = count > 0 ? std::exp(log_sum / count) : 0.0;
      rho_ = rho > 0.0 && rho < 1.0 ? rho : 0.0;
    }
    st.setup_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  if (!Iterate(h, iterations_, cheb_.on, &timed_out))
    return finish(timed_out ? StepStatus::kTimeLimit : StepStatus::kNonFinite);  // the state stays x₀, v₀
  const double t1 = t_ + h;
  x_.noalias() = x0_ + h * v_;
  if (!sys_.obstacles().empty()) {
    st.colliding = ProjectOntoObstacles(sys_, w_, t1, h, x0_, &x_);
    v_ = (x_ - x0_) / h;
  }
  if (!x_.allFinite() || !v_.allFinite()) return finish(StepStatus::kNonFinite);
  x0_.swap(x_);
  v0_.swap(v_);
  t_ = t1;
  return finish(StepStatus::kOk);
}

}  // namespace clothbench
