// Every class of bad input and runaway run, through bench_integrators end to
// end (docs/notes/verification.md, "Bad input, blow-ups and limits"):
//  - refused before computing: exit 2, one line naming the key or option and
//    the rule (control characters escaped), and no file;
//  - accepted but numerically hopeless: the run ends with a failure status
//    (non_finite, energy_growth, time_limit), the other rows complete, and
//    the file stores no non-finite number anywhere.
#include <sys/stat.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

#include <fmt/format.h>

#include "results/result_reader.h"
#include "verify/cli_helpers.h"
#include "verify/hdf5_scan.h"

namespace clothbench {
namespace {

namespace fs = std::filesystem;
using testing::Outcome;

fs::path Dir() { return testing::TempDir("clothbench_bad_input_"); }

Outcome RunBench(const std::string& args) { return testing::RunCommand(CLOTHBENCH_BENCH_BINARY, args, Dir()); }

std::string WriteScene(const std::string& name, const std::string& text) {
  const fs::path p = Dir() / name;
  std::ofstream(p) << text;
  return p.string();
}

// `text` with its first `from` replaced by `to`.
std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

const std::string kTiny = testing::kTinyScene;

// One refusal: exit 2, exactly one line containing `needle`, no file, no
// .tmp, no journal.
void ExpectRefused(const std::string& args, const std::string& needle) {
  const fs::path out = Dir() / "refused.h5";
  fs::remove(out);
  const Outcome o = RunBench(args + " --out " + out.string());
  EXPECT_EQ(o.exit_code, 2) << args << "\n" << o.err;
  EXPECT_EQ(std::count(o.err.begin(), o.err.end(), '\n'), 1) << args << "\n" << o.err;
  EXPECT_NE(o.err.find(needle), std::string::npos) << args << "\n" << o.err;
  EXPECT_FALSE(fs::exists(out)) << args;
  EXPECT_FALSE(fs::exists(out.string() + ".tmp")) << args;
  EXPECT_FALSE(fs::exists(out.string() + ".journal")) << args;  // a refused run leaves no journal either
  EXPECT_FALSE(fs::exists(out.string() + ".lock")) << args;      // nor its lock file
}

std::string Scene(const std::string& name, const std::string& text) { return "--scene " + WriteScene(name, text); }

TEST(BadInput, OutOfRangeSceneValuesAreRefusedBeforeComputing) {
  // Absurd times: billions of steps or frames, or t_end beyond 1e6 s.
  ExpectRefused(Scene("t_end.toml", Replace(kTiny, "t_end = 0.04", "t_end = 1e300")), "t_end: must be a finite number");
  ExpectRefused(Scene("t_end2.toml", Replace(kTiny, "t_end = 0.04", "t_end = 1e7")), "t_end: must be <= 1e6 s");
  ExpectRefused(Scene("steps.toml", Replace(Replace(kTiny, "t_end = 0.04", "t_end = 2e5"), "frame_dt = 0.01", "frame_dt = 1")),
                "h: t_end/h = 200000/0.01 = 2e+07 steps exceeds the limit of 1e+07");
  ExpectRefused(Scene("frame.toml", Replace(kTiny, "frame_dt = 0.01", "frame_dt = 1e-310")), "frame_dt: t_end/frame_dt");
  ExpectRefused(Scene("h.toml", Replace(kTiny, "h = 0.01", "h = 1e-12")), "h: t_end/h");
  // A denormal or absurd density, tension, air drag or gravity.
  ExpectRefused(Scene("rho.toml", Replace(kTiny, "[material]\n", "[material]\ndensity = 1e-310\n")),
                "material.density: must be in [1e-06, 1e+06] kg/m²");
  ExpectRefused(Scene("k.toml", Replace(kTiny, "[100.0, 100.0]", "[1e300, 100.0]")), "material.tension");
  ExpectRefused(Scene("air.toml", kTiny + "[forces.air]\ncoefficient = 1e300\n"), "forces.air.coefficient");
  ExpectRefused(Scene("air2.toml", kTiny + "[forces.air]\ncoefficient = 1e9\n"), "forces.air.coefficient: must be in");
  ExpectRefused(Scene("g.toml", kTiny + "[forces]\ngravity = [0, 0, -1e6]\n"), "forces.gravity");
  // Grids: too many particles (before the memory estimate), sub-micron spacing.
  ExpectRefused(Scene("n.toml", Replace(Replace(kTiny, "nu = 4", "nu = 100000"), "nv = 3", "nv = 100000")),
                "grid.nv: nu × nv = 100000 × 100000 exceeds the limit");
  ExpectRefused(Scene("dx.toml", Replace(kTiny, "size = [0.3, 0.2]", "size = [1e-9, 0.2]")), "grid.size");
  // Obstacles far away or absurdly large.
  const std::string sphere = "\n[[obstacle]]\ntype = \"sphere\"\nradius = 0.1\ncenter = ";
  ExpectRefused(Scene("far.toml", kTiny + sphere + "[1e300, 0, 0]\n"), "obstacle[0].center");
  ExpectRefused(Scene("far2.toml", kTiny + sphere + "[1e7, 0, 0]\n"), "obstacle[0].center: must have coordinates");
  // Dimensions below 1e-6 m (a denormal radius made the polyhedron of
  // virtual particles collapse).
  ExpectRefused(Scene("tiny_r.toml", kTiny + "\n[[obstacle]]\ntype = \"cylinder\"\nradius = 9.31e-310\nheight = 0.7\n"),
                "obstacle[0].radius: must be in [1e-06, 1e+06] m");
  ExpectRefused(Scene("tiny_box.toml", kTiny + "\n[[obstacle]]\ntype = \"box\"\nsize = [1, 1e-9, 1]\n"),
                "obstacle[0].size: must be 3 edge lengths in [1e-6, 1e6] m");
  // Virtual particles need edges: a plane has none.
  ExpectRefused(Scene("vplane.toml", kTiny + "\n[[obstacle]]\ntype = \"plane\"\nvirtual_particles = true\n"),
                "obstacle[0].virtual_particles: must be false for a plane");
  // Stiction holds particles; the regularised law has no sticking.
  ExpectRefused(Scene("stiction.toml", Replace(kTiny, "[solver]\n", "[solver]\nfriction_cap = \"stiction\"\nfriction_law = \"regularised\"\n")),
                "solver: friction_cap = \"stiction\" holds particles in place and friction_law = \"regularised\"");
  // The implicit friction has no explicit impulse to cap.
  ExpectRefused(Scene("implicit_cap.toml", Replace(kTiny, "[solver]\n", "[solver]\nfriction_cap = \"system\"\nfriction_law = \"implicit\"\n")),
                "solver: friction_cap = \"system\" caps an explicit friction impulse and friction_law = \"implicit\" has none");
  ExpectRefused(Scene("iterated_cap.toml", Replace(kTiny, "[solver]\n", "[solver]\nfriction_cap = \"stiction\"\nfriction_law = \"implicit_iterated\"\n")),
                "solver: friction_cap = \"stiction\" caps an explicit friction impulse and friction_law = \"implicit_iterated\" has none");
  ExpectRefused(Scene("no_law.toml", Replace(kTiny, "[solver]\n", "[solver]\nfriction_law = \"iterated\"\n")),
                "solver.friction_law: must be one of \"explicit\" | \"regularised\" | \"implicit\" | \"implicit_iterated\" (got \"iterated\")");
}

TEST(BadInput, MeshesMustBeReadableNonEmptyAndPlacedInRange) {
  const std::string mesh = "\n[[obstacle]]\ntype = \"mesh\"\npath = \"";
  const std::string cube = std::string(CLOTHBENCH_DATA_DIR) + "/meshes/cube.off";
  ExpectRefused(Scene("scale.toml", kTiny + mesh + cube + "\"\nscale = 1e308\n"), "obstacle[0].scale");
  ExpectRefused(Scene("scale2.toml", kTiny + mesh + cube + "\"\nscale = 1e5\ntranslate = [0, 0, -9.5e5]\n"),
                "obstacle[0].path: ");
  std::ofstream(Dir() / "empty.off").close();
  ExpectRefused(Scene("empty.toml", kTiny + mesh + (Dir() / "empty.off").string() + "\"\n"),
                "obstacle[0].path: \"" + (Dir() / "empty.off").string() + "\": cannot be parsed");
  std::ofstream(Dir() / "garbage.off") << "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1\n3 0 1 2\n";  // a coordinate short
  ExpectRefused(Scene("garbage.toml", kTiny + mesh + (Dir() / "garbage.off").string() + "\"\n"),
                "obstacle[0].path: \"" + (Dir() / "garbage.off").string() + "\": vertex 2 is not three finite numbers");
  // A mesh CGAL cannot build is refused naming the face or vertex at fault
  // (TriangleMesh's diagnosis of the polygon soup).
  const std::string tri = "OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n";
  const std::vector<std::pair<std::string, std::string>> broken = {
      {tri + "3 0 1 2\n3 1 3 3\n", "face 1 is degenerate (it names a vertex twice)"},
      {tri + "3 0 1 2\n3 0 1 2\n", "face 1 duplicates face 0"},
      {"OFF\n3 1 0\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n", "vertex 1 is not three finite numbers"},
      {tri + "3 0 1 2\n3 1 3 7\n", "face 1 names vertex 7, but the file has 4 vertices"},
      {"OFF\n5 3 0\n0 0 0\n1 0 0\n0 1 0\n0 -1 0\n0 0 1\n3 0 1 2\n3 1 0 3\n3 0 1 4\n",
       "edge (0, 1) is shared by 3 faces (0, 1, 2): not manifold"},
  };
  for (std::size_t k = 0; k < broken.size(); ++k) {
    const fs::path off = Dir() / fmt::format("broken{}.off", k);
    std::ofstream(off) << broken[k].first;
    ExpectRefused(Scene(fmt::format("broken{}.toml", k), kTiny + mesh + off.string() + "\"\n"),
                  "obstacle[0].path: \"" + off.string() + "\": " + broken[k].second);
  }
  ExpectRefused(Scene("nomesh.toml", kTiny + mesh + "/nonexistent.off\"\n"), "obstacle[0].path: mesh file");
}

TEST(BadInput, OutOfRangeOptionsAreRefusedBeforeComputing) {
  const std::string tiny = Scene("tiny.toml", kTiny);
  ExpectRefused(tiny + " --t-end 1e300", "--t-end: 1e+300 s must be a number in (0, 1e6]");
  ExpectRefused(tiny + " --t-end 1e5", "--t-end: frame_dt: t_end/frame_dt = 100000/0.01");
  ExpectRefused(tiny + " --t-end nan", "--t-end");
  ExpectRefused(tiny + " --integrators sbdf2 --h 1e-12", "--h: sbdf2 at h = 1e-12 s needs t_end/h = 4e+10 steps");
  ExpectRefused(tiny + " --integrators xpbd --h 0.01 --substeps 1000000 --t-end 1",
                "--h/--substeps: xpbd at h = 0.01 s with 1000000 substeps");
  ExpectRefused(tiny + " --time-limit 0", "--time-limit");
  ExpectRefused(tiny + " --time-limit -5", "--time-limit");
  // Empty list items, leading, inner or trailing, name their option.
  ExpectRefused(tiny + " --h 0.01,", "--h: empty item in the list \"0.01,\"");
  ExpectRefused(tiny + " --h ,0.01", "--h: empty item in the list \",0.01\"");
  ExpectRefused(tiny + " --integrators sbdf2,,bdf2", "--integrators: empty item in the list");
  ExpectRefused(tiny + " --integrators sbdf2,", "--integrators: empty item in the list");
  // Tolerances double precision cannot meet.
  ExpectRefused(tiny + " --reference cvode --reference-rtol 1e-16", "--reference-rtol: 1e-16 is below 1e-14");
  ExpectRefused(tiny + " --integrators cvode --rtols 1e-3,1e-15", "--rtols: 1e-15 is below 1e-14");
  // Every output path is probed before computing (exit 2, no journal).
  ExpectRefused(tiny + " --series /proc/clothbench/s.csv", "--series: cannot write \"/proc/clothbench/s.csv\"");
  ExpectRefused(tiny + " --series " + Dir().string(), "--series: \"" + Dir().string() + "\" is a folder");
  // --table runs the thesis' rows: options it would ignore are refused.
  ExpectRefused(" --table 3.1 --h 0.01 --repeat 2", "--table: cannot be combined with --h, --repeat");
}

TEST(BadInput, ControlCharactersAreEscapedIntoOneLine) {
  // A newline and a bell inside a quoted value: the message stays one line
  // and shows them as escapes.
  ExpectRefused(Scene("ctl.toml", kTiny + "preconditioner = \"ic0\\nrm -rf\\u0007\"\n"), "(got \"ic0\\nrm -rf\\x07\")");
  ExpectRefused(Scene("tiny.toml", kTiny) + " --integrators \"$(printf 'sbdf2\\nbdf2')\"", "sbdf2\\nbdf2");
}

// A blown-up explicit run (symplectic Euler far beyond its stability limit
// h < 2/ω ≈ 6e-4 s at k = 1e5 N/m) and a very large air drag treated
// explicitly: each row ends with a failure status at the step where it
// blew up, keeps the frames before, and the file holds no non-finite value
// while the stable SBDF(2) row next to it is ok.
TEST(BadInput, BlowUpsEndWithAStatusAndStoreNoNonFinite) {
  const std::string stiff = Replace(kTiny, "[100.0, 100.0]", "[1e5, 1e5]");
  const fs::path out = Dir() / "blowup.h5";
  const Outcome o =
      RunBench(Scene("stiff.toml", Replace(stiff, "t_end = 0.04", "t_end = 1.0")) +
               " --integrators symplectic_euler,imex_euler,sbdf2 --h 0.01 --reference cvode --out " + out.string());
  ASSERT_EQ(o.exit_code, 0) << o.err;
  const testing::NonFiniteScan scan = testing::ScanForNonFinite(out.string());
  EXPECT_GT(scan.values, 1000);
  EXPECT_TRUE(scan.offenders.empty()) << scan.offenders.front();
  const ResultReader r(out.string());
  const std::string se = "/runs/symplectic_euler_h0.01";
  const std::string status = r.String(se, "status").value_or("");
  EXPECT_TRUE(status == "non_finite" || status == "energy_growth") << status;
  EXPECT_FALSE(r.Double(se, "energy_rate_W").has_value());
  EXPECT_FALSE(r.Double(se, "error_final_m").has_value());
  // Frames up to the failure: fewer than the 101 of a complete run, at least t = 0.
  const std::size_t kept = r.Shape(se + "/times")[0];
  EXPECT_GE(kept, 1u);
  EXPECT_LT(kept, 101u);
  EXPECT_EQ(r.String("/runs/sbdf2_h0.01", "status").value_or(""), "ok");

  // Air drag of c = 1e6 kg/(m² s) on ρ = 1 kg/m² is explicit in IMEX Euler
  // and SBDF(2) (the drag is not in A_α): h·c/ρ = 1e4, far beyond explicit
  // Euler's limit 2, so both blow up; CVODE, implicit in it, completes.
  const fs::path out2 = Dir() / "air.h5";
  const Outcome o2 = RunBench(Scene("air.toml", kTiny + "[forces.air]\ncoefficient = 1e6\n") +
                              " --integrators imex_euler,sbdf2,cvode --rtols 1e-3 --h 0.01 --reference none --out " +
                              out2.string());
  ASSERT_EQ(o2.exit_code, 0) << o2.err;
  const testing::NonFiniteScan scan2 = testing::ScanForNonFinite(out2.string());
  EXPECT_GT(scan2.values, 100);
  EXPECT_TRUE(scan2.offenders.empty()) << scan2.offenders.front();
  const ResultReader r2(out2.string());
  for (const std::string run : {"imex_euler_h0.01", "sbdf2_h0.01"}) {
    const std::string s = r2.String("/runs/" + run, "status").value_or("");
    EXPECT_TRUE(s == "non_finite" || s == "energy_growth") << run << ": " << s;
  }
}

// A wall-time budget: CVODE at rtol 1e-10 on a stiff 30×30 sheet takes far
// more than 0.2 s here, so it ends with time_limit after the step that
// passed the budget, and the SBDF(2) row still completes and is written.
TEST(BadInput, TimeLimitEndsARunAndTheOthersComplete) {
  std::string big = Replace(Replace(kTiny, "nu = 4", "nu = 30"), "nv = 3", "nv = 30");
  big = Replace(Replace(big, "[100.0, 100.0]", "[1e4, 1e4]"), "t_end = 0.04", "t_end = 1.0");
  const fs::path out = Dir() / "limit.h5";
  const Outcome o = RunBench(Scene("limit.toml", big) +
                             " --integrators cvode,sbdf2 --rtols 1e-10 --h 0.01 --reference none --time-limit 0.2 --out " +
                             out.string());
  ASSERT_EQ(o.exit_code, 0) << o.err;
  const ResultReader r(out.string());
  EXPECT_EQ(r.String("/runs/cvode_rtol1e-10", "status").value_or(""), "time_limit");
  const std::string message = r.String("/runs/cvode_rtol1e-10", "message").value_or("");
  EXPECT_NE(message.find("--time-limit 0.2 s"), std::string::npos) << message;
  EXPECT_EQ(r.String("/runs/sbdf2_h0.01", "status").value_or(""), "ok");
  EXPECT_TRUE(testing::ScanForNonFinite(out.string()).offenders.empty());
}

// Degenerate scenes × every method of the default rows, with IDA as the
// reference: a sheet without any stiffness or gravity (nothing moves), a
// 2×2 sheet with one free particle (systems of one unknown block) and a
// sheet with a single fixed particle and no stiffness falling freely. Every
// run ends ok or with a named failure status, the command exits 0 and the
// file holds no non-finite number; a sheet with every particle fixed is
// refused before computing (before, CVODE with KLU crashed on its empty
// system).
TEST(BadInput, DegenerateScenesRunWithEveryMethod) {
  const std::string still = Replace(Replace(Replace(kTiny, "tension = [100.0, 100.0]", "tension = [0.0, 0.0]"),
                                            "shear = 1.0", "shear = 0.0"),
                                    "[constraints]", "[forces]\ngravity = [0.0, 0.0, 0.0]\n[constraints]");
  const std::string one_free = Replace(Replace(Replace(kTiny, "nu = 4", "nu = 2"), "nv = 3", "nv = 2"),
                                       "fixed = [\"corner:u0v1\", \"corner:u1v1\"]",
                                       "fixed = [\"corner:u0v1\", \"corner:u1v1\", \"corner:u0v0\"]");
  const std::string falling = Replace(Replace(kTiny, "tension = [100.0, 100.0]", "tension = [0.0, 0.0]"),
                                      "fixed = [\"corner:u0v1\", \"corner:u1v1\"]", "fixed = [\"corner:u0v1\"]");
  int k = 0;
  for (const std::string& text : {still, one_free, falling}) {
    const fs::path out = Dir() / fmt::format("degenerate{}.h5", k);
    const Outcome o = RunBench(Scene(fmt::format("degenerate{}.toml", k++), text) +
                               " --reference ida --frames ends --repeat 1 --quiet --out " + out.string());
    ASSERT_EQ(o.exit_code, 0) << text << o.err;
    const ResultReader r(out.string());
    int runs = 0;
    for (const std::string& run : r.Children("/runs")) {
      ++runs;
      const std::string status = r.String("/runs/" + run, "status").value_or("");
      EXPECT_TRUE(status == "ok" || status == "no_fixed_point_convergence" || status == "cg_failed") << run << ": " << status;
    }
    EXPECT_GE(runs, 20);
    EXPECT_TRUE(testing::ScanForNonFinite(out.string()).offenders.empty()) << text;
  }
  const std::string all_fixed =
      Replace(one_free, "\"corner:u0v0\"]", "\"corner:u0v0\", \"corner:u1v0\"]");
  ExpectRefused(Scene("all_fixed.toml", all_fixed), "constraints.fixed: fixes all 4 particles; at least one must be free");
}

// Free disk space is checked before computing: on a 1 MB tmpfs the
// swinging sheet's 101 frames (journal and file: about 4.9 MB) are refused
// with exit 2 naming --out and leave nothing; its two end frames fit and
// run. Mounting needs root (CI runs as root); elsewhere the test is skipped.
// What failed at write time before (exit 1 after computing, journal left) or
// exited with a library's words is refused before computing: run ids that
// print alike, output paths that stand as something else or that the file
// system refuses, and mesh files that are folders, FIFOs, symlink loops or
// announce more than they hold. Each: exit 2, one line naming the option or
// key and the path, and nothing left behind.
TEST(BadInput, OutputPathsRunIdsAndMeshPathsAreCheckedBeforeComputing) {
  const std::string tiny = "--scene " + WriteScene("tiny.toml", kTiny) + " --integrators sbdf2 --reference none";
  ExpectRefused(tiny + " --h 0.01,0.0100000000001", "--h: 0.0100000000001 and 0.01 are the same to 6 significant");
  ExpectRefused(tiny + " --h 0.01 --cg-tolerances 1e-6,1.0000001e-6", "--cg-tolerances: 1.0000001e-6 and");
  const fs::path d = Dir() / "outs";
  const auto refused_out = [&](const fs::path& out, const std::string& needle) {
    const Outcome o = RunBench(tiny + " --h 0.01 --out " + out.string());
    EXPECT_EQ(o.exit_code, 2) << out << "\n" << o.err;
    EXPECT_EQ(std::count(o.err.begin(), o.err.end(), '\n'), 1) << o.err;
    EXPECT_NE(o.err.find("--out: \"" + d.string()), std::string::npos) << o.err;
    EXPECT_NE(o.err.find(needle), std::string::npos) << o.err;
    std::error_code ec;
    EXPECT_FALSE(fs::exists(out.string() + ".lock", ec)) << out;
    EXPECT_FALSE(fs::is_directory(out.string() + ".journal", ec)) << out;
  };
  fs::remove_all(d);
  fs::create_directories(d / "a.h5.tmp");
  refused_out(d / "a.h5", "a.h5.tmp\" (its temporary) is a folder");
  fs::create_directories(d / "b.xdmf");
  refused_out(d / "b.h5", "b.xdmf\" is a folder");
  ASSERT_EQ(mkfifo((d / "c.h5").c_str(), 0600), 0);
  refused_out(d / "c.h5", "c.h5\" is a FIFO");
  std::ofstream(d / "e.h5.journal") << "not a folder";
  refused_out(d / "e.h5", "e.h5.journal\" is not a folder");
  refused_out(d / (std::string(250, 'x') + ".h5"), "File name too long");
  fs::create_symlink(d / "loop1", d / "loop2");
  fs::create_symlink(d / "loop2", d / "loop1");
  refused_out(d / "loop1", "loop1\" is a symbolic link");  // never followed
  // Mesh paths: a folder, a FIFO, a symlink loop, a header announcing 2·10⁹
  // vertices (before: "out of memory although the run fitted the memory
  // estimate", exit 1).
  const std::string mesh = "[[obstacle]]\ntype = \"mesh\"\ncollision_distance = 0.01\npath = \"";
  ASSERT_EQ(mkfifo((d / "fifo.off").c_str(), 0600), 0);
  std::ofstream(d / "huge.off") << "OFF\n2000000000 1 0\n0 0 0\n";
  std::ofstream(d / "huge.ply") << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                   "property float z\nelement face 90000\nproperty list uchar int vertex_indices\n"
                                   "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  ExpectRefused(Scene("m1.toml", kTiny + mesh + d.string() + "\"\n"), "\" is not a regular file");
  ExpectRefused(Scene("m2.toml", kTiny + mesh + (d / "fifo.off").string() + "\"\n"), "\" is not a regular file");
  ExpectRefused(Scene("m3.toml", kTiny + mesh + (d / "loop1").string() + "\"\n"), "Too many levels of symbolic links");
  ExpectRefused(Scene("m4.toml", kTiny + mesh + (d / "huge.off").string() + "\"\n"),
                "obstacle[0].path: mesh file \"" + (d / "huge.off").string() + "\": announces 2e+09 vertices");
  ExpectRefused(Scene("m5.toml", kTiny + mesh + (d / "huge.ply").string() + "\"\n"),
                "more than its 184 bytes can hold");
  ExpectRefused("--scene " + (d / "loop1").string(), "cannot be used as a scene file: Too many levels");
  fs::remove_all(d);
}

