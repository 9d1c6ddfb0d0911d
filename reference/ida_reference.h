// SUNDIALS IDA reference (docs/model.md §8): the residual form
//   F(t, y, ẏ) = [ẋ − v ; M v̇ − f(t, x, v)]
// over all particles, with fixed particles as algebraic equations
// x_p − x_p^rest = 0, v_p = 0 (IDASetId, IDASetSuppressAlg), variable-order
// BDF with Newton/KLU on the analytic sparse Jacobian dF/dy + c_j dF/dẏ.
// Consistent initial conditions at rest: ẋ = 0, v̇ = M⁻¹ f(0, x₀, 0).
// A second reference that must agree with CVODE within the tolerances.
#ifndef CLOTHBENCH_REFERENCE_IDA_REFERENCE_H_
#define CLOTHBENCH_REFERENCE_IDA_REFERENCE_H_

#include "sundials/sundials_common.h"

namespace clothbench {

/// The method's name (IdaRow, at the end of reference/ida_reference.cc).
inline constexpr const char* kIdaName = "ida";

/// Integrates `system` from rest to options.t_end; frames by IDA's dense
/// output (IDAGetDky). Never throws for solver failure: see status.
RunSummary RunIda(const ParticleSystem& system, const ReferenceOptions& options);

/// The same IDA integration with the reduced velocity solve (row `ida`,
/// docs/model.md "CVODE's reduced solve"): with γ = 1/c_j the Newton system
/// dF/dy + c_j dF/dẏ reduces on the free particles to
///   (M − γ ∂f/∂v − γ² ∂f/∂x) δv = γ r_v + γ² ∂f/∂x w + γ ∂f/∂v u,
/// δx = γ (r_x + δv), w = r_x (free) or r_x/γ (fixed), u = r_v on the fixed
/// particles, whose rows are δx = r_x, δv = r_v. Solved by the filtered PCG
/// on the closed-form tangent with `spec.preconditioner`, refactorised and
/// with a new Jacobian at IDA's setups, stopping at IDALS's own tolerance.
RunSummary RunIdaReduced(const ParticleSystem& system, const ReferenceOptions& options, const SolverSpec& spec);

}  // namespace clothbench

#endif  // CLOTHBENCH_REFERENCE_IDA_REFERENCE_H_
