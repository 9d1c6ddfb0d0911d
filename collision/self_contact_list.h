// A self-contact candidate list kept over many steps (docs/notes/collisions.md,
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
// Pairs not listed. A rigid motion z = Q x_b + t keeps every distance, so
// a pair's distance at y is also at least its distance at x_b less
// max |(y_i − z_i) − (y_j − z_j)|, for any rotation Q and translation t;
// with Q fixed and t linear along the path, that too is largest at an end.
// Per cluster P (GridPatches' patches) with centre x̄_P at x_b, c_P the
// mean of δ over its triangles' particles at each end, and Q_P a rotation
// fitted to both ends (shape matching's), a particle's residual
// r_k = δ_k − c_P + (I − Q_P)(x_k − x̄_P) is y_k − z_k for z the rigid
// motion of P, and σ_P bounds |r_k| at both ends. A tree over the
// clusters (halved at the median of their centres at x_b, along the
// widest axis) gives each node A a centre, c_A, Q_A and the radius ρ_A of
// its particles about x̄_A at x_b, and
//   σ_A = max over its children C of σ_C + S(A, C), where
//   S(A, B) = max_e |c_Be − c_Ae + (I − Q_A)(x̄_B − x̄_A)| + ‖Q_B − Q_A‖_F ρ_B
// bounds how far B's particles stray from A's rigid motion beyond σ_B.
// Any pair with one element below A and one below B thus has
// |(y_i − z_i) − (y_j − z_j)| ≤ σ_A + σ_B + min(S(A, B), S(B, A)); a pair
// not listed was farther than D at x_b, and farther than the gap g_AB of
// A's and B's boxes there. The list stays complete (every pair that comes
// within `reach` along the path is in it) while every node pair (A, B)
// reached from (root, root) meets σ_A + σ_B + min(S(A, B), S(B, A)) ≤
// max(D, g_AB) − reach (for A = B: 2σ_A ≤ D − reach), a pair that does
// not being split into its children's pairs down to the clusters (the
// dual-tree traversal of Gray & Moore, "N-body problems in statistical
// learning", NIPS 2000). A path that breaks it at two clusters rebuilds
// the list at its start. With Q = I this is the plain Verlet condition;
// the rotations keep the list of a cloth that turns as a whole (a sleeve
// on a turning arm), whose displacements alone grow with the angle.
#ifndef CLOTHBENCH_COLLISION_SELF_CONTACT_LIST_H_
#define CLOTHBENCH_COLLISION_SELF_CONTACT_LIST_H_

#include <array>
#include <vector>

#include <Eigen/Geometry>

#include "collision/self_contact.h"
#include "model/types.h"

namespace clothbench {

class SelfContactList {
 public:
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
  /// reach + 2R; if they fail for this path even then (a path faster than
  /// the skin), adds the pairs whose boxes over the path come within D
  /// (the detector's swept boxes), which covers this path, and the next
  /// is checked again. O(N + C log C) without a build, C the clusters,
  /// when the clusters' motions are smooth.
  /// @return whether it rebuilt
  bool Cover(const MatrixN3& x0, const MatrixN3& x1, double reach);

  const std::vector<SelfContactPair>& pairs() const { return pairs_; }
  std::size_t size() const { return pairs_.size(); }
  /// A lower bound on pair i's distance [m] along the path of the last
  /// Cover: d_b − max |δ_i − δ_j| over both ends (above).
  double LowerBound(std::size_t i) const;
  long builds() const { return builds_; }

 private:
  // max |δ_a − δ_b| [m] over a vertex a of one element and b of the other,
  // at either end (delta0_, delta1_): how far the pair can close.
  double RelativeMotion(const SelfContactPair& pair) const;
  // Lists every pair within D at x0 or, with a path's end (N×3 [m]), every
  // pair that can come within D along x0 → *path_end, each with a lower
  // bound of its distance at x0.
  void Build(const MatrixN3& x0, const MatrixN3* path_end, double reach);
  // The tree over the clusters at x_b (boxes, children) into nodes_;
  // returns the subtree's node, its children stored before it.
  int BuildTree(int first, int last);
  // δ at both ends, and whether the list is complete for them and `reach` (above).
  bool Holds(const MatrixN3& x0, const MatrixN3& x1, double reach);
  // Each cluster's and node's c (both ends) and σ into nodes_.
  void NodeMotions();

  SelfContactDetector detector_;
  double skin_;
  bool built_ = false;
  double built_d_ = 0.0;  // the build's D [m]
  long builds_ = 0;
  MatrixN3 x_built_, delta0_, delta1_;
  // Each cluster's particles (CSR, every particle of its triangles once).
  std::vector<int> cluster_start_, cluster_particles_;
  // The tree: a node's box at x_b, its children (−1 at a cluster, whose
  // index is `cluster`), its particles' count, c at both ends and σ. The
  // clusters' order for the median splits, their centres at x_b, and the
  // traversal's stack of node pairs.
  struct Node {
    Vector3 lo = Vector3::Zero(), hi = Vector3::Zero(), centre = Vector3::Zero();
    Vector3 mean0 = Vector3::Zero(), mean1 = Vector3::Zero();
    Matrix3 moment = Matrix3::Zero(), rotation = Matrix3::Identity();
    Eigen::Quaterniond turn = Eigen::Quaterniond::Identity();  // `rotation`, the next one's start
    int left = -1, right = -1, cluster = -1;
    double count = 0.0, radius = 0.0, sigma = 0.0;
  };
  std::vector<Node> nodes_;
  std::vector<int> order_;
  std::vector<Vector3> centre_;
  std::vector<std::array<int, 2>> stack_;
  std::vector<SelfContactPair> candidates_, pairs_;
  std::vector<double> candidate_distance_, built_distance_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_COLLISION_SELF_CONTACT_LIST_H_
