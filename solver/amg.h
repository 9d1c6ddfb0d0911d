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
/// preconditioner, as CG requires), strength threshold 0.25.
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

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_AMG_H_
