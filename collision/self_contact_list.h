// A self-contact candidate list kept over many steps (docs/collisions.md,
// "Self-contact", "The list kept over steps"): a Verlet list with a skin,
// as molecular dynamics keeps its neighbour lists (Verlet 1967; Allen &
// Tildesley, Computer Simulation of Liquids, 2nd ed. 2017, §5.3), checked
// per cluster of triangles so that a cloth that turns as it folds keeps it.
//
// A build at positions x_b lists every point–triangle and edge–edge pair
// of the cloth's triangles within D = reach + 2R of each other (R the
// build's skin), with its distance d_b there. With δ = y − x_b, a pair's
// distance at positions y is at least d_b − max |δ_i − δ_j| over the
// particles i of its first element and j of its second (a distance of a
// point to a triangle, or of two edges, between convex combinations of the
// particles). Along a straight path x0 → x1, δ_i − δ_j is linear, so its
// largest norm is at an end: the bound of the two ends holds on the path.
//
// Pairs not listed: per cluster P (GridPatches' patches) and end e, c_P the
// mean of δ over its triangles' particles and σ_P the largest |δ_k − c_P|
// over both ends. Any pair with one element in P and one in Q has
// |δ_i − δ_j| ≤ σ_P + σ_Q + max_e |c_P − c_Q|. A pair not listed is farther
// than D at x_b, and farther than its clusters' box gap g_PQ; the list
// stays complete (every pair that comes within `reach` along the path is
// in it) while, for every cluster P, 2σ_P ≤ D − reach; for every pair of
// clusters whose gap was within G = reach + 2·kFarSkins·R at x_b,
// σ_P + σ_Q + max_e |c_P − c_Q| ≤ max(D, g_PQ) − reach; and for all others,
// with c the mean over all particles, 2 max_P (σ_P + max_e |c_P − c|) ≤
// G − reach. A path that breaks one rebuilds the list at its start.
#ifndef CLOTHBENCH_COLLISION_SELF_CONTACT_LIST_H_
#define CLOTHBENCH_COLLISION_SELF_CONTACT_LIST_H_

#include <array>
#include <vector>

#include "collision/self_contact.h"
#include "model/types.h"

namespace clothbench {

class SelfContactList {
 public:
  /// The far clusters' skin as a multiple of R: clusters apart by more than
  /// G = reach + 2·kFarSkins·R at a build are checked together, against G.
  static constexpr double kFarSkins = 8.0;

  /// @param triangles, num_particles as for SelfContactDetector
  /// @param clusters per triangle its cluster, 0 … C − 1 (GridPatches), not empty
  /// @param skin R [m], > 0
  /// @throws std::invalid_argument as SelfContactDetector, if `clusters` is
  ///         empty, or if skin is not > 0
  SelfContactList(const std::vector<std::array<int, 3>>& triangles, int num_particles, const std::vector<int>& clusters,
                  double skin);

  /// Makes the list hold every pair that comes within `reach` [m] (> 0, the
  /// distance of interest) along the straight path x0 → x1 (N×3 [m]): if
  /// the conditions above fail for this reach, rebuilds at x0 with D =
  /// reach + 2R, R doubled until they hold for this path (a step faster
  /// than R still gets a complete list). O(N + cluster pairs) without a
  /// build.
  /// @return whether it rebuilt
  bool Cover(const MatrixN3& x0, const MatrixN3& x1, double reach);

  const std::vector<SelfContactPair>& pairs() const { return pairs_; }
  std::size_t size() const { return pairs_.size(); }
  /// A lower bound on pair i's distance [m] along the path of the last
  /// Cover: d_b − max |δ_i − δ_j| over both ends (above).
  double LowerBound(std::size_t i) const;
  long builds() const { return builds_; }

 private:
  void Build(const MatrixN3& x0, double reach, double skin);
  // δ at both ends, and whether the list is complete for them and `reach` (above).
  bool Holds(const MatrixN3& x0, const MatrixN3& x1, double reach);

  SelfContactDetector detector_;
  double skin_;
  bool built_ = false;
  double built_d_ = 0.0, built_g_ = 0.0;  // the build's D and G [m]
  long builds_ = 0;
  MatrixN3 x_built_, delta0_, delta1_;
  // Each cluster's particles (CSR, every particle of its triangles once),
  // its means at both ends and its σ.
  std::vector<int> cluster_start_, cluster_particles_;
  std::vector<Vector3> mean0_, mean1_;
  std::vector<double> sigma_;
  std::vector<SelfContactDetector::ClusterPair> near_clusters_;
  std::vector<SelfContactPair> candidates_, pairs_;
  std::vector<double> candidate_distance_, built_distance_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_COLLISION_SELF_CONTACT_LIST_H_
