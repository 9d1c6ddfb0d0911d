// A garment's pattern: a four-sided piece of fabric in its own plane,
// sampled regularly in curvilinear coordinates and placed in space
// (docs/guide/scenes.md, "Patterns"; thesis §2.7, Fig. 2.9: clothes are
// assembled from quadrilateral patterns sampled regularly in curvilinear
// coordinates, warp and weft along the sampling lines).
#ifndef CLOTHBENCH_MODEL_PATTERN_H_
#define CLOTHBENCH_MODEL_PATTERN_H_

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "model/types.h"

namespace clothbench {

using Vector2 = Eigen::Vector2d;

/// One `[[pattern]]` table. Its sides are named as a grid's edges: v0 runs
/// from corner u0v0 to u1v0, u1 from u1v0 to u1v1, v1 from u0v1 to u1v1,
/// u0 from u0v0 to u0v1 (u and v are the two thread directions).
struct PatternSpec {
  enum Side { kV0 = 0, kU1 = 1, kV1 = 2, kU0 = 3 };
  static constexpr std::array<const char*, 4> kSideNames = {"v0", "u1", "v1", "u0"};
  static constexpr std::array<const char*, 4> kCornerNames = {"u0v0", "u1v0", "u1v1", "u0v1"};
  /// Per side, the corners it runs from and to (indices into `corners`).
  static constexpr std::array<std::array<int, 2>, 4> kSideCorners = {{{0, 1}, {1, 2}, {3, 2}, {0, 3}}};

  std::string name;
  /// The corners u0v0, u1v0, u1v1, u0v1 in the pattern's plane [m],
  /// counter-clockwise.
  std::array<Vector2, 4> corners;
  /// Each side's polyline [m] in the direction named above, from its first
  /// corner to its second, at least those two points (a straight side).
  std::array<std::vector<Vector2>, 4> sides;
  int nu = 2, nv = 2;  ///< samples along u and v (>= 2)
  /// The placement: plane point (X, Y) ↦ origin + X x_axis + Y y_axis
  /// (orthonormal axes), bent around a cylinder when wrap_radius > 0
  /// (PlacePattern).
  Vector3 origin = Vector3::Zero();
  Vector3 x_axis = Vector3::UnitX(), y_axis = Vector3::UnitY();
  double wrap_radius = 0.0;  ///< [m]; 0: flat
};

/// Why `pattern` cannot be sampled, as "<key>: <rule>" (e.g. "sides.v0:
/// must start at corner u0v0 and end at corner u1v0"), or empty if it can:
/// at least 2 samples along each direction; each side's polyline starts
/// and ends at its corners (within 1e-9 of the pattern's size); the
/// outline (the four sides in turn) is a simple polygon, counter-clockwise
/// (CGAL's Polygon_2::is_simple and orientation); orthonormal axes; a
/// wrap radius >= 0.
std::string PatternRule(const PatternSpec& pattern);

/// The pattern's samples in its plane [m], (nu·nv)×2, row i + nu·j at
/// curvilinear coordinates (u, v) = (i/(nu − 1), j/(nv − 1)): the
/// transfinite (Coons) interpolation of its four sides (Coons 1967; Farin,
/// Curves and Surfaces for CAGD, 5th ed. 2002, §22.1),
///   X(u, v) = (1 − v) S_v0(u) + v S_v1(u) + (1 − u) S_u0(v) + u S_u1(v)
///             − [(1 − u)(1 − v) P00 + u(1 − v) P10 + u v P11 + (1 − u) v P01],
/// each side S parametrised by its arc length over its length. A rectangle
/// with straight sides is sampled uniformly.
/// @throws std::invalid_argument with PatternRule's message if it is not empty
Eigen::MatrixX2d SamplePattern(const PatternSpec& pattern);

/// The samples X (n×2 [m], from SamplePattern) placed in space, n×3 [m]:
/// flat, origin + X x_axis + Y y_axis; with wrap radius R > 0 the plane is
/// rolled onto the cylinder of radius R whose axis is parallel to y_axis
/// through origin − R n (n = x_axis × y_axis), keeping arc length:
///   origin + R sin(X/R) x_axis + Y y_axis − R (1 − cos(X/R)) n,
/// so that the pattern wraps away from its front (+n) side, as a front
/// panel around a body behind it.
MatrixN3 PlacePattern(const PatternSpec& pattern, const Eigen::MatrixX2d& samples);

/// Whether the pattern is a rectangle with straight sides, flat: its
/// samples are then a uniform grid (`[grid]`), with origin at corner u0v0,
/// u_axis and v_axis the placed directions of sides v0 and u0, and size
/// their lengths (set into *origin, *u_axis, *v_axis, *size).
bool PatternIsGrid(const PatternSpec& pattern, Vector3* origin, Vector3* u_axis, Vector3* v_axis,
                   std::array<double, 2>* size);

}  // namespace clothbench

#endif  // CLOTHBENCH_MODEL_PATTERN_H_
