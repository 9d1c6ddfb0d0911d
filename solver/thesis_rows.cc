// The rows of the thesis' integrators and symplectic Euler (StepEngine,
// solver/integrator.h), as the registry lists them (harness/registry.cc),
// with the measurements behind their default parameters and the statuses
// that belong to them.
#include <memory>

#include "solver/method_row.h"

namespace clothbench {
namespace {

template <Method M>
std::unique_ptr<Stepper> MakeEngine(const ParticleSystem& sys, const SolverSpec& spec, int /*count*/,
                                    std::string_view /*variant*/) {
  return std::make_unique<StepEngine>(sys, M, spec);
}

// Why implicit midpoint ends `penetration` at a large h (docs/notes/collisions.md,
// "Implicit midpoint at the obstacles").
constexpr std::string_view kMidpointPenetration =
    "implicit_midpoint rows, penetration: the contact response prescribes the normal velocity v1 at the step's end, "
    "and the midpoint rule moves a particle by h (v0 + v1)/2, so an entering particle travels h|<v0, D>|/2 past where "
    "the response aims it; once that exceeds twice the collision distance delta (h > 4 delta/|<v0, D>|) it can end "
    "deeper than delta. A property of the method with this response (docs/notes/collisions.md, \"Implicit midpoint at the "
    "obstacles\").";

// Why SBDF(2) and BDF(2) end `penetration` at a large h with the history
// kept (docs/notes/collisions.md, "BDF(2) at the obstacles").
constexpr std::string_view kMultistepPenetration =
    "sbdf2/bdf2 rows, penetration: with contact_history = \"keep\" (the default) the multistep formula x1 = (4 x0 - "
    "x-1)/3 + 2h v1/3 carries the last step's displacement on, so in the step after an entry a particle moves about "
    "h|<v0, D>|/3 toward the obstacle whatever v1 the response sets, and it can end deeper than the collision "
    "distance delta once h > 6 delta/|<v0, D>|. A property of the method with this response; contact_history = "
    "\"project\" or \"land\" removes it (docs/notes/collisions.md, \"BDF(2) at the obstacles\").";

}  // namespace

// Default parameters: chosen on the default scene (the swinging sheet,
// h = 0.01 s) so that each row's runs bracket e_rms = 1e-3 m where that
// fits the default run's time budget (docs/notes/work-precision.md).

/// IMEX Euler: 0.61, 0.39, 0.18, 0.060 m at h, h/4, h/16, h/64. Its error
/// is 0.017 m at h/256 (`bench_integrators --integrators
/// imex_euler,implicit_euler/newton --h 0.01,0.0025,6.25e-4,1.5625e-4,3.90625e-5`);
/// 1e-3 m would need h ≈ 2e-6 s (order 1), about 45 s of solver time, so
/// its rows do not bracket 1e-3 m.
MethodEntry ImexEulerRow() {
  return {.name = "imex_euler", .layer = "solver", .collisions = true, .pcg = true,
          .make = MakeEngine<Method::kImexEuler>, .best_preconditioner = kBestPreconditioner,
          .defaults = {{.modifiers = "", .h_factors = {1.0, 1.0 / 4, 1.0 / 16, 1.0 / 64}}}};
}

/// Implicit Euler: 3.0e-3, 1.5e-3, 7.5e-4 m at h/8, h/16, h/32 with the
/// fixed point (larger h cost more: fixed-point rejections); with Newton
/// 2.2e-2, 1.1e-2, 5.9e-3 m at h, h/2, h/4 (1e-3 m needs h ≈ 3e-4 s and
/// 15–20 s, a tangent refresh per iterate, so its rows do not bracket 1e-3 m).
MethodEntry ImplicitEulerRow() {
  return {.name = "implicit_euler", .layer = "solver", .nonlinear_solver = true, .collisions = true, .pcg = true,
          .make = MakeEngine<Method::kImplicitEuler>, .best_preconditioner = kBestPreconditioner,
          .defaults = {{.modifiers = "", .h_factors = {1.0 / 8, 1.0 / 16, 1.0 / 32}},
                       {.modifiers = "newton", .h_factors = {1.0, 1.0 / 2, 1.0 / 4}, .newton_variant = true}}};
}

/// SBDF(2): 4.4e-2 … 1.5e-3 m at h … h/8, and h/16 below 1e-3 m; under
/// error control (sbdf2/error) rtol 1e-2 … 1e-7.
MethodEntry Sbdf2Row() {
  return {.name = "sbdf2", .layer = "solver", .error_control = true, .collisions = true, .pcg = true,
          .make = MakeEngine<Method::kSbdf2>, .best_preconditioner = kBestPreconditioner,
          .defaults = {{.modifiers = "", .h_factors = {1.0, 1.0 / 2, 1.0 / 4, 1.0 / 8, 1.0 / 16}},
                       {.modifiers = "error", .rtols = kDefaultRtols}},
          .status_notes = {{"sbdf2", "penetration", kMultistepPenetration}}};
}

/// BDF(2) with the fixed point: 2.3e-4 m already at h; at larger h the
/// fixed point does not converge and the step is halved, so no run
/// reaches 1e-3 m. With Newton: 7.9e-3, 2.7e-3, 7.4e-4 m at 4h, 2h, h;
/// under error control (bdf2/newton/error) rtol 1e-2 … 1e-7.
MethodEntry Bdf2Row() {
  return {.name = "bdf2", .layer = "solver", .nonlinear_solver = true, .error_control = true, .collisions = true,
          .pcg = true, .make = MakeEngine<Method::kBdf2>, .self_convergence_reference = true,
          .best_preconditioner = kBestPreconditioner, .best_preconditioner_error = kBestPreconditioner,
          .defaults = {{.modifiers = "", .h_factors = {1.0, 1.0 / 2, 1.0 / 4, 1.0 / 8}, .rtols = kDefaultRtols},
                       {.modifiers = "newton", .h_factors = {4.0, 2.0, 1.0}, .newton_variant = true},
                       {.modifiers = "newton/error", .rtols = kDefaultRtols}},
          .status_notes = {{"bdf2", "penetration", kMultistepPenetration},
                           {"bdf2/newton", "penetration", kMultistepPenetration}}};
}

/// Implicit midpoint with the fixed point: 6.3e-5 m already at h (at larger
/// h the fixed point does not converge); with Newton 4.0e-3, 9.9e-4,
/// 2.5e-4 m at 4h, 2h, h.
MethodEntry ImplicitMidpointRow() {
  return {.name = "implicit_midpoint", .layer = "solver", .nonlinear_solver = true, .collisions = true, .pcg = true,
          .make = MakeEngine<Method::kImplicitMidpoint>, .best_preconditioner = kBestPreconditioner,
          .defaults = {{.modifiers = "", .h_factors = {1.0, 1.0 / 2, 1.0 / 4}},
                       {.modifiers = "newton", .h_factors = {4.0, 2.0, 1.0}, .newton_variant = true}},
          .status_notes = {{"implicit_midpoint", "penetration", kMidpointPenetration},
                           {"implicit_midpoint/newton", "penetration", kMidpointPenetration}}};
}

/// SBDF(3): 4.2e-1, 4.6e-2, 1.7e-4, 2.2e-5 m at h, h/2, h/4, h/8; at h and
/// h/2 it gains energy (+294 W and +2.2 W: BDF3 is not A-stable), so its
/// rows start at h/4 (`bench_integrators --integrators
/// sbdf2,sbdf3,arkode,arkode/ark4,arkode/ark5,cvode` with sbdf3 at h … h/8).
MethodEntry Sbdf3Row() {
  return {.name = "sbdf3", .layer = "solver", .collisions = true, .pcg = true, .make = MakeEngine<Method::kSbdf3>,
          .best_preconditioner = kBestPreconditioner,
          .defaults = {{.modifiers = "", .h_factors = {1.0 / 4, 1.0 / 8, 1.0 / 16}}}};
}

/// Symplectic Euler: the explicit baseline of the stability maps; not a
/// default row.
MethodEntry SymplecticEulerRow() {
  return {.name = "symplectic_euler", .layer = "solver", .collisions = true,
          .make = MakeEngine<Method::kSymplecticEuler>};
}

}  // namespace clothbench
