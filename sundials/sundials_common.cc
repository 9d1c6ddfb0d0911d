#include "model/interrupt.h"
#include "sundials/sundials_common.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <chrono>
#include <cstdlib>
#include <limits>
#include <optional>

#include <fmt/format.h>

#include <sunmatrix/sunmatrix_sparse.h>

#include "collision/cloth_mesh.h"
#include "solver/progress.h"
#include "solver/run.h"
#include "solver/thread_budget.h"

namespace clothbench::internal {
namespace {
// A SUNDIALS return flag's name as the run's status (ParseRunStatus maps
// error-test, convergence and work-limit failures; the rest is kSolverFailed).
RunStatus StatusOfFlag(const std::string& name) { return ParseRunStatus(name).value_or(RunStatus::kSolverFailed); }

// Self-contact under a SUNDIALS integrator: the response of the fixed-step
// methods (collision/self_contact_response.h) corrects each internal
// step's end, from the step's start, and a corrected state restarts the
// integrator, as an event does.
class SundialsSelfContact {
 public:
  explicit SundialsSelfContact(const ParticleSystem& system)
      : x_start_(system.rest_positions()), h_scene_(system.scene().h) {
    const auto& collision = system.scene().collision;
    if (collision && collision->self) response_.emplace(system, collision->thickness);
  }
  /// Whether the response corrects the steps (the scene's self = true).
  bool corrects() const { return response_.has_value(); }
  /// W_contact of the response since t = 0 [J] for the guard.
  double work() const { return response_ ? response_->stats().work : 0.0; }
  /// Corrects the internal step of size h ending at t, whose end state
  /// (x, v) it changes in place, and restarts the integrator from a changed
  /// state; the flag of the restart (0 if none, or without the response).
  /// The response's Δt is max(h, the scene's h): its position corrections
  /// are those of the step's path, and a step that a restart made small
  /// does not turn them into large velocities (a repulsion changes the
  /// velocity by 0.1 (thickness − distance)/Δt).
  int CorrectStep(const OneStepDriver& d, double t, double h, MatrixN3* x, MatrixN3* v) {
    if (!response_) return 0;
    // The response changes the state exactly when one of its stages acts.
    const auto acted = [this] {
      const SelfContactStats& s = response_->stats();
      return s.repulsions + s.collisions + s.zone_passes;
    };
    const long before = acted();
    response_->Respond(std::max(h, h_scene_), x_start_, x, v);
    int f = 0;
    if (acted() != before) {
      f = d.restart(t, *x, *v);  // with the obstacle contact made consistent (HybridContact::AfterCorrection)
      if (f >= 0) d.current_state(x, v);
    }
    x_start_ = *x;
    return f;
  }
  /// Its counters, or nullptr without the response.
  const SelfContactStats* stats() const { return response_ ? &response_->stats() : nullptr; }

 private:
  std::optional<SelfContactResponse> response_;
  MatrixN3 x_start_;  // the next internal step's start
  double h_scene_;
};

// A SUNDIALS integrator as a stepper of the run loop (solver/run.h,
// RunStepper): each Step is one internal step (to the next frame at the
// latest, with self-contact), the frames inside it come from the dense
// output, and EndStep applies an event's jump, then the self-contact
// response's, each restarting the integrator.
class SundialsStepper final : public Stepper, public InternalSteps {
 public:
  SundialsStepper(const OneStepDriver& d, const ParticleSystem& system, const ReferenceOptions& options,
                  const std::string& error)
      : d_(d), sys_(system), error_(error), frames_(FrameTimes(options.t_end, options.frame_dt)),
        self_contact_(system),
        breaks_(d.on_event && std::any_of(system.obstacles().begin(), system.obstacles().end(),
                                          [](const Obstacle& o) { return o.moving(); })) {}

  // Stepper: the state the integrator holds (set up at rest by its driver).
  void Reset(double t, const MatrixN3& x, const MatrixN3& v) override {
    t_ = t;
    x_ = x;
    v_ = v;
  }
  StepStats Step(double) override;
  double t() const override { return t_; }
  void SetTime(double t) override { t_ = t; }
  const MatrixN3& x() const override { return x_; }
  const MatrixN3& v() const override { return v_; }
  bool single_update() const override { return false; }
  int matrix_rebuilds() const override { return -1; }  // not counted
  double setup_seconds() const override { return 0.0; }  // the driver's (FinishRun)
  const SelfContactStats* own_self_contact() const override { return self_contact_.stats(); }
  InternalSteps* internal_steps() override { return this; }

