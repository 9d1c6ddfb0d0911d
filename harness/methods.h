// The registry of every method the executables run, by name: the thesis'
// integrators and symplectic Euler (solver/), the peers baraff_witkin, xpbd,
// pd and arkode (peers/), and the references cvode and ida (reference/). Each
// entry says how it is stepped (fixed h, adaptive at an rtol, substepped,
// iterated) and every row runs through the same call, returning the same
// MethodRun.
//
// Row labels: the name, then "/newton" for a fully implicit method with
// Newton's method, then "/error" for SBDF(2) and BDF(2) under local error
// control (adaptive rows, docs/notes/work-precision.md): "bdf2/newton/error".
#ifndef CLOTHBENCH_HARNESS_METHODS_H_
#define CLOTHBENCH_HARNESS_METHODS_H_

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <fmt/format.h>

#include "harness/first_run.h"
#include "model/particle_system.h"
#include "model/trajectory.h"
#include "peers/arkode.h"
#include "peers/baraff_witkin.h"
#include "peers/projective_dynamics.h"
#include "peers/vbd.h"
#include "peers/xpbd.h"
#include "reference/cvode_reference.h"
#include "reference/ida_reference.h"
#include "reference/klu_prediction.h"
#include "results/metrics.h"
#include "results/result_file.h"
#include "results/run_table.h"
#include "solver/integrator.h"
#include "solver/run.h"

