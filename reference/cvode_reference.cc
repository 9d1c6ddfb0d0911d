// CVODE reference (docs/model.md §8).
#include "reference/cvode_reference.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include <cvode/cvode.h>
#include <fmt/format.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_klu.h>
#include <sunmatrix/sunmatrix_sparse.h>

#include "solver/integrator.h"
#include "sundials/hybrid_contact.h"
#include "solver/pcg.h"
#include "solver/tangent.h"

namespace clothbench {
namespace {

// The ODE on the free DOFs y = [x_free; v_free] (internal::FreeDofMap): the
// right-hand side and the sparse Jacobian; on scenes with obstacles the
// current contact mode's ODE (internal::HybridContact), its root functions
// and its events.
class FreeDofOde {
 public:
  /// @param entry_depth the contact events' hysteresis [m] (internal::HybridContact)
  FreeDofOde(const ParticleSystem& sys, double entry_depth)
      : sys_(sys), map_(sys), n_(sys.num_particles()), nf_(map_.num_free()), contact_(sys, entry_depth) {
    internal::StartVirtualParticles(sys);
    x_ = sys.rest_positions();
    v_.setZero(n_, 3);
    f_.setZero(n_, 3);
  }
  internal::HybridContact& contact() { return contact_; }

  /// The root functions at (t, y): one per particle (HybridContact::Roots).
  void Roots(double t, const double* y, double* g) {
    Unpack(y);
    sys_.Forces(t, x_, v_, &f_);
    contact_.Roots(t, x_, v_, f_, g);
  }
  /// The events at a root or break t on the state y (changed in place;
  /// HybridContact::ApplyEvents); returns the mode changes.
  int ApplyEvents(double t, const int* found, bool at_break, double* y) {
    Unpack(y);
    const int changes = contact_.ApplyEvents(
        t, found, at_break, &x_, &v_, [&](double s, const MatrixN3& x, const MatrixN3& v, MatrixN3* f) { sys_.Forces(s, x, v, f); });
    map_.ToY(x_, v_, y);
    return changes;
  }
  /// y from (x, v) (N×3 [m], [m/s]) as a self-contact correction left
  /// them at t (HybridContact::AfterCorrection).
  void SetCorrected(double t, const MatrixN3& x, const MatrixN3& v, double* y) {
    x_ = x;
    v_ = v;
    contact_.AfterCorrection(t, &x_, &v_);
    map_.ToY(x_, v_, y);
  }
  const internal::FreeDofMap& map() const { return map_; }
  int size() const { return map_.size(); }
  /// Wall time of the Jacobian evaluations so far [s].
  double jacobian_seconds() const { return jacobian_seconds_; }
  void Unpack(const double* y) {
    map_.PositionsFromY(y, &x_);
    map_.VelocitiesFromY(y, &v_);
  }

  void Rhs(double t, const double* y, double* ydot) {
    Unpack(y);
    sys_.Forces(t, x_, v_, &f_);
    if (contact_.active()) contact_.AddContactForces(t, x_, v_, &f_);
    const Eigen::VectorXd& m = sys_.masses();
    for (int k = 0; k < nf_; ++k) {
      const int p = map_.particle(k);
      for (int c = 0; c < 3; ++c) {
        ydot[3 * k + c] = y[3 * nf_ + 3 * k + c];
        ydot[3 * nf_ + 3 * k + c] = f_(p, c) / m(p);
      }
    }
  }

