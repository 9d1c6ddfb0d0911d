// Patterns (model/pattern.h; docs/guide/scenes.md, "Patterns"): the Coons
// sampling, the placement, the rules a pattern is refused by, and a
// rectangle pattern that is `[grid]`'s sheet.
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <numbers>
#include <string>

#include "model/particle_system.h"
#include "model/pattern.h"
#include "model/scene.h"
#include "verify/stepping.h"
#include "verify/test_scenes.h"

namespace clothbench {
namespace {

PatternSpec Trapezoid(int nu, int nv) {
  PatternSpec p;
  p.name = "front";
  p.corners = {Vector2(0.0, 0.0), Vector2(1.0, 0.0), Vector2(0.75, 1.0), Vector2(0.25, 1.0)};
  p.sides = {std::vector<Vector2>{p.corners[0], p.corners[1]}, std::vector<Vector2>{p.corners[1], p.corners[2]},
             std::vector<Vector2>{p.corners[3], p.corners[2]}, std::vector<Vector2>{p.corners[0], p.corners[3]}};
  p.nu = nu;
  p.nv = nv;
  return p;
}

TEST(Pattern, CoonsSamplingOfStraightSidesIsBilinear) {
  const PatternSpec p = Trapezoid(5, 3);
  const Eigen::MatrixX2d x = SamplePattern(p);
  ASSERT_EQ(x.rows(), 15);
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 5; ++i) {
      const double u = i / 4.0, v = j / 2.0;
      const Vector2 bilinear = (1 - u) * (1 - v) * p.corners[0] + u * (1 - v) * p.corners[1] + u * v * p.corners[2] +
                               (1 - u) * v * p.corners[3];
      // Round-off of a sum of eight terms of size 1.
      EXPECT_LT((x.row(i + 5 * j).transpose() - bilinear).norm(), 1e-15) << i << "," << j;
    }
}

TEST(Pattern, CoonsSamplingKeepsCurvedSidesAtEqualArcLength) {
  // A hem bowed down by a circular arc of 16 pieces.
  PatternSpec p = Trapezoid(9, 5);
  std::vector<Vector2> hem;
  const double sag = 0.1, half = 0.5, radius = (half * half + sag * sag) / (2 * sag);
  const double spread = std::asin(half / radius);
  for (int k = 0; k <= 16; ++k) {
    const double a = -spread + 2 * spread * k / 16.0;
    hem.emplace_back(0.5 + radius * std::sin(a), -sag + radius * (1.0 - std::cos(a)) - 0.0);
  }
  hem.front() = p.corners[0];
  hem.back() = p.corners[1];
  p.sides[PatternSpec::kV0] = hem;
  ASSERT_EQ(PatternRule(p), "");
  const Eigen::MatrixX2d x = SamplePattern(p);
  // The first row is the hem itself (Coons interpolates its sides), at
  // equal arc lengths: its pieces are equal chords of the polyline.
  // The polyline's 16 pieces of 0.049 rad leave its points within
  // R (1 − cos 0.025) = 4·10⁻⁴ m of the arc (2e-3 below); a chord over
  // two pieces differs from one within a piece by O(θ²/24) = 10⁻⁴ of
  // its length (1e-3 below).
  double chord = (x.row(1) - x.row(0)).norm();
  for (int i = 0; i < 9; ++i) {
    const Vector2 q = x.row(i).transpose();
    EXPECT_NEAR(q.y(), -sag + radius * (1.0 - std::cos(std::asin((q.x() - 0.5) / radius))), 2e-3) << i;
    if (i > 0) {
      EXPECT_NEAR((x.row(i) - x.row(i - 1)).norm(), chord, 1e-3 * chord) << i;
    }
  }
  // The sides u0, u1 and v1 stay straight, the middle row lies between.
  EXPECT_LT((x.row(9 * 4 + 4).transpose() - Vector2(0.5, 1.0)).norm(), 1e-15);  // round-off of 8 terms of size 1
  EXPECT_LT(x(9 * 2 + 4, 1), 0.5);
  EXPECT_GT(x(9 * 2 + 4, 1), 0.5 - sag);
}

TEST(Pattern, WrapKeepsArcLengthOnTheCylinder) {
  PatternSpec p = Trapezoid(21, 2);
  p.corners = {Vector2(-0.3, 0.0), Vector2(0.3, 0.0), Vector2(0.3, 0.5), Vector2(-0.3, 0.5)};
  p.sides = {std::vector<Vector2>{p.corners[0], p.corners[1]}, std::vector<Vector2>{p.corners[1], p.corners[2]},
             std::vector<Vector2>{p.corners[3], p.corners[2]}, std::vector<Vector2>{p.corners[0], p.corners[3]}};
  p.origin = Vector3(0.0, 0.2, 1.0);
  p.x_axis = Vector3::UnitX();
  p.y_axis = Vector3::UnitZ();  // n = x × z = −y: the pattern faces −y, wraps toward +y
  p.wrap_radius = 0.2;
  const MatrixN3 x = PlacePattern(p, SamplePattern(p));
  const Vector3 axis_point = p.origin - p.wrap_radius * p.x_axis.cross(p.y_axis);
  double arc = 0.0;
  for (int i = 0; i < 21; ++i) {
    Vector3 r = x.row(i).transpose() - axis_point;
    r -= r.dot(p.y_axis) * p.y_axis;
    EXPECT_NEAR(r.norm(), 0.2, 1e-12) << i;  // on the cylinder, to round-off of sin, cos at 1 m
    if (i > 0) {
      const double chord = (x.row(i) - x.row(i - 1)).norm();
      arc += 2.0 * 0.2 * std::asin(0.5 * chord / 0.2);
    }
  }
  EXPECT_NEAR(arc, 0.6, 1e-12);  // the row's length in the plane, to the round-off of 20 asin
  EXPECT_GT(x(0, 1), p.origin.y());  // wrapped away from the front (−y)
}

TEST(Pattern, RulesNameTheKey) {
  PatternSpec p = Trapezoid(4, 4);
  EXPECT_EQ(PatternRule(p), "");
  PatternSpec q = p;
  q.nu = 1;
  EXPECT_EQ(PatternRule(q).rfind("samples:", 0), 0u);
  q = p;  // clockwise corners (mirrored)
  for (Vector2& c : q.corners) c.x() = -c.x();
  for (auto& side : q.sides)
    for (Vector2& c : side) c.x() = -c.x();
  EXPECT_EQ(PatternRule(q).rfind("corners:", 0), 0u) << PatternRule(q);
  q = p;  // the v1 side dips below the hem: the outline crosses itself
  q.sides[PatternSpec::kV1] = {p.corners[3], Vector2(0.5, -0.5), p.corners[2]};
  EXPECT_EQ(PatternRule(q).rfind("sides:", 0), 0u) << PatternRule(q);
  q = p;
  q.sides[PatternSpec::kU1] = {p.corners[2], p.corners[1]};  // the wrong way
  EXPECT_EQ(PatternRule(q).rfind("sides.u1: must start at corner u1v0", 0), 0u) << PatternRule(q);
  q = p;
  q.y_axis = Vector3(1.0, 1.0, 0.0).normalized();
  EXPECT_EQ(PatternRule(q).rfind("y_axis:", 0), 0u);
  EXPECT_THROW(SamplePattern(q), std::invalid_argument);
}

const std::string kGridScene = testing::SheetScene(testing::kGridSheet, "edge:v0");
const std::string kPatternScene = testing::SheetScene(testing::kRectanglePattern, "panel:edge:v0");

TEST(Pattern, ARectanglePatternIsTheGridsSheet) {
  const Scene grid = ParseScene(kGridScene, "grid.toml"), pattern = ParseScene(kPatternScene, "pattern.toml");
  ASSERT_EQ(pattern.patterns.size(), 1u);
  EXPECT_EQ(pattern.grid.nu, grid.grid.nu);
  EXPECT_EQ(pattern.grid.nv, grid.grid.nv);
  EXPECT_EQ(pattern.fixed, grid.fixed);
  const ParticleSystem a(grid), b(pattern);
  // Corner u0v0 at the plane's origin: the placement is the grid's, bit for bit.
  EXPECT_EQ(a.rest_positions(), b.rest_positions());
  // And so is a run: implicit Euler with Newton, 10 steps.
  EXPECT_EQ(testing::ImplicitEulerNewtonFromRest(a, 0.005, 10), testing::ImplicitEulerNewtonFromRest(b, 0.005, 10));
  // A rectangle placed elsewhere in its plane and turned in it: the same
  // sheet up to the round-off of its placement.
  std::string turned = kPatternScene;
  const double c = std::cos(0.3), s = std::sin(0.3);
  const auto point = [&](double x, double y) {
    return fmt::format("[{:.17g}, {:.17g}]", 0.25 + c * x - s * y, -0.5 + s * x + c * y);
  };
  turned.replace(turned.find("[[0.0, 0.0]"), std::string("[[0.0, 0.0], [0.6, 0.0], [0.6, 0.4], [0.0, 0.4]]").size(),
                 "[" + point(0, 0) + ", " + point(0.6, 0) + ", " + point(0.6, 0.4) + ", " + point(0, 0.4) + "]");
  // Plane points turned by R(0.3): axes [x y] Rᵀ place them where they were.
  turned.replace(turned.find("x_axis = [0.0, 1.0, 0.0]"), 24, fmt::format("x_axis = [0.0, {:.17g}, {:.17g}]", c, s));
  turned.replace(turned.find("y_axis = [0.0, 0.0, -1.0]"), 25, fmt::format("y_axis = [0.0, {:.17g}, {:.17g}]", s, -c));
  const Scene moved = ParseScene(turned, "turned.toml");
  const ParticleSystem m(moved);
  EXPECT_GT((m.rest_positions() - a.rest_positions()).cwiseAbs().maxCoeff(), 0.1);  // placed elsewhere
  const Vector3 shift = m.rest_positions().row(0) - a.rest_positions().row(0);
  // Round-off of the turned corners (17 digits) and axes, at 1 m: 1e-12.
  EXPECT_LT((m.rest_positions().rowwise() - shift.transpose() - a.rest_positions()).cwiseAbs().maxCoeff(), 1e-12);
}

// A curved or wrapped pattern runs on its own rest geometry (docs/model.md
// §2.7): it starts where PlacePattern puts its samples, at rest.
TEST(Pattern, CurvedAndWrappedPatternsStartAtRestWhereTheyArePlaced) {
  std::string curved = kPatternScene;
  curved.replace(curved.find("samples"), 0, "sides.v0 = [[0.0, 0.0], [0.3, -0.05], [0.6, 0.0]]\nwrap_radius = 0.5\n");
  Scene s = ParseScene(curved, "curved.toml");
  ASSERT_FALSE(s.uniform_grid());
  s.forces.gravity = Vector3::Zero();
  const ParticleSystem sys(s);
  EXPECT_EQ(sys.rest_positions(), PlacePattern(s.patterns[0], SamplePattern(s.patterns[0])));
  MatrixN3 f(sys.num_particles(), 3);
  sys.Forces(0.0, sys.rest_positions(), MatrixN3::Zero(sys.num_particles(), 3), &f);
  // Wrapped, the pattern starts bent, away from its flat rest state.
  const MatrixN3 flat = PlacePattern([&] { PatternSpec p = s.patterns[0]; p.wrap_radius = 0.0; return p; }(),
                                     SamplePattern(s.patterns[0]));
  MatrixN3 g(sys.num_particles(), 3);
  sys.Forces(0.0, flat, MatrixN3::Zero(sys.num_particles(), 3), &g);
  // Flat, the rest state: round-off of k ε at spacings of 0.1 m, 1e-12 N.
  EXPECT_LT(g.cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_GT(f.cwiseAbs().maxCoeff(), 1e-6);
}

TEST(Pattern, PatternMaterialOverridesTheScenesKeyByKey) {
  std::string text = kPatternScene;
  text.replace(text.find("[material]"), 0, "[pattern.material]\nshear = 25.0\ndensity = 0.2\n");
  const Scene s = ParseScene(text, "p.toml");
  ASSERT_EQ(s.pattern_materials.size(), 1u);
  EXPECT_EQ(s.pattern_materials[0].shear, 25.0);     // the pattern's key
  EXPECT_EQ(s.pattern_materials[0].density, 0.2);
  EXPECT_EQ(s.pattern_materials[0].bend[0], 1e-3);   // [material]'s
  EXPECT_EQ(s.material.shear, 25.0);                 // the one pattern's material is the cloth's
  std::string bad = kPatternScene;
  bad.replace(bad.find("[material]"), 0, "[pattern.material]\nshaer = 25.0\n");
  try {
    ParseScene(bad, "p.toml");
    ADD_FAILURE() << "accepted";
  } catch (const SceneError& e) {
    EXPECT_EQ(std::string(e.what()), "p.toml: pattern[0].material.shaer: unknown key");
  }
}

TEST(Pattern, SceneRefusesBadPatternsNamingThem) {
  const auto refusal = [](std::string text) {
    try {
      ParseScene(text, "p.toml");
    } catch (const SceneError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  std::string both = kPatternScene;
  both += "[grid]\nnu = 3\n";
  EXPECT_EQ(refusal(both).rfind("p.toml: grid: give either [grid] or [[pattern]]", 0), 0u) << refusal(both);
  std::string clockwise = kPatternScene;
  clockwise.replace(clockwise.find("[[0.0, 0.0]"), 48, "[[0.0, 0.0], [0.0, 0.4], [0.6, 0.4], [0.6, 0.0]]");
  EXPECT_EQ(refusal(clockwise).rfind("p.toml: pattern[0].corners: must run counter-clockwise", 0), 0u)
      << refusal(clockwise);
  // A simple, counter-clockwise but strongly concave outline folds its
  // transfinite sampling (a fuzzing finding, whose node masses were <= 0).
  std::string concave = kPatternScene;
  concave.replace(concave.find("[[0.0, 0.0]"), 48, "[[0.0, 0.6], [0.0, 0.0], [0.75, 0.1], [0.15, 0.1]]");
  EXPECT_EQ(refusal(concave).rfind("p.toml: pattern[0].corners, sides: the sampling folds over itself at face", 0), 0u)
      << refusal(concave);
  std::string one = kPatternScene;
  one.replace(one.find("samples = [7, 5]"), 16, "samples = [1, 5]");
  EXPECT_EQ(refusal(one).rfind("p.toml: pattern[0].samples:", 0), 0u) << refusal(one);
  std::string side = kPatternScene;
  side.replace(side.find("samples"), 0, "sides.v0 = [[0.1, 0.0], [0.6, 0.0]]\n");
  EXPECT_EQ(refusal(side).rfind("p.toml: pattern[0].sides.v0: must start at corner u0v0", 0), 0u) << refusal(side);
  std::string twice = kPatternScene;
  const std::string table = twice.substr(twice.find("[[pattern]]"), twice.find("[material]") - twice.find("[[pattern]]"));
  twice.replace(twice.find("[material]"), 0, table);
  EXPECT_EQ(refusal(twice).rfind("p.toml: pattern[1].name: \"panel\" names pattern 0 already", 0), 0u) << refusal(twice);
  std::string word = kPatternScene;
  word.replace(word.find("\"panel\""), 7, "\"pa nel\"");
  EXPECT_EQ(refusal(word).rfind("p.toml: pattern[0].name: must be a word", 0), 0u) << refusal(word);
  std::string prefix = kPatternScene;
  prefix.replace(prefix.find("panel:edge"), 5, "back");
  EXPECT_EQ(refusal(prefix), "p.toml: constraints.fixed[0]: \"back\" names no pattern of the scene");
  // A particle named by index does not follow a refinement, with a prefix too.
  std::string indexed = kPatternScene;
  indexed.replace(indexed.find("panel:edge:v0"), 13, "panel:particle:1,0");
  EXPECT_THROW(RefineGrid(ParseScene(indexed, "p.toml"), 100), SceneError);
  // Several patterns: a selection must say whose particles it names.
  std::string two = twice;
  two.replace(two.rfind("\"panel\""), 7, "\"back\"");
  EXPECT_EQ(ParseScene(two, "p.toml").num_particles(), 70);
  std::string unnamed = two;
  unnamed.replace(unnamed.find("panel:edge:v0"), 13, "edge:v0");
  EXPECT_EQ(refusal(unnamed).rfind("p.toml: constraints.fixed[0]: \"edge:v0\" must name its pattern", 0), 0u)
      << refusal(unnamed);
}

}  // namespace
}  // namespace clothbench
