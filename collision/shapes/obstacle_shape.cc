// What every obstacle shape shares: the convex segment cast, the edges of a
// triangulated surface and the reading of keys given in code.
#include "collision/shapes/obstacle_shape.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <stdexcept>

#include <fmt/format.h>

namespace clothbench {

Eigen::Matrix3d RotationFromDegrees(const Vector3& deg) {
  const double d2r = M_PI / 180.0;
  return (Eigen::AngleAxisd(deg.z() * d2r, Vector3::UnitZ()) * Eigen::AngleAxisd(deg.y() * d2r, Vector3::UnitY()) *
          Eigen::AngleAxisd(deg.x() * d2r, Vector3::UnitX()))
      .toRotationMatrix();
}

std::optional<SegmentHit> ObstacleShape::FirstHit(const Vector3& a, const Vector3& b) const {
  Vector3 dir;
  auto f = [&](double s) { return SignedDistance(a + s * (b - a), &dir); };
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
  SignedDistance(h.point, &h.normal);
  return h;
}

void ObstacleShape::Edges(std::vector<Vector3>* vertices, std::vector<std::array<int, 2>>* edges) const {
  std::vector<std::array<int, 3>> triangles;
  Surface(vertices, &triangles);
  edges->clear();
  for (const auto& t : triangles)
    for (std::size_t k = 0; k < 3; ++k)
      edges->push_back({std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3])});
  std::sort(edges->begin(), edges->end());
  edges->erase(std::unique(edges->begin(), edges->end()), edges->end());
}

void AddOutwardTriangle(const std::vector<Vector3>& v, const Vector3& interior, int a, int b, int c,
                        std::vector<std::array<int, 3>>* triangles) {
  const auto at = [&](int i) -> const Vector3& { return v[static_cast<std::size_t>(i)]; };
  const Vector3 n = (at(b) - at(a)).cross(at(c) - at(a));
  const Vector3 centroid = (at(a) + at(b) + at(c)) / 3.0;
  if (n.dot(centroid - interior) < 0.0) std::swap(b, c);
  triangles->push_back({a, b, c});
}

namespace {

// ShapeKeys over values given in code: the same rules, std::invalid_argument.
class ValueKeys final : public ShapeKeys {
 public:
  ValueKeys(std::string_view type, const std::map<std::string, ShapeValue, std::less<>>& values)
      : type_(type), values_(values) {}

  [[noreturn]] void Fail(std::string_view key, std::string_view rule) const override {
    throw std::invalid_argument(fmt::format("{}.{}: {}", type_, key, rule));
  }
  double Range(std::string_view key, double fallback, double lo, double hi, std::string_view units) override {
    const ShapeValue* v = Get(key);
    if (!v) return fallback;
    const double* d = std::get_if<double>(v);
    if (!d) Fail(key, "must be a number");
    if (!(*d >= lo && *d <= hi)) Fail(key, fmt::format("must be in [{:g}, {:g}]{} (got {:g})", lo, hi, units, *d));
    return *d;
  }
  std::array<double, 3> Numbers3(std::string_view key, std::array<double, 3> fallback, bool non_negative) override {
    const ShapeValue* v = Get(key);
    if (!v) return fallback;
    const Vector3* p = std::get_if<Vector3>(v);
    if (!p || !p->allFinite() || (non_negative && p->minCoeff() < 0.0))
      Fail(key, fmt::format("must be an array of 3 {}numbers", non_negative ? "non-negative " : ""));
    return {p->x(), p->y(), p->z()};
  }
  std::string String(std::string_view key, std::string fallback) override {
    const ShapeValue* v = Get(key);
    if (!v) return fallback;
    const std::string* s = std::get_if<std::string>(v);
    if (!s) Fail(key, "must be a string");
    return *s;
  }
  std::vector<TimedPath> TimedPaths(std::string_view key) override {
    const ShapeValue* v = Get(key);
    if (!v) return {};
    const auto* frames = std::get_if<std::vector<TimedPath>>(v);
    if (!frames || frames->empty()) Fail(key, "must be a non-empty array of { t, path }");
    for (const TimedPath& f : *frames)
      if (!std::isfinite(f.t) || f.t < 0.0 || f.path.empty()) Fail(key, "must have times >= 0 and non-empty paths");
    return *frames;
  }
  std::vector<std::pair<std::string, double>> NamedNumbers(std::string_view key) override {
    const ShapeValue* v = Get(key);
    if (!v) return {};
    const auto* named = std::get_if<std::vector<std::pair<std::string, double>>>(v);
    if (!named) Fail(key, "must be a table of numbers by name");
    for (const auto& [name, x] : *named)
      if (!std::isfinite(x)) Fail(key, fmt::format("{} must be a finite number", name));
    return *named;
  }
  std::string ResolvePath(const std::string& path) const override { return path; }
  void NoteInputFile(const std::string&) const override {}

  void RejectUnknown() const {
    for (const auto& [key, value] : values_)
      if (!used_.count(key)) Fail(key, "unknown key");
  }

 private:
  const ShapeValue* Get(std::string_view key) {
    used_.insert(std::string(key));
    const auto it = values_.find(key);
    return it == values_.end() ? nullptr : &it->second;
  }

  std::string type_;
  const std::map<std::string, ShapeValue, std::less<>>& values_;
  std::set<std::string, std::less<>> used_;
};

}  // namespace

std::shared_ptr<const ObstacleShape> ShapeFromValues(std::string_view type,
                                                     const std::map<std::string, ShapeValue, std::less<>>& values) {
  ValueKeys keys(type, values);
  std::shared_ptr<const ObstacleShape> shape = ParseObstacleShape(type, keys);
  keys.RejectUnknown();
  return shape;
}

}  // namespace clothbench
