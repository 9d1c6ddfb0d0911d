// Projective dynamics (Liu et al. 2013; Chebyshev: Wang 2015; docs/model.md §10).
#include "peers/projective_dynamics.h"

namespace clothbench {

ProjectiveDynamics::ProjectiveDynamics(const ParticleSystem& system, const SolverSpec& spec, int iterations,
                                       ChebyshevSettings chebyshev)
    : IteratedStepper(system, "pd", iterations, chebyshev, kRhoIterations, InitialGuess::kInertial),
      sm_(system, PreconditionerType::kCholesky, spec.cholesky_ordering) {
  const int n = system.num_particles();
  for (MatrixN3* m : {&b0_, &b_, &g_, &lkx_}) m->setZero(n, 3);
  if (system.has_prescribed_motion())
    for (MatrixN3* m : {&moving_v_, &coupling_}) m->setZero(n, 3);
}

StepStatus ProjectiveDynamics::Prepare(double h) {
  return sm_.Update(h) ? StepStatus::kOk : StepStatus::kPreconditionerFailed;  // A₁ and its factor
}

// The constant part of the right-hand side, M v₀ − h L_K x₀.
void ProjectiveDynamics::BeginIterations(double h) {
  SymmetricProduct(sys_.stiffness_laplacian(), x0_, &lkx_);
  b0_.noalias() = sys_.masses().asDiagonal() * v0_;
  b0_ -= h * lkx_;
  // Moving fixed particles are a Dirichlet condition on the global step:
  // their velocity V = (x_p(t + h) − x₀)/h moves to the right-hand side,
  // b_free −= A_{free,fixed} V (A_F decouples their rows and columns).
  if (sys_.has_prescribed_motion()) {
    moving_v_.setZero();
    sys_.ForEachPrescribed(t_ + h, [&](int p, const Vector3& x, const Vector3&) {
      moving_v_.row(p) = (x - x0_.row(p).transpose()).transpose() / h;
    });
    SymmetricProduct(sm_.matrix(), moving_v_, &coupling_);
    b0_ -= coupling_;
  }
}

// Local step (F_nl is the springs' projection) and the other forces at
// the iterate; global step with A₁'s factor. Fixed rows stay 0.
void ProjectiveDynamics::Iteration(double h) {
  x_.noalias() = x0_ + h * v_;
  sys_.ExplicitForces(t_ + h, x_, v_, &g_);
  b_.noalias() = b0_ + h * g_;
  for (int p : sys_.fixed()) b_.row(p).setZero();
  sm_.preconditioner().Apply(b_, &v_);
  if (sys_.has_prescribed_motion())
    sys_.ForEachPrescribed(t_ + h, [&](int p, const Vector3&, const Vector3&) { v_.row(p) = moving_v_.row(p); });
}

}  // namespace clothbench
