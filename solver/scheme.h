// One integrator's formula inside the step engine (solver/integrator.h): the
// thesis' methods differ only in how a step's velocity system
//   A_α v₁ = b₀ + βh g(t_g, x̂_g + γ_g h v₁, v_g),  x₁ = x̂ + γ h v₁
// is set up from the current and past states (docs/model.md §4, thesis
// (3.22)–(3.36)), how the explicit terms g are taken, how many updates a
// step does and which formula starts a multistep method. Each integrator
// is one file in solver/schemes/ that defines its Scheme and its registry
// row (MethodEntry, solver/method_row.h); the engine holds the shared
// machinery (contacts, the PCG, the fixed point and Newton, error control)
// and asks its scheme, never its Method.
#ifndef CLOTHBENCH_SOLVER_SCHEME_H_
#define CLOTHBENCH_SOLVER_SCHEME_H_

#include <string_view>

#include <Eigen/Core>

#include "model/types.h"

namespace clothbench {

enum class Method;
class StepEngine;

/// The coefficients of one step's velocity system (docs/model.md §4):
/// A_α v₁ = b₀ + βh g(t_g, x_g, v_g) with x_g = x̂_g + γ_g h v₁, x₁ = x̂ + γh v₁.
struct StageCoefficients {
  double alpha = 1.0, beta = 1.0, gamma = 1.0, gamma_g = 1.0, t_g = 0.0;
  bool midpoint = false;  ///< implicit midpoint: g at the mean velocity
  /// A multistep formula's v̂ − v₀ = carry1 (v₀ − v₋₁) + carry2 (v₋₁ − v₋₂)
  /// (0: one-step, v̂ = v₀); the contact work counts what it carries
  /// (ContactResponse::ReadImpulses).
  double carry1 = 0.0, carry2 = 0.0;
};

/// What a formula reads to set up a step (N×3 states [m], [m/s]) and the
/// stage it fills. The past states are those of the accepted steps before
/// t₀ (x₋₁ at t₀ − h₋₁, x₋₂ at t₀ − h₋₁ − h₋₂); only those the scheme reads
/// (Scheme::past_steps) are meaningful.
struct Stage {
  double t = 0.0;      ///< t₀ [s]
  double h = 0.0;      ///< this step [s]
  double omega = 1.0;  ///< h/h₋₁ (1 without a past step)
  const Eigen::VectorXd* mass = nullptr;  ///< lumped masses [kg]
  const MatrixN3 *x0 = nullptr, *v0 = nullptr, *xm1 = nullptr, *vm1 = nullptr, *xm2 = nullptr, *vm2 = nullptr;
  MatrixN3 *xhat = nullptr, *vhat = nullptr;  ///< out: x̂, v̂ of the step
  MatrixN3* xg0 = nullptr;  ///< out: x̂_g, g's base point (fully implicit updates)
  MatrixN3* b0 = nullptr;   ///< out: b₀
  MatrixN3* tmp = nullptr;  ///< scratch
  /// The engine, for L x (StepEngine::LinearProduct: L_K or L_D as the
  /// engine applies them, less the couplings virtual particles removed).
  const StepEngine* engine = nullptr;
};

class Scheme {
 public:
  virtual ~Scheme() = default;
  /// IMEX: g explicit (from g₀ and its history, Extrapolate), one update a step.
  /// The method's registry name ("sbdf2"): its row's name (solver/schemes/).
  virtual std::string_view name() const = 0;
  virtual bool imex() const = 0;
  /// Updates a step does exactly (IMEX: 1; SBDF(3)'s midpoint start: 2), or
  /// 0: iterated to convergence (fixed point or Newton).
  virtual int exact_updates() const { return imex() ? 1 : 0; }
  /// Whether the step evaluates g₀ = g(t₀, x₀, v₀) (the IMEX methods, and
  /// a start step whose successor extrapolates from it).
  virtual bool evaluates_g0() const { return imex(); }
  /// Past steps the formula reads: 0 (one-step), 1 (x₋₁, v₋₁) or 2 (also x₋₂, v₋₂).
  virtual int past_steps() const { return 0; }
  /// Past values of g the extrapolation ĝ reads (SBDF(2): 1, SBDF(3): 2).
  virtual int past_g() const { return 0; }
  /// Whether step_control = "error" applies (the local error estimate of
  /// docs/notes/work-precision.md): SBDF(2), BDF(2).
  virtual bool error_controlled() const { return false; }
  /// Whether the step is explicit and the engine's velocity system is not
  /// used (symplectic Euler).
  virtual bool explicit_step() const { return false; }
  /// The formula this step takes with `past` accepted steps since the last
  /// restart (capped at 2) and `equal_steps` (h = h₋₁ = h₋₂): a multistep
  /// method's start steps. Default: this one.
  virtual const Scheme& ForStep(int past, bool equal_steps) const {
    (void)past;
    (void)equal_steps;
    return *this;
  }
  /// Sets x̂, v̂, x̂_g and b₀ of the step and returns its coefficients.
  virtual StageCoefficients Prepare(const Stage& s) const = 0;
  /// ĝ from g₀, g₋₁, g₋₂ (IMEX schemes; ω = h/h₋₁). Default: g₀.
  virtual void Extrapolate(const MatrixN3& g0, const MatrixN3& gm1, const MatrixN3& gm2, double omega,
                           MatrixN3* g) const {
    (void)gm1;
    (void)gm2;
    (void)omega;
    *g = g0;
  }
};

/// The scheme of `m` (solver/schemes/).
const Scheme& SchemeOf(Method m);

/// The Euler stage x₁ = x₀ + h v₁, A₁ v₁ = M v₀ − h L_K x₀ + h g, g at t₀
/// (`imex`) or at (t₀ + h, x₀ + h v₁, v₁), shared by IMEX and implicit Euler
/// (solver/schemes/implicit_euler.cc).
StageCoefficients EulerStage(const Stage& s, bool imex);
/// The BDF(2) stage with ω = s.omega (Bdf2Coefficients), shared by BDF(2)
/// and SBDF(2) (solver/schemes/bdf2.cc); `imex`: g's base point x̂_g is not set.
StageCoefficients Bdf2Stage(const Stage& s, bool imex);
/// The midpoint rule's stage, shared by implicit midpoint and SBDF(3)'s
/// start step (solver/schemes/implicit_midpoint.cc).
StageCoefficients MidpointStage(const Stage& s);

/// The schemes, for their start steps and SchemeOf (solver/schemes/*.cc).
const Scheme& ImexEulerScheme();
const Scheme& ImplicitEulerScheme();
const Scheme& Sbdf2Scheme();
const Scheme& Bdf2Scheme();
const Scheme& ImplicitMidpointScheme();
const Scheme& Sbdf3Scheme();
const Scheme& SymplecticEulerScheme();

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_SCHEME_H_
