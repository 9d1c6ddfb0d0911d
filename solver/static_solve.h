// Static equilibrium f(x, v = 0) = 0 of the same discrete equations the
// integrators solve (docs/model.md §9 chapter 2: "a static solve of the same
// discrete equations"). Newton's method on the free coordinates with the
// analytic sparse Jacobian (ParticleSystem::ForceJacobian), Eigen's SparseLU,
// an adaptive Levenberg–Marquardt shift λ = rel·max|K_ii| for modes without
// stiffness (a tension-only sheet has zero in-plane shear stiffness; their
// forces are zero, so the shift does not move the solution), and
// backtracking on ‖f‖. For nearly inextensible sheets start near the
// solution: a linearised step from the flat state stretches stiff fibres at
// second order, and the line search then shrinks every step.
#ifndef CLOTHBENCH_SOLVER_STATIC_SOLVE_H_
#define CLOTHBENCH_SOLVER_STATIC_SOLVE_H_

#include <string>
#include <vector>

#include "model/particle_system.h"

namespace clothbench {

struct StaticOptions {
  /// Stop when max|f_free| ≤ max(tolerance · max|m g|, round-off floor), the
  /// floor being 256 ε times the larger of the largest single force
  /// contribution (L_K x, F_nl, bending, …) and max s_e · max|x|: F_lin and
  /// F_nl of a spring are each ≈ s_e l_e and cancel, and a spring force
  /// inherits s_e times the round-off of the absolute positions.
  double tolerance = 1e-9;
  /// Also converged when the Newton step max|Δx| ≤ step_tolerance [m] while
  /// max|f| ≤ 1e-6 · max|m g|: the iterate then sits at the round-off floor
  /// of the force evaluation (4th differences of positions amplify it).
  double step_tolerance = 1e-12;
  int max_iterations = 200;
  double shift = 1e-10;      ///< initial relative Levenberg–Marquardt shift (adapted)
};

struct StaticSummary {
  bool converged = false;
  int iterations = -1;
  double residual = -1.0;  ///< final max|f_free| [N]
  double threshold = -1.0; ///< the stopping threshold used [N]
  std::string message;
};

/// Solves f(x, 0) = 0 for the coordinates of free particles that are not in
/// `constrained` (indices 3p + c, e.g. the z of a roller), starting from x.
/// @param x N×3 positions [m]: initial guess in, equilibrium out.
StaticSummary SolveStatic(const ParticleSystem& system, const std::vector<int>& constrained, const StaticOptions& options,
                          MatrixN3* x);

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_STATIC_SOLVE_H_
