// Value positions of 3×3 blocks in the row storage of a symmetric pattern.
#include "model/block_scatter.h"

#include <algorithm>

namespace clothbench {

std::vector<int> BlockPositions(const SparseMatrix& m, const std::vector<BlockPair>& blocks) {
  std::vector<int> pos(3 * blocks.size());
  const int* outer = m.outerIndexPtr();
  const int* inner = m.innerIndexPtr();
  // Row 3a + r of the row storage is column 3a + r of m's arrays (the
  // pattern is symmetric); its entries of block column b start at 3b.
  for (std::size_t k = 0; k < blocks.size(); ++k) {
    const int row = 3 * blocks[k][1];
    for (int q = 0; q < 3; ++q) {
      const int col = 3 * blocks[k][0] + q;
      const int* begin = inner + outer[col];
      const int* end = inner + outer[col + 1];
      const int* it = std::lower_bound(begin, end, row);
      // The block's three rows must follow each other in the column; a miss
      // would write into another entry, so it is a logic error.
      if (end - it < 3 || it[0] != row || it[1] != row + 1 || it[2] != row + 2)
        throw std::logic_error("BlockPositions: block outside the pattern");
      pos[3 * k + static_cast<std::size_t>(q)] = static_cast<int>(it - inner);
    }
  }
  return pos;
}

}  // namespace clothbench
