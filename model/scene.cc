// Scene parsing and validation. Every failure is a
// SceneError whose message is one line: "<source>: <key>: <rule>".
#include "model/scene.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>
#include <tuple>

#include <fmt/format.h>
#include <toml++/toml.h>

#include "model/default_scene.h"
#include "model/obstacle.h"
#include "model/output_file.h"
#include "collision/shapes/triangle_mesh.h"

namespace clothbench {

std::string_view ToString(BendModel m) {
  switch (m) {
    case BendModel::kNone: return "none";
    case BendModel::kMembrane: return "membrane";
    case BendModel::kThinPlate: return "thin_plate";
  }
  return "?";
}
std::string_view ToString(TensionModel m) { return m == TensionModel::kSplit ? "split" : "linear"; }
std::string_view ToString(MassLumping m) {
  return m == MassLumping::kUniform ? "uniform" : "area";
}

double Scene::NumericalStiffness(double step) const {
  // h² k/(ρ l²) (§3.4.4): spring stiffness k·lv/lu over particle mass ρ lu lv.
  const double su = material.tension[0] / (lu() * lu());
  const double sv = material.tension[1] / (lv() * lv());
  return step * step * std::max(su, sv) / material.density;
}


void CheckRunLength(const Scene& s, const std::string& source) {
  if (s.t_end / s.frame_dt > kMaxFramesPerRun)
    throw SceneError(fmt::format("{}: frame_dt: t_end/frame_dt = {:g}/{:g} = {:.3g} frames exceeds the limit of {:g}",
                                 source, s.t_end, s.frame_dt, s.t_end / s.frame_dt, kMaxFramesPerRun));
  if (s.t_end / s.h > kMaxStepsPerRun)
    throw SceneError(fmt::format("{}: h: t_end/h = {:g}/{:g} = {:.3g} steps exceeds the limit of {:g}", source,
                                 s.t_end, s.h, s.t_end / s.h, kMaxStepsPerRun));
}

namespace {

// Reads one TOML table, remembering which keys were consumed so that unknown
// keys can be reported.
class TableReader {
 public:
  TableReader(const toml::table* table, std::string prefix, const std::string& source)
      : table_(table), prefix_(std::move(prefix)), source_(source) {}

  [[noreturn]] void Fail(std::string_view key, std::string_view rule) const {
    throw SceneError(fmt::format("{}: {}{}: {}", source_, prefix_, key, rule));
  }

  const toml::node* Get(std::string_view key) {
    used_.insert(std::string(key));
    return table_ ? table_->get(key) : nullptr;
  }

  double Number(std::string_view key, double fallback) {
    const toml::node* n = Get(key);
    if (!n) return fallback;
    if (auto d = n->value<double>()) {
      if (!std::isfinite(*d) || std::abs(*d) > kMaxMagnitude)
        Fail(key, fmt::format("must be a finite number of magnitude at most {:g}", kMaxMagnitude));
      return *d;
    }
    Fail(key, "must be a number");
  }
  /// A number in [lo, hi] (the stated physical range of the key).
  double Range(std::string_view key, double fallback, double lo, double hi, std::string_view units) {
    const double d = Number(key, fallback);
    if (!(d >= lo && d <= hi)) Fail(key, fmt::format("must be in [{:g}, {:g}]{} (got {:g})", lo, hi, units, d));
    return d;
  }
  double NonNegative(std::string_view key, double fallback) {
    const double d = Number(key, fallback);
    if (d < 0.0) Fail(key, fmt::format("must be >= 0 (got {})", d));
    return d;
  }
  double Positive(std::string_view key, double fallback) {
    const double d = Number(key, fallback);
    if (!(d > 0.0)) Fail(key, fmt::format("must be > 0 (got {})", d));
    return d;
  }
  int Integer(std::string_view key, int fallback, int min_value) {
    const toml::node* n = Get(key);
    if (!n) return fallback;
    auto i = n->value_exact<int64_t>();
    if (!i) Fail(key, "must be an integer");
    if (*i < min_value || *i > 1000000) Fail(key, fmt::format("must be an integer in [{}, 1000000] (got {})", min_value, *i));
    return static_cast<int>(*i);
  }
  bool Bool(std::string_view key, bool fallback) {
    const toml::node* n = Get(key);
    if (!n) return fallback;
    auto b = n->value_exact<bool>();
    if (!b) Fail(key, "must be true or false");
    return *b;
  }
  std::string String(std::string_view key, std::string fallback) {
    const toml::node* n = Get(key);
    if (!n) return fallback;
    auto s = n->value_exact<std::string>();
    if (!s) Fail(key, "must be a string");
    return *s;
  }
  template <std::size_t K>
  std::array<double, K> Numbers(std::string_view key, std::array<double, K> fallback, bool non_negative) {
    const toml::node* n = Get(key);
    if (!n) return fallback;
    const toml::array* a = n->as_array();
    const std::string rule = fmt::format("must be an array of {} {}numbers", K, non_negative ? "non-negative " : "");
    if (!a || a->size() != K) Fail(key, rule);
    std::array<double, K> out{};
    for (std::size_t k = 0; k < K; ++k) {
      auto d = (*a)[k].value<double>();
      if (!d || !std::isfinite(*d) || (non_negative && *d < 0.0)) Fail(key, rule);
      if (std::abs(*d) > kMaxMagnitude) Fail(key, fmt::format("{} of magnitude at most {:g}", rule, kMaxMagnitude));
      out[k] = *d;
    }
    return out;
  }
  Vector3 Vec3(std::string_view key, const Vector3& fallback) {
    auto a = Numbers<3>(key, {fallback.x(), fallback.y(), fallback.z()}, false);
    return Vector3(a[0], a[1], a[2]);
  }
  template <class Enum>
  Enum Choice(std::string_view key, Enum fallback, std::initializer_list<Enum> options) {
    const std::string s = String(key, std::string(ToString(fallback)));
    std::string names;
    for (Enum e : options) {
      if (s == ToString(e)) return e;
      names += (names.empty() ? "\"" : " | \"") + std::string(ToString(e)) + "\"";
    }
    Fail(key, fmt::format("must be one of {} (got \"{}\")", names, s));
  }
  const toml::table* SubTable(std::string_view key) {
    const toml::node* n = Get(key);
    if (!n) return nullptr;
    if (!n->as_table()) Fail(key, "must be a table");
    return n->as_table();
  }
  std::string Child(std::string_view key) const { return prefix_ + std::string(key) + "."; }
  const std::string& source() const { return source_; }

  /// Reports the first key that was never read.
  void RejectUnknown() const {
    if (!table_) return;
    for (auto&& [k, node] : *table_) {
      (void)node;
      if (!used_.count(std::string(k.str()))) Fail(k.str(), "unknown key");
    }
  }

