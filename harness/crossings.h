// The cloth's crossings in a result file: per stored frame of a run, the
// pairs of its triangles that cross (collision/self_intersection.h), for
// `clothbench_inspect FILE self-intersections RUN`.
#ifndef CLOTHBENCH_HARNESS_CROSSINGS_H_
#define CLOTHBENCH_HARNESS_CROSSINGS_H_

#include <cstdio>
#include <string>

#include "results/result_reader.h"

namespace clothbench {

/// Prints one line per stored frame of `run` ("reference" or a run id):
/// its time [s] and the number of crossing pairs of the cloth's triangles
/// (each stored quad a, b, c, d split as a b c and a c d, the model's
/// GridTriangles), with the first pair. @return the frames with a pair
/// @throws ResultError if the file has no such run or no stored frames (StoredFramesOf)
/// @throws Interrupted on SIGINT/SIGTERM between frames
long PrintSelfIntersections(std::FILE* out, const ResultReader& f, const std::string& run);

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_CROSSINGS_H_
