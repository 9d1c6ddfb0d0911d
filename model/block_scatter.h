// Closed-form Jacobians accumulated straight into a fixed compressed
// row-major 3N×3N pattern (docs/model.md, "Tangent assembly"): every
// force term lists the 3×3 blocks (row particle, column particle) it writes,
// the caller turns that list into value positions once, and the step loop
// only adds block values at those positions. The items that write blocks
// (stencil centres, springs) are grouped into chunks of particles and the
// chunks coloured so that no two chunks of one colour write the same row
// particle: a colour runs on the OpenMP threads without write conflicts,
// colours run one after the other, and every entry is summed in the same
// order whatever the thread count (bit-identical).
// ChunkColouring::ForEach is threaded in sources compiled with OpenMP.
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


/// Closed-form Jacobians run on the OpenMP threads from this many particles
/// up; an item (stencil centre, spring) costs about a microsecond.
constexpr std::ptrdiff_t kBlockParallelMinimum = 2048;

/// Chunks of items (stencil centres and springs of a range of particles)
/// coloured greedily so that no two chunks of one colour write the same row
/// particle. A colour's chunks run on the OpenMP threads, each chunk's items
/// in order on one thread (neighbouring particles: a chunk's writes stay in
/// cache); colours run one after the other. Every entry is therefore summed
/// in one fixed order for any thread count.
class ChunkColouring {
 public:
  ChunkColouring() = default;
  /// @param num_particles N; @param chunks chunk count
  /// @param rows_of rows_of(chunk, visit) calls visit(p) for every row
  ///        particle p the chunk writes
  /// @return whether 64 colours sufficed (else the object is empty: use
  ///         larger chunks)
  template <class RowsOf>
  bool Build(int num_particles, std::size_t chunks, RowsOf rows_of) {
    std::vector<std::uint64_t> used(static_cast<std::size_t>(num_particles), 0);
    std::vector<int> colour(chunks);
    int colours = 0;
    for (std::size_t k = 0; k < chunks; ++k) {
      std::uint64_t forbidden = 0;
      rows_of(k, [&](int p) { forbidden |= used[static_cast<std::size_t>(p)]; });
      if (forbidden == ~std::uint64_t{0}) {
        starts_.clear();
        order_.clear();
        return false;
      }
      int c = 0;
      while ((forbidden >> c) & 1u) ++c;
      colour[k] = c;
      colours = std::max(colours, c + 1);
      rows_of(k, [&](int p) { used[static_cast<std::size_t>(p)] |= std::uint64_t{1} << c; });
    }
    starts_.assign(static_cast<std::size_t>(colours) + 1, 0);
    for (int c : colour) ++starts_[static_cast<std::size_t>(c) + 1];
    for (std::size_t c = 0; c < static_cast<std::size_t>(colours); ++c) starts_[c + 1] += starts_[c];
    order_.resize(chunks);
    std::vector<std::size_t> fill(starts_.begin(), starts_.end() - 1);
    for (std::size_t k = 0; k < chunks; ++k) order_[fill[static_cast<std::size_t>(colour[k])]++] = k;
    return true;
  }

  /// Calls f(chunk) for every chunk, colour by colour; the chunks of a
  /// colour on the OpenMP threads if `parallel`.
  template <class F>
  void ForEach(F f, bool parallel) const {
    for (std::size_t c = 0; c + 1 < starts_.size(); ++c) {
      const auto begin = static_cast<std::ptrdiff_t>(starts_[c]), end = static_cast<std::ptrdiff_t>(starts_[c + 1]);
#ifdef _OPENMP
#pragma omp parallel for schedule(static) if (parallel && end - begin > 1)
#endif
      for (std::ptrdiff_t i = begin; i < end; ++i) f(order_[static_cast<std::size_t>(i)]);
    }
    (void)parallel;
  }

 private:
  std::vector<std::size_t> starts_, order_;  // chunks by colour
};

/// Value positions of blocks in the compressed row storage of a matrix
/// whose pattern is that of `m` (symmetric, stored compressed column-major:
/// row i of the row storage is column i of m's arrays). Per block (a, b):
/// 3 positions, the index of entry (3a + r, 3b) for r = 0, 1, 2 (entries
/// (3a + r, 3b + 1) and (3a + r, 3b + 2) follow it in its row). A term's
/// blocks are rows of its item's particles, so a row storage keeps an
/// item's writes together (a stencil centre's row is one stretch).
/// @throws std::logic_error if a block is not in the pattern
std::vector<int> BlockPositions(const SparseMatrix& m, const std::vector<BlockPair>& blocks);

/// vals[pos[r] + q] += b(r, q): one block at its three row positions.
EIGEN_ALWAYS_INLINE void AddBlock(const Matrix3& b, const int* pos, double* vals) {
  for (int r = 0; r < 3; ++r) {
    double* d = vals + pos[r];
    d[0] += b(r, 0);
    d[1] += b(r, 1);
    d[2] += b(r, 2);
  }
}


}  // namespace clothbench

#endif  // CLOTHBENCH_MODEL_BLOCK_SCATTER_H_
