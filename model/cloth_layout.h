// A cloth sewn from patterns (docs/model.md §2.8; thesis §2.7, §6.3): each
// pattern a block of samples, its particles in the cloth's numbering after
// the seams' pairs are merged, and across each seamed side the particles of
// the other side, so that every stencil reads across a seam as inside a
// pattern.
#ifndef CLOTHBENCH_MODEL_CLOTH_LAYOUT_H_
#define CLOTHBENCH_MODEL_CLOTH_LAYOUT_H_

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "model/pattern.h"
#include "model/types.h"

namespace clothbench {

/// One `[[seam]]`: samples first_a … last_a of side `side_a` of pattern
/// `pattern_a` sewn to samples first_b … last_b of side `side_b` of
/// pattern `pattern_b` (PatternSpec::Side; samples counted in the side's
/// direction): first_a + k to first_b + k, or to last_b − k when
/// `reversed`. A last of −1 is the side's last sample.
struct SeamSpec {
  std::string a, b;  ///< as written: "<pattern>:edge:<side>"
  bool reversed = false;
  int pattern_a = 0, side_a = 0, pattern_b = 0, side_b = 0;
  int first_a = 0, last_a = -1, first_b = 0, last_b = -1;
};

/// The sample pairs (t_a, t_b) of `seam` along its two sides (SeamSpec),
/// for sides of la and lb samples; empty if its ranges do not fit them.
std::vector<std::array<int, 2>> SeamPairs(const SeamSpec& seam, int la, int lb);

/// One pattern's block. Node (i, j), 0 ≤ i < nu, 0 ≤ j < nv, and the
/// frame of two cells around it: a cell beyond a seamed side holds the
/// node of the other side at the same depth and position along the seam,
/// -1 elsewhere.
struct ClothBlock {
  int nu = 2, nv = 2;
  Eigen::MatrixX2d plane;  ///< the nu·nv rest samples [m] in the pattern's plane, row i + nu·j
  /// Per frame cell (Cell), the cloth particle, or −1.
  std::vector<int> particle;
  /// Per frame cell, its rest position in this pattern's plane [m]: a
  /// node's sample; beyond a seam, the seam's node continued along this
  /// pattern's thread that crosses it by the other pattern's rest distance
  /// (a seam at rest is flat and straight across).
  std::vector<Eigen::Vector2d> rest;
  /// Per node, whether its stencils are this block's: every cloth particle
  /// has its stencils in exactly one block (the first pattern's node of a
  /// merged seam pair).
  std::vector<char> owner;
  int Cell(int i, int j) const { return (i + 2) + (nu + 4) * (j + 2); }
  /// The particle at (i, j), −2 ≤ i < nu + 2, −2 ≤ j < nv + 2, or −1.
  int At(int i, int j) const {
    if (i < -2 || i >= nu + 2 || j < -2 || j >= nv + 2) return -1;
    return particle[static_cast<std::size_t>(Cell(i, j))];
  }
};

/// The cloth of a scene's patterns and seams.
struct ClothLayout {
  std::vector<ClothBlock> blocks;  ///< one per pattern, in the scene's order
  int num_particles = 0;           ///< after merging
  /// Per pattern, its first particle before merging: pattern k's node
  /// (i, j) is unsewn particle first[k] + i + nu_k j.
  std::vector<int> first;
  std::vector<int> merged;   ///< per unsewn particle, its cloth particle
  MatrixN3 start;            ///< num_particles × 3 start positions [m]
  std::array<double, 2> least_spacing = {0.0, 0.0};  ///< smallest rest spacing along u and v [m]
  double largest_gap = 0.0;  ///< the largest distance between a seam's two samples at the start [m]
  /// False while a sewing phase is pending (solver/sewing.h): `start` is
  /// then each pair's midpoint, and the cloth cannot be run.
  bool sewn = true;
  /// The quads (i, j), (i+1, j), (i+1, j+1), (i, j+1) of every pattern in
  /// cloth particles, pattern by pattern.
  std::vector<std::array<int, 4>> quads;
};

/// Why `seam` cannot join `patterns`, as "<key>: <rule>", or empty: both
/// sides' patterns exist; the two sides differ; they have the same number
/// of samples.
std::string SeamRule(const std::vector<PatternSpec>& patterns, const SeamSpec& seam);

/// Builds the cloth of `patterns` (placed by PlacePattern) joined by
/// `seams`: each seam's sample pairs are merged into one particle, at the
/// pair's midpoint (docs/model.md §2.8).
/// @param samples per pattern its rest samples ((nu·nv)×2 [m]) in place of
///   SamplePattern's, or null (tests give graded samplings)
/// @throws std::invalid_argument with SeamRule's message, or if a side is in
///   two seams, or if `samples` does not match the patterns
ClothLayout BuildClothLayout(const std::vector<PatternSpec>& patterns, const std::vector<SeamSpec>& seams,
                             const std::vector<Eigen::MatrixX2d>* samples = nullptr);

}  // namespace clothbench

#endif  // CLOTHBENCH_MODEL_CLOTH_LAYOUT_H_
