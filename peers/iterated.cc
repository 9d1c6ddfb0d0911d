// The iterated peers' step (peers/iterated.h; docs/model.md §10).
#include "peers/iterated.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <stdexcept>

#include <fmt/format.h>

#include "model/interrupt.h"
#include "peers/position_contacts.h"

namespace clothbench {

IteratedStepper::IteratedStepper(const ParticleSystem& system, std::string_view name, int iterations,
                                 ChebyshevSettings chebyshev, int rho_iterations, InitialGuess initial_guess,
                                 ObstacleResponse response, RhoEstimate rho_estimate)
    : sys_(system),
      iterations_(iterations),
      cheb_(chebyshev),
      rho_iterations_(rho_iterations),
      rho_estimate_(rho_estimate),
      initial_guess_(initial_guess),
      response_(response),
      contacts_(system),
      proximity_(system) {
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
  if (initial_guess_ != InitialGuess::kInertial) v_last_.setZero(n, 3);
  const bool filter = response_ == ObstacleResponse::kVelocityFilter && contacts_.active();
  if (initial_guess_ == InitialGuess::kSafeguardedExtrapolation || filter)
    for (MatrixN3* m : {&v_guess_, &x_guess_, &f_guess_}) m->setZero(n, 3);
  if (filter) {
    filter_.Reserve(n);
    constraint_.assign(static_cast<std::size_t>(n), -1);
    constraints_.reserve(static_cast<std::size_t>(n));
  }
  if (filter || response_ == ObstacleResponse::kOwn) xm1_.setZero(n, 3);
  increments_.reserve(static_cast<std::size_t>(std::max(iterations, rho_iterations)));
  if (cheb_.on && cheb_.rho == 0.0 && rho_estimate_ == RhoEstimate::kKrylov) {
    std::vector<Eigen::Index> free;  // column-major N×3: coordinate c of particle p at c·N + p
    for (int c = 0; c < 3; ++c)
      for (int p = 0; p < n; ++p)
        if (w_(p) > 0.0) free.push_back(static_cast<Eigen::Index>(c) * n + p);
    const std::size_t stride = std::max<std::size_t>(1, (free.size() + kKrylovRhoRows - 1) / kKrylovRhoRows);
    for (std::size_t i = 0; i < free.size(); i += stride) sketch_index_.push_back(free[i]);
  }
}

void IteratedStepper::PlanRun(double t_end, double h) {
  planned_sweeps_ = h > 0.0 && t_end > 0.0 ? static_cast<long>(std::ceil(t_end / h - 1e-9)) * iterations_ : 0;
  if (!sketch_index_.empty() && sketch_.cols() < RhoSweeps())
    sketch_.setZero(static_cast<Eigen::Index>(sketch_index_.size()), RhoSweeps());
}

int IteratedStepper::RhoSweeps() const {
  if (rho_estimate_ != RhoEstimate::kKrylov || planned_sweeps_ <= 0) return rho_iterations_;
  return static_cast<int>(
      std::clamp<long>(planned_sweeps_ / 10, std::min(kKrylovRhoMin, rho_iterations_), rho_iterations_));
}

void IteratedStepper::Reset(double t, const MatrixN3& x, const MatrixN3& v) {
  t_ = t;
  x0_ = x;
  v0_ = v;
  for (int p : sys_.fixed()) v0_.row(p).setZero();
  sys_.Prescribe(t, &x0_, &v0_);  // moving fixed particles (`[[constraints.motion]]`)
  h_last_step_ = 0.0;
  have_history_ = false;
  contacts_.Reset();
  proximity_.Reset();
}

int IteratedStepper::SetUpContacts(double h) {
  const int colliding = contacts_.SetUp(t_, h, x0_, v0_, have_history_ ? &xm1_ : nullptr, &filter_);
  sys_.ForEachPrescribed(t_ + h, [&](int p, const Vector3& x, const Vector3&) {
    filter_.SetFixedTarget(p, (x - x0_.row(p).transpose()) / h);
  });
  std::fill(constraint_.begin(), constraint_.end(), -1);
  constraints_.clear();
  filter_.ForEachTarget([&](int p, int count, const Eigen::Matrix3d& dirs, const Vector3& targets) {
    if (count >= 3) return;  // fixed: never relaxed
    constraint_[static_cast<std::size_t>(p)] = static_cast<int>(constraints_.size());
    constraints_.push_back({count, dirs, targets});
  });
  return colliding;
}

bool IteratedStepper::LocalStep(int p, const Matrix3& j, const Vector3& r, Vector3* vp) const {
  const int k = response_ == ObstacleResponse::kVelocityFilter && !constraint_.empty()
                    ? constraint_[static_cast<std::size_t>(p)]
                    : -1;
  const double scale = j.cwiseAbs().maxCoeff();
  if (k < 0) {
    Matrix3 inverse;
    bool invertible = false;
    j.computeInverseWithCheck(inverse, invertible, 1e-12 * scale * scale * scale);
    if (!invertible) return false;
    *vp -= inverse * r;
    return true;
  }
  // Δ = D δ + T a: the constrained components D δ reach their targets, and
  // the free ones solve Tᵀ (r + j Δ) = 0 (T an orthonormal complement of D).
  const LocalConstraint& c = constraints_[static_cast<std::size_t>(k)];
  Vector3 delta = Vector3::Zero();
  for (int i = 0; i < c.count; ++i) delta += (c.targets(i) - c.dirs.col(i).dot(*vp)) * c.dirs.col(i);
  Eigen::Matrix<double, 3, 2> t;
  int free = 0;
  if (c.count == 1) {
    const Vector3 n = c.dirs.col(0);
    Vector3 axis = Vector3::Zero();
    int least = 0;
    n.cwiseAbs().minCoeff(&least);
    axis(least) = 1.0;
    t.col(0) = n.cross(axis).normalized();
    t.col(1) = n.cross(t.col(0));
    free = 2;
  } else {
    t.col(0) = c.dirs.col(0).cross(c.dirs.col(1)).normalized();
    free = 1;
  }
  const Vector3 rhs = -(r + j * delta);
  if (free == 2) {
    const Eigen::Matrix2d a = t.transpose() * j * t;
    const double det = a.determinant();
    if (!(std::abs(det) > 1e-12 * scale * scale)) return false;
    *vp += delta + t * (a.inverse() * (t.transpose() * rhs));
  } else {
    const double a = t.col(0).dot(j * t.col(0));
    if (!(std::abs(a) > 1e-12 * scale)) return false;
    *vp += delta + t.col(0) * (t.col(0).dot(rhs) / a);
  }
  return true;
}

void IteratedStepper::ReadContactImpulses(double h) {
  // Each particle's row of the implicit Euler equations at the step's end,
  // r_p = m_p (v₁ − v₀) − h (f(t₁, x₁, v₁) + friction)_p: along a contact's
  // direction, the constraint impulse; its free components are what the
  // iterations left, the release tolerance (as η‖S_F b‖ for the PCG).
  x_guess_.noalias() = x0_ + h * v_;
  sys_.Forces(t_ + h, x_guess_, v_, &f_guess_);
  f_guess_ += contacts_.friction();
  const Eigen::VectorXd& m = sys_.masses();
  double free2 = 0.0;
  for (int p = 0; p < v_.rows(); ++p) {
    if (w_(p) == 0.0) continue;
    Vector3 r = m(p) * (v_.row(p) - v0_.row(p)).transpose() - h * f_guess_.row(p).transpose();
    const int k = constraint_[static_cast<std::size_t>(p)];
    if (k >= 0)
      for (int i = 0; i < constraints_[static_cast<std::size_t>(k)].count; ++i) {
        const Vector3 d = constraints_[static_cast<std::size_t>(k)].dirs.col(i);
        r -= r.dot(d) * d;
      }
    free2 += r.squaredNorm();
  }
  auto residual_row = [&](int p) {
    return Vector3(m(p) * (v_.row(p) - v0_.row(p)).transpose() - h * f_guess_.row(p).transpose());
  };
  contacts_.ReadImpulses(residual_row, v0_, v_, v0_, std::sqrt(free2));
}

double IteratedStepper::ResidualNorm2(double h, const MatrixN3& v) {
  x_guess_.noalias() = x0_ + h * v;
  sys_.Forces(t_ + h, x_guess_, v, &f_guess_);
  if (const MatrixN3* friction = contact_forces()) f_guess_ += *friction;
  double sum = 0.0;
  for (int p = 0; p < v.rows(); ++p) {
    if (w_(p) == 0.0) continue;
    Vector3 r = ((v.row(p) - v0_.row(p)) / w_(p) - h * f_guess_.row(p)).transpose();
    if (const int k = constraint_.empty() ? -1 : constraint_[static_cast<std::size_t>(p)]; k >= 0)
      for (int i = 0; i < constraints_[static_cast<std::size_t>(k)].count; ++i) {  // the constraint carries these
        const Vector3 d = constraints_[static_cast<std::size_t>(k)].dirs.col(i);
        r -= r.dot(d) * d;
      }
    sum += r.squaredNorm() * w_(p);
  }
  return sum;
}

void IteratedStepper::StartIterate(double h, bool rho_start) {
  InertialVelocity(h, &v_);
  if (initial_guess_ != InitialGuess::kInertial && h_last_step_ > 0.0)
    for (int p = 0; p < v_.rows(); ++p) {
      const Vector3 a_ext = w_(p) * f_ext_.row(p).transpose();
      const double a_ext2 = a_ext.squaredNorm();
      if (a_ext2 == 0.0) continue;  // fixed, or no constant force
      const Vector3 a = (v0_.row(p) - v_last_.row(p)).transpose() / h_last_step_;
      v_.row(p) = v0_.row(p) + h * std::clamp(a.dot(a_ext) / a_ext2, 0.0, 1.0) * a_ext.transpose();
    }
  const bool filter = contact_forces() != nullptr;
  if (filter) filter_.Impose(&v_);  // contacts' normal velocities at their targets, fixed particles at rest
  if (initial_guess_ == InitialGuess::kSafeguardedExtrapolation && h_last_step_ > 0.0) {
    v_guess_.noalias() = v0_ + (h / h_last_step_) * (v0_ - v_last_);
    for (int p : sys_.fixed()) v_guess_.row(p).setZero();
    if (filter) filter_.Impose(&v_guess_);
    if (ResidualNorm2(h, v_guess_) < ResidualNorm2(h, v_)) v_.swap(v_guess_);
  }
  if (rho_start) {
    // ρ is the contraction near the solution: from the guess alone a
    // sheet in free fall (every particle accelerating alike, no internal
    // force) converges in one sweep and gives no ρ. A deterministic
    // perturbation of amplitude 1e-4 of the spacing per step (linear
    // regime, far above VelocityNoise) excites every mode, as a power
    // iteration starts from a random vector.
    const double amplitude = 1e-4 * std::min(sys_.scene().lu(), sys_.scene().lv()) / h;
    std::uint32_t state = 12345u;  // a linear congruential sequence: the same start on every run and thread count
    for (int p = 0; p < v_.rows(); ++p)
      for (int c = 0; c < 3; ++c) {
        state = state * 1664525u + 1013904223u;
        if (w_(p) > 0.0) v_(p, c) += amplitude * (static_cast<double>(state >> 8) / 16777216.0 - 0.5);
      }
    if (filter) filter_.Impose(&v_);
  }
  // A moving fixed particle (w = 0, never updated) goes exactly to its
  // prescribed position at the step's end: x₀ + h v = x_p(t + h).
  sys_.ForEachPrescribed(t_ + h, [&](int p, const Vector3& x, const Vector3&) {
    v_.row(p) = (x - x0_.row(p).transpose()).transpose() / h;
  });
}

bool IteratedStepper::Iterate(double h, int k_max, bool accelerate, bool rho_start, bool* timed_out) {
  StartIterate(h, rho_start);
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
    AfterIteration(h);
    increments_.push_back((v_ - v_start_).norm());
    if (rho_start && MeasureRhoAfter(k, h)) return true;
    v_prev_.swap(v_start_);
  }
  return true;
}