  // J = [[0, I], [M⁻¹ ∂f/∂x, M⁻¹ ∂f/∂v]] on the free DOFs, compressed
  // column storage with a state-independent pattern.
  const SparseMatrix& Jacobian(double t, const double* y) {
    struct Timer {  // adds the evaluation's wall time on every return
      std::chrono::steady_clock::time_point start;
      double* total;
      ~Timer() { *total += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); }
    } timer{std::chrono::steady_clock::now(), &jacobian_seconds_};
    Unpack(y);
    dfdx_.clear();
    dfdv_.clear();
    sys_.ForceJacobian(t, x_, v_, &dfdx_, &dfdv_);
    jt_.clear();
    const int off = 3 * nf_;
    for (int i = 0; i < off; ++i) jt_.emplace_back(i, off + i, 1.0);
    // Explicit zero diagonal: without it SUNMatScaleAddI_Sparse (I − γJ)
    // rebuilds the matrix at every setup (measured: 56% of CVODE's time).
    for (int i = 0; i < 2 * off; ++i) jt_.emplace_back(i, i, 0.0);
    // A sliding particle's rows: S_p M⁻¹ ∂f/∂(x, v) (S_p = I − n nᵀ: the
    // constraint force takes the normal component) and its friction's
    // −rate/m S_p on the velocity block. Its 3×3 blocks are dense, so the
    // pattern does not change.
    sliding_.assign(static_cast<std::size_t>(n_), -1);
    normals_.clear();
    contact_.ForEachSliding([&](int p, const Vector3& n) {
      sliding_[static_cast<std::size_t>(p)] = static_cast<int>(normals_.size());
      normals_.push_back(Matrix3::Identity() - n * n.transpose());
    });
    auto map = [&](const std::vector<Triplet>& src, int col_off) {
      for (const Triplet& e : src) {
        const int pr = map_.free_index(e.row() / 3);
        const int pc = map_.free_index(e.col() / 3);
        if (pr < 0 || pc < 0) continue;
        const double value = e.value() / sys_.masses()(e.row() / 3);
        const int s = sliding_[static_cast<std::size_t>(e.row() / 3)];
        if (s < 0) {
          jt_.emplace_back(off + 3 * pr + e.row() % 3, col_off + 3 * pc + e.col() % 3, value);
        } else {
          const Matrix3& proj = normals_[static_cast<std::size_t>(s)];
          for (int c = 0; c < 3; ++c)
            jt_.emplace_back(off + 3 * pr + c, col_off + 3 * pc + e.col() % 3, proj(c, e.row() % 3) * value);
        }
      }
    };
    map(dfdx_, 0);
    map(dfdv_, off);
    for (int p = 0; p < n_; ++p) {
      const int s = sliding_[static_cast<std::size_t>(p)];
      const int k = map_.free_index(p);
      if (s < 0 || k < 0) continue;
      const double rate = contact_.friction_rates()(p) / sys_.masses()(p);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
          jt_.emplace_back(off + 3 * k + r, off + 3 * k + c, -rate * normals_[static_cast<std::size_t>(s)](r, c));
    }
    jac_.resize(size(), size());
    jac_.setFromTriplets(jt_.begin(), jt_.end());
    jac_.makeCompressed();
    return jac_;
  }

