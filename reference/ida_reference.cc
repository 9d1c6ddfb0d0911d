// IDA reference (docs/model.md §8).
#include "reference/ida_reference.h"

#include <algorithm>
#include <chrono>
#include <memory>

#include <fmt/format.h>
#include <ida/ida.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_klu.h>
#include <sunmatrix/sunmatrix_sparse.h>

#include "solver/integrator.h"
#include "solver/pcg.h"
#include "solver/tangent.h"
#include "sundials/hybrid_contact.h"

namespace clothbench {
namespace {

// y = [x (3N); v (3N)] over all particles, index 3p + c. On scenes with
// obstacles the residual is the current contact mode's
// (internal::HybridContact, as CVODE's), with its roots and events.
class ResidualForm {
 public:
  /// @param entry_depth the contact events' hysteresis [m]
  ResidualForm(const ParticleSystem& sys, double entry_depth)
      : sys_(sys), n_(sys.num_particles()), contact_(sys, entry_depth) {
    internal::StartVirtualParticles(sys);
    x_.setZero(n_, 3);
    v_.setZero(n_, 3);
    f_.setZero(n_, 3);
  }
  int size() const { return 6 * n_; }
  internal::HybridContact& contact() { return contact_; }

  /// The root functions at (t, y): one per particle (HybridContact::Roots).
  void Roots(double t, const double* y, double* g) {
    Unpack(y);
    sys_.Forces(t, x_, v_, &f_);
    contact_.Roots(t, x_, v_, f_, g);
  }
  /// The events at a root or break t on y (changed in place;
  /// HybridContact::ApplyEvents), and ẏ consistent with the new modes:
  /// ẋ = v, M v̇ = f + the contact forces.
  void ApplyEvents(double t, const int* found, bool at_break, double* y, double* yp) {
    Unpack(y);
    contact_.ApplyEvents(t, found, at_break, &x_, &v_,
                         [&](double s, const MatrixN3& x, const MatrixN3& v, MatrixN3* f) { sys_.Forces(s, x, v, f); });
    Pack(t, y, yp);
  }
  /// y = (x, v) and the consistent yp = (v, M⁻¹ f(t, x, v)) of the state
  /// (x, v) (N×3 [m], [m/s]) at time t.
  void SetState(double t, const MatrixN3& x, const MatrixN3& v, double* y, double* yp) {
    x_ = x;
    v_ = v;
    Pack(t, y, yp);
  }
  /// The same after the self-contact response changed (x, v) at t, with
  /// the obstacle contact made consistent again
  /// (HybridContact::AfterCorrection).
  void SetCorrected(double t, const MatrixN3& x, const MatrixN3& v, double* y, double* yp) {
    x_ = x;
    v_ = v;
    contact_.AfterCorrection(t, &x_, &v_);
    Pack(t, y, yp);
  }
  void Pack(double t, double* y, double* yp) {
    sys_.Forces(t, x_, v_, &f_);
    contact_.AddContactForces(t, x_, v_, &f_);
    for (int p = 0; p < n_; ++p)
      for (int c = 0; c < 3; ++c) {
        const bool fixed = sys_.is_fixed(p);
        y[3 * p + c] = x_(p, c);
        y[3 * n_ + 3 * p + c] = v_(p, c);
        yp[3 * p + c] = fixed ? 0.0 : v_(p, c);
        yp[3 * n_ + 3 * p + c] = fixed ? 0.0 : f_(p, c) / sys_.masses()(p);
      }
  }

  void Unpack(const double* y) {
    for (int p = 0; p < n_; ++p)
      for (int c = 0; c < 3; ++c) {
        x_(p, c) = y[3 * p + c];
        v_(p, c) = y[3 * n_ + 3 * p + c];
      }
  }
  void State(const double* y, MatrixN3* x, MatrixN3* v) const {
    x->resize(n_, 3);
    v->resize(n_, 3);
    for (int p = 0; p < n_; ++p)
      for (int c = 0; c < 3; ++c) {
        (*x)(p, c) = y[3 * p + c];
        (*v)(p, c) = y[3 * n_ + 3 * p + c];
      }
  }

