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

namespace clothbench {
namespace {

// y = [x (3N); v (3N)] over all particles, index 3p + c.
class ResidualForm {
 public:
  explicit ResidualForm(const ParticleSystem& sys) : sys_(sys), n_(sys.num_particles()) {
    x_.setZero(n_, 3);
    v_.setZero(n_, 3);
    f_.setZero(n_, 3);
  }
  int size() const { return 6 * n_; }

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
    for (const Triplet& e : dfdx_)
      if (!sys_.is_fixed(e.row() / 3)) jt_.emplace_back(off + e.row(), e.col(), -e.value());
    for (const Triplet& e : dfdv_)
      if (!sys_.is_fixed(e.row() / 3)) jt_.emplace_back(off + e.row(), off + e.col(), -e.value());
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

 public:
  /// Wall time of the Jacobian evaluations so far [s].
  double jacobian_seconds() const { return jacobian_seconds_; }
};

// IDA's reduced Newton solve (RunIdaReduced): y = [x; v] over all
// particles, fixed particles algebraic.
class IdaReducedSolve {
 public:
  IdaReducedSolve(const ParticleSystem& sys, const SolverSpec& spec)
      : sys_(sys), spec_(spec), n_(sys.num_particles()), tangent_(sys, spec) {
    for (MatrixN3* m : {&x_, &v_, &w_, &u_, &rhs_}) m->setZero(n_, 3);
    dv_.setZero(n_, 3);
    br_.setZero(n_, 3);
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
        if (w && !fixed) wmax = std::max(wmax, w[3 * n_ + 3 * p + c]);
      }
    }
    tangent_.AddJacobianProducts(g * g, w_, g, u_, &rhs_);
    br_ = rhs_;
    const PcgStatus status = tangent_.Solve(
        g, br_, internal::PcgStopForTolerance(cj * wmax, w ? tol : 0.0, {spec_.cg_tolerance, spec_.cg_max_iterations}),
        &dv_);
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
  MatrixN3 x_, v_, w_, u_, rhs_;
  MatrixN3R dv_, br_;
};

// IDA's user data: the residual form, and the reduced solve of row `ida`.
struct IdaUser {
  ResidualForm* form = nullptr;
  IdaReducedSolve* reduced = nullptr;
};

int ResFn(realtype t, N_Vector y, N_Vector yp, N_Vector r, void* user) {
  static_cast<IdaUser*>(user)->form->Residual(t, N_VGetArrayPointer(y), N_VGetArrayPointer(yp),
                                              N_VGetArrayPointer(r));
  return 0;
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
  ResidualForm form(system);
  std::unique_ptr<IdaReducedSolve> solve;
  if (reduced) solve = std::make_unique<IdaReducedSolve>(system, *reduced);
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
  if (ok && solve)
    ok = check(IDASetPreconditioner(h.mem, PrecSetup, PrecSolve), "IDASetPreconditioner");
  else if (ok)
    ok = check(IDASetJacFn(h.mem, JacFn), "IDASetJacFn");
  if (ok) {
    internal::OneStepDriver d;
    d.step = [&](double* t) { return IDASolve(h.mem, options.t_end, t, h.y, h.yp, IDA_ONE_STEP); };
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
    internal::RunFrames(d, system, options, err, &res);
  }
  SundialsStats& st = res.sundials.emplace();
  IDAGetNumSteps(h.mem, &st.nst);
  IDAGetNumResEvals(h.mem, &st.nfe);
  IDAGetNumNonlinSolvIters(h.mem, &st.nni);
  IDAGetNumLinIters(h.mem, &st.nli);
  IDAGetNumErrTestFails(h.mem, &st.netf);
  IDAGetNumNonlinSolvConvFails(h.mem, &st.ncfn);
  IDAGetNumJacEvals(h.mem, &st.nje);
  IDAGetNumLinSolvSetups(h.mem, &st.nsetups);
  if (solve) {
    st.nli = solve->tangent().total_iterations();
    st.nje = solve->tangent().jacobian_evaluations();
    res.setup_time_s = solve->tangent().setup_seconds();
  } else {
    res.setup_time_s = klu_seconds + form.jacobian_seconds();
  }
  internal::SummariseCounters(&res);
  res.wall_time_s = std::chrono::duration<double>(Clock::now() - wall_start).count();
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
