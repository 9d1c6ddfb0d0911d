// Garments through bench_integrators and clothbench_inspect (docs/model.md
// §2.7–2.9): a rectangle pattern is the [grid] sheet on every default row,
// and a sewn garment runs, stores its sewn start, reruns bit for bit and
// keeps its seams closed.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include "results/result_reader.h"
#include "verify/cli_helpers.h"
#include "verify/test_scenes.h"

namespace clothbench {
namespace {

namespace fs = std::filesystem;

using testing::Outcome;

fs::path Dir() { return testing::TempDir("clothbench_garment_"); }

std::string WriteScene(const std::string& name, const std::string& text) {
  const fs::path p = Dir() / name;
  std::ofstream(p) << text;
  return p.string();
}

std::vector<std::string> RunIds(const ResultReader& f) { return f.Children("/runs"); }

// The same 7 × 5 sheet as [grid] and as one rectangle [[pattern]], 0.05 s
// with frames every 0.01 s. Every default row (fixed-step, iterated,
// substepped, adaptive, SUNDIALS) on both scenes: the same runs, the same
// positions at every stored frame.
TEST(GarmentCli, ARectanglePatternGivesTheGridsRunsOnEveryDefaultRow) {
  const fs::path a = Dir() / "grid.h5", b = Dir() / "pattern.h5";
  const std::string common = " --reference none --frames all --repeat 1 --quiet --out ";
  const Outcome ga = testing::RunCommand(
      CLOTHBENCH_BENCH_BINARY,
      "--scene " + WriteScene("grid.toml", testing::SheetScene(testing::kGridSheet, "edge:v0", 0.01, 0.01)) + common +
          a.string(),
      Dir());
  ASSERT_EQ(ga.exit_code, 0) << ga.err;
  const Outcome gb = testing::RunCommand(
      CLOTHBENCH_BENCH_BINARY,
      "--scene " +
          WriteScene("pattern.toml", testing::SheetScene(testing::kRectanglePattern, "panel:edge:v0", 0.01, 0.01)) +
          common + b.string(),
      Dir());
  ASSERT_EQ(gb.exit_code, 0) << gb.err;
  const ResultReader fa(a.string()), fb(b.string());
  const std::vector<std::string> ids = RunIds(fa);
  ASSERT_EQ(ids, RunIds(fb));
  // Every default row is there: 23 labels, most with several runs.
  std::set<std::string> labels;
  for (const std::string& id : ids) labels.insert(fa.String("/runs/" + id, "label").value_or(""));
  EXPECT_EQ(labels.size(), 23u);
  int compared = 0;
  for (const std::string& id : ids) {
    const std::string g = "/runs/" + id;
    EXPECT_EQ(fa.String(g, "status"), fb.String(g, "status")) << id;
    if (!fa.Exists(g + "/positions")) continue;  // a run that did not start stores no frames
    const std::vector<std::size_t> shape = fa.Shape(g + "/positions");
    ASSERT_EQ(shape, fb.Shape(g + "/positions")) << id;
    for (std::size_t k = 0; k < shape[0]; ++k) {
      // The sampling's round-off is the only allowed difference: a
      // rectangle's bilinear samples reproduce the grid's to ~1e-16 m,
      // which a run may carry to ~1e-12 m; 1e-9 m is the criterion.
      const double d = (fa.Frame(g + "/positions", k) - fb.Frame(g + "/positions", k)).cwiseAbs().maxCoeff();
      EXPECT_LE(d, 1e-9) << id << " frame " << k;
    }
    ++compared;
  }
  EXPECT_GE(compared, 40);  // the default rows' runs that store frames
}

// scenes/sewn_panels.toml through the command line: the sewing phase runs
// before the rows, the file stores the sewn start, the stored frames have
// no crossing triangle pair, and inspect rerun reproduces a run from the
// file alone; CVODE takes the self-contact response as the other rows do.
TEST(GarmentCli, ASewnGarmentRunsStoresItsStartAndReruns) {
  const fs::path out = Dir() / "panels.h5";
  const Outcome o = testing::RunCommand(
      CLOTHBENCH_BENCH_BINARY,
      std::string("--scene ") + CLOTHBENCH_SCENES_DIR +
          "/sewn_panels.toml --integrators sbdf2,xpbd,vbd,cvode "
          "--h 0.005 --substeps 4 --iterations 4 --rtols 1e-4 --t-end 0.2 --reference none --frames all --repeat 1 "
          "--quiet --out " +
          out.string(),
      Dir());
  ASSERT_EQ(o.exit_code, 0) << o.err;
  const ResultReader f(out.string());
  // 2 × 11 × 8 samples, the 2 × 8 seam pairs merged.
  ASSERT_TRUE(f.Exists("/scene/sewn_start"));
  EXPECT_EQ(f.Shape("/scene/sewn_start"), (std::vector<std::size_t>{160, 3}));
  EXPECT_LE(f.Double("/scene/sewn_start", "largest_gap_m").value_or(1.0), 1e-6);
  for (const char* id : {"sbdf2_h0.005", "xpbd_h0.005_n4", "vbd_h0.005_k4", "cvode_rtol0.0001"}) {
    EXPECT_EQ(f.String(std::string("/runs/") + id, "status"), "ok") << id;
    const Outcome si =
        testing::RunCommand(CLOTHBENCH_INSPECT_BINARY, out.string() + " self-intersections " + id, Dir());
    EXPECT_EQ(si.exit_code, 0) << id << ": " << si.out << si.err;
  }
  // The summary states the contact checks over every run: here 0 crossing
  // pairs (the runs above), and the deepest particle inside the obstacle.
  const Outcome summary = testing::RunCommand(CLOTHBENCH_INSPECT_BINARY, out.string() + " summary", Dir());
  EXPECT_EQ(summary.exit_code, 0) << summary.err;
  EXPECT_NE(summary.out.find("crossing triangle pairs: 0 at every stored frame of every run"), std::string::npos)
      << summary.out;
  double deepest = -1.0;
  for (const std::string& id : f.Children("/runs"))
    deepest = std::max(deepest, f.Double("/runs/" + id, "penetration_ratio").value_or(-1.0));
  ASSERT_GE(deepest, 0.0) << "sewn_panels has an obstacle: every run stores penetration_ratio";
  EXPECT_NE(summary.out.find(fmt::format("deepest penetration over the runs' stored frames: {:.3f} δ", deepest)),
            std::string::npos)
      << summary.out;
  const Outcome rerun = testing::RunCommand(CLOTHBENCH_INSPECT_BINARY, out.string() + " rerun sbdf2_h0.005", Dir());
  EXPECT_EQ(rerun.exit_code, 0) << rerun.out << rerun.err;
  EXPECT_NE(rerun.out.find("bit for bit"), std::string::npos) << rerun.out;
}

}  // namespace
}  // namespace clothbench
