// Projective dynamics' contact impulses (Ly et al. 2020; peers/contact_impulses.h).
#include "peers/contact_impulses.h"

#include <algorithm>
#include <chrono>
#include "collision/edge_projection.h"
#include "collision/cloth_mesh.h"

namespace clothbench {

namespace {
using Clock = std::chrono::steady_clock;
double Since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }
}  // namespace

ContactImpulses::ContactImpulses(const ParticleSystem& system, const Eigen::VectorXd& w) : sys_(system), w_(w) {
  const int n = system.num_particles();
  obstacles_ = !system.obstacles().empty();
  const auto& collision = system.scene().collision;
  self_ = collision && collision->self;
  if (!active()) return;
  if (obstacles_) {
    detection_.emplace(system);
    prior_.assign(static_cast<std::size_t>(n), ObstacleDetection::Prior{});
    nodes_.reserve(static_cast<std::size_t>(n));
  }
  if (self_) {
    thickness_ = collision->thickness;
    skin_ = kSkinFraction * std::min(system.scene().lu(), system.scene().lv());
    detector_.emplace(SceneTriangles(system.scene()).vertices, n,
                      ScenePatches(system.scene(), SelfContactResponse::kPatchCells));
    pair_count_.assign(static_cast<std::size_t>(n), 0);
    motion_.assign(static_cast<std::size_t>(n), 0.0);
    x_end_.setZero(n, 3);
  }
  listed_.assign(static_cast<std::size_t>(n), 0);
  marked_.assign(static_cast<std::size_t>(n), 0);
  touched_.reserve(static_cast<std::size_t>(n));
  impulse_.setZero(n, 3);
}

void ContactImpulses::Reset() {
  if (detection_) detection_->Reset();
  std::fill(prior_.begin(), prior_.end(), ObstacleDetection::Prior{});
  nodes_.clear();
  pairs_.clear();
  work_ = ContactResponse::Work{};
  self_stats_ = SelfContactStats{};
}

int ContactImpulses::BeginStep(double t0, double h, const MatrixN3& x0, const MatrixN3& v_guess,
                               const MatrixN3* x_prev) {
  for (int p : touched_) {
    marked_[static_cast<std::size_t>(p)] = 0;
    listed_[static_cast<std::size_t>(p)] = 0;
    if (self_) pair_count_[static_cast<std::size_t>(p)] = 0;
  }
  touched_.clear();
  nodes_.clear();
  pairs_.clear();
  const auto touch = [&](int p) {
    if (marked_[static_cast<std::size_t>(p)]) return;
    marked_[static_cast<std::size_t>(p)] = 1;
    touched_.push_back(p);
  };
  if (obstacles_) {
    // The detection's test 3 (predicted entry) looks along the first
    // iterate's velocity: a sheet at rest above a floor enters within the
    // step under gravity alone.
    detection_->BeginStep(t0);
    const auto& obstacles = sys_.obstacles();
    for (int p = 0; p < sys_.num_particles(); ++p) {
      if (w_(p) == 0.0) continue;
      const Vector3 x = x0.row(p).transpose(), v = v_guess.row(p).transpose();
      Vector3 xp;
      if (x_prev) xp = x_prev->row(p).transpose();
      ObstacleContact c;
      const ObstacleDetection::Prior prior = prior_[static_cast<std::size_t>(p)];
      prior_[static_cast<std::size_t>(p)] = ObstacleDetection::Prior{};
      if (!detection_->Detect(p, h, x, v, x_prev ? &xp : nullptr, prior, 0.0, &c)) continue;
      const ObstacleSpec& spec = obstacles[static_cast<std::size_t>(c.obstacle)].spec();
      nodes_.push_back({p, c.obstacle, c.normal, (spec.collision_distance - c.distance) / h, c.v_obstacle,
                        spec.friction, Vector3::Zero()});
      listed_[static_cast<std::size_t>(p)] = 1;
      touch(p);
    }
  }
  if (self_) {
    const auto start = Clock::now();
    x_end_.noalias() = x0 + h * v_guess;
    detector_->Candidates(x0, x_end_, thickness_ + skin_, &candidates_);
    // A pair is listed if its distance at x₀, less the predicted motion of
    // a particle of each element, is within δ and the skin: the broad
    // phase's boxes report ten times more (on the fold's 900 particles).
    // (The motion relative to each other lists fewer, none while a sheet
    // falls as a whole, but the twisted strip at 1.25 ms and 4 iterations
    // then ended `speed` at t = 1.90 s.)
    for (int p = 0; p < x0.rows(); ++p) motion_[static_cast<std::size_t>(p)] = (x_end_.row(p) - x0.row(p)).norm();
    // The candidates' geometry at x₀ in parallel, each into its own slot;
    // then the list in the candidates' order.
    const auto n_candidates = static_cast<long>(candidates_.size());
    geometry_.resize(candidates_.size());
    listed_pair_.resize(candidates_.size());
#pragma omp parallel for schedule(static) if (n_candidates > kParallelPairTests)
    for (long i = 0; i < n_candidates; ++i) {
      const SelfContactPair& pair = candidates_[static_cast<std::size_t>(i)];
      const std::size_t first = pair.kind == SelfContactPair::kPointTriangle ? 1 : 2;
      double reach_a = 0.0, reach_b = 0.0;
      for (std::size_t k = 0; k < 4; ++k)
        (k < first ? reach_a : reach_b) =
            std::max(k < first ? reach_a : reach_b, motion_[static_cast<std::size_t>(pair.p[k])]);
      const PairGeometry g = Closest(pair, x0);
      geometry_[static_cast<std::size_t>(i)] = g;
      // Touching or crossed: no side to keep (the run's response).
      listed_pair_[static_cast<std::size_t>(i)] =
          g.distance > 0.0 && !(g.distance - reach_a - reach_b > thickness_ + skin_);
    }
    for (std::size_t i = 0; i < candidates_.size(); ++i) {
      if (!listed_pair_[i]) continue;
      const SelfContactPair& pair = candidates_[i];
      const PairGeometry& g = geometry_[i];
      PairContact c{pair, g.w, g.n, (thickness_ - g.distance) / h, 0.0, 0.0};
      bool free = false;
      for (std::size_t k = 0; k < 4; ++k) free = free || (w_(pair.p[k]) > 0.0 && c.w[k] != 0.0);
      if (!free) continue;
      for (int p : pair.p) ++pair_count_[static_cast<std::size_t>(p)];
      pairs_.push_back(c);
    }
    // The broad phase reports in CGAL's order; the list is sorted, so the
    // impulses' sums run in one order whatever the thread count.
    std::sort(pairs_.begin(), pairs_.end(), [](const PairContact& a, const PairContact& b) { return a.pair < b.pair; });
    for (PairContact& c : pairs_) {
      for (std::size_t k = 0; k < 4; ++k) {
        const int p = c.pair.p[k];
        c.compliance += c.w[k] * c.w[k] * pair_count_[static_cast<std::size_t>(p)] * w_(p);
        touch(p);
      }
    }
    ++self_stats_.steps;
    ++self_stats_.broad_phases;
    self_stats_.candidates += static_cast<long>(pairs_.size());
    self_stats_.detection_seconds += Since(start);
  }
  return static_cast<int>(nodes_.size());
}