namespace clothbench {

/// Settings shared by all rows of one invocation.
struct RunContext {
  std::string arkode_table = "ARK324L2SA";
  RunLimits limits{};  ///< wall time and steps of every row (--time-limit)
  std::string variant;  ///< the row's variant (RowMethod::variant)
  /// True if the command line named the preconditioner (--preconditioner):
  /// it then holds for every row, MethodEntry::best_preconditioner included.
  bool preconditioner_from_cli = false;
  /// True if the command line named the CG tolerance (--cg-tolerance or
  /// --cg-tolerances): it then holds for every row, MethodEntry::best_cg_tolerance
  /// included.
  bool cg_tolerance_from_cli = false;
  /// True if the command line named J_α's terms (--tangent-terms): they then
  /// hold for every row, MethodEntry::best_tangent_explicit_terms included.
  bool tangent_terms_from_cli = false;
  CvodeSettings cvode{};  ///< --cvode-setting
  /// Whether a row predicted past the limits is not started
  /// (MethodEntry::predict; false: --start-predicted).
  bool refuse_predicted = true;
};

struct MethodEntry {
  std::string_view name;
  StepKind kind = StepKind::kFixedStep;
  std::string_view layer;         ///< "solver", "peers" or "reference"
  bool nonlinear_solver = false;  ///< takes fixed_point | newton (fully implicit thesis methods)
  bool error_control = false;     ///< may run adaptively as "<name>/error" (SBDF(2), BDF(2))
  bool collisions = false;        ///< has a collision response (docs/model.md §7)
  bool pcg = false;               ///< solves with the filtered PCG (so the CG tolerance η applies)
  bool tangent = false;           ///< always holds the 3N×3N tangent system J_α (memory check)
  bool sparse_jacobian = false;   ///< holds a 6N×6N Jacobian and its KLU factor (memory check)
  /// Fixed-step, substepped and iterated methods (and error-controlled
  /// SBDF(2)/BDF(2)): the stepper on `sys` with settings `spec`, `count`
  /// substeps or iterations per step for substepped and iterated ones, and
  /// the row's `variant` ("chebyshev"); nullptr for the SUNDIALS-stepped ones.
  std::unique_ptr<Stepper> (*make)(const ParticleSystem& sys, const SolverSpec& spec, int count,
                                   std::string_view variant) = nullptr;
  /// SUNDIALS-stepped adaptive methods: one run at `o.rtol`; nullptr otherwise.
  RunSummary (*integrate)(const ParticleSystem& sys, const ReferenceOptions& o, const SolverSpec& spec,
                          const RunContext& ctx) = nullptr;
  /// What a run on `sys` for the row's `variant` cannot avoid in time and
  /// memory, known before it starts (FirstRunPrediction, solver/run.h);
  /// nullptr or zeros: none. A row predicted past --time-limit or the
  /// available memory is not started (harness/first_run.h).
  FirstRunPrediction (*predict)(const ParticleSystem& sys, std::string_view variant) = nullptr;
  /// Whether the method can be the reference (--reference NAME,
  /// clothbench.reference(): RunReference), the tight run every row's error
  /// is measured against.
  bool reference = false;
  /// Variants a row may name after a '/' ("arkode/ark4", "cvode/klu").
  std::vector<std::string_view> variants = {};
  /// Rows without a variant read an ARKODE IMEX table (--arkode-table).
  bool arkode_table = false;
  /// Rows read CVODE's setup knobs (--cvode-setting).
  bool cvode_settings = false;
  /// Fills what a row's record says about the stepper beyond the registry
  /// (xpbd: the terms it solves as constraints and those it applies
  /// explicitly); nullptr: nothing.
  void (*describe)(const Stepper& stepper, const ParticleSystem& sys, RunRecord* record) = nullptr;
  /// The preconditioner that measures best for this method's fixed-step,
  /// substepped and SUNDIALS rows, used instead of a scene's IC(0) (the
  /// thesis' setting) unless --preconditioner names one; a scene that names
  /// any other preconditioner keeps it (the measurement is in
  /// kBestPreconditioner's comment); nullopt: the scene's.
  std::optional<PreconditionerType> best_preconditioner = std::nullopt;
  /// The same for its error-controlled rows ("/error"), whose step changes
  /// and refactorises the preconditioner nearly every step.
  std::optional<PreconditionerType> best_preconditioner_error = std::nullopt;
  /// The CG tolerance η that measures best for this method, used instead of
  /// the scene's solver.cg_tolerance unless the command line names one
  /// (the measurement is beside the entry); nullopt: the scene's.
  std::optional<double> best_cg_tolerance = std::nullopt;
  /// The same for SolverSpec::tangent_explicit_terms (whether the explicit
  /// terms' Jacobians enter J_α) where the method holds J_α.
  std::optional<bool> best_tangent_explicit_terms = std::nullopt;
};

/// The default run's preconditioner for every method that uses the PCG:
/// CHOLMOD's factor of A_α (for the Newton, Baraff–Witkin and SUNDIALS rows
/// the preconditioner of their tangent system). The thesis' IC(0) stays the
/// scenes' setting, used by --table and the stability maps.
///
/// Measured on the default scene (400 particles): the default run three
/// times with each of `--preconditioner ic0`, `cholesky`, `jacobi` (and
/// once with `amg`, slower than IC(0) for every method), each method's
/// solver time summed over its rows, the least of the three runs. Against
/// IC(0), the factor takes 0.75× for sbdf2, 0.90× sbdf3, 0.92× imex_euler,
/// 0.99× implicit_euler, 0.82× bdf2, 0.85× implicit_midpoint, 0.68×/0.80×/
/// 0.78× their Newton rows, 0.68× bdf2/newton/error, 0.66× baraff_witkin,
/// 0.92× cvode, 0.92–0.95× the arkode rows (and 0.96× for ida, run alone
/// twice with `--integrators ida`); 3×3 block Jacobi was never the
/// fastest. The one exception is sbdf2/error: 1.111 s against 0.977 s with
/// IC(0) (each change of h refactorises, and at 400 particles IC(0) is the
/// cheaper factorisation), so it keeps the scene's. Rows without the PCG
/// (blender, xpbd, cvode/klu) varied by 1–3 % between these runs, the
/// timing noise of the minimum. At 10⁴–10⁶ particles the factor wins for
/// SBDF(2) by 10–30× (docs/notes/performance.md, bench_scaling), and it is the
/// large_sheet scene's own setting.
/// Without contacts "auto" is that factor; in contact it chooses between the
/// factor with contact factors and the prefiltered AMG (docs/notes/performance.md,
/// "The contact policy").
inline constexpr PreconditionerType kBestPreconditioner = PreconditionerType::kAuto;

/// pd/chebyshev's acceleration (Wang 2015). ρ is measured in each run, at
/// the first step of each h (ProjectiveDynamics::kRhoIterations plain
/// iterations), because it depends on the scene: on the default scene at
/// h = 0.01 s the plain iteration contracts by 0.9101 per iteration at
/// t = 0.3 s (test PdChebyshev.RhoOfThePlainIteration). γ and the delay
/// were measured there with ρ fixed at 0.91: the rms difference of the
/// final positions to implicit_euler/newton after 0.5 s, with 4 / 8 / 16 /
/// 32 iterations, is 1.7e-2 / 3.9e-3 / 7.1e-4 / – m for plain PD; with
/// γ = 1, delay 1: 6.0e-2 / 3.3e-3 / 3.4e-4 / 6.6e-7; γ = 0.9, delay 2:
/// 3.9e-3 / 3.9e-3 / 2.4e-5 / 1.6e-6; γ = 1, delay 4: 1.7e-2 / 1.8e-3 /
/// 2.9e-5 / 9.1e-7 (ρ = 0.85 and 0.95 were no better at 16). γ = 0.9 with
/// delay 2 is the only setting better than plain PD at every count.
inline constexpr ChebyshevSettings kPdChebyshev{.on = true, .rho = 0.0, .gamma = 0.9, .delay = 2};

/// vbd/chebyshev's acceleration, with ρ measured in each run at the first
/// step of each h (KrylovRho over a tenth of the run's sweeps, at most
/// VertexBlockDescent::kRhoIterations = 128; 0.9788 from 40 on the default
/// scene at h = 0.01 s with 4 sweeps per step; the settings below were
/// chosen with the ratio of 512 plain increments, 0.9840 there). The paper's schedule (Chen
/// et al. 2024, §3.8: γ = 1, ω leaves 1 at the second sweep) diverges there
/// with 4 sweeps per step (rms difference to implicit_euler/newton after
/// 0.5 s: 1.3e21 m; 4.2e-2 and 3.0e-4 m with 16 and 64 sweeps; ρ from 128
/// sweeps and the inertial first iterate), and so does ρ = 0.99 with it at
/// 16 and 64; pd/chebyshev's γ = 0.9 and delay 2 give 2.5e-1, 1.7e-2,
/// 6.4e-5 m at 4, 16, 64 sweeps with the adaptive first iterate and ρ from
/// 512 sweeps, falling at every count (plain VBD: 3.0e-1, 1.9e-1, 5.1e-2 m;
/// test VertexBlockDescent.ConvergesToImplicitEulerWithTheIterations).
/// γ = 1 with delay 2 reached 3.5e-5 m at 64 there; not adopted, as it was
/// measured on this one scene only. Without a restart the schedule lets
/// Gauss–Seidel's complex modes grow: a tilted 15×12 sheet (verify/vbd_test.cc)
/// blows up at 4–6 sweeps per step, and the hanging sheet goes from 1.1e-3
/// m at 128 sweeps to 5.1e-3 m at 256; with the adaptive restart
/// (ChebyshevSettings::restart) no count from 1 to 256 fails on the tilted,
/// swinging and hanging sheets, the distance falls from 16 sweeps on, and
/// the default scene's 64-sweep distance is unchanged (6.4e-5 m;
/// docs/model.md §10).
inline constexpr ChebyshevSettings kVbdChebyshev{
    .on = true, .rho = 0.0, .gamma = 0.9, .delay = 2, .restart = true};

namespace internal {
template <Method M>
std::unique_ptr<Stepper> MakeEngine(const ParticleSystem& sys, const SolverSpec& spec, int /*count*/,
                                    std::string_view /*variant*/) {
  return std::make_unique<StepEngine>(sys, M, spec);
}
}  // namespace internal

namespace internal {
/// The field's other methods' rows (peers/), in table order: Baraff–Witkin
/// at its best and as Blender ships it, XPBD, projective dynamics, VBD.
inline std::vector<MethodEntry> PeerEntries() {
  constexpr auto kSubstepped = StepKind::kSubstepped, kIterated = StepKind::kIterated;
  constexpr auto kBest = kBestPreconditioner;
  return {
      // baraff_witkin: also measured at h = 0.01, 0.00125, 0.0003125 s alone
      // (`bench_integrators --integrators baraff_witkin --h
      // 0.01,0.00125,0.0003125 --preconditioner P`): solver time 0.124,
      // 0.554, 1.835 s with "cholesky", 0.174, 0.876, 3.149 s with "ic0"
      // (IC(0) of J refactorised every step), 0.230, 0.693, 2.048 s with 3×3
      // block Jacobi and 0.281, 0.635, 1.878 s with none.
      // Its CG tolerance is Blender's conjgrad_epsilon, 10⁻², on the Δv
      // form's ‖S r‖/‖S b_Δ‖ (the scenes' η = 10⁻⁶ is the thesis' velocity-
      // form setting). Measured (`bench_integrators --integrators
      // baraff_witkin --cg-tolerances 1e-6,1e-4,1e-3,1e-2`, default scene):
      // e_rms 2.986e-3 / 2.961e-3 / 3.008e-3 m at h = 0.00125 s and
      // 7.540e-4 / 7.541e-4 / 7.765e-4 m at h = 0.0003125 s for η = 10⁻⁶,
      // 10⁻³, 10⁻² (+0.7 % and +3 % at 10⁻²), solver time 0.537 / 0.433 /
      // 0.388 s and 1.734 / 1.534 / 1.439 s. On the 10⁶-particle sheet the
      // final positions differ from the η = 10⁻⁶ run by 2.1·10⁻⁶ m rms
      // after 1.4·10⁻² m of motion, and a step takes 2.6–2.9 s instead of
      // 6.6–7.6 s (docs/notes/newton.md).
      // J_α of tension and mass only (tangent_explicit_terms = false; shear,
      // bending and the other terms enter f₀ but not J): `bench_integrators
      // --integrators baraff_witkin --h 0.01,0.00125 --tangent-terms all`
      // and `tension` on the default scene: solver time 0.064 / 0.379 s with
      // all terms, 0.032 / 0.163 s with tension (CG iterations 785 / 1655
      // and 796 / 1660), e_rms 2.351e-2 / 3.008e-3 m and 2.206e-2 / 2.781e-3
      // m. At h = 0.01 s on hanging_sheet, wind_sheet, tablecloth,
      // hanging_tablecloth, round_table and swinging_box it takes 0.48–0.53×
      // the solver time with the same CG counts (±3 %) and dE/dt to three
      // digits. The Newton rows keep the scene's: their quadratic
      // convergence needs the whole J (bdf2/newton at h = 0.01 s: 503
      // instead of 300 updates, the same time).
      {.name = kBaraffWitkinName, .layer = "peers", .collisions = true, .pcg = true, .tangent = true,
       .make = [](const ParticleSystem& sys, const SolverSpec& spec, int, std::string_view) -> std::unique_ptr<Stepper> {
         return std::make_unique<BaraffWitkin>(sys, spec);
       },
       .best_preconditioner = kBest, .best_cg_tolerance = 1e-2, .best_tangent_explicit_terms = false},
      // Blender's solver as it ships (peers/baraff_witkin.h): its own CG
      // settings, so the scene's η does not apply.
      {.name = kBlenderName, .layer = "peers", .collisions = true, .tangent = true,
       .make = [](const ParticleSystem& sys, const SolverSpec& spec, int, std::string_view) -> std::unique_ptr<Stepper> {
         return std::make_unique<BaraffWitkin>(sys, spec, BaraffWitkinOptions{true});
       }},
      {.name = kXpbdName, .kind = kSubstepped, .layer = "peers", .collisions = true,
       .make = [](const ParticleSystem& sys, const SolverSpec&, int substeps,
                  std::string_view) -> std::unique_ptr<Stepper> { return std::make_unique<Xpbd>(sys, substeps); },
       .describe = [](const Stepper& stepper, const ParticleSystem& sys, RunRecord* row) {
         const auto& x = static_cast<const Xpbd&>(stepper);  // this entry's make builds an Xpbd
         for (const std::string& t : x.explicit_terms()) row->explicit_terms += (row->explicit_terms.empty() ? "" : ",") + t;
         row->constraints = std::string("tension") + (x.shear_constraint() ? ",shear" : "") +
                            (sys.obstacles().empty() ? "" : ",obstacles");
       }},
      // pd: projective dynamics, the model's springs projected and A₁
      // prefactored; pd/chebyshev with Wang's acceleration at the measured
      // ρ (kPdChebyshev).
      {.name = kProjectiveDynamicsName, .kind = kIterated, .layer = "peers", .collisions = true,
       .make = [](const ParticleSystem& sys, const SolverSpec& spec, int iterations,
                  std::string_view variant) -> std::unique_ptr<Stepper> {
         return std::make_unique<ProjectiveDynamics>(
             sys, spec, iterations, variant == "chebyshev" ? kPdChebyshev : ChebyshevSettings{});
       },
       .variants = {"chebyshev"},
       .describe = [](const Stepper& stepper, const ParticleSystem& sys, RunRecord* row) {
         // The springs are projected (F_nl); every other explicit term
         // enters the global step's right-hand side at the iterate.
         row->chebyshev_rho = static_cast<const ProjectiveDynamics&>(stepper).rho();  // this entry builds one
         row->chebyshev_rho_sweeps = static_cast<const ProjectiveDynamics&>(stepper).rho_sweeps();
         row->constraints = "tension";
         for (const std::string& t : sys.TermNames())
           if (t != "tension_nonlinear") row->explicit_terms += (row->explicit_terms.empty() ? "" : ",") + t;
       }},
      // vbd: Vertex Block Descent, one local Newton step per particle and
      // sweep, colours in sequence; vbd/chebyshev with the paper's
      // acceleration at the measured ρ (kVbdChebyshev). Every term is
      // implicit in the local steps.
      {.name = kVbdName, .kind = kIterated, .layer = "peers", .collisions = true,
       .make = [](const ParticleSystem& sys, const SolverSpec&, int iterations,
                  std::string_view variant) -> std::unique_ptr<Stepper> {
         return std::make_unique<VertexBlockDescent>(sys, iterations,
                                                     variant == "chebyshev" ? kVbdChebyshev : ChebyshevSettings{});
       },
       .variants = {"chebyshev"},
       .describe = [](const Stepper& stepper, const ParticleSystem&, RunRecord* row) {
         const auto& vbd = static_cast<const VertexBlockDescent&>(stepper);  // this entry builds one
         row->chebyshev_rho = vbd.rho();
         row->chebyshev_rho_sweeps = vbd.rho_sweeps();
         row->colours = vbd.colours();
       }},
  };
}
}  // namespace internal

/// cvode/klu and ida/klu: KLU's analysis of their Newton matrix
/// (reference/klu_prediction.h); the reduced rows: none.
inline FirstRunPrediction PredictKluVariant(const ParticleSystem& sys, std::string_view variant) {
  return variant == "klu" ? PredictKluRun(sys) : FirstRunPrediction{};
}

/// Every method, in table order.
inline const std::vector<MethodEntry>& Registry() {
  using internal::MakeEngine;
  constexpr auto kAdaptive = StepKind::kAdaptive;
  constexpr auto kBest = kBestPreconditioner;
  static const std::vector<MethodEntry> r = [&] {
    std::vector<MethodEntry> rows = {
      {.name = "imex_euler", .layer = "solver", .collisions = true, .pcg = true,
       .make = MakeEngine<Method::kImexEuler>, .best_preconditioner = kBest},
      {.name = "implicit_euler", .layer = "solver", .nonlinear_solver = true, .collisions = true, .pcg = true,
       .make = MakeEngine<Method::kImplicitEuler>, .best_preconditioner = kBest},
      {.name = "sbdf2", .layer = "solver", .error_control = true, .collisions = true, .pcg = true,
       .make = MakeEngine<Method::kSbdf2>, .best_preconditioner = kBest},
      {.name = "bdf2", .layer = "solver", .nonlinear_solver = true, .error_control = true, .collisions = true,
       .pcg = true, .make = MakeEngine<Method::kBdf2>, .best_preconditioner = kBest,
       .best_preconditioner_error = kBest},
      {.name = "implicit_midpoint", .layer = "solver", .nonlinear_solver = true, .collisions = true, .pcg = true,
       .make = MakeEngine<Method::kImplicitMidpoint>, .best_preconditioner = kBest},
      {.name = "sbdf3", .layer = "solver", .collisions = true, .pcg = true, .make = MakeEngine<Method::kSbdf3>,
       .best_preconditioner = kBest},
      {.name = "symplectic_euler", .layer = "solver", .collisions = true, .make = MakeEngine<Method::kSymplecticEuler>},
    };
    for (MethodEntry& e : internal::PeerEntries()) rows.push_back(std::move(e));
    std::vector<MethodEntry> sundials = {
      {.name = kArkodeName, .kind = kAdaptive, .layer = "peers", .pcg = true,
       .integrate = [](const ParticleSystem& sys, const ReferenceOptions& o, const SolverSpec& spec,
                       const RunContext& ctx) { return RunArkode(sys, o, ctx.arkode_table, &spec); },
       .variants = {"ark4", "ark5"}, .arkode_table = true, .best_preconditioner = kBest},
      // cvode: the reduced velocity solve with the PCG; cvode/klu:
      // KLU on the 6N×6N first-order Jacobian (the reference's solver).
      // Both integrate obstacle contact as a hybrid system with event
      // location (sundials/hybrid_contact.h).
      {.name = kCvodeName, .kind = kAdaptive, .layer = "reference", .collisions = true, .pcg = true, .tangent = true,
       .sparse_jacobian = true,
       .integrate = [](const ParticleSystem& sys, const ReferenceOptions& o, const SolverSpec& spec,
                       const RunContext& ctx) {
         return ctx.variant == "klu" ? RunCvode(sys, o) : RunCvodeReduced(sys, o, spec);
       },
       .predict = PredictKluVariant,
       .reference = true, .variants = {"klu"}, .cvode_settings = true, .best_preconditioner = kBest},
      // ida: the reduced velocity solve; ida/klu: KLU on the 6N×6N
      // residual Jacobian (the reference's solver).
      {.name = kIdaName, .kind = kAdaptive, .layer = "reference", .collisions = true, .pcg = true, .tangent = true,
       .sparse_jacobian = true,
       .integrate = [](const ParticleSystem& sys, const ReferenceOptions& o, const SolverSpec& spec,
                       const RunContext& ctx) {
         return ctx.variant == "klu" ? RunIda(sys, o) : RunIdaReduced(sys, o, spec);
       },
       .predict = PredictKluVariant,
       .reference = true, .variants = {"klu"}, .best_preconditioner = kBest},
    };
    for (MethodEntry& e : sundials) rows.push_back(std::move(e));
    return rows;
  }();
  return r;
}

/// The row every equal-accuracy ratio is relative to (docs/notes/work-precision.md):
/// CVODE with the reduced velocity solve.
inline constexpr std::string_view kWorkPrecisionBaseline = kCvodeName;
/// The default reference (--reference): CVODE with the reduced velocity
/// solve, the fastest of the candidates at every size measured
/// (docs/notes/work-precision.md, "The reference").
inline constexpr std::string_view kDefaultReference = kCvodeName;

/// The methods that can be the reference, for messages ("cvode, ida").
inline std::string ReferenceNames();

inline const MethodEntry* FindMethod(std::string_view name) {
  for (const MethodEntry& e : Registry())
    if (e.name == name) return &e;
  return nullptr;
}

inline std::string ReferenceNames() {
  std::string s;
  for (const MethodEntry& e : Registry())
    if (e.reference) {
      s += (s.empty() ? "" : ", ") + std::string(e.name);
      for (std::string_view v : e.variants) s += fmt::format(", {}/{}", e.name, v);
    }
  return s;
}

/// The known names, for messages.
inline std::string KnownMethodNames() {
  std::string s;
  for (const MethodEntry& e : Registry()) s += (s.empty() ? "" : ", ") + std::string(e.name);
  return s;
}

/// One run of one row: the step loop's RunSummary (its record, the
/// attributes the table prints and the result file stores, with the
/// trajectory and step history) and what the caller derives from it against
/// a reference: the record's error, order and energy fields and these.
struct MethodRun : RunSummary {
  std::optional<TrajectoryErrors> err;
  EnergySeries energy;

