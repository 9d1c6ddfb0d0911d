// The position-based peers' adapter to the obstacles
// (collision/obstacle_proximity.h; docs/notes/collisions.md).
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

ObstacleProximity::ObstacleProximity(const ParticleSystem& system)
    : sys_(system), cull_(system.obstacles(), static_cast<std::size_t>(system.num_particles())) {
  const std::size_t n = static_cast<std::size_t>(system.num_particles()), n_obs = system.obstacles().size();
  if (n_obs == 0) return;
  found_.reserve(n);
  hit_.assign(n, 0);
  distance_.assign(n, 0.0);
  direction_.assign(n, Vector3::Zero());
}

void ObstacleProximity::Reset() {
  cull_.Reset();
  queries_ = culled_ = 0;
}

void ObstacleProximity::set_distance_cull(bool on) { cull_.set_enabled(on); }

const std::vector<ObstacleContact>& ObstacleProximity::Find(int k, const ObstaclePose& pose, const MatrixN3& p,
                                                            const Eigen::VectorXd& w,
                                                            const std::vector<char>* held) {
  found_.clear();
  const Obstacle& o = sys_.obstacles()[static_cast<std::size_t>(k)];
  const auto ku = static_cast<std::size_t>(k);
  cull_.Advance(ku, pose);
  const bool cull = cull_.culls(ku);
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
  cull_.Advance(ku, pose);
  const bool cull = cull_.culls(ku);
  const int n = sys_.num_particles();
  long queries = 0, culled = 0;
#pragma omp parallel for schedule(dynamic, 256) reduction(+ : queries, culled) if (n >= kParallelQueries)
  for (int i = 0; i < n; ++i) {
    const auto iu = static_cast<std::size_t>(i);
    distance_[iu] = Query(o, ku, i, pose, x.row(i).transpose(), cull ? half : -kInf, &queries, &culled);
  }
  queries_ += queries;
  culled_ += culled;
  return SumPenetration(distance_.data(), n, o.spec().collision_distance);
}

double ObstacleProximity::Query(const Obstacle& o, std::size_t k, int i, const ObstaclePose& pose, const Vector3& q,
                                double skip_above, long* queries, long* culled) {
  const auto iu = static_cast<std::size_t>(i);
  if (skip_above > -kInf) {
    const double bound = cull_.Bound(k, iu, q);
    if (bound > skip_above + kRoundOff) {
      ++*culled;
      return kInf;
    }
  }
  const double d = o.SignedDistance(pose, q, &direction_[iu]);
  ++*queries;
  cull_.Record(k, iu, q, d);
  return d;
}

}  // namespace clothbench
