// The kernel threads of a run on a shared machine (solver/thread_budget.h).
#include "solver/thread_budget.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <utility>

#include <fcntl.h>
#include <sched.h>
#include <omp.h>
#include <unistd.h>

namespace clothbench {
namespace {

// The first `size - 1` bytes of `path`, NUL-terminated; 0 if unreadable.
std::size_t ReadSmall(const char* path, char* buf, std::size_t size) {
  const int fd = ::open(path, O_RDONLY | O_CLOEXEC);
  if (fd < 0) return 0;
  std::size_t got = 0;
  while (got + 1 < size) {
    const ssize_t n = ::read(fd, buf + got, size - 1 - got);
    if (n <= 0) break;
    got += static_cast<std::size_t>(n);
  }
  ::close(fd);
  buf[got] = '\0';
  return got;
}

// The last decision of any budget of the process and its steady-clock
// time [ns]: a run that starts within kRecent of it starts on that many
// threads (a sweep's next run, a repeat's next timing) rather than on the
// requested count for its first interval.
std::atomic<int> g_last_threads{0};
std::atomic<long long> g_last_ns{0};
constexpr std::chrono::seconds kRecent{2};

long long NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// The busy ticks of one /proc/stat cpu line's fields from `p` (user nice
// system idle iowait irq softirq steal): all but idle and iowait; -1 if
// the line is short. `*end` is set past the fields read.
double BusyTicks(const char* p, const char** end) {
  double busy = 0.0;
  for (int field = 0; field < 8; ++field) {
    char* stop = nullptr;
    const double v = static_cast<double>(std::strtoull(p, &stop, 10));
    if (stop == p) return -1.0;
    p = stop;
    if (field != 3 && field != 4) busy += v;
  }
  *end = p;
  return busy;
}

// The busy ticks of the cores this process may run on (its affinity mask:
// a container's or a taskset's cores, not the whole host's); the machine's
// total where a core of the mask has no line in the first `size` bytes.
double AffineBusyTicks(const char* buf) {
  static const cpu_set_t mask = [] {
    cpu_set_t m;
    CPU_ZERO(&m);
    if (::sched_getaffinity(0, sizeof m, &m) != 0) CPU_ZERO(&m);
    return m;
  }();
  const char* end = nullptr;
  const double total = BusyTicks(buf + 4, &end);  // the "cpu  " line
  const int wanted = CPU_COUNT(&mask);
  if (total < 0.0 || wanted == 0) return total;
  double busy = 0.0;
  int found = 0;
  for (const char* line = std::strchr(buf, '\n'); line && std::strncmp(line + 1, "cpu", 3) == 0;
       line = std::strchr(line + 1, '\n')) {
    char* stop = nullptr;
    const long cpu = std::strtol(line + 4, &stop, 10);
    if (stop == line + 4 || cpu < 0 || cpu >= CPU_SETSIZE || !CPU_ISSET(static_cast<int>(cpu), &mask)) continue;
    const double b = BusyTicks(stop, &end);
    if (b < 0.0) break;
    busy += b;
    ++found;
  }
  return found == wanted ? busy : total;
}

}  // namespace

CpuTimes ReadCpuTimes() {
  static const double tick = static_cast<double>(::sysconf(_SC_CLK_TCK));
  CpuTimes t;
  if (!(tick > 0.0)) return t;
  // /proc/stat: "cpu  user nice system idle iowait irq softirq steal ..."
  // [ticks], then one such line per core ("cpu0 ...").
  char buf[16384];
  if (ReadSmall("/proc/stat", buf, sizeof buf) == 0 || std::strncmp(buf, "cpu ", 4) != 0) return t;
  const double busy = AffineBusyTicks(buf);
  if (busy < 0.0) return t;
  // /proc/self/stat: "pid (comm) state ..." with utime, stime the 14th and
  // 15th fields; comm may hold spaces and parentheses, so count from the last ')'.
  char self[1024];
  if (ReadSmall("/proc/self/stat", self, sizeof self) == 0) return t;
  const char* q = std::strrchr(self, ')');
  if (!q || q[1] != ' ' || q[2] == '\0') return t;
  q += 3;  // past ") " and the state's letter
  double own = 0.0;
  for (int field = 4; field <= 15; ++field) {
    char* end = nullptr;
    const double v = static_cast<double>(std::strtoull(q, &end, 10));
    if (end == q) return t;
    q = end;
    if (field >= 14) own += v;
  }
  t.wall = std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
  t.machine = busy / tick;
  t.process = own / tick;
  t.valid = true;
  return t;
}

ThreadBudget::ThreadBudget(int requested, int cores, std::function<CpuTimes()> probe)
    : requested_(std::max(1, requested > 0 ? requested : omp_get_max_threads())),
      cores_(std::max(1, cores > 0 ? cores : omp_get_num_procs())),
      threads_(requested_),
      fewest_(requested_),
      probe_(std::move(probe)),
      before_(requested_ > 1 ? probe_() : CpuTimes{}),
      last_(Clock::now()) {
  const auto* source = probe_.target<CpuTimes (*)()>();
  shared_ = source && *source == &ReadCpuTimes;  // a planted machine (tests) neither reads nor leaves a decision
  const int last = shared_ ? g_last_threads.load() : 0;
  if (requested_ > 1 && last >= 1 && last < requested_ &&
      NowNs() - g_last_ns.load() < std::chrono::duration_cast<std::chrono::nanoseconds>(kRecent).count()) {
    SetThreads(last);
  }
}

ThreadBudget::~ThreadBudget() {
  if (threads_ != requested_) omp_set_num_threads(requested_);
}

void ThreadBudget::SetThreads(int threads) {
  omp_set_num_threads(threads);
  threads_ = threads;
  fewest_ = std::min(fewest_, threads);
}

void ThreadBudget::Update() {
  if (requested_ == 1) return;  // nothing to lower
  const Clock::time_point now = Clock::now();
  if (now - last_ < kInterval) return;
  const CpuTimes after = probe_();
  const double seconds = after.wall - before_.wall;
  if (after.valid && before_.valid && seconds > 0.0) {
    // The cores the other processes kept busy over the interval.
    const double others = std::max(0.0, (after.machine - before_.machine) - (after.process - before_.process)) / seconds;
    const int free = static_cast<int>(std::lround(static_cast<double>(cores_) - others));
    const int next = std::clamp(free, 1, requested_);
    if (next != threads_) SetThreads(next);
    if (shared_) {
      g_last_threads.store(next);
      g_last_ns.store(NowNs());
    }
  }
  before_ = after;
  last_ = now;
}

}  // namespace clothbench
