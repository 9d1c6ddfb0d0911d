// ARKODE ARKStep IMEX peer (docs/model.md §8, §10).
#include "peers/arkode.h"

#include <chrono>
#include <stdexcept>
#include <utility>

#include <arkode/arkode_arkstep.h>
#include <fmt/format.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sundials/sundials_linearsolver.h>

#include "solver/integrator.h"
#include "solver/pcg.h"

namespace clothbench {
namespace {

struct TablePair {
  const char* name;
  ARKODE_ERKTableID explicit_table;
  ARKODE_DIRKTableID implicit_table;
  int order;
};

constexpr TablePair kTables[] = {
    {"ARK324L2SA", ARKODE_ARK324L2SA_ERK_4_2_3, ARKODE_ARK324L2SA_DIRK_4_2_3, 3},
    {"ARK436L2SA", ARKODE_ARK436L2SA_ERK_6_3_4, ARKODE_ARK436L2SA_DIRK_6_3_4, 4},
    {"ARK437L2SA", ARKODE_ARK437L2SA_ERK_7_3_4, ARKODE_ARK437L2SA_DIRK_7_3_4, 4},
    {"ARK548L2SA", ARKODE_ARK548L2SA_ERK_8_4_5, ARKODE_ARK548L2SA_DIRK_8_4_5, 5},
    {"ARK548L2SAb", ARKODE_ARK548L2SAb_ERK_8_4_5, ARKODE_ARK548L2SAb_DIRK_8_4_5, 5},
};

// The split ODE on the free degrees of freedom y = [x_free; v_free], and the
// reduced stage solve.
class ImexOde {
 public:
  ImexOde(const ParticleSystem& sys, const SolverSpec& spec)
      : sys_(sys),
        spec_(spec),
        map_(sys),
        n_(sys.num_particles()),
        nf_(map_.num_free()),
        sysmat_(sys, spec.preconditioner, spec.cholesky_ordering) {
    for (MatrixN3* m : {&x_, &v_, &f_, &rx_, &rv_, &rhs_, &dv_, &tmp_}) m->setZero(n_, 3);
    x_ = sys.rest_positions();
    filter_.Reserve(n_);
    for (int p : sys.fixed()) filter_.Fix(p);
    work_.Resize(n_);
  }
  const internal::FreeDofMap& map() const { return map_; }
  int size() const { return map_.size(); }
  void FromY(const double* y, MatrixN3* x, MatrixN3* v) const {
    map_.PositionsFromY(y, x);
    map_.VelocitiesFromY(y, v);
  }
  // f_E = (0, M⁻¹ g(t, x, v)).
  void Explicit(double t, const double* y, double* ydot) {
    FromY(y, &x_, &v_);
    sys_.ExplicitForces(t, x_, v_, &f_);
    Store(f_, nullptr, ydot);
  }
  // f_I = (v, M⁻¹(−L_K x − L_D v)).
  void Implicit(const double* y, double* ydot) {
    FromY(y, &x_, &v_);
    f_.noalias() = sys_.stiffness_laplacian() * x_;
    if (sys_.has_tension_damping()) f_.noalias() += sys_.damping_laplacian() * v_;
    f_ = -f_;
    Store(f_, y, ydot);
  }
  // (I − γ J_I) δ = r by δv from (M + γ L_D + γ² L_K) δv = M r_v − γ L_K r_x
  // and δx = r_x + γ δv. Returns the PCG status.
  PcgStatus Solve(double gamma, const double* r, double* delta, const double* w, double tol) {
    if (!sysmat_.Update(gamma)) return PcgStatus::kBreakdown;
    map_.SplitY(r, &rx_, &rv_);
    tmp_.noalias() = sys_.stiffness_laplacian() * rx_;
    rhs_.noalias() = sys_.masses().asDiagonal() * rv_;
    rhs_ -= gamma * tmp_;
    dv_.setZero();
    const PcgSummary s =
        FilteredPcg(sysmat_.matrix(), rhs_, filter_, sysmat_.preconditioner(),
                    internal::PcgStopForTolerance(map_, sys_.masses(), w, tol, {spec_.cg_tolerance, spec_.cg_max_iterations}),
                    &dv_, &work_);
    last_iterations_ = s.iterations;
    total_iterations_ += s.iterations;
    last_residual_ = s.residual_norm;
    for (int k = 0; k < nf_; ++k)
      for (int c = 0; c < 3; ++c) {
        delta[3 * nf_ + 3 * k + c] = dv_(map_.particle(k), c);
        delta[3 * k + c] = r[3 * k + c] + gamma * dv_(map_.particle(k), c);
      }
    return s.status;
  }
  int last_iterations() const { return last_iterations_; }
  long total_iterations() const { return total_iterations_; }
  double last_residual() const { return last_residual_; }
  double setup_seconds() const { return sysmat_.setup_seconds(); }