 private:
  const toml::table* table_;
  std::string prefix_;
  const std::string& source_;
  std::set<std::string> used_;
};

int ParseIndex(const std::string& s, int limit, const std::string& what) {
  std::size_t pos = 0;
  int v = -1;
  try {
    v = std::stoi(s, &pos);
  } catch (...) {
    pos = 0;
  }
  if (pos != s.size() || v < 0 || v >= limit) throw SceneError(what + fmt::format("index \"{}\" must be an integer in [0, {})", s, limit));
  return v;
}

// [grid]: the sheet's particles.
void ParseGrid(TableReader& top, const std::string& source, Scene& s) {
  TableReader g(top.SubTable("grid"), top.Child("grid"), source);
  s.grid.nu = g.Integer("nu", s.grid.nu, 2);
  s.grid.nv = g.Integer("nv", s.grid.nv, 2);
  if (double(s.grid.nu) * double(s.grid.nv) > kMaxParticles)
    g.Fail("nv", fmt::format("nu × nv = {} × {} exceeds the limit of {:g} particles", s.grid.nu, s.grid.nv,
                             kMaxParticles));
  auto size = g.Numbers<2>("size", s.grid.size, true);
  if (!(size[0] > 0 && size[1] > 0)) g.Fail("size", "must be 2 positive numbers [m]");
  if (size[0] > 1e4 || size[1] > 1e4) g.Fail("size", "must be at most 1e4 m per side");
  if (size[0] / (s.grid.nu - 1) < 1e-6 || size[1] / (s.grid.nv - 1) < 1e-6)
    g.Fail("size", fmt::format("gives a particle spacing size/(n - 1) below 1e-6 m ({:g} m, {:g} m)",
                               size[0] / (s.grid.nu - 1), size[1] / (s.grid.nv - 1)));
  s.grid.size = size;
  s.grid.origin = g.Vec3("origin", s.grid.origin);
  if (s.grid.origin.cwiseAbs().maxCoeff() > 1e6) g.Fail("origin", "must have coordinates of magnitude at most 1e6 m");
  s.grid.u_axis = g.Vec3("u_axis", s.grid.u_axis);
  s.grid.v_axis = g.Vec3("v_axis", s.grid.v_axis);
  if (std::abs(s.grid.u_axis.norm() - 1.0) > 1e-9) g.Fail("u_axis", "must be a unit vector");
  if (std::abs(s.grid.v_axis.norm() - 1.0) > 1e-9) g.Fail("v_axis", "must be a unit vector");
  if (std::abs(s.grid.u_axis.dot(s.grid.v_axis)) > 1e-9) g.Fail("v_axis", "must be orthogonal to u_axis");
  g.RejectUnknown();
}

// [material].
// The keys of a material table over `mat`: a key not given keeps its value.
void ReadMaterial(TableReader& m, MaterialSpec& mat) {
  // Cloth is 0.05–1 kg/m²: the floor keeps masses normal doubles and
  // h²k/(ρl²) finite.
  mat.density = m.Range("density", mat.density, 1e-6, 1e6, " kg/m²");
  mat.tension = m.Numbers<2>("tension", mat.tension, true);
  mat.tension_damping = m.NonNegative("tension_damping", mat.tension_damping);
  mat.tension_model = m.Choice("tension_model", mat.tension_model, {TensionModel::kSplit, TensionModel::kLinear});
  mat.shear = m.NonNegative("shear", mat.shear);
  mat.shear_damping = m.NonNegative("shear_damping", mat.shear_damping);
  mat.bend = m.Numbers<2>("bend", mat.bend, true);
  mat.bend_damping = m.NonNegative("bend_damping", mat.bend_damping);
  mat.bend_model = m.Choice("bend_model", mat.bend_model,
                            {BendModel::kMembrane, BendModel::kThinPlate, BendModel::kNone});
  mat.transverse = m.Number("transverse", mat.transverse);
  mat.mass_lumping = m.Choice("mass_lumping", mat.mass_lumping, {MassLumping::kUniform, MassLumping::kArea});
  m.RejectUnknown();
}

void ParseMaterial(TableReader& top, const std::string& source, Scene& s) {
  TableReader m(top.SubTable("material"), top.Child("material"), source);
  ReadMaterial(m, s.material);
}

// Each pattern's material: [material] with its [pattern.material] keys
// over it. The model's one pattern makes its material the cloth's.
void ParsePatternMaterials(const toml::table& root, const std::string& source, Scene& s) {
  const toml::array* a = root["pattern"].as_array();
  if (!a) return;
  for (std::size_t k = 0; k < s.patterns.size(); ++k) {
    MaterialSpec mat = s.material;
    const toml::table* t = (*a)[k].as_table();
    if (const toml::table* over = t ? (*t)["material"].as_table() : nullptr) {
      TableReader m(over, fmt::format("pattern[{}].material.", k), source);
      ReadMaterial(m, mat);
    }
    s.pattern_materials.push_back(mat);
  }
  if (!s.pattern_materials.empty()) s.material = s.pattern_materials.front();
}

// [forces].
void ParseForces(TableReader& top, const std::string& source, Scene& s) {
  TableReader f(top.SubTable("forces"), top.Child("forces"), source);
  s.forces.gravity = f.Vec3("gravity", s.forces.gravity);
  if (s.forces.gravity.norm() > 1e4) f.Fail("gravity", "must have a magnitude of at most 1e4 m/s²");
  if (const toml::table* wt = f.SubTable("wind")) {
    TableReader w(wt, f.Child("wind"), source);
    WindSpec wind;
    wind.direction = w.Vec3("direction", wind.direction);
    if (wind.direction.norm() > 1e3) w.Fail("direction", "must have a magnitude of at most 1e3");
    wind.constant = w.Range("constant", wind.constant, -1e3, 1e3, "");
    wind.angular_frequency = w.Range("angular_frequency", wind.angular_frequency, -1e6, 1e6, " rad/s");
    wind.drag = w.Range("drag", wind.drag, 0.0, 1e6, "");
    wind.lift = w.Range("lift", wind.lift, 0.0, 1e6, "");
    w.RejectUnknown();
    s.forces.wind = wind;
  }
  if (const toml::table* at = f.SubTable("air")) {
    TableReader a(at, f.Child("air"), source);
    s.forces.air = a.Range("coefficient", 0.0, 0.0, 1e6, " kg/(m² s)");
    a.RejectUnknown();
  }
  f.RejectUnknown();
}

// Keyframed rigid motion (thesis §6.2): keyframes = [{ t, translate, rotate }, ...]
// of an obstacle or of fixed particles (`required`: the key must be there).
std::vector<ObstacleKeyframe> ParseKeyframes(TableReader& o, const std::string& prefix, const std::string& source,
                                             bool required) {
  std::vector<ObstacleKeyframe> keyframes;
  const toml::node* kf = o.Get("keyframes");
  if (!kf && required) o.Fail("keyframes", "is required: [{ t = s, translate = [x, y, z], rotate = [a, b, c] }, ...]");
  if (kf) {
    const toml::array* keys = kf->as_array();
    if (!keys || keys->empty())
      o.Fail("keyframes", "must be a non-empty array of tables { t = s, translate = [x, y, z], rotate = [a, b, c] }");
    for (std::size_t j = 0; j < keys->size(); ++j) {
      const toml::table* kt = (*keys)[j].as_table();
      const std::string kprefix = fmt::format("{}keyframes[{}].", prefix, j);
      if (!kt) throw SceneError(fmt::format("{}: {}: must be a table {{ t, translate, rotate }}", source,
                                            kprefix.substr(0, kprefix.size() - 1)));
      TableReader kr(kt, kprefix, source);
      ObstacleKeyframe key;
      if (!kt->contains("t")) kr.Fail("t", "is required (keyframe time [s])");
      key.t = kr.NonNegative("t", key.t);
      if (!keyframes.empty() && !(key.t > keyframes.back().t))
        kr.Fail("t", fmt::format("must be greater than the previous keyframe's t = {}", keyframes.back().t));
      key.translate = kr.Vec3("translate", key.translate);
      if (key.translate.cwiseAbs().maxCoeff() > 1e6)
        kr.Fail("translate", "must have coordinates of magnitude at most 1e6 m");
      key.rotate = kr.Vec3("rotate", key.rotate);
      if (key.rotate.cwiseAbs().maxCoeff() > 3600) kr.Fail("rotate", "must be angles of magnitude at most 3600 degrees");
      kr.RejectUnknown();
      keyframes.push_back(key);
    }
  }
  return keyframes;
}

// A point [x, y] of a pattern's plane, or fails naming `key`.
Vector2 PlanePoint(const toml::node& n, TableReader& t, std::string_view key, std::string_view rule) {
  const toml::array* a = n.as_array();
  if (!a || a->size() != 2) t.Fail(key, rule);
  Vector2 q;
  for (std::size_t k = 0; k < 2; ++k) {
    auto d = (*a)[k].value<double>();
    if (!d || !std::isfinite(*d) || std::abs(*d) > 1e6) t.Fail(key, fmt::format("{} (finite, of magnitude at most 1e6 m)", rule));
    q[static_cast<Eigen::Index>(k)] = *d;
  }
  return q;
}

// One [[pattern]] table (model/pattern.h; docs/guide/scenes.md, "Patterns").
PatternSpec ParsePattern(TableReader& t) {
  PatternSpec p;
  p.name = t.String("name", "");
  if (p.name.empty() || p.name.size() > 64 ||
      !std::all_of(p.name.begin(), p.name.end(), [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; }))
    t.Fail("name", "must be a word of 1 … 64 letters, digits or '_'");
  const toml::node* corners = t.Get("corners");
  const toml::array* ca = corners ? corners->as_array() : nullptr;
  const char* corner_rule = "must be 4 points [x, y] [m]: u0v0, u1v0, u1v1, u0v1";
  if (!ca || ca->size() != 4) t.Fail("corners", corner_rule);
  for (std::size_t k = 0; k < 4; ++k) p.corners[k] = PlanePoint((*ca)[k], t, "corners", corner_rule);
  const auto& ends = PatternSpec::kSideCorners;
  for (std::size_t s = 0; s < 4; ++s) p.sides[s] = {p.corners[ends[s][0]], p.corners[ends[s][1]]};
  if (const toml::table* sides = t.SubTable("sides")) {
    TableReader st(sides, t.Child("sides"), t.source());
    for (std::size_t s = 0; s < 4; ++s) {
      const char* key = PatternSpec::kSideNames[s];
      const toml::node* n = st.Get(key);
      if (!n) continue;
      const toml::array* a = n->as_array();
      const std::string rule = fmt::format("must be a polyline of 2 … 10000 points [x, y] [m] from corner {} to corner {}",
                                           PatternSpec::kCornerNames[ends[s][0]], PatternSpec::kCornerNames[ends[s][1]]);
      if (!a || a->size() < 2 || a->size() > 10000) st.Fail(key, rule);
      p.sides[s].clear();
      for (const toml::node& q : *a) p.sides[s].push_back(PlanePoint(q, st, key, rule));
    }
    st.RejectUnknown();
  }
  const toml::node* samples = t.Get("samples");
  const toml::array* sa = samples ? samples->as_array() : nullptr;
  if (!sa || sa->size() != 2) t.Fail("samples", "must be 2 integers [nu, nv], each in [2, 1000000]");
  std::array<int, 2> n{};
  for (std::size_t k = 0; k < 2; ++k) {
    auto i = (*sa)[k].value_exact<int64_t>();
    if (!i || *i < 2 || *i > 1000000) t.Fail("samples", "must be 2 integers [nu, nv], each in [2, 1000000]");
    n[k] = static_cast<int>(*i);
  }
  p.nu = n[0];
  p.nv = n[1];
  if (double(p.nu) * double(p.nv) > kMaxParticles)
    t.Fail("samples", fmt::format("nu × nv = {} × {} exceeds the limit of {:g} particles", p.nu, p.nv, kMaxParticles));
  p.origin = t.Vec3("origin", p.origin);
  if (p.origin.cwiseAbs().maxCoeff() > 1e6) t.Fail("origin", "must have coordinates of magnitude at most 1e6 m");
  p.x_axis = t.Vec3("x_axis", p.x_axis);
  p.y_axis = t.Vec3("y_axis", p.y_axis);
  p.wrap_radius = t.NonNegative("wrap_radius", 0.0);
  t.SubTable("material");  // read over [material] (ParsePatternMaterials)
  t.RejectUnknown();
  if (const std::string rule = PatternRule(p); !rule.empty()) t.Fail(rule.substr(0, rule.find(':')), rule.substr(rule.find(':') + 2));
  return p;
}

// "<pattern>:edge:<side>" of a [[seam]] key: the pattern's index and side.
std::array<int, 2> SeamSide(TableReader& t, const char* key, const Scene& s, std::string* text) {
  *text = t.String(key, "");
  const char* rule = "must name a pattern's side, \"<pattern>:edge:<v0|u1|v1|u0>\"";
  const auto colon = text->find(':');
  if (colon == std::string::npos || text->compare(colon, 6, ":edge:") != 0) t.Fail(key, rule);
  const std::string name = text->substr(0, colon), side = text->substr(colon + 6);
  int k = 0;
  while (k < static_cast<int>(s.patterns.size()) && s.patterns[static_cast<std::size_t>(k)].name != name) ++k;
  if (k == static_cast<int>(s.patterns.size()))
    t.Fail(key, fmt::format("\"{}\" names no pattern of the scene", EscapeControl(name)));
  for (int e = 0; e < 4; ++e)
    if (side == PatternSpec::kSideNames[static_cast<std::size_t>(e)]) return {k, e};
  t.Fail(key, rule);
}

// [[seam]]: two patterns' sides sewn sample to sample (docs/guide/scenes.md, "Seams").
void ParseSeams(TableReader& top, const std::string& source, Scene& s) {
  const toml::node* n = top.Get("seam");
  if (!n) return;
  const toml::array* a = n->as_array();
  if (!a || a->empty()) top.Fail("seam", "must be an array of tables ([[seam]])");
  for (std::size_t k = 0; k < a->size(); ++k) {
    const toml::table* t = (*a)[k].as_table();
    if (!t) throw SceneError(fmt::format("{}: seam[{}]: must be a table", source, k));
    TableReader r(t, fmt::format("seam[{}].", k), source);
    SeamSpec seam;
    const auto side_a = SeamSide(r, "a", s, &seam.a), side_b = SeamSide(r, "b", s, &seam.b);
    seam.pattern_a = side_a[0];
    seam.side_a = side_a[1];
    seam.pattern_b = side_b[0];
    seam.side_b = side_b[1];
    seam.reversed = r.Bool("reversed", false);
    // Optional sample ranges [first, last] along each side (a shoulder, the
    // side below an armhole); the whole side by default.
    for (const auto& [key, first, last] : {std::tuple<const char*, int*, int*>{"a_samples", &seam.first_a, &seam.last_a},
                                           std::tuple<const char*, int*, int*>{"b_samples", &seam.first_b, &seam.last_b}}) {
      const toml::node* range = r.Get(key);
      if (!range) continue;
      const toml::array* ra = range->as_array();
      const char* rule = "must be 2 integers [first, last], samples along the side in its direction";
      if (!ra || ra->size() != 2) r.Fail(key, rule);
      const auto f = (*ra)[0].value_exact<int64_t>(), l = (*ra)[1].value_exact<int64_t>();
      if (!f || !l || *f < 0 || *l < 0 || *l > 1000000) r.Fail(key, rule);
      *first = static_cast<int>(*f);
      *last = static_cast<int>(*l);
    }
    r.RejectUnknown();
    if (const std::string rule = SeamRule(s.patterns, seam); !rule.empty())
      r.Fail(rule.substr(0, rule.find(':')), rule.substr(rule.find(':') + 2));
    s.seams.push_back(seam);
  }
}

// [[pattern]]: the cloth as patterns, in place of [grid]. One flat
// rectangle with straight sides and no seam is [grid]'s sheet; any other
// cloth is Scene::cloth (docs/model.md §2.7–2.8).
void ParsePatterns(TableReader& top, const std::string& source, Scene& s) {
  const toml::node* n = top.Get("pattern");
  if (!n) {
    if (top.Get("seam")) top.Fail("seam", "needs [[pattern]] tables to sew");
    return;
  }
  const toml::array* a = n->as_array();
  if (!a || a->empty()) top.Fail("pattern", "must be an array of tables ([[pattern]])");
  if (top.Get("grid")) top.Fail("grid", "give either [grid] or [[pattern]] tables, not both");
  for (std::size_t k = 0; k < a->size(); ++k) {
    const toml::table* t = (*a)[k].as_table();
    if (!t) throw SceneError(fmt::format("{}: pattern[{}]: must be a table", source, k));
    TableReader r(t, fmt::format("pattern[{}].", k), source);
    s.patterns.push_back(ParsePattern(r));
    for (std::size_t q = 0; q < k; ++q)
      if (s.patterns[q].name == s.patterns[k].name) r.Fail("name", fmt::format("\"{}\" names pattern {} already", s.patterns[k].name, q));
  }
  ParseSeams(top, source, s);
  if (const toml::table* sewing = top.SubTable("sewing")) {
    TableReader w(sewing, top.Child("sewing"), source);
    if (s.seams.empty()) top.Fail("sewing", "needs [[seam]] tables to sew");
    if (!w.Get("time")) w.Fail("time", "must be given: the phase's length [s] > 0");
    s.sewing_time = w.Positive("time", 0.0);
    w.RejectUnknown();
  }
  double total = 0.0;
  for (const PatternSpec& p : s.patterns) total += static_cast<double>(p.nu) * p.nv;
  if (total > kMaxParticles)
    top.Fail("pattern", fmt::format("{:.0f} samples in all exceed the limit of {:g} particles", total, kMaxParticles));
  const PatternSpec& p = s.patterns.front();
  s.grid.nu = p.nu;
  s.grid.nv = p.nv;
  if (s.patterns.size() > 1 || !s.seams.empty() ||
      !PatternIsGrid(p, &s.grid.origin, &s.grid.u_axis, &s.grid.v_axis, &s.grid.size)) {
    try {
      SetCloth(&s, BuildClothLayout(s.patterns, s.seams));
    } catch (const std::invalid_argument& e) {  // a side in two seams
      top.Fail("seam", e.what());
    }
    if (s.sewing_time > 0.0) {
      ClothLayout pending = *s.cloth;  // sewn by solver/sewing.h before any run
      pending.sewn = false;
      SetCloth(&s, std::move(pending));
    } else if (s.cloth->largest_gap > kSeamGap) {
      top.Fail("seam", fmt::format("pairs up to {:.3g} m apart at the start: a seam's samples must start within {:g} m "
                                   "of each other, or give [sewing] time to bring them together",
                                   s.cloth->largest_gap, kSeamGap));
    }
  }
  if (s.grid.origin.cwiseAbs().maxCoeff() > 1e6)
    top.Fail("pattern", "must place corner u0v0 at coordinates of magnitude at most 1e6 m, as [grid]'s origin");
  if (s.lu() < 1e-6 || s.lv() < 1e-6) top.Fail("pattern", "must have spacings of at least 1e-6 m");
}

}  // namespace

void SetCloth(Scene* scene, ClothLayout cloth) {
  const ClothBlock& first = cloth.blocks.front();
  const PatternSpec& p = scene->patterns.front();
  GridSpec& g = scene->grid;
  g.nu = first.nu;
  g.nv = first.nv;
  g.origin = p.origin;
  g.u_axis = p.x_axis;
  g.v_axis = p.y_axis;
  g.size = {first.plane.col(0).maxCoeff() - first.plane.col(0).minCoeff(),
            first.plane.col(1).maxCoeff() - first.plane.col(1).minCoeff()};
  scene->cloth = std::make_shared<const ClothLayout>(std::move(cloth));
}

void SetCurvilinearCloth(Scene* scene, const PatternSpec& pattern, Eigen::MatrixX2d plane) {
  const std::vector<Eigen::MatrixX2d> samples = {std::move(plane)};
  scene->patterns = {pattern};
  scene->seams.clear();
  SetCloth(scene, BuildClothLayout(scene->patterns, {}, &samples));
}

namespace {

// A selection ("edge:u1", or "<pattern>:edge:u1" on patterns) as particle
// indices: a pattern's nodes through the cloth's numbering.
std::vector<int> ResolveSelection(const std::string& spec, const Scene& s, const std::string& what) {
  const auto colon = spec.find(':');
  const std::string head = spec.substr(0, colon);
  if (colon != std::string::npos && head != "edge" && head != "corner" && head != "particle") {
    for (std::size_t k = 0; k < s.patterns.size(); ++k) {
      const PatternSpec& p = s.patterns[k];
      if (p.name != head) continue;
      std::vector<int> local = ResolveFixed(spec.substr(colon + 1), p.nu, p.nv, what);
      if (!s.cloth) return local;
      for (int& q : local) q = s.cloth->merged[static_cast<std::size_t>(s.cloth->first[k] + q)];
      std::sort(local.begin(), local.end());
      local.erase(std::unique(local.begin(), local.end()), local.end());
      return local;
    }
    throw SceneError(what + fmt::format("\"{}\" names no pattern of the scene", EscapeControl(head)));
  }
  if (s.patterns.size() > 1)
    throw SceneError(what + fmt::format("\"{}\" must name its pattern on a cloth of several patterns, e.g. \"{}:{}\"",
                                        EscapeControl(spec), s.patterns.front().name, EscapeControl(spec)));
  if (s.patterns.empty()) return ResolveFixed(spec, s.grid.nu, s.grid.nv, what);
  return ResolveSelection(s.patterns.front().name + ":" + spec, s, what);
}

// [constraints]: fixed particles.
void ParseConstraints(TableReader& top, const std::string& source, Scene& s) {
  TableReader c(top.SubTable("constraints"), top.Child("constraints"), source);
  if (const toml::node* n = c.Get("fixed")) {
    const toml::array* a = n->as_array();
    if (!a) c.Fail("fixed", "must be an array of strings");
    std::set<int> fixed;
    for (std::size_t k = 0; k < a->size(); ++k) {
      auto str = (*a)[k].value_exact<std::string>();
      if (!str) c.Fail("fixed", "must be an array of strings");
      s.fixed_specs.push_back(*str);
      for (int p : ResolveSelection(*str, s, fmt::format("{}: constraints.fixed[{}]: ", source, k)))
        fixed.insert(p);
    }
    s.fixed.assign(fixed.begin(), fixed.end());
    // A sheet with every particle fixed has no unknowns: nothing to integrate.
    if (static_cast<long>(s.fixed.size()) >= static_cast<long>(s.num_particles()))
      c.Fail("fixed", fmt::format("fixes all {} particles; at least one must be free", s.fixed.size()));
  }
  // [[constraints.motion]]: fixed particles on a keyframed rigid motion.
  if (const toml::node* n = c.Get("motion")) {
    const toml::array* a = n->as_array();
    if (!a) c.Fail("motion", "must be an array of tables ([[constraints.motion]])");
    std::set<int> moving;
    for (std::size_t k = 0; k < a->size(); ++k) {
      const std::string prefix = fmt::format("constraints.motion[{}].", k);
      const toml::table* t = (*a)[k].as_table();
      if (!t) throw SceneError(fmt::format("{}: constraints.motion[{}]: must be a table", source, k));
      TableReader m(t, prefix, source);
      FixedMotionSpec motion;
      motion.particles_spec = m.String("particles", "");
      if (motion.particles_spec.empty()) m.Fail("particles", "must name fixed particles, e.g. \"edge:u1\"");
      std::set<int> ps;
      for (int p : ResolveSelection(motion.particles_spec, s, fmt::format("{}: {}particles: ", source, prefix)))
        ps.insert(p);
      for (int p : ps) {
        if (!std::binary_search(s.fixed.begin(), s.fixed.end(), p))
          m.Fail("particles", fmt::format("\"{}\" names particle {}, which constraints.fixed does not fix",
                                          motion.particles_spec, p));
        if (!moving.insert(p).second)
          m.Fail("particles", fmt::format("\"{}\" names particle {}, which an earlier motion moves already",
                                          motion.particles_spec, p));
      }
      motion.particles.assign(ps.begin(), ps.end());
      if (m.Get("anchor")) {
        const Vector3 anchor = m.Vec3("anchor", Vector3::Zero());
        if (anchor.cwiseAbs().maxCoeff() > 1e6) m.Fail("anchor", "must have coordinates of magnitude at most 1e6 m");
        motion.anchor = anchor;
      }
      motion.keyframes = ParseKeyframes(m, prefix, source, true);
      m.RejectUnknown();
      s.motions.push_back(std::move(motion));
    }
  }
  c.RejectUnknown();
}

// [solver] (model/solver_spec.h).
void ParseSolver(TableReader& top, const std::string& source, Scene& s) {
  TableReader v(top.SubTable("solver"), top.Child("solver"), source);
  SolverSpec& so = s.solver;
  so.cg_tolerance = v.Positive("cg_tolerance", so.cg_tolerance);
  if (so.cg_tolerance >= 1.0) v.Fail("cg_tolerance", "must be < 1");
  so.cg_reference = v.Choice("cg_reference", so.cg_reference, {CgReference::kFixedOnly, CgReference::kFiltered});
  // Absent: scaled with the grid. IC(0)-PCG iterations on A_α grow like the
  // grid side (bench_scaling: 42, 132, 420 per SBDF(2) step at N = 10³, 10⁴,
  // 10⁵), so 4·max(nu, nv) leaves 3× headroom; never below 1000.
  so.cg_max_iterations = v.Integer("cg_max_iterations", std::max(1000, 4 * std::max(s.grid.nu, s.grid.nv)), 1);
  so.preconditioner = v.Choice("preconditioner", so.preconditioner,
                               {PreconditionerType::kIc0, PreconditionerType::kCholesky, PreconditionerType::kAmg,
                                PreconditionerType::kAuto, PreconditionerType::kJacobi, PreconditionerType::kNone});
  so.cholesky_ordering =
      v.Choice("cholesky_ordering", so.cholesky_ordering, {CholeskyOrdering::kMetis, CholeskyOrdering::kAmd});
  so.max_updates = v.Integer("max_updates", so.max_updates, 1);
  {
    auto band = v.Numbers<2>("controller_updates", {double(so.controller_updates[0]), double(so.controller_updates[1])}, true);
    if (band[0] != std::floor(band[0]) || band[1] != std::floor(band[1]) || band[0] < 1 || band[0] > band[1])
      v.Fail("controller_updates", "must be 2 integers [lo, hi] with 1 <= lo <= hi");
    so.controller_updates = {static_cast<int>(band[0]), static_cast<int>(band[1])};
  }
  so.fixed_point_tolerance = v.NonNegative("fixed_point_tolerance", so.fixed_point_tolerance);
  so.nonlinear_solver =
      v.Choice("nonlinear_solver", so.nonlinear_solver, {NonlinearSolver::kFixedPoint, NonlinearSolver::kNewton});
  so.newton_jacobian = v.Choice("newton_jacobian", so.newton_jacobian, {NewtonJacobian::kRefresh, NewtonJacobian::kFrozen});
  so.tangent_projection =
      v.Choice("tangent_projection", so.tangent_projection, {TangentProjection::kClamp, TangentProjection::kNone});
  so.tangent_explicit_terms = v.Bool("tangent_explicit_terms", so.tangent_explicit_terms);
  so.contact_history = v.Choice("contact_history", so.contact_history, {ContactHistory::kKeep, ContactHistory::kRestart, ContactHistory::kProject, ContactHistory::kLand});
  so.friction_law = v.Choice("friction_law", so.friction_law, {FrictionLaw::kExplicit, FrictionLaw::kRegularised, FrictionLaw::kImplicit,
                                                         FrictionLaw::kImplicitIterated});
  so.friction_cap = v.Choice("friction_cap", so.friction_cap, {FrictionCap::kMass, FrictionCap::kSystem, FrictionCap::kStiction});
  so.contact_factors = v.Bool("contact_factors", so.contact_factors);
  so.amg_frames =
      v.Choice("amg_frames", so.amg_frames, {AmgFrames::kAdaptive, AmgFrames::kNearestAxis, AmgFrames::kSpread});
  so.predictor = v.Choice("predictor", so.predictor, {Predictor::kConstantVelocity, Predictor::kExtrapolate});
  so.step_control = v.Choice("step_control", so.step_control, {StepControl::kFixed, StepControl::kIterations, StepControl::kError});
  so.rtol = v.Positive("rtol", so.rtol);
  if (so.rtol >= 1.0) v.Fail("rtol", "must be < 1");
  so.atol = v.NonNegative("atol", so.atol);
  so.step_factor = v.Number("step_factor", so.step_factor);
  if (!(so.step_factor > 1.0)) v.Fail("step_factor", "must be > 1");
  so.h_min = v.Positive("h_min", so.h_min);
  so.h_max = v.NonNegative("h_max", so.h_max);
  so.max_rejections = v.Integer("max_rejections", so.max_rejections, 0);
  v.RejectUnknown();
  if (std::string why; !so.IsValid(&why)) throw SceneError(fmt::format("{}: solver: {}", source, why));
}

}  // namespace

std::string SelfContactThicknessRule(const Scene& scene, double thickness) {
  const double lu = scene.lu(), lv = scene.lv(), closest = lu * lv / std::hypot(lu, lv);
  if (thickness < closest) return "";
  return fmt::format("must be below the rest distance of the grid's closest non-adjacent elements, "
                     "lu·lv/sqrt(lu² + lv²) = {:.4g} m", closest);
}

namespace {

// [collision]: self-contact.
void ParseCollision(TableReader& top, const std::string& source, Scene& s) {
  const toml::table* table = top.SubTable("collision");
  if (!table) return;
  TableReader c(table, top.Child("collision"), source);
  SelfCollisionSpec spec;
  spec.self = c.Bool("self", spec.self);
  spec.thickness = c.Positive("thickness", spec.thickness);
  if (const std::string why = SelfContactThicknessRule(s, spec.thickness); !why.empty()) c.Fail("thickness", why);
  c.RejectUnknown();
  s.collision = spec;
}

// A shape's keys (collision/shapes/obstacle_shape.h) read from its
// [[obstacle]] table.
class SceneShapeKeys final : public ShapeKeys {
 public:
  SceneShapeKeys(TableReader& table, const std::string& source) : table_(table), source_(source) {}
  [[noreturn]] void Fail(std::string_view key, std::string_view rule) const override { table_.Fail(key, rule); }
  double Range(std::string_view key, double fallback, double lo, double hi, std::string_view units) override {
    return table_.Range(key, fallback, lo, hi, units);
  }
  std::array<double, 3> Numbers3(std::string_view key, std::array<double, 3> fallback, bool non_negative) override {
    return table_.Numbers<3>(key, fallback, non_negative);
  }
  std::string String(std::string_view key, std::string fallback) override { return table_.String(key, fallback); }
  std::vector<TimedPath> TimedPaths(std::string_view key) override {
    std::vector<TimedPath> frames;
    const toml::node* node = table_.Get(key);
    if (!node) return frames;
    const toml::array* items = node->as_array();
    if (!items || items->empty()) table_.Fail(key, "must be a non-empty array of tables { t = s, path = \"file\" }");
    for (std::size_t j = 0; j < items->size(); ++j) {
      const toml::table* ft = (*items)[j].as_table();
      std::string base = table_.Child(key);  // "obstacle[k].frames."
      base.pop_back();
      const std::string prefix = fmt::format("{}[{}].", base, j);
      if (!ft) throw SceneError(fmt::format("{}: {}: must be a table {{ t, path }}", source_, prefix.substr(0, prefix.size() - 1)));
      TableReader fr(ft, prefix, source_);
      if (!ft->contains("t")) fr.Fail("t", "is required (the frame's time [s])");
      TimedPath f;
      f.t = fr.NonNegative("t", 0.0);
      f.path = fr.String("path", "");
      if (f.path.empty()) fr.Fail("path", "must name a mesh file (OFF, OBJ or PLY)");
      fr.RejectUnknown();
      frames.push_back(std::move(f));
    }
    return frames;
  }
  std::vector<std::pair<std::string, double>> NamedNumbers(std::string_view key) override {
    std::vector<std::pair<std::string, double>> out;
    const toml::node* node = table_.Get(key);
    if (!node) return out;
    const toml::table* t = node->as_table();
    if (!t) table_.Fail(key, "must be a table { name = number, ... }");
    for (const auto& [name, value] : *t) {
      const std::optional<double> x = value.value<double>();
      if (!x || !std::isfinite(*x))
        table_.Fail(key, fmt::format("{} must be a finite number", EscapeControl(std::string(name.str()))));
      out.emplace_back(std::string(name.str()), *x);
    }
    return out;
  }
  // Relative paths are relative to the scene file (for a built-in scene,
  // the file it was embedded from: the source tree's scenes/).
  std::string ResolvePath(const std::string& path) const override {
    std::filesystem::path p(path);
    if (p.is_relative()) {
      const bool embedded = source_.rfind("<embedded", 0) == 0;
      p = (embedded ? std::filesystem::path(CLOTHBENCH_SOURCE_DIR) / "scenes"
                    : std::filesystem::path(source_).parent_path()) / p;
    }
    return p.string();
  }
  void NoteInputFile(const std::string& path) const override { clothbench::NoteInputFile(path); }