 private:
  const ParticleSystem& sys_;
  internal::FreeDofMap map_;
  int n_, nf_;
  MatrixN3 x_, v_, f_;
  std::vector<Triplet> dfdx_, dfdv_, jt_;
  SparseMatrix jac_;
  double jacobian_seconds_ = 0.0;
  internal::HybridContact contact_;
  std::vector<int> sliding_;        // per particle: index in normals_, −1: free
  std::vector<Matrix3> normals_;    // sliding particles' tangential projections S_p
};

// CVODE's user data: the ODE, and the reduced solve of row `cvode`.
struct CvodeUser {
  FreeDofOde* ode = nullptr;
  class ReducedNewtonSolve* reduced = nullptr;
  void* mem = nullptr;  // CVODE's
};

int RhsFn(realtype t, N_Vector y, N_Vector ydot, void* user) {
  static_cast<CvodeUser*>(user)->ode->Rhs(t, N_VGetArrayPointer(y), N_VGetArrayPointer(ydot));
  return 0;
}

int RootFn(realtype t, N_Vector y, realtype* g, void* user) {
  const auto* u = static_cast<CvodeUser*>(user);
  u->ode->contact().set_step_horizon(u->mem, {CVodeGetNumSteps, CVodeGetLastStep, CVodeGetCurrentTime}, t);
  u->ode->Roots(t, N_VGetArrayPointer(y), g);
  return 0;
}

int JacFn(realtype t, N_Vector y, N_Vector, SUNMatrix jac, void* user, N_Vector, N_Vector, N_Vector) {
  return internal::CopyToSunSparse(static_cast<CvodeUser*>(user)->ode->Jacobian(t, N_VGetArrayPointer(y)), jac);
}

// The reduced Newton solve of CVODE on the free DOFs (docs/model.md,
// "CVODE's reduced solve"): with y = [x; v] and J = [[0, I], [M⁻¹K, M⁻¹D]]
// (K = ∂f/∂x, D = ∂f/∂v), (I − γJ) [δx; δv] = [r_x; r_v] is
// δx = r_x + γ δv and (M − γD − γ²K) δv = M r_v + γ K r_x, the tangent
// system J_α of solver/tangent.h at αh = γ.
class ReducedNewtonSolve {
 public:
  ReducedNewtonSolve(const ParticleSystem& sys, const SolverSpec& spec, internal::HybridContact* contact)
      : sys_(sys), spec_(spec), map_(sys), nf_(map_.num_free()), tangent_(sys, spec), contact_(contact) {
    for (MatrixN3* m : {&x_, &v_, &rx_, &rv_, &rhs_}) m->setZero(sys.num_particles(), 3);
    dv_.setZero(sys.num_particles(), 3);
    br_.setZero(sys.num_particles(), 3);
    if (contact_ && contact_->active()) filter_.Reserve(sys.num_particles());
  }

  // CVODE's setup (psetup): the Jacobian at (t, y) unless jok, J_γ, and the
  // preconditioner of J_γ. Returns 0, or 1 (recoverable) if the
  // preconditioner could not be built.
  int Setup(double t, const double* y, bool jok, int* jcur, double gamma) {
    if (!jok || tangent_.jacobian_evaluations() == 0) {  // the first setup evaluates whatever jok says
      map_.PositionsFromY(y, &x_);
      map_.VelocitiesFromY(y, &v_);
    }
    const long before = tangent_.jacobian_evaluations();
    const int flag = tangent_.Setup(t, x_, v_, gamma, !jok);
    *jcur = tangent_.jacobian_evaluations() > before ? 1 : 0;
    return flag;
  }

  // δ = (I − γJ)⁻¹ r through the reduced system; the matrix follows γ, the
  // preconditioner is the last setup's. The PCG stops at CVLS's tolerance
  // tol on ‖w ∘ residual‖₂ (internal::PcgStopForTolerance).
  PcgStatus Solve(double gamma, const double* r, double* delta, const double* w, double tol) {
    map_.SplitY(r, &rx_, &rv_);
    rhs_.noalias() = sys_.masses().asDiagonal() * rv_;
    tangent_.AddJacobianProducts(gamma, rx_, 0.0, rx_, &rhs_);
    br_ = rhs_;
    const PcgOptions stop =
        internal::PcgStopForTolerance(map_, sys_.masses(), w, tol, {spec_.cg_tolerance, spec_.cg_max_iterations});
    PcgStatus status;
    if (contact_ && contact_->active()) {
      // A sliding particle's normal row is δv_n = n·r_v (its acceleration's
      // normal part is the constraint's, not a function of the unknowns);
      // its tangential rows carry the friction rate.
      filter_.Clear();
      for (int p : sys_.fixed()) filter_.Fix(p);
      contact_->ForEachSliding([&](int p, const Vector3& n) { filter_.Constrain(p, n, n.dot(rv_.row(p).transpose())); });
      status = tangent_.Solve(gamma, br_, stop, &dv_, filter_, contact_->friction_rates());
    } else {
      status = tangent_.Solve(gamma, br_, stop, &dv_);
    }
    for (int k = 0; k < nf_; ++k)
      for (int c = 0; c < 3; ++c) {
        const double d = dv_(map_.particle(k), c);
        delta[3 * nf_ + 3 * k + c] = d;
        delta[3 * k + c] = r[3 * k + c] + gamma * d;
      }
    return status;
  }
  const internal::ReducedTangent& tangent() const { return tangent_; }
  int last_iterations() const { return tangent_.last_iterations(); }
  double last_residual() const { return tangent_.last_residual(); }

