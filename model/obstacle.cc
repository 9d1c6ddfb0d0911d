// Signed distances, segment casts and keyframed rigid motion of obstacles
// (docs/model.md §7; thesis §5.1, §6.2).
#include "model/obstacle.h"

#include "model/triangle_mesh.h"

#include <algorithm>
#include <map>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <Eigen/Geometry>
#include <fmt/format.h>

namespace clothbench {

std::string_view ToString(ObstacleType t) {
  switch (t) {
    case ObstacleType::kPlane: return "plane";
    case ObstacleType::kSphere: return "sphere";
    case ObstacleType::kBox: return "box";
    case ObstacleType::kCylinder: return "cylinder";
    case ObstacleType::kMesh: return "mesh";
  }
  return "?";
}

namespace {

// Signed distance of p to an axis-aligned box with half extents e at the
// origin, and the outward direction of the closest surface point.
double BoxDistance(const Vector3& p, const Vector3& e, Vector3* dir) {
  const Vector3 q = p.cwiseAbs() - e;
  if (q.maxCoeff() > 0.0) {  // outside: direction to the closest point
    const Vector3 outside = q.cwiseMax(0.0);
    Vector3 d = outside.cwiseProduct(p.cwiseSign());
    const double dist = d.norm();
    *dir = d / dist;
    return dist;
  }
  int k = 0;  // inside: leave through the nearest face
  q.maxCoeff(&k);
  *dir = Vector3::Zero();
  (*dir)(k) = p(k) >= 0.0 ? 1.0 : -1.0;
  return q(k);
}

}  // namespace

Eigen::Matrix3d RotationFromDegrees(const Vector3& deg) {
  const double d2r = M_PI / 180.0;
  return (Eigen::AngleAxisd(deg.z() * d2r, Vector3::UnitZ()) * Eigen::AngleAxisd(deg.y() * d2r, Vector3::UnitY()) *
          Eigen::AngleAxisd(deg.x() * d2r, Vector3::UnitX()))
      .toRotationMatrix();
}

Obstacle::Obstacle(const ObstacleSpec& spec) : spec_(spec) {
  if (spec.type == ObstacleType::kMesh)
    mesh_ = std::make_shared<const TriangleMesh>(spec.path, spec.scale, spec.rotate, spec.translate);
  if (mesh_ && !spec.keyframes.empty()) {
    std::vector<double> xyz;
    std::vector<int32_t> triangles;
    mesh_->Export(&xyz, &triangles);
    auto vertices = std::make_shared<std::vector<Vector3>>(xyz.size() / 3);
    for (std::size_t i = 0; i < vertices->size(); ++i) (*vertices)[i] = Vector3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    vertices_ = std::move(vertices);
  }
  anchor_ = spec.type == ObstacleType::kMesh ? spec.translate : spec.center;
  for (const ObstacleKeyframe& k : spec.keyframes)
    key_rotations_.emplace_back(Eigen::Quaterniond(RotationFromDegrees(k.rotate)).normalized());
}

double Obstacle::MotionBound(const ObstaclePose& a, const ObstaclePose& b) const {
  if (!mesh_) return std::numeric_limits<double>::infinity();
  if (!moving()) return 0.0;
  double largest = 0.0;
  for (const Vector3& v : *vertices_) largest = std::max(largest, (b.ToWorld(v) - a.ToWorld(v)).norm());
  return largest;
}

Penetration Obstacle::PenetrationOf(const ObstaclePose& pose, const MatrixN3& x) const {
  Penetration r;
  for (int p = 0; p < x.rows(); ++p) {
    Vector3 dir;
    const double d = SignedDistance(pose, x.row(p).transpose(), &dir);
    if (d < 0.0) {
      if (-d > r.max_depth) r.max_depth = -d, r.deepest = p;
      r.depth_sum += -d;
      ++r.inside;
    }
    if (d < 0.5 * spec_.collision_distance) ++r.close;
  }
  return r;
}

ObstaclePose Obstacle::PoseAt(double t) const {
  ObstaclePose pose;
  pose.anchor = anchor_;
  const auto& keys = spec_.keyframes;
  if (keys.empty()) return pose;
  pose.identity = false;
  std::size_t k = 0;  // segment [k, k+1] containing t, or a held end pose
  while (k + 1 < keys.size() && keys[k + 1].t <= t) ++k;
  if (t <= keys.front().t || k + 1 == keys.size()) {
    const std::size_t held = t <= keys.front().t ? 0 : keys.size() - 1;
    pose.rotation = key_rotations_[held].toRotationMatrix();
    pose.translation = keys[held].translate;
    return pose;
  }
  // Linear translation and constant-rate rotation (the shortest arc from
  // R_k to R_k+1) over the segment: R(t) = exp(s θ [a]) R_k.
  const double dt = keys[k + 1].t - keys[k].t, s = (t - keys[k].t) / dt;
  Eigen::Quaterniond dq = key_rotations_[k + 1] * key_rotations_[k].inverse();
  if (dq.w() < 0.0) dq.coeffs() *= -1.0;
  const Eigen::AngleAxisd arc(dq);
  pose.rotation = Eigen::AngleAxisd(s * arc.angle(), arc.axis()) * key_rotations_[k].toRotationMatrix();
  pose.translation = (1.0 - s) * keys[k].translate + s * keys[k + 1].translate;
  pose.linear_velocity = (keys[k + 1].translate - keys[k].translate) / dt;
  pose.angular_velocity = (arc.angle() / dt) * arc.axis();
  return pose;
}

namespace {

// A point that no query may see: not finite, or beyond kMaxQueryMagnitude.
bool OutOfRange(const Vector3& p) { return !(p.cwiseAbs().maxCoeff() <= kMaxQueryMagnitude); }

}  // namespace

double Obstacle::SignedDistance(const ObstaclePose& pose, const Vector3& p, Vector3* dir) const {
  // A blown-up state never reaches CGAL (its exact fallback raises SIGFPE
  // on non-finite input) or the analytic formulas: it is far from every
  // obstacle, and the step that produced it ends as non_finite or
  // energy_growth (solver/run.h).
  if (OutOfRange(p)) {
    *dir = Vector3::UnitZ();
    return std::numeric_limits<double>::infinity();
  }
  if (pose.identity) return PlacedSignedDistance(p, dir);
  Vector3 d_placed;
  const double d = PlacedSignedDistance(pose.ToPlaced(p), &d_placed);
  *dir = pose.ToWorldDirection(d_placed);
  return d;
}

std::optional<SegmentHit> Obstacle::FirstHit(const ObstaclePose& pose, const Vector3& a_world,
                                             const Vector3& b_world) const {
  if (OutOfRange(a_world) || OutOfRange(b_world)) return std::nullopt;  // as in SignedDistance
  const Vector3 a = pose.ToPlaced(a_world), b = pose.ToPlaced(b_world);
  std::optional<SegmentHit> hit;
  if (spec_.type == ObstacleType::kMesh) {
    hit = mesh_->FirstHit(a, b);
  } else {
    Vector3 dir;
    auto f = [&](double s) { return PlacedSignedDistance(a + s * (b - a), &dir); };
    if (f(0.0) < 0.0) return std::nullopt;  // already inside: proximity handles it
    // Golden-section search for the minimum of the convex f on [0, 1].
    const double g = 0.5 * (std::sqrt(5.0) - 1.0);
    double lo = 0.0, hi = 1.0, m1 = hi - g * (hi - lo), m2 = lo + g * (hi - lo), f1 = f(m1), f2 = f(m2);
    double s_min = f(1.0) < 0.0 ? 1.0 : -1.0;
    if (s_min < 0.0) {
      while (hi - lo > 1e-12) {
        if (f1 < 0.0) { s_min = m1; break; }
        if (f2 < 0.0) { s_min = m2; break; }
        if (f1 < f2) { hi = m2; m2 = m1; f2 = f1; m1 = hi - g * (hi - lo); f1 = f(m1); }
        else { lo = m1; m1 = m2; f1 = f2; m2 = lo + g * (hi - lo); f2 = f(m2); }
      }
      if (s_min < 0.0) return std::nullopt;  // the segment stays outside
    }
    lo = 0.0;  // f(lo) ≥ 0 > f(hi): bisection for the entry
    hi = s_min;
    while (hi - lo > 1e-12) {
      const double mid = 0.5 * (lo + hi);
      (f(mid) >= 0.0 ? lo : hi) = mid;
    }
    SegmentHit h;
    h.s = lo;
    h.point = a + lo * (b - a);
    PlacedSignedDistance(h.point, &h.normal);
    hit = h;
  }
  if (!hit) return std::nullopt;
  hit->point = pose.ToWorld(hit->point);
  hit->normal = pose.ToWorldDirection(hit->normal);
  return hit;
}

double Obstacle::PlacedSignedDistance(const Vector3& p, Vector3* dir) const {
  const ObstacleSpec& s = spec_;
  switch (s.type) {
    case ObstacleType::kMesh:
      return mesh_->SignedDistance(p, dir);
    case ObstacleType::kPlane:
      *dir = s.normal;
      return (p - s.center).dot(s.normal);
    case ObstacleType::kSphere: {
      const Vector3 r = p - s.center;
      const double len = r.norm();
      *dir = len > 1e-15 ? Vector3(r / len) : Vector3::UnitZ();
      return len - s.radius;
    }
    case ObstacleType::kBox:
      return BoxDistance(p - s.center, 0.5 * s.size, dir);
    case ObstacleType::kCylinder: {
      // Solid cylinder, axis z, top at center.z, bottom at center.z − height.
      const Vector3 r = p - s.center;
      const double rho = std::hypot(r.x(), r.y());
      const Vector3 radial = rho > 1e-15 ? Vector3(r.x() / rho, r.y() / rho, 0.0) : Vector3::UnitX();
      const double dr = rho - s.radius;                           // > 0 outside the mantle
      const double dz = std::max(r.z(), -s.height - r.z());       // > 0 above the top / below the bottom
      const bool top = r.z() > -0.5 * s.height;
      const Vector3 axial = top ? Vector3::UnitZ() : Vector3(-Vector3::UnitZ());
      if (dr > 0.0 && dz > 0.0) {  // outside near a rim: distance to the rim circle
        const Vector3 d = dr * radial + dz * axial;
        const double dist = d.norm();
        *dir = d / dist;
        return dist;
      }
      if (dr > dz) {
        *dir = radial;
        return dr;
      }
      *dir = axial;
      return dz;
    }
  }
  *dir = Vector3::UnitZ();
  return 1e300;
}

namespace {

// A geodesic sphere: the icosahedron's faces split kIcosphereLevels times
// into four, the new vertices pushed out to the sphere. Counter-clockwise
// seen from outside.
void Icosphere(const Vector3& centre, double radius, std::vector<Vector3>* vertices,
               std::vector<std::array<int, 3>>* faces) {
  const double g = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Vector3> unit = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0}, {0, -1, g}, {0, 1, g},
                               {0, -1, -g}, {0, 1, -g}, {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
  for (Vector3& v : unit) v.normalize();
  std::vector<std::array<int, 3>> f = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9},  {5, 11, 4},
                                       {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4},  {3, 4, 2},   {3, 2, 6},  {3, 6, 8},
                                       {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (int level = 0; level < Obstacle::kIcosphereLevels; ++level) {
    std::map<std::pair<int, int>, int> middle;
    const auto mid = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      const auto [it, fresh] = middle.try_emplace(key, static_cast<int>(unit.size()));
      if (fresh) unit.push_back((unit[static_cast<std::size_t>(a)] + unit[static_cast<std::size_t>(b)]).normalized());
      return it->second;
    };
    std::vector<std::array<int, 3>> next;
    for (const auto& t : f) {
      const int ab = mid(t[0], t[1]), bc = mid(t[1], t[2]), ca = mid(t[2], t[0]);
      next.push_back({t[0], ab, ca});
      next.push_back({t[1], bc, ab});
      next.push_back({t[2], ca, bc});
      next.push_back({ab, bc, ca});
    }
    f.swap(next);
  }
  for (const Vector3& u : unit) vertices->push_back(centre + radius * u);
  faces->insert(faces->end(), f.begin(), f.end());
}

}  // namespace

