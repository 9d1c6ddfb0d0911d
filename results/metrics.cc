#include "results/metrics.h"

#include <cmath>
#include <limits>
#include <stdexcept>

#include <fmt/format.h>

namespace clothbench {

double ErrorRms(const MatrixN3& x, const MatrixN3& ref) {
  if (x.rows() != ref.rows() || x.rows() == 0)  // Eigen checks no sizes in Release: never read past an array
    throw std::invalid_argument(fmt::format("e_rms of {} against {} particles (the same N ≥ 1 expected)", x.rows(),
                                            ref.rows()));
  return std::sqrt((x - ref).squaredNorm() / static_cast<double>(x.rows()));
}

double ErrorMean(const MatrixN3& x, const MatrixN3& ref) {
  return (x - ref).rowwise().norm().sum() / static_cast<double>(x.rows());
}

std::string_view ToString(ErrorMetric m) {
  return m == ErrorMetric::kL2 ? "l2" : m == ErrorMetric::kMax ? "max" : "final";
}

std::optional<ErrorMetric> ParseErrorMetric(std::string_view text) {
  if (text == "final") return ErrorMetric::kFinal;
  if (text == "l2") return ErrorMetric::kL2;
  if (text == "max") return ErrorMetric::kMax;
  return std::nullopt;
}

ErrorMetric DefaultErrorMetric(const Scene& scene) {
  return scene.obstacles.empty() ? ErrorMetric::kFinal : ErrorMetric::kL2;
}

namespace {

// e_rms at the last frame, its root mean square over the frames and its
// maximum; false if a value is not finite.
bool FrameNorms(const std::vector<MatrixN3>& run, const std::vector<MatrixN3>& ref, double* at_end, double* l2,
                double* max) {
  double sum = 0.0;
  *max = 0.0;
  for (std::size_t k = 0; k < run.size(); ++k) {
    const double e = ErrorRms(run[k], ref[k]);
    sum += e * e;
    *max = std::max(*max, e);
  }
  *at_end = ErrorRms(run.back(), ref.back());
  *l2 = std::sqrt(sum / static_cast<double>(run.size()));
  return std::isfinite(*at_end) && std::isfinite(*l2) && std::isfinite(*max);
}

}  // namespace

std::optional<TrajectoryErrors> CompareTrajectories(const std::vector<MatrixN3>& run, const std::vector<MatrixN3>& ref) {
  if (run.size() != ref.size() || run.empty()) return std::nullopt;
  TrajectoryErrors e;
  if (!FrameNorms(run, ref, &e.rms_at_end, &e.rms_l2, &e.rms_max)) return std::nullopt;
  e.mean_at_end = ErrorMean(run.back(), ref.back());
  return e;
}

std::optional<TrajectoryErrors> CompareTrajectories(const Trajectory& run, const Trajectory& ref) {
  std::optional<TrajectoryErrors> e = CompareTrajectories(run.positions, ref.positions);
  if (!e || run.velocities.size() != run.positions.size() || ref.velocities.size() != ref.positions.size()) return e;
  double at_end = 0.0, l2 = 0.0, max = 0.0;
  if (!FrameNorms(run.velocities, ref.velocities, &at_end, &l2, &max)) return std::nullopt;
  e->v_rms_at_end = at_end;
  e->v_rms_l2 = l2;
  e->v_rms_max = max;
  return e;
}

double ObservedOrder(double h1, double e1, double h2, double e2) { return std::log(e1 / e2) / std::log(h1 / h2); }

double EnergySeries::Rate() const {
  if (t.size() < 2) return 0.0;
  return (total.back() - total.front() - external_work.back() - ContactWork(t.size() - 1)) / (t.back() - t.front());
}

double EnergySeries::ContactPower() const {
  if (t.size() < 2 || (contact_work_holding.size() != t.size() && contact_work_self.size() != t.size()))
    return std::numeric_limits<double>::quiet_NaN();
  return ContactWork(t.size() - 1) / (t.back() - t.front());
}

const std::vector<EnergyField>& EnergySeriesFields() {
  using E = EnergySeries;
  static const std::vector<EnergyField> fields = {
      {"kinetic", &E::kinetic},
      {"tension", &E::tension},
      {"shear", &E::shear},
      {"bending", &E::bending},
      {"gravity", &E::gravity},
      {"external_work", &E::external_work},
      {"contact_work_holding", &E::contact_work_holding, true},
      {"contact_work_pulling", &E::contact_work_pulling, true},
      {"contact_work_friction", &E::contact_work_friction, true},
      {"contact_work_self", &E::contact_work_self, true},
      {"total", &E::total},
  };
  return fields;
}

EnergySeries ComputeEnergies(const ParticleSystem& system, const Trajectory& traj) {
  EnergySeries s;
  const std::size_t f = std::min(traj.positions.size(), traj.velocities.size());
  MatrixN3 fext(system.num_particles(), 3);
  double work = 0.0, power_prev = 0.0;
  for (std::size_t k = 0; k < f; ++k) {
    EnergyBreakdown e = system.Energies(traj.positions[k], traj.velocities[k]);
    if (k < traj.virtual_particles.tension_energy.size()) e.tension += traj.virtual_particles.tension_energy[k];
    s.t.push_back(traj.times[k]);
    s.kinetic.push_back(e.kinetic);
    s.tension.push_back(e.tension);
    s.shear.push_back(e.shear);
    s.bending.push_back(e.bending);
    s.gravity.push_back(e.gravity);
    s.total.push_back(e.total());
    s.momentum.push_back(e.momentum);
    if (k < traj.external_work.size()) {
      work = traj.external_work[k];
    } else if (system.has_external_work()) {
      fext.setZero();
      system.AddExternalForces(traj.times[k], traj.positions[k], traj.velocities[k], &fext);
      const double power = (fext.array() * traj.velocities[k].array()).sum();
      if (k > 0) work += 0.5 * (traj.times[k] - traj.times[k - 1]) * (power + power_prev);
      power_prev = power;
    }
    s.external_work.push_back(work);
  }
  if (f > 0 && traj.contact_work_holding.size() >= f && traj.contact_work_pulling.size() >= f &&
      traj.contact_work_friction.size() >= f) {
    const auto first = [f](const std::vector<double>& v) { return std::vector<double>(v.begin(), v.begin() + static_cast<long>(f)); };
    s.contact_work_holding = first(traj.contact_work_holding);
    s.contact_work_pulling = first(traj.contact_work_pulling);
    s.contact_work_friction = first(traj.contact_work_friction);
  }
  if (f > 0 && traj.contact_work_self.size() >= f)
    s.contact_work_self.assign(traj.contact_work_self.begin(), traj.contact_work_self.begin() + static_cast<long>(f));
  return s;
}

PenetrationSeries ComputePenetration(const ParticleSystem& system, const Trajectory& traj,
                                     const PenetrationQuery& query) {
  PenetrationSeries s;
  const auto& obs = system.obstacles();
  s.obstacles = static_cast<int>(obs.size());
  for (std::size_t f = 0; f < traj.positions.size(); ++f) {
    const MatrixN3& x = traj.positions[f];
    for (std::size_t k = 0; k < obs.size(); ++k) {
      const Obstacle& o = obs[k];
      const ObstaclePose pose = o.PoseAt(traj.times[f]);
      const Penetration p = query ? query(static_cast<int>(k), pose, x) : o.PenetrationOf(pose, x);
      s.max_depth.push_back(p.max_depth);
      s.mean_depth.push_back(p.inside ? p.depth_sum / p.inside : 0.0);
      s.close.push_back(p.close);
    }
  }
  return s;
}

}  // namespace clothbench
