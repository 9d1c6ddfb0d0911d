// IDA reference (SPEC §8).
#include "reference/ida_reference.h"

#include <chrono>

#include <fmt/format.h>
#include <ida/ida.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_klu.h>
#include <sunmatrix/sunmatrix_sparse.h>

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
};

int ResFn(realtype t, N_Vector y, N_Vector yp, N_Vector r, void* user) {
  static_cast<ResidualForm*>(user)->Residual(t, N_VGetArrayPointer(y), N_VGetArrayPointer(yp), N_VGetArrayPointer(r));
  return 0;
}

int JacFn(realtype t, realtype cj, N_Vector y, N_Vector, N_Vector, SUNMatrix jac, void* user, N_Vector, N_Vector,
          N_Vector) {
  return internal::CopyToSunSparse(static_cast<ResidualForm*>(user)->Jacobian(t, cj, N_VGetArrayPointer(y)), jac);
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

RunSummary RunIda(const ParticleSystem& system, const ReferenceOptions& options) {
  using Clock = std::chrono::steady_clock;
  const auto wall_start = Clock::now();
  RunSummary res;
  res.integrator = "ida";
  ResidualForm form(system);
  IdaHandles h;
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
  const SparseMatrix& j0 = form.Jacobian(0.0, 1.0, N_VGetArrayPointer(h.y));
  h.a = SUNSparseMatrix(n, n, j0.nonZeros(), CSC_MAT, h.ctx);
  h.ls = SUNLinSol_KLU(h.y, h.a, h.ctx);
  SUNLinSol_KLUSetOrdering(h.ls, 0);  // AMD
  h.mem = IDACreate(h.ctx);
  const bool ok = check(IDASetErrHandlerFn(h.mem, internal::StoreErrorMessage, &err), "IDASetErrHandlerFn") &&
                  check(IDAInit(h.mem, ResFn, 0.0, h.y, h.yp), "IDAInit") &&
                  check(IDASetUserData(h.mem, &form), "IDASetUserData") &&
                  check(IDASStolerances(h.mem, options.rtol, options.AbsoluteTolerance()), "IDASStolerances") &&
                  check(IDASetId(h.mem, h.id), "IDASetId") &&
                  check(IDASetSuppressAlg(h.mem, SUNTRUE), "IDASetSuppressAlg") &&
                  check(IDASetLinearSolver(h.mem, h.ls, h.a), "IDASetLinearSolver") &&
                  check(IDASetJacFn(h.mem, JacFn), "IDASetJacFn") &&
                  check(IDASetMaxOrd(h.mem, options.max_order), "IDASetMaxOrd") &&
                  check(IDASetStopTime(h.mem, options.t_end), "IDASetStopTime") &&
                  check(IDASetMaxNumSteps(h.mem, 100000000L), "IDASetMaxNumSteps");
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
  internal::SummariseCounters(&res);
  res.wall_time_in_seconds = std::chrono::duration<double>(Clock::now() - wall_start).count();
  return res;
}

}  // namespace clothbench
