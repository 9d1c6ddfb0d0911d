// ARKODE ARKStep (SUNDIALS 6.4) as the adaptive IMEX Runge–Kutta peer of the
// SBDF family (docs/model.md §8, §10). On y = (x, v) of the free particles,
//   f_I(y) = (v, M⁻¹(−L_K x − L_D v))   implicit, declared linear (ARKStepSetLinear)
//   f_E(t, y) = (0, M⁻¹ g(t, x, v))     explicit
// (the split of (3.20); fixed particles are not unknowns, as in the CVODE
// reference). The stage systems (I − γ J_I) δ = r are solved by a custom
// SUNLinearSolver that eliminates δx = r_x + γ δv:
//   (M + γ L_D + γ² L_K) δv = M r_v − γ L_K r_x,
// the step engine's A_α with αh = γ, solved by the filtered PCG with the
// scene's preconditioner, stopping at ARKLS's own tolerance for iterative
// solvers in ARKODE's weighted norm (sundials/sundials_common.h,
// PcgStopForTolerance).
#ifndef CLOTHBENCH_PEERS_ARKODE_H_
#define CLOTHBENCH_PEERS_ARKODE_H_

#include <string>
#include <vector>

#include "model/particle_system.h"
#include "sundials/sundials_common.h"

namespace clothbench {

inline constexpr const char* kArkodeName = "arkode";

/// The ARK IMEX pairs of SUNDIALS 6.4 by name: ARK324L2SA (order 3, the
/// default), ARK436L2SA, ARK437L2SA (4), ARK548L2SA, ARK548L2SAb (5).
const std::vector<std::string>& ArkodeTableNames();

/// Integrates `system` from rest to options.t_end at rtol/atol of `options`
/// with the IMEX pair `table`; frames by ARKStepGetDky. Stats: nst, nfe
/// (explicit f_E evaluations), nfe_i (implicit), nni, nli (our PCG
/// iterations), netf, ncfn, nsetups. On scenes with obstacles it
/// integrates the hybrid contact problem (sundials/hybrid_contact.h;
/// docs/notes/collisions.md, "Contact in continuous time"): a sliding particle's
/// normal part of f_I moves to f_E as the constraint's acceleration
/// (HybridContact::SplitExplicit, SplitImplicit), its friction stays in
/// f_I, events are roots (ARKStepRootInit) followed by ARKStepReset, and
/// the step is at most the frame interval (roots are sought between step
/// ends only). `events` counts them.
/// @param solver the PCG's tolerance, limits and preconditioner; nullptr:
///               the scene's
/// @throws std::invalid_argument for an unknown table name.
RunSummary RunArkode(const ParticleSystem& system, const ReferenceOptions& options,
                          const std::string& table = "ARK324L2SA", const SolverSpec* solver = nullptr);

}  // namespace clothbench

#endif  // CLOTHBENCH_PEERS_ARKODE_H_
