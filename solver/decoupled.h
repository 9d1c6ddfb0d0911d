// The pattern of A_F, the matrix that the "cholesky" and "amg"
// preconditioners build (docs/model.md §5): A_α with the rows and columns of the
// fixed particles decoupled (their off-diagonal entries dropped, the
// diagonal kept). Internal to solver/.
#ifndef CLOTHBENCH_SOLVER_DECOUPLED_H_
#define CLOTHBENCH_SOLVER_DECOUPLED_H_

#include <vector>

#include "model/types.h"

namespace clothbench::internal {

/// Compressed columns of A_F (both triangles, or the upper one only), and
/// for each kept entry its position in A's values, so that new values of A
/// are copied in without a search.
struct DecoupledPattern {
  std::vector<int> outer;   ///< N + 1 column starts
  std::vector<int> inner;   ///< row index of each kept entry (sorted per column)
  std::vector<int> source;  ///< position of each kept entry in A.valuePtr()
};

/// @param a      N×N symmetric, both triangles stored, rows sorted
/// @param fixed  particles to decouple (any order)
/// @param upper_only keep rows i ≤ j only (CHOLMOD's stype = 1 storage)
inline DecoupledPattern DecoupleFixed(const SparseMatrix& a, const std::vector<int>& fixed, bool upper_only) {
  const int n = static_cast<int>(a.cols());
  std::vector<char> is_fixed(static_cast<std::size_t>(n), 0);
  for (int p : fixed) is_fixed[static_cast<std::size_t>(p)] = 1;
  DecoupledPattern d;
  d.outer.assign(static_cast<std::size_t>(n) + 1, 0);
  d.inner.reserve(static_cast<std::size_t>(a.nonZeros()));
  d.source.reserve(static_cast<std::size_t>(a.nonZeros()));
  for (int j = 0; j < n; ++j) {
    for (int pos = a.outerIndexPtr()[j]; pos < a.outerIndexPtr()[j + 1]; ++pos) {
      const int i = a.innerIndexPtr()[pos];
      if (upper_only && i > j) break;  // rows sorted: the rest is the lower triangle
      if (i != j && (is_fixed[static_cast<std::size_t>(i)] || is_fixed[static_cast<std::size_t>(j)])) continue;
      d.inner.push_back(i);
      d.source.push_back(pos);
    }
    d.outer[static_cast<std::size_t>(j) + 1] = static_cast<int>(d.inner.size());
  }
  return d;
}

}  // namespace clothbench::internal

#endif  // CLOTHBENCH_SOLVER_DECOUPLED_H_
