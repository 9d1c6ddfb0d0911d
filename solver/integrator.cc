// Step engine (docs/model.md §3, §4, §6; thesis (3.21)–(3.36), Alg. 6).
#include "solver/integrator.h"

#include "model/interrupt.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>

namespace clothbench {

std::string_view ToString(Method m) { return SchemeOf(m).name(); }

std::optional<Method> MethodFromString(std::string_view s) {
  for (Method m : kEngineMethods)
    if (ToString(m) == s) return m;
  return std::nullopt;
}

const std::vector<Method>& ThesisTableMethods() {
  static const std::vector<Method> kAll = {Method::kImexEuler, Method::kImplicitEuler, Method::kSbdf2, Method::kBdf2,
                                           Method::kImplicitMidpoint};
  return kAll;
}

const Scheme& SchemeOf(Method m) {
  switch (m) {
    case Method::kImexEuler: return ImexEulerScheme();
    case Method::kImplicitEuler: return ImplicitEulerScheme();
    case Method::kSbdf2: return Sbdf2Scheme();
    case Method::kBdf2: return Bdf2Scheme();
    case Method::kImplicitMidpoint: return ImplicitMidpointScheme();
    case Method::kSymplecticEuler: return SymplecticEulerScheme();
    case Method::kSbdf3: return Sbdf3Scheme();
  }
  return ImexEulerScheme();  // not reached: every Method is listed
}

bool IsImex(Method m) { return SchemeOf(m).imex(); }

bool IsFullyImplicit(Method m) { return !SchemeOf(m).imex() && !SchemeOf(m).explicit_step(); }

std::string_view ToString(StepStatus s) {
  switch (s) {
    case StepStatus::kOk: return "ok";
    case StepStatus::kCgFailed: return "cg_failed";
    case StepStatus::kNoFixedPointConvergence: return "no_fixed_point_convergence";
    case StepStatus::kNonFinite: return "non_finite";
    case StepStatus::kPreconditionerFailed: return "preconditioner_failed";
    case StepStatus::kFixedPointDiverged: return "fixed_point_diverged";
    case StepStatus::kNoNewtonConvergence: return "no_newton_convergence";
    case StepStatus::kNewtonDiverged: return "newton_diverged";
    case StepStatus::kErrorTestFailed: return "error_test_failed";
    case StepStatus::kTimeLimit: return "time_limit";
  }
  return "?";
}

RunStatus RunStatusOf(StepStatus s) {
  switch (s) {
    case StepStatus::kOk: return RunStatus::kOk;
    case StepStatus::kCgFailed: return RunStatus::kCgFailed;
    case StepStatus::kNoFixedPointConvergence: return RunStatus::kNoFixedPointConvergence;
    case StepStatus::kNonFinite: return RunStatus::kNonFinite;
    case StepStatus::kPreconditionerFailed: return RunStatus::kPreconditionerFailed;
    case StepStatus::kFixedPointDiverged: return RunStatus::kFixedPointDiverged;
    case StepStatus::kNoNewtonConvergence: return RunStatus::kNoNewtonConvergence;
    case StepStatus::kNewtonDiverged: return RunStatus::kNewtonDiverged;
    case StepStatus::kErrorTestFailed: return RunStatus::kErrorTestFailed;
    case StepStatus::kTimeLimit: return RunStatus::kTimeLimit;
  }
  return RunStatus::kSolverFailed;
}

// ---------------------------------------------------------------------------
SystemMatrix::SystemMatrix(const ParticleSystem& system, PreconditionerType type, CholeskyOrdering ordering,
                           bool contact_factors)
    : precond_(type, ordering, contact_factors) {
  const auto start = std::chrono::steady_clock::now();
  const int n = system.num_particles();
  // Pattern: diagonal plus every spring, so A's pattern never changes.
  std::vector<Triplet> t;
  for (int p = 0; p < n; ++p) t.emplace_back(p, p, 0.0);
  for (const Spring& s : system.springs()) {
    t.emplace_back(s.a, s.b, 0.0);
    t.emplace_back(s.b, s.a, 0.0);
  }
  a_.resize(n, n);
  a_.setFromTriplets(t.begin(), t.end());
  a_.makeCompressed();
  const Eigen::Index nnz = a_.nonZeros();
  m_vals_.setZero(nnz);
  lk_vals_.setZero(nnz);
  ld_vals_.setZero(nnz);
  const SparseMatrix& lk = system.stiffness_laplacian();
  const SparseMatrix& ld = system.damping_laplacian();
  for (int col = 0; col < n; ++col)
    for (int pos = a_.outerIndexPtr()[col]; pos < a_.outerIndexPtr()[col + 1]; ++pos) {
      const int row = a_.innerIndexPtr()[pos];
      if (row == col) m_vals_(pos) = system.masses()(row);
      lk_vals_(pos) = lk.coeff(row, col);
      if (ld.nonZeros() > 0) ld_vals_(pos) = ld.coeff(row, col);
    }
  ThrowIfInterrupted();  // between the setup's phases: after the assembly,
  analyzed_ = precond_.Analyze(a_, system.fixed());
  ThrowIfInterrupted();  // and after the ordering
  setup_seconds_ = analysis_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

bool SystemMatrix::Update(double alpha_h) {
  if (alpha_h == alpha_h_) return true;  // cached while αh is constant (docs/model.md §3)
  const auto start = std::chrono::steady_clock::now();
  Eigen::Map<Eigen::VectorXd> vals(a_.valuePtr(), a_.nonZeros());
  vals = m_vals_ + (alpha_h * alpha_h) * lk_vals_ + alpha_h * ld_vals_;  // (3.24), (3.31)
  removed_.clear();  // rebuilt: nothing to restore
  ++rebuilds_;
  const bool ok = analyzed_ && precond_.Factorize(a_);
  setup_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  alpha_h_ = ok ? alpha_h : -1.0;
  return ok;
}

bool SystemMatrix::Refactorize() {
  const auto start = std::chrono::steady_clock::now();
  const bool ok = analyzed_ && precond_.Factorize(a_);
  setup_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return ok;
}

void SystemMatrix::Restore() {
  double* vals = a_.valuePtr();
  for (auto it = removed_.rbegin(); it != removed_.rend(); ++it) vals[it->first] = it->second;
  removed_.clear();
}

void SystemMatrix::AddToDiagonal(int p, double value) {
  double* vals = a_.valuePtr();
  const int* outer = a_.outerIndexPtr();
  const int* inner = a_.innerIndexPtr();
  const int* at = std::lower_bound(inner + outer[p], inner + outer[p + 1], p);
  const int pos = static_cast<int>(at - inner);
  removed_.emplace_back(pos, vals[pos]);
  vals[pos] += value;
}

void SystemMatrix::RemoveCouplings(const std::vector<RemovedCoupling>& couplings) {
  double* vals = a_.valuePtr();
  const int* outer = a_.outerIndexPtr();
  const int* inner = a_.innerIndexPtr();
  for (const RemovedCoupling& c : couplings) {
    const double w = alpha_h_ * alpha_h_ * c.stiffness + alpha_h_ * c.damping;
    for (const auto& [row, col] : {std::pair{c.a, c.b}, std::pair{c.b, c.a}}) {
      const int* at = std::lower_bound(inner + outer[col], inner + outer[col + 1], row);
      const int pos = static_cast<int>(at - inner);
      removed_.emplace_back(pos, vals[pos]);
      vals[pos] += w;
    }
  }
}

bool SystemMatrix::AdaptTo(const VelocityFilter& filter) {
  const double before = precond_.contact_stats().seconds;
  const bool ok = precond_.AdaptTo(a_, filter);
  setup_seconds_ += precond_.contact_stats().seconds - before;
  return ok;
}

// ---------------------------------------------------------------------------
StepEngine::StepEngine(const ParticleSystem& system, Method method, const SolverSpec& solver)
    : sys_(system),
      method_(method),
      scheme_(SchemeOf(method)),
      opts_(solver),
      sysmat_(system, solver.preconditioner, solver.cholesky_ordering, solver.contact_factors),
      contacts_(system) {
  sysmat_.set_amg_frames(solver.amg_frames);
  contacts_.set_friction_law(solver.friction_law);
  contacts_.set_stiction(solver.friction_cap == FrictionCap::kStiction);
  const int n = system.num_particles();
  filter_.Reserve(n);
  for (int p : system.fixed()) filter_.Fix(p);
  work_.Resize(n);
  if (IsImplicit(solver.friction_law) && contacts_.active()) {
    friction_diagonal_.setZero(n);
    sysmat_.ReserveChanges(n);
  }
  const bool multistep = scheme_.past_steps() > 0;
  if (multistep) contacts_.KeepEchoes(scheme_.past_steps());
  error_control_ = solver.step_control == StepControl::kError && scheme_.error_controlled();
  // Under error control the contact events are located and restart the
  // method (docs/notes/collisions.md, "Error control through contact events"):
  // entries within a hundredth of the absolute tolerance happen now.
  event_location_ = error_control_ && contacts_.active();
  if (event_location_) {
    contacts_.set_event_tolerance(kEventToleranceFraction * solver.AbsoluteTolerance());
    // The impulses read from the solve's residual set the friction and the
    // releases: at the scene's η = 1e-6 their noise kept rtol 1e-7 on the
    // swinging box below 1e-6 s steps (time_limit at t = 0.44 s; with
    // η = 1e-11 it reached 0.5 s in 27 s), so η follows rtol.
    opts_.cg_tolerance = std::min(opts_.cg_tolerance, kCgToleranceFraction * solver.rtol);
    x_left_.setZero(n, 3);
    v_left_.setZero(n, 3);
  }
  if (multistep && contacts_.active() && (solver.contact_history == ContactHistory::kRestart || event_location_)) {
    in_contact_.assign(static_cast<std::size_t>(n), 0);
    in_contact_prev_.assign(static_cast<std::size_t>(n), 0);
  }
  if (IsFullyImplicit(method) && solver.nonlinear_solver == NonlinearSolver::kNewton) {
    const auto start = std::chrono::steady_clock::now();
    TangentOptions to;
    to.projection = solver.tangent_projection;
    to.include_explicit_terms = solver.tangent_explicit_terms;
    to.symmetrize = true;  // the PCG needs a symmetric matrix (see TangentOptions)
    tangent_ = std::make_unique<TangentSystem>(system, to);
    tangent_pre_ = TangentPreconditioner(solver.preconditioner);
    tangent_pre_.Analyze(tangent_->matrix(), &sysmat_.preconditioner());
    tangent_work_.Resize(n);
    vr_.setZero(n, 3);
    br_.setZero(n, 3);
    tangent_setup_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  for (MatrixN3* m : {&x0_, &v0_, &xm1_, &vm1_, &gm1_, &g0_, &g_, &b0_, &b_, &xhat_, &vhat_, &xg0_, &vg_, &xg_, &v1_, &x1_,
                      &tmp_, &vprev_})
    m->setZero(n, 3);
  if (error_control_)
    for (MatrixN3* m : {&xm2_, &vm2_, &a_init_}) m->setZero(n, 3);
  if (scheme_.past_steps() >= 2)
    for (MatrixN3* m : {&xm2_, &vm2_}) m->setZero(n, 3);
  if (scheme_.past_g() >= 2) gm2_.setZero(n, 3);
}

void StepEngine::Reset(double t, const MatrixN3& x, const MatrixN3& v) {
  t_ = t;
  x0_ = x;
  v0_ = v;
  filter_.Impose(&v0_);
  past_ = 0;
  have_g0_ = false;
  h_prev_ = h_prev2_ = 0.0;
  event_step_ = false;
  jumped_ = false;
  events_ = 0;
  contacts_.Reset();
  refactor_choice_ = RefactorChoice();
  std::fill(in_contact_prev_.begin(), in_contact_prev_.end(), 0);
  if (error_control_) {
    // v̇ at the start, the exact slope of the error estimate's predictors.
    sys_.Forces(t, x0_, v0_, &a_init_);
    a_init_ = sys_.masses().cwiseInverse().asDiagonal() * a_init_;
    filter_.Impose(&a_init_);
  }
}

// The start slope after a contact event: v̇ = M⁻¹(f + F_friction) at the
// state, less the directions the contacts prescribe (their velocity is
// the response's, not integrated; ErrorNorm leaves them out).
void StepEngine::StartSlope() {
  sys_.Forces(t_, x0_, v0_, &a_init_);
  a_init_ += contacts_.friction();
  a_init_ = sys_.masses().cwiseInverse().asDiagonal() * a_init_;
  filter_.Project(&a_init_);
}

StepStats StepEngine::Step(double h) {
  const auto start = std::chrono::steady_clock::now();
  const double setup_before = sysmat_.setup_seconds() + tangent_setup_seconds_;
  StepStats st = StepImpl(h);
  st.solve_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  st.setup_time = sysmat_.setup_seconds() + tangent_setup_seconds_ - setup_before;
  return st;
}

StepStats StepEngine::StepImpl(double h) {
  if (scheme_.explicit_step()) {
    StepStats st;
    st.t = t_ + h;
    st.h = h;
    return ExplicitStep(h, st);
  }
  if (!event_location_) {
    StepStats st = SolveHolding(h);
    return st.status == StepStatus::kOk ? FinishStep(h, st) : st;
  }
  // Event location (docs/notes/collisions.md, "Error control through contact
  // events"): a step in which a free particle crossed into the collision
  // area is redone up to the earliest crossing, whose entries then jump.
  int updates = 0, cg_iterations = 0;
  StepStats st;
  jumped_ = false;
  for (int pass = 0;; ++pass) {
    st = SolveHolding(h);
    updates += st.updates;
    cg_iterations += st.cg_iterations;
    if (st.status != StepStatus::kOk) break;
    const double theta = pass + 1 < kLocationPasses ? contacts_.Crossing(t_, h, x0_, v0_, x1_, v1_) : 1.0;
    if (theta >= 1.0) {
      st = FinishStep(h, st);
      if (st.status == StepStatus::kOk) {
        x_left_ = x0_;  // into allocated storage
        v_left_ = v0_;
        jumped_ = contacts_.ApplyJumps(t_, &x0_, &v0_) > 0;
      }
      break;
    }
    h *= theta;
  }
  st.updates = updates;
  st.cg_iterations = cg_iterations;
  return st;
}

Vector3 StepEngine::ResidualRow(int p) const {
  Vector3 av = Vector3::Zero();
  for (SparseMatrix::InnerIterator it(sysmat_.matrix(), p); it; ++it) av += it.value() * v1_.row(it.row()).transpose();
  return Vector3(av - b_.row(p).transpose());
}

StepStats StepEngine::SolveHolding(double h) {
  StepStats st = Solve(h);
  const bool friction_step = friction_step_, refactored = refactored_;
  int updates = st.updates, cg_iterations = st.cg_iterations;
  for (int k = 0; contacts_.revises() && k < ContactResponse::kHoldRevisions && st.status == StepStatus::kOk; ++k) {
    if (!contacts_.ReviseHolds([this](int p) { return ResidualRow(p); }, v0_, v1_, vhat_,
                               opts_.cg_tolerance * FreeRowsNorm(b_, sys_.fixed()), opts_.cg_tolerance))
      break;
    revising_ = true;
    st = Solve(h);
    revising_ = false;
    updates += st.updates;
    cg_iterations += st.cg_iterations;
  }
  st.updates = updates;
  st.cg_iterations = cg_iterations;
  if (friction_step && st.status == StepStatus::kOk) refactor_choice_.Count(refactored, cg_iterations);
  return st;
}

StepStats StepEngine::Solve(double h) {
  StepStats st;
  st.t = t_ + h;
  st.h = h;
  // The contacts first: under ContactHistory::kRestart, and under event
  // location, a multistep method whose contact set changed restarts with
  // its one-step start.
  int colliding = 0;
  if (contacts_.active()) {
    const MatrixN3* xm1 = past_ > 0 ? &xm1_ : nullptr;
    colliding = revising_ ? contacts_.SetUpAgain(&filter_) : contacts_.SetUp(t_, h, x0_, v0_, xm1, &filter_);
    // event_step_ stays set over a retry or a redo (ContactSetChanged
    // compares with the last attempt) until the step is accepted.
    if (!in_contact_.empty() && ContactSetChanged() && (past_ > 0 || event_location_)) {
      past_ = 0;
      event_step_ = event_location_;
    }
    if (event_step_) StartSlope();  // with this attempt's filter and friction
  }
  PrescribeFixedTargets(sys_, t_ + h, &filter_);  // moving fixed particles: their velocity at the step's end
  const Scheme& step = StepScheme(h);
  // Variable-step BDF(2) coefficients, ω = h_n/h_{n−1} (docs/model.md §4, (3.28)–(3.32)).
  const double omega = past_ > 0 ? h / h_prev_ : 1.0;
  const bool multistep_form = step.past_steps() > 0;
  if (colliding > 0 && multistep_form && opts_.contact_history == ContactHistory::kProject) ProjectContactHistory();
  // SBDF(2)/(3) extrapolate g from its history. With virtual particles g
  // is this step's force function (model/virtual_springs.h), so the
  // history is evaluated with it: extrapolating across a change of
  // topology would double the jump of the virtual springs' forces.
  if (const VirtualSprings* vp = sys_.virtual_springs()) {
    const bool active = !vp->particles().empty();
    if ((active || virtual_before_) && past_ > 0) {
      if (step.past_g() >= 1) EngineExplicitForces(t_ - h_prev_, xm1_, vm1_, &gm1_);
      if (step.past_g() >= 2) EngineExplicitForces(t_ - h_prev_ - h_prev2_, xm2_, vm2_, &gm2_);
    }
    virtual_before_ = active;
  }
  const StageCoefficients c = PrepareStage(step, h, omega);
  carry_ = HistoryCarry{c.carry1, c.carry2};
  if (colliding > 0 && multistep_form && opts_.contact_history == ContactHistory::kLand) LandContactTargets(h, c.gamma);

  if (!sysmat_.Update(c.alpha * h)) {
    st.status = StepStatus::kPreconditionerFailed;
    return st;
  }
  sysmat_.Restore();  // the last step's friction rates (FrictionLaw::kImplicit) and removed couplings
  const bool friction_before = friction_diagonal_set_;
  if (friction_diagonal_set_) {
    friction_diagonal_.setZero();
    friction_diagonal_set_ = false;
  }
  if (const VirtualSprings* vp = sys_.virtual_springs()) sysmat_.RemoveCouplings(vp->removed_couplings());
  if (contacts_.active()) {
    st.colliding = colliding;
    if (opts_.friction_cap == FrictionCap::kSystem) {
      // A_α is isotropic: tᵀ A_pq t = A_pq (model/solver_spec.h, FrictionCap).
      const SparseMatrix& a = sysmat_.matrix();
      const auto coupling = [&](int p, const Vector3&, auto&& visit) {
        for (SparseMatrix::InnerIterator it(a, p); it; ++it)
          if (it.row() != p) visit(static_cast<int>(it.row()), -it.value());
      };
      contacts_.CapBySystem(coupling);
    }
    b0_ += h * contacts_.friction();  // Coulomb friction, explicit (docs/model.md §2.5)
    // FrictionLaw::kImplicit: −c (v₁ − u)_t in the solve (h c on A's
    // diagonal, h c u in b; the filter keeps their tangential part).
    contacts_.ForEachFrictionDamping([&](int p, double rate, const Vector3& u) {
      friction_diagonal_(p) = h * rate;
      friction_diagonal_set_ = true;
      sysmat_.AddToDiagonal(p, h * rate);
      b0_.row(p) += (h * rate) * u.transpose();
    });
    // The preconditioner of A with this step's rates (and without the
    // last step's), when that has paid (RefactorChoice); a solve again of
    // the same step keeps the step's factor.
    friction_step_ = !revising_ && (friction_before || friction_diagonal_set_);
    refactored_ = friction_step_ && refactor_choice_.Choose(sysmat_.preconditioner().RefactorIterations(sys_.num_particles()));
    if (refactored_ && !sysmat_.Refactorize()) {
      st.status = StepStatus::kPreconditionerFailed;
      return st;
    }
    const bool adapted = sysmat_.AdaptTo(filter_);
    st.preconditioner = sysmat_.preconditioner().ServedBy();
    if (!adapted) {
      st.status = StepStatus::kPreconditionerFailed;
      return st;
    }
  }
  // IMEX steps, and a start step whose successor extrapolates g₀.
  if (step.evaluates_g0()) ExplicitTerms(step, omega);

  // Predictor (3.25, 3.32): constant velocity, or linear extrapolation.
  // A solve again of the step (SolveHolding) starts from the last solve's
  // v₁, which differs only where contacts were released.
  if (!revising_) {
    v1_ = v0_;
    if (opts_.predictor == Predictor::kExtrapolate && past_ > 0) v1_ += omega * (v0_ - vm1_);
  }

  const PcgOptions pcg_opts{opts_.cg_tolerance, opts_.cg_max_iterations};
  // With contacts and CgReference::kFixedOnly, η is relative to ‖S_F b‖:
  // only the fixed particles' rows are left out (see CgReference).
  const bool fixed_only_norm = contacts_.active() && opts_.cg_reference == CgReference::kFixedOnly;
  if (step.exact_updates() == 0 && tangent_) {
    if (!NewtonIterate(h, c.alpha, c.beta, c.gamma_g, c.t_g, c.midpoint, fixed_only_norm, &st)) return st;
  } else if (!FixedPointIterate(h, c, step, fixed_only_norm, pcg_opts, &st)) {
    return st;
  }
  x1_ = xhat_ + (c.gamma * h) * v1_;
  // Fixed particles at rest have v = 0; c1 x₀ − c2 x₋₁ would let them drift
  // by round-off (c1 − c2 = 1 only in exact arithmetic), so keep x₀ exactly.
  // Moving ones end at their prescribed state.
  HoldFixed(sys_, t_ + h, x0_, &x1_, &v1_);
  return st;
}

bool StepEngine::ContactSetChanged() {
  std::fill(in_contact_.begin(), in_contact_.end(), 0);
  filter_.ForEachConstraint([&](int p, int, const auto&) {
    if (!sys_.is_fixed(p)) in_contact_[static_cast<std::size_t>(p)] = 1;  // a contact (held by stiction: 3 directions)
  });
  const bool changed = in_contact_ != in_contact_prev_;
  in_contact_prev_.swap(in_contact_);
  return changed;
}

// ContactHistory::kProject: along the collision direction D of each particle
// the response constrains, with target velocity u = ⟨v₁, D⟩ (4.4), the
// history is replaced by a constant normal velocity u:
//   ⟨x₋ₖ, D⟩ ← ⟨x₀, D⟩ − (t₀ − t₋ₖ) u,  ⟨v₋ₖ, D⟩ ← u,
// tangential components kept. Any BDF formula is exact on a linear path, so
// x̂ then lies at ⟨x₀, D⟩ + (1 − γ) h u and x₁ = x̂ + γ h v₁ at ⟨x₀, D⟩ + h u:
// along D the multistep method moves as the one-step update of (4.4) does
// (variable step: c2 h₋₁ = h ω/(1 + 2ω) = (1 − c3) h).
void StepEngine::ProjectContactHistory() {
  const bool second = xm2_.rows() > 0;
  const double back2 = h_prev_ + h_prev2_;
  filter_.ForEachTarget([&](int p, int count, const Eigen::Matrix3d& dirs, const Vector3& targets) {
    if (count >= 3) return;  // fixed particles, and contacts held by stiction (their history kept)
    const Vector3 d = dirs.col(0);
    const double u = targets(0), x0 = x0_.row(p).dot(d);
    auto set = [&](MatrixN3& m, double value) { m.row(p) += (value - m.row(p).dot(d)) * d.transpose(); };
    set(xm1_, x0 - h_prev_ * u);
    set(vm1_, u);
    if (second) {
      set(xm2_, x0 - back2 * u);
      set(vm2_, u);
    }
  });
}

// ContactHistory::kLand: the target velocity u of (4.4) moves a particle by
// h u along D in the one-step update x₁ = x₀ + h v₁. The multistep formula
// x₁ = x̂ + γ h v₁ does so with
//   ⟨v₁, D⟩ = (h u − ⟨x̂ − x₀, D⟩)/(γ h),
// which lands an entering particle on δ (and moves a particle in the band
// by ω_r (δ − d)) with the history kept.
void StepEngine::LandContactTargets(double h, double gamma) {
  filter_.ForEachTarget([&](int p, int count, const Eigen::Matrix3d& dirs, Vector3& targets) {
    if (count >= 3) return;
    const double drift = (xhat_.row(p) - x0_.row(p)).dot(dirs.col(0).transpose());
    targets(0) = (h * targets(0) - drift) / (gamma * h);
  });
}

const Scheme& StepEngine::StepScheme(double h) const {
  // Multistep methods start with a one-step formula of the same family
  // (docs/model.md §4): SBDF(2) with IMEX Euler, BDF(2) with implicit
  // Euler, SBDF(3) with the IMEX midpoint step and SBDF(2).
  return scheme_.ForStep(past_, h == h_prev_ && h_prev_ == h_prev2_);
}

void StepEngine::EngineExplicitForces(double t, const MatrixN3& x, const MatrixN3& v, MatrixN3* g) const {
  sys_.ExplicitForces(t, x, v, g);
  if (const VirtualSprings* vp = sys_.virtual_springs()) vp->AddRemovedCouplings(x, v, g);
}

void StepEngine::LinearProduct(bool damping, const MatrixN3& x, MatrixN3* out) const {
  out->noalias() = (damping ? sys_.damping_laplacian() : sys_.stiffness_laplacian()) * x;
  if (const VirtualSprings* vp = sys_.virtual_springs()) vp->AddCouplingProduct(damping, x, out);
}

StageCoefficients StepEngine::PrepareStage(const Scheme& scheme, double h, double omega) {
  Stage stage;
  stage.t = t_;
  stage.h = h;
  stage.omega = omega;
  stage.mass = &sys_.masses();
  stage.x0 = &x0_;
  stage.v0 = &v0_;
  stage.xm1 = &xm1_;
  stage.vm1 = &vm1_;
  stage.xm2 = &xm2_;
  stage.vm2 = &vm2_;
  stage.xhat = &xhat_;
  stage.vhat = &vhat_;
  stage.xg0 = &xg0_;
  stage.b0 = &b0_;
  stage.tmp = &tmp_;
  stage.engine = this;
  return scheme.Prepare(stage);
}

void StepEngine::ExplicitTerms(const Scheme& scheme, double omega) {
  if (!have_g0_) {
    EngineExplicitForces(t_, x0_, v0_, &g0_);
    have_g0_ = true;
  }
  scheme.Extrapolate(g0_, gm1_, gm2_, omega, &g_);
}

bool StepEngine::FixedPointIterate(double h, const StageCoefficients& c, const Scheme& scheme, bool fixed_only_norm,
                                   PcgOptions pcg_opts, StepStats* st) {
  const double beta = c.beta, gamma_g = c.gamma_g, t_g = c.t_g;
  const bool midpoint = c.midpoint;
  // IMEX steps do one update, a start step may do an exact number
  // (Scheme::exact_updates: SBDF(3)'s midpoint start two), the fully
  // implicit ones iterate to convergence.
  const bool imex = scheme.imex();
  const int exact = scheme.exact_updates();
  const int max_updates = exact > 0 ? exact : opts_.max_updates;
  const double b0_norm = FreeRowsNorm(b0_, sys_.fixed());
  bool converged = false;
  for (int u = 0; u < max_updates && !converged; ++u) {
    if (!imex) {
      // Evaluate g at the current iterate (Alg. 6 line 7).
      xg_ = xg0_ + (gamma_g * h) * v1_;
      if (midpoint) {
        vg_ = 0.5 * (v0_ + v1_);
        EngineExplicitForces(t_g, xg_, vg_, &g_);
      } else {
        EngineExplicitForces(t_g, xg_, v1_, &g_);
      }
    }
    b_ = b0_ + (beta * h) * g_;
    if (fixed_only_norm) pcg_opts.rhs_norm = FreeRowsNorm(b_, sys_.fixed());
    pcg_opts.residual_floor = RoundOffFloor(b0_norm, beta * h * FreeRowsNorm(g_, sys_.fixed()));
    if (opts_.fixed_point_tolerance > 0.0) vprev_ = v1_;
    last_pcg_ = FilteredPcg(sysmat_.matrix(), b_, filter_, sysmat_.preconditioner(), pcg_opts, &v1_, &work_);
    ++st->updates;
    st->cg_iterations += last_pcg_.iterations;
    if (last_pcg_.status != PcgStatus::kConverged) {
      st->pcg_status = last_pcg_.status;
      if (last_pcg_.status == PcgStatus::kTimeLimit)
        st->status = StepStatus::kTimeLimit;
      else if (last_pcg_.status != PcgStatus::kNonFinite)
        st->status = StepStatus::kCgFailed;
      else
        st->status = (!imex && u > 0) ? StepStatus::kFixedPointDiverged : StepStatus::kNonFinite;
      return false;
    }
    // Alg. 6 line 11: converged when the PCG needed 0 iterations (the new
    // g did not move the solution beyond the CG tolerance); optionally also
    // when max |Δv| ≤ fixed_point_tolerance.
    if ((exact > 0 && u + 1 == exact) || last_pcg_.iterations == 0 ||
        (opts_.fixed_point_tolerance > 0.0 && (v1_ - vprev_).cwiseAbs().maxCoeff() <= opts_.fixed_point_tolerance)) {
      converged = true;
      break;
    }
  }
  if (!converged) {
    st->status = StepStatus::kNoFixedPointConvergence;
    return false;
  }
  return true;
}

StepStats StepEngine::FinishStep(double h, StepStats st) {
  if (error_control_) {
    st.error_norm = ErrorNorm(h, &st.error_order);
    if (!std::isfinite(st.error_norm)) {
      st.status = StepStatus::kNonFinite;
      return st;
    }
    if (st.error_norm > 1.0) {
      st.status = StepStatus::kErrorTestFailed;
      return st;
    }
  }
  if (contacts_.active()) {
    contacts_.SetImplicitFriction(v1_);
    contacts_.ReadImpulses([this](int p) { return ResidualRow(p); }, v0_, v1_, vhat_,
                           opts_.cg_tolerance * FreeRowsNorm(b_, sys_.fixed()), carry_);
  }
  if (!Commit(h)) st.status = StepStatus::kNonFinite;
  return st;
}

// Local error estimate of variable-step BDF(2) by Milne's device (Hairer &
// Wanner, Solving ODEs II, §III.7; Shampine & Gordon 1975): for z = x and
// z = v, the corrector z₁ is compared with a quadratic predictor P
// extrapolated to t₁ = t₀ + h. With steps h, H = h₋₁, H₂ = h₋₂ and a cubic z,
//   z₁ − z(t₁) ≈  E_c z⁽³⁾,  E_c = (c2 (h+H)³ − c1 h³)/6   (BDF(2) truncation error, ω = h/H)
//   P  − z(t₁) ≈ −E_p z⁽³⁾                                  (extrapolation error)
// so the corrector's local error is E_c/(E_c + E_p)·(z₁ − P). P is
//  - from the third step on, the quadratic through z₋₂, z₋₁, z₀:
//    E_p = h (h+H)(h+H+H₂)/6 (2/11·(z₁ − P) at constant h);
//  - in the second step, the quadratic through z₋₁ and z₀ with the exact
//    initial slope ż₋₁ (ẋ = v, v̇ = M⁻¹f at t = 0): E_p = h (h+H)²/6.
// The start step (implicit or IMEX Euler) is compared with the explicit Euler
// predictor z₀ + h ż₀: local error (z₁ − P)/2, first order. The slope of
// the numerical solution (the BDF derivative) is not used anywhere: it is
// itself O(h²) off, which would enter P at the order of the estimate.
// SBDF(2) uses the same estimate: the extrapolation error of ĝ is not in it.
// The norm is CVODE's weighted RMS over the free particles' x and v
// components, w = 1/(rtol |z₀| + atol).
double StepEngine::ErrorNorm(double h, int* order) {
  const double rtol = opts_.rtol, atol = opts_.AbsoluteTolerance();
  const int n = sys_.num_particles();
  double k = 0.5;  // LTE = k (z₁ − P)
  const double hh = h_prev_, h2 = h_prev2_;
  if (past_ == 0) {
    *order = 1;
  } else {
    *order = 2;
    const Bdf2Coefficients bdf(h / hh);
    const double ec = (bdf.c2 * std::pow(h + hh, 3) - bdf.c1 * h * h * h) / 6.0;
    const double ep = past_ == 1 ? h * (h + hh) * (h + hh) / 6.0 : h * (h + hh) * (h + hh + h2) / 6.0;
    k = ec / (ec + ep);
  }
  // Predictors at t₀ + h. slope: ż₀ (start step) or ż₋₁ (second step).
  auto predict = [&](double zm2, double zm1, double z0, double slope) {
    if (past_ == 0) return z0 + h * slope;
    if (past_ == 1) {
      // P(s) through (−H, z₋₁) with slope ż₋₁ there, and (0, z₀).
      const double q = (z0 - zm1 - slope * hh) / (hh * hh);
      const double s = h + hh;
      return zm1 + slope * s + q * s * s;
    }
    // Newton form through (−H−H₂, z₋₂), (−H, z₋₁), (0, z₀).
    const double d1 = (z0 - zm1) / hh, d0 = (zm1 - zm2) / h2;
    const double d2 = (d1 - d0) / (hh + h2);
    return z0 + d1 * h + d2 * h * (h + hh);
  };
  // The local errors k (z₁ − P) of x and v in tmp_ and vprev_ (scratch).
  for (int p = 0; p < n; ++p) {
    if (sys_.is_fixed(p)) continue;
    for (int c = 0; c < 3; ++c) {
      double px, pv;
      if (past_ == 0) {
        px = predict(0, 0, x0_(p, c), v0_(p, c));
        pv = predict(0, 0, v0_(p, c), a_init_(p, c));
      } else if (past_ == 1) {
        px = predict(0, xm1_(p, c), x0_(p, c), vm1_(p, c));
        pv = predict(0, vm1_(p, c), v0_(p, c), a_init_(p, c));
      } else {
        px = predict(xm2_(p, c), xm1_(p, c), x0_(p, c), 0);
        pv = predict(vm2_(p, c), vm1_(p, c), v0_(p, c), 0);
      }
      tmp_(p, c) = k * (x1_(p, c) - px);
      vprev_(p, c) = k * (v1_(p, c) - pv);
    }
  }
  // A contact's normal direction is prescribed by the response ((4.4): an
  // impact's jump, the relaxation toward the δ-surface), not integrated:
  // its error is not the method's, and is left out.
  // Nor is the tangential one of a particle whose friction sticks it in
  // the step (the cap of Coulomb's law stops it: a jump, not the method's).
  if (contacts_.active()) {
    filter_.Project(&tmp_);
    filter_.Project(&vprev_);
    for (int p = 0; p < n; ++p)
      if (contacts_.sticks(p)) {
        tmp_.row(p).setZero();
        vprev_.row(p).setZero();
      }
  }
  double sum = 0.0;
  long count = 0;
  for (int p = 0; p < n; ++p) {
    if (sys_.is_fixed(p)) continue;
    for (int c = 0; c < 3; ++c) {
      const double wx = tmp_(p, c) / (rtol * std::abs(x0_(p, c)) + atol);
      const double wv = vprev_(p, c) / (rtol * std::abs(v0_(p, c)) + atol);
      sum += wx * wx + wv * wv;
    }
    count += 6;
  }
  return count > 0 ? std::sqrt(sum / static_cast<double>(count)) : 0.0;
}

// Newton's method for the fully implicit step (docs/model.md §10). The step equation
// of every method is F(v₁) = A_α v₁ − b₀ − βh g(t_g, x̂_g + γ_g h v₁, v_g(v₁)) = 0
// on the free directions (S F = 0, (I − S) v₁ = z), with v_g = v₁, or
// (v₀ + v₁)/2 for the midpoint rule. Its Jacobian is exactly
//   dF/dv₁ = A_α − βh (γ_g h ∂g/∂x + ∂v_g/∂v₁ ∂g/∂v) = M − αh ∂f/∂v − α²h² ∂f/∂x = J_α,
// since β = α = γ_g (implicit Euler, BDF(2)) or β = 1, γ_g = α² = 1/4,
// ∂v_g/∂v₁ = α = 1/2 (midpoint), with ∂f/∂· at (t_g, x_g, v_g). Each
// iteration solves J_α v_new = J_α v − F(v) by the filtered PCG, whose
// initial residual is then −S F(v). The stop is Alg. 6's: ‖S F(v)‖₂ ≤ η·‖S_F b‖₂
// (the fixed point's "PCG needed 0 iterations"; the same norm, see
// CgReference), or max |Δv| ≤ fixed_point_tolerance if that is set, so both
// solvers stop at the same discrete solution within the same tolerance; or
// ‖S F(v)‖₂ at the round-off of b (RoundOffFloor, solver/pcg.h), below
// which neither test can pass (cloth at rest without external forces).
// The inner PCG stops at a tenth of that threshold, so that the next
// residual is not dominated by the linear solve's own error.
bool StepEngine::NewtonIterate(double h, double alpha, double beta, double gamma_g, double t_g, bool midpoint,
                               bool fixed_only_norm, StepStats* st) {
  constexpr double kLinearFraction = 0.1;
  const double alpha_h = alpha * h;
  const SparseMatrix& a = sysmat_.matrix();
  filter_.Impose(&v1_);  // the iterates satisfy the constraints from the start
  double dv_max = 0.0, dv_norm = 0.0, dv_prev = 0.0;
  const double b0_norm = FreeRowsNorm(b0_, sys_.fixed());
  for (int u = 0; u < opts_.max_updates; ++u) {
    xg_ = xg0_ + (gamma_g * h) * v1_;
    if (midpoint) vg_ = 0.5 * (v0_ + v1_);
    const MatrixN3& vg = midpoint ? vg_ : v1_;
    EngineExplicitForces(t_g, xg_, vg, &g_);
    b_ = b0_ + (beta * h) * g_;
    ++st->updates;
    // F(v) = A_α v − b in tmp_, its filtered norm, and the reference ‖S_F b‖.
    SymmetricProduct(a, v1_, &tmp_);
    tmp_ -= b_;
    double reference = 0.0;
    if (fixed_only_norm) {
      reference = FreeRowsNorm(b_, sys_.fixed());
    } else {
      vprev_ = b_;
      filter_.Project(&vprev_);
      reference = vprev_.norm();
    }
    vprev_ = tmp_;
    filter_.Project(&vprev_);
    const double residual = vprev_.norm();
    if (!std::isfinite(residual)) {
      st->status = u > 0 ? StepStatus::kNewtonDiverged : StepStatus::kNonFinite;
      return false;
    }
    // Below the round-off of b (RoundOffFloor) the residual says nothing.
    const double floor = RoundOffFloor(b0_norm, beta * h * FreeRowsNorm(g_, sys_.fixed()));
    const double threshold = std::max(opts_.cg_tolerance * reference, floor);
    // Both tests: the residual (Alg. 6's), and the error of the iterate
    // relative to the velocities, estimated from the last correction as
    // ρ/(1 − ρ)‖Δv‖ with the observed contraction ρ = ‖Δv_k‖/‖Δv_{k−1}‖ (as
    // CVODE's Newton test, Hindmarsh et al. 2005 §2.1), or ‖Δv‖ itself after
    // the first correction; or max |Δv| ≤ fixed_point_tolerance if set. The
    // residual alone is not enough at large numerical stiffness: ‖S_F b‖
    // then holds the large, mutually cancelling spring terms (h L_K x and
    // h F_nl), so η‖S_F b‖ allows velocity errors far above η‖v‖ (measured:
    // energy growth of implicit Euler at S = 1e8, h = 0.01 s).
    const double rate = dv_prev > 0.0 ? dv_norm / dv_prev : 1.0;
    const double error_estimate = rate < 1.0 && u > 1 ? rate / (1.0 - rate) * dv_norm : dv_norm;
    const bool small_step = u == 0 || error_estimate <= opts_.cg_tolerance * std::max(v1_.norm(), v0_.norm());
    if ((residual <= threshold && small_step) || residual <= floor ||
        (u > 0 && opts_.fixed_point_tolerance > 0.0 && dv_max <= opts_.fixed_point_tolerance)) {
      last_pcg_ = PcgSummary{PcgStatus::kConverged, 0, residual, reference};
      return true;
    }
    if (u + 1 == opts_.max_updates) break;  // no update left to check a new iterate
    if (u == 0 || opts_.newton_jacobian == NewtonJacobian::kRefresh) {
      const auto start = std::chrono::steady_clock::now();
      tangent_->Update(t_g, xg_, vg, alpha_h);
      if (friction_diagonal_set_) tangent_->AddToDiagonal(friction_diagonal_);  // FrictionLaw::kImplicit
      const bool ok = tangent_pre_.Factorize(tangent_->matrix());
      tangent_setup_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      if (!ok) {
        st->status = StepStatus::kPreconditionerFailed;
        return false;
      }
    }
    // J v_new = J v − F(v), from v.
    vr_ = v1_;
    TangentProduct(tangent_->matrix(), vr_, &br_);
    br_ -= tmp_;
    PcgOptions inner{kLinearFraction * opts_.cg_tolerance, opts_.cg_max_iterations, reference,
                     kLinearFraction * floor};
    last_pcg_ = FilteredPcg(tangent_->matrix(), br_, filter_, tangent_pre_, inner, &vr_, &tangent_work_);
    st->cg_iterations += last_pcg_.iterations;
    if (last_pcg_.status != PcgStatus::kConverged) {
      st->pcg_status = last_pcg_.status;
      if (last_pcg_.status == PcgStatus::kTimeLimit)
        st->status = StepStatus::kTimeLimit;
      else if (last_pcg_.status != PcgStatus::kNonFinite)
        st->status = StepStatus::kCgFailed;
      else
        st->status = u > 0 ? StepStatus::kNewtonDiverged : StepStatus::kNonFinite;
      return false;
    }
    dv_max = (vr_ - v1_).cwiseAbs().maxCoeff();
    dv_prev = dv_norm;
    dv_norm = (vr_ - v1_).norm();
    v1_ = vr_;
  }
  st->status = StepStatus::kNoNewtonConvergence;
  return false;
}

bool StepEngine::Commit(double h) {
  if (!x1_.allFinite() || !v1_.allFinite()) return false;
  // (x₋₁, v₋₁, g₋₁) ← (x₀, v₀, g₀), (x₀, v₀) ← (x₁, v₁). Swaps, no copies.
  if (error_control_ || scheme_.past_steps() >= 2) {  // (x₋₂, v₋₂) ← (x₋₁, v₋₁): error estimate, two-step formulas
    xm2_.swap(xm1_);
    vm2_.swap(vm1_);
    h_prev2_ = h_prev_;
  }
  if (scheme_.past_g() >= 2) gm2_.swap(gm1_);
  past_ = std::min(past_ + 1, 2);
  xm1_.swap(x0_);
  x0_.swap(x1_);
  vm1_.swap(v0_);
  v0_.swap(v1_);
  gm1_.swap(g0_);  // g₋₁ for SBDF(2): its start step (IMEX Euler) evaluates g₀ too
  have_g0_ = false;
  h_prev_ = h;
  if (event_step_) ++events_;
  event_step_ = false;
  t_ += h;
  return true;
}

// Symplectic (semi-implicit) Euler: v₁ = v₀ + h M⁻¹ f(t₀, x₀, v₀),
// x₁ = x₀ + h v₁ — the explicit baseline of the stability maps. Stable only
// while h ω_max < 2 (its CFL limit, numerical stiffness·λ_max < 4).
StepStats StepEngine::ExplicitStep(double h, StepStats st) {
  sys_.Forces(t_, x0_, v0_, &g_);
  v1_ = v0_ + h * (sys_.masses().cwiseInverse().asDiagonal() * g_);
  filter_.Impose(&v1_);
  x1_ = x0_ + h * v1_;
  if (sys_.has_prescribed_motion()) HoldFixed(sys_, t_ + h, x0_, &x1_, &v1_);
  if (!Commit(h)) st.status = StepStatus::kNonFinite;
  return st;
}

}  // namespace clothbench
