// ARKODE ARKStep IMEX peer (docs/model.md §8, §10).
#include "peers/arkode.h"

#include <algorithm>
#include <chrono>
#include <limits>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <arkode/arkode_arkstep.h>
#include <fmt/format.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sundials/sundials_linearsolver.h>

#include "solver/integrator.h"
#include "solver/pcg.h"
#include "sundials/hybrid_contact.h"

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
// reduced stage solve; on scenes with obstacles the current contact mode's
// split (internal::HybridContact::SplitExplicit, SplitImplicit), its root
// functions and its events.
class ImexOde {
 public:
  /// @param entry_depth the contact events' hysteresis [m] (internal::HybridContact)
  ImexOde(const ParticleSystem& sys, const SolverSpec& spec, double entry_depth)
      : sys_(sys),
        spec_(spec),
        map_(sys),
        n_(sys.num_particles()),
        nf_(map_.num_free()),
        sysmat_(sys, spec.preconditioner, spec.cholesky_ordering),
        contact_(sys, entry_depth) {
    internal::StartVirtualParticles(sys);
    for (MatrixN3* m : {&x_, &v_, &f_, &fe_, &rx_, &rv_, &rhs_, &dv_, &tmp_}) m->setZero(n_, 3);
    x_ = sys.rest_positions();
    filter_.Reserve(n_);
    for (int p : sys.fixed()) filter_.Fix(p);
    work_.Resize(n_);
    if (contact_.active()) {
      // A (N×N, one entry per particle pair) with the friction rates on its
      // diagonal (Solve): the values follow A's, the diagonal positions are
      // found once.
      sysmat_.Update(1.0);
      a_friction_ = sysmat_.matrix();
      diagonal_.resize(static_cast<std::size_t>(n_));
      for (int i = 0; i < n_; ++i) {
        const int* inner = a_friction_.innerIndexPtr();
        const int begin = a_friction_.outerIndexPtr()[i], end = a_friction_.outerIndexPtr()[i + 1];
        diagonal_[static_cast<std::size_t>(i)] = static_cast<int>(std::lower_bound(inner + begin, inner + end, i) - inner);
      }
    }
  }
  internal::HybridContact& contact() { return contact_; }
  /// ARKODE's memory, its step count at its last (re)start (ARKStepReset
  /// keeps the counters) and its largest step [s]: the root functions'
  /// step horizon.
  void* mem() const { return mem_; }
  long steps_at_reset() const { return steps_at_reset_; }
  double max_step() const { return max_step_; }
  void set_mem(void* mem) { mem_ = mem; }
  /// ARKStepSetMaxStep, kept for the step horizon.
  int SetMaxStep(double h) {
    max_step_ = h;
    return ARKStepSetMaxStep(mem_, h);
  }
  void MarkReset() {
    if (ARKStepGetNumSteps(mem_, &steps_at_reset_) < 0) steps_at_reset_ = 0;
  }
  /// The root functions at (t, y): one per particle (HybridContact::Roots).
  void Roots(double t, const double* y, double* g) {
    FromY(y, &x_, &v_);
    sys_.Forces(t, x_, v_, &f_);
    contact_.Roots(t, x_, v_, f_, g);
  }
  /// The events at a root or break t on the state y (changed in place;
  /// HybridContact::ApplyEvents); returns the mode changes.
  int ApplyEvents(double t, const int* found, bool at_break, double* y) {
    FromY(y, &x_, &v_);
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
  void FromY(const double* y, MatrixN3* x, MatrixN3* v) const {
    map_.PositionsFromY(y, x);
    map_.VelocitiesFromY(y, v);
  }
  // f_E = (0, M⁻¹ g(t, x, v)); a sliding particle's is split.
  void Explicit(double t, const double* y, double* ydot) {
    FromY(y, &x_, &v_);
    sys_.ExplicitForces(t, x_, v_, &f_);
    if (contact_.active() && contact_.any_sliding()) contact_.SplitExplicit(t, x_, v_, &f_);
    Store(f_, nullptr, ydot);
  }
  // f_I = (v, M⁻¹(−L_K x − L_D v)); a sliding particle's is split.
  void Implicit(double t, const double* y, double* ydot) {
    FromY(y, &x_, &v_);
    f_.noalias() = sys_.stiffness_laplacian() * x_;
    if (sys_.has_tension_damping()) f_.noalias() += sys_.damping_laplacian() * v_;
    f_ = -f_;
    if (contact_.active() && contact_.any_sliding()) {
      sys_.ExplicitForces(t, x_, v_, &fe_);
      contact_.SplitImplicit(t, x_, v_, fe_, &f_);
    }
    Store(f_, y, ydot);
  }
  // (I − γ J_I) δ = r by δv from (M + γ L_D + γ² L_K) δv = M r_v − γ L_K r_x
  // and δx = r_x + γ δv. Returns the PCG status.
  // With contacts, a sliding particle's normal row is δv_n = n·r_v (its
  // implicit acceleration has no normal part) and its tangential rows
  // carry γ times its friction rate.
  PcgStatus Solve(double gamma, const double* r, double* delta, const double* w, double tol) {
    if (!sysmat_.Update(gamma)) return PcgStatus::kBreakdown;
    map_.SplitY(r, &rx_, &rv_);
    tmp_.noalias() = sys_.stiffness_laplacian() * rx_;
    rhs_.noalias() = sys_.masses().asDiagonal() * rv_;
    rhs_ -= gamma * tmp_;
    dv_.setZero();
    const SparseMatrix* a = &sysmat_.matrix();
    if (contact_.active()) {
      filter_.Clear();
      for (int p : sys_.fixed()) filter_.Fix(p);
      contact_.ForEachSliding([&](int p, const Vector3& n) { filter_.Constrain(p, n, n.dot(rv_.row(p).transpose())); });
      if (contact_.friction_rates().any()) {
        std::copy(a->valuePtr(), a->valuePtr() + a->nonZeros(), a_friction_.valuePtr());
        for (int p = 0; p < n_; ++p)
          a_friction_.valuePtr()[diagonal_[static_cast<std::size_t>(p)]] += gamma * contact_.friction_rates()(p);
        a = &a_friction_;
      }
    }
    const PcgSummary s =
        FilteredPcg(*a, rhs_, filter_, sysmat_.preconditioner(),
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
  internal::HybridContact contact_;
  void* mem_ = nullptr;
  long steps_at_reset_ = 0;
  double max_step_ = std::numeric_limits<double>::infinity();
  SparseMatrix a_friction_;    // with contacts: A + γ diag(friction rates)
  std::vector<int> diagonal_;  // per particle, the position of A's diagonal entry in its values
  VelocityFilter filter_;      // the fixed particles; with contacts also the sliding ones' normals
  PcgWorkspace work_;
  MatrixN3 x_, v_, f_, fe_, rx_, rv_, rhs_, dv_, tmp_;
  int last_iterations_ = 0;
  long total_iterations_ = 0;
  double last_residual_ = 0.0;
};

int ExplicitRhs(realtype t, N_Vector y, N_Vector ydot, void* user) {
  static_cast<ImexOde*>(user)->Explicit(t, N_VGetArrayPointer(y), N_VGetArrayPointer(ydot));
  return 0;
}
int ImplicitRhs(realtype t, N_Vector y, N_Vector ydot, void* user) {
  static_cast<ImexOde*>(user)->Implicit(t, N_VGetArrayPointer(y), N_VGetArrayPointer(ydot));
  return 0;
}
int RootFn(realtype t, N_Vector y, realtype* g, void* user) {
  auto* ode = static_cast<ImexOde*>(user);
  ode->contact().set_step_horizon(ode->mem(), {ARKStepGetNumSteps, ARKStepGetLastStep, ARKStepGetCurrentTime}, t,
                                  ode->steps_at_reset(), ode->max_step());
  ode->Roots(t, N_VGetArrayPointer(y), g);
  return 0;
}
// f_I is linear with a constant Jacobian while no particle slides (one
// Newton iteration per stage); a sliding particle's split makes it
// nonlinear (the normal follows x, friction follows v).
int SetLinearity(void* mem, ImexOde& ode) {
  return ode.contact().active() && ode.contact().any_sliding() ? ARKStepSetNonlinear(mem) : ARKStepSetLinear(mem, 0);
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
  if (internal::RefusesPrescribedMotion(system, &res)) return res;
  std::string why;
  if (!spec.IsValid(&why)) {
    res.status = RunStatus::kInvalidOptions;
    res.message = why;
    return res;
  }
  ImexOde ode(system, spec, 1e-2 * options.AbsoluteTolerance());
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
  ode.set_mem(h.mem);
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
  bool ok = check(ARKStepSetErrHandlerFn(h.mem, internal::StoreErrorMessage, &err), "ARKStepSetErrHandlerFn") &&
                  check(ARKStepSetUserData(h.mem, &ode), "ARKStepSetUserData") &&
                  check(ARKStepSetTableNum(h.mem, pair->implicit_table, pair->explicit_table), "ARKStepSetTableNum") &&
                  check(ARKStepSStolerances(h.mem, options.rtol, options.AbsoluteTolerance()), "ARKStepSStolerances") &&
                  check(ARKStepSetLinearSolver(h.mem, h.ls, nullptr), "ARKStepSetLinearSolver") &&
                  check(ARKStepSetStopTime(h.mem, options.t_end), "ARKStepSetStopTime") &&
                  check(ARKStepSetMaxNumSteps(h.mem, 100000000L), "ARKStepSetMaxNumSteps");
  // Obstacles: the contact modes at t = 0, one root function per particle
  // (entries as d − δ falls through 0, releases as λ does), and a reset
  // after every event (sundials/hybrid_contact.h), as for CVODE.
  std::vector<int> roots_found;
  if (ok && ode.contact().active()) {
    ode.contact().Initialize(0.0, system.rest_positions(), MatrixN3::Zero(system.num_particles(), 3));
    const int nr = ode.contact().num_roots();
    roots_found.assign(static_cast<std::size_t>(nr), 0);
    std::vector<int> direction(static_cast<std::size_t>(nr), -1);
    // The roots are sought between step ends only: a free fall, which the
    // pairs integrate exactly, took one step from 0.053 s to t_end = 0.5 s
    // on the round table and passed through the 0.7 m table unseen. The
    // frame interval bounds the step (a particle would need 70 m/s to
    // cross that table within it).
    ok = check(ode.SetMaxStep(options.frame_dt), "ARKStepSetMaxStep") &&
         check(ARKStepRootInit(h.mem, nr, RootFn), "ARKStepRootInit") &&
         check(ARKStepSetRootDirection(h.mem, direction.data()), "ARKStepSetRootDirection") &&
         check(ARKStepSetNoInactiveRootWarn(h.mem), "ARKStepSetNoInactiveRootWarn");
  }
  ok = ok && check(SetLinearity(h.mem, ode), "ARKStepSetLinear");
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
    // A jump of the state at t (an event, the self-contact response):
    // ARKODE restarts from h.y and keeps its counters.
    const auto reset = [&](double t) {
      int f = ARKStepReset(h.mem, t, h.y);
      ode.MarkReset();
      if (f >= 0) f = SetLinearity(h.mem, ode);
      return f < 0 ? f : ARKStepSetStopTime(h.mem, options.t_end);
    };
    if (ode.contact().active())
      d.on_event = [&](double t, bool root, bool at_break) {
        std::fill(roots_found.begin(), roots_found.end(), 0);
        const int f = root ? ARKStepGetRootInfo(h.mem, roots_found.data()) : 0;
        if (f < 0) return f;
        ode.ApplyEvents(t, roots_found.data(), at_break, N_VGetArrayPointer(h.y));
        return reset(t);
      };
    d.stop_at = [&](double t_stop) { return ARKStepSetStopTime(h.mem, t_stop); };
    d.restart = [&](double t, const MatrixN3& x, const MatrixN3& v) {
      ode.SetCorrected(t, x, v, N_VGetArrayPointer(h.y));
      return reset(t);
    };
    internal::RunFrames(d, system, options, err, &res);
  }
  SundialsStats st;  // ARKStepReset keeps the counters
  ARKStepGetNumSteps(h.mem, &st.nst);
  ARKStepGetNumRhsEvals(h.mem, &st.nfe, &st.nfe_i);
  ARKStepGetNumNonlinSolvIters(h.mem, &st.nni);
  st.nli = ode.total_iterations();
  ARKStepGetNumErrTestFails(h.mem, &st.netf);
  ARKStepGetNumNonlinSolvConvFails(h.mem, &st.ncfn);
  ARKStepGetNumLinSolvSetups(h.mem, &st.nsetups);
  internal::FinishRun(st, nullptr, ode.contact().active() ? &ode.contact().event_times() : nullptr, ode.setup_seconds(),
                      wall_start, &res);
  return res;
}

}  // namespace clothbench

// The rows of ARKODE, as the registry lists them (harness/registry.cc).
#include "solver/method_row.h"

namespace clothbench {
namespace {

// The arkode row's IMEX pair when the command line names none.
constexpr const char* kDefaultTable = "ARK324L2SA";

// --arkode-table: the IMEX pair of the arkode row without a variant (/ark4
// and /ark5 name theirs), stored as the run's butcher_table.
const MethodSetting kTableSetting = {
    .field = "arkode_table",
    .option = "--arkode-table",
    .help = "ARKODE IMEX pair: ARK324L2SA (default), ARK436L2SA, ARK437L2SA, ARK548L2SA, ARK548L2SAb",
    .what = "rows that read an ARKODE table",
    .check =
        [](const std::string& value) {
          const std::vector<std::string>& names = ArkodeTableNames();
          if (std::find(names.begin(), names.end(), value) != names.end()) return std::string();
          std::string known;
          for (const std::string& n : names) known += (known.empty() ? "" : ", ") + n;
          return fmt::format("\"{}\" must be one of {}", value, known);
        },
    .reads = [](std::string_view variant) { return variant.empty(); },
    .attribute = "butcher_table"};

}  // namespace

/// arkode: ARKStep's IMEX pair (--arkode-table, ARK324L2SA by default);
/// arkode/ark4 is ARK436L2SA (Kennedy & Carpenter 2003, order 4),
/// arkode/ark5 ARK548L2SA (order 5). Default tolerances: arkode rtol
/// 1e-2 … 1e-6 (its error is 1.7e-4 m already at rtol 1e-3; rtol 1e-7
/// alone costs 9.6 s); arkode/ark4 1.1e-3, 2.9e-5, 1.7e-6, 1.4e-7, 1.2e-8 m
/// at rtol 1e-2 … 1e-6; arkode/ark5 2.0e-5 m at rtol 1e-2 with 51
/// error-test failures, then 1.5e-6, 7.7e-7, 6.6e-9, 5.5e-10 m at rtol
/// 1e-3 … 1e-6 (below ~1e-9 m the CVODE reference at rtol 1e-10 is the
/// limit). `bench_integrators --integrators
/// sbdf2,sbdf3,arkode,arkode/ark4,arkode/ark5,cvode` with the arkode rows at
/// rtol 1e-2 … 1e-7.
MethodEntry ArkodeRow() {
  static const std::vector<double> kRtols = {1e-2, 1e-3, 1e-4, 1e-5, 1e-6};
  return {.name = kArkodeName, .kind = StepKind::kAdaptive, .layer = "peers", .pcg = true,
          .integrate = [](const ParticleSystem& sys, const ReferenceOptions& o, const SolverSpec& spec,
                          std::string_view variant, const RunContext& ctx) {
            const std::string table = variant == "ark4"   ? "ARK436L2SA"
                                      : variant == "ark5" ? "ARK548L2SA"
                                                          : ctx.Setting("arkode_table").value_or(kDefaultTable);
            RunSummary res = RunArkode(sys, o, table, &spec);
            res.SetMethodAttribute("butcher_table", table);  // the IMEX additive Runge–Kutta pair
            return res;
          },
          .variants = {"ark4", "ark5"}, .settings = {kTableSetting},
          .best_preconditioner = kBestPreconditioner,
          .defaults = {{.modifiers = "", .rtols = kRtols},
                       {.modifiers = "ark4", .rtols = kRtols},
                       {.modifiers = "ark5", .rtols = {1e-3, 1e-4, 1e-5, 1e-6}}}};
}

}  // namespace clothbench
