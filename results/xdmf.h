// XDMF 3 descriptions of result files, for ParaView and other XDMF readers.
#ifndef CLOTHBENCH_RESULTS_XDMF_H_
#define CLOTHBENCH_RESULTS_XDMF_H_

#include <string>

namespace clothbench {

/// Writes "<stem>.xdmf" next to the result file `h5_path` (written through
/// "<stem>.xdmf.tmp" and renamed): one temporal collection per trajectory
/// (/reference and each /runs/<id> with frames) whose steps are uniform
/// grids over the HDF5 datasets: /scene/faces as Quadrilateral topology,
/// the frame's positions [N, 3] as XYZ geometry and, where stored, its
/// velocities as a node vector attribute "velocity" [m/s]; each step's Time
/// is the frame time [s]. Frames are addressed through the per-frame views
/// <group>/frame_views/{positions,velocities}_<k> (ResultFile::WriteFrameViews),
/// plain datasets that every XDMF reader takes. Triangle-mesh obstacles
/// stored under /scene/obstacles/<k> (vertices [V, 3] m, triangles [T, 3])
/// are listed as static uniform grids.
/// @returns the XDMF path, or "" if the file holds no frames (nothing
/// written). @throws ResultError if the file cannot be read or written.
std::string WriteXdmf(const std::string& h5_path);

}  // namespace clothbench

#endif  // CLOTHBENCH_RESULTS_XDMF_H_
