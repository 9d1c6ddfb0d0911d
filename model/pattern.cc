// A garment's pattern: its rule, Coons sampling and placement (pattern.h).
#include "model/pattern.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <utility>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_2.h>
#include <Eigen/Geometry>
#include <fmt/format.h>

namespace clothbench {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;

double Size(const PatternSpec& p) {
  double size = 0.0;
  for (const Vector2& a : p.corners)
    for (const Vector2& b : p.corners) size = std::max(size, (a - b).norm());
  return size;
}

// The point at arc-length fraction t ∈ [0, 1] of a polyline.
Vector2 AlongSide(const std::vector<Vector2>& side, double t) {
  double total = 0.0;
  for (std::size_t k = 1; k < side.size(); ++k) total += (side[k] - side[k - 1]).norm();
  double target = t * total;
  for (std::size_t k = 1; k < side.size(); ++k) {
    const double piece = (side[k] - side[k - 1]).norm();
    if (target <= piece && piece > 0.0) return side[k - 1] + (target / piece) * (side[k] - side[k - 1]);
    target -= piece;
  }
  return side.back();
}

// The transfinite (Coons) sampling of the pattern's plane, nu × nv
// points, u fastest (docs/model.md §2.7), for a pattern whose sides pass
// the other rules.
Eigen::MatrixX2d Sample(const PatternSpec& p) {
  Eigen::MatrixX2d x(static_cast<Eigen::Index>(p.nu) * p.nv, 2);
  const auto& c = p.corners;
  for (int j = 0; j < p.nv; ++j) {
    const double v = static_cast<double>(j) / (p.nv - 1);
    const Vector2 u0 = AlongSide(p.sides[PatternSpec::kU0], v), u1 = AlongSide(p.sides[PatternSpec::kU1], v);
    for (int i = 0; i < p.nu; ++i) {
      const double u = static_cast<double>(i) / (p.nu - 1);
      const Vector2 v0 = AlongSide(p.sides[PatternSpec::kV0], u), v1 = AlongSide(p.sides[PatternSpec::kV1], u);
      const Vector2 corners = (1 - u) * (1 - v) * c[0] + u * (1 - v) * c[1] + u * v * c[2] + (1 - u) * v * c[3];
      x.row(i + static_cast<Eigen::Index>(p.nu) * j) =
          ((1 - v) * v0 + v * v1 + (1 - u) * u0 + u * u1 - corners).transpose();
    }
  }
  return x;
}


// The first face (i, j) of the sampling x whose two triangles do not both
// have positive area in the pattern's plane, or nothing: a strongly
// concave outline folds its transfinite sampling over itself, and a
// folded face has a negative area, so its nodes' masses can be ≤ 0.
std::optional<std::pair<int, int>> FoldedFace(const PatternSpec& p, const Eigen::MatrixX2d& x) {
  const double floor = 1e-14 * Size(p) * Size(p);
  const auto area = [&](Eigen::Index a, Eigen::Index b, Eigen::Index c) {
    const Vector2 ab = (x.row(b) - x.row(a)).transpose(), ac = (x.row(c) - x.row(a)).transpose();
    return 0.5 * (ab.x() * ac.y() - ab.y() * ac.x());
  };
  for (int j = 0; j + 1 < p.nv; ++j)
    for (int i = 0; i + 1 < p.nu; ++i) {
      const Eigen::Index k = i + static_cast<Eigen::Index>(p.nu) * j, up = k + p.nu;
      if (!(area(k, k + 1, up + 1) > floor) || !(area(k, up + 1, up) > floor) || !(area(k, k + 1, up) > floor) ||
          !(area(k + 1, up + 1, up) > floor))
        return std::pair(i, j);
    }
  return std::nullopt;
}

}  // namespace

