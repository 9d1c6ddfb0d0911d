// SIGINT / SIGTERM for the executables: the handler only records the signal
// (model/interrupt.h); the run stops after the current step, the result
// file's .tmp is removed while unwinding, and Main exits 128 + signal
// (130 for SIGINT, 143 for SIGTERM) with one line.
#ifndef CLOTHBENCH_BENCH_SIGNALS_H_
#define CLOTHBENCH_BENCH_SIGNALS_H_

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cerrno>
#include <cstring>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "harness/output_lock.h"
#include "harness/overrun.h"
#include "model/interrupt.h"

namespace clothbench {

inline void OnContinueSignal(int) { NoteContinued(); }

inline void OnInterruptSignal(int sig) {
  RequestInterrupt(sig);
  // A second signal ends the process at once (default action).
  std::signal(sig, SIG_DFL);
}

inline void InstallInterruptHandlers() {
  struct sigaction sa {};
  sa.sa_handler = OnInterruptSignal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = 0;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  // A file-size limit (ulimit -f, RLIMIT_FSIZE) makes a write fail with
  // EFBIG, reported with the file's name, instead of killing the process
  // with SIGXFSZ and leaving its temporary files.
  signal(SIGXFSZ, SIG_IGN);
  // SIGCONT after a stop (SIGSTOP, Ctrl-Z): the watchdog measures the
  // stop, so that a deadline passed while stopped is not taken for a run
  // stuck inside a library call. SA_RESTART: no system call fails with EINTR.
  struct sigaction cont {};
  cont.sa_handler = OnContinueSignal;
  sigemptyset(&cont.sa_mask);
  cont.sa_flags = SA_RESTART;
  sigaction(SIGCONT, &cont, nullptr);
}

inline const char* SignalName(int sig) { return sig == SIGINT ? "SIGINT" : sig == SIGTERM ? "SIGTERM" : "a signal"; }

namespace internal {
inline std::atomic<bool> g_interrupt_handled{false};
inline std::mutex g_watchdog_mutex;
inline std::string g_watchdog_note;  // what the watchdog's line says of the journal
}  // namespace internal

/// Main's handler of Interrupted calls this first: the watchdog stands down
/// while Main cleans up and exits.
inline void InterruptHandled() { internal::g_interrupt_handled.store(true); }

/// What the watchdog's line adds, e.g. where the finished runs are kept.
inline void SetWatchdogNote(std::string note) {
  const std::lock_guard<std::mutex> lock(internal::g_watchdog_mutex);
  internal::g_watchdog_note = std::move(note);
}

namespace internal {
inline std::atomic<bool> g_watch_overruns{false};
inline std::vector<std::string> g_restart_argv;  // set before g_watch_overruns; empty: exit 75, no restart
inline std::chrono::milliseconds g_overrun_grace{5000};

// The watchdog's action on a run `grace` past its deadline: marks its task
// (harness/overrun.h) and restarts the command or ends the process. Returns
// only when no journalled task is in progress.
inline void EndOverrun(const std::string& program) {
  std::string line;
  const OverrunMark mark = MarkOverrun(&line);
  if (mark == OverrunMark::kNoTask) return;
  std::fflush(stdout);
  if (mark == OverrunMark::kAgain) {
    fmt::print(stderr, "{}: {} again, although it was run past its deadline after the same overrun in an earlier "
                       "process; ended (exit 1) so that the same command does not enter the call once more\n",
               program, line);
    std::fflush(stderr);
    ::_exit(1);
  }
  if (!g_restart_argv.empty()) {
    fmt::print(stderr, "{}: {}; the process restarts the same command, which records the run as time_limit and "
                       "resumes from the journal\n",
               program, line);
    std::fflush(stderr);
    std::vector<char*> argv;
    for (std::string& a : g_restart_argv) argv.push_back(a.data());
    argv.push_back(nullptr);
    KeepOutputLocksAcrossExec();  // the restarted command takes its --out locks over
    ::execv("/proc/self/exe", argv.data());  // returns only on failure
    fmt::print(stderr, "{}: the restart failed ({}); ", program, std::strerror(errno));
  } else {
    fmt::print(stderr, "{}: {}; ", program, line);
  }
  fmt::print(stderr, "ended (exit {}): the same command records the run as time_limit and resumes from the "
                     "journal\n",
             kExitPartial);
  std::fflush(stderr);
  ::_exit(kExitPartial);
}
}  // namespace internal

/// Makes the watchdog (StartInterruptWatchdog) also end a run that stays
/// `grace` past its --time-limit: such a run is inside one library call
/// that checks no deadline (EarliestActiveDeadline, model/interrupt.h). The
/// watchdog marks the run's journalled task (harness/overrun.h) and, with
/// `restart_argv` (the command's arguments, argv[0] first), restarts the
/// command in the same process (execv of /proc/self/exe: the same pid; the
/// output locks' descriptors stay open across it and the restarted command
/// takes them over, KeepOutputLocksAcrossExec),
/// which resumes from the journal and records the task as time_limit
/// without entering the call again. Without it (MPI ranks, which one rank
/// cannot restart) the process exits kExitPartial (75), and the same
/// command resumes. A run outside a journalled task is left alone.
inline void WatchOverruns(std::vector<std::string> restart_argv,
                          std::chrono::milliseconds grace = std::chrono::milliseconds(5000)) {
  internal::g_restart_argv = std::move(restart_argv);
  internal::g_overrun_grace = grace;
  internal::g_watch_overruns.store(true);
}

/// Starts a detached thread that ends the process when SIGINT or SIGTERM
/// is not noticed within `grace`: the run is then inside one library call
/// that checks no flag and has no callback to stop it (a KLU or CHOLMOD
/// factorisation, a BoomerAMG setup), which can take minutes at 10⁵
/// particles. It prints one line, "<program>: interrupted by <signal>
/// inside a library call ...; <note>", and calls _exit(128 + signal): the
/// run in progress is lost, as it is when a step notices the signal; every
/// finished run is in its journal already, written as it ended, and a
/// journal entry being written is a ".tmp" that readers ignore. A result
/// file is never being written then: its writer checks the flag between
/// frames. After WatchOverruns it also ends a run past its deadline.
inline void StartInterruptWatchdog(std::string program,
                                   std::chrono::milliseconds grace = std::chrono::milliseconds(1000)) {
  std::thread([program = std::move(program), grace] {
    using Clock = std::chrono::steady_clock;
    // A run is stuck inside a library call when it has been running past
    // its deadline for the grace: time the process spent stopped (SIGSTOP,
    // a suspended job) does not count, the grace starts again when it
    // continues, and the stop is added to the run's message.
    Clock::time_point resumed = Clock::time_point::min();
    AccountStop(Clock::now());
    while (!InterruptRequested()) {
      const Clock::time_point now = Clock::now();
      if (AccountStop(now)) resumed = now;
      if (internal::g_watch_overruns.load()) {
        const auto deadline = EarliestActiveDeadline();
        if (deadline != Clock::time_point::max() && now - std::max(deadline, resumed) > internal::g_overrun_grace)
          internal::EndOverrun(program);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    const auto noticed_by = std::chrono::steady_clock::now() + grace;
    while (std::chrono::steady_clock::now() < noticed_by) {
      if (internal::g_interrupt_handled.load()) return;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    if (internal::g_interrupt_handled.load()) return;
    const int sig = internal::g_interrupt_signal.load();
    std::string note;
    {
      const std::lock_guard<std::mutex> lock(internal::g_watchdog_mutex);
      note = internal::g_watchdog_note;
    }
    std::fflush(stdout);
    fmt::print(stderr, "{}: interrupted by {}, which no step noticed within {} ms (a library call such as a "
                       "factorisation cannot); the run in progress is lost, no result file written{}\n",
               program, SignalName(sig), grace.count(), note.empty() ? "" : "; " + note);
    std::fflush(stderr);
    ::_exit(128 + sig);
  }).detach();
}

}  // namespace clothbench

#endif  // CLOTHBENCH_BENCH_SIGNALS_H_