  // Consistent initial values at rest: ẋ = v = 0, M v̇ = f(0, x₀, 0).
  void Initial(double* y, double* yp) {
    const MatrixN3& x0 = sys_.rest_positions();
    MatrixN3 v0 = MatrixN3::Zero(n_, 3);
    sys_.Forces(0.0, x0, v0, &f_);
    for (int p = 0; p < n_; ++p)
      for (int c = 0; c < 3; ++c) {
        y[3 * p + c] = x0(p, c);
        y[3 * n_ + 3 * p + c] = 0.0;
        yp[3 * p + c] = 0.0;
        yp[3 * n_ + 3 * p + c] = sys_.is_fixed(p) ? 0.0 : f_(p, c) / sys_.masses()(p);
      }
  }

  // Differential (1) or algebraic (0) component (IDASetId).
  void Ids(double* id) const {
    for (int p = 0; p < n_; ++p)
      for (int c = 0; c < 3; ++c) id[3 * p + c] = id[3 * n_ + 3 * p + c] = sys_.is_fixed(p) ? 0.0 : 1.0;
  }

  void Residual(double t, const double* y, const double* yp, double* r) {
    Unpack(y);
    sys_.Forces(t, x_, v_, &f_);
    if (contact_.active()) contact_.AddContactForces(t, x_, v_, &f_);
    const MatrixN3& rest = sys_.rest_positions();
    for (int p = 0; p < n_; ++p) {
      const bool fixed = sys_.is_fixed(p);
      const double m = sys_.masses()(p);
      for (int c = 0; c < 3; ++c) {
        const int ix = 3 * p + c, iv = 3 * n_ + 3 * p + c;
        r[ix] = fixed ? y[ix] - rest(p, c) : yp[ix] - y[iv];
        r[iv] = fixed ? y[iv] : m * yp[iv] - f_(p, c);
      }
    }
  }

  // dF/dy + c_j dF/dẏ with a state- and c_j-independent pattern.
  const SparseMatrix& Jacobian(double t, double cj, const double* y) {
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
    const int off = 3 * n_;
    for (int i = 0; i < 2 * off; ++i) jt_.emplace_back(i, i, 0.0);
    for (int p = 0; p < n_; ++p) {
      const bool fixed = sys_.is_fixed(p);
      for (int c = 0; c < 3; ++c) {
        const int ix = 3 * p + c, iv = off + 3 * p + c;
        if (fixed) {
          jt_.emplace_back(ix, ix, 1.0);
          jt_.emplace_back(iv, iv, 1.0);
        } else {
          jt_.emplace_back(ix, ix, cj);
          jt_.emplace_back(ix, iv, -1.0);
          jt_.emplace_back(iv, iv, cj * sys_.masses()(p));
        }
      }
    }
    // A sliding particle's rows: −S_p ∂f/∂(x, v) (S_p = I − n nᵀ: the
    // constraint force takes the normal component) and +rate S_p from its
    // friction on the velocity block; its 3×3 blocks are dense, so the
    // pattern does not change.
    projection_.assign(static_cast<std::size_t>(n_), -1);
    projections_.clear();
    contact_.ForEachSliding([&](int p, const Vector3& n) {
      projection_[static_cast<std::size_t>(p)] = static_cast<int>(projections_.size());
      projections_.push_back(Matrix3::Identity() - n * n.transpose());
    });
    auto add = [&](const std::vector<Triplet>& src, int col_off) {
      for (const Triplet& e : src) {
        const int p = e.row() / 3;
        if (sys_.is_fixed(p)) continue;
        const int s = projection_[static_cast<std::size_t>(p)];
        if (s < 0) {
          jt_.emplace_back(off + e.row(), col_off + e.col(), -e.value());
        } else {
          for (int c = 0; c < 3; ++c)
            jt_.emplace_back(off + 3 * p + c, col_off + e.col(),
                             -projections_[static_cast<std::size_t>(s)](c, e.row() % 3) * e.value());
        }
      }
    };
    add(dfdx_, 0);
    add(dfdv_, off);
    for (int p = 0; p < n_; ++p) {
      const int s = projection_[static_cast<std::size_t>(p)];
      if (s < 0) continue;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
          jt_.emplace_back(off + 3 * p + r, off + 3 * p + c,
                           contact_.friction_rates()(p) * projections_[static_cast<std::size_t>(s)](r, c));
    }
    jac_.resize(size(), size());
    jac_.setFromTriplets(jt_.begin(), jt_.end());
    jac_.makeCompressed();
    return jac_;
  }

