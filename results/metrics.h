// Error measures and observed order (docs/model.md §9).
#ifndef CLOTHBENCH_RESULTS_METRICS_H_
#define CLOTHBENCH_RESULTS_METRICS_H_

#include <cstdint>
#include <functional>
#include <optional>
#include <string_view>
#include <vector>

#include "model/particle_system.h"
#include "model/types.h"
#include "model/trajectory.h"

namespace clothbench {

/// e_rms = sqrt((1/N) Σ_p |x_p − x_p^ref|²) [m] (docs/model.md §9) of two
/// N×3 position arrays [m].
/// @throws std::invalid_argument if their N differ or N = 0
double ErrorRms(const MatrixN3& x, const MatrixN3& ref);
/// The thesis' "normalised by the number of nodes" error (1/N) Σ_p |x_p − x_p^ref| [m] (§2.8).
double ErrorMean(const MatrixN3& x, const MatrixN3& ref);

/// Which error norm the observed orders, the equal-accuracy table and the
/// plots use (--error-metric; docs/notes/work-precision.md): e_rms at t_end
/// ("final"), the root mean square over the frames of the per-frame e_rms
/// ("l2"), or its maximum over the frames ("max").
enum class ErrorMetric { kFinal, kL2, kMax };
std::string_view ToString(ErrorMetric m);
/// "final", "l2" or "max"; nothing for any other text.
std::optional<ErrorMetric> ParseErrorMetric(std::string_view text);
/// The metric of a scene's tables when the caller names none, the same for
/// every entry point: l2 on scenes with obstacles (contact events are not
/// smooth, so the whole trajectory is compared), final otherwise.
ErrorMetric DefaultErrorMetric(const Scene& scene);

struct TrajectoryErrors {
  double rms_at_end = 0.0;   ///< e_rms at the last frame [m]
  double rms_l2 = 0.0;       ///< sqrt((1/F) Σ_f e_rms(f)²) over the F frames [m]
  double rms_max = 0.0;      ///< max over frames of e_rms [m]
  double mean_at_end = 0.0;  ///< (1/N) Σ|x − x_ref| at the last frame [m]
  /// The same three of the velocities [m/s], if both runs kept them.
  std::optional<double> v_rms_at_end, v_rms_l2, v_rms_max;
  /// The position error of `metric` [m].
  double Of(ErrorMetric metric) const {
    return metric == ErrorMetric::kL2 ? rms_l2 : metric == ErrorMetric::kMax ? rms_max : rms_at_end;
  }
};

/// Compares positions frame by frame. Returns nothing if the frame counts
/// differ (a run that stopped early) or a value is not finite.
std::optional<TrajectoryErrors> CompareTrajectories(const std::vector<MatrixN3>& run, const std::vector<MatrixN3>& ref);
/// The same, and the velocities' errors where both trajectories hold every
/// frame's velocities.
std::optional<TrajectoryErrors> CompareTrajectories(const Trajectory& run, const Trajectory& ref);

/// Observed order log(e1/e2)/log(h1/h2) between step sizes h1 > h2 (docs/model.md §9).
double ObservedOrder(double h1, double e1, double h2, double e2);

/// Energies [J] and momentum [kg m/s] per frame.
struct EnergySeries {
  std::vector<double> t, kinetic, tension, shear, bending, gravity, external_work, total;
  /// Work of the contact response since t = 0 [J] (Trajectory): of the
  /// holding and pulling constraint impulses and of friction; empty when the
  /// method has none.
  std::vector<double> contact_work_holding, contact_work_pulling, contact_work_friction;
  /// Work of the self-contact response since t = 0 [J]; empty without it.
  std::vector<double> contact_work_self;
  /// W_contact at frame k [J]: the obstacles' and the self-contact's, each
  /// where tracked (0 when neither is).
  double ContactWork(std::size_t k) const {
    return (k < contact_work_holding.size()
                ? contact_work_holding[k] + contact_work_pulling[k] + contact_work_friction[k]
                : 0.0) +
           (k < contact_work_self.size() ? contact_work_self[k] : 0.0);
  }
  std::vector<Vector3> momentum;
  /// (E(t_end) − E(0) − W_ext(t_end) − W_contact(t_end)) / t_end [W]: the
  /// rate at which the run gains (> 0) or dissipates (< 0) energy beyond the
  /// work of external forces and of the contact response (docs/model.md §7):
  /// the integrator's own drift. Physical damping contributes; the
  /// reference run shows how much.
  double Rate() const;
  /// W_contact(t_end)/t_end [W], NaN when no contact work is tracked.
  double ContactPower() const;
};

/// One series of an EnergySeries: its dataset name under <run>/energy
/// (docs/guide/results-schema.md) and its member. Every series is in J, one value
/// per frame; the contact work series are empty for methods without our
/// contact response and then not stored.
struct EnergyField {
  const char* name;
  std::vector<double> EnergySeries::*member;
  bool contact_work = false;  ///< stored only when not empty
  bool Stored(const EnergySeries& e) const { return !contact_work || !(e.*member).empty(); }
};
/// The stored series in file order: the one list the result writer and the
/// Python module iterate.
const std::vector<EnergyField>& EnergySeriesFields();

/// Evaluates ParticleSystem::Energies at every frame. External work comes
/// from the run (trapezoidal rule per step) or, for the SUNDIALS references,
/// from the trapezoidal rule over frames.
EnergySeries ComputeEnergies(const ParticleSystem& system, const Trajectory& trajectory);

/// Penetration of the cloth into each obstacle per frame: rows are
/// frames, columns obstacles.
struct PenetrationSeries {
  int obstacles = 0;
  std::vector<double> max_depth;   ///< [F·O] max over particles of max(0, −d) [m]
  std::vector<double> mean_depth;  ///< [F·O] mean of −d over particles with d < 0 (0 if none) [m]
  std::vector<int32_t> close;      ///< [F·O] particles with d < δ/2
};

/// Obstacle k's penetration at `pose` for the N×3 positions x [m]
/// (Obstacle::PenetrationOf, or a culled query with its result:
/// collision/obstacle_proximity.h).
using PenetrationQuery = std::function<Penetration(int k, const ObstaclePose& pose, const MatrixN3& x)>;

/// Signed distances d of every particle to every obstacle at every frame,
/// by `query` (empty: Obstacle::PenetrationOf), frame by frame in time order.
PenetrationSeries ComputePenetration(const ParticleSystem& system, const Trajectory& trajectory,
                                     const PenetrationQuery& query = {});

}  // namespace clothbench

#endif  // CLOTHBENCH_RESULTS_METRICS_H_
