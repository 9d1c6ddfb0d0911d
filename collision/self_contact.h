// Self-contact of the cloth (docs/notes/collisions.md, "Self-contact"): the
// point–triangle and edge–edge pairs of its grid triangles that come within
// a thickness of each other or cross during a step, and the response of
// Bridson, Fedkiw & Anderson 2002 (§6–7): repulsion within the thickness,
// inelastic impulses at the instants the continuous collision detection
// (CCD) finds, and rigid impact zones (§7.4, after Provot 1997) where
// impulses alone leave a collision. The broad phase is CGAL's
// box_intersection_d on boxes swept over the step.
#ifndef CLOTHBENCH_COLLISION_SELF_CONTACT_H_
#define CLOTHBENCH_COLLISION_SELF_CONTACT_H_

#include <array>
#include <vector>

#include "collision/contact_list.h"
#include "model/types.h"

namespace clothbench {

/// Element-pair tests (closest points, the motion bound, CCD) that a
/// parallel region of the self-contact code needs before it starts a
/// second thread: about 1 ms of serial work at ~70 ns a closest-point test
/// (this project's machine). Below it the region's work is smaller than
/// what waking a thread costs when the other core is busy (another
/// process, ctest -j2), where a second thread made the fold's SBDF(2) step
/// 2.8x slower than one (scripts/self_contact_cost; docs/notes/performance.md,
/// "Parallel regions on a busy machine").
inline constexpr long kParallelPairTests = 16384;

/// Where a pair is closest, or where it touched: the weights w of its four
/// particles (relative position Σ w_k x_k: point minus triangle point, or
/// the first edge's point minus the second's), the unit normal n along
/// which that relative position is measured, and the distance [m].
struct PairGeometry {
  std::array<double, 4> w{};
  Vector3 n = Vector3::UnitZ();
  double distance = 0.0;
};

/// The closest points of `pair` at positions x (N×3 [m]): the weights, the
/// distance and the unit normal from the second element to the first (at
/// zero distance: the triangle's normal, or the edges' cross product).
/// Ericson, Real-Time Collision Detection (2005), §5.1.5 and §5.1.9.
PairGeometry Closest(const SelfContactPair& pair, const MatrixN3& x);

/// The distance [m] of the bounding boxes of the pair's two elements at x
/// (N×3 [m]): a lower bound on the elements' distance (Ericson 2005, §5.1.3)
/// at a tenth of Closest's cost.
double ElementBoxGap(const SelfContactPair& pair, const MatrixN3& x);

/// The first instant θ ∈ [0, 1] at which `pair`, its particles moving on
/// straight lines from x0 to x1 (N×3 [m]), is coplanar (the cubic of
/// Provot 1997 and Bridson et al. 2002, §6.3) with a distance of at most
/// `tolerance` [m]; the geometry there in *at (its normal turned against
/// the pair's relative motion over the step). false if none.
bool FirstCoplanarContact(const SelfContactPair& pair, const MatrixN3& x0, const MatrixN3& x1, double tolerance,
                          double* theta, PairGeometry* at);

/// The clusters of the grid's triangles (GridTriangles(nu, nv) order) for
/// SelfContactDetector: square patches of `cells` × `cells` quads.
/// @throws std::invalid_argument if nu or nv is below 2 or cells below 1
std::vector<int> GridPatches(int nu, int nv, int cells);

/// The candidate pairs of a cloth's triangles over a step: the broad phase.
class SelfContactDetector {
 public:
  /// @param triangles the cloth's triangles (GridTriangles(nu, nv).vertices,
  ///        collision/edge_projection.h), indices into N particles
  /// @param num_particles N
  /// @param clusters per triangle its cluster, 0 … C − 1 (GridPatches):
  ///        CGAL boxes the clusters, and the triangle pairs are taken
  ///        from the reported cluster pairs and from within each cluster;
  ///        empty: every triangle its own cluster
  /// @throws std::invalid_argument if a triangle names a particle outside
  ///         [0, N), or `clusters` is neither empty nor one per triangle
  SelfContactDetector(const std::vector<std::array<int, 3>>& triangles, int num_particles,
                      const std::vector<int>& clusters = {});

  /// Every point–triangle and edge–edge pair that shares no particle and
  /// whose boxes, each the bounding box of its element at x0 and at x1
  /// (N×3 [m]) grown by `margin` [m], overlap: a superset of the pairs
  /// within `margin` at x0 and of those that touch while moving linearly
  /// from x0 to x1. CGAL's box_self_intersection_d boxes the clusters
  /// only; each element pair comes from the pair of triangles that own its
  /// elements (within a cluster, or from a reported pair of clusters),
  /// once, in CGAL's order of report (the same for the same
  /// input; the response sorts the pairs it acts on); `out` is reused.
  /// Left out: the pairs of triangles whose distance at x0 exceeds
  /// `margin` + `slack` [m] + the largest displacement of a particle of
  /// one relative to one of the other over x0 → x1 (they can neither touch
  /// nor come within the margin); `slack` covers later changes of x1 that
  /// move each particle's displacement by at most slack/2.
  /// (Ericson 2005, §5.1.3's box distance bounds the triangles' distance.)
  void Candidates(const MatrixN3& x0, const MatrixN3& x1, double margin, std::vector<SelfContactPair>* out,
                  double slack = 0.0);

  /// The clusters' triangles (CSR): cluster c holds
  /// cluster_triangles()[cluster_start()[c] … cluster_start()[c + 1]).
  const std::vector<int>& cluster_start() const { return cluster_start_; }
  const std::vector<int>& cluster_triangles() const { return cluster_triangles_; }

  const std::vector<std::array<int, 3>>& triangles() const { return triangles_; }
  const std::vector<std::array<int, 2>>& edges() const { return edges_; }

 private:
  std::vector<std::array<int, 3>> triangles_;
  std::vector<std::array<int, 2>> edges_;  // unique, sorted, a < b
  int num_particles_;
  // Per triangle the particles and edges (indices into edges_) it owns, the
  // first triangle to hold them; −1 elsewhere. The broad phase boxes only
  // triangles and takes each element pair from its owners' pair.
  std::vector<std::array<int, 3>> owned_points_, owned_edges_;
  // The triangles of each cluster (CSR), and the pairs of triangles that
  // share a cluster.
  std::vector<int> cluster_start_, cluster_triangles_;
  std::vector<std::array<int, 2>> same_cluster_;
  // The element pairs of triangles ta and tb (either order) into out.
  void TrianglePair(std::size_t ta, std::size_t tb, double reach_base, std::vector<SelfContactPair>* out) const;
  // Candidates' boxes: the particles' (x0 and x1 grown by `margin`), the
  // edges' and triangles' as their hulls, the triangles' at x0 alone and
  // their particles' displacements (centre and radius).
  void ComputeBoxes(const MatrixN3& x0, const MatrixN3& x1, double margin);
  // Boxes of one call (allocated once): particles, edges, triangles.
  std::vector<Vector3> point_lo_, point_hi_, edge_lo_, edge_hi_, tri_lo_, tri_hi_;
  // Per triangle: its box at x0, and its displacements' mean and radius.
  std::vector<Vector3> tri0_lo_, tri0_hi_, move_centre_;
  std::vector<double> move_radius_;
  // The cluster pairs CGAL reported, and each chunk's element pairs (its
  // range of the same-cluster pairs, the first parts_same_[c], then of
  // the reported ones).
  std::vector<std::array<int, 2>> reported_;
  std::vector<std::vector<SelfContactPair>> parts_;
  std::vector<std::size_t> parts_same_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_COLLISION_SELF_CONTACT_H_