// A write that fails after computing (here a file-size limit, RLIMIT_FSIZE,
// below the result file but above every journal entry: a disk that fills
// while the file is written) exits 1 with one line naming the file, the
// system's reason and the journal; it leaves no .tmp, no .part and no lock,
// and keeps the finished runs, from which the same command then writes the
// file without computing them again. Before, HDF5's exit handler crashed
// (SIGSEGV) on the file whose close had failed, and SIGXFSZ killed a run
// under `ulimit -f`.
TEST(BadInput, AFullDiskAtWriteTimeKeepsOnlyTheFinishedRuns) {
  const fs::path d = Dir() / "full";
  fs::remove_all(d);
  fs::create_directories(d);
  const fs::path out = d / "r.h5";
  const std::string args = "--scene " + WriteScene("full.toml", kTiny) +
                           " --integrators sbdf2,bdf2 --h 0.01,0.005 --frames all --quiet --out " + out.string();
  // 40 blocks: 20 KiB under dash (/bin/sh, 512-byte blocks), 40 KiB under
  // bash; journal entries of this scene are below 10 KiB, the file above 60 KiB.
  const Outcome full = testing::RunCommand("ulimit -f 40 && " + std::string(CLOTHBENCH_BENCH_BINARY), args, Dir());
  EXPECT_EQ(full.exit_code, 1) << full.err;
  EXPECT_EQ(std::count(full.err.begin(), full.err.end(), '\n'), 1) << full.err;
  EXPECT_NE(full.err.find(out.string() + ".tmp: HDF5 error:"), std::string::npos) << full.err;
  EXPECT_NE(full.err.find("File too large; no result file written; the 5 finished runs stay in"), std::string::npos)
      << full.err;
  std::vector<std::string> left;
  for (const auto& e : fs::recursive_directory_iterator(d)) left.push_back(fs::relative(e.path(), d).string());
  std::sort(left.begin(), left.end());
  EXPECT_EQ(left, (std::vector<std::string>{"r.h5.journal", "r.h5.journal/0.run", "r.h5.journal/1.run",
                                            "r.h5.journal/2.run", "r.h5.journal/3.run", "r.h5.journal/4.run",
                                            "r.h5.journal/key"}));
  const Outcome again = RunBench(args);
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_NE(again.out.find("5 of 5 runs from " + out.string() + ".journal; computing 0"), std::string::npos)
      << again.out;
  EXPECT_TRUE(fs::is_regular_file(out));
  EXPECT_FALSE(fs::exists(out.string() + ".journal"));
  fs::remove_all(d);
}