  StepKind kind() const { return step_kind; }
};

/// The ARKODE IMEX pair of an arkode row modifier: "ark4" is ARK436L2SA
/// (Kennedy & Carpenter 2003, order 4), "ark5" ARK548L2SA (order 5); ""
/// for any other modifier.
inline std::string ArkodeRowTable(std::string_view modifier) {
  if (modifier == "ark4") return "ARK436L2SA";
  if (modifier == "ark5") return "ARK548L2SA";
  return "";
}

/// One row's method: a registry entry with its nonlinear solver and, for
/// SBDF(2)/BDF(2), error control.
struct RowMethod {
  const MethodEntry* entry = nullptr;
  NonlinearSolver solver = NonlinearSolver::kFixedPoint;
  bool error_control = false;
  /// A method's variant, the last part of its label: for arkode "ark4" and
  /// "ark5", the IMEX pair of that order (ArkodeRowTable; none: the
  /// invocation's --arkode-table); for cvode and ida "klu", KLU on the
  /// first-order Jacobian instead of the reduced solve.
  std::string variant;

  std::string name() const { return std::string(entry->name); }
  StepKind kind() const { return error_control ? StepKind::kAdaptive : entry->kind; }
  /// "bdf2", "bdf2/newton", "sbdf2/error", "baraff_witkin".
  std::string label() const {
    std::string s = name();
    if (solver == NonlinearSolver::kNewton) s += "/newton";
    if (error_control) s += "/error";
    if (!variant.empty()) s += "/" + variant;
    return s;
  }
  /// The label as an HDF5 group-name part ("bdf2_newton").
  std::string id() const {
    std::string s = label();
    for (char& c : s)
      if (c == '/') c = '_';
    return s;
  }
  /// The id of this row's run at `param` (h [s] or rtol) and `count`
  /// (substeps or iterations): "bdf2_newton_h0.01", "xpbd_h0.01_n4",
  /// "pd_chebyshev_h0.01_k16", "cvode_rtol0.0001" (a sweep over CG
  /// tolerances appends "_eta<η>").
  std::string RunId(double param, int count) const {
    const StepKindSpec& k = SpecOf(kind());
    std::string run_id = fmt::format("{}_{}{:g}", id(), k.param, param);
    if (k.counted()) run_id += fmt::format("_{}{}", k.count_id, count);
    return run_id;
  }
  bool fully_implicit() const { return entry->nonlinear_solver; }
  /// Whether the row reads an ARKODE IMEX table (arkode rows without /ark4 or /ark5).
  bool reads_arkode_table() const { return entry->arkode_table && variant.empty(); }
  /// Whether the method's linear solves use the PCG (and so the CG tolerance η).
  bool uses_pcg() const { return entry->pcg && variant != "klu"; }
  /// Whether the row builds the 3N×3N tangent system J_α.
  bool builds_tangent() const {
    return (entry->tangent && variant != "klu") || solver == NonlinearSolver::kNewton;
  }
  /// `spec` with this row's nonlinear solver and, under error control, the
  /// step control and tolerance `rtol` (= atol).
  SolverSpec Settings(SolverSpec spec, double rtol = 0.0) const {
    spec.nonlinear_solver = solver;
    if (error_control) {
      spec.step_control = StepControl::kError;
      spec.rtol = rtol;
      spec.atol = 0.0;
    }
    return spec;
  }
  /// A stepper for fixed-step rows and the stability maps, with the scene's
  /// solver settings and this row's nonlinear solver; nullptr for adaptive
  /// methods that SUNDIALS steps.
  std::unique_ptr<Stepper> Make(const ParticleSystem& sys, const SolverSpec& spec) const {
    return entry->make ? entry->make(sys, Settings(spec), 1, variant) : nullptr;
  }

