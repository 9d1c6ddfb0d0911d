// The self-contact candidate list kept over steps (self_contact_list.h).
#include "collision/self_contact_list.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <Eigen/Geometry>

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

double SelfContactList::LowerBound(std::size_t i) const { return built_distance_[i] - RelativeMotion(pairs_[i]); }

double SelfContactList::RelativeMotion(const SelfContactPair& pair) const {
  const std::size_t first = pair.kind == SelfContactPair::kPointTriangle ? 1 : 2;
  double most = 0.0;
  for (std::size_t a = 0; a < first; ++a)
    for (std::size_t b = first; b < 4; ++b) {
      most = std::max(most, (delta0_.row(pair.p[a]) - delta0_.row(pair.p[b])).squaredNorm());
      most = std::max(most, (delta1_.row(pair.p[a]) - delta1_.row(pair.p[b])).squaredNorm());
    }
  return std::sqrt(most);
}

namespace {

// The rotation R that maximises tr(Rᵀ M) (M = Σ (y − ȳ)(x_b − x̄)ᵀ, the
// rotation of shape matching: Müller et al., "Meshless deformations based
// on shape matching", SIGGRAPH 2005, §3.3), by the iteration of Müller,
// Bender, Chentanez & Macklin, "A robust method to extract the rotational
// part of deformations", MIG 2016, Listing 1, from q (the node's last
// rotation) for at most kRotationSweeps. Any rotation keeps the bounds
// valid; the closer to M's, the tighter they are.
// Two sweeps from the last check's rotation follow a cloth's turn between
// checks; 8 sweeps to 10⁻⁹ rad spent 6.6 % of the 100 × 100 fold's SBDF(2)
// run in this function (`perf`), 2 keep it below the list's other work.
constexpr int kRotationSweeps = 2;
// A step below 10⁻⁴ rad moves a particle 8 mm from its centre by 0.8 µm,
// under 10⁻³ of the 1.5 mm skin at 10⁴ particles: not worth another sweep.
constexpr double kRotationTolerance = 1e-4;
void Rotate(const Matrix3& m, Eigen::Quaterniond* q) {
  for (int sweep = 0; sweep < kRotationSweeps; ++sweep) {
    const Matrix3 r = q->toRotationMatrix();
    const Vector3 omega = (r.col(0).cross(m.col(0)) + r.col(1).cross(m.col(1)) + r.col(2).cross(m.col(2))) /
                          (std::abs(r.col(0).dot(m.col(0)) + r.col(1).dot(m.col(1)) + r.col(2).dot(m.col(2))) + 1e-300);
    const double w = omega.norm();
    if (!(w > kRotationTolerance)) break;
    *q = Eigen::Quaterniond(Eigen::AngleAxisd(w, omega / w)) * *q;
    q->normalize();
  }
}

// max_e |(c_Be − c_Ae) + (I − Q_A)(x̄_B − x̄_A)| + ‖Q_B − Q_A‖_F ρ_B: how
// far B's particles stray from A's rigid motion, beyond σ_B (above).
template <class Node>
double Stray(const Node& a, const Node& b) {
  const Vector3 arm = b.centre - a.centre;
  const Vector3 turn = arm - a.rotation * arm;
  return std::max((b.mean0 - a.mean0 + turn).norm(), (b.mean1 - a.mean1 + turn).norm()) +
         (b.rotation - a.rotation).norm() * b.radius;
}

}  // namespace

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
      // Σ over both ends of (y − ȳ)(x_b − x̄)ᵀ, y = x_b + δ.
      Matrix3 moment = Matrix3::Zero();
      for (int k = cluster_start_[c]; k < cluster_start_[c + 1]; ++k) {
        const int p = cluster_particles_[static_cast<std::size_t>(k)];
        const Vector3 arm = x_built_.row(p).transpose() - node.centre;
        moment += (2.0 * arm + delta0_.row(p).transpose() - m0 + delta1_.row(p).transpose() - m1) * arm.transpose();
      }
      Rotate(moment, &node.turn);
      const Matrix3 q = node.turn.toRotationMatrix();
      double s = 0.0;
      for (int k = cluster_start_[c]; k < cluster_start_[c + 1]; ++k) {
        const int p = cluster_particles_[static_cast<std::size_t>(k)];
        const Vector3 arm = x_built_.row(p).transpose() - node.centre;
        const Vector3 turn = arm - q * arm;
        s = std::max({s, (delta0_.row(p).transpose() - m0 + turn).squaredNorm(),
                      (delta1_.row(p).transpose() - m1 + turn).squaredNorm()});
      }
      node.mean0 = m0;
      node.mean1 = m1;
      node.moment = moment;
      node.rotation = q;
      node.sigma = std::sqrt(s);
      continue;
    }
    // Children are stored before their parent (BuildTree); the moments add
    // with the parallel-axis terms of the children's centres.
    const Node& l = nodes_[static_cast<std::size_t>(node.left)];
    const Node& r = nodes_[static_cast<std::size_t>(node.right)];
    node.mean0 = (l.count * l.mean0 + r.count * r.mean0) / node.count;
    node.mean1 = (l.count * l.mean1 + r.count * r.mean1) / node.count;
    node.moment = l.moment + r.moment;
    for (const Node* child : {&l, &r}) {
      const Vector3 arm = child->centre - node.centre;
      node.moment += child->count * (2.0 * arm + child->mean0 - node.mean0 + child->mean1 - node.mean1) * arm.transpose();
    }
    Rotate(node.moment, &node.turn);
    node.rotation = node.turn.toRotationMatrix();
    node.sigma = std::max(l.sigma + Stray(node, l), r.sigma + Stray(node, r));
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
    const double apart = std::min(Stray(na, nb), Stray(nb, na));
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
    node.centre = centre_[c];
    for (int k = cluster_start_[c]; k < cluster_start_[c + 1]; ++k)
      node.radius = std::max(node.radius, (x_built_.row(cluster_particles_[static_cast<std::size_t>(k)]).transpose() - node.centre).norm());
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
    node.centre = (l.count * l.centre + r.count * r.centre) / node.count;
    node.radius = std::max(l.radius + (l.centre - node.centre).norm(), r.radius + (r.centre - node.centre).norm());
  }
  nodes_.push_back(node);
  return static_cast<int>(nodes_.size()) - 1;
}

