// Closed-form Jacobians accumulated straight into a fixed compressed
// column-major 3N×3N pattern (docs/model.md, "Tangent assembly"): every
// force term lists the 3×3 blocks (row particle, column particle) it writes,
// the caller turns that list into value positions once, and the step loop
// only adds block values at those positions. The items that write blocks
// (stencil centres, springs) are coloured so that no two items of one colour
// write the same row particle: a colour runs on the OpenMP threads without
// write conflicts, colours run one after the other, and every entry is
// summed in the same order whatever the thread count (bit-identical).
// Colouring::ForEach is threaded in sources compiled with OpenMP.
#ifndef CLOTHBENCH_MODEL_BLOCK_SCATTER_H_
#define CLOTHBENCH_MODEL_BLOCK_SCATTER_H_

#include <array>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>

#include <Eigen/Core>

#include "model/types.h"

namespace clothbench {

using Matrix3 = Eigen::Matrix3d;

/// Closed-form Jacobians run a colour on the OpenMP threads from this many
/// items (stencil centres, springs) up; an item costs about a microsecond.
constexpr std::ptrdiff_t kBlockParallelMinimum = 2048;

/// Greedy colouring of items by the row particles they write (at most 64
/// colours; a grid stencil needs at most 13). Items of one colour keep their
/// item order.
class Colouring {
 public:
  Colouring() = default;
  /// @param num_particles N; @param items item count
  /// @param rows_per_item how many row particles each item writes
  /// @param row row(item, k), the k-th row particle of an item
  /// @throws std::logic_error if more than 64 colours would be needed
  template <class RowOf>
  Colouring(int num_particles, std::size_t items, int rows_per_item, RowOf row) {
    std::vector<std::uint64_t> used(static_cast<std::size_t>(num_particles), 0);
    std::vector<int> colour(items);
    int colours = 0;
    for (std::size_t i = 0; i < items; ++i) {
      std::uint64_t forbidden = 0;
      for (int k = 0; k < rows_per_item; ++k) forbidden |= used[static_cast<std::size_t>(row(i, k))];
      if (forbidden == ~std::uint64_t{0}) throw std::logic_error("Colouring: more than 64 colours");
      int c = 0;
      while ((forbidden >> c) & 1u) ++c;
      colour[i] = c;
      colours = c + 1 > colours ? c + 1 : colours;
      for (int k = 0; k < rows_per_item; ++k) used[static_cast<std::size_t>(row(i, k))] |= std::uint64_t{1} << c;
    }
    starts_.assign(static_cast<std::size_t>(colours) + 1, 0);
    for (int c : colour) ++starts_[static_cast<std::size_t>(c) + 1];
    for (std::size_t c = 0; c < static_cast<std::size_t>(colours); ++c) starts_[c + 1] += starts_[c];
    order_.resize(items);
    std::vector<std::size_t> fill(starts_.begin(), starts_.end() - 1);
    for (std::size_t i = 0; i < items; ++i) order_[fill[static_cast<std::size_t>(colour[i])]++] = i;
  }
  int num_colours() const { return static_cast<int>(starts_.size()) - 1; }

  /// Calls f(item) for every item, colour by colour; inside a colour on the
  /// OpenMP threads when it has at least `parallel_minimum` items.
  template <class F>
  void ForEach(F f, std::ptrdiff_t parallel_minimum) const {
    for (std::size_t c = 0; c + 1 < starts_.size(); ++c) {
      const auto begin = static_cast<std::ptrdiff_t>(starts_[c]), end = static_cast<std::ptrdiff_t>(starts_[c + 1]);
#ifdef _OPENMP
#pragma omp parallel for schedule(static) if (end - begin >= parallel_minimum)
#endif
      for (std::ptrdiff_t i = begin; i < end; ++i) f(order_[static_cast<std::size_t>(i)]);
    }
  }

 private:
  std::vector<std::size_t> starts_, order_;
};

/// Value positions of blocks in a compressed column-major matrix `m` whose
/// pattern holds them: 3 per block, the index of entry (3a, 3b + q) for
/// q = 0, 1, 2 (rows 3a + 1 and 3a + 2 follow it in its column).
/// @throws std::logic_error if a block is not in the pattern
std::vector<int> BlockPositions(const SparseMatrix& m, const std::vector<BlockPair>& blocks);

/// vals[pos[q] + r] += b(r, q): one block at its three column positions.
inline void AddBlock(const Matrix3& b, const int* pos, double* vals) {
  for (int q = 0; q < 3; ++q) {
    double* d = vals + pos[q];
    d[0] += b(0, q);
    d[1] += b(1, q);
    d[2] += b(2, q);
  }
}

/// The skew matrix [a]× with [a]× w = a × w.
inline Matrix3 Skew(const Vector3& a) {
  Matrix3 s;
  s << 0.0, -a.z(), a.y(), a.z(), 0.0, -a.x(), -a.y(), a.x(), 0.0;
  return s;
}

}  // namespace clothbench

#endif  // CLOTHBENCH_MODEL_BLOCK_SCATTER_H_
