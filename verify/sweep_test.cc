// stress_stability and bench_integrators as sweeps (harness/sweep.h): under
// `mpirun -n 2` they write the serial run's file (bit for bit; for
// bench_integrators all but timings and the machine); a sweep stopped
// part-way (--max-cells, --max-runs, SIGINT) keeps <out>.journal and no
// result file, and the rerun computes only the missing cells and writes the
// same file; a journal of other arguments is refused.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <stdexcept>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <sys/stat.h>

#include <fmt/format.h>

#include "harness/bench_sweep.h"
#include "harness/methods.h"
#include "harness/overrun.h"
#include "harness/run_codec.h"
#include "harness/side_by_side.h"
#include "harness/sweep.h"
#include "model/particle_system.h"
#include "results/result_reader.h"
#include "results/run_records.h"
#include "verify/cli_helpers.h"
#include "verify/hdf5_scan.h"

namespace clothbench {
namespace {

namespace fs = std::filesystem;
using testing::Outcome;

fs::path Dir() { return testing::TempDir("clothbench_sweep_"); }

// Two scenes × two methods × 4 h × 6 stiffness = 96 cells of 40 steps on
// 10×10 particles: well under a second.
const std::string kSweep = " --scenes hanging_sheet,swinging_sheet --integrators sbdf2,bdf2 --steps 40";
constexpr long kCells = 96;

Outcome Sweep(const std::string& args, const std::string& launcher = "") {
  return testing::RunCommand(launcher + CLOTHBENCH_STRESS_BINARY, args, Dir());
}

// `mpirun -n <ranks>` with Open MPI's consent to run as root (CI runs as
// root) and to place 2 ranks on fewer cores.
std::string MpiRun(int ranks) {
  return "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 " + std::string(CLOTHBENCH_MPIEXEC) + " -n " +
         std::to_string(ranks) + " --oversubscribe ";
}

long JournalCells(const fs::path& journal) {
  std::ifstream in(journal);
  std::string line;
  long n = 0;
  while (std::getline(in, line)) n += line.rfind("cell ", 0) == 0;
  return n;
}

// Every dataset under /stress, bit for bit, and the same list of groups.
void ExpectSameMaps(const fs::path& a, const fs::path& b) {
  const ResultReader ra(a.string()), rb(b.string());
  ASSERT_EQ(ra.Children("/stress"), rb.Children("/stress"));
  EXPECT_EQ(ra.Doubles("/stress/stiffness"), rb.Doubles("/stress/stiffness"));
  EXPECT_EQ(ra.Doubles("/stress/h"), rb.Doubles("/stress/h"));
  int maps = 0;
  for (const std::string& scene : ra.Children("/stress")) {
    if (scene == "stiffness" || scene == "h") continue;
    ASSERT_EQ(ra.Children("/stress/" + scene), rb.Children("/stress/" + scene));
    for (const std::string& method : ra.Children("/stress/" + scene)) {
      const std::string g = "/stress/" + scene + "/" + method;
      EXPECT_EQ(ra.Ints(g + "/outcome"), rb.Ints(g + "/outcome")) << g;
      EXPECT_EQ(ra.Ints(g + "/steps_completed"), rb.Ints(g + "/steps_completed")) << g;
      for (const char* d : {"/updates_per_step", "/cg_per_step", "/energy_excess"})
        EXPECT_EQ(ra.Doubles(g + d), rb.Doubles(g + d)) << g << d;
      ++maps;
    }
  }
  EXPECT_EQ(maps, 4);
}

// The printed maps without the lines that name the file, the machine or
// the journal.
std::string Maps(const std::string& out) {
  std::stringstream in(out), kept;
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("machine:", 0) != 0 && line.rfind("results:", 0) != 0 && line.find("cells from") == std::string::npos)
      kept << line << "\n";
  return kept.str();
}

// bench_integrators: 13 runs (the CVODE reference, 2 × sbdf2, 2 ×
// bdf2/newton, 4 × xpbd, 2 × cvode, 2 × arkode) of the tiny scene.
const std::string kRows = " --integrators sbdf2,bdf2/newton,xpbd,cvode,arkode --h 0.01,0.005 --substeps 1,4 "
                          "--rtols 1e-3,1e-4";
constexpr long kRuns = 13;

Outcome Bench(const std::string& args, const std::string& launcher = "") {
  static const std::string scene = [] {
    const fs::path p = Dir() / "tiny.toml";
    std::ofstream(p) << testing::kTinyScene;
    return p.string();
  }();
  return testing::RunCommand(launcher + CLOTHBENCH_BENCH_BINARY, " --scene " + scene + args, Dir());
}

// What may differ between two runs of the same rows: timings, what is
// derived from them (the equal-accuracy table) and the machine (host, MPI
// ranks, OpenMP threads per rank; the repetitions within --time-budget).
bool TimingOrMachine(const std::string& key) {
  for (const char* s : {"_time_s", "solve_time_s", "work_precision", "@created", "@host", "@mpi_ranks", "@threads",
                        "@repeats"})
    if (key.find(s) != std::string::npos) return true;
  return false;
}

void ExpectSameRuns(const fs::path& a, const fs::path& b, std::size_t min_values = 500) {
  std::map<std::string, std::string> ca = testing::ReadContents(a.string()).values,
                                     cb = testing::ReadContents(b.string()).values;
  std::erase_if(ca, [](const auto& kv) { return TimingOrMachine(kv.first); });
  std::erase_if(cb, [](const auto& kv) { return TimingOrMachine(kv.first); });
  EXPECT_GT(ca.size(), min_values);  // every run's frames, energies, step statistics and attributes
  ASSERT_EQ(ca.size(), cb.size());
  for (const auto& [key, bytes] : ca) {
    const auto it = cb.find(key);
    ASSERT_NE(it, cb.end()) << key;
    EXPECT_EQ(bytes, it->second) << key;
  }
}

std::size_t RunFiles(const fs::path& journal) {
  std::size_t n = 0;
  if (fs::is_directory(journal))
    for (const auto& e : fs::directory_iterator(journal)) n += e.path().extension() == ".run";
  return n;
}

// --sweep-to-targets does not start a refinement predicted past
// --time-limit: h / 2 (and twice the substeps or iterations) costs twice
// the last run; rtol / 10 the last refinement's growth, never less than the
// last run; no prediction without the runs it needs. Exact arithmetic.
TEST(Sweep, ARefinementsWallTimeIsPredictedFromTheLastRuns) {
  EXPECT_EQ(PredictedWallTime(StepKind::kFixedStep, 12.0, 0.0), 24.0);
  EXPECT_EQ(PredictedWallTime(StepKind::kIterated, 3.0, 1.0), 6.0);
  EXPECT_EQ(PredictedWallTime(StepKind::kAdaptive, 6.0, 2.0), 18.0);
  EXPECT_EQ(PredictedWallTime(StepKind::kAdaptive, 6.0, 8.0), 6.0);
  EXPECT_EQ(PredictedWallTime(StepKind::kAdaptive, 6.0, 0.0), 0.0);
  EXPECT_EQ(PredictedWallTime(StepKind::kFixedStep, 0.0, 0.0), 0.0);
}

// --sizes does not start a method predicted past --time-limit from its
// starts at the smaller sizes: the last start scaled by (N/N_last)^p, p
// measured between the last two starts, at least 1 (linear: a lower bound
// of any method's cost in N); 1 with one start; none without. The
// tolerance is round-off of pow and log (1e-12 relative).
TEST(Sweep, AStartsWallTimeIsPredictedFromTheSmallerSizes) {
  using S = SizeHistory::Start;
  EXPECT_EQ(PredictedStartTime({}, 1000), 0.0);
  EXPECT_NEAR(PredictedStartTime({S{100, 2.0, true}}, 400), 8.0, 1e-12);       // p = 1
  EXPECT_NEAR(PredictedStartTime({S{100, 1.0, true}, S{400, 8.0, true}}, 1600), 64.0, 1e-11);  // p = 1.5
  EXPECT_NEAR(PredictedStartTime({S{100, 4.0, true}, S{400, 2.0, true}}, 800), 4.0, 1e-12);   // p clamped to 1
  EXPECT_NEAR(PredictedStartTime({S{100, 1.0, true}, S{400, 30.0, false}}, 1600),
              30.0 * std::pow(4.0, std::log(30.0) / std::log(4.0)), 1e-9);  // a time_limit start: its limit
  // A prediction already made at this size (a rung skipped at the start,
  // which the refinement asks about again) is not a smaller size's run.
  EXPECT_NEAR(PredictedStartTime({S{100, 1.0, true}, S{400, 8.0, true}, S{1600, 64.0, false, true}}, 1600), 64.0,
              1e-11);
}

// The reference's checks run side by side (harness/side_by_side.h): runs
// are taken in submission order, each on one kernel thread; a cancelled
// run in flight ends as at a deadline (an SBDF(2) run of 10⁷ steps ends
// time_limit within its next step), and a cancelled queued run never starts.
TEST(SideBySide, RunsInOrderOnOneKernelThreadAndCancelsWhatIsNotNeeded) {
  Scene scene = BuiltinScene("swinging_sheet");
  const ParticleSystem sys(scene);
  std::atomic<bool> third_started{false};
  SideBySide pool(1);
  const std::size_t a = pool.Submit([] {
    RunSummary r;
    r.steps = KernelThreads();
    return r;
  });
  std::atomic<bool> second_started{false};
  const std::size_t b = pool.Submit([&] {
    second_started = true;
    return RunIntegrator(sys, Method::kSbdf2, {0.01, 1e5, 1e5});
  });
  const std::size_t c = pool.Submit([&] {
    third_started = true;
    return RunSummary{};
  });
  EXPECT_EQ(pool.Take(a).steps, 1);
  while (!second_started) std::this_thread::yield();
  pool.Cancel(b);
  const RunSummary stopped = pool.Take(b);
  EXPECT_EQ(stopped.status, RunStatus::kTimeLimit) << stopped.message;
  EXPECT_NE(stopped.message, "cancelled before it started");
  EXPECT_LT(stopped.steps, 10000000);
  const RunSummary never = pool.Take(c);
  EXPECT_EQ(never.status, RunStatus::kTimeLimit);
  EXPECT_EQ(never.message, "cancelled before it started");
  EXPECT_FALSE(third_started);
}

// Without workers a run is computed when taken, on this thread, and what
// it throws reaches the caller.
TEST(SideBySide, WithoutWorkersComputesWhenTakenAndPassesExceptionsOn) {
  int computed = 0;
  SideBySide pool(0);
  const std::size_t a = pool.Submit([&] {
    RunSummary r;
    r.steps = ++computed;
    return r;
  });
  const std::size_t b = pool.Submit([]() -> RunSummary { throw std::runtime_error("thrown in a run"); });
  const std::size_t c = pool.Submit([&] {
    ++computed;
    return RunSummary{};
  });
  EXPECT_EQ(computed, 0);
  EXPECT_EQ(pool.Take(a).steps, 1);
  EXPECT_EQ(computed, 1);
  EXPECT_THROW((void)pool.Take(b), std::runtime_error);
  pool.Cancel(c, c + 1);
  EXPECT_EQ(pool.Take(c).message, "cancelled before it started");
  EXPECT_EQ(computed, 1);
}

TEST(Sweep, BenchIntegratorsOnTwoRanksWritesTheSerialFile) {
  const fs::path serial = Dir() / "rows_serial.h5", mpi = Dir() / "rows_mpi.h5";
  const Outcome a = Bench(kRows + " --out " + serial.string());
  ASSERT_EQ(a.exit_code, 0) << a.err;
  const Outcome b = Bench(kRows + " --out " + mpi.string(), MpiRun(2));
  ASSERT_EQ(b.exit_code, 0) << b.err;
  EXPECT_NE(b.out.find("0 of 13 runs from " + mpi.string() + ".journal; computing 13 on 2 ranks"), std::string::npos)
      << b.out;
  ExpectSameRuns(serial, mpi);
  EXPECT_EQ(ResultReader(mpi.string()).Long("/", "mpi_ranks").value_or(0), 2);
  EXPECT_FALSE(fs::exists(mpi.string() + ".journal"));
  EXPECT_FALSE(fs::exists(serial.string() + ".journal"));
}

// BoomerAMG inside a sweep: each rank sets up its own hierarchies (a
// different number per rank, as the runs are dealt), so hypre's objects
// must live on MPI_COMM_SELF; with them on MPI_COMM_WORLD the ranks'
// setups meet in hypre's collectives and this job hangs (the ctest TIMEOUT
// then fails it).
TEST(Sweep, AmgRunsOnTwoRanksWriteTheSerialFile) {
  const std::string rows = " --integrators sbdf2,bdf2/newton --h 0.01,0.005 --preconditioner amg";
  const fs::path serial = Dir() / "amg_serial.h5", mpi = Dir() / "amg_mpi.h5";
  const Outcome a = Bench(rows + " --out " + serial.string());
  ASSERT_EQ(a.exit_code, 0) << a.err;
  const Outcome b = Bench(rows + " --out " + mpi.string(), MpiRun(2));
  ASSERT_EQ(b.exit_code, 0) << b.err;
  ExpectSameRuns(serial, mpi, 100);
  EXPECT_EQ(ResultReader(mpi.string()).Long("/", "mpi_ranks").value_or(0), 2);
}

TEST(Sweep, BenchIntegratorsResumesWithOnlyTheMissingRuns) {
  const fs::path whole = Dir() / "rows_whole.h5", sliced = Dir() / "rows_sliced.h5";
  const fs::path journal = sliced.string() + ".journal";
  fs::remove_all(journal);
  ASSERT_EQ(Bench(kRows + " --out " + whole.string()).exit_code, 0);
  const Outcome first = Bench(kRows + " --max-runs 5 --out " + sliced.string());
  EXPECT_EQ(first.exit_code, 75) << first.err;
  EXPECT_NE(first.out.find("stopped after 5 runs (--max-runs): 5 of 13 done"), std::string::npos) << first.out;
  EXPECT_EQ(RunFiles(journal), 5u);
  EXPECT_FALSE(fs::exists(sliced));
  EXPECT_FALSE(fs::exists(sliced.string() + ".tmp"));
  const Outcome second = Bench(kRows + " --max-runs 4 --out " + sliced.string(), MpiRun(2));
  EXPECT_EQ(second.exit_code, 75) << second.err;
  EXPECT_EQ(RunFiles(journal), 9u);
  const Outcome last = Bench(kRows + " --out " + sliced.string() + " --quiet");
  ASSERT_EQ(last.exit_code, 0) << last.err;
  EXPECT_NE(last.out.find("9 of 13 runs from " + journal.string() + "; computing 4 on 1 rank"), std::string::npos)
      << last.out;
  EXPECT_FALSE(fs::exists(journal));
  ExpectSameRuns(whole, sliced);
  static_assert(kRuns == 13);
}

TEST(Sweep, BenchIntegratorsRefusesAJournalOfOtherArguments) {
  const fs::path out = Dir() / "rows_other.h5";
  const fs::path journal = out.string() + ".journal";
  fs::remove_all(journal);
  ASSERT_EQ(Bench(kRows + " --max-runs 2 --out " + out.string()).exit_code, 75);
  const Outcome o = Bench(" --integrators sbdf2 --h 0.01 --out " + out.string());
  EXPECT_EQ(o.exit_code, 2) << o.err;
  EXPECT_EQ(std::count(o.err.begin(), o.err.end(), '\n'), 1) << o.err;
  EXPECT_NE(o.err.find(journal.string() + ": was written by a run with other arguments"), std::string::npos) << o.err;
  EXPECT_EQ(RunFiles(journal), 2u);
  EXPECT_FALSE(fs::exists(out));
}

// A row whose run ends time_limit does not start its finer rungs (smaller
// h, tighter rtol): they are stored not_started, naming the rung that
// stopped and the time it reached; --start-predicted runs them. With a
// 1 ns --time-limit every started run ends time_limit in its first step.
TEST(Sweep, FinerRungsAfterATimeLimitAreNotStarted) {
  const std::string rows = " --integrators sbdf2,cvode --h 0.01,0.005 --rtols 1e-3,1e-4 --reference none "
                           "--time-limit 1e-9 --quiet";
  const fs::path out = Dir() / "finer.h5", all = Dir() / "finer_all.h5";
  const Outcome o = Bench(rows + " --out " + out.string());
  ASSERT_EQ(o.exit_code, 0) << o.err;
  const RunTable t = ReadRunTable(ResultReader(out.string()));
  ASSERT_EQ(t.runs.size(), 4u);
  for (const RunRecord& r : t.runs) {
    const bool first = r.h == 0.01 || r.rtol == 1e-3;
    EXPECT_EQ(r.status, first ? RunStatus::kTimeLimit : RunStatus::kNotStarted) << r.id << ": " << r.message;
    if (!first)
      EXPECT_NE(r.message.find(r.integrator == "cvode" ? "rtol 0.0001 is finer than cvode rtol 0.001, which ended "
                                                         "time_limit at t = "
                                                       : "sbdf2 h = 0.005 s is finer than sbdf2 h = 0.01 s, which ended "
                                                         "time_limit at t = "),
                std::string::npos)
          << r.message;
  }
  const Outcome started = Bench(rows + " --start-predicted --out " + all.string());
  ASSERT_EQ(started.exit_code, 0) << started.err;
  for (const RunRecord& r : ReadRunTable(ResultReader(all.string())).runs)
    EXPECT_EQ(r.status, RunStatus::kTimeLimit) << r.id << ": " << r.message;
}

// A journal written by a build whose run records differ (another
// RunRecordFormat: a field added or removed) is refused like one of other
// arguments, its runs kept: decoded by this build they would be malformed,
// and a journal's malformed entries are removed and computed again.
TEST(Sweep, BenchIntegratorsRefusesAJournalOfAnotherRecordFormat) {
  const fs::path out = Dir() / "rows_format.h5";
  const fs::path journal = out.string() + ".journal";
  fs::remove_all(journal);
  ASSERT_EQ(Bench(kRows + " --max-runs 2 --out " + out.string()).exit_code, 75);
  std::string key = testing::Slurp(journal / "key");
  const std::size_t at = key.find("format=");
  ASSERT_NE(at, std::string::npos) << key;
  key.replace(at + 7, 16, std::string(16, '0'));
  std::ofstream(journal / "key", std::ios::binary | std::ios::trunc) << key;
  const Outcome o = Bench(kRows + " --out " + out.string());
  EXPECT_EQ(o.exit_code, 2) << o.err;
  EXPECT_EQ(std::count(o.err.begin(), o.err.end(), '\n'), 1) << o.err;
  EXPECT_NE(o.err.find("or by a build whose records differ"), std::string::npos) << o.err;
  EXPECT_EQ(RunFiles(journal), 2u);
  EXPECT_FALSE(fs::exists(out));
}

// Journals that cannot lie (harness/sweep.h): every stored run carries a
// checksum of its content and of the command's key. An entry altered by one
// byte, a symbolic link and a FIFO in its place are all rejected with one
// line (nothing blocks on the FIFO) and computed again, and the file equals
// the uninterrupted run's. A folder with entries but no key is refused.
TEST(Sweep, DamagedJournalEntriesAreComputedAgain) {
  const fs::path whole = Dir() / "rows_whole2.h5", damaged = Dir() / "rows_damaged.h5";
  const fs::path journal = damaged.string() + ".journal";
  fs::remove_all(journal);
  ASSERT_EQ(Bench(kRows + " --out " + whole.string()).exit_code, 0);
  ASSERT_EQ(Bench(kRows + " --max-runs 5 --out " + damaged.string()).exit_code, 75);
  ASSERT_EQ(RunFiles(journal), 5u);
  {  // run 4 with a NaN in a stored frame, under a checksum that fits: caught by the range check
    const std::string key = testing::Slurp(journal / "key"), entry = testing::Slurp(journal / "4.run");
    MethodRun m = DecodeRun(entry.substr(entry.find('\n') + 1), 12);  // the tiny scene: 4 × 3
    ASSERT_FALSE(m.trajectory.positions.empty());
    m.trajectory.positions.back()(7, 2) = std::nan("");
    const std::string bytes = EncodeRun(m);
    std::ofstream(journal / "4.run", std::ios::binary)
        << fmt::format("clothbench run crc={:08x} bytes={}\n", JournalChecksum(key, bytes), bytes.size()) << bytes;
  }
  {  // one byte of run 1's content flipped (past its header line)
    std::fstream f(journal / "1.run", std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(-10, std::ios::end);
    const char c = static_cast<char>(f.get());
    f.seekp(-10, std::ios::end);
    f.put(static_cast<char>(c ^ 0x5a));
  }
  fs::remove(journal / "2.run");
  fs::create_symlink(journal / "0.run", journal / "2.run");
  fs::remove(journal / "3.run");
  ASSERT_EQ(::mkfifo((journal / "3.run").c_str(), 0644), 0);
  const Outcome o = Bench(kRows + " --out " + damaged.string() + " --quiet");
  ASSERT_EQ(o.exit_code, 0) << o.err;
  EXPECT_EQ(std::count(o.err.begin(), o.err.end(), '\n'), 1) << o.err;
  EXPECT_NE(o.err.find(journal.string() + ": 4 stored runs failed the check"), std::string::npos) << o.err;
  EXPECT_NE(o.out.find("1 of 13 runs from " + journal.string()), std::string::npos) << o.out;
  ExpectSameRuns(whole, damaged);
  // Entries without a key: refused, the folder left alone.
  fs::remove(damaged);
  fs::create_directories(journal);
  std::ofstream(journal / "0.run") << "clothbench run crc=00000000 bytes=0\n";
  const Outcome keyless = Bench(kRows + " --out " + damaged.string());
  EXPECT_EQ(keyless.exit_code, 2) << keyless.err;
  EXPECT_NE(keyless.err.find(journal.string() + ": has no key file"), std::string::npos) << keyless.err;
  EXPECT_TRUE(fs::exists(journal / "0.run"));
  EXPECT_FALSE(fs::exists(damaged));
}

// Table 3.1 (4 self-convergence references, 4 BDF(2) rows; ~14 s serial
// here): on 2 ranks the same counts, e_rms and attributes, timings aside.
TEST(Sweep, ThesisTableOnTwoRanksWritesTheSerialFile) {
  const fs::path serial = Dir() / "table_serial.h5", mpi = Dir() / "table_mpi.h5";
  const Outcome a = testing::RunCommand(CLOTHBENCH_BENCH_BINARY, " --table 3.1 --out " + serial.string(), Dir());
  ASSERT_EQ(a.exit_code, 0) << a.err;
  const Outcome b = testing::RunCommand(MpiRun(2) + CLOTHBENCH_BENCH_BINARY, " --table 3.1 --out " + mpi.string(), Dir());
  ASSERT_EQ(b.exit_code, 0) << b.err;
  ExpectSameRuns(serial, mpi, 60);  // 4 rows × 15 attributes and the table's own
  EXPECT_EQ(ResultReader(mpi.string()).Long("/", "mpi_ranks").value_or(0), 2);
  EXPECT_NE(b.out.find("2 MPI ranks"), std::string::npos) << b.out;
}

TEST(Sweep, TwoMpiRanksWriteTheSameMapsAsTheSerialRun) {
  const fs::path serial = Dir() / "serial.h5", mpi = Dir() / "mpi.h5";
  const Outcome a = Sweep(kSweep + " --out " + serial.string());
  ASSERT_EQ(a.exit_code, 0) << a.err;
  const Outcome b = Sweep(kSweep + " --out " + mpi.string(), MpiRun(2));
  ASSERT_EQ(b.exit_code, 0) << b.err;
  EXPECT_NE(b.out.find("0 of 96 cells from " + mpi.string() + ".journal; computing 96 on 2 ranks"), std::string::npos)
      << b.out;
  ExpectSameMaps(serial, mpi);
  EXPECT_EQ(Maps(a.out), Maps(b.out));  // rank 0 alone prints, the same maps
  EXPECT_EQ(ResultReader(mpi.string()).Long("/", "mpi_ranks").value_or(0), 2);
  EXPECT_FALSE(fs::exists(mpi.string() + ".journal"));
  EXPECT_FALSE(fs::exists(serial.string() + ".journal"));
}

TEST(Sweep, AStoppedSweepResumesWithOnlyTheMissingCells) {
  const fs::path whole = Dir() / "whole.h5", sliced = Dir() / "sliced.h5";
  const fs::path journal = sliced.string() + ".journal";
  fs::remove(journal);
  fs::remove(sliced);  // an earlier run's complete file
  ASSERT_EQ(Sweep(kSweep + " --out " + whole.string()).exit_code, 0);
  // First slice: 30 cells, exit 75, the journal holds them, no file.
  const Outcome first = Sweep(kSweep + " --max-cells 30 --out " + sliced.string());
  EXPECT_EQ(first.exit_code, 75) << first.err;
  EXPECT_NE(first.out.find("stopped after 30 cells (--max-cells): 30 of 96 done"), std::string::npos) << first.out;
  EXPECT_EQ(JournalCells(journal), 30);
  EXPECT_FALSE(fs::exists(sliced));
  EXPECT_FALSE(fs::exists(sliced.string() + ".tmp"));
  // Second slice on two MPI ranks: 40 more.
  const Outcome second = Sweep(kSweep + " --max-cells 40 --out " + sliced.string(), MpiRun(2));
  EXPECT_EQ(second.exit_code, 75) << second.err;
  EXPECT_NE(second.out.find("30 of 96 cells from " + journal.string() + "; computing 40 on 2 ranks"), std::string::npos)
      << second.out;
  EXPECT_EQ(JournalCells(journal), 70);
  // The rest: only the 26 missing cells are computed; the journal is
  // removed with the complete file, which equals the uninterrupted run's.
  const Outcome last = Sweep(kSweep + " --out " + sliced.string());
  ASSERT_EQ(last.exit_code, 0) << last.err;
  EXPECT_NE(last.out.find("70 of 96 cells from " + journal.string() + "; computing 26 on 1 rank"), std::string::npos)
      << last.out;
  EXPECT_FALSE(fs::exists(journal));
  ExpectSameMaps(whole, sliced);
}

// The stress sweep's journal lines carry a checksum too: a line with one
// digit changed, one with an outcome out of range (checksum made to fit)
// and a garbage line are rejected with one line and computed again; the
// maps equal the uninterrupted sweep's.
TEST(Sweep, AlteredStressJournalLinesAreComputedAgain) {
  const fs::path whole = Dir() / "whole3.h5", altered = Dir() / "altered.h5";
  const fs::path journal = altered.string() + ".journal";
  fs::remove(journal);
  ASSERT_EQ(Sweep(kSweep + " --out " + whole.string()).exit_code, 0);
  ASSERT_EQ(Sweep(kSweep + " --max-cells 10 --out " + altered.string()).exit_code, 75);
  std::vector<std::string> lines;
  {
    std::ifstream in(journal);
    for (std::string line; std::getline(in, line);) lines.push_back(line);
  }
  ASSERT_EQ(lines.size(), 11u);  // the header and 10 cells
  lines[1][lines[1].find(' ', 5) + 1] ^= 1;  // the outcome digit of the first cell: its checksum no longer fits
  {  // an outcome of 99 with a checksum computed for it
    std::string body = lines[2].substr(0, lines[2].rfind(" crc="));
    const std::size_t a = body.find(' ', 5) + 1, b = body.find(' ', a);
    body = body.substr(0, a) + "99" + body.substr(b);
    lines[2] = body + fmt::format(" crc={:08x}", JournalChecksum(lines[0], body));
  }
  lines.push_back("cell \x01\x7f garbage");
  {
    std::ofstream out(journal);
    for (const std::string& l : lines) out << l << "\n";
  }
  const Outcome o = Sweep(kSweep + " --out " + altered.string());
  ASSERT_EQ(o.exit_code, 0) << o.err;
  EXPECT_EQ(std::count(o.err.begin(), o.err.end(), '\n'), 1) << o.err;
  EXPECT_NE(o.err.find(journal.string() + ": 3 cell lines failed the check"), std::string::npos) << o.err;
  EXPECT_NE(o.out.find("8 of 96 cells from " + journal.string()), std::string::npos) << o.out;
  ExpectSameMaps(whole, altered);
}

TEST(Sweep, AJournalOfOtherArgumentsIsRefused) {
  const fs::path out = Dir() / "other.h5";
  const fs::path journal = out.string() + ".journal";
  fs::remove(journal);
  ASSERT_EQ(Sweep(kSweep + " --max-cells 3 --out " + out.string()).exit_code, 75);
  const Outcome o = Sweep(" --scenes hanging_sheet,swinging_sheet --integrators sbdf2,bdf2 --steps 41 --out " + out.string());
  EXPECT_EQ(o.exit_code, 2) << o.err;
  EXPECT_EQ(std::count(o.err.begin(), o.err.end(), '\n'), 1) << o.err;
  EXPECT_NE(o.err.find(journal.string() + ": was written by a sweep with other arguments"), std::string::npos) << o.err;
  EXPECT_EQ(JournalCells(journal), 3);  // left as it was
  EXPECT_FALSE(fs::exists(out));
}

// SIGINT in the middle of a sweep (600 steps per cell: ~10 s here), sent
// once the journal holds a cell (so the handlers are installed and the
// sweep is under way, however slow the machine): exit 130 with one line,
// no file, no .tmp, and the journal keeps the cells finished before it.
TEST(Sweep, SigintKeepsTheJournalAndLeavesNoFile) {
  const fs::path out = Dir() / "sigint.h5";
  const fs::path journal = out.string() + ".journal", err = Dir() / "sigint_err.txt", rc = Dir() / "sigint_rc.txt";
  fs::remove(journal);
  const std::string script = std::string(CLOTHBENCH_STRESS_BINARY) + " --steps 600 --out " + out.string() +
                             " > /dev/null 2> " + err.string() + " & pid=$!; i=0; until grep -q ^cell " + journal.string() +
                             " 2> /dev/null || [ $i -ge 600 ]; do sleep 0.05; i=$((i+1)); done; kill -INT $pid; wait $pid; "
                             "echo $? > " + rc.string();
  ASSERT_EQ(std::system(("sh -c '" + script + "'").c_str()), 0);
  EXPECT_EQ(std::stoi(testing::Slurp(rc)), 130);
  const std::string text = testing::Slurp(err);
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 1) << text;
  EXPECT_NE(text.find("interrupted by SIGINT"), std::string::npos) << text;
  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(out.string() + ".tmp"));
  EXPECT_FALSE(fs::exists(out.string() + ".lock"));
  EXPECT_TRUE(fs::exists(journal));
  const long cells = JournalCells(journal);
  EXPECT_GE(cells, 1);
  EXPECT_LT(cells, 288);  // interrupted: not all 2 scenes × 6 methods × 24 cells
}