bool SelfContactList::Cover(const MatrixN3& x0, const MatrixN3& x1, double reach) {
  if (!(reach > 0.0)) throw std::invalid_argument("SelfContactList::Cover: the reach must be > 0");
  if (built_ && Holds(x0, x1, reach)) return false;
  x_built_ = x0;
  Build(x0, nullptr, reach);
  if (Holds(x0, x1, reach)) return true;
  // A path too fast for the skin: the pairs that come within D along it
  // too, so that this path is covered; the next path is checked again.
  Build(x0, &x1, reach);
  return true;
}

void SelfContactList::Build(const MatrixN3& x0, const MatrixN3* path_end, double reach) {
  built_ = true;
  built_d_ = reach + 2.0 * skin_;
  ++builds_;
  // Every pair within D at some point of x0 → x1: boxes over the path
  // grown by D/2 overlap wherever the elements come within D (in each
  // coordinate), and the detector's triangle-pair pruning keeps every pair
  // of triangles that can come within margin + slack = D.
  const double d = built_d_;
  const bool swept = path_end != nullptr;
  if (swept) {  // δ at both ends (x_b = x0), for RelativeMotion and LowerBound
    delta0_.setZero();
    delta1_ = *path_end - x0;
  }
  detector_.Candidates(x0, swept ? *path_end : x0, 0.5 * d, &candidates_, 0.5 * d);
  const auto n = static_cast<long>(candidates_.size());
  candidate_distance_.resize(candidates_.size());
  // A pair whose elements' boxes are farther than D apart at x0 (a
  // diagonal neighbour that the per-coordinate overlap let through, or a
  // pair that comes near only along the path) needs no closest points:
  // that box gap bounds its distance there from below. Without a path,
  // such a pair is left out.
#pragma omp parallel for schedule(static) if (n > kParallelPairTests)
  for (long i = 0; i < n; ++i) {
    const SelfContactPair& pair = candidates_[static_cast<std::size_t>(i)];
    const double gap = ElementBoxGap(pair, x0);
    candidate_distance_[static_cast<std::size_t>(i)] = gap > d ? gap : Closest(pair, x0).distance;
  }
  pairs_.clear();
  built_distance_.clear();
  for (std::size_t i = 0; i < candidates_.size(); ++i) {
    // Along the path a pair closes by at most its largest relative vertex
    // travel (its closest points are convex combinations of its vertices,
    // as in LowerBound): one that stays farther than D is left out.
    const double travel = swept ? RelativeMotion(candidates_[i]) : 0.0;
    if (!(candidate_distance_[i] - travel <= d)) continue;
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
