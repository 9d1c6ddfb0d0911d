// The sewing phase of a garment (docs/model.md §2.9; thesis §6.3, Fig. 6.6):
// each seam's sample pairs are driven on straight paths to their common
// midpoint over [sewing] time, the rest of the cloth following under its
// own forces and the obstacles with gravity and wind off; then every pair
// is one particle and the garment starts from there.
#ifndef CLOTHBENCH_SOLVER_SEWING_H_
#define CLOTHBENCH_SOLVER_SEWING_H_

#include "model/scene.h"

namespace clothbench {

/// What the sewing phase did.
struct SewingSummary {
  int steps = 0;             ///< fixed steps of implicit Euler (Newton) at the scene's h
  double largest_gap = 0.0;  ///< the largest distance between a seam's two samples at the phase's end [m]
  double seconds = 0.0;      ///< wall time [s]
};

/// Sews `scene` if it has a `[sewing]` phase not yet run
/// (Scene::sewing_time > 0 and ClothLayout::sewn false): runs the phase on
/// the patterns apart, then makes the sewn cloth (merged pairs, starting
/// where the phase ended, at rest) the scene's Scene::cloth. Fixed
/// particles of the scene are free during the phase, and self-contact is
/// off (a pair's two samples close onto one point). A scene without a
/// pending phase is left as it is.
/// @throws SceneError "<source>: sewing: …" if the phase does not end ok
///   (the run's status and message)
SewingSummary Sew(Scene* scene);

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_SEWING_H_
