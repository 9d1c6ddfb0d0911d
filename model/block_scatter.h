// Closed-form Jacobians accumulated straight into a fixed compressed
// column-major 3N×3N pattern (docs/model.md, "Tangent assembly"): every
// force term lists the 3×3 blocks (row particle, column particle) it writes,
// the caller turns that list into value positions once, and the step loop
// only adds block values at those positions. The items that write blocks
// (stencil centres, springs) are chunked and the chunks coloured so that no
// two chunks of one colour write the same row particle: a colour runs on the
// OpenMP threads without write conflicts, colours run one after the other,
// and every entry is summed in the same order whatever the thread count
// (bit-identical).
// Colouring::ForEach is threaded in sources compiled with OpenMP.
#ifndef CLOTHBENCH_MODEL_BLOCK_SCATTER_H_
#define CLOTHBENCH_MODEL_BLOCK_SCATTER_H_

#include <algorithm>
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

/// Items grouped into chunks of consecutive items, and the chunks coloured
/// greedily so that no two chunks of one colour write the same row particle.
/// A colour's chunks run on the OpenMP threads, the items of a chunk in
/// order on one thread (consecutive stencil centres touch neighbouring
/// memory, so a chunk stays in cache); colours run one after the other.
/// Every entry is therefore summed in one fixed order for any thread count.
class Colouring {
 public:
  /// Items per chunk (the chunk size doubles until 64 colours suffice).
  static constexpr std::size_t kChunk = 512;

  Colouring() = default;
  /// @param num_particles N; @param items item count
  /// @param rows_per_item how many row particles each item writes
  /// @param row row(item, k), the k-th row particle of an item
  template <class RowOf>
  Colouring(int num_particles, std::size_t items, int rows_per_item, RowOf row) {
    for (chunk_ = kChunk;; chunk_ *= 2)
      if (TryColour(num_particles, items, rows_per_item, row)) return;
  }
  int num_colours() const { return static_cast<int>(starts_.size()) - 1; }

  /// Calls f(item) for every item, colour by colour; the chunks of a colour
  /// on the OpenMP threads when the items number at least
  /// `parallel_minimum`.
  template <class F>
  void ForEach(F f, std::ptrdiff_t parallel_minimum) const {
    const bool parallel = static_cast<std::ptrdiff_t>(items_) >= parallel_minimum;
    for (std::size_t c = 0; c + 1 < starts_.size(); ++c) {
      const auto begin = static_cast<std::ptrdiff_t>(starts_[c]), end = static_cast<std::ptrdiff_t>(starts_[c + 1]);
#ifdef _OPENMP
#pragma omp parallel for schedule(static) if (parallel && end - begin > 1)
#endif
      for (std::ptrdiff_t i = begin; i < end; ++i) {
        const std::size_t first = order_[static_cast<std::size_t>(i)] * chunk_;
        const std::size_t last = std::min(first + chunk_, items_);
        for (std::size_t item = first; item < last; ++item) f(item);
      }
    }
    (void)parallel;
  }

 private:
  template <class RowOf>
  bool TryColour(int num_particles, std::size_t items, int rows_per_item, RowOf row) {
    items_ = items;
    const std::size_t chunks = (items + chunk_ - 1) / chunk_;
    std::vector<std::uint64_t> used(static_cast<std::size_t>(num_particles), 0);
    std::vector<int> colour(chunks);
    int colours = 0;
    for (std::size_t k = 0; k < chunks; ++k) {
      const std::size_t first = k * chunk_, last = std::min(first + chunk_, items);
      std::uint64_t forbidden = 0;
      for (std::size_t i = first; i < last; ++i)
        for (int r = 0; r < rows_per_item; ++r) forbidden |= used[static_cast<std::size_t>(row(i, r))];
      if (forbidden == ~std::uint64_t{0}) return false;
      int c = 0;
      while ((forbidden >> c) & 1u) ++c;
      colour[k] = c;
      colours = std::max(colours, c + 1);
      for (std::size_t i = first; i < last; ++i)
        for (int r = 0; r < rows_per_item; ++r) used[static_cast<std::size_t>(row(i, r))] |= std::uint64_t{1} << c;
    }
    starts_.assign(static_cast<std::size_t>(colours) + 1, 0);
    for (int c : colour) ++starts_[static_cast<std::size_t>(c) + 1];
    for (std::size_t c = 0; c < static_cast<std::size_t>(colours); ++c) starts_[c + 1] += starts_[c];
    order_.resize(chunks);
    std::vector<std::size_t> fill(starts_.begin(), starts_.end() - 1);
    for (std::size_t k = 0; k < chunks; ++k) order_[fill[static_cast<std::size_t>(colour[k])]++] = k;
    return true;
  }

  std::size_t chunk_ = kChunk, items_ = 0;
  std::vector<std::size_t> starts_, order_;  // chunks by colour
};

/// Value positions of blocks in a compressed column-major matrix `m` whose
/// pattern holds them: 3 per block, the index of entry (3a, 3b + q) for
/// q = 0, 1, 2 (rows 3a + 1 and 3a + 2 follow it in its column).
/// @throws std::logic_error if a block is not in the pattern
std::vector<int> BlockPositions(const SparseMatrix& m, const std::vector<BlockPair>& blocks);

/// vals[pos[q] + r] += b(r, q): one block at its three column positions.
EIGEN_ALWAYS_INLINE void AddBlock(const Matrix3& b, const int* pos, double* vals) {
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
