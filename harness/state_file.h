// contact_replay's state files: a scene's positions and velocities at a
// time, for taking steps from there (bench/contact_replay.cc).
//
// A state file is "CBSTATE2", the FNV-1a 64 hash of the scene's text
// (uint64), N (int64), t [s] (double), x and v (N×3 doubles each,
// column-major) and the CRC-32 of everything before it.
#ifndef CLOTHBENCH_HARNESS_STATE_FILE_H_
#define CLOTHBENCH_HARNESS_STATE_FILE_H_

#include <cstddef>
#include <optional>
#include <string>

#include "model/scene.h"
#include "model/types.h"

namespace clothbench {

/// A saved state: time [s], positions [m] and velocities [m/s], N×3.
struct State {
  double t = 0.0;
  MatrixN3 x, v;
};

/// The bytes of a state file of n particles.
std::size_t StateBytes(Eigen::Index n);

/// The bytes of a state file of `s` on `scene`.
std::string EncodeState(const Scene& scene, const State& s);

/// Reads a state file saved from `scene` (n particles). Only a regular file
/// of exactly StateBytes(n) bytes is opened and read (a FIFO, a folder or a
/// device is refused before it is opened); it is noted as an input of the
/// command (model/output_file.h). @return the state, or nullopt with *why
/// naming the broken rule (another scene, truncated, damaged, non-finite,
/// outside [0, t_end]).
std::optional<State> ReadState(const std::string& path, const Scene& scene, Eigen::Index n, std::string* why);

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_STATE_FILE_H_
