// What the deforming shapes share (mesh_sequence.cc, skeleton.cc): points
// given at increasing times that move linearly between them, and the few
// states a step asks for, kept by time (docs/model.md §7).
#ifndef CLOTHBENCH_COLLISION_SHAPES_POINT_FRAMES_H_
#define CLOTHBENCH_COLLISION_SHAPES_POINT_FRAMES_H_

#include <algorithm>
#include <limits>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "collision/shapes/obstacle_shape.h"

namespace clothbench {

/// Points [m] at increasing times [s]: between frames t_k < t_{k+1} they
/// move linearly, X(t) = (1 − λ) X_k + λ X_{k+1}, with the chord's velocity
/// (X_{k+1} − X_k)/(t_{k+1} − t_k); outside [t_0, t_last] they are held.
class PointFrames {
 public:
  /// Appends a frame at t > the last frame's time, with as many points.
  void Add(double t, std::vector<Vector3> x) {
    if (!x_.empty()) {
      const double dt = t - times_.back();
      double speed = 0.0;
      for (std::size_t j = 0; j < x.size(); ++j) speed = std::max(speed, (x[j] - x_.back()[j]).norm() / dt);
      speeds_.push_back(speed);
    }
    times_.push_back(t);
    x_.push_back(std::move(x));
  }
  bool empty() const { return times_.empty(); }
  double last_time() const { return times_.back(); }
  const std::vector<double>& times() const { return times_; }
  const std::vector<Vector3>& frame(std::size_t k) const { return x_[k]; }
  /// The largest speed of a point [m/s] at any time in [t0, t1] [s]: over
  /// the frame intervals that meet it (0 where the points are held).
  double max_speed(double t0, double t1) const {
    if (times_.size() < 2 || t1 < times_.front() || t0 > times_.back()) return 0.0;
    // Interval k, [t_k, t_{k+1}], meets [t0, t1] iff t_k ≤ t1 and t_{k+1} ≥ t0.
    auto k = static_cast<std::size_t>(std::lower_bound(times_.begin() + 1, times_.end(), t0) - times_.begin()) - 1;
    double speed = 0.0;
    for (; k < speeds_.size() && times_[k] <= t1; ++k) speed = std::max(speed, speeds_[k]);
    return speed;
  }
  /// The points at time t [m] and their velocities [m/s] (0 where held).
  void At(double t, std::vector<Vector3>* x, std::vector<Vector3>* v) const {
    const std::size_t n = x_[0].size();
    v->assign(n, Vector3::Zero());
    if (t < times_.front() || t >= times_.back()) {
      *x = t < times_.front() ? x_.front() : x_.back();
      return;
    }
    const std::size_t k = static_cast<std::size_t>(std::upper_bound(times_.begin(), times_.end(), t) - times_.begin()) - 1;
    const double dt = times_[k + 1] - times_[k], lambda = (t - times_[k]) / dt;
    x->resize(n);
    for (std::size_t j = 0; j < n; ++j) {
      (*x)[j] = (1.0 - lambda) * x_[k][j] + lambda * x_[k + 1][j];
      (*v)[j] = (x_[k + 1][j] - x_[k][j]) / dt;
    }
  }
  /// The first frame time after t [s] (+∞ after the last): the
  /// velocities are constant between t and it.
  double NextTime(double t) const {
    const auto next = std::upper_bound(times_.begin(), times_.end(), t);
    return next == times_.end() ? std::numeric_limits<double>::infinity() : *next;
  }

 private:
  std::vector<double> times_;
  std::vector<std::vector<Vector3>> x_;
  std::vector<double> speeds_;  // per frame interval: its points' largest speed [m/s]
};

/// The largest distance [m] between corresponding points of a and b.
/// @throws std::logic_error if their counts differ
inline double MaxPointDistance(const std::vector<Vector3>& a, const std::vector<Vector3>& b) {
  if (a.size() != b.size()) throw std::logic_error("states of different deforming shapes");
  double d = 0.0;
  for (std::size_t k = 0; k < a.size(); ++k) d = std::max(d, (a[k] - b[k]).norm());
  return d;
}

/// The states of a deforming shape at the last few times asked for (a
/// step's start, end and stages), built once each; any thread may ask.
class StateCache {
 public:
  template <class Build>
  std::shared_ptr<const ObstacleShape> At(double t, Build build) const {
    const std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& [ct, state] : states_)
      if (ct == t) return state;
    std::shared_ptr<const ObstacleShape> state = build(t);
    if (states_.size() >= kKept) states_.erase(states_.begin());  // the oldest goes
    states_.emplace_back(t, state);
    return state;
  }

 private:
  static constexpr std::size_t kKept = 8;
  mutable std::mutex mutex_;
  mutable std::vector<std::pair<double, std::shared_ptr<const ObstacleShape>>> states_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_COLLISION_SHAPES_POINT_FRAMES_H_
