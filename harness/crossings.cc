// The cloth's crossings in a result file (crossings.h).
#include "harness/crossings.h"

#include <array>
#include <cstdint>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "collision/self_intersection.h"
#include "model/interrupt.h"
#include "results/mesh_export.h"

namespace clothbench {

long PrintSelfIntersections(std::FILE* out, const ResultReader& f, const std::string& run) {
  const StoredFrames stored = StoredFramesOf(f, run, "self-intersections");
  const std::vector<int32_t> faces = f.Ints("/scene/faces");
  std::vector<std::array<int, 3>> triangles;
  triangles.reserve(faces.size() / 2);
  for (std::size_t q = 0; q + 3 < faces.size(); q += 4) {
    triangles.push_back({faces[q], faces[q + 1], faces[q + 2]});
    triangles.push_back({faces[q], faces[q + 2], faces[q + 3]});
  }
  long crossed = 0;
  for (std::size_t k = 0; k < stored.count; ++k) {
    ThrowIfInterrupted();
    const std::vector<std::pair<int, int>> pairs = SelfIntersections(f.Frame(stored.dataset, k), triangles);
    crossed += pairs.empty() ? 0 : 1;
    fmt::print(out, "frame {} t = {:g} s: {} crossing triangle pairs{}\n", k, stored.TimeOf(k), pairs.size(),
               pairs.empty() ? std::string()
                             : fmt::format(" (first: triangles {} and {})", pairs.front().first, pairs.front().second));
  }
  return crossed;
}

}  // namespace clothbench
