// SUNDIALS CVODE reference (SPEC §8): variable-order BDF with Newton
// iteration and KLU on the analytic sparse Jacobian, integrating
//   ẋ = v,  v̇ = M⁻¹ f(t, x, v)                                        (3.13)
// on the free degrees of freedom (fixed particles stay at rest). At
// rtol ≤ 1e-10 it produces the reference trajectory; at looser rtol it is a
// competitor row of the bench table.
#ifndef CLOTHBENCH_REFERENCE_CVODE_REFERENCE_H_
#define CLOTHBENCH_REFERENCE_CVODE_REFERENCE_H_

#include "reference/sundials_common.h"

namespace clothbench {

/// Integrates `system` from rest to options.t_end; frames by CVODE's dense
/// output (CVodeGetDky). Never throws for solver failure: see status.
RunSummary RunCvode(const ParticleSystem& system, const ReferenceOptions& options);

}  // namespace clothbench

#endif  // CLOTHBENCH_REFERENCE_CVODE_REFERENCE_H_
