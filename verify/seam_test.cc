// Seams (docs/model.md §2.8, docs/guide/scenes.md "Seams"): sewn sides become one
// particle, stencils read across the seam, and a seam is no hinge.
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <numbers>
#include <string>

#include "collision/cloth_mesh.h"
#include "model/particle_system.h"
#include "solver/static_solve.h"
#include "verify/stepping.h"

namespace clothbench {
namespace {

constexpr double kRadius = 0.1, kHeight = 0.3;
constexpr int kRing = 16, kRows = 7;  // particles around the tube and along it

std::string Material() {
  return "t_end = 0.1\nh = 0.005\nframe_dt = 0.05\n[material]\ndensity = 0.2\ntension = [300.0, 300.0]\n"
         "shear = 10.0\nbend = [2e-4, 2e-4]\n[forces]\ngravity = [0.0, -9.81, 0.0]\n";
}

// A pattern table: a w × kHeight rectangle, wrapped on the tube's cylinder
// (axis along y through (0, 0, −R)) from `origin` along `x_axis`.
std::string Pattern(const char* name, double width, int nu, const std::string& origin, const std::string& x_axis) {
  return fmt::format("[[pattern]]\nname = \"{}\"\ncorners = [[0.0, 0.0], [{:.17g}, 0.0], [{:.17g}, {:.17g}], [0.0, {:.17g}]]\n"
                     "samples = [{}, {}]\norigin = {}\nx_axis = {}\ny_axis = [0.0, 1.0, 0.0]\nwrap_radius = {:.17g}\n",
                     name, width, width, kHeight, kHeight, nu, kRows, origin, x_axis, kRadius);
}

// The tube from one pattern sewn to itself, side u0 to side u1.
Scene OnePatternTube() {
  const double w = 2.0 * std::numbers::pi * kRadius;
  const std::string text = "name = \"tube\"\n" + Material() + Pattern("tube", w, kRing + 1, "[0.0, 0.0, 0.0]", "[1.0, 0.0, 0.0]") +
                           "[[seam]]\na = \"tube:edge:u0\"\nb = \"tube:edge:u1\"\n"
                           "[constraints]\nfixed = [\"tube:edge:v1\"]\n";
  return ParseScene(text, "tube.toml");
}

// The same tube from two half patterns: the back one placed at the front
// one's end, turned about the axis, sewn at both sides.
Scene TwoPatternTube() {
  const double w = std::numbers::pi * kRadius;
  const std::string back_origin = fmt::format("[0.0, 0.0, {:.17g}]", -2.0 * kRadius);
  const std::string text = "name = \"tube2\"\n" + Material() +
                           Pattern("front", w, kRing / 2 + 1, "[0.0, 0.0, 0.0]", "[1.0, 0.0, 0.0]") +
                           Pattern("back", w, kRing / 2 + 1, back_origin, "[-1.0, 0.0, 0.0]") +
                           "[[seam]]\na = \"front:edge:u1\"\nb = \"back:edge:u0\"\n"
                           "[[seam]]\na = \"back:edge:u1\"\nb = \"front:edge:u0\"\n"
                           "[constraints]\nfixed = [\"front:edge:v1\", \"back:edge:v1\"]\n";
  return ParseScene(text, "tube2.toml");
}

TEST(Seam, SewnSidesAreOneParticleAndTheTubeIsClosed) {
  for (const Scene& s : {OnePatternTube(), TwoPatternTube()}) {
    ASSERT_NE(s.cloth, nullptr);
    EXPECT_EQ(s.num_particles(), kRing * kRows) << s.name;  // every seam pair merged
    EXPECT_LT(s.cloth->largest_gap, 1e-12) << s.name;       // the wrap closes the tube to round-off
    // Every triangle edge has a triangle across it but on the two rims.
    const ClothTriangles t = SceneTriangles(s);
    int open = 0;
    for (const auto& across : t.across)
      for (int a : across) open += a < 0;
    EXPECT_EQ(open, 2 * kRing) << s.name;
    // The fixed rim: kRing particles, once each.
    EXPECT_EQ(s.fixed.size(), static_cast<std::size_t>(kRing)) << s.name;
    const ParticleSystem sys(s);
    // Around: kRing per row; along: kRing per row but the last.
    EXPECT_EQ(sys.springs().size(), static_cast<std::size_t>(2 * kRing * kRows - kRing)) << s.name;
    // The cylinder's area, 2πR H, in its masses (uniform lumping: full cells; the rims count a whole cell each).
    EXPECT_NEAR(sys.masses().sum() / 0.2, 2.0 * std::numbers::pi * kRadius * kHeight * kRows / (kRows - 1), 1e-12)
        << s.name;
  }
}

// The tube from one pattern and from two half patterns reaches the same
// equilibrium (hanging from its top rim, under gravity): across a seam the
// stencils read the other pattern as they read inside one, so the two
// models are the same up to the order of their sums. Tolerance 1e-8 m: the
// static solve stops at max|f| ≤ 1e-9 max|m g| (solver/static_solve.h),
// which over the tube's smallest stiffness, bending at B/l³ ~ 0.03 N/m,
// leaves up to ~1e-9 m. With the ghost cells across the seams removed
// (each pattern's bending stops at the seam: a hinge) the equilibria differ
// by orders of magnitude more, so the comparison can fail.
TEST(Seam, ATubeFromOnePatternAndFromTwoHalvesHangAlike) {
  const Scene one = OnePatternTube(), two = TwoPatternTube();
  const ParticleSystem a(one), b(two);
  // Particle k of the one-pattern tube is the two-pattern tube's particle
  // at the same start position.
  std::vector<int> match(static_cast<std::size_t>(a.num_particles()), -1);
  for (int p = 0; p < a.num_particles(); ++p)
    for (int q = 0; q < b.num_particles(); ++q)
      if ((a.rest_positions().row(p) - b.rest_positions().row(q)).norm() < 1e-9) match[static_cast<std::size_t>(p)] = q;
  ASSERT_EQ(std::count(match.begin(), match.end(), -1), 0);
  const auto hang = [](const ParticleSystem& sys) {
    MatrixN3 x = sys.rest_positions();
    const StaticSummary st = SolveStatic(sys, {}, {}, &x);
    EXPECT_TRUE(st.converged) << sys.scene().name << ": " << st.message;
    return x;
  };
  const MatrixN3 xa = hang(a), xb = hang(b);
  double sag = 0.0, differ = 0.0;
  for (int p = 0; p < a.num_particles(); ++p) {
    sag = std::max(sag, (xa.row(p) - a.rest_positions().row(p)).norm());
    differ = std::max(differ, (xa.row(p) - xb.row(match[static_cast<std::size_t>(p)])).norm());
  }
  std::printf("[ seam ] tube: largest displacement %.3e m, one pattern vs two %.3e m\n", sag, differ);
  EXPECT_GT(sag, 1e-4);  // it does hang
  EXPECT_LT(differ, 1e-8);
  // The hinge: the same two patterns without reading across their seams.
  Scene hinge = two;
  ClothLayout cut = *two.cloth;
  for (ClothBlock& blk : cut.blocks)
    for (int j = -2; j < blk.nv + 2; ++j)
      for (int i = -2; i < blk.nu + 2; ++i)
        if (i < 0 || i >= blk.nu || j < 0 || j >= blk.nv) blk.particle[static_cast<std::size_t>(blk.Cell(i, j))] = -1;
  for (ClothBlock& blk : cut.blocks) std::fill(blk.owner.begin(), blk.owner.end(), 1);  // both sides' stencils, one-sided
  SetCloth(&hinge, std::move(cut));
  const ParticleSystem h(hinge);
  const MatrixN3 xh = hang(h);
  double hinged = 0.0;
  for (int p = 0; p < a.num_particles(); ++p)
    hinged = std::max(hinged, (xa.row(p) - xh.row(match[static_cast<std::size_t>(p)])).norm());
  std::printf("[ seam ] tube: one pattern vs two hinged at their seams %.3e m\n", hinged);
  EXPECT_GT(hinged, 100.0 * std::max(differ, 1e-10));
}

// --sizes on several patterns scales every pattern's intervals by one factor:
// the seams' sides keep equal counts and the tube stays closed.
TEST(Seam, RefinementScalesEveryPattern) {
  const Scene two = TwoPatternTube();
  const Scene fine = RefineGrid(two, 4L * two.num_particles());
  ASSERT_EQ(fine.patterns.size(), 2u);
  EXPECT_EQ(fine.patterns[0].nu, 2 * (kRing / 2) + 1);
  EXPECT_EQ(fine.patterns[0].nv, 2 * (kRows - 1) + 1);
  EXPECT_EQ(fine.num_particles(), 2 * kRing * (2 * (kRows - 1) + 1));
  EXPECT_LT(fine.cloth->largest_gap, 1e-12);
}

// A seam over part of two sides (a shoulder, a side below an armhole):
// only the samples in its ranges merge, and the cells beyond the rest of
// the side stay empty, a free border.
TEST(Seam, ASampleRangeSewsPartOfASide) {
  const std::string panels = "name = \"p\"\n" + Material() +
                             Pattern("left", 0.2, 5, "[0.0, 0.0, 0.0]", "[1.0, 0.0, 0.0]") +
                             Pattern("right", 0.2, 5, "[0.2, 0.0, 0.0]", "[1.0, 0.0, 0.0]");
  // Flat (no wrap): the two panels side by side, touching along x = 0.2.
  std::string flat = panels;
  for (std::size_t at; (at = flat.find("wrap_radius")) != std::string::npos;) flat.erase(at, flat.find('\n', at) - at + 1);
  const Scene s = ParseScene(flat + "[[seam]]\na = \"left:edge:u1\"\nb = \"right:edge:u0\"\na_samples = [2, 5]\n"
                                    "b_samples = [2, 5]\n",
                             "p.toml");
  EXPECT_EQ(s.num_particles(), 2 * 5 * kRows - 4);
  const ClothBlock& left = s.cloth->blocks[0];
  EXPECT_EQ(left.At(4, 3), s.cloth->blocks[1].At(0, 3));  // sewn
  EXPECT_NE(left.At(4, 0), s.cloth->blocks[1].At(0, 0));  // not in the range
  EXPECT_EQ(left.At(5, 3), s.cloth->blocks[1].At(1, 3));  // the cell beyond reads across
  EXPECT_EQ(left.At(5, 0), -1);                           // a free border below the range
  const ParticleSystem sys(s);
  MatrixN3 f(sys.num_particles(), 3);
  sys.Forces(0.0, sys.rest_positions(), MatrixN3::Zero(sys.num_particles(), 3), &f);
  // Flat and sewn where the sides touch: at rest but for gravity, m g per particle (round-off 1e-12 N).
  EXPECT_LT((f - sys.masses() * Vector3(0.0, -9.81, 0.0).transpose()).cwiseAbs().maxCoeff(), 1e-10);
  // --sizes scales the ranges with the sides: 7 → 13 samples along u, the
  // range [2, 5] → [4, 10], the same part of the side, still one pair per sample.
  const Scene fine = RefineGrid(s, 4L * s.num_particles());
  ASSERT_EQ(fine.patterns[0].nv, 13);
  EXPECT_EQ(fine.seams[0].first_a, 4);
  EXPECT_EQ(fine.seams[0].last_a, 10);
  EXPECT_EQ(fine.seams[0].first_b, 4);
  EXPECT_EQ(fine.seams[0].last_b, 10);
  EXPECT_EQ(fine.num_particles(), 2 * fine.patterns[0].nu * 13 - 7);
  const auto refusal = [&](const std::string& seam) {
    try {
      ParseScene(flat + seam, "p.toml");
    } catch (const SceneError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(refusal("[[seam]]\na = \"left:edge:u1\"\nb = \"right:edge:u0\"\na_samples = [2, 7]\n"),
            "p.toml: seam[0].a_samples: [2, 7] must be 2 samples first < last of \"left:edge:u1\"'s 0 … 6");
  EXPECT_EQ(refusal("[[seam]]\na = \"left:edge:u1\"\nb = \"right:edge:u0\"\na_samples = [2, 5]\n"),
            "p.toml: seam[0].b: \"left:edge:u1\" has 4 samples and \"right:edge:u0\" 7: a seam's sides must have the "
            "same number");
  EXPECT_NE(refusal("[[seam]]\na = \"left:edge:u1\"\nb = \"right:edge:u0\"\na_samples = [0, 3]\nb_samples = [0, 3]\n"
                    "[[seam]]\na = \"left:edge:u1\"\nb = \"right:edge:u0\"\na_samples = [3, 6]\nb_samples = [3, 6]\n")
                .find("sample 3 of side u1 of pattern \"left\" is in an earlier seam already"),
            std::string::npos);
}

TEST(Seam, RefusesSeamsNamingTheRule) {
  const auto refusal = [](std::string text) {
    try {
      ParseScene(text, "s.toml");
    } catch (const SceneError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  const double w = std::numbers::pi * kRadius;
  const std::string two = "name = \"x\"\n" + Material() + Pattern("front", w, 9, "[0.0, 0.0, 0.0]", "[1.0, 0.0, 0.0]") +
                          Pattern("back", w, 7, "[0.0, 0.0, -0.3]", "[-1.0, 0.0, 0.0]");
  EXPECT_EQ(refusal(two + "[[seam]]\na = \"front:edge:v0\"\nb = \"back:edge:v0\"\n"),
            "s.toml: seam[0].b: \"front:edge:v0\" has 9 samples and \"back:edge:v0\" 7: a seam's sides must have the "
            "same number");
  EXPECT_EQ(refusal(two + "[[seam]]\na = \"front:edge:v2\"\nb = \"back:edge:v0\"\n"),
            "s.toml: seam[0].a: must name a pattern's side, \"<pattern>:edge:<v0|u1|v1|u0>\"");
  EXPECT_EQ(refusal(two + "[[seam]]\na = \"side:edge:v0\"\nb = \"back:edge:v0\"\n"),
            "s.toml: seam[0].a: \"side\" names no pattern of the scene");
  // Far apart at the start: no sewing phase yet, and said so.
  EXPECT_EQ(refusal(two + "[[seam]]\na = \"front:edge:u0\"\nb = \"back:edge:u1\"\n").rfind("s.toml: seam: pairs up to", 0),
            0u);
  EXPECT_EQ(refusal(two + "[[seam]]\na = \"front:edge:u0\"\nb = \"front:edge:u0\"\n"), "s.toml: seam[0].b: is side a itself");
}

}  // namespace
}  // namespace clothbench
