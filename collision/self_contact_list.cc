// The self-contact candidate list kept over steps (self_contact_list.h).
#include "collision/self_contact_list.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace clothbench {

SelfContactList::SelfContactList(const std::vector<std::array<int, 3>>& triangles, int num_particles,
                                 const std::vector<int>& clusters, double skin)
    : detector_(triangles, num_particles, clusters), skin_(skin) {
  if (!(skin > 0.0)) throw std::invalid_argument("SelfContactList: the skin must be > 0");
  if (clusters.empty()) throw std::invalid_argument("SelfContactList: needs a cluster per triangle");
  for (MatrixN3* m : {&x_built_, &delta0_, &delta1_}) m->setZero(num_particles, 3);
  // Each cluster's particles, once each, in particle order.
  const auto& start = detector_.cluster_start();
  const auto& members = detector_.cluster_triangles();
  const std::size_t n_clusters = start.size() - 1;
  cluster_start_.assign(1, 0);
  std::vector<int> seen(static_cast<std::size_t>(num_particles), -1);
  for (std::size_t c = 0; c < n_clusters; ++c) {
    const std::size_t first = cluster_particles_.size();
    for (int k = start[c]; k < start[c + 1]; ++k)
      for (int p : triangles[static_cast<std::size_t>(members[static_cast<std::size_t>(k)])])
        if (seen[static_cast<std::size_t>(p)] != static_cast<int>(c)) {
          seen[static_cast<std::size_t>(p)] = static_cast<int>(c);
          cluster_particles_.push_back(p);
        }
    std::sort(cluster_particles_.begin() + static_cast<std::ptrdiff_t>(first), cluster_particles_.end());
    cluster_start_.push_back(static_cast<int>(cluster_particles_.size()));
  }
  mean0_.resize(n_clusters);
  mean1_.resize(n_clusters);
  sigma_.resize(n_clusters);
}

double SelfContactList::LowerBound(std::size_t i) const {
  const SelfContactPair& pair = pairs_[i];
  const std::size_t first = pair.kind == SelfContactPair::kPointTriangle ? 1 : 2;
  double most = 0.0;
  for (std::size_t a = 0; a < first; ++a)
    for (std::size_t b = first; b < 4; ++b) {
      most = std::max(most, (delta0_.row(pair.p[a]) - delta0_.row(pair.p[b])).squaredNorm());
      most = std::max(most, (delta1_.row(pair.p[a]) - delta1_.row(pair.p[b])).squaredNorm());
    }
  return built_distance_[i] - std::sqrt(most);
}

bool SelfContactList::Holds(const MatrixN3& x0, const MatrixN3& x1, double reach) {
  delta0_ = x0 - x_built_;
  delta1_ = x1 - x_built_;
  const double d = built_d_, g = built_g_;
  const Vector3 c0 = delta0_.colwise().mean().transpose(), c1 = delta1_.colwise().mean().transpose();
  double far = 0.0;
  for (std::size_t c = 0; c + 1 < cluster_start_.size(); ++c) {
    Vector3 m0 = Vector3::Zero(), m1 = Vector3::Zero();
    for (int k = cluster_start_[c]; k < cluster_start_[c + 1]; ++k) {
      const int p = cluster_particles_[static_cast<std::size_t>(k)];
      m0 += delta0_.row(p).transpose();
      m1 += delta1_.row(p).transpose();
    }
    const double count = cluster_start_[c + 1] - cluster_start_[c];
    m0 /= count;
    m1 /= count;
    double s = 0.0;
    for (int k = cluster_start_[c]; k < cluster_start_[c + 1]; ++k) {
      const int p = cluster_particles_[static_cast<std::size_t>(k)];
      s = std::max({s, (delta0_.row(p).transpose() - m0).squaredNorm(), (delta1_.row(p).transpose() - m1).squaredNorm()});
    }
    s = std::sqrt(s);
    if (2.0 * s > d - reach) return false;
    mean0_[c] = m0;
    mean1_[c] = m1;
    sigma_[c] = s;
    far = std::max(far, s + std::max((m0 - c0).norm(), (m1 - c1).norm()));
  }
  if (2.0 * far > g - reach) return false;
  for (const auto& pq : near_clusters_) {
    const auto a = static_cast<std::size_t>(pq.a), b = static_cast<std::size_t>(pq.b);
    const double apart = std::max((mean0_[a] - mean0_[b]).norm(), (mean1_[a] - mean1_[b]).norm());
    if (sigma_[a] + sigma_[b] + apart > std::max(d, pq.gap) - reach) return false;
  }
  return true;
}

bool SelfContactList::Cover(const MatrixN3& x0, const MatrixN3& x1, double reach) {
  if (!(reach > 0.0)) throw std::invalid_argument("SelfContactList::Cover: the reach must be > 0");
  if (built_ && Holds(x0, x1, reach)) return false;
  x_built_ = x0;
  double skin = skin_;
  for (;;) {
    Build(x0, reach, skin);
    if (Holds(x0, x1, reach)) return true;
    skin *= 2.0;
  }
}

void SelfContactList::Build(const MatrixN3& x0, double reach, double skin) {
  built_ = true;
  built_d_ = reach + 2.0 * skin;
  built_g_ = reach + 2.0 * kFarSkins * skin;
  ++builds_;
  // Every pair within D at x0: boxes grown by D/2 overlap wherever the
  // elements are within D (in each coordinate), and the detector's
  // triangle-pair pruning keeps every pair of triangles within margin +
  // slack = D (Candidates with x1 = x0).
  const double d = built_d_;
  detector_.Candidates(x0, x0, 0.5 * d, &candidates_, 0.5 * d);
  const auto n = static_cast<long>(candidates_.size());
  candidate_distance_.resize(candidates_.size());
  // A pair whose elements' boxes are farther than D apart (a diagonal
  // neighbour that the per-coordinate overlap let through) needs no
  // closest points.
#pragma omp parallel for schedule(static) if (n > kParallelPairTests)
  for (long i = 0; i < n; ++i) {
    const SelfContactPair& pair = candidates_[static_cast<std::size_t>(i)];
    candidate_distance_[static_cast<std::size_t>(i)] = ElementBoxGap(pair, x0) > d ? 2.0 * d : Closest(pair, x0).distance;
  }
  pairs_.clear();
  built_distance_.clear();
  for (std::size_t i = 0; i < candidates_.size(); ++i) {
    if (!(candidate_distance_[i] <= d)) continue;
    pairs_.push_back(candidates_[i]);
    built_distance_.push_back(candidate_distance_[i]);
  }
  detector_.NearClusters(x0, built_g_, &near_clusters_);
}

}  // namespace clothbench