void Obstacle::Edges(const ObstaclePose& pose, std::vector<Vector3>* vertices,
                     std::vector<std::array<int, 2>>* edges) const {
  vertices->clear();
  edges->clear();
  const ObstacleSpec& s = spec_;
  const auto circle = [&](const Vector3& centre, double radius) {  // a closed polygon in a z-plane
    const int first = static_cast<int>(vertices->size());
    for (int k = 0; k < kCircleSegments; ++k) {
      const double phi = 2.0 * std::numbers::pi * k / kCircleSegments;
      vertices->push_back(centre + radius * Vector3(std::cos(phi), std::sin(phi), 0.0));
      edges->push_back({first + k, first + (k + 1) % kCircleSegments});
    }
    return first;
  };
  switch (s.type) {
    case ObstacleType::kPlane:
      break;
    case ObstacleType::kBox: {
      const Vector3 half = 0.5 * s.size;
      for (int k = 0; k < 8; ++k)
        vertices->push_back(s.center + Vector3((k & 1) ? half.x() : -half.x(), (k & 2) ? half.y() : -half.y(),
                                               (k & 4) ? half.z() : -half.z()));
      for (int k = 0; k < 8; ++k)  // the corners that differ in one coordinate
        for (int bit : {1, 2, 4})
          if (!(k & bit)) edges->push_back({k, k | bit});
      break;
    }
    case ObstacleType::kCylinder: {
      const int top = circle(s.center, s.radius);
      const int bottom = circle(s.center - Vector3(0.0, 0.0, s.height), s.radius);
      for (int k = 0; k < kCircleSegments; ++k) edges->push_back({top + k, bottom + k});
      break;
    }
    case ObstacleType::kSphere:
    case ObstacleType::kMesh: {  // the edges of its triangles, each once
      std::vector<std::array<int, 3>> triangles;
      TriangulatedSurface(vertices, &triangles);
      for (const auto& t : triangles)
        for (std::size_t k = 0; k < 3; ++k)
          edges->push_back({std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3])});
      std::sort(edges->begin(), edges->end());
      edges->erase(std::unique(edges->begin(), edges->end()), edges->end());
      break;
    }
  }
  if (!pose.identity)
    for (Vector3& v : *vertices) v = pose.ToWorld(v);
}

