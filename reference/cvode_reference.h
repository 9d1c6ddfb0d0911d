// SUNDIALS CVODE reference (docs/model.md §8): variable-order BDF with Newton
// iteration and KLU on the analytic sparse Jacobian, integrating
//   ẋ = v,  v̇ = M⁻¹ f(t, x, v)                                        (3.13)
// on the free degrees of freedom (fixed particles stay at rest). At
// rtol ≤ 1e-10 it produces the reference trajectory; at looser rtol it is a
// competitor row of the bench table.
#ifndef CLOTHBENCH_REFERENCE_CVODE_REFERENCE_H_
#define CLOTHBENCH_REFERENCE_CVODE_REFERENCE_H_

#include <string>

#include "sundials/sundials_common.h"

namespace clothbench {

/// The method's name (CvodeRow, at the end of reference/cvode_reference.cc).
inline constexpr const char* kCvodeName = "cvode";

/// CVODE's linear-solver setup knobs (CVODE's defaults unless set), as a
/// SUNDIALS user would tune them (--cvode-setting, the cvode rows' own
/// setting); measured in docs/model.md.
struct CvodeSettings {
  long lsetup_frequency = 20;   ///< CVodeSetLSetupFrequency (msbp)
  long jac_eval_frequency = 51; ///< CVodeSetJacEvalFrequency (msbj)
  double dgmax_lsetup = 0.3;    ///< CVodeSetDeltaGammaMaxLSetup
  bool stab_lim_det = false;    ///< CVodeSetStabLimDet
  double eps_lin = 0.05;        ///< CVodeSetEpsLin (linear tolerance factor of iterative solvers)
  /// The velocities' absolute tolerance over the positions' [1/s]: atol_v =
  /// atol_v_scale · atol [m/s] (CVodeSVtolerances); 1 is CVODE's scalar
  /// atol for both (CVodeSStolerances).
  double atol_v_scale = 1.0;
  /// "lsetup_frequency=20,jac_eval_frequency=51,…": what a run stores.
  std::string ToString() const;
  /// Sets `key` (a field name above) from `value`; false with `error` if
  /// the key is unknown or the value out of range.
  bool Set(const std::string& key, const std::string& value, std::string* error);
  /// Sets every KEY=VALUE of the comma-separated `text` ("" sets none).
  /// @return "" or the rule the first bad item breaks, one line
  std::string Parse(const std::string& text);
};

/// Integrates `system` from rest to options.t_end; frames by CVODE's dense
/// output (CVodeGetDky). Never throws for solver failure: see status.
/// The Newton systems (I − γJ) δ = r are solved by KLU on the 6N×6N
/// first-order Jacobian (row `cvode/klu`, and the reference).
RunSummary RunCvode(const ParticleSystem& system, const ReferenceOptions& options, const CvodeSettings& settings = {});

/// The same CVODE integration with the reduced velocity solve (row `cvode`,
/// docs/model.md "CVODE's reduced solve"): a custom SUNLinearSolver
/// eliminates δx = r_x + γ δv from (I − γJ) δ = r and solves
///   (M − γ ∂f/∂v − γ² ∂f/∂x) δv = M r_v + γ ∂f/∂x r_x
/// with the filtered PCG on the closed-form tangent system (clamped and
/// symmetrised as `spec.tangent_projection` says) and `spec.preconditioner`,
/// to CVODE's own linear tolerance for iterative solvers. The Jacobian is evaluated when CVODE's setup
/// asks for it (jok false), the matrix follows γ, and the preconditioner is
/// refactorised at CVODE's setups only. Counters: nje = Jacobian
/// evaluations, nsetups = preconditioner setups, nli = PCG iterations.
RunSummary RunCvodeReduced(const ParticleSystem& system, const ReferenceOptions& options, const SolverSpec& spec,
                            const CvodeSettings& settings = {});

/// The first-order system's Jacobian J = [[0, I], [M⁻¹ ∂f/∂x, M⁻¹ ∂f/∂v]]
/// on the free DOFs y = [x_free; v_free] at rest (t = 0, x the rest
/// positions, v = 0), with its explicit zero diagonal: the pattern that
/// cvode/klu and ida/klu factorise (6 N_free × 6 N_free, compressed columns).
SparseMatrix FirstOrderJacobianAtRest(const ParticleSystem& system);

}  // namespace clothbench

#endif  // CLOTHBENCH_REFERENCE_CVODE_REFERENCE_H_