TEST(BadInput, OutputsThatCannotFitOnTheDiskAreRefused) {
  const fs::path small = Dir() / "small_fs";
  fs::create_directories(small);
  if (std::system(("mount -t tmpfs -o size=1m tmpfs " + small.string() + " 2> /dev/null").c_str()) != 0)
    GTEST_SKIP() << "cannot mount a tmpfs here (not root)";
  struct Unmount {  // also when an assertion returns early
    fs::path dir;
    ~Unmount() { std::system(("umount " + dir.string() + " 2> /dev/null").c_str()); }
  } unmount{small};
  const std::string args = " --scene swinging_sheet --integrators sbdf2 --h 0.01 --reference none --repeat 1 --quiet";
  const Outcome big = RunBench(args + " --out " + (small / "all.h5").string());
  EXPECT_EQ(big.exit_code, 2) << big.err;
  EXPECT_EQ(std::count(big.err.begin(), big.err.end(), '\n'), 1) << big.err;
  EXPECT_NE(big.err.find("--out: \"" + (small / "all.h5").string() + "\": the journal and the result file need about"),
            std::string::npos)
      << big.err;
  EXPECT_TRUE(fs::is_empty(small));
  const Outcome ends = RunBench(args + " --frames ends --out " + (small / "ends.h5").string());
  EXPECT_EQ(ends.exit_code, 0) << ends.err;
  EXPECT_TRUE(fs::exists(small / "ends.h5"));
}

