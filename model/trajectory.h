// The frames of a run, whatever produced it: the thesis' integrators, the
// peers and the SUNDIALS references all return them, and results/ reads and
// compares them without knowing the method.
#ifndef CLOTHBENCH_MODEL_TRAJECTORY_H_
#define CLOTHBENCH_MODEL_TRAJECTORY_H_

#include <cstdint>
#include <vector>

#include "model/types.h"

namespace clothbench {

/// Frames of a run: times [F], N×3 positions [m] and velocities [m/s] per
/// frame, and the work done by non-conservative external forces (wind, air)
/// since t = 0 [J] when the run integrated it (empty otherwise), and the
/// work of the contact response since t = 0 [J] per frame: of its holding
/// and pulling constraint impulses and of friction, when the method has our
/// contact response (empty otherwise; solver/contact.h), and the virtual
/// particles of each frame.
/// The thesis' virtual particles at each frame (collision/virtual_particles.h):
/// frame k's particles are rows offsets[k] … offsets[k + 1] − 1 of x (K×3
/// [m], row-major), cloth_edge (K×2: the cloth edge's particles a < b; −1,
/// −1 inside a face) and obstacle_edge (K×2: the obstacle's index and its
/// edge, Obstacle::Edges; −1, −1 for a point the triangulation adds where
/// two projected edges cross); the frame's refined cloth mesh is rows
/// face_offsets[k] … face_offsets[k + 1] − 1 of faces (T×3; an index below N
/// is a base particle, N + j the frame's virtual particle j);
/// tension_energy[k] is the virtual springs' tension energy minus that of
/// the springs they split [J] (VirtualParticles::TensionEnergyChange),
/// which the frame's energy adds to the base springs'. Empty for a scene
/// without virtual particles.
struct VirtualFrames {
  std::vector<int32_t> offsets, face_offsets;
  std::vector<double> x, tension_energy;
  std::vector<int32_t> cloth_edge, obstacle_edge, faces;
  bool empty() const { return offsets.empty(); }
};

struct Trajectory {
  std::vector<double> times;
  std::vector<MatrixN3> positions;
  std::vector<MatrixN3> velocities;
  std::vector<double> external_work;
  std::vector<double> contact_work_holding, contact_work_pulling, contact_work_friction;
  /// With `[collision]` in the scene: per frame the cloth's crossing
  /// triangle pairs (collision/self_intersection.h), and with `self =
  /// true` the self-contact response's work since t = 0 [J]; empty otherwise.
  std::vector<int32_t> crossing_pairs;
  std::vector<double> contact_work_self;
  VirtualFrames virtual_particles;  ///< per frame, if the scene has them
};

}  // namespace clothbench

#endif  // CLOTHBENCH_MODEL_TRAJECTORY_H_