  /// Runs `sys` from rest to scene.t_end. `param` is h [s] for fixed-step,
  /// substepped and iterated rows (the frame step, split into `count`
  /// substeps, or with `count` iterations) and rtol (= atol) for adaptive
  /// ones; `spec` the solver settings (the scene's, with the invocation's
  /// overrides). Never throws for a numerical failure (see RunRecord::status).
  MethodRun Run(const ParticleSystem& sys, const Scene& scene, const SolverSpec& spec, double param,
                const RunContext& ctx, int count = 1) const;
};

/// An option that only some rows read: its request field (RunRequest,
/// Python keyword), its command-line option, which rows read it and those
/// rows in words. The one table that both the request's rules (a run of a
/// row that does not read a given option is refused) and UnusedOption (a
/// bench option that no row of the invocation reads is refused) consult.
struct RowOption {
  const char* field;
  const char* option;
  bool (*reads)(const RowMethod&);
  const char* rows;
};
inline const std::vector<RowOption>& RowOptions() {
  static const std::vector<RowOption> options = {
      {"rtol", "--rtols", [](const RowMethod& m) { return SpecOf(m.kind()).adaptive(); },
       "adaptive rows: cvode, ida, arkode, sbdf2/error, bdf2/error"},
      {"substeps", "--substeps", [](const RowMethod& m) { return SpecOf(m.kind()).count == "substeps"; },
       "substepped rows: xpbd"},
      {"iterations", "--iterations", [](const RowMethod& m) { return SpecOf(m.kind()).count == "iterations"; },
       "iterated rows: pd, pd/chebyshev, vbd, vbd/chebyshev"},
      {"cg_tolerance", "--cg-tolerance/--cg-tolerances", [](const RowMethod& m) { return m.uses_pcg(); },
       "rows that solve with the PCG"},
      {"preconditioner", "--preconditioner", [](const RowMethod& m) { return m.uses_pcg(); },
       "rows that solve with the PCG"},
      {"nonlinear_solver", "--nonlinear-solver", [](const RowMethod& m) { return m.fully_implicit(); },
       "implicit_euler, bdf2, implicit_midpoint"},
      {"arkode_table", "--arkode-table", [](const RowMethod& m) { return m.reads_arkode_table(); },
       "arkode rows without /ark4 or /ark5"},
      {"cvode_setting", "--cvode-setting", [](const RowMethod& m) { return m.entry->cvode_settings; }, "cvode rows"},
      {"tangent_terms", "--tangent-terms", [](const RowMethod& m) { return m.builds_tangent(); },
       "rows that build J_alpha: Newton rows, baraff_witkin, blender, cvode, ida"},
  };
  return options;
}
/// The RowOptions() entry of request field `field`. @throws std::logic_error for another name.
inline const RowOption& RowOptionOf(std::string_view field) {
  for (const RowOption& o : RowOptions())
    if (field == o.field) return o;
  throw std::logic_error(fmt::format("no row option {}", field));
}

/// The command-line options that only some rows read, and whether each was given.
struct GivenOptions {
  bool rtols = false, substeps = false, iterations = false, cg_tolerance = false, preconditioner = false, nonlinear_solver = false,
       arkode_table = false, cvode_setting = false, tangent_terms = false;
  std::string baseline;  ///< --baseline ROW; empty: not given
};

/// The first given option that no row of `rows` reads (or a --baseline
/// that names no row), as "--rtols: no row
/// of this run uses it (it applies to …)"; empty if every given option is
/// used. An option nobody reads would otherwise be ignored silently.
std::string UnusedOption(const std::vector<RowMethod>& rows, const GivenOptions& given);

/// Under a scene whose [solver] step_control is "error", the rows of the
/// methods that run under error control (sbdf2, bdf2) are their "/error"
/// rows: adaptive, labelled so, at --rtols or by default at the scene's
/// rtol (PlanRows). Without this a "sbdf2" row would step under error
/// control yet be listed, labelled and parameterised by h. The SUNDIALS
/// rows keep their own error control. A fixed-step or substepped row
/// without error control cannot run such a scene: named on the command line
/// (`named`) it is refused before anything is computed; among the default
/// rows it is left out (and a default row that becomes one already listed).
/// @throws std::invalid_argument naming the row and the scene key
void AdoptSceneStepControl(const SolverSpec& spec, std::vector<RowMethod>* rows, bool named,
                           std::string_view option = "--integrators");

/// A row's default parameters when the command line gives none: step sizes
/// as multiples of the scene's h (fixed-step rows; frame steps of
/// substepped rows) and tolerances rtol (adaptive rows). Chosen on the
/// default scene (the swinging sheet, h = 0.01 s) so that each row's runs
/// bracket e_rms = 1e-3 m where that fits the default run's time budget;
/// the measured e_rms that justify them (docs/notes/work-precision.md):
///  - imex_euler: 0.61, 0.39, 0.18, 0.060 m at h, h/4, h/16, h/64. Its error
///    is 0.017 m at h/256 (`bench_integrators --integrators
///    imex_euler,implicit_euler/newton --h 0.01,0.0025,6.25e-4,1.5625e-4,3.90625e-5`); 1e-3 m would need h ≈ 2e-6 s (order 1), about
///    45 s of solver time, so its rows do not bracket 1e-3 m.
///  - implicit_euler: 3.0e-3, 1.5e-3, 7.5e-4 m at h/8, h/16, h/32 (larger h
///    cost more: fixed-point rejections).
///  - implicit_euler/newton: 2.2e-2, 1.1e-2, 5.9e-3 m at h, h/2, h/4;
///    1e-3 m needs h ≈ 3e-4 s and 15–20 s (a tangent refresh per iterate), so
///    its rows do not bracket 1e-3 m.
///  - sbdf2: 4.4e-2 … 1.5e-3 m at h … h/8, and h/16 below 1e-3 m.
///  - bdf2, implicit_midpoint (fixed point): 2.3e-4 and 6.3e-5 m already at
///    h; at larger h the fixed point does not converge and the step is
///    halved, so no run reaches 1e-3 m.
///  - bdf2/newton: 7.9e-3, 2.7e-3, 7.4e-4 m at 4h, 2h, h.
///  - implicit_midpoint/newton: 4.0e-3, 9.9e-4, 2.5e-4 m at 4h, 2h, h.
///  - baraff_witkin: 3.0e-3 m at h/8, 7.5e-4 m at h/32; blender: 2.8e-3 m
///    and 6.4e-4 m (`bench_integrators --integrators baraff_witkin,blender
///    --h 0.01,0.005,0.0025,0.00125,0.000625,0.0003125`).
///  - xpbd: frame steps h and h/16 with --substeps 1,4,16,64 give
///    substeps h/1 … h/1024: 0.19 … 2.7e-3 m at h/256 and ≈ 6.7e-4 m at h/1024.
///  - pd, pd/chebyshev: h, h/4, h/16 with --iterations 1,4,16,64: implicit
///    Euler's floor 2.2e-2, 5.9e-3, 1.5e-3 m, reached in 16, 16 and 4
///    iterations; one iteration gives 2.2e-2, 1.8e-3, 1.2e-3 m
///    (docs/notes/work-precision.md, "pd").
///  - vbd, vbd/chebyshev: a sweep costs 0.22 ms at 400 particles (6× a
///    pd iteration) and the default run's budget holds 1 and 4 sweeps at
///    h, h/4, h/16 (10,500 sweeps per row, 2.3 s), their own counts: at
///    h = 0.01 s 1 and 4 sweeps gain energy (energy_growth) and 16, 64
///    give 0.23, 0.11 m; at h/4 9.8e-2 … 5.9e-3 m (1 … 64); at h/16
///    4.8e-2, 2.5e-3, 1.5e-3 m with 1, 4, 16 (the floor); with Chebyshev
///    the same within 20 % (`bench_integrators --integrators
///    vbd,vbd/chebyshev --h 0.01,0.0025,0.000625`, docs/notes/work-precision.md,
///    "vbd").
///  - sbdf3: 4.2e-1, 4.6e-2, 1.7e-4, 2.2e-5 m at h, h/2, h/4, h/8; at h and
///    h/2 it gains energy (+294 W and +2.2 W: BDF3 is not A-stable), so its
///    rows start at h/4.
///  - cvode, sbdf2/error, bdf2/newton/error: rtol 1e-2 … 1e-7; arkode
///    1e-2 … 1e-6 (its error is 1.7e-4 m already at rtol 1e-3; rtol 1e-7
///    alone costs 9.6 s).
///  - arkode/ark4 (ARK436L2SA): 1.1e-3, 2.9e-5, 1.7e-6, 1.4e-7, 1.2e-8 m at
///    rtol 1e-2 … 1e-6; arkode/ark5 (ARK548L2SA): 2.0e-5 m at rtol 1e-2
///    with 51 error-test failures, then 1.5e-6, 7.7e-7, 6.6e-9, 5.5e-10 m at
///    rtol 1e-3 … 1e-6 (below ~1e-9 m the CVODE reference at rtol 1e-10 is
///    the limit). `bench_integrators --integrators
///    sbdf2,sbdf3,arkode,arkode/ark4,arkode/ark5,cvode` with sbdf3 at
///    h … h/8 and the arkode rows at rtol 1e-2 … 1e-7.
struct DefaultParams {
  std::vector<double> h_factors;  ///< fixed-step and substepped rows: h = factor × scene h
  std::vector<double> rtols;      ///< adaptive rows
  std::vector<int> iterations;    ///< iterated rows without --iterations (empty: kDefaultIterations)
};

/// The iteration counts of an iterated row without --iterations, unless
/// its DefaultParams name its own.
inline const std::vector<int> kDefaultIterations = {1, 4, 16, 64};

/// One row of the default run, in table order, with its parameters.
struct DefaultRow {
  std::string_view label;
  DefaultParams params;
  /// The Newton row of a fully implicit method, listed beside its
  /// fixed-point row unless the command line names the nonlinear solver or
  /// the scene already uses Newton (then the row above it is the Newton row).
  bool newton_variant = false;
};

/// The default run's rows (plan.h: DefaultRowNames) and their parameters
/// (the measurements above).
inline const std::vector<DefaultRow>& DefaultRows() {
  static const std::vector<double> kRtols = {1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7};
  static const std::vector<double> kArkodeRtols = {1e-2, 1e-3, 1e-4, 1e-5, 1e-6};
  static const std::vector<DefaultRow> rows = {
      {"imex_euler", {{1.0, 1.0 / 4, 1.0 / 16, 1.0 / 64}, {}, {}}},
      {"implicit_euler", {{1.0 / 8, 1.0 / 16, 1.0 / 32}, {}, {}}},
      {"implicit_euler/newton", {{1.0, 1.0 / 2, 1.0 / 4}, {}, {}}, true},
      {"sbdf2", {{1.0, 1.0 / 2, 1.0 / 4, 1.0 / 8, 1.0 / 16}, {}, {}}},
      {"bdf2", {{1.0, 1.0 / 2, 1.0 / 4, 1.0 / 8}, kRtols, {}}},
      {"bdf2/newton", {{4.0, 2.0, 1.0}, {}, {}}, true},
      {"implicit_midpoint", {{1.0, 1.0 / 2, 1.0 / 4}, {}, {}}},
      {"implicit_midpoint/newton", {{4.0, 2.0, 1.0}, {}, {}}, true},
      {"sbdf3", {{1.0 / 4, 1.0 / 8, 1.0 / 16}, {}, {}}},
      {"baraff_witkin", {{1.0 / 8, 1.0 / 32}, {}, {}}},
      {"blender", {{1.0 / 8, 1.0 / 32}, {}, {}}},
      {"xpbd", {{1.0, 1.0 / 16}, {}, {}}},
      {"pd", {{1.0, 1.0 / 4, 1.0 / 16}, {}, {}}},
      {"pd/chebyshev", {{1.0, 1.0 / 4, 1.0 / 16}, {}, {}}},
      {"vbd", {{1.0, 1.0 / 4, 1.0 / 16}, {}, {1, 4}}},
      {"vbd/chebyshev", {{1.0, 1.0 / 4, 1.0 / 16}, {}, {1, 4}}},
      {"sbdf2/error", {{}, kRtols, {}}},
      {"bdf2/newton/error", {{}, kRtols, {}}},
      {"arkode", {{}, kArkodeRtols, {}}},
      {"arkode/ark4", {{}, kArkodeRtols, {}}},
      {"arkode/ark5", {{}, {1e-3, 1e-4, 1e-5, 1e-6}, {}}},
      {"cvode", {{}, kRtols, {}}},
      {"cvode/klu", {{}, kRtols, {}}},
  };
  return rows;
}

inline DefaultParams DefaultRowParams(const RowMethod& m) {
  const std::string label = m.label();
  for (const DefaultRow& d : DefaultRows())
    if (d.label == label) return d.params;
  return {{1.0, 1.0 / 2, 1.0 / 4, 1.0 / 8}, {1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7}, {}};
}

/// Parses "fixed_point" | "newton". @throws std::invalid_argument naming `option`.
inline NonlinearSolver ParseNonlinearSolver(const std::string& s, const std::string& option) {
  for (NonlinearSolver n : {NonlinearSolver::kFixedPoint, NonlinearSolver::kNewton})
    if (s == ToString(n)) return n;
  throw std::invalid_argument(fmt::format("{}: \"{}\" must be fixed_point or newton", option, s));
}

/// One RowMethod per name; a fully implicit method without a solver in its
/// name gives one row per solver in `solvers` (in that order). A name may
/// carry modifiers: "bdf2/newton", "sbdf2/error", "bdf2/newton/error".
/// @param kinds if non-empty, the step kinds the caller can run (others are
///              refused, naming `option`)
/// @throws std::invalid_argument for an unknown name, solver or modifier.
std::vector<RowMethod> ExpandMethods(const std::vector<std::string>& names, const std::vector<NonlinearSolver>& solvers,
                                     const std::string& option, const std::vector<StepKind>& kinds = {});

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_METHODS_H_