void ContactImpulses::BeginIterations() {
  for (NodeContact& c : nodes_) c.r.setZero();
  for (PairContact& c : pairs_) c.r = 0.0;
  for (int p : touched_) impulse_.row(p).setZero();
}

void ContactImpulses::Refine(const MatrixN3& v, MatrixN3* b) {
  if (touched_.empty()) return;
  // Every contact from the same iterate (a Jacobi sweep): the order of the
  // lists does not enter.
  for (NodeContact& c : nodes_) {
    const double m = 1.0 / w_(c.particle);
    const Vector3 rel = v.row(c.particle).transpose() - c.v_obstacle;
    const double rel_n = rel.dot(c.normal);
    const double r_n = std::max(0.0, c.r.dot(c.normal) + m * (c.target_n - rel_n));
    Vector3 r_t = c.r - c.r.dot(c.normal) * c.normal - m * (rel - rel_n * c.normal);
    const double len = r_t.norm(), cap = c.mu * r_n;
    if (len > cap) r_t *= cap / len;  // sliding: on the disc's border, against the predicted slip
    c.r = r_n * c.normal + r_t;
  }
  const auto start = Clock::now();
  for (PairContact& c : pairs_) {
    double u = 0.0;
    for (std::size_t k = 0; k < 4; ++k) {
      const Vector3 vk = v.row(c.pair.p[k]).transpose();  // a copy: Eigen sums the dot of a strided row in another order
      u += c.w[k] * c.n.dot(vk);
    }
    c.r = std::max(0.0, c.r + (c.target - u) / c.compliance);
  }
  for (int p : touched_) impulse_.row(p).setZero();
  for (const NodeContact& c : nodes_) impulse_.row(c.particle) += c.r.transpose();
  for (const PairContact& c : pairs_)
    for (std::size_t k = 0; k < 4; ++k)
      if (w_(c.pair.p[k]) > 0.0) impulse_.row(c.pair.p[k]) += (c.w[k] * c.r) * c.n.transpose();
  for (int p : touched_) b->row(p) += impulse_.row(p);
  if (self_) self_stats_.response_seconds += Since(start);
}

int ContactImpulses::EndStep(const MatrixN3& v0, const MatrixN3& v1) {
  int acting = 0;
  double holding = 0.0, friction = 0.0;
  const auto mean = [&](int p) { return Vector3(0.5 * (v0.row(p) + v1.row(p)).transpose()); };
  for (const NodeContact& c : nodes_) {
    const double r_n = c.r.dot(c.normal);
    if (c.r.isZero(0.0)) continue;
    ++acting;
    const Vector3 vm = mean(c.particle);
    holding += r_n * c.normal.dot(vm);
    friction += (c.r - r_n * c.normal).dot(vm);
    if (r_n > 0.0) prior_[static_cast<std::size_t>(c.particle)] = {c.obstacle, c.normal, false};
  }
  for (const PairContact& c : pairs_) {
    if (c.r == 0.0) continue;
    ++acting;
    ++self_stats_.pair_impulses;
    for (std::size_t k = 0; k < 4; ++k)
      if (w_(c.pair.p[k]) > 0.0) holding += c.w[k] * c.r * c.n.dot(mean(c.pair.p[k]));
  }
  work_.holding += holding;
  work_.friction += friction;
  return acting;
}

}  // namespace clothbench
