// Self-contact detection (self_contact.h): the closest points and the
// coplanarity instants of point–triangle and edge–edge pairs, and the broad
// phase (CGAL's box_intersection_d). All CGAL code of it stays here.
#include "collision/self_contact.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include <CGAL/box_intersection_d.h>
#include <Eigen/Geometry>
#include <omp.h>

namespace clothbench {
namespace {

// Barycentric weights (α, β, γ) of the point of triangle abc closest to p
// (Ericson 2005, §5.1.5, by Voronoi regions). A triangle of zero area
// gives its closest vertex or edge point by the same regions, or a if all
// three coincide.
std::array<double, 3> ClosestOnTriangle(const Vector3& p, const Vector3& a, const Vector3& b, const Vector3& c) {
  const Vector3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return {1.0, 0.0, 0.0};
  const Vector3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return {0.0, 1.0, 0.0};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double v = d1 / (d1 - d3);
    return {1.0 - v, v, 0.0};
  }
  const Vector3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return {0.0, 0.0, 1.0};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double w = d2 / (d2 - d6);
    return {1.0 - w, 0.0, w};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0.0, 1.0 - w, w};
  }
  const double sum = va + vb + vc;
  if (!(sum > 0.0)) return {1.0, 0.0, 0.0};
  const double v = vb / sum, w = vc / sum;
  return {1.0 - v - w, v, w};
}

// Parameters (s, t) ∈ [0, 1]² of the closest points p1 + s(q1 − p1) and
// p2 + t(q2 − p2) of two segments (Ericson 2005, §5.1.9). Parallel
// segments (a·e − b² below 1e-14 a·e) take s = 0.
std::array<double, 2> ClosestOnSegments(const Vector3& p1, const Vector3& q1, const Vector3& p2, const Vector3& q2) {
  const Vector3 d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  if (!(a > 0.0) && !(e > 0.0)) return {0.0, 0.0};
  if (!(a > 0.0)) return {0.0, std::clamp(f / e, 0.0, 1.0)};
  const double c = d1.dot(r);
  if (!(e > 0.0)) return {std::clamp(-c / a, 0.0, 1.0), 0.0};
  const double b = d1.dot(d2), denom = a * e - b * b;
  double s = denom > 1e-14 * a * e ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
  double t = (b * s + f) / e;
  if (t < 0.0) {
    t = 0.0;
    s = std::clamp(-c / a, 0.0, 1.0);
  } else if (t > 1.0) {
    t = 1.0;
    s = std::clamp((b - c) / a, 0.0, 1.0);
  }
  return {s, t};
}

Vector3 Row(const MatrixN3& x, int p) { return x.row(p).transpose(); }

// The pair's plane normal at positions x: the triangle's, or the edges'
// cross product; zero if degenerate.
Vector3 PlaneNormal(const SelfContactPair& pair, const std::array<Vector3, 4>& q) {
  const Vector3 n = pair.kind == SelfContactPair::kPointTriangle ? (q[2] - q[1]).cross(q[3] - q[1])
                                                                 : (q[1] - q[0]).cross(q[3] - q[2]);
  const double len = n.norm();
  return len > 0.0 ? Vector3(n / len) : Vector3::Zero();
}

PairGeometry ClosestOf(const SelfContactPair& pair, const std::array<Vector3, 4>& q) {
  PairGeometry g;
  if (pair.kind == SelfContactPair::kPointTriangle) {
    const auto bary = ClosestOnTriangle(q[0], q[1], q[2], q[3]);
    g.w = {1.0, -bary[0], -bary[1], -bary[2]};
  } else {
    const auto st = ClosestOnSegments(q[0], q[1], q[2], q[3]);
    g.w = {1.0 - st[0], st[0], -(1.0 - st[1]), -st[1]};
  }
  Vector3 r = Vector3::Zero();
  for (int k = 0; k < 4; ++k) r += g.w[static_cast<std::size_t>(k)] * q[static_cast<std::size_t>(k)];
  g.distance = r.norm();
  // Below 1e-12 m the direction of r is round-off: the plane's normal,
  // turned toward r where r has a direction at all.
  if (g.distance > 1e-12) {
    g.n = r / g.distance;
  } else {
    const Vector3 n = PlaneNormal(pair, q);
    g.n = n.squaredNorm() > 0.0 ? (n.dot(r) < 0.0 ? Vector3(-n) : n) : Vector3::UnitZ();
  }
  return g;
}

