// libFuzzer target of the result-file reader (results/result_reader.h) and
// of what clothbench_inspect reads after ValidateResultFile accepted a file
// (docs/notes/verification.md, "Fuzzing").
//
// For any byte string, opened as an in-memory HDF5 image, the reader must
// either refuse it with a ResultError whose message is one line naming the
// file, or accept it; after ValidateResultFile accepted it, the run table,
// every attribute, every stored frame of every run, the faces, the step
// tables and the printed table must be readable without another exception,
// every frame value finite (ValidateResultFile checks the face indices).
// Anything else (another exception, a sanitizer report, a violated
// invariant) aborts and is a finding. Seeds: small result files of
// bench_integrators and stress_stability (verify/fuzz/results/).
//
// Mutations: most are signed again (LLVMFuzzerCustomMutator: libFuzzer's
// own byte mutations or a few flipped bits past the integrity block, then
// the block rewritten with the new CRC-32 and size), so that HDF5 parses
// damaged object headers, attribute messages, datatypes and dimensions as
// it would in a file someone edited and signed again; one in eight is left
// unsigned and must be refused by the integrity check.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>

#include <fcntl.h>
#include <poll.h>
#include <sanitizer/common_interface_defs.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zlib.h>

#include <cerrno>
#include <csignal>

#include <fmt/format.h>

#include "results/contained_read.h"
#include "results/result_reader.h"
#include "results/run_table.h"

namespace {

bool g_in_child = false;
int g_pipe[2] = {-1, -1};  // the child's refusal text to the parent
int g_report_fd = 2;  // the child's stderr is /dev/null (HDF5 crashes' ASan reports); findings go here

// A violated invariant: in the child, exit 3 (the parent reports it);
// in-process, abort (libFuzzer saves the input).
[[noreturn]] void Finding(const char* what, const std::string& detail) {
  const std::string line = fmt::format("fuzz_result finding: {}: {}\n", what, detail);
  (void)!write(g_report_fd, line.data(), line.size());
  if (g_in_child) _exit(3);
  std::abort();
}

// Everything a reader reads after ValidateResultFile accepted the file
// (results/contained_read.h: ReadValidatedFile), then the invariants that
// do not depend on a second read of an attribute: every frame finite,
// every time finite. (ValidateResultFile itself checks faces and frame
// shapes against /scene@n_particles; HDF5 1.10 may read a damaged header
// differently a second time, so re-reading N here gave false findings:
// result_regressions/n_particles_reread_differs.bin.)
void ReadEverything(const clothbench::ResultReader& f) {
  using namespace clothbench;
  ReadValidatedFile(f);
  std::vector<std::string> groups;
  if (f.Exists("/reference")) groups.push_back("/reference");
  for (const std::string& id : f.Children("/runs")) groups.push_back("/runs/" + id);
  for (const std::string& g : groups) {
    for (const char* name : {"positions", "velocities", "positions_ends", "velocities_ends"}) {
      const std::string d = g + "/" + name;
      if (!f.Exists(d)) continue;
      const std::size_t frames = f.Shape(d)[0];
      for (std::size_t k = 0; k < frames; ++k)
        if (!f.Frame(d, k).allFinite()) Finding("frame not finite", d);
    }
    if (f.Exists(g + "/times"))
      for (double v : f.Doubles(g + "/times"))
        if (!std::isfinite(v)) Finding("non-finite time", g);
  }
}

}  // namespace

extern "C" std::size_t LLVMFuzzerMutate(uint8_t* data, std::size_t size, std::size_t max_size);

// Rewrites the integrity block of a file image (results/result_file.h:
// "clothbench result crc32 XXXXXXXX bytes N", NUL-padded to kSignatureBytes).
void Sign(uint8_t* data, std::size_t size) {
  const std::size_t block = clothbench::kSignatureBytes;
  if (size < block) return;
  const uLong crc = crc32(0L, data + block, static_cast<uInt>(size - block));
  char text[block];
  std::memset(text, 0, block);
  std::snprintf(text, block, "clothbench result crc32 %08lx bytes %zu\n", crc, size);
  std::memcpy(data, text, block);
}

extern "C" std::size_t LLVMFuzzerCustomMutator(uint8_t* data, std::size_t size, std::size_t max_size,
                                               unsigned int seed) {
  const std::size_t block = clothbench::kSignatureBytes;
  std::srand(seed);
  const int kind = std::rand() % 8;
  if (kind == 0 || size <= block) return LLVMFuzzerMutate(data, size, max_size);  // unsigned
  if (kind <= 3) {  // a few flipped bits past the block
    const int flips = 1 + std::rand() % 4;
    for (int k = 0; k < flips; ++k) data[block + static_cast<std::size_t>(std::rand()) % (size - block)] ^=
        static_cast<uint8_t>(1u << (std::rand() % 8));
  } else {  // libFuzzer's mutations of the HDF5 part
    size = block + LLVMFuzzerMutate(data + block, size - block, max_size - block);
  }
  Sign(data, size);
  return size;
}

