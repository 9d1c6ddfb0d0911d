// The cloth's crossings in a result file (crossings.h).
#include "harness/crossings.h"

#include <array>
#include <cstdint>
#include <stdexcept>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "collision/self_intersection.h"
#include "model/interrupt.h"

namespace clothbench {

long PrintSelfIntersections(std::FILE* out, const ResultReader& f, const std::string& run) {
  const std::string g = run == "reference" ? "/reference" : "/runs/" + run;
  if (!f.Exists(g)) throw std::invalid_argument(fmt::format("self-intersections: no run \"{}\" in {}", run, f.path()));
  const std::string dataset = f.Exists(g + "/positions") ? g + "/positions" : g + "/positions_ends";
  if (!f.Exists(dataset))
    throw std::invalid_argument(fmt::format("self-intersections: run \"{}\" in {} has no stored frames", run, f.path()));
  const std::vector<int32_t> faces = f.Ints("/scene/faces");
  std::vector<std::array<int, 3>> triangles;
  triangles.reserve(faces.size() / 2);
  for (std::size_t q = 0; q + 3 < faces.size(); q += 4) {
    triangles.push_back({faces[q], faces[q + 1], faces[q + 2]});
    triangles.push_back({faces[q], faces[q + 2], faces[q + 3]});
  }
  const std::vector<double> times = f.Doubles(g + "/times");
  const std::size_t frames = f.Shape(dataset)[0];
  const bool ends = dataset.ends_with("_ends");
  long crossed = 0;
  for (std::size_t k = 0; k < frames; ++k) {
    ThrowIfInterrupted();
    const double t = ends ? (k == 0 ? times.front() : times.back()) : times.at(k);
    const std::vector<std::pair<int, int>> pairs = SelfIntersections(f.Frame(dataset, k), triangles);
    crossed += pairs.empty() ? 0 : 1;
    fmt::print(out, "frame {} t = {:g} s: {} crossing triangle pairs{}\n", k, t, pairs.size(),
               pairs.empty() ? std::string()
                             : fmt::format(" (first: triangles {} and {})", pairs.front().first, pairs.front().second));
  }
  return crossed;
}

}  // namespace clothbench