 private:
  TableReader& table_;
  const std::string& source_;
};

// [[obstacle]] tables.
void ParseObstacles(TableReader& top, const std::string& source, Scene& s) {
  if (const toml::node* obs = top.Get("obstacle")) {
    const toml::array* arr = obs->as_array();
    if (!arr) top.Fail("obstacle", "must be an array of tables ([[obstacle]])");
    for (std::size_t k = 0; k < arr->size(); ++k) {
      const toml::table* t = (*arr)[k].as_table();
      const std::string prefix = fmt::format("obstacle[{}].", k);
      if (!t) throw SceneError(fmt::format("{}: obstacle[{}]: must be a table", source, k));
      TableReader o(t, prefix, source);
      ObstacleSpec spec;
      SceneShapeKeys shape_keys(o, source);
      spec.shape = ParseObstacleShape(o.String("type", ""), shape_keys);
      spec.collision_distance = o.Positive("collision_distance", spec.collision_distance);
      if (spec.collision_distance > 1e3) o.Fail("collision_distance", "must be at most 1e3 m");
      spec.friction = o.Range("friction", spec.friction, 0.0, 1e3, "");
      spec.relaxation = o.Positive("relaxation", spec.relaxation);
      if (spec.relaxation > 1.0) o.Fail("relaxation", "must be in (0, 1]");
      spec.virtual_particles = o.Bool("virtual_particles", false);
      spec.continuous = o.Bool("continuous", spec.continuous);
      spec.held = o.Bool("held", spec.held);
      if (spec.virtual_particles && s.cloth && (s.patterns.size() > 1 || !s.seams.empty()))
        o.Fail("virtual_particles", "must be false on a sewn cloth: virtual particles run on one pattern's grid");
      if (spec.virtual_particles && !spec.shape->has_edges())
        o.Fail("virtual_particles", fmt::format("must be false for a {} (it has no edges to project onto the cloth)",
                                                spec.type()));
      spec.keyframes = ParseKeyframes(o, prefix, source, false);
      if (spec.shape->deforms() && !spec.keyframes.empty())
        o.Fail("keyframes", fmt::format("must be absent for a {} (it moves by its own frames)", spec.type()));
      if (spec.shape->deforms() && spec.virtual_particles)
        o.Fail("virtual_particles", fmt::format("must be false for a {} (its edges move with its frames)", spec.type()));
      o.RejectUnknown();
      s.obstacles.push_back(spec);
    }
  }
}

}  // namespace

std::vector<int> ResolveFixed(const std::string& spec, int nu, int nv, const std::string& what) {
  const std::string bad = what + fmt::format("\"{}\" must be \"edge:u0|u1|v0|v1\", \"corner:u0v0|u0v1|u1v0|u1v1\" or \"particle:I,J\"", spec);
  const auto colon = spec.find(':');
  if (colon == std::string::npos) throw SceneError(bad);
  const std::string kind = spec.substr(0, colon), arg = spec.substr(colon + 1);
  std::vector<int> out;
  auto idx = [nu](int i, int j) { return i + nu * j; };
  if (kind == "edge") {
    if (arg == "u0" || arg == "u1") {
      const int i = arg == "u0" ? 0 : nu - 1;
      for (int j = 0; j < nv; ++j) out.push_back(idx(i, j));
    } else if (arg == "v0" || arg == "v1") {
      const int j = arg == "v0" ? 0 : nv - 1;
      for (int i = 0; i < nu; ++i) out.push_back(idx(i, j));
    } else {
      throw SceneError(bad);
    }
  } else if (kind == "corner") {
    if (arg.size() != 4 || arg[0] != 'u' || arg[2] != 'v' || (arg[1] != '0' && arg[1] != '1') || (arg[3] != '0' && arg[3] != '1'))
      throw SceneError(bad);
    out.push_back(idx(arg[1] == '0' ? 0 : nu - 1, arg[3] == '0' ? 0 : nv - 1));
  } else if (kind == "particle") {
    const auto comma = arg.find(',');
    if (comma == std::string::npos) throw SceneError(bad);
    const int i = ParseIndex(arg.substr(0, comma), nu, what);
    const int j = ParseIndex(arg.substr(comma + 1), nv, what);
    out.push_back(idx(i, j));
  } else {
    throw SceneError(bad);
  }
  return out;
}

namespace {

// A cloth that starts inside an analytic obstacle is refused with the
// scene (StartsInside; mesh obstacles are checked when the model loads
// them). Positions as ParticleSystem places them, in blocks, so that a
// 10⁷-particle grid is not held at once.
void CheckStartOutsideObstacles(const Scene& s) {
  const int nu = s.grid.nu, nv = s.grid.nv;
  const double lu = s.lu(), lv = s.lv();
  for (std::size_t k = 0; k < s.obstacles.size(); ++k) {
    if (s.obstacles[k].shape->loads_file()) continue;
    const Obstacle o(s.obstacles[k]);
    constexpr int kBlock = 1 << 16;
    MatrixN3 x;
    for (long first = 0; first < static_cast<long>(nu) * nv; first += kBlock) {
      const long count = std::min<long>(kBlock, static_cast<long>(nu) * nv - first);
      x.resize(count, 3);
      for (long q = 0; q < count; ++q) {
        const long p = first + q;
        const long i = p % nu, j = p / nu;
        x.row(q) = (s.grid.origin + static_cast<double>(i) * lu * s.grid.u_axis +
                    static_cast<double>(j) * lv * s.grid.v_axis).transpose();
      }
      if (const std::string why = StartsInside(o, x, first); !why.empty())
        throw SceneError(fmt::format("{}: obstacle[{}] {}", s.source, k, why));
    }
  }
}

// The sample ranges of `scene`'s seams (a_samples, b_samples) on its
// patterns refined to `scaled(m)` samples per side of m: each range's first
// sample at the same fraction of its side, and the same count on both
// sides (the seam's pairs stay pairs), kept within each side.
void ScaleSeamRanges(const Scene& scene, const std::function<int(int)>& scaled, toml::array* seams) {
  const auto side_length = [&scene](int pattern, int side) {
    const PatternSpec& p = scene.patterns[static_cast<std::size_t>(pattern)];
    return side == PatternSpec::kV0 || side == PatternSpec::kV1 ? p.nu : p.nv;
  };
  for (std::size_t k = 0; k < seams->size() && k < scene.seams.size(); ++k) {
    const SeamSpec& seam = scene.seams[k];
    toml::table* t = (*seams)[k].as_table();
    if (!t || (!t->contains("a_samples") && !t->contains("b_samples"))) continue;
    const int la = side_length(seam.pattern_a, seam.side_a), lb = side_length(seam.pattern_b, seam.side_b);
    const int la2 = scaled(la), lb2 = scaled(lb);
    const int last_a = seam.last_a < 0 ? la - 1 : seam.last_a;
    const double fa = static_cast<double>(la2 - 1) / (la - 1), fb = static_cast<double>(lb2 - 1) / (lb - 1);
    int count = std::max(1, static_cast<int>(std::lround((last_a - seam.first_a) * fa)));
    int first_a = static_cast<int>(std::lround(seam.first_a * fa)), first_b = static_cast<int>(std::lround(seam.first_b * fb));
    count = std::min({count, la2 - 1, lb2 - 1});
    first_a = std::min(first_a, la2 - 1 - count);
    first_b = std::min(first_b, lb2 - 1 - count);
    t->insert_or_assign("a_samples", toml::array{first_a, first_a + count});
    t->insert_or_assign("b_samples", toml::array{first_b, first_b + count});
  }
}

}  // namespace

Scene ParseScene(std::string_view text, const std::string& source) {
  toml::table root;
  try {
    root = toml::parse(text, source);
  } catch (const toml::parse_error& e) {
    std::string desc(e.description());
    std::replace(desc.begin(), desc.end(), '\n', ' ');
    throw SceneError(fmt::format("{}:{}:{}: TOML syntax error: {}", source, e.source().begin.line,
                                 e.source().begin.column, desc));
  }
  Scene s;
  s.source = source;
  s.toml = std::string(text);

  TableReader top(&root, "", source);
  s.name = top.String("name", s.name);
  if (s.name.empty()) top.Fail("name", "must not be empty");
  if (s.name.size() > kMaxSceneNameBytes)
    top.Fail("name", fmt::format("{} bytes, above the limit of {} (it names the result file's scene and its runs)",
                                 s.name.size(), kMaxSceneNameBytes));
  s.t_end = top.Positive("t_end", s.t_end);
  if (s.t_end > 1e6) top.Fail("t_end", fmt::format("must be <= 1e6 s (got {:g})", s.t_end));
  s.frame_dt = top.Positive("frame_dt", s.frame_dt);
  s.h = top.Positive("h", s.h);
  if (s.frame_dt > s.t_end) top.Fail("frame_dt", "must be <= t_end");

  ParsePatterns(top, source, s);
  if (s.patterns.empty()) ParseGrid(top, source, s);
  ParseMaterial(top, source, s);
  ParsePatternMaterials(root, source, s);
  ParseForces(top, source, s);
  ParseConstraints(top, source, s);
  ParseSolver(top, source, s);
  ParseObstacles(top, source, s);
  ParseCollision(top, source, s);
  top.RejectUnknown();
  if (s.h > s.t_end) top.Fail("h", "must be <= t_end");
  CheckRunLength(s, source);
  CheckStartOutsideObstacles(s);
  return s;
}

Scene RefineGrid(const Scene& scene, long n) {
  if (n < 4 || static_cast<double>(n) > kMaxParticles)
    throw SceneError(fmt::format("{}: a refined grid must have 4 … {:g} particles (asked for {})", scene.source,
                                 kMaxParticles, n));
  for (const std::string& f : scene.fixed_specs)
    if (f.rfind("particle:", 0) == 0 || f.find(":particle:") != std::string::npos)
      throw SceneError(fmt::format("{}: constraints.fixed: \"{}\" names a particle by index, which does not follow "
                                   "a refinement of the grid (use edge:… or corner:…)",
                                   scene.source, EscapeControl(f)));
  // nu·nv ≈ n with (nu − 1)/(nv − 1) = r, the scene's ratio: nu ≈ √(n r), nv ≈ √(n/r).
  const double r = static_cast<double>(scene.grid.nu - 1) / static_cast<double>(scene.grid.nv - 1);
  int nu = std::max(2, static_cast<int>(std::lround(std::sqrt(static_cast<double>(n) * r))));
  int nv = std::max(2, static_cast<int>(std::lround(static_cast<double>(n) / nu)));
  // Rounding may overshoot the limit (n = 10⁷ gives 3163×3162): the grid
  // stays within it, one row or column less.
  while (static_cast<double>(nu) * nv > kMaxParticles) (nu >= nv ? nu : nv) -= 1;
  toml::table root;
  try {
    root = toml::parse(scene.toml, scene.source);
  } catch (const toml::parse_error& e) {
    throw SceneError(fmt::format("{}: TOML syntax error: {}", scene.source, std::string(e.description())));
  }
  if (toml::array* patterns = root["pattern"].as_array(); patterns && patterns->size() > 1) {
    // Several patterns: each pattern's intervals scaled by one factor, so
    // that a seam's sides keep equal counts and N is about n.
    const double f = std::sqrt(static_cast<double>(n) / scene.num_particles());
    const auto scaled = [f](int m) { return std::max(2, static_cast<int>(std::lround((m - 1) * f)) + 1); };
    for (std::size_t k = 0; k < patterns->size() && k < scene.patterns.size(); ++k) {
      const PatternSpec& p = scene.patterns[k];
      (*patterns)[k].as_table()->insert_or_assign("samples", toml::array{scaled(p.nu), scaled(p.nv)});
    }
    if (toml::array* seams = root["seam"].as_array()) ScaleSeamRanges(scene, scaled, seams);
  } else if (patterns && !patterns->empty() && (*patterns)[0].as_table()) {
    // One pattern (ParsePatterns): its samples are the grid's.
    (*patterns)[0].as_table()->insert_or_assign("samples", toml::array{nu, nv});
  } else {
    toml::table* grid = root["grid"].as_table();
    if (!grid) grid = root.insert_or_assign("grid", toml::table{}).first->second.as_table();
    grid->insert_or_assign("nu", nu);
    grid->insert_or_assign("nv", nv);
  }
  // Several patterns are named by the particles asked for, a grid by its nu × nv.
  const bool several = scene.patterns.size() > 1;
  root.insert_or_assign("name", several ? fmt::format("{}_{}", scene.name, n) : fmt::format("{}_{}x{}", scene.name, nu, nv));
  std::ostringstream text;
  text << fmt::format("# {} on a {}×{} grid (RefineGrid: bench_integrators --sizes)\n", scene.name, nu, nv) << root
       << '\n';
  Scene refined = ParseScene(text.str(), scene.source);
  return refined;
}

Scene LoadScene(const std::string& path) {
  // A directory, a FIFO or a device is refused before it is opened (a FIFO
  // would block, /dev/null would read as an empty all-defaults scene).
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec && ec != std::errc::no_such_file_or_directory)
    throw SceneError(fmt::format("{}: cannot be used as a scene file: {}", path, ec.message()));
  if (!ec && std::filesystem::exists(status) && !std::filesystem::is_regular_file(status))
    throw SceneError(fmt::format("{}: not a regular file (a scene is a TOML file)", path));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SceneError(fmt::format("{}: cannot open scene file", path));
  NoteInputFile(path);  // an output of this command must not replace it
  std::ostringstream ss;
  ss << in.rdbuf();
  return ParseScene(ss.str(), path);
}

Scene DefaultScene() { return BuiltinScene("swinging_sheet"); }

Scene BuiltinScene(std::string_view name) {
  for (const auto& [n, text] : kBuiltinScenes)
    if (n == name) return ParseScene(text, fmt::format("<embedded:{}.toml>", n));
  throw SceneError(fmt::format("<embedded>: no built-in scene \"{}\"", name));
}

Scene LoadSceneOrBuiltin(const std::string& arg) {
  for (const auto& [n, text] : kBuiltinScenes)
    if (n == arg) return BuiltinScene(n);
  return LoadScene(arg);
}

}  // namespace clothbench
