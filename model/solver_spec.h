// The solver settings of a scene (its [solver] table): plain data that the
// scene parser fills and validates, and that only the solver layers read
// (solver/, peers/, reference/, the harness). Kept apart from the scene's
// model (grid, material, forces) so that a solver header depends on these
// settings and not on the whole scene. docs/model.md §5–6, docs/guide/scenes.md.
#ifndef CLOTHBENCH_MODEL_SOLVER_SPEC_H_
#define CLOTHBENCH_MODEL_SOLVER_SPEC_H_

#include <array>
#include <string>
#include <string_view>

namespace clothbench {

/// Preconditioner of the filtered PCG (docs/model.md §5): none, Jacobi (diag(A) ⊗ I₃),
/// IC(0) of A_α (the thesis' choice), a sparse Cholesky factor from CHOLMOD
/// ("cholesky"), or one V-cycle of algebraic multigrid from hypre BoomerAMG
/// ("amg"), or the contact policy "auto": the Cholesky factor without
/// contacts and, in contact, the factor with contact factors or the
/// prefiltered AMG, whichever the counted cost of its last steps favours
/// (Preconditioner, solver/pcg.h).
enum class PreconditionerType { kNone, kJacobi, kIc0, kCholesky, kAmg, kAuto };
/// Whether the type preconditions with A_α's factor or hierarchy
/// ("cholesky", "amg", "auto"): the 3N×3N tangent systems of Newton,
/// Baraff–Witkin and the SUNDIALS rows then apply it to the three columns.
inline bool UsesAlphaPreconditioner(PreconditionerType t) {
  return t == PreconditionerType::kCholesky || t == PreconditionerType::kAmg || t == PreconditionerType::kAuto;
}
/// Fill-reducing ordering of the CHOLMOD factor (solver key cholesky_ordering).
enum class CholeskyOrdering { kMetis, kAmd };
/// Frames of the prefiltered AMG's hierarchy (solver key amg_frames;
/// Preconditioner::FrameMode in solver/pcg.h): each setup in the frame mode
/// with the fewer V-cycles per solve ("adaptive"), or always in one.
enum class AmgFrames { kAdaptive, kNearestAxis, kSpread };
enum class Predictor { kConstantVelocity, kExtrapolate };
enum class StepControl { kFixed, kIterations, kError };
/// What the PCG tolerance is relative to (docs/model.md §5 and its deviation below).
/// kFiltered: ‖S b‖₂ over every constraint, docs/model.md §5 literally.
/// kFixedOnly: ‖S_F b‖₂, where S_F filters only the fixed (bilateral)
/// particles and not the collision constraints. At resting contact the filter
/// removes the whole load (gravity and the obstacle's reaction both act along
/// D), so ‖S b‖ → 0 and η‖S b‖ falls below round-off: the thesis' fixed-point
/// rule "PCG needed 0 iterations" can then never hold (measured: a flat cloth
/// resting on a plane, BDF(2), 50 updates and a rejected step every step).
/// ‖S_F b‖ keeps the load the obstacle carries in the scale. Without
/// obstacles both are the same number.
enum class CgReference { kFixedOnly, kFiltered };
/// Nonlinear solver of the fully implicit methods (implicit Euler, BDF(2),
/// implicit midpoint). "fixed_point": Alg. 6, the thesis' simplified Newton
/// method with the linear part A_α as matrix (thesis §3.4.3). "newton": Newton's
/// method with the tangent system J_α = M − αh ∂f/∂v − α²h² ∂f/∂x (docs/model.md §10).
enum class NonlinearSolver { kFixedPoint, kNewton };
/// When Newton refreshes J_α: at every iterate ("refresh"), or once per step
/// at the predictor ("frozen", a chord method).
enum class NewtonJacobian { kRefresh, kFrozen };
/// How the tangent system treats compressed springs (solver/tangent.h):
/// "clamp" keeps J_α definite with the transverse factor max(0, 1 − l_e/|d|)
/// (Choi & Ko 2002); "none" is the exact spring Jacobian.
enum class TangentProjection { kClamp, kNone };
/// What a multistep method (SBDF(2), BDF(2), SBDF(3)) does with its history
/// at the obstacles (docs/notes/collisions.md, "Multistep history across contact
/// events"):
///  - "keep": nothing (the thesis' response (4.4) acts on the current step only);
///  - "restart": the one-step start, as after Reset, whenever the set of
///    colliding particles changes between steps;
///  - "project": each constrained particle's history (x₋ₖ, v₋ₖ) is projected
///    along its collision direction D onto a constant normal velocity equal
///    to the response's target, so that the method's position formula moves
///    it along D as the one-step update does, by h·target;
///  - "land": the target velocity is taken from the method's own position
///    formula x₁ = x̂ + γ h v₁, so that the particle moves along D by
///    h·target (4.4) with the history kept: an entering particle lands on δ.
enum class ContactHistory { kKeep, kRestart, kProject, kLand };

/// Coulomb friction at the obstacles (docs/notes/collisions.md, "Friction laws"):
///  - "explicit": the thesis' impulse μ J_hold from the last step, against
///    the tangential velocity v_t at the step's start and capped at m|v_t|
///    (docs/model.md §2.5). A particle it stops is set moving again by the
///    step's tangential forces, at h F_t/m: static friction is a viscous
///    one whose slip velocity shrinks with h;
///  - "regularised": the same impulse scaled by min(1, |v_t|/v_s), the
///    regularised Coulomb law of the contact problem in continuous time
///    (kSlipVelocity; docs/notes/collisions.md, "Contact in continuous time") that
///    the SUNDIALS rows integrate, so that a fixed-step method converges to
///    the same problem as they do (the contact reference's cross-check);
///  - "implicit": Coulomb's force evaluated at the step's end velocity with
///    its rate lagged, F_t = −c_p (v₁ − u)_t, c_p = μ J_N / (h max(|w_t|,
///    kStickVelocity)) from the last step's J_N and the slip w_t at the
///    step's start: a damping in the step's matrix (A_α, or Baraff–Witkin's
///    J) that ties a particle to the obstacle inside the solve, where the
///    implicit springs and damping tie it to its neighbours. A damping
///    toward the obstacle's velocity cannot reverse a slip, so it takes no
///    cap (friction_cap stays "mass"). The
///    explicit laws converge in h only once h is below the time scale m/d
///    of the damping between neighbours; this one from the first h
///    (docs/notes/collisions.md, "Implicit friction"). Thesis methods and
///    Baraff–Witkin (and Blender); PD and VBD are refused (unsupported_scene);
///  - "implicit_iterated": the same force with its rate taken again from the
///    solve's own slip, c_p = μ J_N / (h |(v₁ − u)_t|), and the step solved
///    again, while a contact that still slides (|(v₁ − u)_t| > v_ε) gets
///    less than μ J_N (1 − η) (η the CG tolerance), within the active
///    set's kHoldRevisions solves: Coulomb's sliding force μ J_N where
///    "implicit" gives μ J_N |v₁_t|/|w_t|, less wherever the slip falls
///    within the step (a landing's impact). The same methods.
enum class FrictionLaw { kExplicit, kRegularised, kImplicit, kImplicitIterated };

/// Whether the law puts the friction into the step's solve ("implicit",
/// "implicit_iterated").
inline bool IsImplicit(FrictionLaw f) { return f == FrictionLaw::kImplicit || f == FrictionLaw::kImplicitIterated; }

/// What caps a step's friction impulse against the tangential velocity v_t
/// (docs/model.md §2.5; docs/notes/collisions.md, "The friction cap"):
///  - "mass": m|v_t|, the impulse that stops the particle alone;
///  - "system": a_t|v_t| with a_t = m_p + Σ_q w_q m_q/(m_q + w_q) over p's
///    couplings w_q = −A_pq in the step's matrix (A_α, or Baraff–Witkin's J
///    along t = v_t/|v_t|; ContactResponse::CapBySystem): between m and the
///    impulse that stops p in the solve, 1/(A⁻¹)_pp, so it never reverses
///    p when p is the only particle capped (a bound for the M-matrix A_α,
///    an estimate for J). Neighbours capped in the same step add their
///    impulses, and a region sliding as one gets Σ a_t|v_t| > Σ m|v_t|:
///    more than stops it. On scenes/sticking_slope.toml friction does
///    positive work in 10–30 % of the steps with it, in none with "mass".
///    A_α → M as h → 0, so both caps are one law in the limit;
///    at a finite h the implicit springs and damping tie a particle to its
///    neighbours, and the mass cap stops less of the cloth's motion than the
///    step's solve would, by an amount that shrinks only once h resolves
///    that coupling;
///  - "stiction": a particle the mass cap would stop is held instead: the
///    velocity filter constrains it in all three directions to the
///    obstacle's velocity (and (4.4) along the normal), the thesis' own
///    prescription for stiction (§2.6: constraints hold colliding particles
///    in place until a threshold is reached, then it is sliding friction).
///    The solve finds the impulse that holds every held particle at once;
///    when its tangential part exceeds μ J_N the particle slides in the
///    next step, with the friction impulse μ J_N along it. Not with
///    friction_law = "regularised", which has no sticking.
enum class FrictionCap { kMass, kSystem, kStiction };

/// The slip velocity v_s [m/s] below which the continuous contact problem's
/// Coulomb friction is regularised, F_t = −μ λ w_t / max(|w_t|, v_s)
/// (docs/notes/collisions.md, "Contact in continuous time").
inline constexpr double kSlipVelocity = 1e-3;

/// The slip velocity v_ε [m/s] below which FrictionLaw::kImplicit's rate
/// stops growing, c_p ≤ μ J_N/(h v_ε): a particle friction holds creeps at
/// below v_ε |F_t|/(μ |F_N|) (docs/notes/collisions.md, "Implicit friction").
inline constexpr double kStickVelocity = 1e-5;

std::string_view ToString(PreconditionerType p);
std::string_view ToString(CholeskyOrdering o);
std::string_view ToString(AmgFrames f);
std::string_view ToString(Predictor p);
std::string_view ToString(StepControl s);
std::string_view ToString(CgReference r);
std::string_view ToString(NonlinearSolver s);
std::string_view ToString(NewtonJacobian j);
std::string_view ToString(TangentProjection p);
std::string_view ToString(ContactHistory c);
std::string_view ToString(FrictionLaw f);
std::string_view ToString(FrictionCap f);

/// Settings of the step engine (docs/model.md §5, §6).
struct SolverSpec {
  double cg_tolerance = 1e-6;        ///< η: stop when ‖r‖₂ ≤ η ‖S_F b‖₂ (docs/model.md §5, see CgReference)
  CgReference cg_reference = CgReference::kFixedOnly;  ///< the norm η is relative to
  int cg_max_iterations = 1000;      ///< a scene without the key gets max(1000, 4·max(nu, nv))
  /// The contact policy: the CHOLMOD factor (fastest on the thesis scenes
  /// and at scale) and in contact the factor with contact factors or the
  /// prefiltered AMG by their counted cost (docs/notes/performance.md, "The
  /// contact policy"); the thesis scenes name "ic0" explicitly.
  PreconditionerType preconditioner = PreconditionerType::kAuto;
  CholeskyOrdering cholesky_ordering = CholeskyOrdering::kMetis;  ///< "cholesky" only
  /// Contact-aware preconditioners (Preconditioner, solver/pcg.h): "cholesky"
  /// preconditions each column with a factor that also decouples the
  /// contacts along that axis; "amg" builds its hierarchy on the filtered
  /// 3N×3N matrix in contact frames (prefiltered AMG). Others: unused.
  bool contact_factors = true;
  AmgFrames amg_frames = AmgFrames::kAdaptive;  ///< "amg" with contact_factors only
  int max_updates = 20;              ///< fixed-point updates per step at most (Alg. 6); more: step rejected
  /// Iteration controller band (docs/model.md §6; thesis §3.4.3): h grows by step_factor when
  /// a step needed fewer than [0] updates and shrinks when it needed more than [1].
  std::array<int, 2> controller_updates = {3, 6};
  /// Fixed-point stop: 0 selects the thesis' rule (PCG needed 0 iterations);
  /// > 0 stops when max |Δv| ≤ tol [m/s] as well.
  double fixed_point_tolerance = 0.0;
  /// Alg. 6 (the default and the thesis' reference) or Newton with J_α.
  NonlinearSolver nonlinear_solver = NonlinearSolver::kFixedPoint;
  /// Newton: J_α at every iterate or once per step (docs/notes/newton.md).
  NewtonJacobian newton_jacobian = NewtonJacobian::kRefresh;
  TangentProjection tangent_projection = TangentProjection::kClamp;
  /// Multistep methods on scenes with obstacles: keep or restart the
  /// history when the contact set changes.
  ContactHistory contact_history = ContactHistory::kKeep;
  /// Scenes with obstacles and friction: the thesis' explicit capped impulse
  /// or the continuous contact problem's regularised law (FrictionLaw).
  FrictionLaw friction_law = FrictionLaw::kExplicit;
  /// The friction impulse's cap (FrictionCap): the thesis' methods and Baraff–Witkin.
  FrictionCap friction_cap = FrictionCap::kMass;
  /// Newton and Baraff–Witkin: the explicit terms' Jacobians (shear, bending,
  /// transverse, air) enter J_α; false: tension and mass only.
  bool tangent_explicit_terms = true;
  Predictor predictor = Predictor::kConstantVelocity;  ///< (3.25, 3.32)
  /// fixed h; the thesis' iteration-count controller (docs/model.md §6); or local
  /// error control of SBDF(2)/BDF(2) against rtol/atol (docs/notes/work-precision.md).
  StepControl step_control = StepControl::kFixed;
  double rtol = 1e-4;                ///< step_control = "error": relative tolerance
  /// step_control = "error": absolute tolerance [m for x, m/s for v]; 0: atol = rtol.
  double atol = 0.0;
  double AbsoluteTolerance() const { return atol > 0.0 ? atol : rtol; }
  double step_factor = 2.0;          ///< controller grow/shrink factor (> 1)
  /// [s] smallest step before a run fails (fixed steps and the iteration
  /// controller; under step_control = "error" only round-off bounds h, as
  /// CVODE's hmin = 0, and max_rejections ends a step that cannot pass).
  double h_min = 1e-6;
  double h_max = 0.0;                ///< [s] largest step of a controller; 0: scene h (iterations), t_end (error)
  int max_rejections = 10;           ///< successive rejected attempts before a run fails

  /// Ceres style: false with `error` naming the field, its value and the rule.
  bool IsValid(std::string* error) const;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_MODEL_SOLVER_SPEC_H_