 private:
  const ParticleSystem& sys_;
  const SolverSpec& spec_;
  internal::FreeDofMap map_;
  int nf_;
  internal::ReducedTangent tangent_;
  internal::HybridContact* contact_;
  VelocityFilter filter_;  // with contacts: the fixed particles and the sliding ones' normals
  MatrixN3 x_, v_, rx_, rv_, rhs_;
  MatrixN3R dv_, br_;
};

// CVLS's preconditioner setup: CVODE's jok and γ reach the reduced solve.
int PrecSetup(realtype t, N_Vector y, N_Vector, booleantype jok, booleantype* jcur, realtype gamma, void* user) {
  int cur = 0;
  const int flag =
      static_cast<CvodeUser*>(user)->reduced->Setup(t, N_VGetArrayPointer(y), jok != SUNFALSE, &cur, gamma);
  *jcur = cur ? SUNTRUE : SUNFALSE;
  return flag;
}
// Never called: the solve above does not apply CVLS's preconditioner.
int PrecSolve(realtype, N_Vector, N_Vector, N_Vector r, N_Vector z, realtype, realtype, int, void*) {
  N_VScale(1.0, r, z);
  return 0;
}

// Adds CVODE's counters since its last (re)initialisation to `st`.
void AddCvodeCounters(void* mem, SundialsStats* st) {
  internal::AddCounters(mem,
                        {CVodeGetNumSteps, CVodeGetNumRhsEvals, CVodeGetNumNonlinSolvIters, CVodeGetNumLinIters,
                         CVodeGetNumErrTestFails, CVodeGetNumNonlinSolvConvFails, CVodeGetNumJacEvals,
                         CVodeGetNumLinSolvSetups},
                        st);
}

// The contact modes at t = 0 and one root function per particle, each
// caught as it falls through 0 (sundials/hybrid_contact.h); `found` sized
// for CVodeGetRootInfo.
template <class Check>
bool InitContactRoots(void* mem, const ParticleSystem& system, FreeDofOde* ode, const MatrixN3& v0,
                      std::vector<int>* found, Check check) {
  ode->contact().Initialize(0.0, system.rest_positions(), v0);
  const int nr = ode->contact().num_roots();
  found->assign(static_cast<std::size_t>(nr), 0);
  std::vector<int> direction(static_cast<std::size_t>(nr), -1);
  return check(CVodeRootInit(mem, nr, RootFn), "CVodeRootInit") &&
         check(CVodeSetRootDirection(mem, direction.data()), "CVodeSetRootDirection") &&
         check(CVodeSetNoInactiveRootWarn(mem), "CVodeSetNoInactiveRootWarn");
}

// RAII owner of the SUNDIALS objects.
struct CvodeHandles {
  SUNContext ctx = nullptr;
  N_Vector y = nullptr, dky = nullptr, atol = nullptr;
  SUNMatrix a = nullptr;
  SUNLinearSolver ls = nullptr;
  void* mem = nullptr;
  ~CvodeHandles() {
    if (mem) CVodeFree(&mem);
    if (ls) SUNLinSolFree(ls);
    if (a) SUNMatDestroy(a);
    if (atol) N_VDestroy(atol);
    if (dky) N_VDestroy(dky);
    if (y) N_VDestroy(y);
    if (ctx) SUNContext_Free(&ctx);
  }
};

}  // namespace