std::array<Vector3, 4> Corners(const SelfContactPair& pair, const MatrixN3& x) {
  return {Row(x, pair.p[0]), Row(x, pair.p[1]), Row(x, pair.p[2]), Row(x, pair.p[3])};
}

// The pair's positions at θ along the straight paths a + θd.
void PositionsAt(const std::array<Vector3, 4>& a, const std::array<Vector3, 4>& d, double theta,
                 std::array<Vector3, 4>* q) {
  for (std::size_t k = 0; k < 4; ++k) (*q)[k] = a[k] + theta * d[k];
}

}  // namespace

PairGeometry Closest(const SelfContactPair& pair, const MatrixN3& x) { return ClosestOf(pair, Corners(pair, x)); }

double ElementBoxGap(const SelfContactPair& pair, const MatrixN3& x) {
  const std::size_t first = pair.kind == SelfContactPair::kPointTriangle ? 1 : 2;
  Vector3 lo_a = Row(x, pair.p[0]), hi_a = lo_a;
  Vector3 lo_b = Row(x, pair.p[first]), hi_b = lo_b;
  for (std::size_t k = 1; k < 4; ++k) {
    if (k == first) continue;
    const Vector3 q = Row(x, pair.p[k]);
    Vector3& lo = k < first ? lo_a : lo_b;
    Vector3& hi = k < first ? hi_a : hi_b;
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  return (lo_b - hi_a).cwiseMax(lo_a - hi_b).cwiseMax(0.0).norm();
}

bool FirstCoplanarContact(const SelfContactPair& pair, const MatrixN3& x0, const MatrixN3& x1, double tolerance,
                          double* theta, PairGeometry* at) {
  const std::array<Vector3, 4> a = Corners(pair, x0), b = Corners(pair, x1);
  std::array<Vector3, 4> d;
  for (std::size_t k = 0; k < 4; ++k) d[k] = b[k] - a[k];
  // f(θ) = (E₁ + θD₁) × (E₂ + θD₂) · (Q + θD_Q) = c₀ + c₁θ + c₂θ² + c₃θ³;
  // its critical points split [0, 1] into pieces on which f is monotone.
  Vector3 e1, d1, e2, d2, q, dq;
  if (pair.kind == SelfContactPair::kPointTriangle) {
    e1 = a[2] - a[1], d1 = d[2] - d[1], e2 = a[3] - a[1], d2 = d[3] - d[1], q = a[0] - a[1], dq = d[0] - d[1];
  } else {
    e1 = a[1] - a[0], d1 = d[1] - d[0], e2 = a[3] - a[2], d2 = d[3] - d[2], q = a[2] - a[0], dq = d[2] - d[0];
  }
  const Vector3 n0 = e1.cross(e2), n1 = e1.cross(d2) + d1.cross(e2), n2 = d1.cross(d2);
  const double c1 = n0.dot(dq) + n1.dot(q), c2 = n1.dot(dq) + n2.dot(q), c3 = n2.dot(dq);
  std::array<double, 4> cuts{0.0, 1.0, 1.0, 1.0};
  int n_cuts = 1;
  // Roots of f' = c₁ + 2c₂θ + 3c₃θ² in (0, 1).
  const double qa = 3.0 * c3, qb = 2.0 * c2, qc = c1;
  if (qa != 0.0) {
    const double disc = qb * qb - 4.0 * qa * qc;
    if (disc > 0.0) {
      const double sq = std::sqrt(disc);
      // The numerically stable pair of roots.
      const double u = -0.5 * (qb + (qb >= 0.0 ? sq : -sq));
      for (double r : {u / qa, u != 0.0 ? qc / u : -1.0})
        if (r > 0.0 && r < 1.0) cuts[static_cast<std::size_t>(n_cuts++)] = r;
    }
  } else if (qb != 0.0) {
    const double r = -qc / qb;
    if (r > 0.0 && r < 1.0) cuts[static_cast<std::size_t>(n_cuts++)] = r;
  }
  cuts[static_cast<std::size_t>(n_cuts++)] = 1.0;
  std::sort(cuts.begin(), cuts.begin() + n_cuts);
  // Signs and roots on the cubic's coefficients (4 operations a value);
  // the positions only at a root.
  const double c0 = n0.dot(q);
  const auto f = [&](double t) { return ((c3 * t + c2) * t + c1) * t + c0; };
  std::array<Vector3, 4> pos;
  double f_lo = f(cuts[0]);
  for (int i = 0; i + 1 < n_cuts; ++i) {
    double lo = cuts[static_cast<std::size_t>(i)], hi = cuts[static_cast<std::size_t>(i) + 1];
    const double f_hi = f(hi);
    double root = -1.0;
    if (f_lo == 0.0) {
      root = lo;
    } else if ((f_lo < 0.0) != (f_hi < 0.0)) {
      // Bisection to the last bit of θ (about 50 halvings of [0, 1]).
      const bool rising = f_lo < 0.0;
      while (hi - lo > 1e-15) {
        const double mid = 0.5 * (lo + hi);
        ((f(mid) < 0.0) == rising ? lo : hi) = mid;
      }
      root = hi;
    } else if (f_hi == 0.0 && i + 2 == n_cuts) {
      root = hi;
    }
    f_lo = f_hi;
    if (root < 0.0) continue;
    PositionsAt(a, d, root, &pos);
    PairGeometry g = ClosestOf(pair, pos);
    if (!(g.distance <= tolerance)) continue;
    // The plane's normal at the contact (the closest points' direction is
    // round-off there), or theirs if the pair is degenerate; turned so that
    // the relative motion over the step runs against it (approach).
    const Vector3 plane = PlaneNormal(pair, pos);
    if (plane.squaredNorm() > 0.0) g.n = plane;
    Vector3 rel = Vector3::Zero();
    for (std::size_t k = 0; k < 4; ++k) rel += g.w[k] * d[k];
    if (g.n.dot(rel) > 0.0) g.n = -g.n;
    *theta = root;
    *at = g;
    return true;
  }
  return false;
}

std::vector<int> GridPatches(int nu, int nv, int cells) {
  if (nu < 2 || nv < 2 || cells < 1) throw std::invalid_argument("GridPatches: needs nu, nv ≥ 2 and cells ≥ 1");
  const int across = (nu - 1 + cells - 1) / cells;
  std::vector<int> out;
  out.reserve(static_cast<std::size_t>(2 * (nu - 1) * (nv - 1)));
  for (int j = 0; j < nv - 1; ++j)
    for (int i = 0; i < nu - 1; ++i) {
      const int patch = i / cells + across * (j / cells);
      out.push_back(patch);  // the quad's lower and upper triangles
      out.push_back(patch);
    }
  return out;
}

SelfContactDetector::SelfContactDetector(const std::vector<std::array<int, 3>>& triangles, int num_particles,
                                         const std::vector<int>& clusters)
    : triangles_(triangles), num_particles_(num_particles) {
  if (!clusters.empty() && clusters.size() != triangles.size())
    throw std::invalid_argument("SelfContactDetector: " + std::to_string(clusters.size()) + " clusters for " +
                                std::to_string(triangles.size()) + " triangles");
  // Clusters (CSR), each triangle its own without them.
  const int n_clusters =
      clusters.empty() ? static_cast<int>(triangles.size()) : *std::max_element(clusters.begin(), clusters.end()) + 1;
  cluster_start_.assign(static_cast<std::size_t>(n_clusters) + 1, 0);
  const auto cluster = [&](std::size_t k) { return clusters.empty() ? static_cast<int>(k) : clusters[k]; };
  for (std::size_t k = 0; k < triangles.size(); ++k) {
    if (cluster(k) < 0) throw std::invalid_argument("SelfContactDetector: a negative cluster");
    ++cluster_start_[static_cast<std::size_t>(cluster(k)) + 1];
  }
  for (std::size_t c = 0; c + 1 < cluster_start_.size(); ++c) cluster_start_[c + 1] += cluster_start_[c];
  cluster_triangles_.resize(triangles.size());
  std::vector<int> fill(cluster_start_.begin(), cluster_start_.end() - 1);
  for (std::size_t k = 0; k < triangles.size(); ++k)
    cluster_triangles_[static_cast<std::size_t>(fill[static_cast<std::size_t>(cluster(k))]++)] = static_cast<int>(k);
  for (std::size_t c = 0; c + 1 < cluster_start_.size(); ++c)
    for (int a = cluster_start_[c]; a < cluster_start_[c + 1]; ++a)
      for (int b = a + 1; b < cluster_start_[c + 1]; ++b)
        same_cluster_.push_back({cluster_triangles_[static_cast<std::size_t>(a)], cluster_triangles_[static_cast<std::size_t>(b)]});
  for (std::size_t k = 0; k < triangles.size(); ++k)
    for (int p : triangles[k])
      if (p < 0 || p >= num_particles)
        throw std::invalid_argument("SelfContactDetector: triangle " + std::to_string(k) + " names particle " +
                                    std::to_string(p) + " of " + std::to_string(num_particles));
  for (const auto& t : triangles)
    for (int k = 0; k < 3; ++k) {
      const int a = t[static_cast<std::size_t>(k)], b = t[static_cast<std::size_t>((k + 1) % 3)];
      edges_.push_back({std::min(a, b), std::max(a, b)});
    }
  std::sort(edges_.begin(), edges_.end());
  edges_.erase(std::unique(edges_.begin(), edges_.end()), edges_.end());
  // Owners: the first triangle that holds each particle and each edge.
  std::vector<int> particle_owner(static_cast<std::size_t>(num_particles), -1);
  owned_points_.assign(triangles.size(), {-1, -1, -1});
  owned_edges_.assign(triangles.size(), {-1, -1, -1});
  for (std::size_t k = 0; k < triangles.size(); ++k)
    for (std::size_t c = 0; c < 3; ++c) {
      const int p = triangles[k][c];
      if (particle_owner[static_cast<std::size_t>(p)] < 0) {
        particle_owner[static_cast<std::size_t>(p)] = static_cast<int>(k);
        owned_points_[k][c] = p;
      }
    }
  std::vector<char> edge_owned(edges_.size(), 0);
  for (std::size_t k = 0; k < triangles.size(); ++k)
    for (std::size_t c = 0; c < 3; ++c) {
      const int a = triangles[k][c], b = triangles[k][(c + 1) % 3];
      const std::array<int, 2> e{std::min(a, b), std::max(a, b)};
      const std::size_t index = static_cast<std::size_t>(std::lower_bound(edges_.begin(), edges_.end(), e) - edges_.begin());
      if (!edge_owned[index]) {
        edge_owned[index] = 1;
        owned_edges_[k][c] = static_cast<int>(index);
      }
    }
}

namespace {

// A box with its cluster's index as its id (CGAL breaks ties between equal
// coordinates by id: by index, its report order is the same on every run).
class TriangleBox : public CGAL::Box_intersection_d::Box_d<double, 3, CGAL::Box_intersection_d::ID_NONE> {
 public:
  using Base = CGAL::Box_intersection_d::Box_d<double, 3, CGAL::Box_intersection_d::ID_NONE>;
  using ID = std::size_t;
  TriangleBox(double lo[3], double hi[3], std::size_t index) : Base(lo, hi), index_(index) {}
  std::size_t id() const { return index_; }

 private:
  std::size_t index_;
};

// Whether two closed boxes overlap.
bool Overlap(const Vector3& alo, const Vector3& ahi, const Vector3& blo, const Vector3& bhi) {
  return (alo.array() <= bhi.array()).all() && (blo.array() <= ahi.array()).all();
}

}  // namespace

void SelfContactDetector::TrianglePair(std::size_t ta, std::size_t tb, double reach_base,
                                       std::vector<SelfContactPair>* out) const {
  // The triangles' distance at x0 is at least their boxes' there; over
  // the step it shrinks by at most the largest displacement of a particle
  // of one relative to one of the other, |c_a − c_b| + r_a + r_b. Pairs
  // that stay further apart than the margin (and the slack, reach_base in
  // all) have no element pair to test: a sheet that slides along itself is
  // left out.
  const Vector3 gap = (tri0_lo_[tb] - tri0_hi_[ta]).cwiseMax(tri0_lo_[ta] - tri0_hi_[tb]).cwiseMax(0.0);
  const double reach = reach_base + (move_centre_[ta] - move_centre_[tb]).norm() + move_radius_[ta] + move_radius_[tb];
  if (gap.squaredNorm() > reach * reach) return;
  for (int flip = 0; flip < 2; ++flip) {
    const std::size_t a = flip ? tb : ta, b = flip ? ta : tb;
    const auto& tri = triangles_[b];
    for (int p : owned_points_[a]) {
      if (p < 0 || p == tri[0] || p == tri[1] || p == tri[2]) continue;
      const std::size_t q = static_cast<std::size_t>(p);
      if (Overlap(point_lo_[q], point_hi_[q], tri_lo_[b], tri_hi_[b]))
        out->push_back({SelfContactPair::kPointTriangle, {p, tri[0], tri[1], tri[2]}});
    }
  }
  for (int e : owned_edges_[ta]) {
    if (e < 0) continue;
    const auto& ea = edges_[static_cast<std::size_t>(e)];
    for (int f : owned_edges_[tb]) {
      if (f < 0) continue;
      const auto& fb = edges_[static_cast<std::size_t>(f)];
      if (ea[0] == fb[0] || ea[0] == fb[1] || ea[1] == fb[0] || ea[1] == fb[1]) continue;
      if (!Overlap(edge_lo_[static_cast<std::size_t>(e)], edge_hi_[static_cast<std::size_t>(e)],
                   edge_lo_[static_cast<std::size_t>(f)], edge_hi_[static_cast<std::size_t>(f)]))
        continue;
      out->push_back(ea < fb ? SelfContactPair{SelfContactPair::kEdgeEdge, {ea[0], ea[1], fb[0], fb[1]}}
                             : SelfContactPair{SelfContactPair::kEdgeEdge, {fb[0], fb[1], ea[0], ea[1]}});
    }
  }
}

void SelfContactDetector::ComputeBoxes(const MatrixN3& x0, const MatrixN3& x1, double margin) {
  // The boxes of the particles (x0 and x1 grown by the margin), then of the
  // edges and triangles as the hulls of their particles' boxes.
  point_lo_.resize(static_cast<std::size_t>(num_particles_));
  point_hi_.resize(static_cast<std::size_t>(num_particles_));
  for (int p = 0; p < num_particles_; ++p) {
    const Vector3 a = x0.row(p).transpose(), b = x1.row(p).transpose();
    point_lo_[static_cast<std::size_t>(p)] = a.cwiseMin(b).array() - margin;
    point_hi_[static_cast<std::size_t>(p)] = a.cwiseMax(b).array() + margin;
  }
  edge_lo_.resize(edges_.size());
  edge_hi_.resize(edges_.size());
  for (std::size_t k = 0; k < edges_.size(); ++k) {
    const auto [a, b] = edges_[k];
    edge_lo_[k] = point_lo_[static_cast<std::size_t>(a)].cwiseMin(point_lo_[static_cast<std::size_t>(b)]);
    edge_hi_[k] = point_hi_[static_cast<std::size_t>(a)].cwiseMax(point_hi_[static_cast<std::size_t>(b)]);
  }
  tri_lo_.resize(triangles_.size());
  tri_hi_.resize(triangles_.size());
  tri0_lo_.resize(triangles_.size());
  tri0_hi_.resize(triangles_.size());
  move_centre_.resize(triangles_.size());
  move_radius_.resize(triangles_.size());
  for (std::size_t k = 0; k < triangles_.size(); ++k) {
    const auto& t = triangles_[k];
    Vector3 lo = point_lo_[static_cast<std::size_t>(t[0])], hi = point_hi_[static_cast<std::size_t>(t[0])];
    for (std::size_t c = 1; c < 3; ++c) {
      lo = lo.cwiseMin(point_lo_[static_cast<std::size_t>(t[c])]);
      hi = hi.cwiseMax(point_hi_[static_cast<std::size_t>(t[c])]);
    }
    tri_lo_[k] = lo;
    tri_hi_[k] = hi;
    // The triangle's box at x0 alone, and its particles' displacements
    // x1 − x0 as a centre (their mean) and a radius about it.
    Vector3 lo0 = x0.row(t[0]).transpose(), hi0 = lo0, mean = Vector3::Zero();
    std::array<Vector3, 3> d;
    for (std::size_t c = 0; c < 3; ++c) {
      const Vector3 a = x0.row(t[c]).transpose();
      lo0 = lo0.cwiseMin(a);
      hi0 = hi0.cwiseMax(a);
      d[c] = x1.row(t[c]).transpose() - a;
      mean += d[c];
    }
    mean /= 3.0;
    tri0_lo_[k] = lo0;
    tri0_hi_[k] = hi0;
    move_centre_[k] = mean;
    move_radius_[k] = std::max({(d[0] - mean).norm(), (d[1] - mean).norm(), (d[2] - mean).norm()});
  }
}

void SelfContactDetector::Candidates(const MatrixN3& x0, const MatrixN3& x1, double margin,
                                     std::vector<SelfContactPair>* out, double slack) {
  out->clear();
  ComputeBoxes(x0, x1, margin);
  // Each pair of elements from the pair of triangles that own them (a
  // particle's or edge's box lies in its owner's, so the owners' boxes
  // overlap whenever the elements' do): every pair exactly once. The
  // triangle pairs come from within each cluster and from the cluster
  // pairs whose boxes CGAL reports.
  const std::size_t n_clusters = cluster_start_.size() - 1;
  std::vector<TriangleBox> boxes;
  boxes.reserve(n_clusters);
  for (std::size_t c = 0; c < n_clusters; ++c) {
    const std::size_t first = static_cast<std::size_t>(cluster_triangles_[static_cast<std::size_t>(cluster_start_[c])]);
    Vector3 lo = tri_lo_[first], hi = tri_hi_[first];
    for (int k = cluster_start_[c] + 1; k < cluster_start_[c + 1]; ++k) {
      const std::size_t t = static_cast<std::size_t>(cluster_triangles_[static_cast<std::size_t>(k)]);
      lo = lo.cwiseMin(tri_lo_[t]);
      hi = hi.cwiseMax(tri_hi_[t]);
    }
    double l[3] = {lo.x(), lo.y(), lo.z()}, h[3] = {hi.x(), hi.y(), hi.z()};
    boxes.emplace_back(l, h, c);
  }
  reported_.clear();
  CGAL::box_self_intersection_d(boxes.begin(), boxes.end(), [&](const TriangleBox& first, const TriangleBox& second) {
    reported_.push_back({static_cast<int>(first.id()), static_cast<int>(second.id())});
  });
  // The triangle pairs within each cluster, then those of the reported
  // cluster pairs in CGAL's order, in kChunks contiguous ranges of both
  // lists, each into a part of its own; the threads take the chunks one at
  // a time (a thread slowed by another process on its core takes fewer),
  // and the parts are joined in chunk order: the serial order for any
  // thread count. From about a millisecond of work up (a reported cluster
  // pair is up to 64 triangle pairs; kParallelPairTests).
  const auto n_same = static_cast<std::ptrdiff_t>(same_cluster_.size());
  const auto n_reported = static_cast<std::ptrdiff_t>(reported_.size());
  const bool parallel = n_same + 64 * n_reported >= 4 * kParallelPairTests;
  constexpr std::ptrdiff_t kChunks = 16;
  if (parts_.size() < static_cast<std::size_t>(kChunks)) {
    parts_.resize(static_cast<std::size_t>(kChunks));
    parts_same_.resize(static_cast<std::size_t>(kChunks));
  }
#pragma omp parallel for schedule(dynamic, 1) if (parallel)
  for (std::ptrdiff_t c = 0; c < kChunks; ++c) {
    std::vector<SelfContactPair>& part = parts_[static_cast<std::size_t>(c)];
    part.clear();
    for (std::ptrdiff_t k = n_same * c / kChunks; k < n_same * (c + 1) / kChunks; ++k) {
      const auto ta = static_cast<std::size_t>(same_cluster_[static_cast<std::size_t>(k)][0]);
      const auto tb = static_cast<std::size_t>(same_cluster_[static_cast<std::size_t>(k)][1]);
      if (Overlap(tri_lo_[ta], tri_hi_[ta], tri_lo_[tb], tri_hi_[tb])) TrianglePair(ta, tb, margin + slack, &part);
    }
    parts_same_[static_cast<std::size_t>(c)] = part.size();
    for (std::ptrdiff_t k = n_reported * c / kChunks; k < n_reported * (c + 1) / kChunks; ++k) {
      const auto ca = static_cast<std::size_t>(reported_[static_cast<std::size_t>(k)][0]);
      const auto cb = static_cast<std::size_t>(reported_[static_cast<std::size_t>(k)][1]);
      for (int i = cluster_start_[ca]; i < cluster_start_[ca + 1]; ++i) {
        const std::size_t ta = static_cast<std::size_t>(cluster_triangles_[static_cast<std::size_t>(i)]);
        for (int j = cluster_start_[cb]; j < cluster_start_[cb + 1]; ++j) {
          const std::size_t tb = static_cast<std::size_t>(cluster_triangles_[static_cast<std::size_t>(j)]);
          if (Overlap(tri_lo_[ta], tri_hi_[ta], tri_lo_[tb], tri_hi_[tb])) TrianglePair(ta, tb, margin + slack, &part);
        }
      }
    }
  }
  // Every chunk's same-cluster pairs first, then every chunk's reported ones.
  for (std::ptrdiff_t c = 0; c < kChunks; ++c) {
    const auto& part = parts_[static_cast<std::size_t>(c)];
    out->insert(out->end(), part.begin(), part.begin() + static_cast<std::ptrdiff_t>(parts_same_[static_cast<std::size_t>(c)]));
  }
  for (std::ptrdiff_t c = 0; c < kChunks; ++c) {
    const auto& part = parts_[static_cast<std::size_t>(c)];
    out->insert(out->end(), part.begin() + static_cast<std::ptrdiff_t>(parts_same_[static_cast<std::size_t>(c)]), part.end());
  }
}

}  // namespace clothbench
