// The position-based peers' adapter to the obstacles
// (collision/obstacle_proximity.h; docs/collisions.md).
#include "collision/obstacle_proximity.h"

#include <cmath>
#include <limits>

namespace clothbench {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// The cull skips a particle only if its bound exceeds δ by this much [m]:
// the bound d_a − |p − x_a| − m is rounded in three operations, each off by
// at most an ulp of quantities below 10⁶ m (the placement's limit), about
// 10⁻¹⁰ m; 10⁻⁹ m keeps the cull exact under that rounding.
constexpr double kRoundOff = 1e-9;

// Below this many particles the queries run on one thread. A mesh query
// costs microseconds (CGAL's AABB tree), so far fewer particles pay for the
// threads than the model's kernels need (kParallelMinimum).
constexpr int kParallelQueries = 1024;

}  // namespace

ObstacleProximity::ObstacleProximity(const ParticleSystem& system) : sys_(system) {
  const std::size_t n = static_cast<std::size_t>(system.num_particles()), n_obs = system.obstacles().size();
  if (n_obs == 0) return;
  found_.reserve(n);
  hit_.assign(n, 0);
  distance_.assign(n, 0.0);
  direction_.assign(n, Vector3::Zero());
  for (const Obstacle& o : system.obstacles()) cullable_.push_back(o.mesh() != nullptr);
  motion_.assign(n_obs, 0.0);
  last_pose_.resize(n_obs);
  for (std::size_t k = 0; k < n_obs; ++k) last_pose_[k] = system.obstacles()[k].PoseAt(0.0);
  anchor_.assign(n * n_obs, Vector3::Zero());
  anchor_distance_.assign(n * n_obs, -kInf);
  anchor_motion_.assign(n * n_obs, 0.0);
}

void ObstacleProximity::Reset() {
  std::fill(anchor_distance_.begin(), anchor_distance_.end(), -kInf);
  queries_ = culled_ = 0;
}

void ObstacleProximity::set_distance_cull(bool on) {
  for (std::size_t k = 0; k < cullable_.size(); ++k) cullable_[k] = on && sys_.obstacles()[k].mesh() != nullptr;
}

const std::vector<ObstacleContact>& ObstacleProximity::Find(int k, const ObstaclePose& pose, const MatrixN3& p,
                                                            const Eigen::VectorXd& w,
                                                            const std::vector<char>* held) {
  found_.clear();
  const Obstacle& o = sys_.obstacles()[static_cast<std::size_t>(k)];
  const auto ku = static_cast<std::size_t>(k);
  const bool cull = Advance(ku, pose);
  const double delta = o.spec().collision_distance;
  const int n = sys_.num_particles();
  // The queries in parallel, each particle's into its own slot, then the
  // entries in increasing particle order: the same list for any thread count.
  long queries = 0, culled = 0;
#pragma omp parallel for schedule(dynamic, 256) reduction(+ : queries, culled) if (n >= kParallelQueries)
  for (int i = 0; i < n; ++i) {
    const auto iu = static_cast<std::size_t>(i);
    hit_[iu] = 0;
    if (w(i) == 0.0) continue;
    const double d = Query(o, ku, i, pose, p.row(i).transpose(), cull ? delta : -kInf, &queries, &culled);
    distance_[iu] = d;
    hit_[iu] = d < (held && (*held)[iu] ? 0.0 : delta) ? 1 : 0;
  }
  queries_ += queries;
  culled_ += culled;
  for (int i = 0; i < n; ++i) {
    const auto iu = static_cast<std::size_t>(i);
    if (!hit_[iu]) continue;
    ObstacleContact c;
    c.particle = i;
    c.obstacle = k;
    c.normal = direction_[iu];
    c.distance = distance_[iu];
    c.inside = true;
    found_.push_back(c);
  }
  return found_;
}

Penetration ObstacleProximity::PenetrationOf(int k, const ObstaclePose& pose, const MatrixN3& x) {
  const Obstacle& o = sys_.obstacles()[static_cast<std::size_t>(k)];
  const auto ku = static_cast<std::size_t>(k);
  const double half = 0.5 * o.spec().collision_distance;
  const bool cull = Advance(ku, pose);
  const int n = sys_.num_particles();
  long queries = 0, culled = 0;
#pragma omp parallel for schedule(dynamic, 256) reduction(+ : queries, culled) if (n >= kParallelQueries)
  for (int i = 0; i < n; ++i) {
    const auto iu = static_cast<std::size_t>(i);
    distance_[iu] = Query(o, ku, i, pose, x.row(i).transpose(), cull ? half : -kInf, &queries, &culled);
  }
  queries_ += queries;
  culled_ += culled;
  // Obstacle::PenetrationOf's sums, in particle order.
  Penetration r;
  for (int i = 0; i < n; ++i) {
    const double d = distance_[static_cast<std::size_t>(i)];
    if (d < 0.0) {
      if (-d > r.max_depth) r.max_depth = -d, r.deepest = i;
      r.depth_sum += -d;
      ++r.inside;
    }
    if (d < half) ++r.close;
  }
  return r;
}

bool ObstacleProximity::Advance(std::size_t k, const ObstaclePose& pose) {
  const bool cull = cullable_[k] != 0;
  const Obstacle& o = sys_.obstacles()[k];
  if (cull && o.moving()) {
    motion_[k] += o.MotionBound(last_pose_[k], pose);
    last_pose_[k] = pose;
  }
  return cull;
}

double ObstacleProximity::Query(const Obstacle& o, std::size_t k, int i, const ObstaclePose& pose, const Vector3& q,
                                double skip_above, long* queries, long* culled) {
  const auto iu = static_cast<std::size_t>(i);
  const std::size_t at = k * static_cast<std::size_t>(sys_.num_particles()) + iu;
  if (skip_above > -kInf) {
    const double bound = anchor_distance_[at] - (q - anchor_[at]).norm() - (motion_[k] - anchor_motion_[at]);
    if (bound > skip_above + kRoundOff) {
      ++*culled;
      return kInf;
    }
  }
  const double d = o.SignedDistance(pose, q, &direction_[iu]);
  ++*queries;
  if (cullable_[k]) {
    anchor_[at] = q;
    anchor_distance_[at] = std::isfinite(d) ? d : -kInf;
    anchor_motion_[at] = motion_[k];
  }
  return d;
}

}  // namespace clothbench
