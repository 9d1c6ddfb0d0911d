// The iterated peers' step (peers/iterated.h; docs/model.md §10).
#include "peers/iterated.h"

#include <algorithm>
#include <chrono>
#include <stdexcept>

#include <fmt/format.h>

#include "model/interrupt.h"
#include "peers/position_contacts.h"

namespace clothbench {

IteratedStepper::IteratedStepper(const ParticleSystem& system, std::string_view name, int iterations,
                                 ChebyshevSettings chebyshev, int rho_iterations, InitialGuess initial_guess)
    : sys_(system),
      iterations_(iterations),
      cheb_(chebyshev),
      rho_iterations_(rho_iterations),
      initial_guess_(initial_guess) {
  if (iterations < 1) throw std::invalid_argument(fmt::format("{}: iterations = {} must be at least 1", name, iterations));
  if (!cheb_.valid())
    throw std::invalid_argument(fmt::format("{}/chebyshev: rho = {} must be in [0, 1), gamma = {} in (0, 1], delay = {} "
                                            "at least 1",
                                            name, cheb_.rho, cheb_.gamma, cheb_.delay));
  const int n = system.num_particles();
  w_ = system.masses().cwiseInverse();
  for (int p : system.fixed()) w_(p) = 0.0;
  f_ext_.setZero(n, 3);
  for (const auto& term : system.terms())
    if (const MatrixN3* f = term->constant_force()) f_ext_ += *f;
  for (MatrixN3* m : {&x0_, &v0_, &v_, &x_, &v_start_, &v_prev_}) m->setZero(n, 3);
  if (initial_guess_ == InitialGuess::kAdaptive) v_last_.setZero(n, 3);
  increments_.reserve(static_cast<std::size_t>(std::max(iterations, rho_iterations)));
}

void IteratedStepper::Reset(double t, const MatrixN3& x, const MatrixN3& v) {
  t_ = t;
  x0_ = x;
  v0_ = v;
  for (int p : sys_.fixed()) v0_.row(p).setZero();
  h_last_step_ = 0.0;
}

bool IteratedStepper::Iterate(double h, int k_max, bool accelerate, bool* timed_out) {
  v_.noalias() = v0_ + h * (w_.asDiagonal() * f_ext_);
  if (initial_guess_ == InitialGuess::kAdaptive && h_last_step_ > 0.0)
    for (int p = 0; p < v_.rows(); ++p) {
      const Vector3 a_ext = w_(p) * f_ext_.row(p).transpose();
      const double a_ext2 = a_ext.squaredNorm();
      if (a_ext2 == 0.0) continue;  // fixed, or no constant force
      const Vector3 a = (v0_.row(p) - v_last_.row(p)).transpose() / h_last_step_;
      v_.row(p) = v0_.row(p) + h * std::clamp(a.dot(a_ext) / a_ext2, 0.0, 1.0) * a_ext.transpose();
    }
  v_prev_ = v_;
  BeginIterations(h);
  increments_.clear();
  double omega = 1.0;
  int start = 0;           // the iteration the schedule (re)started at (ChebyshevSettings::restart)
  double start_plain = 0;  // the plain increment ‖v̂ − v^k‖ where ω first left 1 after it
  for (int k = 0; k < k_max; ++k) {
    if (DeadlinePassed()) {
      *timed_out = true;
      return false;
    }
    v_start_ = v_;
    Iteration(h);
    if (!v_.allFinite()) return false;
    if (accelerate && k >= start + cheb_.delay) {
      const double plain = cheb_.restart ? (v_ - v_start_).norm() : 0.0;
      if (k == start + cheb_.delay) start_plain = plain;
      // With the restart on, the last iteration also keeps its plain result:
      // no later sweep would show whether its extrapolation lost progress.
      if (cheb_.restart && ((k > start + cheb_.delay && plain > start_plain) || k + 1 == k_max)) {
        start = k + 1;  // keep v̂ (v_); ω is 1 again for `delay` iterations
        omega = 1.0;
      } else {
        omega = cheb_.Omega(k - start, rho_, omega);
        // v^{k+1} = ω (γ (v̂ − v^k) + v^k − v^{k−1}) + v^{k−1} with v̂ = v_
        // after the iteration, v^k = v_start_, v^{k−1} = v_prev_.
        v_ = omega * (cheb_.gamma * (v_ - v_start_) + v_start_ - v_prev_) + v_prev_;
      }
    }
    increments_.push_back((v_ - v_start_).norm());
    v_prev_.swap(v_start_);
  }
  return true;
}

StepStats IteratedStepper::Step(double h) {
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
  if (h != h_) {
    const auto t0 = std::chrono::steady_clock::now();
    if (const StepStatus s = Prepare(h); s != StepStatus::kOk) return finish(s);
    h_ = h;
    rho_ = cheb_.rho;
    if (cheb_.on && cheb_.rho == 0.0) {
      // ρ measured on this step's plain iterations (the state is not changed).
      const auto r0 = std::chrono::steady_clock::now();
      if (!Iterate(h, rho_iterations_, /*accelerate=*/false, &timed_out))
        return finish(timed_out ? StepStatus::kTimeLimit : StepStatus::kNonFinite);
      rho_ = ChebyshevRho(increments_, VelocityNoise(x0_.norm(), h));
      rho_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - r0).count();
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
  if (initial_guess_ == InitialGuess::kAdaptive) {
    v_last_ = v0_;
    h_last_step_ = h;
  }
  v0_.swap(v_);
  t_ = t1;
  return finish(StepStatus::kOk);
}

}  // namespace clothbench