 private:
  const ParticleSystem& sys_;
  int n_;
  MatrixN3 x_, v_, f_;
  std::vector<Triplet> dfdx_, dfdv_, jt_;
  SparseMatrix jac_;
  double jacobian_seconds_ = 0.0;
  internal::HybridContact contact_;
  std::vector<int> projection_;      // per particle: index in projections_, −1: not sliding
  std::vector<Matrix3> projections_;  // sliding particles' S_p

 public:
  /// Wall time of the Jacobian evaluations so far [s].
  double jacobian_seconds() const { return jacobian_seconds_; }
};

// IDA's reduced Newton solve (RunIdaReduced): y = [x; v] over all
// particles, fixed particles algebraic.
class IdaReducedSolve {
 public:
  IdaReducedSolve(const ParticleSystem& sys, const SolverSpec& spec, internal::HybridContact* contact)
      : sys_(sys), spec_(spec), n_(sys.num_particles()), tangent_(sys, spec), contact_(contact) {
    for (MatrixN3* m : {&x_, &v_, &w_, &u_, &rhs_, &bv_}) m->setZero(n_, 3);
    dv_.setZero(n_, 3);
    br_.setZero(n_, 3);
    if (contact_ && contact_->active()) filter_.Reserve(n_);
  }

  // IDA's setup: the Jacobian at (t, y) (IDA has no jok: every setup is
  // a new Jacobian), J_γ with γ = 1/c_j, and its preconditioner.
  int Setup(double t, const double* y, double cj) {
    for (int p = 0; p < n_; ++p)
      for (int c = 0; c < 3; ++c) {
        x_(p, c) = y[3 * p + c];
        v_(p, c) = y[3 * n_ + 3 * p + c];
      }
    return tangent_.Setup(t, x_, v_, 1.0 / cj, true);
  }

  // δ from the reduced system (see RunIdaReduced); `cj` is IDA's current
  // c_j. The x rows are solved exactly and the free v rows' residual is c_j
  // times the PCG's, so ‖res_PCG‖₂ ≤ tol / (c_j max w_v) meets IDALS's stop.
  PcgStatus Solve(double cj, const double* b, double* delta, const double* w, double tol) {
    const double g = 1.0 / cj;
    double wmax = 0.0;
    for (int p = 0; p < n_; ++p) {
      const bool fixed = sys_.is_fixed(p);
      for (int c = 0; c < 3; ++c) {
        const double bx = b[3 * p + c], bv = b[3 * n_ + 3 * p + c];
        w_(p, c) = fixed ? bx / g : bx;
        u_(p, c) = fixed ? bv : 0.0;
        rhs_(p, c) = fixed ? 0.0 : g * bv;
        bv_(p, c) = bv;
        if (w && !fixed) wmax = std::max(wmax, w[3 * n_ + 3 * p + c]);
      }
    }
    tangent_.AddJacobianProducts(g * g, w_, g, u_, &rhs_);
    br_ = rhs_;
    const PcgOptions stop =
        internal::PcgStopForTolerance(cj * wmax, w ? tol : 0.0, {spec_.cg_tolerance, spec_.cg_max_iterations});
    PcgStatus status;
    if (contact_ && contact_->active()) {
      // A sliding particle's normal row is c_j m δv_n = b_v,n (its
      // acceleration's normal part is the constraint's); its tangential
      // rows carry the friction rate.
      filter_.Clear();
      for (int p : sys_.fixed()) filter_.Fix(p);
      contact_->ForEachSliding([&](int p, const Vector3& n) {
        filter_.Constrain(p, n, g * n.dot(bv_.row(p).transpose()) / sys_.masses()(p));
      });
      status = tangent_.Solve(g, br_, stop, &dv_, filter_, contact_->friction_rates());
    } else {
      status = tangent_.Solve(g, br_, stop, &dv_);
    }
    for (int p = 0; p < n_; ++p) {
      const bool fixed = sys_.is_fixed(p);
      for (int c = 0; c < 3; ++c) {
        const int ix = 3 * p + c, iv = 3 * n_ + 3 * p + c;
        if (fixed) {
          delta[ix] = b[ix];
          delta[iv] = b[iv];
        } else {
          delta[iv] = dv_(p, c);
          delta[ix] = g * (b[ix] + dv_(p, c));
        }
      }
    }
    return status;
  }
  const internal::ReducedTangent& tangent() const { return tangent_; }
  int last_iterations() const { return tangent_.last_iterations(); }
  double last_residual() const { return tangent_.last_residual(); }

