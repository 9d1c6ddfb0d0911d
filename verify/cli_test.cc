// bench_integrators end to end: bad input gives one line on stderr and a
// non-zero exit with no result file; a complete run writes the HDF5 layout;
// an interrupted run leaves no file under the final name.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <sys/stat.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <sstream>
#include <utility>
#include <vector>

#include "model/scene.h"
#include "results/result_file.h"
#include "results/result_reader.h"
#include "results/scale_verdict.h"
#include "results/run_records.h"
#include "results/run_table.h"
#include "verify/cli_helpers.h"

namespace clothbench {
namespace {

namespace fs = std::filesystem;

using testing::Outcome;

fs::path TempDir() { return testing::TempDir("clothbench_cli_"); }

Outcome RunBench(const std::string& args) { return testing::RunCommand(CLOTHBENCH_BENCH_BINARY, args, TempDir()); }

std::string WriteScene(const std::string& name, const std::string& text) {
  const fs::path p = TempDir() / name;
  std::ofstream(p) << text;
  return p.string();
}

const char* const kTiny = testing::kTinyScene;

void ExpectOneLineError(const Outcome& o, const std::string& needle, int code = 2) {
  EXPECT_EQ(o.exit_code, code) << o.err;
  EXPECT_EQ(std::count(o.err.begin(), o.err.end(), '\n'), 1) << o.err;
  EXPECT_NE(o.err.find(needle), std::string::npos) << o.err;
}

TEST(BenchCli, BadInputGivesOneLineAndNoFile) {
  const fs::path out = TempDir() / "bad.h5";
  const std::string o = " --out " + out.string();
  ExpectOneLineError(RunBench("--scene /nonexistent/scene.toml" + o), "cannot open scene file");
  ExpectOneLineError(RunBench("--scene /dev/null" + o), "/dev/null: not a regular file");
  ExpectOneLineError(RunBench("--scene " + TempDir().string() + o), "not a regular file");
  const fs::path fifo = TempDir() / "scene.fifo";
  fs::remove(fifo);
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  ExpectOneLineError(RunBench("--scene " + fifo.string() + o), "scene.fifo: not a regular file");
  ExpectOneLineError(RunBench("--scene " + WriteScene("syntax.toml", "name = \"x\"\n[grid\nnu = 3\n") + o),
                     "TOML syntax error");
  ExpectOneLineError(RunBench("--scene " + WriteScene("unknown.toml", std::string(kTiny) + "foo = 1\n") + o),
                     "solver.foo: unknown key");
  std::string neg = kTiny;
  neg.replace(neg.find("[100.0, 100.0]"), 14, "[-1.0, 100.0]");
  ExpectOneLineError(RunBench("--scene " + WriteScene("neg.toml", neg) + o), "material.tension");
  std::string badfix = kTiny;
  badfix.replace(badfix.find("corner:u1v1"), 11, "corner:u2v1");
  ExpectOneLineError(RunBench("--scene " + WriteScene("fix.toml", badfix) + o), "constraints.fixed[1]");
  const std::string plane = "\n[[obstacle]]\ntype = \"plane\"\nkeyframes = ";
  ExpectOneLineError(RunBench("--scene " + WriteScene("kf_t.toml", kTiny + plane + "[{ translate = [0, 0, 1] }]\n") + o),
                     "obstacle[0].keyframes[0].t: is required");
  ExpectOneLineError(RunBench("--scene " + WriteScene("kf_order.toml", kTiny + plane + "[{ t = 0.5 }, { t = 0.5 }]\n") + o),
                     "obstacle[0].keyframes[1].t: must be greater than the previous keyframe's t = 0.5");
  const std::string tiny = " --scene " + WriteScene("tiny.toml", kTiny);
  ExpectOneLineError(RunBench(tiny + " --integrators sbdf2,rk4" + o), "unknown integrator \"rk4\"");
  ExpectOneLineError(RunBench(tiny + " --h 0.01,-0.005" + o), "--h: \"-0.005\" is not a positive number");
  ExpectOneLineError(RunBench(tiny + " --h 0" + o), "--h: \"0\" is not a positive number");
  ExpectOneLineError(RunBench(tiny + " --reference ode45" + o), "--reference");
  ExpectOneLineError(RunBench(tiny + " --no-such-flag" + o), "no-such-flag");
  ExpectOneLineError(RunBench(tiny + " --preconditioner ilu" + o), "--preconditioner: \"ilu\" must be");
  ExpectOneLineError(RunBench(tiny + " --frames some" + o), "--frames: \"some\" must be");
  ExpectOneLineError(RunBench(tiny + " --integrators sbdf2 --baseline cvode" + o),
                     "--baseline: \"cvode\" is not a row of this run (sbdf2)");
  ExpectOneLineError(RunBench(tiny + " --integrators sbdf2 --rtols 1e-3,1e-4" + o),
                     "--rtols: no row of this run uses it (it applies to adaptive rows");
  ExpectOneLineError(RunBench(tiny + " --integrators cvode --substeps 4" + o), "--substeps: no row of this run uses it");
  ExpectOneLineError(RunBench(tiny + " --integrators xpbd --preconditioner amg" + o),
                     "--preconditioner: no row of this run uses it");
  ExpectOneLineError(RunBench(tiny + " --integrators sbdf2 --tangent-terms all" + o),
                     "--tangent-terms: no row of this run uses it");
  ExpectOneLineError(RunBench(tiny + " --error-metric rms" + o), "--error-metric: \"rms\" must be final, l2 or max");
  ExpectOneLineError(RunBench(tiny + " --tangent-terms some" + o), "--tangent-terms: \"some\" must be all or tension");
  ExpectOneLineError(RunBench(tiny + " --cvode-setting foo=1" + o), "--cvode-setting: \"foo\" is not one of");
  ExpectOneLineError(RunBench(tiny + " --cvode-setting eps_lin=-1" + o), "--cvode-setting: eps_lin=-1: must be");
  ExpectOneLineError(RunBench(tiny + " --cvode-setting lsetup_frequency" + o), "is not KEY=VALUE");
  // Refused before computing: duplicate list entries (two rows with one id)
  // and an output folder that cannot be written.
  ExpectOneLineError(RunBench(tiny + " --h 0.01,0.005,0.01" + o), "--h: 0.01 is listed twice");
  ExpectOneLineError(RunBench(tiny + " --integrators cvode --rtols 1e-3,1e-3" + o), "--rtols: 0.001 is listed twice");
  ExpectOneLineError(RunBench(tiny + " --integrators sbdf2,bdf2,sbdf2" + o), "--integrators: sbdf2 is listed twice");
  ExpectOneLineError(RunBench(tiny + " --integrators bdf2,bdf2/newton --nonlinear-solver fixed_point,newton" + o),
                     "--integrators: bdf2/newton is listed twice");
  ExpectOneLineError(RunBench(tiny + " --out /proc/clothbench/x.h5"), "--out: folder \"/proc/clothbench\"");
  std::string pre = kTiny;
  pre += "preconditioner = \"multigrid\"\n";
  ExpectOneLineError(RunBench("--scene " + WriteScene("pre.toml", pre) + o), "solver.preconditioner");
  // 3000 × 3000 particles (below the 1e7 limit of the scene format) with
  // the CVODE reference: refused by the memory estimate before any
  // computing, naming nu and nv (the reference's Jacobian and KLU factor
  // alone, ~4 kB per particle, need ~37 GB).
  std::string huge = kTiny;
  huge.replace(huge.find("nu = 4"), 6, "nu = 3000");
  huge.replace(huge.find("nv = 3"), 6, "nv = 3000");
  ExpectOneLineError(RunBench("--scene " + WriteScene("huge.toml", huge) + o), "grid.nu × grid.nv = 3000 × 3000");
  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(out.string() + ".tmp"));
}

// --table 5.1 runs the thesis' three virtual-particle examples and prints
// each beside the thesis' combined time (76.5, 171.5, 234 ms), with a file;
// it refuses the options that choose rows.
TEST(BenchCli, Table51PrintsTheThreeExamplesBesideTheThesis) {
  const fs::path out = TempDir() / "table_5_1.h5";
  const Outcome r = RunBench("--table 5.1 --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* row : {"round table", "square table", "ball", "76.5", "171.5", "234.0"})
    EXPECT_NE(r.out.find(row), std::string::npos) << row << " in:\n" << r.out;
  EXPECT_TRUE(fs::is_regular_file(out));
  ExpectOneLineError(RunBench("--table 5.1 --preconditioner amg --out " + (TempDir() / "t.h5").string()),
                     "--table 5.1: runs the scenes as they are");
}

TEST(BenchCli, CompleteRunWritesLayout) {
  const fs::path out = TempDir() / "tiny.h5";
  fs::remove(out);
  const Outcome o = RunBench("--scene " + WriteScene("tiny.toml", kTiny) +
                             " --integrators bdf2,cvode --h 0.01,0.005 --rtols 1e-6 --out " + out.string());
  ASSERT_EQ(o.exit_code, 0) << o.err;
  ASSERT_TRUE(fs::exists(out));
  EXPECT_FALSE(fs::exists(out.string() + ".tmp"));
  const hid_t f = H5Fopen(out.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  for (const char* obj : {"/scene", "/reference/times", "/reference/positions", "/runs/bdf2_h0.01/positions",
                          "/runs/bdf2_h0.005/step_stats", "/runs/cvode_rtol1e-06/times"})
    EXPECT_GT(H5Oexists_by_name(f, obj, H5P_DEFAULT), 0) << obj;
  for (const char* attr : {"schema", "created", "git_commit", "host", "compiler", "build_type"})
    EXPECT_GT(H5Aexists(f, attr), 0) << attr;
  EXPECT_GT(H5Aexists_by_name(f, "/runs/bdf2_h0.005", "error_final_m", H5P_DEFAULT), 0);
  EXPECT_GT(H5Aexists_by_name(f, "/runs/bdf2_h0.005", "observed_order", H5P_DEFAULT), 0);
  // --frames default: the label's first row (h = 0.01) keeps every frame,
  // [F, N, 3] with F = 5 frames (0, 0.01, …, 0.04) and N = 12; the second
  // row keeps t = 0 and t_end as positions_ends [2, N, 3].
  for (const auto& [path, frames] : {std::pair{"/runs/bdf2_h0.01/positions", 5u},
                                     std::pair{"/runs/bdf2_h0.005/positions_ends", 2u}}) {
    const hid_t ds = H5Dopen2(f, path, H5P_DEFAULT);
    ASSERT_GE(ds, 0) << path;
    const hid_t sp = H5Dget_space(ds);
    hsize_t dims[3];
    ASSERT_EQ(H5Sget_simple_extent_dims(sp, dims, nullptr), 3);
    EXPECT_EQ(dims[0], frames) << path;
    EXPECT_EQ(dims[1], 12u);
    EXPECT_EQ(dims[2], 3u);
    H5Sclose(sp);
    H5Dclose(ds);
  }
  EXPECT_EQ(H5Lexists(f, "/runs/bdf2_h0.005/positions", H5P_DEFAULT), 0);
  // Per-frame views for XDMF readers: frame 4 of the first row is a [N, 3]
  // virtual dataset equal to positions[4].
  {
    const hid_t all = H5Dopen2(f, "/runs/bdf2_h0.01/positions", H5P_DEFAULT);
    const hid_t view = H5Dopen2(f, "/runs/bdf2_h0.01/frame_views/positions_4", H5P_DEFAULT);
    ASSERT_GE(view, 0);
    std::vector<double> x(5 * 12 * 3), v(12 * 3);
    ASSERT_GE(H5Dread(all, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, x.data()), 0);
    ASSERT_GE(H5Dread(view, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()), 0);
    EXPECT_TRUE(std::equal(v.begin(), v.end(), x.begin() + 4 * 12 * 3));
    H5Dclose(view);
    H5Dclose(all);
  }
  // The grid's quads once: (4 − 1) × (3 − 1) = 6 faces of 4 particle
  // indices; the first is (0,0), (1,0), (1,1), (0,1) = 0, 1, 5, 4.
  const hid_t fd = H5Dopen2(f, "/scene/faces", H5P_DEFAULT);
  ASSERT_GE(fd, 0);
  const hid_t fsp = H5Dget_space(fd);
  hsize_t fdims[2];
  ASSERT_EQ(H5Sget_simple_extent_dims(fsp, fdims, nullptr), 2);
  EXPECT_EQ(fdims[0], 6u);
  EXPECT_EQ(fdims[1], 4u);
  std::vector<int32_t> faces(24);
  ASSERT_GE(H5Dread(fd, H5T_NATIVE_INT32, H5S_ALL, H5S_ALL, H5P_DEFAULT, faces.data()), 0);
  EXPECT_EQ(faces[0], 0);
  EXPECT_EQ(faces[1], 1);
  EXPECT_EQ(faces[2], 5);
  EXPECT_EQ(faces[3], 4);
  EXPECT_EQ(faces[23], 10);  // last quad (2,1), (3,1), (3,2), (2,2) = 6, 7, 11, 10
  H5Sclose(fsp);
  H5Dclose(fd);
  H5Fclose(f);
}

// --frames: "default" and "positions" keep velocities at the ends only (a
// single row is its label's first, so "default" keeps its positions), "all"
// every frame, "none" no frame datasets; every frame dataset is chunked one
// frame per chunk and deflate-compressed.
TEST(BenchCli, FramesModesAndCompression) {
  const std::string tiny = "--scene " + WriteScene("tiny.toml", kTiny) + " --integrators sbdf2 --h 0.01 --out ";
  struct Case {
    const char* mode;
    bool positions, velocities, velocities_ends;
  };
  for (const Case c : {Case{"default", true, false, true}, Case{"positions", true, false, true},
                       Case{"all", true, true, false},
                       Case{"none", false, false, false}}) {
    const fs::path out = TempDir() / (std::string("frames_") + c.mode + ".h5");
    const Outcome o = RunBench(tiny + out.string() + " --frames " + c.mode);
    ASSERT_EQ(o.exit_code, 0) << o.err;
    const hid_t f = H5Fopen(out.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    ASSERT_GE(f, 0);
    EXPECT_EQ(H5Lexists(f, "/runs/sbdf2_h0.01/positions", H5P_DEFAULT) > 0, c.positions) << c.mode;
    EXPECT_EQ(H5Lexists(f, "/runs/sbdf2_h0.01/velocities", H5P_DEFAULT) > 0, c.velocities) << c.mode;
    EXPECT_EQ(H5Lexists(f, "/runs/sbdf2_h0.01/velocities_ends", H5P_DEFAULT) > 0, c.velocities_ends) << c.mode;
    EXPECT_GT(H5Aexists_by_name(f, "/runs/sbdf2_h0.01", "error_final_m", H5P_DEFAULT), 0) << c.mode;
    if (c.positions) {
      const hid_t ds = H5Dopen2(f, "/runs/sbdf2_h0.01/positions", H5P_DEFAULT);
      const hid_t dcpl = H5Dget_create_plist(ds);
      hsize_t chunk[3] = {0, 0, 0};
      EXPECT_EQ(H5Pget_layout(dcpl), H5D_CHUNKED);
      EXPECT_EQ(H5Pget_chunk(dcpl, 3, chunk), 3);
      EXPECT_EQ(chunk[0], 1u);   // one frame per chunk
      EXPECT_EQ(chunk[1], 12u);  // all N particles
      unsigned flags = 0, values[8] = {0};
      bool deflate = false;
      for (int k = 0; k < H5Pget_nfilters(dcpl); ++k) {
        size_t nelmts = 8;
        deflate |= H5Pget_filter2(dcpl, static_cast<unsigned>(k), &flags, &nelmts, values, 0, nullptr, nullptr) ==
                   H5Z_FILTER_DEFLATE;
      }
      EXPECT_TRUE(deflate);
      H5Pclose(dcpl);
      H5Dclose(ds);
    }
    H5Fclose(f);
  }
}

TEST(BenchCli, NoReferenceLeavesErrorsOut) {
  const fs::path out = TempDir() / "noref.h5";
  const Outcome o = RunBench("--scene " + WriteScene("tiny.toml", kTiny) +
                             " --integrators sbdf2 --reference none --out " + out.string());
  ASSERT_EQ(o.exit_code, 0) << o.err;
  const hid_t f = H5Fopen(out.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  EXPECT_EQ(H5Lexists(f, "/reference", H5P_DEFAULT), 0);
  EXPECT_EQ(H5Aexists_by_name(f, "/runs/sbdf2_h0.01", "error_final_m", H5P_DEFAULT), 0);
  H5Fclose(f);
}

// A run killed half-way (SIGKILL, no cleanup at all) leaves nothing under
// the final name.
TEST(BenchCli, InterruptedRunLeavesNoFinalFile) {
  const fs::path out = TempDir() / "killed.h5";
  fs::remove(out);
  const std::string cmd = "timeout -s KILL 2 " + std::string(CLOTHBENCH_BENCH_BINARY) + " --out " + out.string() +
                          " > /dev/null 2>&1";
  const int rc = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(rc));
  EXPECT_EQ(WEXITSTATUS(rc), 137);  // killed by timeout, not finished
  EXPECT_FALSE(fs::exists(out));
}

// SIGINT and SIGTERM in the middle of a run (XPBD with 1024 substeps per
// 0.01 s step, ~9 s here), sent once the run's journal holds the
// reference, so that the handlers are installed and a row is under way
// however slow or loaded the machine: the run stops after the current step
// and exits 128 + signal with one line, leaving neither the result file nor
// its .tmp.
TEST(BenchCli, SignalsLeaveNoFileAndExit128PlusSignal) {
  for (const auto& [sig, code] : {std::pair{"INT", 130}, std::pair{"TERM", 143}}) {
    const fs::path out = TempDir() / (std::string("signal_") + sig + ".h5");
    const fs::path err = TempDir() / "signal_err.txt", rc = TempDir() / "signal_rc.txt";
    fs::remove_all(out.string() + ".journal");
    const std::string script =
        std::string(CLOTHBENCH_BENCH_BINARY) + " --integrators xpbd --h 0.01 --substeps 1024 --out " + out.string() +
        " > /dev/null 2> " + err.string() + " & pid=$!; i=0; until [ -f " + out.string() +
        ".journal/0.run ] || [ $i -ge 600 ]; do sleep 0.05; i=$((i+1)); done; kill -" + sig + " $pid; wait $pid; echo $? > " +
        rc.string();
    ASSERT_EQ(std::system(("sh -c '" + script + "'").c_str()), 0) << sig;
    EXPECT_EQ(std::stoi(testing::Slurp(rc)), code) << sig;
    const std::string text = testing::Slurp(err);
    EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 1) << text;
    EXPECT_NE(text.find(std::string("interrupted by SIG") + sig), std::string::npos) << text;
    EXPECT_FALSE(fs::exists(out)) << sig;
    EXPECT_FALSE(fs::exists(out.string() + ".tmp")) << sig;
    EXPECT_TRUE(fs::exists(out.string() + ".journal/0.run")) << sig;  // the reference, kept for a rerun
  }
}

// A stale .tmp from an earlier crash is replaced, and gone after the run.
TEST(BenchCli, StaleTmpIsReplaced) {
  const fs::path out = TempDir() / "stale.h5";
  fs::remove(out);
  std::ofstream(out.string() + ".tmp") << "left by a crashed run";
  const Outcome o = RunBench("--scene " + WriteScene("tiny.toml", kTiny) +
                             " --integrators sbdf2 --h 0.01 --reference none --out " + out.string());
  ASSERT_EQ(o.exit_code, 0) << o.err;
  EXPECT_TRUE(fs::exists(out));
  EXPECT_FALSE(fs::exists(out.string() + ".tmp"));
}

TEST(ResultFile, AppearsOnlyOnCommit) {
  const fs::path out = TempDir() / "unit.h5";
  fs::remove(out);
  {
    ResultFile f(out.string());
    f.CreateGroup("/runs/x");
    f.SetAttribute("/runs/x", "status", std::string("ok"));
    EXPECT_TRUE(fs::exists(out.string() + ".tmp"));
    EXPECT_FALSE(fs::exists(out));
  }  // destroyed without Commit: like an exception mid-run
  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(out.string() + ".tmp"));
  {
    ResultFile f(out.string());
    f.WriteVector("/times", {0.0, 0.1}, "s");
    f.Commit();
  }
  EXPECT_TRUE(fs::exists(out));
  EXPECT_FALSE(fs::exists(out.string() + ".tmp"));
}

// A scene file over 64 KiB (HDF5's attribute limit) is stored whole, as the
// /scene/toml dataset.
TEST(BenchCli, LargeSceneTextIsStored) {
  const fs::path out = TempDir() / "large_text.h5";
  std::string scene = kTiny;
  while (scene.size() < 70 * 1024) scene += "# a comment line that makes the scene file larger than 64 KiB\n";
  const Outcome o = RunBench("--scene " + WriteScene("large_text.toml", scene) +
                             " --integrators sbdf2 --h 0.01 --reference none --out " + out.string());
  ASSERT_EQ(o.exit_code, 0) << o.err;
  const hid_t f = H5Fopen(out.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  const hid_t ds = H5Dopen2(f, "/scene/toml", H5P_DEFAULT);
  ASSERT_GE(ds, 0);
  const hid_t type = H5Dget_type(ds);
  std::string text(H5Tget_size(type), '\0');
  ASSERT_GE(H5Dread(ds, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, text.data()), 0);
  EXPECT_EQ(text, scene);
  H5Tclose(type);
  H5Dclose(ds);
  H5Fclose(f);
}

// A triangle-mesh obstacle is stored once, placed, under
// /scene/obstacles/<k> (the cube of data/meshes: 8 vertices, 12 triangles),
// and the XDMF lists it as a static Triangle grid.
TEST(BenchCli, MeshObstaclesAreStoredForTheXdmf) {
  const fs::path out = TempDir() / "mesh.h5";
  const std::string scene = std::string(kTiny) + "\n[[obstacle]]\ntype = \"mesh\"\npath = \"" +
                            std::string(CLOTHBENCH_DATA_DIR) +
                            "/meshes/cube.off\"\nscale = 0.05\ntranslate = [0.15, 0.1, -0.5]\n";
  const Outcome o = RunBench("--scene " + WriteScene("mesh.toml", scene) +
                             " --integrators sbdf2 --h 0.01 --reference none --out " + out.string());
  ASSERT_EQ(o.exit_code, 0) << o.err;
  const hid_t f = H5Fopen(out.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  for (const auto& [path, rows] : {std::pair{"/scene/obstacles/0/vertices", 8u}, std::pair{"/scene/obstacles/0/triangles", 12u}}) {
    const hid_t ds = H5Dopen2(f, path, H5P_DEFAULT);
    ASSERT_GE(ds, 0) << path;
    const hid_t sp = H5Dget_space(ds);
    hsize_t dims[2] = {0, 0};
    ASSERT_EQ(H5Sget_simple_extent_dims(sp, dims, nullptr), 2);
    EXPECT_EQ(dims[0], rows) << path;
    EXPECT_EQ(dims[1], 3u) << path;
    H5Sclose(sp);
    H5Dclose(ds);
  }
  // Placed: x = 0.05 x_file + translate, so every vertex z is −0.5 ± 0.05.
  std::vector<double> v(24);
  const hid_t ds = H5Dopen2(f, "/scene/obstacles/0/vertices", H5P_DEFAULT);
  ASSERT_GE(H5Dread(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()), 0);
  // 1e-15: scale and translate in double, a few ulps of 0.5.
  for (int k = 0; k < 8; ++k) EXPECT_NEAR(std::abs(v[3 * k + 2] + 0.5), 0.05, 1e-15) << k;
  H5Dclose(ds);
  H5Fclose(f);
  std::ifstream in(TempDir() / "mesh.xdmf");
  std::stringstream xml;
  xml << in.rdbuf();
  EXPECT_NE(xml.str().find(R"(<Grid Name="obstacle_0" GridType="Uniform">)"), std::string::npos);
  EXPECT_NE(xml.str().find(R"(<Topology TopologyType="Triangle" NumberOfElements="12">)"), std::string::npos);
}

// Progress: a run longer than 2 s (XPBD with 512 substeps per 0.01 s step,
// ~4.6 s here, so it stays above 2 s on a machine twice as fast) draws a progress line on stderr when stderr is a terminal
// (util-linux `script` provides one), nothing with --quiet, and nothing
// when stderr is a file.
TEST(BenchCli, ProgressOnlyOnATerminal) {
  const fs::path out = TempDir() / "progress.h5", tty = TempDir() / "tty.txt";
  const std::string run = std::string(CLOTHBENCH_BENCH_BINARY) +
                          " --integrators xpbd --h 0.01 --substeps 512 --reference none --frames none --out " +
                          out.string();
  if (std::system("command -v script > /dev/null") != 0) GTEST_FAIL() << "util-linux script is missing";
  for (const bool quiet : {false, true}) {
    const std::string cmd =
        "script -qec '" + run + (quiet ? " --quiet" : "") + "' /dev/null > " + tty.string() + " 2>&1";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
    std::ifstream in(tty);
    std::stringstream ss;
    ss << in.rdbuf();
    const bool drawn = ss.str().find("xpbd h = 0.01 s/512: t = ") != std::string::npos &&
                       ss.str().find(" s elapsed, ~") != std::string::npos;
    EXPECT_EQ(drawn, !quiet) << ss.str();
  }
  const Outcome o = RunBench("--integrators xpbd --h 0.01 --substeps 512 --reference none --frames none --out " +
                             out.string());
  EXPECT_EQ(o.exit_code, 0);
  EXPECT_TRUE(o.err.empty()) << o.err;
}

// Without --preconditioner each PCG method gets its measured best
// ("auto": the CHOLMOD factor, in contact the contact policy) in place of the scene's ic0, the thesis' setting; a scene that
// names another preconditioner (the contact-scale scenes' prefiltered AMG,
// or Jacobi) keeps it.
TEST(BenchCli, OnlyASceneIc0GivesWayToTheMethodsBest) {
  for (const char* named : {"ic0", "amg", "jacobi"}) {
    SCOPED_TRACE(named);
    const fs::path out = TempDir() / (std::string("named_") + named + ".h5");
    const std::string scene = WriteScene(std::string("named_") + named + ".toml",
                                         std::string(kTiny) + "preconditioner = \"" + named + "\"\n");
    const Outcome o = RunBench("--scene " + scene + " --integrators sbdf2,bdf2/newton --h 0.01 --reference none " +
                               "--frames none --quiet --out " + out.string());
    ASSERT_EQ(o.exit_code, 0) << o.err;
    const RunTable t = ReadRunTable(ResultReader(out.string()));
    ASSERT_EQ(t.runs.size(), 2u);
    for (const RunRecord& r : t.runs) EXPECT_EQ(r.preconditioner, std::string(named) == "ic0" ? "auto" : named) << r.id;
  }
}

// The Fig. 4.3 series table names a run that did not end ok (its columns
// cover only the steps before it stopped): SBDF(3) at h = 0.01 s on the
// swinging box ends energy_growth (verify/blow_up_test.cc).
TEST(BenchCli, SeriesTableNamesARunThatStopped) {
  const fs::path csv = TempDir() / "fig_4_3.csv", out = TempDir() / "fig_4_3.h5";
  const Outcome o = RunBench("--scene swinging_box --integrators sbdf3,sbdf2 --h 0.01 --reference none --repeat 1 "
                             "--frames none --series " + csv.string() + " --out " + out.string());
  ASSERT_EQ(o.exit_code, 0) << o.err;
  const std::size_t row = o.out.find("\nsbdf3 ", o.out.find("Fig. 4.3 series"));
  ASSERT_NE(row, std::string::npos) << o.out;
  const std::string line = o.out.substr(row + 1, o.out.find('\n', row + 1) - row - 1);
  EXPECT_NE(line.find("energy_growth (stopped at t = "), std::string::npos) << line;
  const std::size_t ok_row = o.out.find("\nsbdf2 ", o.out.find("Fig. 4.3 series"));
  ASSERT_NE(ok_row, std::string::npos);
  EXPECT_EQ(o.out.substr(ok_row + 1, o.out.find('\n', ok_row + 1) - ok_row - 1).find("stopped"), std::string::npos);
}

// --sweep-to-targets: each row's runs are chosen from its errors until
// they bracket every target, or the row stops for a stated reason. On the
// swinging sheet over 0.2 s with sbdf2 and cvode at targets 1e-3 and 1e-5 m:
// a row whose reason is "targets met" has a cost at every target and a run
// below the smallest; the reasons are printed and stored; the options that
// set the runs by hand are refused.
TEST(BenchCli, SweepToTargetsBracketsEveryTargetOrSaysWhy) {
  const fs::path out = TempDir() / "sweep_to_targets.h5";
  const std::string common = " --integrators sbdf2,cvode --t-end 0.2 --targets 1e-3,1e-5 --repeat 1 --frames none";
  const Outcome o = RunBench(common + " --sweep-to-targets --out " + out.string());
  ASSERT_EQ(o.exit_code, 0) << o.err;
  EXPECT_NE(o.out.find("sweep to the targets, why each method stopped:"), std::string::npos) << o.out;
  const RunTable t = ReadRunTable(ResultReader(out.string()));
  ASSERT_TRUE(t.work_precision.has_value());
  const EqualAccuracyTable& w = *t.work_precision;
  ASSERT_EQ(w.stop_reasons.size(), 2u);
  EXPECT_EQ(w.stop_reasons[0].rfind("sbdf2: ", 0), 0u) << w.stop_reasons[0];
  for (std::size_t m = 0; m < w.labels.size(); ++m) {
    const bool met = w.stop_reasons[m].find("targets met") != std::string::npos;
    for (std::size_t j = 0; j < w.targets.size(); ++j)
      EXPECT_TRUE(w.cost[m][j].has_value() || !met) << w.labels[m] << " at " << w.targets[j];
    // A row that met the targets has a run below the smallest.
    double smallest = 1e300;
    for (const RunRecord& r : t.runs)
      if (r.label == w.labels[m] && r.ok() && r.error_final_m) smallest = std::min(smallest, *r.error_final_m);
    if (met) {
      EXPECT_LE(smallest, 1e-5) << w.labels[m];
    }
  }
  for (const char* option : {"--h 0.01", "--rtols 1e-4", "--reference none", "--max-runs 3"}) {
    const Outcome refused = RunBench(common + " --sweep-to-targets " + option + " --out " + out.string());
    EXPECT_EQ(refused.exit_code, 2) << option;
    EXPECT_NE(refused.err.find(std::string(option).substr(0, std::string(option).find(' '))), std::string::npos)
        << refused.err;
  }
}

// --sizes: one target sweep per size on the refined grid, each size's
// file, and the verdict file whose /scale_verdict holds every size's fastest
// method per target with its cost, read back and printed by
// clothbench_inspect verdict; combinations it cannot honour are refused.
TEST(BenchCli, SizesWriteOneFilePerSizeAndTheScaleVerdict) {
  const fs::path out = TempDir() / "sizes.h5";
  const std::string common =
      " --integrators sbdf2,cvode --t-end 0.2 --targets 1e-2,1e-3 --repeat 1 --frames none --quiet";
  const Outcome o = RunBench(common + " --sizes 100,400 --out " + out.string());
  ASSERT_EQ(o.exit_code, 0) << o.err;
  EXPECT_NE(o.out.find("Scale verdict"), std::string::npos) << o.out;
  for (const char* size : {"n100", "n400"}) {
    const fs::path f = TempDir() / (std::string("sizes.") + size + ".h5");
    ASSERT_TRUE(fs::exists(f)) << f;
    EXPECT_FALSE(fs::exists(f.string() + ".journal")) << "a size's journal outlived the verdict";
    const RunTable t = ReadRunTable(ResultReader(f.string()));
    EXPECT_EQ(t.n_particles, size == std::string("n100") ? 100 : 400);
    ASSERT_TRUE(t.work_precision.has_value());
    EXPECT_EQ(t.work_precision->stop_reasons.size(), 2u);  // the sizes are target sweeps
  }
  const ResultReader r(out.string());
  (void)ValidateResultFile(r);
  const ScaleVerdict v = ReadScaleVerdict(r);
  ASSERT_EQ(v.sizes, (std::vector<long>{100, 400}));
  ASSERT_EQ(v.targets, (std::vector<double>{1e-2, 1e-3}));
  ASSERT_EQ(v.labels, (std::vector<std::string>{"sbdf2", "cvode"}));
  EXPECT_TRUE(r.Exists("/sizes/n100/work_precision/solver_time"));
  for (std::size_t s = 0; s < 2; ++s)
    for (std::size_t j = 0; j < 2; ++j) {
      // Both rows bracket 1e-2 and 1e-3 m on these sheets: a fastest with the least cost.
      ASSERT_GE(v.fastest[s][j], 0) << s << " " << j;
      const double best = *v.cost[s][j][static_cast<std::size_t>(v.fastest[s][j])];
      for (std::size_t m = 0; m < 2; ++m)
        if (v.cost[s][j][m]) {
          EXPECT_LE(best, *v.cost[s][j][m]);
        }
      if (v.margin[s][j]) {
        EXPECT_GE(*v.margin[s][j], 1.0);
      }
    }
  const Outcome printed = testing::RunCommand(CLOTHBENCH_INSPECT_BINARY, out.string() + " verdict", TempDir());
  ASSERT_EQ(printed.exit_code, 0) << printed.err;
  EXPECT_NE(printed.out.find("Scale verdict"), std::string::npos) << printed.out;
  EXPECT_NE(printed.out.find("      400 "), std::string::npos) << printed.out;
  for (const char* bad : {"--sizes 400,100", "--sizes 100,2.5", "--sizes 100 --h 0.01", "--sizes 100 --series x.csv",
                          "--sizes 100,101", "--sizes 100 --reference none"}) {
    const Outcome refused = RunBench(common + " " + bad + " --out " + out.string());
    EXPECT_EQ(refused.exit_code, 2) << bad << ": " << refused.err;
    EXPECT_EQ(std::count(refused.err.begin(), refused.err.end(), '\n'), 1) << refused.err;
  }
  const Outcome particle = RunBench(
      common + " --sizes 100 --scene " +
      WriteScene("indexed.toml", "[constraints]\nfixed = [\"particle:1,1\"]\n") + " --out " + out.string());
  EXPECT_EQ(particle.exit_code, 2);
  EXPECT_NE(particle.err.find("constraints.fixed"), std::string::npos) << particle.err;
}

// A contact scene's equal-accuracy table: against the stated reference,
// CVODE integrating the contact problem with event location, whose own
// error (e_l2 against rtol/10) is measured, printed and stored, in the l2
// metric unless --error-metric names another; and its cross-check, the
// self-convergence run (BDF(2) at h_min/32 with tight tolerances, its own
// estimate against 2 h_ref), with the difference of the two references,
// printed and stored. The reference's error is below the row's (a row
// cannot be measured more precisely than its reference), and the
// self-convergence run, a fixed-step run at h/32, is nearer to the
// reference than the row at h.
TEST(BenchCli, ContactSceneTableStatesItsReferenceAndItsSelfConvergence) {
  const fs::path out = TempDir() / "contact_verdict.h5";
  const Outcome o = RunBench("--scene swinging_box --integrators sbdf2 --h 0.01 --t-end 0.5 --repeat 1 --frames none "
                             "--out " + out.string());
  ASSERT_EQ(o.exit_code, 0) << o.err;
  EXPECT_NE(o.out.find("reference: CVODE BDF/Newton"), std::string::npos) << o.out;
  EXPECT_NE(o.out.find("cross-check: BDF(2) with the thesis' response at bdf2 h = "), std::string::npos) << o.out;
  EXPECT_NE(o.out.find(" m/s, 1 kernel thread (self-convergence against 2h and 4h, observed order "),
            std::string::npos)
      << o.out;
  EXPECT_NE(o.out.find("Equal accuracy: solver time [s] at e_l2"), std::string::npos) << o.out;
  const RunTable t = ReadRunTable(ResultReader(out.string()));
  EXPECT_EQ(t.error_metric, "l2");
  ASSERT_TRUE(t.reference.has_value());
  const double own = t.reference->error_estimate_m;
  ASSERT_EQ(t.runs.size(), 1u);
  ASSERT_TRUE(t.runs[0].error_l2_m.has_value());
  EXPECT_GT(own, 0.0);
  EXPECT_LT(own, *t.runs[0].error_l2_m);
  EXPECT_EQ(t.reference->cross_check.rfind("bdf2 h = ", 0), 0u) << t.reference->cross_check;
  EXPECT_NE(t.reference->cross_check.find("friction_law = regularised, predictor = extrapolate, fixed_point_tolerance = 1e-09 m/s, 1 kernel thread (self-convergence against 2h and 4h"),
            std::string::npos)
      << t.reference->cross_check;
  EXPECT_GT(t.reference->cross_check_error_estimate_m, 0.0);
  EXPECT_GT(t.reference->cross_check_difference_m, 0.0);
  EXPECT_LT(t.reference->cross_check_difference_m, *t.runs[0].error_l2_m);
}

// The scene's solver settings that no run attribute carries are stored in
// /scene and read back as written, so that a file names every setting.
TEST(BenchCli, TheSceneStoresEverySolverSetting) {
  const fs::path out = TempDir() / "solver_settings.h5";
  const std::string scene = WriteScene("solver_settings.toml",
                                       std::string(kTiny) +
                                           "contact_factors = false\ncholesky_ordering = \"amd\"\n"
                                           "cg_max_iterations = 77\ntangent_projection = \"none\"\n"
                                           "newton_jacobian = \"frozen\"\ncontroller_updates = [2, 5]\n"
                                           "fixed_point_tolerance = 1e-7\nstep_factor = 1.5\nh_min = 1e-5\n"
                                           "h_max = 0.02\nmax_rejections = 7\ncontact_history = \"restart\"\n");
  const Outcome o = RunBench("--scene " + scene + " --integrators sbdf2 --h 0.01 --reference none --frames none " +
                             "--quiet --out " + out.string());
  ASSERT_EQ(o.exit_code, 0) << o.err;
  const RunTable t = ReadRunTable(ResultReader(out.string()));
  EXPECT_EQ(t.contact_factors, "false");
  EXPECT_EQ(t.cholesky_ordering, "amd");
  EXPECT_EQ(t.cg_max_iterations, 77);
  EXPECT_EQ(t.tangent_projection, "none");
  EXPECT_EQ(t.newton_jacobian, "frozen");
  EXPECT_EQ(t.contact_history, "restart");
  EXPECT_EQ(t.controller_updates, "2,5");
  EXPECT_EQ(t.fixed_point_tolerance, 1e-7);
  EXPECT_EQ(t.step_factor, 1.5);
  EXPECT_EQ(t.h_min, 1e-5);
  EXPECT_EQ(t.h_max, 0.02);
  EXPECT_EQ(t.max_rejections, 7);
}

// Every run stores the settings it actually ran with, whatever the scene
// says: an option × row-kind walk (fixed-step, error-controlled, Newton,
// SUNDIALS, ARKODE, substepped, Baraff–Witkin) read back from the file.
TEST(BenchCli, EveryRunStoresTheSettingsItUsed) {
  const fs::path out = TempDir() / "settings.h5";
  const std::string scene = WriteScene("settings.toml", kTiny);
  const Outcome o = RunBench("--scene " + scene + " --integrators sbdf2,sbdf2/error,bdf2/newton,cvode,arkode,xpbd," +
                             "baraff_witkin,pd/chebyshev --h 0.01 --rtols 1e-3 --substeps 2 --iterations 3 " +
                             "--preconditioner jacobi " +
                             "--cg-tolerance 1e-5 --tangent-terms all --arkode-table ARK437L2SA --reference none " +
                             "--frames none --quiet --out " + out.string());
  ASSERT_EQ(o.exit_code, 0) << o.err;
  const RunTable t = ReadRunTable(ResultReader(out.string()));
  ASSERT_EQ(t.runs.size(), 8u);
  for (const RunRecord& r : t.runs) {
    SCOPED_TRACE(r.id);
    EXPECT_EQ(r.status, RunStatus::kOk);
    EXPECT_GT(r.threads, 0);
    const bool pcg = r.integrator != "xpbd" && r.integrator != "pd";
    EXPECT_EQ(r.preconditioner, pcg ? "jacobi" : "");  // --preconditioner overrides each method's best
    EXPECT_EQ(r.cg_tolerance, pcg ? 1e-5 : 0.0);       // and --cg-tolerance baraff_witkin's 1e-2
    EXPECT_EQ(r.predictor, pcg ? "constant" : "");
    const bool tangent = r.label == "bdf2/newton" || r.integrator == "cvode" || r.integrator == "baraff_witkin";
    EXPECT_EQ(r.tangent_terms, tangent ? "all" : "");  // --tangent-terms overrides baraff_witkin's tension
    EXPECT_EQ(r.newton_jacobian, r.label == "bdf2/newton" ? "refresh" : "");
    EXPECT_EQ(r.MethodText("butcher_table"), r.integrator == "arkode" ? "ARK437L2SA" : "");
    const bool sundials = r.integrator == "cvode" || r.integrator == "arkode";
    EXPECT_EQ(r.step_control, sundials ? "sundials" : r.label == "sbdf2/error" ? "error" : "fixed");
    EXPECT_EQ(r.step_kind, r.integrator == "xpbd"                 ? StepKind::kSubstepped
                           : r.integrator == "pd"                 ? StepKind::kIterated
                           : sundials || r.label == "sbdf2/error" ? StepKind::kAdaptive
                                                                  : StepKind::kFixedStep);
    if (r.step_kind == StepKind::kAdaptive) { EXPECT_TRUE(r.rtol == 1e-3 && r.atol == 1e-3); }
    if (r.step_kind == StepKind::kSubstepped) { EXPECT_EQ(r.substeps, 2); }
    if (r.step_kind == StepKind::kIterated) { EXPECT_TRUE(r.iterations == 3 && r.id == "pd_chebyshev_h0.01_k3"); }
    EXPECT_EQ(r.iterations, r.step_kind == StepKind::kIterated ? 3 : 0);
  }
}

// --repeat K times every run K times: the least solver time is reported with
// the median and the largest, each later timing having reproduced the first
// run's end state (else the run fails, which this exit code would show).
TEST(BenchCli, RepeatTimesEveryRun) {
  const fs::path out = TempDir() / "repeat.h5";
  const Outcome o = RunBench("--scene " + WriteScene("repeat.toml", kTiny) +
                             " --integrators sbdf2,cvode --h 0.01,0.005 --rtols 1e-3 --repeat 3 --reference none "
                             "--frames none --quiet --out " + out.string());
  ASSERT_EQ(o.exit_code, 0) << o.err;
  const RunTable t = ReadRunTable(ResultReader(out.string()));
  ASSERT_EQ(t.runs.size(), 3u);
  for (const RunRecord& r : t.runs) {
    EXPECT_EQ(r.repeats, 3) << r.id;
    EXPECT_LE(r.solver_time_s, r.solver_time_s_median) << r.id;
    EXPECT_LE(r.solver_time_s_median, r.solver_time_s_max) << r.id;
    EXPECT_GE(r.TimeSpread(), 0.0) << r.id;
  }
  ExpectOneLineError(RunBench("--scene " + WriteScene("repeat.toml", kTiny) + " --repeat 0 --out " + out.string()),
                     "--repeat");
}

// A scene under error control ([solver] step_control = "error") makes its
// sbdf2 and bdf2 rows the error-controlled rows they step as: labelled
// sbdf2/error, adaptive, at --rtols or else at the scene's rtol, and stored
// so. (They were listed by h, ignoring --rtols.)
TEST(BenchCli, SceneErrorControlMakesErrorRows) {
  const std::string scene =
      WriteScene("error_control.toml", std::string(kTiny) + "step_control = \"error\"\nrtol = 1e-3\n");
  const fs::path out = TempDir() / "error_control.h5";
  Outcome o = RunBench("--scene " + scene + " --integrators sbdf2 --rtols 1e-3,1e-5 --reference none --frames none "
                       "--repeat 1 --quiet --out " + out.string());
  ASSERT_EQ(o.exit_code, 0) << o.err;
  RunTable t = ReadRunTable(ResultReader(out.string()));
  ASSERT_EQ(t.runs.size(), 2u);
  for (const RunRecord& r : t.runs) {
    EXPECT_EQ(r.label, "sbdf2/error") << r.id;
    EXPECT_EQ(r.step_kind, StepKind::kAdaptive) << r.id;
    EXPECT_EQ(r.step_control, "error") << r.id;
  }
  EXPECT_EQ(t.runs[0].rtol, 1e-3);
  EXPECT_EQ(t.runs[1].rtol, 1e-5);
  EXPECT_LT(t.runs[0].steps, t.runs[1].steps);  // a tighter rtol takes more steps
  o = RunBench("--scene " + scene + " --integrators sbdf2 --reference none --frames none --repeat 1 --quiet --out " +
               out.string());
  ASSERT_EQ(o.exit_code, 0) << o.err;
  t = ReadRunTable(ResultReader(out.string()));
  ASSERT_EQ(t.runs.size(), 1u);
  EXPECT_EQ(t.runs[0].id, "sbdf2_error_rtol0.001");
  // A named row that cannot control its step by the error is refused before
  // anything is computed: exit 2, one line naming the row and the scene key,
  // no file; the default rows leave such methods out.
  fs::remove(out);
  o = RunBench("--scene " + scene + " --integrators sbdf2,imex_euler --reference none --frames none --repeat 1 "
               "--quiet --out " + out.string());
  EXPECT_EQ(o.exit_code, 2) << o.err;
  EXPECT_EQ(std::count(o.err.begin(), o.err.end(), '\n'), 1) << o.err;
  EXPECT_NE(o.err.find("--integrators: imex_euler cannot step under the scene's [solver] step_control = \"error\""),
            std::string::npos)
      << o.err;
  EXPECT_FALSE(fs::exists(out));
  o = RunBench("--scene " + scene + " --reference none --frames none --repeat 1 --quiet --out " + out.string());
  ASSERT_EQ(o.exit_code, 0) << o.err;
  for (const RunRecord& r : ReadRunTable(ResultReader(out.string())).runs) EXPECT_EQ(r.status, RunStatus::kOk) << r.id;
}

// contact_replay: a state saved in contact replays from there (the sheet on
// the round table stays constrained), two replays of one state take the
// same steps (CG iterations and constrained particles per step, to the
// digit), and a damaged or foreign state file is refused with one line.
TEST(ContactReplay, SavedStateReplaysReproduciblyAndBadStatesAreRefused) {
  const fs::path dir = TempDir();
  const std::string prefix = (dir / "rt").string();
  const auto run = [&](const std::string& args) { return testing::RunCommand(CLOTHBENCH_REPLAY_BINARY, args, dir); };
  const Outcome saved = run("save --scene round_table --at 0.3,0.6 --out " + prefix);
  ASSERT_EQ(saved.exit_code, 0) << saved.err;
  ASSERT_TRUE(fs::exists(prefix + "_0.state") && fs::exists(prefix + "_1.state"));
  EXPECT_FALSE(fs::exists(prefix + "_1.state.tmp"));
  // Column `c` (0-based) of every step line: 1 CG iterations, 2 constrained
  // particles, 7 and 8 setups in nearest-axis and in spread frames.
  const auto column = [](const std::string& out, int c) {
    std::istringstream in(out);
    std::vector<double> values;
    for (std::string line; std::getline(in, line);) {
      if (line.empty() || line[0] == '#') continue;
      std::istringstream fields(line);
      double v = 0.0;
      for (int k = 0; k <= c; ++k) fields >> v;
      values.push_back(v);
    }
    return values;
  };
  const auto counts = [&](const std::string& out) { return std::pair(column(out, 1), column(out, 2)); };
  const std::string replay = "replay --scene round_table --steps 3 --state " + prefix + "_1.state";
  const Outcome first = run(replay);
  ASSERT_EQ(first.exit_code, 0) << first.err;
  const auto rows = counts(first.out);
  ASSERT_EQ(rows.first.size(), 3u) << first.out;
  for (std::size_t k = 0; k < 3; ++k) {
    EXPECT_GT(rows.first[k], 0);
    EXPECT_GT(rows.second[k], 40);  // of 400: the sheet rests on the table top at t = 0.6 s
  }
  EXPECT_NE(first.out.find("  0.6100 "), std::string::npos) << first.out;
  const Outcome second = run(replay);
  ASSERT_EQ(second.exit_code, 0) << second.err;
  EXPECT_EQ(counts(second.out), rows);

  // Refused: a truncated file, another scene's state, bad options.
  const fs::path cut = dir / "cut.state";
  {
    const std::string bytes = testing::Slurp(prefix + "_1.state");
    std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  }
  ExpectOneLineError(run("replay --scene round_table --steps 1 --state " + cut.string()), "truncated");
  ExpectOneLineError(run("replay --scene " + WriteScene("tiny.toml", kTiny) + " --steps 1 --state " + prefix +
                         "_1.state"),
                     "a state of this scene's 12 particles has");
  // Another scene with the same 400 particles (a lighter sheet on the same table).
  {
    std::string other = LoadSceneOrBuiltin("round_table").toml;
    other += "\n# the same particles, another scene text\n";
    ExpectOneLineError(run("replay --scene " + WriteScene("other_table.toml", other) + " --steps 1 --state " +
                           prefix + "_1.state"),
                       "was saved from another scene");
  }
  // Special files are refused before they are opened or read: a FIFO (it
  // would block), a folder, /dev/zero (endless).
  const fs::path fifo = dir / "state.fifo";
  fs::remove(fifo);
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  for (const std::string& special : {fifo.string(), dir.string(), std::string("/dev/zero")})
    ExpectOneLineError(run("replay --scene round_table --steps 1 --state " + special), "is not a regular file");
  // Steps past t_end (round_table: t_end = 1 s, h = 0.01 s; the state is at 0.6 s).
  ExpectOneLineError(run("replay --scene round_table --steps 41 --state " + prefix + "_1.state"), "past t_end");
  ExpectOneLineError(run(replay + " --integrator leapfrog"), "--integrator: unknown integrator \"leapfrog\"");
  ExpectOneLineError(run(replay + " --integrator xpbd"), "--integrator xpbd: not one of");
  ExpectOneLineError(run(replay + " --preconditioner lu"), "--preconditioner: \"lu\" must be");
  // save: an output that exists as something else than a regular file, or
  // whose lock another process holds, is refused before computing.
  const std::string taken = (dir / "taken").string();
  fs::create_directories(taken + "_0.state");
  ExpectOneLineError(run("save --scene round_table --at 0.02 --out " + taken), "is a folder");
  fs::remove_all(taken + "_0.state");
  ExpectOneLineError(run(replay + " --amg-frames wobbly"), "--amg-frames: \"wobbly\" must be");
  // The overrides replace keys the scene names (round_table names ic0).
  const Outcome overridden = run(replay + " --preconditioner amg --amg-frames nearest_axis");
  ASSERT_EQ(overridden.exit_code, 0) << overridden.err;
  const std::vector<double> nearest = column(overridden.out, 7), spread = column(overridden.out, 8);
  EXPECT_GT(std::accumulate(nearest.begin(), nearest.end(), 0.0), 0.0) << overridden.out;
  EXPECT_EQ(std::accumulate(spread.begin(), spread.end(), 0.0), 0.0) << overridden.out;
  ExpectOneLineError(run("save --scene round_table --at 0.5,0.2 --out " + prefix), "times must increase");
}

}  // namespace
}  // namespace clothbench

namespace clothbench {
namespace {

// A small tmpfs mounted at `dir` (root only), unmounted by the destructor;
// mounted() is false where the machine does not allow it.
class SmallTmpfs {
 public:
  SmallTmpfs(const fs::path& dir, const std::string& size) : dir_(dir) {
    fs::create_directories(dir_);
    mounted_ = ::geteuid() == 0 &&
               std::system(("mount -t tmpfs -o size=" + size + " tmpfs " + dir_.string() + " 2>/dev/null").c_str()) == 0;
  }
  ~SmallTmpfs() {
    if (mounted_) (void)std::system(("umount " + dir_.string()).c_str());
  }
  SmallTmpfs(const SmallTmpfs&) = delete;
  SmallTmpfs& operator=(const SmallTmpfs&) = delete;
  bool mounted() const { return mounted_; }

 private:
  fs::path dir_;
  bool mounted_ = false;
};

// On a full disk `contact_replay save` fails naming the cause and leaves
// neither the state nor its temporary (a 400-particle state is 19 kB; the
// tmpfs holds 8 kB).
TEST(ContactReplay, FullDiskNamesTheCauseAndLeavesNoTemporary) {
  const fs::path dir = TempDir() / "full";
  SmallTmpfs disk(dir, "8k");
  if (!disk.mounted()) GTEST_SKIP() << "mounting a tmpfs needs root; not checked on this machine";
  const Outcome o = testing::RunCommand(CLOTHBENCH_REPLAY_BINARY,
                                        "save --scene round_table --at 0.02 --out " + (dir / "s").string(), TempDir());
  ExpectOneLineError(o, "No space left on device", 1);
  std::vector<std::string> left;
  for (const auto& e : fs::directory_iterator(dir)) left.push_back(e.path().filename().string());
  EXPECT_TRUE(left.empty()) << left.front();
}

}  // namespace
}  // namespace clothbench

namespace clothbench {
namespace {

// On a full disk stress_stability fails naming the cause, leaves no
// temporary file, and keeps its journal (named in the line) so that the
// same command resumes once there is room: the rerun computes no cell
// again and writes the file.
TEST(StressCli, FullDiskNamesTheCauseAndLeavesNoTemporary) {
  const fs::path dir = TempDir() / "full_stress";
  const std::string args = "--integrators sbdf2 --h 0.01 --stiffness 1,10,100 --steps 5 --out ";
  {
    SmallTmpfs disk(dir, "8k");  // the journal fits, the 9 kB result file does not
    if (!disk.mounted()) GTEST_SKIP() << "mounting a tmpfs needs root; not checked on this machine";
    const Outcome o = testing::RunCommand(CLOTHBENCH_STRESS_BINARY, args + (dir / "s.h5").string(), TempDir());
    ExpectOneLineError(o, "No space left on device", 1);
    EXPECT_NE(o.err.find("s.h5.journal: the same command resumes"), std::string::npos) << o.err;
    EXPECT_FALSE(fs::exists(dir / "s.h5.tmp"));
    EXPECT_FALSE(fs::exists(dir / "s.h5"));
    EXPECT_TRUE(fs::exists(dir / "s.h5.journal"));
    fs::copy_file(dir / "s.h5.journal", TempDir() / "s.h5.journal", fs::copy_options::overwrite_existing);
  }
  // Room again (the tmpfs unmounted, the journal where the command wrote it).
  fs::copy_file(TempDir() / "s.h5.journal", dir / "s.h5.journal", fs::copy_options::overwrite_existing);
  const Outcome again = testing::RunCommand(CLOTHBENCH_STRESS_BINARY, args + (dir / "s.h5").string(), TempDir());
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_NE(again.out.find("6 of 6 cells from"), std::string::npos) << again.out;
  EXPECT_TRUE(fs::exists(dir / "s.h5"));
  EXPECT_FALSE(fs::exists(dir / "s.h5.journal"));
}

// On a disk too full for the journal's first line (a 4 kB tmpfs, whose
// first block the lock's probe takes), stress_stability names the cause and
// leaves nothing: no empty journal that a rerun would take for another
// sweep's, no lock, no temporary. Once there is room the same command runs.
TEST(StressCli, ADiskTooFullForTheJournalLeavesNothing) {
  const fs::path dir = TempDir() / "full_journal";
  const std::string args = "--integrators sbdf2 --h 0.01 --stiffness 1,10 --steps 5 --out ";
  {
    SmallTmpfs disk(dir, "4k");
    if (!disk.mounted()) GTEST_SKIP() << "mounting a tmpfs needs root; not checked on this machine";
    // Fill the disk but for a few bytes.
    {
      std::ofstream fill(dir / "fill", std::ios::binary);
      const std::string block(512, 'x');
      while (fill.write(block.data(), static_cast<std::streamsize>(block.size())) && fill.flush()) {
      }
    }
    const Outcome o = testing::RunCommand(CLOTHBENCH_STRESS_BINARY, args + (dir / "s.h5").string(), TempDir());
    EXPECT_NE(o.exit_code, 0) << o.out;
    EXPECT_EQ(std::count(o.err.begin(), o.err.end(), '\n'), 1) << o.err;
    EXPECT_NE(o.err.find("No space left on device"), std::string::npos) << o.err;
    std::vector<std::string> left;
    for (const auto& e : fs::directory_iterator(dir))
      if (e.path().filename() != "fill") left.push_back(e.path().filename().string());
    EXPECT_TRUE(left.empty()) << left.front();
  }
  const Outcome again = testing::RunCommand(CLOTHBENCH_STRESS_BINARY, args + (dir / "s.h5").string(), TempDir());
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_TRUE(fs::exists(dir / "s.h5"));
}

}  // namespace
}  // namespace clothbench