void Obstacle::TriangulatedSurface(std::vector<Vector3>* vertices, std::vector<std::array<int, 3>>* triangles) const {
  vertices->clear();
  triangles->clear();
  if (spec_.type == ObstacleType::kSphere) {
    Icosphere(spec_.center, spec_.radius, vertices, triangles);
    return;
  }
  std::vector<double> xyz;
  std::vector<int32_t> t;
  mesh_->Export(&xyz, &t);
  for (std::size_t k = 0; k + 2 < xyz.size(); k += 3) vertices->emplace_back(xyz[k], xyz[k + 1], xyz[k + 2]);
  for (std::size_t k = 0; k + 2 < t.size(); k += 3) triangles->push_back({t[k], t[k + 1], t[k + 2]});
}

void Obstacle::Surface(std::vector<Vector3>* vertices, std::vector<std::array<int, 3>>* triangles) const {
  if (spec_.type == ObstacleType::kSphere || spec_.type == ObstacleType::kMesh) {
    TriangulatedSurface(vertices, triangles);
    return;
  }
  triangles->clear();
  std::vector<std::array<int, 2>> edges;
  Edges(ObstaclePose{}, vertices, &edges);
  const ObstacleSpec& s = spec_;
  std::vector<Vector3>& v = *vertices;
  Vector3 interior = s.center;  // the analytic obstacles are convex: outward is away from an interior point
  const auto add = [&](int a, int b, int c) {
    const Vector3 n = (v[static_cast<std::size_t>(b)] - v[static_cast<std::size_t>(a)])
                          .cross(v[static_cast<std::size_t>(c)] - v[static_cast<std::size_t>(a)]);
    const Vector3 centroid = (v[static_cast<std::size_t>(a)] + v[static_cast<std::size_t>(b)] + v[static_cast<std::size_t>(c)]) / 3.0;
    if (n.dot(centroid - interior) < 0.0) std::swap(b, c);
    triangles->push_back({a, b, c});
  };
  const auto quad = [&](int a, int b, int c, int d) {  // a b c d around the quad
    add(a, b, c);
    add(a, c, d);
  };
  const int m = kCircleSegments;
  switch (s.type) {
    case ObstacleType::kPlane:
      vertices->clear();
      break;
    case ObstacleType::kBox:
      // The corners with bit `axis` equal to `side`, in cyclic order.
      for (int axis : {1, 2, 4})
        for (int side : {0, 1}) {
          const int o1 = axis == 1 ? 2 : 1, o2 = axis == 4 ? 2 : 4, base = side ? axis : 0;
          quad(base, base | o1, base | o1 | o2, base | o2);
        }
      break;
    case ObstacleType::kCylinder: {
      interior = s.center - Vector3(0.0, 0.0, 0.5 * s.height);
      const int top_centre = static_cast<int>(v.size()), bottom_centre = top_centre + 1;
      v.push_back(s.center);
      v.push_back(s.center - Vector3(0.0, 0.0, s.height));
      for (int k = 0; k < m; ++k) {
        const int next = (k + 1) % m;
        add(top_centre, k, next);
        add(bottom_centre, m + k, m + next);
        quad(k, m + k, m + next, next);
      }
      break;
    }
    case ObstacleType::kSphere:
    case ObstacleType::kMesh:  // TriangulatedSurface above
      break;
  }
}

std::string StartsInside(const Obstacle& o, const MatrixN3& x, long first) {
  const Penetration pen = o.PenetrationOf(o.PoseAt(0.0), x);
  if (pen.deepest < 0 || !(pen.max_depth > o.spec().collision_distance)) return "";
  return fmt::format("({}): particle {} starts {:.3g} m inside it at ({:g}, {:g}, {:g}) m, deeper than its collision "
                     "distance {:g} m ({} particles start inside); move the grid or the obstacle",
                     ToString(o.spec().type), first + pen.deepest, pen.max_depth, x(pen.deepest, 0), x(pen.deepest, 1),
                     x(pen.deepest, 2), o.spec().collision_distance, pen.inside);
}

}  // namespace clothbench
