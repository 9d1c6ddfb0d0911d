// clothbench_inspect and the results/ reader against files bench_integrators
// writes: the table is reprinted from the file alone, diff flags a changed
// e_rms, older schemas give one line naming the version, damaged and
// inconsistent files give one line naming the dataset, export writes the
// stored frame, and ResultReader reads back what the writer stored.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <sys/stat.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "results/result_reader.h"
#include "results/run_records.h"
#include "results/run_table.h"
#include "verify/cli_helpers.h"

namespace clothbench {
namespace {

namespace fs = std::filesystem;

using testing::Outcome;
using testing::Slurp;

fs::path TempDir() { return testing::TempDir("clothbench_inspect_"); }

Outcome RunCommand(const std::string& binary, const std::string& args) {
  return testing::RunCommand(binary, args, TempDir());
}

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::stringstream ss(text);
  for (std::string line; std::getline(ss, line);) lines.push_back(line);
  return lines;
}


// One bench_integrators run shared by the tests: fixed-step, Newton,
// substepped and adaptive rows (every kind of h|rtol column, footnotes,
// rejected-step lines and the equal-accuracy table).
class InspectTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    scene_ = (TempDir() / "tiny.toml").string();
    std::ofstream(scene_) << testing::kTinyScene;
    file_ = (TempDir() / "tiny.h5").string();
    printed_ = new Outcome(RunCommand(CLOTHBENCH_BENCH_BINARY, "--scene " + scene_ +
                                                            " --integrators sbdf2,bdf2/newton,xpbd,cvode --h 0.01,0.005 "
                                                            "--substeps 1,4 --rtols 1e-4,1e-6 --out " + file_));
  }
  static void TearDownTestSuite() { delete printed_; }

  static std::string scene_, file_;
  static Outcome* printed_;
};

std::string InspectTest::scene_, InspectTest::file_;
Outcome* InspectTest::printed_ = nullptr;

TEST_F(InspectTest, TableReproducesThePrintedTable) {
  ASSERT_EQ(printed_->exit_code, 0) << printed_->err;
  const Outcome o = RunCommand(CLOTHBENCH_INSPECT_BINARY, file_ + " table");
  ASSERT_EQ(o.exit_code, 0) << o.err;
  // bench_integrators ends with "results: FILE" and "ParaView: FILE.xdmf";
  // clothbench_inspect starts with one header line naming the file, its
  // creation time and commit. Everything between is the same, line for line.
  std::vector<std::string> printed = Lines(printed_->out), reprinted = Lines(o.out);
  ASSERT_GE(printed.size(), 10u);
  ASSERT_EQ(printed.back().rfind("ParaView: ", 0), 0u) << printed.back();
  printed.pop_back();
  ASSERT_EQ(printed.back(), "results: " + file_);
  printed.pop_back();
  ASSERT_FALSE(reprinted.empty());
  EXPECT_EQ(reprinted.front().rfind("# " + file_ + ": written ", 0), 0u) << reprinted.front();
  reprinted.erase(reprinted.begin());
  ASSERT_EQ(reprinted.size(), printed.size());
  for (std::size_t k = 0; k < printed.size(); ++k) EXPECT_EQ(reprinted[k], printed[k]) << "line " << k + 1;
}

TEST_F(InspectTest, ReaderReadsWhatTheWriterStored) {
  ASSERT_EQ(printed_->exit_code, 0) << printed_->err;
  const ResultReader f(file_);
  const RunTable t = ReadRunTable(f);
  EXPECT_EQ(t.schema, kResultSchema);
  EXPECT_EQ(t.scene_name, "tiny");
  EXPECT_EQ(t.n_particles, 12);
  // 2 sbdf2 + 2 bdf2/newton + 2 h × 2 substeps xpbd + 2 cvode rows, in run order.
  ASSERT_EQ(t.runs.size(), 10u);
  EXPECT_EQ(t.runs.front().id, "sbdf2_h0.01");
  EXPECT_EQ(t.runs.back().id, "cvode_rtol1e-06");
  EXPECT_EQ(t.runs.back().step_kind, StepKind::kAdaptive);
  EXPECT_EQ(t.runs[2].nonlinear_solver, "newton");
  ASSERT_TRUE(t.runs[1].error_final_m.has_value());
  ASSERT_TRUE(t.runs[1].observed_order.has_value());
  ASSERT_TRUE(t.work_precision.has_value());
  EXPECT_EQ(t.work_precision->labels.size(), 4u);
  // Frames: the first row of a label keeps every frame (F = 5), the others
  // t = 0 and t_end; Frame() refuses an index past the end.
  EXPECT_EQ(f.Shape("/runs/sbdf2_h0.01/positions"), (std::vector<std::size_t>{5, 12, 3}));
  EXPECT_EQ(f.Shape("/runs/sbdf2_h0.005/positions_ends"), (std::vector<std::size_t>{2, 12, 3}));
  EXPECT_THROW(f.Frame("/runs/sbdf2_h0.005/positions_ends", 2), ResultError);
  const std::vector<StepRecord> steps = f.StepStats("/runs/sbdf2_h0.01/step_stats");
  ASSERT_EQ(steps.size(), 4u);  // 0.04 s / 0.01 s
  EXPECT_NEAR(steps.back().t, 0.04, 1e-15);
}

