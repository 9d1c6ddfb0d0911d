// One stored frame of a result file as a mesh file (clothbench_inspect
// FILE export RUN --frame K --obj|--ply OUT).
#ifndef CLOTHBENCH_RESULTS_MESH_EXPORT_H_
#define CLOTHBENCH_RESULTS_MESH_EXPORT_H_

#include <cstddef>
#include <string>
#include <vector>

#include "results/result_reader.h"

namespace clothbench {

/// The stored position frames of one run: every frame_dt ("positions") or
/// t = 0 and t_end only ("positions_ends").
struct StoredFrames {
  std::string dataset;        ///< the positions dataset [frames, N, 3]
  std::size_t count = 0;      ///< its frames (≥ 1)
  std::vector<double> times;  ///< the run's frame times [s]
  /// The time of frame k [s].
  double TimeOf(std::size_t k) const {
    return dataset.ends_with("_ends") ? (k == 0 ? times.front() : times.back()) : times.at(k);
  }
};

/// The stored frames of run `run` ("reference" for the reference) of `file`.
/// @param command names the command in the messages ("export", "self-intersections")
/// @throws ResultError (one line) for a run that is not in the file or one
///   without stored frames
StoredFrames StoredFramesOf(const ResultReader& file, const std::string& run, const std::string& command);

/// The mesh formats a frame is exported to.
enum class MeshFormat { kObj, kPly };

/// What ExportFrame wrote.
struct ExportedFrame {
  double t = 0.0;      ///< the frame's time [s]
  long vertices = 0;   ///< the cloth's particles
  long quads = 0;      ///< the grid's quads
};

/// Writes frame `frame` (0-based) of run `run` ("reference" for the
/// reference) of `file` to `path` as Wavefront OBJ or ASCII PLY: positions
/// [m] with 17 significant digits, the grid's quads as faces, a comment
/// naming the file, run, frame and t. Written by the project's one output
/// primitive (model/output_file.h): `path` must be absent or a regular
/// file, never a link, device, FIFO or an input of the command; it is
/// checked before anything is read.
/// @param option how the command names `path` ("--obj", "--ply")
/// @throws OutputRefused for such a path; ResultError (one line) for a run
///   that is not in the file, one without stored frames, or a frame out of
///   range; std::runtime_error if the file cannot be written
ExportedFrame ExportFrame(const ResultReader& file, const std::string& run, long frame, MeshFormat format,
                          const std::string& path, const std::string& option);

}  // namespace clothbench

#endif  // CLOTHBENCH_RESULTS_MESH_EXPORT_H_