namespace {

// rtol and atol; with cs.atol_v_scale ≠ 1 a vector atol, atol on the
// positions and atol_v_scale · atol on the velocities (y = [x_free; v_free]).
template <class Check>
bool SetTolerances(void* mem, N_Vector y, const ReferenceOptions& options, const CvodeSettings& cs, N_Vector* atol,
                   Check check) {
  const double a = options.AbsoluteTolerance();
  if (cs.atol_v_scale == 1.0) return check(CVodeSStolerances(mem, options.rtol, a), "CVodeSStolerances");
  const sunindextype n = N_VGetLength(y);
  *atol = N_VClone(y);
  double* w = N_VGetArrayPointer(*atol);
  for (sunindextype k = 0; k < n; ++k) w[k] = k < n / 2 ? a : cs.atol_v_scale * a;
  return check(CVodeSVtolerances(mem, options.rtol, *atol), "CVodeSVtolerances");
}

// The calls of the run loop's stepper (internal::RunFrames) on CVODE's handles:
// one step, dense output, the state, and the restarts after an event or
// the self-contact response (counters summed into `counters`).
internal::OneStepDriver CvodeDriver(CvodeHandles& h, FreeDofOde& ode, const ReferenceOptions& options,
                                    std::vector<int>& roots_found, SundialsStats& counters) {
  internal::OneStepDriver d;
  d.step = [&](double* t) { return CVode(h.mem, options.t_end, h.y, t, CV_ONE_STEP); };
  d.state_at = [&](double tf, MatrixN3* x, MatrixN3* v) {
    const int f = CVodeGetDky(h.mem, tf, 0, h.dky);
    if (f >= 0) {
      ode.map().PositionsFromY(N_VGetArrayPointer(h.dky), x);
      ode.map().VelocitiesFromY(N_VGetArrayPointer(h.dky), v);
    }
    return f;
  };
  d.current_state = [&](MatrixN3* x, MatrixN3* v) {
    ode.map().PositionsFromY(N_VGetArrayPointer(h.y), x);
    ode.map().VelocitiesFromY(N_VGetArrayPointer(h.y), v);
  };
  d.last_step = [&](double* hl, int* q) {
    CVodeGetLastStep(h.mem, hl);
    CVodeGetLastOrder(h.mem, q);
  };
  d.flag_name = [](int f) { return std::string(CVodeGetReturnFlagName(f)); };
  // A jump of the state at t (an event, the self-contact response): the
  // counters so far are kept and CVODE restarts from h.y at order 1 with
  // the step h_start (0: CVODE's estimate). Copied into the calls below:
  // it ends with this function.
  const auto reinit = [&](double t, double h_start) {
    AddCvodeCounters(h.mem, &counters);
    int f = CVodeSetInitStep(h.mem, h_start);
    if (f >= 0) f = CVodeReInit(h.mem, t, h.y);
    return f < 0 ? f : CVodeSetStopTime(h.mem, options.t_end);
  };
  if (ode.contact().active())
    d.on_event = [&, reinit](double t, bool root, bool at_break) {
      std::fill(roots_found.begin(), roots_found.end(), 0);
      const int f = root ? CVodeGetRootInfo(h.mem, roots_found.data()) : 0;
      if (f < 0) return f;
      ode.ApplyEvents(t, roots_found.data(), at_break, N_VGetArrayPointer(h.y));
      return reinit(t, 0.0);
    };
  d.stop_at = [&](double t_stop) { return CVodeSetStopTime(h.mem, t_stop); };
  // After the self-contact response, from the step CVODE would have taken
  // next (CVodeGetCurrentStep, its error estimate's): a fold at rest is
  // corrected (repelled) at every step, and each restart from CVODE's
  // estimate of a first step took 92,303 steps to t = 0.45 s on
  // fold_over_rod at rtol 1e-3; from the last step's size, which a restart
  // never lets grow, 17,767 steps to 0.47 s, the last ones 6e-8 s.
  d.restart = [&, reinit](double t, const MatrixN3& x, const MatrixN3& v) {
    ode.SetCorrected(t, x, v, N_VGetArrayPointer(h.y));
    double h_next = 0.0;
    CVodeGetCurrentStep(h.mem, &h_next);
    return reinit(t, h_next);
  };
  return d;
}

// CVODE with KLU (reduced == nullptr) or the reduced solve with `reduced`'s
// settings.
RunSummary RunCvodeWith(const ParticleSystem& system, const ReferenceOptions& options, const CvodeSettings& cs,
                        const SolverSpec* reduced) {
  using Clock = std::chrono::steady_clock;
  const auto wall_start = Clock::now();
  RunSummary res;
  internal::NameSundialsRun(kCvodeName, "reference", options, &res);
  if (internal::RefusesPrescribedMotion(system, &res)) return res;
  FreeDofOde ode(system, 1e-2 * options.AbsoluteTolerance());
  std::unique_ptr<ReducedNewtonSolve> solve;
  if (reduced) solve = std::make_unique<ReducedNewtonSolve>(system, *reduced, &ode.contact());
  CvodeUser user{&ode, solve.get()};
  CvodeHandles h;
  double klu_seconds = 0.0;  // KLU setups and Jacobian evaluations (cvode/klu)
  std::string err;

  auto check = [&](int flag, const char* call) {
    return internal::CheckFlag(flag, call, CVodeGetReturnFlagName, err, &res);
  };

  SUNContext_Create(nullptr, &h.ctx);
  const sunindextype n = ode.size();
  h.y = N_VNew_Serial(n, h.ctx);
  h.dky = N_VNew_Serial(n, h.ctx);
  MatrixN3 v0 = MatrixN3::Zero(system.num_particles(), 3);
  ode.map().ToY(system.rest_positions(), v0, N_VGetArrayPointer(h.y));
  h.mem = CVodeCreate(CV_BDF, h.ctx);
  user.mem = h.mem;
  if (solve) {
    // CVLS hands the custom solver its preconditioner-setup wrapper, which
    // calls PrecSetup with CVODE's jok and γ: the Jacobian is re-evaluated
    // exactly when CVODE's heuristics (msbj, dgmax, convergence failures)
    // ask. The PCG stops at CVLS's own tolerance for iterative solvers
    // (eplifac = 0.05 of the Newton test, in CVODE's weighted norm), as
    // with CVODE's Krylov solvers.
    void* mem = h.mem;
    h.ls = internal::NewCustomLinearSolver(
        h.ctx, internal::ReducedSolveHooks(solve.get(), [mem](double* gamma) {
          return CVodeGetCurrentGamma(mem, gamma) == CV_SUCCESS;
        }));
  } else {
    const SparseMatrix& j0 = ode.Jacobian(0.0, N_VGetArrayPointer(h.y));
    h.a = SUNSparseMatrix(n, n, j0.nonZeros(), CSC_MAT, h.ctx);
    SUNLinearSolver klu = SUNLinSol_KLU(h.y, h.a, h.ctx);
    SUNLinSol_KLUSetOrdering(klu, 0);  // AMD: the Jacobian pattern is structurally symmetric
    // KLU's symbolic analysis and factorisations count as setup time, as
    // the PCG rows' factorisations do.
    h.ls = internal::NewTimedLinearSolver(h.ctx, klu, &klu_seconds);
  }
  bool ok = check(CVodeSetErrHandlerFn(h.mem, internal::StoreErrorMessage, &err), "CVodeSetErrHandlerFn") &&
            check(CVodeInit(h.mem, RhsFn, 0.0, h.y), "CVodeInit") &&
            check(CVodeSetUserData(h.mem, &user), "CVodeSetUserData") &&
            SetTolerances(h.mem, h.y, options, cs, &h.atol, check) &&
            check(CVodeSetLinearSolver(h.mem, h.ls, h.a), "CVodeSetLinearSolver") &&
            check(CVodeSetMaxOrd(h.mem, options.max_order), "CVodeSetMaxOrd") &&
            check(CVodeSetStopTime(h.mem, options.t_end), "CVodeSetStopTime") &&
            check(CVodeSetMaxNumSteps(h.mem, 100000000L), "CVodeSetMaxNumSteps");
  // Obstacles: the contact modes at t = 0, one root function per particle
  // (entries as d − δ falls through 0, releases as λ does), and a restart
  // after every event (sundials/hybrid_contact.h).
  std::vector<int> roots_found;
  SundialsStats counters;  // summed over the restarts
  if (ok && ode.contact().active()) ok = InitContactRoots(h.mem, system, &ode, v0, &roots_found, check);
  if (ok && solve)
    ok = check(CVodeSetPreconditioner(h.mem, PrecSetup, PrecSolve), "CVodeSetPreconditioner");
  else if (ok)
    ok = check(CVodeSetJacFn(h.mem, JacFn), "CVodeSetJacFn");
  ok = ok && check(CVodeSetLSetupFrequency(h.mem, cs.lsetup_frequency), "CVodeSetLSetupFrequency") &&
       check(CVodeSetJacEvalFrequency(h.mem, cs.jac_eval_frequency), "CVodeSetJacEvalFrequency") &&
       check(CVodeSetDeltaGammaMaxLSetup(h.mem, cs.dgmax_lsetup), "CVodeSetDeltaGammaMaxLSetup") &&
       check(CVodeSetStabLimDet(h.mem, cs.stab_lim_det ? SUNTRUE : SUNFALSE), "CVodeSetStabLimDet") &&
       (!solve || check(CVodeSetEpsLin(h.mem, cs.eps_lin), "CVodeSetEpsLin"));
  res.SetMethodAttribute("sundials_settings", cs.ToString());  // CVODE's setup knobs ("lsetup_frequency=20,…")
  if (ok) {
    const internal::OneStepDriver d = CvodeDriver(h, ode, options, roots_found, counters);
    internal::RunFrames(d, system, options, err, &res);
  }
  AddCvodeCounters(h.mem, &counters);
  internal::FinishRun(counters, solve ? &solve->tangent() : nullptr,
                      ode.contact().active() ? &ode.contact().event_times() : nullptr,
                      solve ? solve->tangent().setup_seconds() : klu_seconds + ode.jacobian_seconds(), wall_start, &res);
  return res;
}

}  // namespace