 private:
  // ydot = (v or 0, M⁻¹ force) on the free rows.
  void Store(const MatrixN3& force, const double* y, double* ydot) const {
    const Eigen::VectorXd& m = sys_.masses();
    for (int k = 0; k < nf_; ++k) {
      const int p = map_.particle(k);
      for (int c = 0; c < 3; ++c) {
        ydot[3 * k + c] = y ? y[3 * nf_ + 3 * k + c] : 0.0;
        ydot[3 * nf_ + 3 * k + c] = force(p, c) / m(p);
      }
    }
  }
  const ParticleSystem& sys_;
  const SolverSpec& spec_;
  internal::FreeDofMap map_;
  int n_, nf_;
  SystemMatrix sysmat_;
  VelocityFilter filter_;
  PcgWorkspace work_;
  MatrixN3 x_, v_, f_, rx_, rv_, rhs_, dv_, tmp_;
  int last_iterations_ = 0;
  long total_iterations_ = 0;
  double last_residual_ = 0.0;
};

int ExplicitRhs(realtype t, N_Vector y, N_Vector ydot, void* user) {
  static_cast<ImexOde*>(user)->Explicit(t, N_VGetArrayPointer(y), N_VGetArrayPointer(ydot));
  return 0;
}
int ImplicitRhs(realtype, N_Vector y, N_Vector ydot, void* user) {
  static_cast<ImexOde*>(user)->Implicit(N_VGetArrayPointer(y), N_VGetArrayPointer(ydot));
  return 0;
}

struct ArkodeHandles {
  SUNContext ctx = nullptr;
  N_Vector y = nullptr, dky = nullptr;
  SUNLinearSolver ls = nullptr;
  void* mem = nullptr;
  ~ArkodeHandles() {
    if (mem) ARKStepFree(&mem);
    if (ls) SUNLinSolFree(ls);
    if (dky) N_VDestroy(dky);
    if (y) N_VDestroy(y);
    if (ctx) SUNContext_Free(&ctx);
  }
};

}  // namespace

const std::vector<std::string>& ArkodeTableNames() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> v;
    for (const TablePair& t : kTables) v.emplace_back(t.name);
    return v;
  }();
  return names;
}

