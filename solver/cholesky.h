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

/// Rows from which the factor's solves and the per-particle loops around
/// them (frames, contact policy) use a second thread: each runs once per
/// PCG iteration, and below this its work is a fraction of a millisecond,
/// less than waiting for a thread whose core another process keeps busy
/// (at 10⁴ particles and 4096 rows, two threads beside a busy process made
/// SBDF(2)'s run on the fold 2x one thread; docs/notes/performance.md,
/// "Parallel regions on a busy machine").
inline constexpr long kParallelSolveRows = 65536;

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
  /// The same numeric factorisation with, in addition to the fixed
  /// particles, the rows and columns of every particle p with
  /// decoupled[p] ≠ 0 decoupled: their off-diagonal values are set to zero in
  /// the analysed pattern (no new analysis). nullptr: none (as Factorize).
  bool Factorize(const SparseMatrix& a, const std::vector<char>* decoupled);
  /// Decouples particle p in the factor the solves use (CHOLMOD's row
  /// delete, Davis & Hager 2005): it becomes the factor of the matrix whose
  /// row and column p are those of the identity. Cost: the part of the
  /// factor below p's path in the elimination tree, not a refactorisation.
  /// The first modification after a factorisation converts the factor to
  /// LDLᵀ (allocates). @return false if CHOLMOD failed.
  bool DecoupleRow(int p, const SparseMatrix& a);
  /// Couples particle p back (CHOLMOD's row add): row and column p of the
  /// factorised matrix become A_F's (values of `a`), without the entries of
  /// the particles q with decoupled[q] ≠ 0. Row p must be decoupled.
  /// @return false if CHOLMOD failed.
  bool CoupleRow(int p, const SparseMatrix& a, const std::vector<char>& decoupled);
  /// A factor with this one's symbolic analysis (ordering, pattern, value
  /// map), to be factorised with other decoupled particles; nullptr if
  /// CHOLMOD failed or this factor is not analysed. Allocates.
  std::unique_ptr<CholeskyFactor> CloneAnalysis() const;
  /// z ← A_F⁻¹ r for the three columns at once: one pass over L each way,
  /// the elimination tree's two halves on two threads (tree_solve()), else
  /// CHOLMOD's solve on two lanes. The same bits for any thread count.
  /// @param r, z N×3.
  void Solve(const MatrixN3& r, MatrixN3* z) const;
  /// Columns col0 … col0 + ncol − 1 of z ← A_F⁻¹ r, with the workspace of
  /// `lane` (0 or 1): two lanes may run at once on different columns.
  /// @return false if CHOLMOD failed (the columns are then NaN).
  bool SolveColumns(const MatrixN3& r, MatrixN3* z, int col0, int ncol, int lane) const;

  /// Nonzeros of the factor L (after Factorize), and whether CHOLMOD chose
  /// a supernodal factor.
  long factor_nonzeros() const;
  /// Floating-point operations of one numeric factorisation, as CHOLMOD's
  /// analysis counts them (cholmod_common::fl; 0 before Analyze).
  double factorization_flops() const;
  bool supernodal() const;
  /// Whether Solve runs the tree-parallel solve (a fresh simplicial LLᵀ
  /// copy whose elimination tree splits into two parts; docs/notes/performance.md)
  /// rather than CHOLMOD's solve.
  bool tree_solve() const;

 private:
  bool PrepareRow(long n, long nnz);  // room for one column of nnz entries
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_CHOLESKY_H_
