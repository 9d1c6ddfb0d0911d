// The projection of an obstacle edge onto a cloth face (thesis §5.3;
// collision/edge_projection.h).
#include "collision/edge_projection.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <Eigen/Geometry>
#include <Eigen/SVD>

namespace clothbench {
namespace {

// Normals that differ by less than this (about 1e-8 rad) are the same
// direction: the bisecting plane S_i becomes its flat limit.
constexpr double kSameNormal = 1e-8;

// The point where the line through the homogeneous centre (c, w) and z meets
// the plane ⟨n, Z⟩ = d; nullopt if the line is parallel to the plane.
std::optional<Vector3> ProjectPoint(const Eigen::Vector4d& centre, const Vector3& z, const Vector3& n, double d) {
  const Vector3 c = centre.head<3>();
  const double w = centre(3);
  const double hc = n.dot(c) - w * d, hz = n.dot(z) - d;
  // The line's points are α (c, w) + β (z, 1); α hc + β hz = 0 on the plane.
  const double denominator = hz * w - hc;
  if (std::abs(denominator) <= 1e-14 * (std::abs(hz * w) + std::abs(hc))) return std::nullopt;
  return Vector3((hz * c - hc * z) / denominator);
}

}  // namespace

Vector3 ProjectionFace::Normal() const { return (p[1] - p[0]).cross(p[2] - p[0]).normalized(); }

Eigen::Vector4d CentreOfProjection(const ProjectionFace& f) {
  const Vector3 n = f.Normal();
  Eigen::Matrix<double, 3, 4> planes;
  for (int i = 0; i < 3; ++i) {
    const Vector3& a = f.p[static_cast<std::size_t>(i)];
    const Vector3 e = (f.p[static_cast<std::size_t>((i + 1) % 3)] - a).normalized();
    const std::optional<Vector3>& ni = f.neighbour_normal[static_cast<std::size_t>(i)];
    Vector3 m = e.cross(n);  // the flat limit: the plane through the edge containing n_f
    if (ni && (n - *ni).norm() > kSameNormal) m = (n - *ni).normalized();
    planes.row(i) << m.transpose(), -m.dot(a);
  }
  // The homogeneous point on all three planes: the null vector of the 3×4
  // system (unique up to scale when the planes are independent).
  const Eigen::JacobiSVD<Eigen::Matrix<double, 3, 4>> svd(planes, Eigen::ComputeFullV);
  Eigen::Vector4d c = svd.matrixV().col(3);
  if (std::abs(c(3)) <= 1e-12 * c.head<3>().norm()) c(3) = 0.0;  // at infinity: parallel projection
  return c.normalized();
}

EdgeProjection ProjectEdgeOntoFace(const Vector3& x, const Vector3& y, const ProjectionFace& f,
                                   const Eigen::Vector4d& centre) {
  return ProjectEdgeOntoFace(x, y, f, centre, f.Normal());
}

EdgeProjection ProjectEdgeOntoFace(const Vector3& x, const Vector3& y, const ProjectionFace& f,
                                   const Eigen::Vector4d& centre, const Vector3& n) {
  EdgeProjection out;
  const double d = n.dot(f.p[0]);
  const double hx = n.dot(x) - d, hy = n.dot(y) - d;
  if (hx <= 0.0 && hy <= 0.0) return out;  // no part above the face
  // The part of XY above the face: parameters [s0, s1] (clipped at h = 0).
  const double s0 = hx >= 0.0 ? 0.0 : hx / (hx - hy), s1 = hy >= 0.0 ? 1.0 : hx / (hx - hy);
  const Vector3 xk = x + s0 * (y - x), yk = x + s1 * (y - x);
  const std::optional<Vector3> xb = ProjectPoint(centre, xk, n, d), yb = ProjectPoint(centre, yk, n, d);
  const std::optional<Vector3> ab = ProjectPoint(centre, 0.5 * (xk + yk), n, d);
  if (!xb || !yb || !ab) return out;
  const Vector3 dir = *yb - *xb;
  const double scale = std::max({(f.p[1] - f.p[0]).norm(), (f.p[2] - f.p[0]).norm(), dir.norm()});
  if (dir.norm() <= 1e-12 * scale) return out;  // the edge is a ray from C_f: its image is a point
  // Clip X̄ + u (Ȳ − X̄), u in [0, 1], to the triangle (Cyrus–Beck with the
  // inward normals n × (P_{i+1} − P_i) in the face's plane).
  double lo = 0.0, hi = 1.0;
  int lo_edge = -1, hi_edge = -1;
  for (int i = 0; i < 3; ++i) {
    const Vector3& a = f.p[static_cast<std::size_t>(i)];
    const Vector3 k = n.cross(f.p[static_cast<std::size_t>((i + 1) % 3)] - a);
    const double num = k.dot(*xb - a), den = k.dot(dir);
    if (std::abs(den) <= 1e-14 * k.norm() * dir.norm()) {
      if (num < 0.0) return out;  // parallel to edge i and outside it
      continue;
    }
    const double u = -num / den;
    if (den > 0.0 && u > lo) {
      lo = u;
      lo_edge = i;
    } else if (den < 0.0 && u < hi) {
      hi = u;
      hi_edge = i;
    }
  }
  if (lo >= hi) return out;
  // Back onto XY by the cross ratio: with Ā at parameter ua of X̄Ȳ, a point
  // at u comes from the point of the kept segment at
  // t = u (1 − ua) / (u (1 − ua) + (1 − u) ua).
  const double ua = dir.dot(*ab - *xb) / dir.squaredNorm();
  const auto back = [&](double u) {
    const double t = u * (1.0 - ua) / (u * (1.0 - ua) + (1.0 - u) * ua);
    return s0 + t * (s1 - s0);
  };
  out.hit = true;
  out.v_bar = *xb + lo * dir;
  out.w_bar = *xb + hi * dir;
  out.sv = back(lo);
  out.sw = back(hi);
  out.v = x + out.sv * (y - x);
  out.w = x + out.sw * (y - x);
  out.v_edge = lo_edge;
  out.w_edge = hi_edge;
  return out;
}

ClothTriangles GridTriangles(int nu, int nv) {
  if (nu < 2 || nv < 2) throw std::invalid_argument("GridTriangles: the grid needs at least 2 × 2 particles");
  ClothTriangles out;
  const int quads = (nu - 1) * (nv - 1);
  out.vertices.reserve(static_cast<std::size_t>(2 * quads));
  out.across.reserve(static_cast<std::size_t>(2 * quads));
  // Quad q = i + (nu − 1) j has triangles 2q (lower: (i, j), (i+1, j),
  // (i+1, j+1)) and 2q + 1 (upper: (i, j), (i+1, j+1), (i, j+1)).
  const auto quad = [&](int i, int j) { return i >= 0 && i < nu - 1 && j >= 0 && j < nv - 1 ? i + (nu - 1) * j : -1; };
  for (int j = 0; j < nv - 1; ++j)
    for (int i = 0; i < nu - 1; ++i) {
      const int p = i + nu * j, q = quad(i, j);
      const int below = quad(i, j - 1), right = quad(i + 1, j), above = quad(i, j + 1), left = quad(i - 1, j);
      // Lower: edge (i,j)→(i+1,j) is the top of the quad below, in its
      // upper triangle; (i+1,j)→(i+1,j+1) the left side of the quad to the
      // right, in its upper triangle; (i+1,j+1)→(i,j) this quad's diagonal.
      out.vertices.push_back({p, p + 1, p + 1 + nu});
      out.across.push_back({below >= 0 ? 2 * below + 1 : -1, right >= 0 ? 2 * right + 1 : -1, 2 * q + 1});
      // Upper: the diagonal; (i+1,j+1)→(i,j+1) the bottom of the quad
      // above, in its lower triangle; (i,j+1)→(i,j) the right side of the
      // quad to the left, in its lower triangle.
      out.vertices.push_back({p, p + 1 + nu, p + nu});
      out.across.push_back({2 * q, above >= 0 ? 2 * above : -1, left >= 0 ? 2 * left : -1});
    }
  return out;
}

}  // namespace clothbench
