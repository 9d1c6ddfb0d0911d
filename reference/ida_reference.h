// SUNDIALS IDA reference (SPEC §8): the residual form
//   F(t, y, ẏ) = [ẋ − v ; M v̇ − f(t, x, v)]
// over all particles, with fixed particles as algebraic equations
// x_p − x_p^rest = 0, v_p = 0 (IDASetId, IDASetSuppressAlg), variable-order
// BDF with Newton/KLU on the analytic sparse Jacobian dF/dy + c_j dF/dẏ.
// Consistent initial conditions at rest: ẋ = 0, v̇ = M⁻¹ f(0, x₀, 0).
// A second reference that must agree with CVODE within the tolerances.
#ifndef CLOTHBENCH_REFERENCE_IDA_REFERENCE_H_
#define CLOTHBENCH_REFERENCE_IDA_REFERENCE_H_

#include "reference/sundials_common.h"

namespace clothbench {

/// Integrates `system` from rest to options.t_end; frames by IDA's dense
/// output (IDAGetDky). Never throws for solver failure: see status.
RunSummary RunIda(const ParticleSystem& system, const ReferenceOptions& options);

}  // namespace clothbench

#endif  // CLOTHBENCH_REFERENCE_IDA_REFERENCE_H_