RunSummary RunArkode(const ParticleSystem& system, const ReferenceOptions& options, const std::string& table,
                          const SolverSpec* solver) {
  const SolverSpec& spec = solver ? *solver : system.scene().solver;
  const TablePair* pair = nullptr;
  for (const TablePair& t : kTables)
    if (table == t.name) pair = &t;
  if (!pair) {
    std::string known;
    for (const std::string& n : ArkodeTableNames()) known += (known.empty() ? "" : ", ") + n;
    throw std::invalid_argument(fmt::format("arkode table \"{}\" is not one of {}", table, known));
  }
  using Clock = std::chrono::steady_clock;
  const auto wall_start = Clock::now();
  RunSummary res;
  internal::NameSundialsRun(kArkodeName, "peers", options, &res);
  if (!system.obstacles().empty()) {
    res.status = RunStatus::kUnsupportedScene;
    res.message = "arkode has no collision response: the scene has obstacles";
    return res;
  }
  std::string why;
  if (!spec.IsValid(&why)) {
    res.status = RunStatus::kInvalidOptions;
    res.message = why;
    return res;
  }
  ImexOde ode(system, spec);
  ArkodeHandles h;
  std::string err;
  auto check = [&](int flag, const char* call) {
    return internal::CheckFlag(flag, call, ARKStepGetReturnFlagName, err, &res);
  };
  SUNContext_Create(nullptr, &h.ctx);
  const sunindextype n = ode.size();
  h.y = N_VNew_Serial(n, h.ctx);
  h.dky = N_VNew_Serial(n, h.ctx);
  ode.map().ToY(system.rest_positions(), MatrixN3::Zero(system.num_particles(), 3), N_VGetArrayPointer(h.y));
  h.mem = ARKStepCreate(ExplicitRhs, ImplicitRhs, 0.0, h.y, h.ctx);
  // The custom SUNLinearSolver (sundials/sundials_common.h) solves ARKLS's
  // systems through ImexOde::Solve with γ from ARKStepGetCurrentGamma, the
  // PCG stopping at ARKLS's own tolerance for iterative solvers in its
  // weighted norm (internal::PcgStopForTolerance).
  {
    void* mem = h.mem;
    h.ls = internal::NewCustomLinearSolver(h.ctx, internal::ReducedSolveHooks(&ode, [mem](double* gamma) {
                                             return ARKStepGetCurrentGamma(mem, gamma) == ARK_SUCCESS;
                                           }));
  }
  const bool ok = check(ARKStepSetErrHandlerFn(h.mem, internal::StoreErrorMessage, &err), "ARKStepSetErrHandlerFn") &&
                  check(ARKStepSetUserData(h.mem, &ode), "ARKStepSetUserData") &&
                  check(ARKStepSetTableNum(h.mem, pair->implicit_table, pair->explicit_table), "ARKStepSetTableNum") &&
                  check(ARKStepSStolerances(h.mem, options.rtol, options.AbsoluteTolerance()), "ARKStepSStolerances") &&
                  check(ARKStepSetLinearSolver(h.mem, h.ls, nullptr), "ARKStepSetLinearSolver") &&
                  // f_I is linear with a constant Jacobian: one Newton iteration per stage.
                  check(ARKStepSetLinear(h.mem, 0), "ARKStepSetLinear") &&
                  check(ARKStepSetStopTime(h.mem, options.t_end), "ARKStepSetStopTime") &&
                  check(ARKStepSetMaxNumSteps(h.mem, 100000000L), "ARKStepSetMaxNumSteps");
  if (ok) {
    internal::OneStepDriver d;
    d.step = [&](double* t) { return ARKStepEvolve(h.mem, options.t_end, h.y, t, ARK_ONE_STEP); };
    d.state_at = [&](double tf, MatrixN3* x, MatrixN3* v) {
      const int f = ARKStepGetDky(h.mem, tf, 0, h.dky);
      if (f >= 0) ode.FromY(N_VGetArrayPointer(h.dky), x, v);
      return f;
    };
    d.current_state = [&](MatrixN3* x, MatrixN3* v) { ode.FromY(N_VGetArrayPointer(h.y), x, v); };
    d.last_step = [&](double* hl, int* q) {
      ARKStepGetLastStep(h.mem, hl);
      *q = pair->order;
    };
    d.flag_name = [](int f) { return std::string(ARKStepGetReturnFlagName(f)); };
    internal::RunFrames(d, system, options, err, &res);
  }
  SundialsStats& st = res.sundials.emplace();
  ARKStepGetNumSteps(h.mem, &st.nst);
  ARKStepGetNumRhsEvals(h.mem, &st.nfe, &st.nfe_i);
  ARKStepGetNumNonlinSolvIters(h.mem, &st.nni);
  st.nli = ode.total_iterations();
  ARKStepGetNumErrTestFails(h.mem, &st.netf);
  ARKStepGetNumNonlinSolvConvFails(h.mem, &st.ncfn);
  ARKStepGetNumLinSolvSetups(h.mem, &st.nsetups);
  res.setup_time_s = ode.setup_seconds();
  internal::SummariseCounters(&res);
  res.wall_time_s = std::chrono::duration<double>(Clock::now() - wall_start).count();
  return res;
}

}  // namespace clothbench
