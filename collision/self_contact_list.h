// A self-contact candidate list kept over many steps (docs/collisions.md,
// "Self-contact", "The list kept over steps"): a Verlet list with a skin,
// as molecular dynamics keeps its neighbour lists (Verlet 1967; Allen &
// Tildesley, Computer Simulation of Liquids, 2nd ed. 2017, §5.3).
//
// At a build at positions x_b it lists every point–triangle and edge–edge
// pair of the cloth's triangles within D = reach + 2R of each other (R the
// build's skin), with its distance d_b there. A pair's distance at any
// positions y is at least d_b − (ρ_A + ρ_B), ρ_A the largest |y_k − x_b,k − c|
// over the particles k of its first element, ρ_B over its second, for any
// common shift c (a distance of a point to a triangle, or of two edges,
// is a convex combination of the particles' positions and moves by at
// most that much). Along a straight path x0 → x1 the displacement from
// x_b less the path's own mean shift is a convex combination of the ends',
// so with ρ_k = max(|x0_k − x_b,k − c0|, |x1_k − x_b,k − c1|) (c0, c1 the
// mean displacements at the ends) the bound holds along the whole path.
// While every ρ_k ≤ R, every pair that comes within `reach` along the path
// is listed; a path that leaves the skin rebuilds the list at its start.
#ifndef CLOTHBENCH_COLLISION_SELF_CONTACT_LIST_H_
#define CLOTHBENCH_COLLISION_SELF_CONTACT_LIST_H_

#include <array>
#include <vector>

#include "collision/self_contact.h"
#include "model/types.h"

namespace clothbench {

class SelfContactList {
 public:
  /// @param triangles, num_particles, clusters as for SelfContactDetector
  /// @param reach the distance of interest [m], > 0: every pair that comes
  ///        within it along a covered path is listed
  /// @param skin R [m], > 0: how far (Euclidean, less the mean shift) a
  ///        particle may move from the build's positions before a rebuild
  /// @throws std::invalid_argument as SelfContactDetector, or if reach or
  ///         skin is not > 0
  SelfContactList(const std::vector<std::array<int, 3>>& triangles, int num_particles, const std::vector<int>& clusters,
                  double reach, double skin);

  /// Makes the list cover the straight path x0 → x1 (N×3 [m]): updates
  /// every particle's ρ_k and, if one exceeds the build's skin, rebuilds at
  /// x0 (with a skin of max(R, 1.25 · the path's largest ρ), so that a
  /// step faster than R still gets a complete list). O(N) without a build.
  /// @return whether it rebuilt
  bool Cover(const MatrixN3& x0, const MatrixN3& x1);

  /// Forgets the list: the next Cover builds.
  void Invalidate() { built_ = false; }

  const std::vector<SelfContactPair>& pairs() const { return pairs_; }
  std::size_t size() const { return pairs_.size(); }
  /// A lower bound on pair i's distance [m] along the path of the last
  /// Cover: d_b − (ρ_A + ρ_B) (above).
  double LowerBound(std::size_t i) const {
    const SelfContactPair& pair = pairs_[i];
    const auto r = [&](std::size_t k) { return rho_[static_cast<std::size_t>(pair.p[k])]; };
    if (pair.kind == SelfContactPair::kPointTriangle) return built_distance_[i] - r(0) - std::max({r(1), r(2), r(3)});
    return built_distance_[i] - std::max(r(0), r(1)) - std::max(r(2), r(3));
  }
  /// The largest ρ_k of the last Cover [m].
  double largest_motion() const { return largest_; }
  long builds() const { return builds_; }

 private:
  void Build(const MatrixN3& x0, double skin);
  // ρ_k over the path; returns the largest.
  double Motion(const MatrixN3& x0, const MatrixN3& x1);

  SelfContactDetector detector_;
  double reach_, skin_;
  bool built_ = false;
  double built_skin_ = 0.0, largest_ = 0.0;
  long builds_ = 0;
  MatrixN3 x_built_;
  std::vector<double> rho_;
  std::vector<SelfContactPair> candidates_, pairs_;
  std::vector<double> candidate_distance_, built_distance_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_COLLISION_SELF_CONTACT_LIST_H_