 private:
  const ParticleSystem& sys_;
  const SolverSpec& spec_;
  int n_;
  internal::ReducedTangent tangent_;
  internal::HybridContact* contact_;
  VelocityFilter filter_;  // with contacts: the fixed particles and the sliding ones' normals
  MatrixN3 x_, v_, w_, u_, rhs_, bv_;
  MatrixN3R dv_, br_;
};

// IDA's user data: the residual form, and the reduced solve of row `ida`.
struct IdaUser {
  ResidualForm* form = nullptr;
  IdaReducedSolve* reduced = nullptr;
  void* mem = nullptr;  // IDA's
};

int ResFn(realtype t, N_Vector y, N_Vector yp, N_Vector r, void* user) {
  static_cast<IdaUser*>(user)->form->Residual(t, N_VGetArrayPointer(y), N_VGetArrayPointer(yp),
                                              N_VGetArrayPointer(r));
  return 0;
}

int RootFn(realtype t, N_Vector y, N_Vector, realtype* g, void* user) {
  const auto* u = static_cast<IdaUser*>(user);
  u->form->contact().set_step_horizon(u->mem, {IDAGetNumSteps, IDAGetLastStep, IDAGetCurrentTime}, t);
  u->form->Roots(t, N_VGetArrayPointer(y), g);
  return 0;
}

// Adds IDA's counters since its last (re)initialisation to `st`.
void AddIdaCounters(void* mem, SundialsStats* st) {
  internal::AddCounters(mem,
                        {IDAGetNumSteps, IDAGetNumResEvals, IDAGetNumNonlinSolvIters, IDAGetNumLinIters,
                         IDAGetNumErrTestFails, IDAGetNumNonlinSolvConvFails, IDAGetNumJacEvals,
                         IDAGetNumLinSolvSetups},
                        st);
}

int JacFn(realtype t, realtype cj, N_Vector y, N_Vector, N_Vector, SUNMatrix jac, void* user, N_Vector, N_Vector,
          N_Vector) {
  return internal::CopyToSunSparse(static_cast<IdaUser*>(user)->form->Jacobian(t, cj, N_VGetArrayPointer(y)), jac);
}

int PrecSetup(realtype t, N_Vector y, N_Vector, N_Vector, realtype cj, void* user) {
  return static_cast<IdaUser*>(user)->reduced->Setup(t, N_VGetArrayPointer(y), cj);
}
// Never called: the reduced solve does not apply IDALS's preconditioner.
int PrecSolve(realtype, N_Vector, N_Vector, N_Vector, N_Vector r, N_Vector z, realtype, realtype, void*) {
  N_VScale(1.0, r, z);
  return 0;
}

struct IdaHandles {
  SUNContext ctx = nullptr;
  N_Vector y = nullptr, yp = nullptr, id = nullptr, dky = nullptr;
  SUNMatrix a = nullptr;
  SUNLinearSolver ls = nullptr;
  void* mem = nullptr;
  ~IdaHandles() {
    if (mem) IDAFree(&mem);
    if (ls) SUNLinSolFree(ls);
    if (a) SUNMatDestroy(a);
    for (N_Vector v : {dky, id, yp, y})
      if (v) N_VDestroy(v);
    if (ctx) SUNContext_Free(&ctx);
  }
};

}  // namespace

namespace {

RunSummary RunIdaWith(const ParticleSystem& system, const ReferenceOptions& options, const SolverSpec* reduced) {
  using Clock = std::chrono::steady_clock;
  const auto wall_start = Clock::now();
  RunSummary res;
  internal::NameSundialsRun(kIdaName, "reference", options, &res);
  if (internal::RefusesPrescribedMotion(system, &res)) return res;
  ResidualForm form(system, 1e-2 * options.AbsoluteTolerance());
  std::unique_ptr<IdaReducedSolve> solve;
  if (reduced) solve = std::make_unique<IdaReducedSolve>(system, *reduced, &form.contact());
  IdaUser user{&form, solve.get()};
  IdaHandles h;
  double klu_seconds = 0.0;  // KLU setups (ida/klu)
  std::string err;
  auto check = [&](int flag, const char* call) {
    return internal::CheckFlag(flag, call, IDAGetReturnFlagName, err, &res);
  };

  SUNContext_Create(nullptr, &h.ctx);
  const sunindextype n = form.size();
  h.y = N_VNew_Serial(n, h.ctx);
  h.yp = N_VNew_Serial(n, h.ctx);
  h.id = N_VNew_Serial(n, h.ctx);
  h.dky = N_VNew_Serial(n, h.ctx);
  form.Initial(N_VGetArrayPointer(h.y), N_VGetArrayPointer(h.yp));
  form.Ids(N_VGetArrayPointer(h.id));
  h.mem = IDACreate(h.ctx);
  user.mem = h.mem;
  if (solve) {
    // IDALS hands the custom solver its preconditioner-setup wrapper: IDA's
    // setups evaluate the Jacobian; the PCG stops at IDALS's own tolerance.
    void* mem = h.mem;
    h.ls = internal::NewCustomLinearSolver(h.ctx, internal::ReducedSolveHooks(solve.get(), [mem](double* cj) {
                                             return IDAGetCurrentCj(mem, cj) == IDA_SUCCESS;
                                           }),
                                           h.y);
  } else {
    const SparseMatrix& j0 = form.Jacobian(0.0, 1.0, N_VGetArrayPointer(h.y));
    h.a = SUNSparseMatrix(n, n, j0.nonZeros(), CSC_MAT, h.ctx);
    SUNLinearSolver klu = SUNLinSol_KLU(h.y, h.a, h.ctx);
    SUNLinSol_KLUSetOrdering(klu, 0);  // AMD
    h.ls = internal::NewTimedLinearSolver(h.ctx, klu, &klu_seconds);  // setups count as setup time
  }
  bool ok = check(IDASetErrHandlerFn(h.mem, internal::StoreErrorMessage, &err), "IDASetErrHandlerFn") &&
                  check(IDAInit(h.mem, ResFn, 0.0, h.y, h.yp), "IDAInit") &&
                  check(IDASetUserData(h.mem, &user), "IDASetUserData") &&
                  check(IDASStolerances(h.mem, options.rtol, options.AbsoluteTolerance()), "IDASStolerances") &&
                  check(IDASetId(h.mem, h.id), "IDASetId") &&
                  check(IDASetSuppressAlg(h.mem, SUNTRUE), "IDASetSuppressAlg") &&
                  check(IDASetLinearSolver(h.mem, h.ls, h.a), "IDASetLinearSolver") &&
                  check(IDASetMaxOrd(h.mem, options.max_order), "IDASetMaxOrd") &&
                  check(IDASetStopTime(h.mem, options.t_end), "IDASetStopTime") &&
                  check(IDASetMaxNumSteps(h.mem, 100000000L), "IDASetMaxNumSteps");
  // Obstacles: the contact modes at t = 0 and one root function per
  // particle, caught as it falls through 0 (sundials/hybrid_contact.h).
  std::vector<int> roots_found;
  SundialsStats counters;  // summed over the restarts
  if (ok && form.contact().active()) {
    form.contact().Initialize(0.0, system.rest_positions(), MatrixN3::Zero(system.num_particles(), 3));
    const int nr = form.contact().num_roots();
    roots_found.assign(static_cast<std::size_t>(nr), 0);
    std::vector<int> direction(static_cast<std::size_t>(nr), -1);
    ok = check(IDARootInit(h.mem, nr, RootFn), "IDARootInit") &&
         check(IDASetRootDirection(h.mem, direction.data()), "IDASetRootDirection") &&
         check(IDASetNoInactiveRootWarn(h.mem), "IDASetNoInactiveRootWarn");
  }
  if (ok && solve)
    ok = check(IDASetPreconditioner(h.mem, PrecSetup, PrecSolve), "IDASetPreconditioner");
  else if (ok)
    ok = check(IDASetJacFn(h.mem, JacFn), "IDASetJacFn");
  if (ok) {
    internal::OneStepDriver d;
    // One step, never past the stop time (t_end, or the next frame with
    // self-contact). The output time given is 2 t_end: IDA's first step
    // after a restart is at most 0.001 |tout − t|, and with tout = t_end
    // the restarts of the self-contact response at every step crept to
    // t_end, each step 0.001 of the time left (fold_over_rod to t_end =
    // 0.5 s at rtol 1e-3: 13,809 of 24,915 steps in its last 1e-6 s).
    d.step = [&](double* t) { return IDASolve(h.mem, 2.0 * options.t_end, t, h.y, h.yp, IDA_ONE_STEP); };
    d.state_at = [&](double tf, MatrixN3* x, MatrixN3* v) {
      const int f = IDAGetDky(h.mem, tf, 0, h.dky);
      if (f >= 0) form.State(N_VGetArrayPointer(h.dky), x, v);
      return f;
    };
    d.current_state = [&](MatrixN3* x, MatrixN3* v) { form.State(N_VGetArrayPointer(h.y), x, v); };
    d.last_step = [&](double* hl, int* q) {
      IDAGetLastStep(h.mem, hl);
      IDAGetLastOrder(h.mem, q);
    };
    d.flag_name = [](int f) { return std::string(IDAGetReturnFlagName(f)); };
    // A jump of the state at t (an event, the self-contact response): the
    // counters so far are kept and IDA restarts from (h.y, h.yp).
    const auto reinit = [&](double t) {
      AddIdaCounters(h.mem, &counters);
      const int f = IDAReInit(h.mem, t, h.y, h.yp);
      return f < 0 ? f : IDASetStopTime(h.mem, options.t_end);
    };
    if (form.contact().active())
      d.on_event = [&](double t, bool root, bool at_break) {
        std::fill(roots_found.begin(), roots_found.end(), 0);
        const int f = root ? IDAGetRootInfo(h.mem, roots_found.data()) : 0;
        if (f < 0) return f;
        form.ApplyEvents(t, roots_found.data(), at_break, N_VGetArrayPointer(h.y), N_VGetArrayPointer(h.yp));
        return reinit(t);
      };
    d.stop_at = [&](double t_stop) { return IDASetStopTime(h.mem, t_stop); };
    d.restart = [&](double t, const MatrixN3& x, const MatrixN3& v) {
      form.SetCorrected(t, x, v, N_VGetArrayPointer(h.y), N_VGetArrayPointer(h.yp));
      return reinit(t);
    };
    internal::RunFrames(d, system, options, err, &res);
  }
  AddIdaCounters(h.mem, &counters);
  internal::FinishRun(counters, solve ? &solve->tangent() : nullptr,
                      form.contact().active() ? &form.contact().event_times() : nullptr,
                      solve ? solve->tangent().setup_seconds() : klu_seconds + form.jacobian_seconds(), wall_start, &res);
  return res;
}

}  // namespace

RunSummary RunIda(const ParticleSystem& system, const ReferenceOptions& options) {
  return RunIdaWith(system, options, nullptr);
}

RunSummary RunIdaReduced(const ParticleSystem& system, const ReferenceOptions& options, const SolverSpec& spec) {
  return RunIdaWith(system, options, &spec);
}

}  // namespace clothbench

// The rows of IDA, as the registry lists them (harness/registry.cc).
#include "reference/klu_prediction.h"
#include "solver/method_row.h"

namespace clothbench {

/// ida: the reduced velocity solve; ida/klu: KLU on the 6N×6N residual
/// Jacobian (the reference's solver). Not a default row.
MethodEntry IdaRow() {
  return {.name = kIdaName, .kind = StepKind::kAdaptive, .layer = "reference", .collisions = true, .pcg = true,
          .tangent = true, .sparse_jacobian = true,
          .integrate = [](const ParticleSystem& sys, const ReferenceOptions& o, const SolverSpec& spec,
                          std::string_view variant, const RunContext&) {
            return variant == "klu" ? RunIda(sys, o) : RunIdaReduced(sys, o, spec);
          },
          .predict = PredictKluVariant,
          .reference = true, .variants = {"klu"}, .best_preconditioner = kBestPreconditioner};
}

}  // namespace clothbench