std::string CvodeSettings::ToString() const {
  return fmt::format(
      "lsetup_frequency={},jac_eval_frequency={},dgmax_lsetup={:g},stab_lim_det={},eps_lin={:g},atol_v_scale={:g}",
      lsetup_frequency, jac_eval_frequency, dgmax_lsetup, stab_lim_det ? 1 : 0, eps_lin, atol_v_scale);
}

bool CvodeSettings::Set(const std::string& key, const std::string& value, std::string* error) {
  auto fail = [&](const std::string& why) {
    *error = fmt::format("{}={}: {}", key, value, why);
    return false;
  };
  char* end = nullptr;
  const double v = std::strtod(value.c_str(), &end);
  if (value.empty() || *end != '\0' || !std::isfinite(v)) return fail("the value must be a number");
  if (key == "lsetup_frequency" || key == "jac_eval_frequency") {
    if (v < 1 || v > 1e9 || v != std::floor(v)) return fail("must be a whole number from 1 to 1e9");
    (key == "lsetup_frequency" ? lsetup_frequency : jac_eval_frequency) = static_cast<long>(v);
  } else if (key == "dgmax_lsetup" || key == "eps_lin") {
    if (!(v > 0.0) || v > 1e3) return fail("must be in (0, 1e3]");
    (key == "dgmax_lsetup" ? dgmax_lsetup : eps_lin) = v;
  } else if (key == "atol_v_scale") {
    if (!(v >= 1e-6) || v > 1e6) return fail("must be in [1e-6, 1e6]");
    atol_v_scale = v;
  } else if (key == "stab_lim_det") {
    if (v != 0.0 && v != 1.0) return fail("must be 0 or 1");
    stab_lim_det = v == 1.0;
  } else {
    *error = fmt::format("\"{}\" is not one of lsetup_frequency, jac_eval_frequency, dgmax_lsetup, stab_lim_det, "
                         "eps_lin, atol_v_scale",
                         key);
    return false;
  }
  return true;
}