std::string PatternRule(const PatternSpec& p) {
  if (p.nu < 2 || p.nv < 2) return fmt::format("samples: must be 2 integers >= 2 (got {}, {})", p.nu, p.nv);
  if (std::abs(p.x_axis.norm() - 1.0) > 1e-9) return "x_axis: must be a unit vector";
  if (std::abs(p.y_axis.norm() - 1.0) > 1e-9) return "y_axis: must be a unit vector";
  if (std::abs(p.x_axis.dot(p.y_axis)) > 1e-9) return "y_axis: must be orthogonal to x_axis";
  if (!(p.wrap_radius >= 0.0)) return "wrap_radius: must be >= 0";
  const double tolerance = 1e-9 * Size(p);
  for (std::size_t s = 0; s < 4; ++s) {
    const auto& side = p.sides[s];
    const auto [a, b] = PatternSpec::kSideCorners[s];
    if (side.size() < 2 || (side.front() - p.corners[a]).norm() > tolerance || (side.back() - p.corners[b]).norm() > tolerance)
      return fmt::format("sides.{}: must start at corner {} and end at corner {}", PatternSpec::kSideNames[s],
                         PatternSpec::kCornerNames[a], PatternSpec::kCornerNames[b]);
  }
  // The outline counter-clockwise: v0, u1, then v1 and u0 backwards, each
  // side without its last point (the next side's first).
  CGAL::Polygon_2<Kernel> outline;
  const auto add = [&](const std::vector<Vector2>& side, bool backwards) {
    for (std::size_t k = 0; k + 1 < side.size(); ++k) {
      const Vector2& q = backwards ? side[side.size() - 1 - k] : side[k];
      outline.push_back(Kernel::Point_2(q.x(), q.y()));
    }
  };
  add(p.sides[PatternSpec::kV0], false);
  add(p.sides[PatternSpec::kU1], false);
  add(p.sides[PatternSpec::kV1], true);
  add(p.sides[PatternSpec::kU0], true);
  if (!outline.is_simple()) return "sides: the outline crosses or touches itself";
  if (outline.orientation() != CGAL::COUNTERCLOCKWISE)
    return "corners: must run counter-clockwise, u0v0, u1v0, u1v1, u0v1";
  if (const auto face = FoldedFace(p, Sample(p)))
    return fmt::format("corners, sides: the sampling folds over itself at face ({}, {}) (a face of area <= 0 in the "
                       "pattern's plane; a strongly concave outline does): move the corners or sides",
                       face->first, face->second);
  return {};
}

Eigen::MatrixX2d SamplePattern(const PatternSpec& p) {
  if (const std::string rule = PatternRule(p); !rule.empty())
    throw std::invalid_argument(fmt::format("pattern {}: {}", p.name, rule));
  return Sample(p);
}

MatrixN3 PlacePattern(const PatternSpec& p, const Eigen::MatrixX2d& samples) {
  MatrixN3 x(samples.rows(), 3);
  const Vector3 normal = p.x_axis.cross(p.y_axis);
  const double r = p.wrap_radius;
  for (Eigen::Index k = 0; k < samples.rows(); ++k) {
    const double along = samples(k, 0), up = samples(k, 1);
    const Vector3 at = r > 0.0 ? Vector3(p.origin + r * std::sin(along / r) * p.x_axis + up * p.y_axis -
                                         r * (1.0 - std::cos(along / r)) * normal)
                               : Vector3(p.origin + along * p.x_axis + up * p.y_axis);
    x.row(k) = at.transpose();
  }
  return x;
}

bool PatternIsGrid(const PatternSpec& p, Vector3* origin, Vector3* u_axis, Vector3* v_axis, std::array<double, 2>* size) {
  if (p.wrap_radius > 0.0) return false;
  for (const auto& side : p.sides)
    if (side.size() != 2) return false;
  const auto& c = p.corners;
  const Vector2 du = c[1] - c[0], dv = c[3] - c[0];
  const double tolerance = 1e-12 * Size(p);
  if (std::abs(du.dot(dv)) > tolerance * Size(p) || (c[2] - (c[1] + dv)).norm() > tolerance) return false;
  *origin = p.origin + c[0].x() * p.x_axis + c[0].y() * p.y_axis;
  *u_axis = (du.x() * p.x_axis + du.y() * p.y_axis).normalized();
  *v_axis = (dv.x() * p.x_axis + dv.y() * p.y_axis).normalized();
  *size = {du.norm(), dv.norm()};
  return true;
}

}  // namespace clothbench