bool IteratedStepper::MeasureRhoAfter(int k, double h) {
  ++rho_sweeps_;
  if (rho_estimate_ != RhoEstimate::kKrylov) return false;  // ChebyshevRho after all rho_iterations_
  // An increment at round-off: the plain iteration converges within the
  // measurement and gives no usable ρ (as ChebyshevRho).
  if (increments_.back() <= VelocityNoise(x0_.norm(), h)) {
    rho_ = 0.0;
    return true;
  }
  for (Eigen::Index i = 0; i < sketch_.rows(); ++i) {
    const Eigen::Index c = sketch_index_[static_cast<std::size_t>(i)];
    sketch_(i, k) = v_.data()[c] - v_start_.data()[c];
  }
  const int m = k + 1;
  if (m < rho_measure_ && m < sketch_.rows()) return false;
  rho_ = m >= 3 ? KrylovRho(sketch_, m) : 0.0;  // fewer than 3 free coordinates: no Krylov space to speak of
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
  const bool filter = response_ == ObstacleResponse::kVelocityFilter && contacts_.active();
  if (filter) st.colliding = SetUpContacts(h);
  if (response_ == ObstacleResponse::kOwn) st.colliding = BeginContacts(h);
  if (h != h_) {
    const auto t0 = std::chrono::steady_clock::now();
    if (const StepStatus s = Prepare(h); s != StepStatus::kOk) return finish(s);
    h_ = h;
    rho_ = cheb_.rho;
    if (cheb_.on && cheb_.rho == 0.0 && cheb_.ExtrapolatedIterations(iterations_) > 0) {
      // ρ measured on this step's plain iterations (the state is not changed).
      const auto r0 = std::chrono::steady_clock::now();
      rho_measure_ = RhoSweeps();
      if (rho_estimate_ == RhoEstimate::kKrylov && sketch_.cols() < rho_measure_)  // no PlanRun before
        sketch_.setZero(static_cast<Eigen::Index>(sketch_index_.size()), rho_measure_);
      if (!Iterate(h, rho_measure_, /*accelerate=*/false, /*rho_start=*/true, &timed_out))
        return finish(timed_out ? StepStatus::kTimeLimit : StepStatus::kNonFinite);
      if (rho_estimate_ == RhoEstimate::kIncrementRatio) rho_ = ChebyshevRho(increments_, VelocityNoise(x0_.norm(), h));
      rho_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - r0).count();
    }
    st.setup_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  if (!Iterate(h, iterations_, cheb_.on, /*rho_start=*/false, &timed_out))
    return finish(timed_out ? StepStatus::kTimeLimit : StepStatus::kNonFinite);  // the state stays x₀, v₀
  const double t1 = t_ + h;
  x_.noalias() = x0_ + h * v_;
  if (filter) {
    ReadContactImpulses(h);
  } else if (response_ == ObstacleResponse::kOwn) {
    st.colliding = EndContacts(h);
  } else if (!sys_.obstacles().empty()) {
    st.colliding = ProjectOntoObstacles(sys_, &proximity_, w_, t1, h, x0_, &x_);
    v_ = (x_ - x0_) / h;
  }
  sys_.Prescribe(t1, &x_, &v_);  // moving fixed particles end at their prescribed state
  if (!x_.allFinite() || !v_.allFinite()) return finish(StepStatus::kNonFinite);
  if (filter || response_ == ObstacleResponse::kOwn) {
    xm1_ = x0_;
    have_history_ = true;
  }
  x0_.swap(x_);
  if (initial_guess_ != InitialGuess::kInertial) {
    v_last_ = v0_;
    h_last_step_ = h;
  }
  v0_.swap(v_);
  t_ = t1;
  return finish(StepStatus::kOk);
}

}  // namespace clothbench