std::string CvodeSettings::Parse(const std::string& text) {
  if (text.empty()) return "";
  std::size_t begin = 0;
  while (true) {
    const std::size_t comma = text.find(',', begin);
    std::string kv = text.substr(begin, comma == std::string::npos ? std::string::npos : comma - begin);
    const auto b = kv.find_first_not_of(" \t"), e = kv.find_last_not_of(" \t");
    if (b == std::string::npos) return fmt::format("empty item in the list \"{}\"", text);
    kv = kv.substr(b, e - b + 1);
    const std::size_t eq = kv.find('=');
    std::string why;
    if (eq == std::string::npos) return fmt::format("\"{}\" is not KEY=VALUE", kv);
    if (!Set(kv.substr(0, eq), kv.substr(eq + 1), &why)) return why;
    if (comma == std::string::npos) return "";
    begin = comma + 1;
  }
}

RunSummary RunCvode(const ParticleSystem& system, const ReferenceOptions& options, const CvodeSettings& settings) {
  return RunCvodeWith(system, options, settings, nullptr);
}

SparseMatrix FirstOrderJacobianAtRest(const ParticleSystem& system) {
  FreeDofOde ode(system, 0.0);
  std::vector<double> y(static_cast<std::size_t>(ode.size()));
  ode.map().ToY(system.rest_positions(), MatrixN3::Zero(system.num_particles(), 3), y.data());
  return ode.Jacobian(0.0, y.data());
}