// One writer per output (harness/output_lock.h): while a sweep writes
// <out>, a second stress_stability and a bench_integrators given the same
// --out exit 2 at once with one line naming the first one's pid, and leave
// its journal alone; the first, interrupted, removes its lock file.
TEST(Sweep, ASecondWriterOfTheSameOutputIsRefused) {
  const fs::path out = Dir() / "locked.h5";
  const fs::path journal = out.string() + ".journal", lock = out.string() + ".lock";
  const fs::path err2 = Dir() / "locked_err2.txt", err3 = Dir() / "locked_err3.txt", rc = Dir() / "locked_rc.txt",
                 pidfile = Dir() / "locked_pid.txt";
  fs::remove_all(journal);
  fs::remove(lock);
  const std::string script =
      std::string(CLOTHBENCH_STRESS_BINARY) + " --steps 600 --out " + out.string() + " > /dev/null 2>&1 & pid=$!; echo $pid > " +
      pidfile.string() + "; i=0; until grep -q ^cell " + journal.string() +
      " 2> /dev/null || [ $i -ge 600 ]; do sleep 0.05; i=$((i+1)); done; " + CLOTHBENCH_STRESS_BINARY + " --out " +
      out.string() + " > /dev/null 2> " + err2.string() + "; r2=$?; " + CLOTHBENCH_BENCH_BINARY + " --out " +
      out.string() + " > /dev/null 2> " + err3.string() + "; r3=$?; kill -INT $pid; wait $pid; echo $r2 $r3 > " +
      rc.string();
  ASSERT_EQ(std::system(("sh -c '" + script + "'").c_str()), 0);
  std::istringstream codes(testing::Slurp(rc));
  int r2 = 0, r3 = 0;
  codes >> r2 >> r3;
  EXPECT_EQ(r2, 2);
  EXPECT_EQ(r3, 2);
  std::string pid = testing::Slurp(pidfile);
  pid.erase(pid.find_last_not_of(" \n") + 1);
  for (const fs::path& e : {err2, err3}) {
    const std::string text = testing::Slurp(e);
    EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 1) << text;
    EXPECT_NE(text.find("is being written by process " + pid), std::string::npos) << text;
  }
  EXPECT_FALSE(fs::exists(lock));
  EXPECT_GE(JournalCells(journal), 1);  // the first one's cells, untouched
}

