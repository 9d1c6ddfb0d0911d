// Algebraic multigrid preconditioner of the filtered PCG (docs/model.md §5): one
// V-cycle of hypre's BoomerAMG on the N×N matrix A_F (A_α with the fixed
// particles decoupled, as for the Cholesky factor), applied to each of the
// three coordinate columns. hypre links MPI; clothbench runs it as a single
// process (MPI is initialised on first use, no mpirun needed).
#ifndef CLOTHBENCH_SOLVER_AMG_H_
#define CLOTHBENCH_SOLVER_AMG_H_

#include <memory>
#include <vector>

#include "model/types.h"

namespace clothbench {

/// BoomerAMG with settings for a 2-D graph Laplacian plus mass: HMIS
/// coarsening, extended+i interpolation (at most 4 entries per row),
/// one hybrid symmetric Gauss–Seidel sweep down and up (a symmetric
/// preconditioner, as CG requires), strength threshold 0.25; from 2·10⁴
/// particles on the first level is coarsened aggressively, with 2-stage
/// extended+i interpolation there (solver/amg.cc, CoarsenAggressively).
/// Not copyable (owns hypre objects).
class AmgPreconditioner {
 public:
  AmgPreconditioner();
  ~AmgPreconditioner();
  AmgPreconditioner(const AmgPreconditioner&) = delete;
  AmgPreconditioner& operator=(const AmgPreconditioner&) = delete;

  /// Records the pattern of `a` (N×N, both triangles) and the particles
  /// to decouple. Allocates. @return false if MPI or hypre failed to start.
  bool Analyze(const SparseMatrix& a, const std::vector<int>& fixed);
  /// AMG setup (coarsening, interpolation, Galerkin products) for the values
  /// of `a`. Allocates inside hypre; called only when αh changes.
  bool Factorize(const SparseMatrix& a);
  /// z ← M⁻¹ r: one V-cycle from a zero guess, per column. @param r, z N×3.
  void Solve(const MatrixN3& r, MatrixN3* z) const;
  /// Number of levels of the last setup.
  int levels() const;

  /// The prefiltered hierarchy (Tamstorf, Jones & McCormick 2015, §4): the
  /// same settings in systems mode, three functions per node with nodal
  /// coarsening (the Frobenius norm of each 3×3 block), for the 3N×3N
  /// matrix K = S A S + (I − S) of the filtered system (4.3), given as CSR
  /// rows with the interleaved index 3p + c. Allocates.
  /// @param row_start 3N + 1 offsets, @param cols, values the entries of
  ///        each row (K symmetric, both triangles)
  /// @return false if hypre failed or the V-cycle is not finite.
  bool FactorizeSystem(int n_nodes, const std::vector<int>& row_start, const std::vector<int>& cols,
                       const std::vector<double>& values);
  /// Replaces the finest level's matrix of the prefiltered hierarchy by
  /// `values` (a K of the same size whose contacts changed since
  /// FactorizeSystem), keeping the coarse levels and the interpolation:
  /// BoomerAMG smooths and forms residuals with the matrix a V-cycle is
  /// given (hypre's BoomerAMGSolve sets its finest level to it), so the
  /// smoother sees the current constraints while the coarse correction is
  /// that of the hierarchy's. Allocates (a new hypre matrix).
  /// @return false if a row of K has no diagonal entry or no system
  /// hierarchy is set up.
  bool UpdateSystemFineLevel(int n_nodes, const std::vector<int>& row_start, const std::vector<int>& cols,
                             const std::vector<double>& values);
  /// The prefiltered hierarchy's asymptotic convergence factor as a
  /// stationary iteration: `cycles` V-cycles on K e = 0 from a fixed
  /// pseudo-random start, returning ‖e_k‖ / ‖e_{k−1}‖ (2-norm) of the last
  /// cycle, which tends to the spectral radius of I − M⁻¹K (the slowest
  /// error a V-cycle leaves). A diagnostic (contact_replay --cycle-factor);
  /// allocates nothing, overwrites the hierarchy's vectors.
  /// @return NaN if no system hierarchy is set up.
  double SystemCycleFactor(int cycles) const;
  /// z ← K⁻¹ r approximately: one V-cycle on the interleaved 3N vector.
  /// @param r, z N×3. NaN if no system hierarchy is set up.
  void SolveSystem(const MatrixN3& r, MatrixN3* z) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_AMG_H_