// The limit holds inside a step too (model/interrupt.h): one XPBD step of
// 10⁶ substeps on 500×500 particles (hours) and one SBDF(2) step whose
// unpreconditioned PCG on the very stiff sheet (k = 1e9 N/m, η = 1e-12)
// needs 2144 iterations and 5.9 s alone (`bench_integrators` on this scene
// with --time-limit 100; at 300×300 it needed 1174 iterations, 0.77 s, under
// the limit on a quiet machine) both end as time_limit, each run's wall
// time within a tenth of the 1 s limit (plus the 0.5 s allowed for its
// setup: assembly and a factor-free start take milliseconds here).
TEST(BadInput, TimeLimitHoldsInsideSubstepsAndPcgIterations) {
  std::string big = Replace(Replace(kTiny, "nu = 4", "nu = 500"), "nv = 3", "nv = 500");
  big = Replace(Replace(big, "[100.0, 100.0]", "[1e9, 1e9]"), "cg_tolerance = 1e-10", "cg_tolerance = 1e-12\ncg_max_iterations = 1000000");
  const fs::path out = Dir() / "limit_inside.h5";
  const Outcome o = RunBench(Scene("limit_inside.toml", big) +
                             " --integrators xpbd,sbdf2 --h 0.04 --substeps 1000000 --preconditioner none --reference "
                             "none --frames none --repeat 1 --time-limit 1 --out " + out.string());
  ASSERT_EQ(o.exit_code, 0) << o.err;
  const ResultReader r(out.string());
  for (const char* run : {"/runs/xpbd_h0.04_n1000000", "/runs/sbdf2_h0.04"}) {
    EXPECT_EQ(r.String(run, "status").value_or(""), "time_limit") << run;
    EXPECT_LT(r.Double(run, "wall_time_s").value_or(1e9), 1.1 + 0.5) << run;
  }
}

}  // namespace
}  // namespace clothbench
