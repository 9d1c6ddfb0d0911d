// The frames of a run, whatever produced it: the thesis' integrators, the
// peers and the SUNDIALS references all return them, and results/ reads and
// compares them without knowing the method.
#ifndef CLOTHBENCH_MODEL_TRAJECTORY_H_
#define CLOTHBENCH_MODEL_TRAJECTORY_H_

#include <vector>

#include "model/types.h"

namespace clothbench {

/// Frames of a run: times [F], N×3 positions [m] and velocities [m/s] per
/// frame, and the work done by non-conservative external forces (wind, air)
/// since t = 0 [J] when the run integrated it (empty otherwise), and the
/// work of the contact response since t = 0 [J] per frame: of its holding
/// and pulling constraint impulses and of friction, when the method has our
/// contact response (empty otherwise; solver/contact.h).
struct Trajectory {
  std::vector<double> times;
  std::vector<MatrixN3> positions;
  std::vector<MatrixN3> velocities;
  std::vector<double> external_work;
  std::vector<double> contact_work_holding, contact_work_pulling, contact_work_friction;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_MODEL_TRAJECTORY_H_