  // InternalSteps.
  bool stops_at_frames() const override { return self_contact_.corrects(); }
  bool StateAt(double t, MatrixN3* x, MatrixN3* v, RunStatus* status, std::string* message) override {
    const int f = d_.state_at(t, x, v);
    return f >= 0 || Fail(f, "dense output failed with ", status, message);
  }
  bool EndStep(RunStatus* status, std::string* message) override;
  void Failure(RunStatus* status, std::string* message) const override {
    Fail(flag_, "step failed with ", status, message);
  }
  double counted_contact_work() const override { return self_contact_.work(); }

 private:
  // False, with the status of `flag` and the handler's message (else `what` and the flag's name).
  bool Fail(int flag, const char* what, RunStatus* status, std::string* message) const {
    *status = StatusOfFlag(d_.flag_name(flag));
    *message = error_.empty() ? what + d_.flag_name(flag) : error_;
    return false;
  }
  // The first break of a moving obstacle's motion after t (+∞ if none).
  double NextBreak(double t) const {
    double next = std::numeric_limits<double>::infinity();
    for (const Obstacle& o : sys_.obstacles()) next = std::min(next, o.NextBreak(t));
    return next;
  }
  const OneStepDriver& d_;
  const ParticleSystem& sys_;
  const std::string& error_;  // the SUNDIALS error handler's message
  std::vector<double> frames_;
  std::size_t next_frame_ = 1;  // the first frame after t_
  SundialsSelfContact self_contact_;
  const bool breaks_;  // stop at the breaks of moving obstacles (with contact)
  double break_ = std::numeric_limits<double>::infinity();  // the next break, a stop time
  double t_ = 0.0, h_ = 0.0;
  int flag_ = 0;  // the last step's
  MatrixN3 x_, v_;
};

StepStats SundialsStepper::Step(double) {
  StepStats st;
  st.updates = st.cg_iterations = st.colliding = -1;  // not counted per step
  while (next_frame_ < frames_.size() && frames_[next_frame_] <= t_ + 1e-12) ++next_frame_;
  const auto start = std::chrono::steady_clock::now();
  // With self-contact every frame is a stop time: a stored frame is a
  // corrected state, not the uncorrected step's interpolant. So is every
  // break of a moving obstacle's motion (HybridContact's "Breaks").
  double stop = self_contact_.corrects() ? frames_[std::min(next_frame_, frames_.size() - 1)]
                                         : std::numeric_limits<double>::infinity();
  break_ = breaks_ ? NextBreak(t_) : std::numeric_limits<double>::infinity();
  if (break_ < std::min(stop, frames_.back())) stop = break_;
  flag_ = stop < std::numeric_limits<double>::infinity() ? d_.stop_at(stop) : 0;
  if (flag_ >= 0) flag_ = d_.step(&t_);
  st.solve_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (flag_ < 0) {
    // Past the deadline our PCG stopped the step: a time limit, not a failure.
    st.status = DeadlinePassed() ? StepStatus::kTimeLimit : StepStatus::kNoNewtonConvergence;
    return st;
  }
  int q = 0;
  d_.last_step(&h_, &q);
  st.t = t_;
  st.h = h_;
  st.error_order = q;
  d_.current_state(&x_, &v_);  // every internal step's state against the guard (no contact response)
  return st;
}

bool SundialsStepper::EndStep(RunStatus* status, std::string* message) {
  const bool root = flag_ == 2 && d_.on_event;
  const bool at_break = breaks_ && t_ >= break_;  // stopped there (the stop time is returned exactly)
  const bool event = root || at_break;
  int f = event ? d_.on_event(t_, root, at_break) : 0;
  if (f >= 0 && (event || self_contact_.corrects())) {
    d_.current_state(&x_, &v_);  // the step's end, after the event's jump
    f = self_contact_.CorrectStep(d_, t_, h_, &x_, &v_);
  }
  return f >= 0 || Fail(f, "restart after an event failed with ", status, message);
}
}  // namespace

void RunFrames(const OneStepDriver& d, const ParticleSystem& system, const ReferenceOptions& options,
               const std::string& error, RunSummary* res) {
  SundialsStepper stepper(d, system, options, error);
  RunOptions run;
  run.h = options.t_end;  // the integrator chooses its steps
  run.t_end = options.t_end;
  run.frame_dt = options.frame_dt;
  run.limits = options.limits;
  RunStepper(system, stepper, run, res);
}

bool RefusesPrescribedMotion(const ParticleSystem& system, RunSummary* res) {
  if (!system.has_prescribed_motion()) return false;
  res->status = RunStatus::kUnsupportedScene;
  res->message = "constraints.motion: the SUNDIALS rows hold fixed particles at rest (docs/guide/scenes.md, "
                 "\"Moving fixed particles\")";
  return true;
}

void NameSundialsRun(const char* integrator, const char* layer, const ReferenceOptions& options, RunSummary* res) {
  res->integrator = integrator;
  res->label = integrator;
  res->layer = layer;
  res->step_kind = StepKind::kAdaptive;
  res->rtol = options.rtol;
  res->atol = options.AbsoluteTolerance();
  res->step_control = "sundials";
}

void FinishRun(const SundialsStats& counters, const ReducedTangent* tangent, const std::vector<double>* events,
               double setup_s, std::chrono::steady_clock::time_point wall_start, RunSummary* res) {
  SundialsStats& st = res->sundials.emplace(counters);
  if (tangent) {
    st.nli = tangent->total_iterations();
    st.nje = tangent->jacobian_evaluations();
  }
  if (events) res->events = static_cast<long>(events->size());
  res->setup_time_s = setup_s;
  SummariseCounters(res);
  res->wall_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
}

void SummariseCounters(RunSummary* res) {
  const SundialsStats& s = *res->sundials;
  res->steps = static_cast<int>(s.nst);
  res->updates = s.nni;
  res->cg_iterations = s.nli;
  res->rejected = static_cast<int>(s.netf);
  res->error_test_failures = static_cast<int>(s.netf);
}

FreeDofMap::FreeDofMap(const ParticleSystem& system) : sys_(system) {
  free_index_.assign(static_cast<std::size_t>(system.num_particles()), -1);
  for (int p = 0; p < system.num_particles(); ++p)
    if (!system.is_fixed(p)) {
      free_index_[static_cast<std::size_t>(p)] = static_cast<int>(free_.size());
      free_.push_back(p);
    }
}

void FreeDofMap::ToY(const MatrixN3& x, const MatrixN3& v, double* y) const {
  const int nf = num_free();
  for (int k = 0; k < nf; ++k)
    for (int c = 0; c < 3; ++c) {
      y[3 * k + c] = x(particle(k), c);
      y[3 * nf + 3 * k + c] = v(particle(k), c);
    }
}

void FreeDofMap::PositionsFromY(const double* y, MatrixN3* x) const {
  *x = sys_.rest_positions();
  for (int k = 0; k < num_free(); ++k)
    for (int c = 0; c < 3; ++c) (*x)(particle(k), c) = y[3 * k + c];
}

void FreeDofMap::SplitY(const double* y, MatrixN3* x, MatrixN3* v) const {
  const int nf = num_free();
  x->setZero();
  v->setZero();
  for (int k = 0; k < nf; ++k)
    for (int c = 0; c < 3; ++c) {
      (*x)(particle(k), c) = y[3 * k + c];
      (*v)(particle(k), c) = y[3 * nf + 3 * k + c];
    }
}

void FreeDofMap::VelocitiesFromY(const double* y, MatrixN3* v) const {
  const int nf = num_free();
  v->setZero(sys_.num_particles(), 3);
  for (int k = 0; k < nf; ++k)
    for (int c = 0; c < 3; ++c) (*v)(particle(k), c) = y[3 * nf + 3 * k + c];
}

void AddCounters(void* mem, const CounterGetters& get, SundialsStats* st) {
  const std::pair<long*, CounterGetter> pairs[] = {{&st->nst, get.nst},   {&st->nfe, get.nfe},   {&st->nni, get.nni},
                                                   {&st->nli, get.nli},   {&st->netf, get.netf}, {&st->ncfn, get.ncfn},
                                                   {&st->nje, get.nje},   {&st->nsetups, get.nsetups}};
  for (const auto& [total, getter] : pairs) {
    long v = 0;
    if (getter(mem, &v) >= 0) *total = std::max(*total, 0L) + v;
  }
}

void StoreErrorMessage(int code, const char* module, const char* function, char* msg, void* error_string) {
  *static_cast<std::string*>(error_string) = fmt::format("{} {} (flag {}): {}", module, function, code, msg);
}

bool CheckFlag(int flag, const char* call, char* (*flag_name)(long int), const std::string& error,
               RunSummary* res) {
  if (flag < 0 && res->message.empty()) {
    res->status = StatusOfFlag(flag_name(flag));
    res->message = error.empty() ? fmt::format("{} failed with {}", call, flag_name(flag)) : error;
  }
  return flag >= 0;
}

namespace {

struct CustomContent {
  CustomSolverHooks hooks;
  void* p_data = nullptr;
  SUNPSetupFn p_setup = nullptr;
  N_Vector weights = nullptr;  // the package's (not owned)
  N_Vector resid = nullptr;    // owned; zero (IDALS asks for it; read only after 0 iterations, which CustomNumIters never reports)
  int last_flag = 0;
};
CustomContent* Content(SUNLinearSolver s) { return static_cast<CustomContent*>(s->content); }

SUNLinearSolver_Type CustomType(SUNLinearSolver) { return SUNLINEARSOLVER_ITERATIVE; }
SUNLinearSolver_ID CustomId(SUNLinearSolver) { return SUNLINEARSOLVER_CUSTOM; }
int CustomSetATimes(SUNLinearSolver, void*, SUNATimesFn) { return SUNLS_SUCCESS; }
int CustomSetPreconditioner(SUNLinearSolver s, void* p_data, SUNPSetupFn p_setup, SUNPSolveFn) {
  Content(s)->p_data = p_data;
  Content(s)->p_setup = p_setup;
  return SUNLS_SUCCESS;
}
int CustomSetScalingVectors(SUNLinearSolver s, N_Vector s1, N_Vector) {
  Content(s)->weights = s1;
  return SUNLS_SUCCESS;
}
int CustomInitialize(SUNLinearSolver) { return SUNLS_SUCCESS; }
// Past the run's deadline (or after a signal) no setup starts: a
// factorisation cannot be stopped once begun (KLU, CHOLMOD). The
// unrecoverable failure ends the step, and the run loop records time_limit.
int CustomSetup(SUNLinearSolver s, SUNMatrix) {
  CustomContent* c = Content(s);
  if (DeadlinePassed()) return c->last_flag = SUNLS_PSET_FAIL_UNREC;
  const int flag = c->p_setup ? c->p_setup(c->p_data) : 0;
  return c->last_flag = flag == 0 ? SUNLS_SUCCESS : SUNLS_PSET_FAIL_REC;
}
int CustomSolve(SUNLinearSolver s, SUNMatrix, N_Vector x, N_Vector b, realtype tol) {
  CustomContent* c = Content(s);
  return c->last_flag = c->hooks.solve(N_VGetArrayPointer(b), N_VGetArrayPointer(x),
                                       c->weights ? N_VGetArrayPointer(c->weights) : nullptr, tol);
}
// At least 1: IDALS and CVLS take SUNLinSolResid as the solution of an
// iterative solve that reports 0 iterations (a Krylov solver's zero initial
// guess), but the reduced solve returns its solution in x whatever the PCG
// did; its x rows are solved exactly even when the PCG needed none (a cloth
// in free fall: the reduced right-hand side is 0). With 0 reported, IDA's
// position corrections were dropped and a cloth without fixed particles
// never moved. The rows' own counters come from the PCG, not from here.
int CustomNumIters(SUNLinearSolver s) { return std::max(1, Content(s)->hooks.iterations()); }
realtype CustomResNorm(SUNLinearSolver s) { return Content(s)->hooks.residual(); }
sunindextype CustomLastFlag(SUNLinearSolver s) { return Content(s)->last_flag; }
N_Vector CustomResid(SUNLinearSolver s) { return Content(s)->resid; }
int CustomFree(SUNLinearSolver s) {
  if (!s) return SUNLS_SUCCESS;
  if (Content(s)->resid) N_VDestroy(Content(s)->resid);
  delete Content(s);
  s->content = nullptr;
  SUNLinSolFreeEmpty(s);
  return SUNLS_SUCCESS;
}

struct TimedContent {
  SUNLinearSolver inner = nullptr;
  double* seconds = nullptr;
};
TimedContent* Timed(SUNLinearSolver s) { return static_cast<TimedContent*>(s->content); }
SUNLinearSolver_Type TimedType(SUNLinearSolver s) { return SUNLinSolGetType(Timed(s)->inner); }
SUNLinearSolver_ID TimedId(SUNLinearSolver s) { return SUNLinSolGetID(Timed(s)->inner); }
int TimedInitialize(SUNLinearSolver s) { return SUNLinSolInitialize(Timed(s)->inner); }
int TimedSetup(SUNLinearSolver s, SUNMatrix a) {
  if (DeadlinePassed()) return SUNLS_PACKAGE_FAIL_UNREC;  // as CustomSetup
  const auto start = std::chrono::steady_clock::now();
  const int flag = SUNLinSolSetup(Timed(s)->inner, a);
  *Timed(s)->seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return flag;
}
int TimedSolve(SUNLinearSolver s, SUNMatrix a, N_Vector x, N_Vector b, realtype tol) {
  return SUNLinSolSolve(Timed(s)->inner, a, x, b, tol);
}
sunindextype TimedLastFlag(SUNLinearSolver s) { return SUNLinSolLastFlag(Timed(s)->inner); }
int TimedFree(SUNLinearSolver s) {
  if (!s) return SUNLS_SUCCESS;
  SUNLinSolFree(Timed(s)->inner);
  delete Timed(s);
  s->content = nullptr;
  SUNLinSolFreeEmpty(s);
  return SUNLS_SUCCESS;
}

}  // namespace

ReducedTangent::ReducedTangent(const ParticleSystem& sys, const SolverSpec& spec)
    : tangent_(sys, TangentOptions{spec.tangent_projection, spec.tangent_explicit_terms, true}),
      pre_(spec.preconditioner) {
  const auto start = std::chrono::steady_clock::now();
  if (UsesAlphaPreconditioner(spec.preconditioner))
    laplacian_ = std::make_unique<SystemMatrix>(sys, spec.preconditioner, spec.cholesky_ordering);
  pre_.Analyze(tangent_.matrix(), laplacian_ ? &laplacian_->preconditioner() : nullptr);
  filter_.Reserve(sys.num_particles());
  for (int p : sys.fixed()) filter_.Fix(p);
  work_.Resize(sys.num_particles());
  setup_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

int ReducedTangent::Setup(double t, const MatrixN3& x, const MatrixN3& v, double gamma, bool evaluate) {
  const auto start = std::chrono::steady_clock::now();
  if (evaluate || jacobian_evaluations_ == 0) {
    tangent_.Update(t, x, v, gamma);
    ++jacobian_evaluations_;
  } else {
    tangent_.SetAlphaH(gamma);
  }
  bool ok = !laplacian_ || laplacian_->Update(gamma);
  ok = ok && pre_.Factorize(tangent_.matrix());
  setup_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return ok ? 0 : 1;
}

PcgStatus ReducedTangent::Solve(double gamma, const MatrixN3R& b, const PcgOptions& options, MatrixN3R* dv,
                                const VelocityFilter& filter, const Eigen::VectorXd& rate) {
  tangent_.SetAlphaH(gamma);  // drops the last solve's rates
  tangent_.AddToDiagonal(gamma * rate);
  dv->setZero();
  const PcgSummary s = FilteredPcg(tangent_.matrix(), b, filter, pre_, options, dv, &work_);
  tangent_.SetAlphaH(gamma);
  last_iterations_ = s.iterations;
  total_iterations_ += s.iterations;
  last_residual_ = s.residual_norm;
  return s.status;
}

PcgStatus ReducedTangent::Solve(double gamma, const MatrixN3R& b, const PcgOptions& options, MatrixN3R* dv) {
  if (gamma != tangent_.alpha_h()) tangent_.SetAlphaH(gamma);
  dv->setZero();
  const PcgSummary s = FilteredPcg(tangent_.matrix(), b, filter_, pre_, options, dv, &work_);
  last_iterations_ = s.iterations;
  total_iterations_ += s.iterations;
  last_residual_ = s.residual_norm;
  return s.status;
}

double ReducedTangent::setup_seconds() const {
  return setup_seconds_ + (laplacian_ ? laplacian_->setup_seconds() : 0.0);
}

SUNLinearSolver NewTimedLinearSolver(SUNContext ctx, SUNLinearSolver inner, double* seconds) {
  SUNLinearSolver s = inner ? SUNLinSolNewEmpty(ctx) : nullptr;
  if (!s) {
    if (inner) SUNLinSolFree(inner);
    return nullptr;
  }
  s->ops->gettype = TimedType;
  s->ops->getid = TimedId;
  s->ops->initialize = TimedInitialize;
  s->ops->setup = TimedSetup;
  s->ops->solve = TimedSolve;
  s->ops->lastflag = TimedLastFlag;
  s->ops->free = TimedFree;
  s->content = new TimedContent{inner, seconds};
  return s;
}

SUNLinearSolver NewCustomLinearSolver(SUNContext ctx, CustomSolverHooks hooks, N_Vector like) {
  SUNLinearSolver s = SUNLinSolNewEmpty(ctx);
  if (!s) return nullptr;
  s->ops->gettype = CustomType;
  s->ops->getid = CustomId;
  s->ops->setatimes = CustomSetATimes;
  s->ops->setpreconditioner = CustomSetPreconditioner;
  s->ops->setscalingvectors = CustomSetScalingVectors;
  s->ops->initialize = CustomInitialize;
  s->ops->setup = CustomSetup;
  s->ops->solve = CustomSolve;
  s->ops->numiters = CustomNumIters;
  s->ops->resnorm = CustomResNorm;
  s->ops->lastflag = CustomLastFlag;
  s->ops->free = CustomFree;
  s->content = new CustomContent{std::move(hooks)};
  if (like) {
    Content(s)->resid = N_VClone(like);
    N_VConst(0.0, Content(s)->resid);
    s->ops->resid = CustomResid;
  }
  return s;
}

PcgOptions PcgStopForTolerance(const FreeDofMap& map, const Eigen::VectorXd& masses, const double* w, double tol,
                               const PcgOptions& fallback) {
  if (!w) return fallback;
  const int nf = map.num_free();
  double wmax = 0.0;
  for (int k = 0; k < nf; ++k)
    for (int c = 0; c < 3; ++c) wmax = std::max(wmax, w[3 * nf + 3 * k + c] / masses(map.particle(k)));
  return PcgStopForTolerance(wmax, tol, fallback);
}

PcgOptions PcgStopForTolerance(double max_scaled_weight, double tol, const PcgOptions& fallback) {
  if (!(tol > 0.0) || !(max_scaled_weight > 0.0) || !std::isfinite(max_scaled_weight)) return fallback;
  PcgOptions o = fallback;
  o.tolerance = 1.0;
  o.rhs_norm = tol / max_scaled_weight;
  return o;
}

int CopyToSunSparse(const SparseMatrix& j, void* sun_matrix) {
  auto m = static_cast<SUNMatrix>(sun_matrix);
  if (SUNSparseMatrix_NNZ(m) < j.nonZeros() && SUNSparseMatrix_Reallocate(m, j.nonZeros()) != 0) return -1;
  sunindextype* colptr = SUNSparseMatrix_IndexPointers(m);
  sunindextype* rowval = SUNSparseMatrix_IndexValues(m);
  realtype* data = SUNSparseMatrix_Data(m);
  for (Eigen::Index c = 0; c <= j.outerSize(); ++c) colptr[c] = j.outerIndexPtr()[c];
  for (Eigen::Index k = 0; k < j.nonZeros(); ++k) {
    rowval[k] = j.innerIndexPtr()[k];
    data[k] = j.valuePtr()[k];
  }
  return 0;
}

}  // namespace clothbench::internal