// The reading of ReadOnce, in a child process: HDF5 1.10 crashes on some
// damaged headers that pass the integrity check (edited and signed again),
// and leaks memory on others, so clothbench_inspect reads untrusted files
// the same way (results/contained_read.h: CheckReadableInChild). A child
// killed by a signal (or reporting a sanitizer error about HDF5's memory)
// is such a contained crash: counted, and saved under
// $CLOTHBENCH_FUZZ_CONTAINED if set. A child that finds a violated
// invariant exits 3 and the parent reports the finding. The coverage of a
// child does not reach libFuzzer, so the fuzzing is driven by the
// re-signing mutator on the seeds rather than by coverage.
void ReadOnce(const uint8_t* data, std::size_t size) {
  using namespace clothbench;
  try {
    const ResultReader f("fuzz.h5", data, size);
    ValidateResultFile(f);
    try {
      ReadEverything(f);
    } catch (const ResultError& e) {
      // A frame value that is not finite is found when the frame is read
      // (ValidateResultFile checks extents, not every frame's values).
      if (std::string(e.what()).find("non-finite value") == std::string::npos &&
          std::string(e.what()).find("cannot read") == std::string::npos)
        Finding("ResultError after ValidateResultFile accepted the file", e.what());
    }
  } catch (const ResultError& e) {
    const std::string m = e.what();
    if (m.empty() || m.find('\n') != std::string::npos || m.rfind("fuzz.h5", 0) != 0)
      Finding("refusal not one line naming the file", m);
    // The refusal's kind, without its numbers, for the parent's feedback.
    std::string kind;
    for (char c : m.substr(0, 64))
      if (!(c >= '0' && c <= '9')) kind += c;
    if (g_in_child) (void)!write(g_pipe[1], kind.data(), kind.size());
  } catch (const std::bad_alloc&) {
    // A damaged dimension asking for more memory than -malloc_limit_mb:
    // clothbench_inspect refuses such a file (exit 2).
  }
}

long g_contained = 0;
constexpr unsigned kChildSeconds = 10;  // a child's alarm; the parent kills it at twice that

// One of 32 branches per outcome text (each a distinct edge for libFuzzer).
void Feedback(const std::string& text) {
  unsigned h = 2166136261u;
  for (unsigned char c : text) h = (h ^ c) * 16777619u;
  volatile int sink = 0;
  switch (h % 32) {
#define CB_CASE(k) \
  case k:          \
    sink = k;      \
    break;
    CB_CASE(0) CB_CASE(1) CB_CASE(2) CB_CASE(3) CB_CASE(4) CB_CASE(5) CB_CASE(6) CB_CASE(7)
    CB_CASE(8) CB_CASE(9) CB_CASE(10) CB_CASE(11) CB_CASE(12) CB_CASE(13) CB_CASE(14) CB_CASE(15)
    CB_CASE(16) CB_CASE(17) CB_CASE(18) CB_CASE(19) CB_CASE(20) CB_CASE(21) CB_CASE(22) CB_CASE(23)
    CB_CASE(24) CB_CASE(25) CB_CASE(26) CB_CASE(27) CB_CASE(28) CB_CASE(29) CB_CASE(30) CB_CASE(31)
#undef CB_CASE
    default:
      break;
  }
  (void)sink;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  if (std::getenv("CLOTHBENCH_FUZZ_IN_PROCESS")) {  // replaying an input under a debugger or a sanitizer's report
    ReadOnce(data, size);
    return 0;
  }
  if (pipe(g_pipe) != 0) Finding("pipe failed", std::strerror(errno));
  const pid_t pid = fork();
  if (pid < 0) Finding("fork failed", std::strerror(errno));
  if (pid == 0) {
    g_in_child = true;
    // No crash handler of libFuzzer's in the child: a crash there is a
    // contained one (and its handler can deadlock in malloc).
    // libFuzzer's SIGALRM handler (its -timeout) would ignore the alarm
    // below, and its SIGINT/SIGTERM handlers allocate.
    for (int sig : {SIGSEGV, SIGBUS, SIGABRT, SIGILL, SIGFPE, SIGALRM, SIGINT, SIGTERM}) std::signal(sig, SIG_DFL);
    alarm(kChildSeconds);  // an HDF5 loop on a damaged header: killed, contained like a crash
    __sanitizer_set_death_callback(nullptr);  // libFuzzer's would save a contained crash as a finding
    g_report_fd = dup(2);
    if (const int null = open("/dev/null", O_WRONLY); null >= 0) dup2(null, 2);
    close(g_pipe[0]);
    ReadOnce(data, size);
    _exit(0);
  }
  close(g_pipe[1]);
  // The child's refusal, until it exits; the parent's own deadline kills a
  // child that outlives its alarm (blocked with the signal masked).
  char stage_text[256] = {0};
  ssize_t got = 0;
  pollfd p{g_pipe[0], POLLIN, 0};
  int ready = 0;
  while ((ready = poll(&p, 1, static_cast<int>(2000 * kChildSeconds))) < 0 && errno == EINTR) {
  }
  if (ready > 0) got = read(g_pipe[0], stage_text, sizeof stage_text - 1);
  else kill(pid, SIGKILL);
  close(g_pipe[0]);
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  // Coverage for libFuzzer from the child's outcome: the refusal's text
  // (which check refused, which object) hashed into one of 32 branches.
  Feedback(got > 0 ? std::string(stage_text, static_cast<std::size_t>(got)) : std::string("whole"));
  if (WIFEXITED(status) && WEXITSTATUS(status) == 3) Finding("the child found a violated invariant", "see above");
  if (WIFSIGNALED(status) || (WIFEXITED(status) && WEXITSTATUS(status) != 0)) {
    ++g_contained;  // an HDF5 crash (ASan reports it and exits 1), contained as clothbench_inspect contains it
    if (const char* dir = std::getenv("CLOTHBENCH_FUZZ_CONTAINED")) {
      const std::string path = fmt::format("{}/contained-{}.h5", dir, g_contained);
      if (std::FILE* out = std::fopen(path.c_str(), "wb")) {
        std::fwrite(data, 1, size, out);
        std::fclose(out);
      }
    }
    return 0;
  }
  return 0;
}
