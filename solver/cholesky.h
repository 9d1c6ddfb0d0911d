// Sparse Cholesky factor of the N×N system matrix A_α through CHOLMOD
// (SuiteSparse), the direct preconditioner of the filtered PCG (docs/model.md §5:
// "a CHOLMOD factorisation of the unconstrained A_α, reused while h is
// constant"). The symbolic analysis (fill-reducing ordering, supernodes) is
// done once per pattern; the numeric factorisation is repeated only when the
// values change (αh changes).
#ifndef CLOTHBENCH_SOLVER_CHOLESKY_H_
#define CLOTHBENCH_SOLVER_CHOLESKY_H_

#include <memory>
#include <vector>

#include "model/solver_spec.h"
#include "model/types.h"

namespace clothbench {

/// L Lᵀ = P A_F Pᵀ, where A_F is A with the rows and columns of the fixed
/// particles decoupled (off-diagonal entries dropped, diagonal kept).
/// A fixed particle constrains all three directions alike, so
/// S_F A S_F + (I − S_F) diag(A) is again an N×N matrix ⊗ I₃ and its factor
/// is exact for the filtered system of a scene without contacts: the PCG
/// converges in one iteration. Contacts (one direction per particle) change
/// S from step to step; for them the factor is a preconditioner.
/// Not copyable (owns CHOLMOD objects). No allocation in Solve after the
/// first call.
class CholeskyFactor {
 public:
  CholeskyFactor();
  ~CholeskyFactor();
  CholeskyFactor(const CholeskyFactor&) = delete;
  CholeskyFactor& operator=(const CholeskyFactor&) = delete;

  /// Symbolic analysis of the pattern of `a` (N×N, symmetric, both triangles
  /// stored) with the given fill-reducing ordering. Allocates.
  /// @param fixed sorted indices of the particles to decouple (may be empty)
  /// @return false if CHOLMOD failed (out of memory).
  bool Analyze(const SparseMatrix& a, const std::vector<int>& fixed, CholeskyOrdering ordering);
  /// Numeric factorisation of `a` (same pattern as analysed). Returns false
  /// if A_F is not positive definite or CHOLMOD failed.
  bool Factorize(const SparseMatrix& a);
  /// z ← A_F⁻¹ r for the three columns at once. @param r, z N×3.
  void Solve(const MatrixN3& r, MatrixN3* z) const;

  /// Nonzeros of the factor L (after Factorize), and whether CHOLMOD chose
  /// a supernodal factor.
  long factor_nonzeros() const;
  bool supernodal() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_CHOLESKY_H_
