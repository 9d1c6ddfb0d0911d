// Signed distances, segment casts and keyframed rigid motion of obstacles
// (docs/model.md §7; thesis §5.1, §6.2).
#include "model/obstacle.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <vector>

#include <Eigen/Geometry>
#include <fmt/format.h>

#include "collision/shapes/triangle_mesh.h"

namespace clothbench {

Obstacle::Obstacle(const ObstacleSpec& given) : spec_(given) {
  if (!given.shape) throw std::invalid_argument("obstacle without a shape");
  if (given.held) {
    spec_.held = false;
    spec_ = HeldAt(spec_, 0.0);
  }
  const ObstacleSpec& spec = spec_;
  shape_ = spec.shape->Load();
  if (mesh() && !spec.keyframes.empty()) {
    std::vector<double> xyz;
    std::vector<int32_t> triangles;
    mesh()->Export(&xyz, &triangles);
    auto vertices = std::make_shared<std::vector<Vector3>>(xyz.size() / 3);
    for (std::size_t i = 0; i < vertices->size(); ++i) (*vertices)[i] = Vector3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    vertices_ = std::move(vertices);
  }
  motion_ = KeyframedMotion(spec.keyframes, shape_->anchor());
}

KeyframedMotion::KeyframedMotion(std::vector<ObstacleKeyframe> keys, const Vector3& anchor)
    : keys_(std::move(keys)), anchor_(anchor) {
  for (const ObstacleKeyframe& k : keys_)
    rotations_.emplace_back(Eigen::Quaterniond(RotationFromDegrees(k.rotate)).normalized());
}

double Obstacle::MotionBound(const ObstaclePose& a, const ObstaclePose& b) const {
  if (a.deformed && b.deformed) return a.deformed->MaxVertexDistance(*b.deformed);
  if (!mesh()) return std::numeric_limits<double>::infinity();
  if (!moving()) return 0.0;
  double largest = 0.0;
  for (const Vector3& v : *vertices_) largest = std::max(largest, (b.ToWorld(v) - a.ToWorld(v)).norm());
  return largest;
}

Penetration Obstacle::PenetrationOf(const ObstaclePose& pose, const MatrixN3& x) const {
  // The distances in parallel (a mesh query costs microseconds), into a
  // buffer of this thread, then summed in particle order: the same sums
  // for any thread count. The buffer grows at the first call, before any
  // step loop (the start's check, StartsInside).
  thread_local std::vector<double> distance;
  const auto n = static_cast<int>(x.rows());
  distance.resize(static_cast<std::size_t>(n));
  double* dist = distance.data();
#pragma omp parallel for schedule(dynamic, 256) if (n >= 1024 && mesh())
  for (int p = 0; p < n; ++p) {
    Vector3 dir;
    dist[p] = SignedDistance(pose, x.row(p).transpose(), &dir);
  }
  return SumPenetration(dist, n, spec_.collision_distance);
}

Penetration SumPenetration(const double* d, int n, double delta) {
  Penetration r;
  for (int p = 0; p < n; ++p) {
    if (d[p] < 0.0) {
      if (-d[p] > r.max_depth) r.max_depth = -d[p], r.deepest = p;
      r.depth_sum += -d[p];
      ++r.inside;
    }
    if (d[p] < 0.5 * delta) ++r.close;
  }
  return r;
}

ObstacleSpec HeldAt(const ObstacleSpec& spec, double t) {
  ObstacleSpec held = spec;
  // Already held at t = 0 (`held`), or nothing moves.
  if (spec.held || !spec.shape || (spec.keyframes.empty() && !spec.shape->deforms())) return held;
  const Obstacle obstacle(spec);
  const ObstaclePose pose = obstacle.PoseAt(t);
  if (pose.deformed) held.shape = pose.deformed;
  if (!spec.keyframes.empty()) {
    // R = Rz(γ) Ry(β) Rx(α) (RotationFromDegrees): Eigen's z-y-x angles.
    const Vector3 zyx = pose.rotation.eulerAngles(2, 1, 0) * (180.0 / M_PI);
    held.keyframes = {ObstacleKeyframe{0.0, pose.translation, Vector3(zyx.z(), zyx.y(), zyx.x())}};
  }
  return held;
}

ObstaclePose KeyframedMotion::PoseAt(double t) const {
  ObstaclePose pose;
  pose.anchor = anchor_;
  const auto& keys = keys_;
  if (keys.empty()) return pose;
  pose.identity = false;
  std::size_t k = 0;  // segment [k, k+1] containing t, or a held end pose
  while (k + 1 < keys.size() && keys[k + 1].t <= t) ++k;
  if (t <= keys.front().t || k + 1 == keys.size()) {
    const std::size_t held = t <= keys.front().t ? 0 : keys.size() - 1;
    pose.rotation = rotations_[held].toRotationMatrix();
    pose.translation = keys[held].translate;
    return pose;
  }
  // Linear translation and constant-rate rotation (the shortest arc from
  // R_k to R_k+1) over the segment: R(t) = exp(s θ [a]) R_k.
  const double dt = keys[k + 1].t - keys[k].t, s = (t - keys[k].t) / dt;
  Eigen::Quaterniond dq = rotations_[k + 1] * rotations_[k].inverse();
  if (dq.w() < 0.0) dq.coeffs() *= -1.0;
  const Eigen::AngleAxisd arc(dq);
  pose.rotation = Eigen::AngleAxisd(s * arc.angle(), arc.axis()) * rotations_[k].toRotationMatrix();
  pose.translation = (1.0 - s) * keys[k].translate + s * keys[k + 1].translate;
  pose.linear_velocity = (keys[k + 1].translate - keys[k].translate) / dt;
  pose.angular_velocity = (arc.angle() / dt) * arc.axis();
  return pose;
}

namespace {

// A point that no query may see: not finite, or beyond kMaxQueryMagnitude.
bool OutOfRange(const Vector3& p) { return !(p.cwiseAbs().maxCoeff() <= kMaxQueryMagnitude); }

}  // namespace

double Obstacle::SignedDistance(const ObstaclePose& pose, const Vector3& p, Vector3* dir) const {
  // A blown-up state never reaches CGAL (its exact fallback raises SIGFPE
  // on non-finite input) or the analytic formulas: it is far from every
  // obstacle, and the step that produced it ends as non_finite or
  // energy_growth (solver/run.h).
  if (OutOfRange(p)) {
    *dir = Vector3::UnitZ();
    return std::numeric_limits<double>::infinity();
  }
  if (pose.deformed) return pose.deformed->SignedDistance(p, dir);
  if (pose.identity) return shape_->SignedDistance(p, dir);
  Vector3 d_placed;
  const double d = shape_->SignedDistance(pose.ToPlaced(p), &d_placed);
  *dir = pose.ToWorldDirection(d_placed);
  return d;
}

std::optional<SegmentHit> Obstacle::FirstHit(const ObstaclePose& pose, const Vector3& a_world,
                                             const Vector3& b_world) const {
  if (OutOfRange(a_world) || OutOfRange(b_world)) return std::nullopt;  // as in SignedDistance
  if (pose.deformed) return pose.deformed->FirstHit(a_world, b_world);
  const Vector3 a = pose.ToPlaced(a_world), b = pose.ToPlaced(b_world);
  std::optional<SegmentHit> hit = shape_->FirstHit(a, b);
  if (!hit) return std::nullopt;
  hit->point = pose.ToWorld(hit->point);
  hit->normal = pose.ToWorldDirection(hit->normal);
  return hit;
}

void Obstacle::Edges(const ObstaclePose& pose, std::vector<Vector3>* vertices,
                     std::vector<std::array<int, 2>>* edges) const {
  if (pose.deformed) return pose.deformed->Edges(vertices, edges);
  shape_->Edges(vertices, edges);
  if (!pose.identity)
    for (Vector3& v : *vertices) v = pose.ToWorld(v);
}

std::string StartsInside(const Obstacle& o, const MatrixN3& x, long first) {
  const Penetration pen = o.PenetrationOf(o.PoseAt(0.0), x);
  if (pen.deepest < 0 || !(pen.max_depth > o.spec().collision_distance)) return "";
  return fmt::format("({}): particle {} starts {:.3g} m inside it at ({:g}, {:g}, {:g}) m, deeper than its collision "
                     "distance {:g} m ({} particles start inside); move the grid or the obstacle",
                     o.shape().type(), first + pen.deepest, pen.max_depth, x(pen.deepest, 0), x(pen.deepest, 1),
                     x(pen.deepest, 2), o.spec().collision_distance, pen.inside);
}

}  // namespace clothbench
