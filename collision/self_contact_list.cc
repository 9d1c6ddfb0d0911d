// The self-contact candidate list kept over steps (self_contact_list.h).
#include "collision/self_contact_list.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace clothbench {

SelfContactList::SelfContactList(const std::vector<std::array<int, 3>>& triangles, int num_particles,
                                 const std::vector<int>& clusters, double reach, double skin)
    : detector_(triangles, num_particles, clusters), reach_(reach), skin_(skin) {
  if (!(reach > 0.0) || !(skin > 0.0)) throw std::invalid_argument("SelfContactList: reach and skin must be > 0");
  x_built_.setZero(num_particles, 3);
  rho_.assign(static_cast<std::size_t>(num_particles), 0.0);
}

double SelfContactList::Motion(const MatrixN3& x0, const MatrixN3& x1) {
  const auto n = static_cast<int>(rho_.size());
  Vector3 c0 = Vector3::Zero(), c1 = Vector3::Zero();
  for (int p = 0; p < n; ++p) {
    c0 += (x0.row(p) - x_built_.row(p)).transpose();
    c1 += (x1.row(p) - x_built_.row(p)).transpose();
  }
  c0 /= n;
  c1 /= n;
  double largest = 0.0;
  for (int p = 0; p < n; ++p) {
    const double a = ((x0.row(p) - x_built_.row(p)).transpose() - c0).squaredNorm();
    const double b = ((x1.row(p) - x_built_.row(p)).transpose() - c1).squaredNorm();
    const double r = std::sqrt(std::max(a, b));
    rho_[static_cast<std::size_t>(p)] = r;
    largest = std::max(largest, r);
  }
  return largest;
}

bool SelfContactList::Cover(const MatrixN3& x0, const MatrixN3& x1) {
  if (built_) {
    largest_ = Motion(x0, x1);
    if (largest_ <= built_skin_) return false;
  }
  x_built_ = x0;
  largest_ = Motion(x0, x1);
  Build(x0, std::max(skin_, 1.25 * largest_));
  return true;
}

void SelfContactList::Build(const MatrixN3& x0, double skin) {
  built_ = true;
  built_skin_ = skin;
  ++builds_;
  // Every pair within D at x0: boxes grown by D overlap wherever the
  // elements are within 2D, and the detector's triangle-pair pruning keeps
  // every pair of triangles within D (Candidates with x1 = x0, slack 0).
  const double d = reach_ + 2.0 * skin;
  detector_.Candidates(x0, x0, d, &candidates_);
  const auto n = static_cast<long>(candidates_.size());
  candidate_distance_.resize(candidates_.size());
#pragma omp parallel for schedule(static) if (n > kParallelPairTests)
  for (long i = 0; i < n; ++i)
    candidate_distance_[static_cast<std::size_t>(i)] = Closest(candidates_[static_cast<std::size_t>(i)], x0).distance;
  pairs_.clear();
  built_distance_.clear();
  for (std::size_t i = 0; i < candidates_.size(); ++i) {
    if (!(candidate_distance_[i] <= d)) continue;
    pairs_.push_back(candidates_[i]);
    built_distance_.push_back(candidate_distance_[i]);
  }
}

}  // namespace clothbench