// A task whose run stayed inside one library call past its --time-limit in
// an earlier process (its marker `<k>.overrun`, harness/overrun.h) runs
// under a deadline passed already: the fixed-step driver and SUNDIALS'
// record time_limit before their first step, with the earlier process'
// seconds as wall time; a marked reference is not run at all; without a
// marker the run is the ordinary one.
TEST(Sweep, AnOverrunTaskRecordsTimeLimitBeforeItsFirstStep) {
  const fs::path folder = Dir() / "overrun.h5.journal";
  fs::remove_all(folder);
  SweepComm comm(nullptr, nullptr);
  const RecordJournal journal(folder.string(), "key", comm);
  const Scene scene = BuiltinScene("swinging_sheet");
  const ParticleSystem sys(scene);
  for (const std::string label : {"sbdf2", "cvode"}) {
    const std::vector<RowMethod> rows = ExpandMethods({label}, {scene.solver.nonlinear_solver}, "test");
    ASSERT_EQ(rows.size(), 1u);
    const double param = label == "cvode" ? 1e-3 : scene.h;
    const auto run = [&] { return rows[0].Run(sys, scene, scene.solver, param, RunContext{}); };
    const MethodRun plain = RunJournalledTask(journal, 1, label, 20.0, false, run);
    EXPECT_TRUE(plain.ok()) << label << ": " << plain.message;
    EXPECT_GT(plain.steps, 0) << label;
    {  // the drivers' check before each step: no step is attempted
      const ScopedDeadline passed(PassedDeadline());
      const MethodRun r = run();
      EXPECT_EQ(r.status, RunStatus::kTimeLimit) << label;
      EXPECT_NE(r.message.find("after 0 steps"), std::string::npos) << label << ": " << r.message;
      EXPECT_TRUE(r.step_stats.empty()) << label;
    }
    WriteFileAtomically(journal.OverrunEntry(1), "elapsed_s=25.5\n", "--out");
    ASSERT_EQ(journal.Overrun(1), 25.5);
    const MethodRun marked = RunJournalledTask(journal, 1, label, 20.0, false, run);
    EXPECT_EQ(marked.status, RunStatus::kTimeLimit) << label << ": " << marked.message;
    EXPECT_EQ(marked.steps, 0) << label;
    EXPECT_EQ(marked.wall_time_s, 25.5) << label;
    EXPECT_NE(marked.message.find("inside one library call"), std::string::npos) << marked.message;
    EXPECT_EQ(marked.id, plain.id) << "the row's identity is the ordinary run's";
    journal.ClearOverrun(1);
    EXPECT_FALSE(journal.Overrun(1).has_value());
  }
  WriteFileAtomically(journal.OverrunEntry(0), "elapsed_s=3\n", "--out");
  bool computed = false;
  const RunSummary ref = RunJournalledTask(journal, 0, "the reference", 20.0, true, [&] {
    computed = true;
    return RunSummary{};
  });
  EXPECT_FALSE(computed) << "a marked reference is not run again";
  EXPECT_EQ(ref.status, RunStatus::kTimeLimit);
  // A marker that is not "elapsed_s=<seconds>", or a link, is no marker.
  WriteFileAtomically(journal.OverrunEntry(2), "elapsed_s=-1\n", "--out");
  EXPECT_FALSE(journal.Overrun(2).has_value());
  fs::create_symlink(journal.OverrunEntry(0), journal.OverrunEntry(3));
  EXPECT_FALSE(journal.Overrun(3).has_value());
  fs::remove_all(folder);
}

}  // namespace
}  // namespace clothbench