RunSummary RunCvodeReduced(const ParticleSystem& system, const ReferenceOptions& options, const SolverSpec& spec,
                            const CvodeSettings& settings) {
  return RunCvodeWith(system, options, settings, &spec);
}

}  // namespace clothbench

// The rows of CVODE, as the registry lists them (harness/registry.cc).
#include <string>

#include "reference/klu_prediction.h"
#include "solver/method_row.h"

namespace clothbench {

// --cvode-setting: CVODE's setup knobs, every cvode row's own setting,
// stored as the run's sundials_settings.
const MethodSetting kCvodeSetting = {
    .field = "cvode_setting",
    .option = "--cvode-setting",
    .help = "comma-separated KEY=VALUE setup knobs of CVODE (CVODE's defaults otherwise): lsetup_frequency=20, "
            "jac_eval_frequency=51, dgmax_lsetup=0.3, stab_lim_det=0, eps_lin=0.05, atol_v_scale=1 (atol of the "
            "velocities over that of the positions); stored as the runs' sundials_settings",
    .what = "rows that read CVODE's settings",
    .check = [](const std::string& value) { return CvodeSettings().Parse(value); },
    .attribute = "sundials_settings"};

/// cvode: the reduced velocity solve with the PCG; cvode/klu: KLU on the
/// 6N×6N first-order Jacobian (the reference's solver). Both integrate
/// obstacle contact as a hybrid system with event location
/// (sundials/hybrid_contact.h). cvode is the default reference and the
/// equal-accuracy baseline: the fastest of the candidates at every size
/// measured (docs/notes/work-precision.md, "The reference"). Default
/// tolerances rtol 1e-2 … 1e-7.
MethodEntry CvodeRow() {
  return {.name = kCvodeName, .kind = StepKind::kAdaptive, .layer = "reference", .collisions = true, .pcg = true,
          .tangent = true, .sparse_jacobian = true,
          .integrate = [](const ParticleSystem& sys, const ReferenceOptions& o, const SolverSpec& spec,
                          std::string_view variant, const RunContext& ctx) {
            CvodeSettings cs;
            cs.Parse(ctx.Setting("cvode_setting").value_or(""));  // checked before the run (kCvodeSetting)
            return variant == "klu" ? RunCvode(sys, o, cs) : RunCvodeReduced(sys, o, spec, cs);
          },
          .predict = PredictKluVariant,
          .reference = true, .default_reference = true, .variants = {"klu"}, .settings = {kCvodeSetting},
          .best_preconditioner = kBestPreconditioner,
          .defaults = {{.modifiers = "", .rtols = kDefaultRtols}, {.modifiers = "klu", .rtols = kDefaultRtols}}};
}

}  // namespace clothbench