// Copies `from` to `to` and overwrites the double attribute `name` of
// `object` (or the string attribute when `text` is given).
void CopyWithAttribute(const std::string& from, const std::string& to, const std::string& object,
                       const std::string& name, double value, const char* text = nullptr) {
  fs::copy_file(from, to, fs::copy_options::overwrite_existing);
  const hid_t f = H5Fopen(to.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  const hid_t a = H5Aopen_by_name(f, object.c_str(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(a, 0) << object << "@" << name;
  if (text) {
    const hid_t type = H5Aget_type(a);
    std::string buf(H5Tget_size(type), '\0');
    std::copy(text, text + std::min(std::strlen(text), buf.size()), buf.begin());
    EXPECT_GE(H5Awrite(a, type, buf.data()), 0);
    H5Tclose(type);
    H5Aclose(a);
  } else {
    // Deleted and created again: HDF5 1.10 cannot rewrite an attribute of
    // an object with dense attribute storage (> 8 attributes) in place.
    H5Aclose(a);
    ASSERT_GE(H5Adelete_by_name(f, object.c_str(), name.c_str(), H5P_DEFAULT), 0);
    const hid_t space = H5Screate(H5S_SCALAR);
    const hid_t b = H5Acreate_by_name(f, object.c_str(), name.c_str(), H5T_IEEE_F64LE, space, H5P_DEFAULT,
                                      H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(b, 0);
    EXPECT_GE(H5Awrite(b, H5T_NATIVE_DOUBLE, &value), 0);
    H5Aclose(b);
    H5Sclose(space);
  }
  H5Fclose(f);
  // Signed again, as the writer of such a file would have: the edit stands
  // for a file of another build, not for damage (that is refused:
  // EditedOrDamagedFilesAreRefusedBeforeHdf5ReadsThem).
  SignResultFile(to);
}

TEST_F(InspectTest, DiffFlagsAChangedErms) {
  ASSERT_EQ(printed_->exit_code, 0) << printed_->err;
  // A file against itself: nothing flagged, exit 0.
  const Outcome same = RunCommand(CLOTHBENCH_INSPECT_BINARY, file_ + " diff " + file_);
  EXPECT_EQ(same.exit_code, 0) << same.out << same.err;
  EXPECT_NE(same.out.find("0 of 10 runs flagged"), std::string::npos) << same.out;
  // One run's e_rms 1e-3 larger (relative; far above the default --rtol
  // 1e-6): that run is flagged, the others are not, exit 1.
  const double e = *ResultReader(file_).Double("/runs/bdf2_newton_h0.005", "error_final_m");
  const std::string changed = (TempDir() / "changed.h5").string();
  CopyWithAttribute(file_, changed, "/runs/bdf2_newton_h0.005", "error_final_m", e * 1.001);
  const Outcome d = RunCommand(CLOTHBENCH_INSPECT_BINARY, file_ + " diff " + changed);
  EXPECT_EQ(d.exit_code, 1) << d.out << d.err;
  EXPECT_NE(d.out.find("1 of 10 runs flagged"), std::string::npos) << d.out;
  bool flagged_line = false;
  for (const std::string& line : Lines(d.out))
    flagged_line |= line.rfind("bdf2_newton_h0.005 ", 0) == 0 && line.ends_with("e_rms");
  EXPECT_TRUE(flagged_line) << d.out;
  // The same change within a looser --rtol 1e-2 is not flagged.
  EXPECT_EQ(RunCommand(CLOTHBENCH_INSPECT_BINARY, file_ + " diff " + changed + " --rtol 1e-2").exit_code, 0);
}

TEST_F(InspectTest, OlderSchemaGivesOneLineNamingTheVersion) {
  ASSERT_EQ(printed_->exit_code, 0) << printed_->err;
  const std::string old = (TempDir() / "old.h5").string();
  CopyWithAttribute(file_, old, "/", "schema", 0.0, "clothbench/1");
  for (const char* command : {" summary", " table", " runs --json"}) {
    const Outcome o = RunCommand(CLOTHBENCH_INSPECT_BINARY, old + command);
    EXPECT_EQ(o.exit_code, 2) << command;
    EXPECT_EQ(std::count(o.err.begin(), o.err.end(), '\n'), 1) << o.err;
    EXPECT_NE(o.err.find("schema clothbench/1"), std::string::npos) << o.err;
    EXPECT_TRUE(o.out.empty()) << o.out;
  }
  const Outcome none = RunCommand(CLOTHBENCH_INSPECT_BINARY, (TempDir() / "missing.h5").string() + " summary");
  EXPECT_EQ(none.exit_code, 2);
  EXPECT_EQ(std::count(none.err.begin(), none.err.end(), '\n'), 1) << none.err;
}

TEST_F(InspectTest, ExportWritesTheStoredFrame) {
  ASSERT_EQ(printed_->exit_code, 0) << printed_->err;
  const std::string obj = (TempDir() / "frame.obj").string();
  const Outcome o = RunCommand(CLOTHBENCH_INSPECT_BINARY, file_ + " export sbdf2_h0.01 --frame 4 --obj " + obj);
  ASSERT_EQ(o.exit_code, 0) << o.err;
  const ResultReader f(file_);
  const MatrixN3 x = f.Frame("/runs/sbdf2_h0.01/positions", 4);
  std::vector<std::string> v, quads;
  for (const std::string& line : Lines(Slurp(obj))) {
    if (line.rfind("v ", 0) == 0) v.push_back(line);
    if (line.rfind("f ", 0) == 0) quads.push_back(line);
  }
  ASSERT_EQ(v.size(), 12u);
  ASSERT_EQ(quads.size(), 6u);
  // Positions are printed with 17 significant digits: they read back exactly.
  std::stringstream last(v.back().substr(2));
  double px = 0, py = 0, pz = 0;
  last >> px >> py >> pz;
  EXPECT_EQ(px, x(11, 0));
  EXPECT_EQ(py, x(11, 1));
  EXPECT_EQ(pz, x(11, 2));
  EXPECT_EQ(quads.front(), "f 1 2 6 5");  // the first quad, 1-based
  // A frame that is not stored, an unknown run: one line, exit 2, no file.
  const std::string ply = (TempDir() / "frame.ply").string();
  for (const char* bad : {" export sbdf2_h0.005 --frame 3 --ply ", " export rk4_h0.01 --ply "}) {
    const Outcome b = RunCommand(CLOTHBENCH_INSPECT_BINARY, file_ + bad + ply);
    EXPECT_EQ(b.exit_code, 2) << bad;
    EXPECT_EQ(std::count(b.err.begin(), b.err.end(), '\n'), 1) << b.err;
    EXPECT_FALSE(fs::exists(ply));
  }
}

// The end state and counts of one stored run: positions and velocities at
// t_end (every frame or only the ends, whichever the file kept).
struct EndState {
  MatrixN3 x, v;
  long steps, updates, cg_iterations;
};

EndState ReadEndState(const std::string& file, const std::string& id) {
  const ResultReader f(file);
  const std::string g = "/runs/" + id;
  const auto last = [&](const std::string& name) {
    const std::string d = f.Exists(g + "/" + name) ? g + "/" + name : g + "/" + name + "_ends";
    return f.Frame(d, f.Shape(d)[0] - 1);
  };
  const RunRecord r = ReadRunRecord(f, g, id);
  return {last("positions"), last("velocities"), r.steps, r.updates, r.cg_iterations};
}

// `clothbench_inspect FILE command RUN` prints a script that recomputes the
// run from the file alone. Runs are deterministic on one build and thread
// count, so the recomputed end state must equal the stored one bit for bit
// (no tolerance). The scene makes Newton its default nonlinear solver, so
// the fixed-point row must name its solver; --t-end shortens the scene's
// run, so the script must pass it; the mesh obstacle is named relative to the
// scene file, so the script must link it next to the scene file it writes.
// Copies `from` to `to`, lets `edit` change it through the HDF5 API and
// signs it again: a file that is a sound HDF5 file with a valid integrity
// block, but breaks a rule of the schema.
void CopyAndEdit(const std::string& from, const std::string& to, const std::function<void(hid_t)>& edit) {
  fs::copy_file(from, to, fs::copy_options::overwrite_existing);
  const hid_t f = H5Fopen(to.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  edit(f);
  H5Fclose(f);
  SignResultFile(to);
}

// Replaces dataset `path` by a float64 dataset of shape `dims` filled with `value`.
void ReplaceDataset(hid_t f, const std::string& path, std::vector<hsize_t> dims, double value) {
  ASSERT_GE(H5Ldelete(f, path.c_str(), H5P_DEFAULT), 0) << path;
  const hid_t space = H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr);
  const hid_t ds = H5Dcreate2(f, path.c_str(), H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(ds, 0) << path;
  std::size_t n = 1;
  for (hsize_t d : dims) n *= d;
  const std::vector<double> values(n, value);
  if (n > 0) {
    EXPECT_GE(H5Dwrite(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), 0);
  }
  H5Dclose(ds);
  H5Sclose(space);
}

// Every subcommand that reads a file refuses a damaged or inconsistent one
// before reading it: exit 2, one line naming the file and the dataset or
// attribute, nothing on stdout. Before the integrity block and
// ValidateResultFile, the empty-times file crashed `export` (SIGSEGV) and a
// few flipped bits crashed HDF5 itself.
void CopyWithString(const std::string& from, const std::string& to, const std::string& object,
                    const std::string& name, const std::string& text);  // below

// `self-intersections`: one line per stored frame of the run (the tiny
// sheet hangs without folding: no crossing pair, exit 0); an unknown run is
// one line and exit 2. The counting itself: SelfIntersection.* tests.
TEST_F(InspectTest, SelfIntersectionsCountsEveryStoredFrame) {
  ASSERT_EQ(printed_->exit_code, 0) << printed_->err;
  const Outcome o = RunCommand(CLOTHBENCH_INSPECT_BINARY, file_ + " self-intersections sbdf2_h0.01");
  ASSERT_EQ(o.exit_code, 0) << o.err;
  const ResultReader f(file_);
  const std::vector<std::string> lines = Lines(o.out);
  ASSERT_EQ(lines.size(), f.Shape("/runs/sbdf2_h0.01/positions")[0]);
  EXPECT_EQ(lines.front(), "frame 0 t = 0 s: 0 crossing triangle pairs");
  const Outcome bad = RunCommand(CLOTHBENCH_INSPECT_BINARY, file_ + " self-intersections no_such_run");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("no run \"no_such_run\""), std::string::npos) << bad.err;
}

TEST_F(InspectTest, BrokenFilesGiveExit2NamingTheDataset) {
  ASSERT_EQ(printed_->exit_code, 0) << printed_->err;
  const auto refused = [&](const std::string& file, const std::string& args, const std::string& named) {
    const Outcome o = RunCommand(CLOTHBENCH_INSPECT_BINARY, file + " " + args);
    EXPECT_EQ(o.exit_code, 2) << args << ": " << o.err;
    EXPECT_EQ(std::count(o.err.begin(), o.err.end(), '\n'), 1) << o.err;
    EXPECT_NE(o.err.find(named), std::string::npos) << "expected \"" << named << "\" in: " << o.err;
    EXPECT_TRUE(o.out.empty()) << o.out;
  };
  const std::string bytes = Slurp(file_);
  // One flipped bit anywhere past the integrity block, and a truncation.
  const std::string flipped = (TempDir() / "flipped.h5").string(), cut = (TempDir() / "cut.h5").string();
  for (std::size_t at : {std::size_t{600}, bytes.size() / 2, bytes.size() - 1}) {
    std::string b = bytes;
    b[at] = static_cast<char>(b[at] ^ 0x04);
    std::ofstream(flipped, std::ios::binary) << b;
    refused(flipped, "summary", "CRC-32");
  }
  std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() - 100);
  refused(cut, "table", "truncated");
  // A FIFO is refused, not waited on (RunCommand would hang).
  const std::string fifo = (TempDir() / "fifo.h5").string();
  fs::remove(fifo);
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  refused(fifo, "summary", "not a regular file");
  // Sound HDF5, signed, but inconsistent with the schema.
  const std::string bad = (TempDir() / "bad.h5").string();
  CopyAndEdit(file_, bad, [](hid_t f) { ReplaceDataset(f, "/runs/sbdf2_h0.005/times", {0}, 0.0); });
  for (const char* args : {"summary", "export sbdf2_h0.005 --obj x.obj", "table"})
    refused(bad, args, "/runs/sbdf2_h0.005/");
  CopyAndEdit(file_, bad, [](hid_t f) { ReplaceDataset(f, "/runs/sbdf2_h0.01/times", {5}, 1e300 * 1e10); });
  refused(bad, "runs", "/runs/sbdf2_h0.01/times: [0] = inf is not finite");
  CopyAndEdit(file_, bad, [](hid_t f) {
    ASSERT_GE(H5Ldelete(f, "/scene/faces", H5P_DEFAULT), 0);
    const hsize_t dims[2] = {1, 4};
    const int32_t q[4] = {0, 1, 12, 2};  // 12: one past the last of the 12 particles
    const hid_t space = H5Screate_simple(2, dims, nullptr);
    const hid_t ds = H5Dcreate2(f, "/scene/faces", H5T_STD_I32LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    EXPECT_GE(H5Dwrite(ds, H5T_NATIVE_INT32, H5S_ALL, H5S_ALL, H5P_DEFAULT, q), 0);
    H5Dclose(ds);
    H5Sclose(space);
  });
  refused(bad, "export sbdf2_h0.01 --frame 1 --ply x.ply", "/scene/faces: [0, 2] = 12 is not a particle index");
  CopyAndEdit(file_, bad, [](hid_t f) { ReplaceDataset(f, "/runs/cvode_rtol0.0001/positions", {5, 11, 3}, 0.5); });
  refused(bad, "summary", "/runs/cvode_rtol0.0001/positions: shape [5, 11, 3], [5, 12, 3] expected");
  const std::string nan_attr = (TempDir() / "nan_attr.h5").string();
  CopyWithAttribute(file_, nan_attr, "/runs/sbdf2_h0.01", "solver_time_s", std::nan(""));
  refused(nan_attr, "runs --json", "/runs/sbdf2_h0.01@solver_time_s: nan is not finite");
  // Status and step kind are enumerations: any other text is refused; a
  // SUNDIALS flag name (what files stored before) reads as its status.
  CopyWithString(file_, bad, "/runs/sbdf2_h0.01", "status", "exploded");
  refused(bad, "summary", "/runs/sbdf2_h0.01 attribute status = \"exploded\"");
  CopyWithString(file_, bad, "/runs/sbdf2_h0.01", "step_kind", "sometimes");
  refused(bad, "runs", "attribute step_kind = \"sometimes\"");
  CopyWithString(file_, bad, "/runs/sbdf2_h0.01", "status", "CV_CONV_FAILURE");
  const Outcome o = RunCommand(CLOTHBENCH_INSPECT_BINARY, bad + " runs");
  EXPECT_NE(o.out.find("sbdf2_h0.01 label=sbdf2 status=no_newton_convergence"), std::string::npos) << o.out << o.err;
}

TEST(InspectCommand, RecomputesARunBitForBit) {
  const fs::path dir = TempDir() / "command";
  fs::create_directories(dir / "meshes");
  fs::copy_file(fs::path(CLOTHBENCH_DATA_DIR) / "meshes" / "cube.off", dir / "meshes" / "cube.off",
                fs::copy_options::overwrite_existing);
  std::string scene = testing::kTinyScene;
  scene += "nonlinear_solver = \"newton\"\n\n[[obstacle]]\ntype = \"mesh\"\npath = \"meshes/cube.off\"\n"
           "scale = 0.05\ntranslate = [0.15, 0.1, -0.5]\n";
  std::ofstream(dir / "scene.toml") << scene;
  const std::string file = (dir / "original.h5").string();
  const Outcome o = RunCommand(CLOTHBENCH_BENCH_BINARY,
                               "--scene " + (dir / "scene.toml").string() +
                                   " --integrators sbdf2,sbdf2/error,cvode,xpbd,bdf2/fixed_point,baraff_witkin "
                                   "--h 0.005 --rtols 1e-4 --substeps 4 --t-end 0.03 --frames ends --reference none "
                                   "--quiet --out " + file);
  ASSERT_EQ(o.exit_code, 0) << o.err;
  for (const char* id : {"sbdf2_h0.005", "sbdf2_error_rtol0.0001", "cvode_rtol0.0001", "xpbd_h0.005_n4",
                         "bdf2_h0.005", "baraff_witkin_h0.005"}) {
    const fs::path rerun = dir / (std::string("rerun_") + id);
    fs::remove_all(rerun);
    const Outcome c = RunCommand(CLOTHBENCH_INSPECT_BINARY, file + " command " + id + " --dir " + rerun.string());
    ASSERT_EQ(c.exit_code, 0) << c.err;
    const fs::path script = dir / (std::string(id) + ".sh");
    std::ofstream(script) << c.out;
    const Outcome s = RunCommand("sh", script.string());
    ASSERT_EQ(s.exit_code, 0) << id << ": " << s.err << "\n" << c.out;
    const RunTable t = ReadRunTable(ResultReader((rerun / "run.h5").string()));
    ASSERT_EQ(t.runs.size(), 1u) << id;
    EXPECT_EQ(t.runs[0].id, id);
    const EndState a = ReadEndState(file, id), b = ReadEndState((rerun / "run.h5").string(), id);
    EXPECT_EQ(a.steps, b.steps) << id;
    EXPECT_EQ(a.updates, b.updates) << id;
    EXPECT_EQ(a.cg_iterations, b.cg_iterations) << id;
    EXPECT_TRUE(a.x == b.x) << id << ": positions at t_end differ by " << (a.x - b.x).cwiseAbs().maxCoeff() << " m";
    EXPECT_TRUE(a.v == b.v) << id << ": velocities at t_end differ by " << (a.v - b.v).cwiseAbs().maxCoeff();
    // `rerun` computes the same run in-process, without a shell, and says
    // whether the end state equals the stored one bit for bit.
    const std::string in_process = (dir / (std::string("inproc_") + id + ".h5")).string();
    fs::remove(in_process);
    const Outcome p = RunCommand(CLOTHBENCH_INSPECT_BINARY, file + " rerun " + id + " --out " + in_process);
    EXPECT_EQ(p.exit_code, 0) << id << ": " << p.err << p.out;
    EXPECT_NE(p.out.find("equals the stored one bit for bit"), std::string::npos) << p.out;
    const EndState e = ReadEndState(in_process, id);
    EXPECT_TRUE(a.x == e.x && a.v == e.v) << id;
    EXPECT_EQ(a.cg_iterations, e.cg_iterations) << id;
  }
  // A rerun whose end state differs says so with exit 1: the stored
  // positions moved by 1e-9 m (far above round-off's 0, the same build
  // reproduces a run exactly).
  const std::string moved = (dir / "moved.h5").string();
  CopyAndEdit(file, moved, [&](hid_t f) {
    const std::string d = H5Lexists(f, "/runs/sbdf2_h0.005/positions", H5P_DEFAULT) > 0
                              ? "/runs/sbdf2_h0.005/positions"
                              : "/runs/sbdf2_h0.005/positions_ends";
    const hid_t ds = H5Dopen2(f, d.c_str(), H5P_DEFAULT);
    ASSERT_GE(ds, 0);
    const hid_t space = H5Dget_space(ds);
    std::vector<double> x(static_cast<std::size_t>(H5Sget_simple_extent_npoints(space)));
    H5Sclose(space);
    ASSERT_GE(H5Dread(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, x.data()), 0);
    x.back() += 1e-9;
    ASSERT_GE(H5Dwrite(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, x.data()), 0);
    H5Dclose(ds);
  });
  const Outcome differs = RunCommand(CLOTHBENCH_INSPECT_BINARY, moved + " rerun sbdf2_h0.005");
  EXPECT_EQ(differs.exit_code, 1) << differs.out << differs.err;
  EXPECT_NE(differs.out.find("differs"), std::string::npos) << differs.out;
  // The reference and an unknown run: one line, exit 2.
  for (const char* bad : {" command reference", " command rk4_h0.01", " rerun reference", " rerun rk4_h0.01"}) {
    const Outcome b = RunCommand(CLOTHBENCH_INSPECT_BINARY, file + bad);
    EXPECT_EQ(b.exit_code, 2) << bad;
    EXPECT_EQ(std::count(b.err.begin(), b.err.end(), '\n'), 1) << b.err;
  }
}

}  // namespace
}  // namespace clothbench

namespace clothbench {
namespace {

// Copies `from` to `to` with the string attribute `name` of `object` set to
// `text` (deleted and created again at the text's size), signed again.
void CopyWithString(const std::string& from, const std::string& to, const std::string& object,
                    const std::string& name, const std::string& text) {
  CopyAndEdit(from, to, [&](hid_t f) {
    ASSERT_GE(H5Adelete_by_name(f, object.c_str(), name.c_str(), H5P_DEFAULT), 0) << object << "@" << name;
    const hid_t type = H5Tcopy(H5T_C_S1);
    H5Tset_size(type, text.empty() ? 1 : text.size());
    const hid_t space = H5Screate(H5S_SCALAR);
    const hid_t a =
        H5Acreate_by_name(f, object.c_str(), name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(a, 0);
    std::string buf = text.empty() ? std::string(1, '\0') : text;
    EXPECT_GE(H5Awrite(a, type, buf.data()), 0);
    H5Aclose(a);
    H5Sclose(space);
    H5Tclose(type);
  });
}

// A result file is data from anyone: edited and signed again, its stored
// strings must never run as shell code through `command … | sh`. Values the
// request validates (preconditioner, J_α terms, ARKODE table, frames, label,
// threads, h) are refused with exit 2 and one line naming the attribute's
// field; provenance strings that only appear in the script's comment
// (host, created, git_commit, build_type) are printed quoted with their
// newlines escaped, and the script, run by sh in a scratch folder, creates
// no marker file.
TEST(InspectCommand, StoredStringsNeverRunAsShellCode) {
  const fs::path dir = TempDir() / "shell";
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir / "scene.toml") << testing::kTinyScene;
  const std::string file = (dir / "original.h5").string();
  const Outcome o = RunCommand(CLOTHBENCH_BENCH_BINARY,
                               "--scene " + (dir / "scene.toml").string() +
                                   " --integrators sbdf2,bdf2/newton,arkode --h 0.01 --rtols 1e-4 --t-end 0.02 "
                                   "--reference none --quiet --out " + file);
  ASSERT_EQ(o.exit_code, 0) << o.err;
  const fs::path marker = dir / "MARKER";
  const std::string m = marker.string();
  const std::vector<std::string> payloads = {"x; touch " + m, "$(touch " + m + ")", "`touch " + m + "`",
                                             "x'\ntouch " + m + "\n'", "x\ntouch " + m + "\n#",
                                             "' ; touch " + m + " ; '"};
  const struct {
    const char *object, *name, *run, *field;
  } refused[] = {
      {"/runs/sbdf2_h0.01", "preconditioner", "sbdf2_h0.01", "preconditioner"},
      {"/runs/bdf2_newton_h0.01", "tangent_terms", "bdf2_newton_h0.01", "tangent_terms"},
      {"/runs/arkode_rtol0.0001", "butcher_table", "arkode_rtol0.0001", "arkode_table"},
      {"/scene", "frames", "sbdf2_h0.01", "frames"},
      {"/runs/sbdf2_h0.01", "label", "sbdf2_h0.01", "label"},
  };
  const std::string edited = (dir / "edited.h5").string();
  for (const auto& r : refused)
    for (const std::string& p : payloads) {
      CopyWithString(file, edited, r.object, r.name, p);
      const Outcome c = RunCommand(CLOTHBENCH_INSPECT_BINARY, edited + " command " + r.run + " --dir " +
                                                                  (dir / "rerun").string());
      EXPECT_EQ(c.exit_code, 2) << r.name << " = " << p << "\n" << c.out;
      EXPECT_EQ(std::count(c.err.begin(), c.err.end(), '\n'), 1) << c.err;
      EXPECT_NE(c.err.find(r.field), std::string::npos) << c.err;
      EXPECT_TRUE(c.out.empty()) << c.out;
    }
  // Numbers the request validates: a thread count of 2^31, a negative h.
  const std::string bad = (dir / "bad.h5").string();
  CopyAndEdit(file, bad, [](hid_t f) {
    const long threads = 1L << 31;
    ASSERT_GE(H5Adelete_by_name(f, "/runs/sbdf2_h0.01", "threads", H5P_DEFAULT), 0);
    const hid_t space = H5Screate(H5S_SCALAR);
    const hid_t a = H5Acreate_by_name(f, "/runs/sbdf2_h0.01", "threads", H5T_STD_I64LE, space, H5P_DEFAULT,
                                      H5P_DEFAULT, H5P_DEFAULT);
    EXPECT_GE(H5Awrite(a, H5T_NATIVE_LONG, &threads), 0);
    H5Aclose(a);
    H5Sclose(space);
  });
  Outcome c = RunCommand(CLOTHBENCH_INSPECT_BINARY, bad + " command sbdf2_h0.01");
  EXPECT_EQ(c.exit_code, 2) << c.out;
  EXPECT_NE(c.err.find("threads"), std::string::npos) << c.err;
  CopyWithAttribute(file, bad, "/runs/sbdf2_h0.01", "h", -0.01);
  c = RunCommand(CLOTHBENCH_INSPECT_BINARY, bad + " command sbdf2_h0.01");
  EXPECT_EQ(c.exit_code, 2) << c.out;
  EXPECT_NE(c.err.find("h: "), std::string::npos) << c.err;
  // A scene text whose particle count disagrees with /scene@n_particles.
  CopyAndEdit(file, bad, [](hid_t f) {
    const long n = 13;
    EXPECT_GE(H5Adelete_by_name(f, "/scene", "n_particles", H5P_DEFAULT), 0);
    const hid_t space = H5Screate(H5S_SCALAR);
    const hid_t a =
        H5Acreate_by_name(f, "/scene", "n_particles", H5T_STD_I64LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    EXPECT_GE(H5Awrite(a, H5T_NATIVE_LONG, &n), 0);
    H5Aclose(a);
    H5Sclose(space);
  });
  c = RunCommand(CLOTHBENCH_INSPECT_BINARY, bad + " command sbdf2_h0.01");
  EXPECT_EQ(c.exit_code, 2) << c.out;
  EXPECT_NE(c.err.find("particles"), std::string::npos) << c.err;

  // Provenance strings are comment words only: the script runs, no marker.
  for (const char* name : {"host", "created", "git_commit", "build_type"})
    for (const std::string& p : payloads) {
      CopyWithString(file, edited, "/", name, p);
      const fs::path rerun = dir / "rerun";
      fs::remove_all(rerun);
      const Outcome s = RunCommand(CLOTHBENCH_INSPECT_BINARY, edited + " command sbdf2_h0.01 --dir " + rerun.string());
      ASSERT_EQ(s.exit_code, 0) << name << ": " << s.err;
      const fs::path script = dir / "script.sh";
      std::ofstream(script) << s.out;
      const Outcome run = RunCommand("sh", script.string());
      EXPECT_EQ(run.exit_code, 0) << run.err << "\n" << s.out;
      EXPECT_FALSE(fs::exists(marker)) << name << " = " << p << " ran as code:\n" << s.out;
      fs::remove(marker);
    }
}

}  // namespace
}  // namespace clothbench

namespace clothbench {
namespace {

// A result file whose integrity block matches but whose attribute headers
// were damaged (found by verify/fuzz/fuzz_result.cc): HDF5 1.10 itself
// crashes (SIGSEGV) reading it. Every subcommand reads untrusted files
// whole in a child process first, so the file is refused with exit 2 and
// one line naming the file and saying it is damaged (the child's listing
// of the file's links fails before any read that would crash), and
// nothing is printed on stdout.
TEST(InspectCommand, AFileThatCrashesHdf5IsRefusedWithExit2) {
  const std::string file = std::string(CLOTHBENCH_FUZZ_REGRESSIONS) + "/hdf5_crash_signed.bin";
  for (const char* args : {" summary", " table", " runs --json", " rerun x", " command x"}) {
    const Outcome o = RunCommand(CLOTHBENCH_INSPECT_BINARY, file + args);
    EXPECT_EQ(o.exit_code, 2) << args << ": " << o.err;
    EXPECT_EQ(std::count(o.err.begin(), o.err.end(), '\n'), 1) << o.err;
    EXPECT_NE(o.err.find("damaged"), std::string::npos) << o.err;
    EXPECT_TRUE(o.out.empty()) << o.out;
  }
}

}  // namespace
}  // namespace clothbench

namespace clothbench {
namespace {

// A row that blows up (symplectic Euler at h = 0.01 s on the swinging
// sheet: energy_growth after 4 steps) is stored with the frames it kept
// and their energies, a series as long as its times: the file reads back
// whole (a failed run used to leave its energy series empty, and the
// reader refused the file the writer had just written).
TEST(InspectCommand, AFileWithABlownUpRowReadsBack) {
  const fs::path dir = TempDir() / "blown_up";
  fs::create_directories(dir);
  const std::string file = (dir / "se.h5").string();
  const Outcome o = RunCommand(CLOTHBENCH_BENCH_BINARY, "--integrators symplectic_euler --h 0.01 --reference none "
                                                        "--quiet --out " + file);
  ASSERT_EQ(o.exit_code, 0) << o.err;
  for (const char* args : {" summary", " table", " runs --json"}) {
    const Outcome r = RunCommand(CLOTHBENCH_INSPECT_BINARY, file + args);
    EXPECT_EQ(r.exit_code, 0) << args << ": " << r.err;
  }
  const ResultReader f(file);
  const RunTable t = ReadRunTable(f);
  ASSERT_EQ(t.runs.size(), 1u);
  EXPECT_NE(t.runs[0].status, RunStatus::kOk);
  const std::size_t frames = f.Shape("/runs/symplectic_euler_h0.01/times")[0];
  EXPECT_GT(frames, 1u);
  EXPECT_EQ(f.Shape("/runs/symplectic_euler_h0.01/energy/kinetic")[0], frames);
  EXPECT_FALSE(t.runs[0].energy_rate_W.has_value());  // dE/dt is an ok run's only
}

}  // namespace
}  // namespace clothbench
