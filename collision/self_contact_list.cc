// The self-contact candidate list kept over steps (self_contact_list.h).
#include "collision/self_contact_list.h"

#include <algorithm>
#include <cmath>
#include <limits>
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
  nodes_.reserve(2 * n_clusters - 1);
  order_.resize(n_clusters);
  centre_.resize(n_clusters);
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

void SelfContactList::NodeMotions() {
  for (Node& node : nodes_) {
    if (node.cluster >= 0) {
      const auto c = static_cast<std::size_t>(node.cluster);
      Vector3 m0 = Vector3::Zero(), m1 = Vector3::Zero();
      for (int k = cluster_start_[c]; k < cluster_start_[c + 1]; ++k) {
        const int p = cluster_particles_[static_cast<std::size_t>(k)];
        m0 += delta0_.row(p).transpose();
        m1 += delta1_.row(p).transpose();
      }
      m0 /= node.count;
      m1 /= node.count;
      double s = 0.0;
      for (int k = cluster_start_[c]; k < cluster_start_[c + 1]; ++k) {
        const int p = cluster_particles_[static_cast<std::size_t>(k)];
        s = std::max({s, (delta0_.row(p).transpose() - m0).squaredNorm(), (delta1_.row(p).transpose() - m1).squaredNorm()});
      }
      node.mean0 = m0;
      node.mean1 = m1;
      node.sigma = std::sqrt(s);
      continue;
    }
    // Children are stored before their parent (BuildTree).
    const Node& l = nodes_[static_cast<std::size_t>(node.left)];
    const Node& r = nodes_[static_cast<std::size_t>(node.right)];
    node.mean0 = (l.count * l.mean0 + r.count * r.mean0) / node.count;
    node.mean1 = (l.count * l.mean1 + r.count * r.mean1) / node.count;
    node.sigma = std::max(l.sigma + std::max((l.mean0 - node.mean0).norm(), (l.mean1 - node.mean1).norm()),
                          r.sigma + std::max((r.mean0 - node.mean0).norm(), (r.mean1 - node.mean1).norm()));
  }
}

bool SelfContactList::Holds(const MatrixN3& x0, const MatrixN3& x1, double reach) {
  delta0_ = x0 - x_built_;
  delta1_ = x1 - x_built_;
  NodeMotions();
  const double d = built_d_;
  const int root = static_cast<int>(nodes_.size()) - 1;
  stack_.clear();
  stack_.push_back({root, root});
  while (!stack_.empty()) {
    const auto [a, b] = stack_.back();
    stack_.pop_back();
    const Node& na = nodes_[static_cast<std::size_t>(a)];
    const Node& nb = nodes_[static_cast<std::size_t>(b)];
    if (a == b) {
      if (2.0 * na.sigma <= d - reach) continue;
      if (na.cluster >= 0) return false;
      stack_.push_back({na.left, na.left});
      stack_.push_back({na.right, na.right});
      stack_.push_back({na.left, na.right});
      continue;
    }
    const double gap = (nb.lo - na.hi).cwiseMax(na.lo - nb.hi).cwiseMax(0.0).norm();
    const double apart = std::max((na.mean0 - nb.mean0).norm(), (na.mean1 - nb.mean1).norm());
    if (na.sigma + nb.sigma + apart <= std::max(d, gap) - reach) continue;
    if (na.cluster >= 0 && nb.cluster >= 0) return false;
    // Split the node with more particles (a cluster is never split).
    if (nb.cluster >= 0 || (na.cluster < 0 && na.count >= nb.count)) {
      stack_.push_back({na.left, b});
      stack_.push_back({na.right, b});
    } else {
      stack_.push_back({a, nb.left});
      stack_.push_back({a, nb.right});
    }
  }
  return true;
}

int SelfContactList::BuildTree(int first, int last) {
  Node node;
  if (last - first == 1) {
    const auto c = static_cast<std::size_t>(order_[static_cast<std::size_t>(first)]);
    node.cluster = static_cast<int>(c);
    node.lo = Vector3::Constant(std::numeric_limits<double>::infinity());
    node.hi = -node.lo;
    for (int k = cluster_start_[c]; k < cluster_start_[c + 1]; ++k) {
      const int p = cluster_particles_[static_cast<std::size_t>(k)];
      node.lo = node.lo.cwiseMin(x_built_.row(p).transpose());
      node.hi = node.hi.cwiseMax(x_built_.row(p).transpose());
    }
    node.count = cluster_start_[c + 1] - cluster_start_[c];
  } else {
    Vector3 lo = Vector3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    for (int k = first; k < last; ++k) {
      lo = lo.cwiseMin(centre_[static_cast<std::size_t>(order_[static_cast<std::size_t>(k)])]);
      hi = hi.cwiseMax(centre_[static_cast<std::size_t>(order_[static_cast<std::size_t>(k)])]);
    }
    Eigen::Index axis = 0;
    (hi - lo).maxCoeff(&axis);
    const int mid = first + (last - first) / 2;
    std::nth_element(order_.begin() + first, order_.begin() + mid, order_.begin() + last, [&](int p, int q) {
      return centre_[static_cast<std::size_t>(p)](axis) < centre_[static_cast<std::size_t>(q)](axis);
    });
    node.left = BuildTree(first, mid);
    node.right = BuildTree(mid, last);
    const Node& l = nodes_[static_cast<std::size_t>(node.left)];
    const Node& r = nodes_[static_cast<std::size_t>(node.right)];
    node.lo = l.lo.cwiseMin(r.lo);
    node.hi = l.hi.cwiseMax(r.hi);
    node.count = l.count + r.count;
  }
  nodes_.push_back(node);
  return static_cast<int>(nodes_.size()) - 1;
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
  // The clusters' tree at x_b, halved at their centres' medians.
  for (std::size_t c = 0; c < order_.size(); ++c) {
    order_[c] = static_cast<int>(c);
    Vector3 sum = Vector3::Zero();
    for (int k = cluster_start_[c]; k < cluster_start_[c + 1]; ++k)
      sum += x0.row(cluster_particles_[static_cast<std::size_t>(k)]).transpose();
    centre_[c] = sum / (cluster_start_[c + 1] - cluster_start_[c]);
  }
  nodes_.clear();
  BuildTree(0, static_cast<int>(order_.size()));
}

}  // namespace clothbench
