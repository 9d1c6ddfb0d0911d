// Projective dynamics (Liu et al. 2013; Chebyshev: Wang 2015; docs/model.md §10).
#include "peers/projective_dynamics.h"

#include "peers/position_contacts.h"

namespace clothbench {

ProjectiveDynamics::ProjectiveDynamics(const ParticleSystem& system, const SolverSpec& spec, int iterations,
                                       ChebyshevSettings chebyshev, ContactModel contact)
    : IteratedStepper(system, "pd", iterations, chebyshev, kRhoIterations, InitialGuess::kInertial,
                      contact == ContactModel::kImpulses && ContactImpulses::Acts(system)
                          ? ObstacleResponse::kOwn
                          : ObstacleResponse::kProjection),
      sm_(system, PreconditionerType::kCholesky, spec.cholesky_ordering) {
  const int n = system.num_particles();
  for (MatrixN3* m : {&b0_, &b_, &g_, &lkx_}) m->setZero(n, 3);
  if (system.has_prescribed_motion())
    for (MatrixN3* m : {&moving_v_, &coupling_}) m->setZero(n, 3);
  if (contact == ContactModel::kImpulses && ContactImpulses::Acts(system)) {
    impulses_.emplace(system, w_);
    guess_.setZero(n, 3);
  }
}

void ProjectiveDynamics::Reset(double t, const MatrixN3& x, const MatrixN3& v) {
  IteratedStepper::Reset(t, x, v);
  if (impulses_) impulses_->Reset();
}

int ProjectiveDynamics::BeginContacts(double h) {
  InertialVelocity(h, &guess_);
  return impulses_->BeginStep(t_, h, x0_, guess_, previous_positions());
}

// The impulses' work and the holding contacts; then the fail-safe: a
// particle the list missed, or a listed one that ends inside an obstacle,
// is projected out of the obstacles, its velocity
// (x₁ − x₀)/h, and the impulse of that change counts as contact work.
int ProjectiveDynamics::EndContacts(double h) {
  int acting = impulses_->EndStep(v0_, v_);
  if (!sys_.obstacles().empty()) {
    guess_ = x_;  // reused: the positions before the projection
    acting += ProjectOntoObstacles(sys_, proximity(), w_, t_ + h, h, x0_, &x_, &impulses_->listed());
    double work = 0.0;
    for (int p = 0; p < x_.rows(); ++p) {
      if (x_.row(p) == guess_.row(p)) continue;
      const Vector3 v1 = (x_.row(p) - x0_.row(p)).transpose() / h;
      work += 0.5 * (v1.squaredNorm() - v_.row(p).squaredNorm()) / w_(p);
      v_.row(p) = v1.transpose();
    }
    impulses_->AddFailSafeWork(work);
  }
  return acting;
}

StepStatus ProjectiveDynamics::Prepare(double h) {
  return sm_.Update(h) ? StepStatus::kOk : StepStatus::kPreconditionerFailed;  // A₁ and its factor
}

// The constant part of the right-hand side, M v₀ − h L_K x₀.
void ProjectiveDynamics::BeginIterations(double h) {
  if (impulses_) impulses_->BeginIterations();
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
  if (impulses_) impulses_->Refine(v_, &b_);
  sm_.preconditioner().Apply(b_, &v_);
  if (sys_.has_prescribed_motion())
    sys_.ForEachPrescribed(t_ + h, [&](int p, const Vector3&, const Vector3&) { v_.row(p) = moving_v_.row(p); });
}

}  // namespace clothbench

// The row of projective dynamics, as the registry lists it (harness/registry.cc).
#include "solver/method_row.h"

namespace clothbench {

/// pd: projective dynamics, the model's springs projected and A₁
/// prefactored; pd/chebyshev with Wang's acceleration at the measured ρ
/// (kPdChebyshev). Default parameters: h, h/4, h/16 with --iterations
/// 1,4,16,64 reach implicit Euler's floor 2.2e-2, 5.9e-3, 1.5e-3 m in 16,
/// 16 and 4 iterations; one iteration gives 2.2e-2, 1.8e-3, 1.2e-3 m
/// (docs/notes/work-precision.md, "pd").
MethodEntry ProjectiveDynamicsRow() {
  return {.name = kProjectiveDynamicsName, .kind = StepKind::kIterated, .layer = "peers", .collisions = true,
          .make = [](const ParticleSystem& sys, const SolverSpec& spec, int iterations,
                     std::string_view variant) -> std::unique_ptr<Stepper> {
            return std::make_unique<ProjectiveDynamics>(sys, spec, iterations,
                                                        variant == "chebyshev" ? kPdChebyshev : ChebyshevSettings{});
          },
          .variants = {"chebyshev"},
          .describe = [](const Stepper& stepper, const ParticleSystem& sys, RunRecord* row) {
            // constraints: the springs are projected (F_nl); explicit_terms:
            // every other term enters the global step's right-hand side at
            // the iterate; chebyshev_rho(_sweeps): the ρ measured and used
            // by pd/chebyshev and the plain iterations behind it.
            const auto& pd = static_cast<const ProjectiveDynamics&>(stepper);  // this entry builds one
            if (pd.rho() > 0.0) row->SetMethodAttribute("chebyshev_rho", pd.rho());
            if (pd.rho_sweeps() > 0) row->SetMethodAttribute("chebyshev_rho_sweeps", long{pd.rho_sweeps()});
            row->SetMethodAttribute("constraints", std::string("tension"));
            std::string terms;
            for (const std::string& t : sys.TermNames())
              if (t != "tension_nonlinear") terms += (terms.empty() ? "" : ",") + t;
            if (!terms.empty()) row->SetMethodAttribute("explicit_terms", terms);
          },
          .defaults = {{.modifiers = "", .h_factors = {1.0, 1.0 / 4, 1.0 / 16}},
                       {.modifiers = "chebyshev", .h_factors = {1.0, 1.0 / 4, 1.0 / 16}}},
          .table_note = "pd rows: updates = iterations (each projects the springs, evaluates the other forces at the "
                        "iterate and solves with A_1's factor, factorised once per h); projected: ",
          .table_note_terms = "at the iterate: "};
}

}  // namespace clothbench
