// A run that stays inside one library call past its --time-limit: KLU,
// CHOLMOD and BoomerAMG have no callback to stop a factorisation or a
// setup, which take minutes at 10⁵ particles, so no deadline check inside
// our code is reached until the call returns. The executables' watchdog
// (bench/signals.h, WatchOverruns) sees such a run through
// EarliestActiveDeadline (model/interrupt.h); this file names the
// journalled task the run belongs to, so that the watchdog can leave a
// marker in the sweep's journal before it ends (or restarts) the process,
// and so that the task, run again, records time_limit before its first
// step instead of entering the call again (RunJournalledTask).
#ifndef CLOTHBENCH_HARNESS_OVERRUN_H_
#define CLOTHBENCH_HARNESS_OVERRUN_H_

#include <chrono>
#include <mutex>
#include <optional>
#include <string>
#include <utility>

#include <fmt/format.h>

#include "harness/sweep.h"
#include "model/interrupt.h"
#include "model/output_file.h"
#include "solver/record/run_status.h"

namespace clothbench {

namespace internal {
struct OverrunTask {
  std::string marker;   // <journal>/<k>.overrun
  std::string what;     // "cvode/klu rtol 1e-3", for the watchdog's line
  double limit_s = 0.0; // the task's --time-limit [s]
  bool again = false;   // the task overran in an earlier process already
  std::chrono::steady_clock::time_point start;
};
inline std::mutex g_overrun_mutex;
inline std::optional<OverrunTask> g_overrun_task;
}  // namespace internal

/// Names the journalled task whose run is in progress on this process for
/// the object's lifetime (one at a time: the sweeps compute one task after
/// the other on each rank).
class ScopedOverrunTask {
 public:
  /// @param journal the sweep's journal; @param index the task
  /// @param what the run, as the progress line names it
  /// @param limit_s the task's --time-limit [s] (≤ 0: none)
  /// @param again whether the task overran in an earlier process
  ScopedOverrunTask(const RecordJournal& journal, long index, std::string what, double limit_s, bool again) {
    const std::lock_guard<std::mutex> lock(internal::g_overrun_mutex);
    internal::g_overrun_task = internal::OverrunTask{journal.OverrunEntry(index), std::move(what), limit_s, again,
                                                     std::chrono::steady_clock::now()};
  }
  ~ScopedOverrunTask() {
    const std::lock_guard<std::mutex> lock(internal::g_overrun_mutex);
    internal::g_overrun_task.reset();
  }
  ScopedOverrunTask(const ScopedOverrunTask&) = delete;
  ScopedOverrunTask& operator=(const ScopedOverrunTask&) = delete;
};

/// What MarkOverrun did.
enum class OverrunMark {
  kNoTask,  ///< no journalled task is in progress: nothing to mark, the process goes on
  kMarked,  ///< the marker is written: the process may end, a rerun records the task as time_limit
  kAgain,   ///< the task had overrun before and did so again: the marker stays, the process must not restart
};

/// Called by the watchdog (another thread) when a run has been past its
/// deadline for its grace: writes the task's marker "elapsed_s=<s>"
/// (WriteFileAtomically: a temporary, renamed) and says in `line` what
/// overran ("cvode/klu rtol 1e-3 stayed inside one library call 25.1 s
/// after its start, past --time-limit 20 s").
/// @return kNoTask when no task is named; kMarked; kAgain for a task run
///   past its deadline already (RunJournalledTask), which must not loop
inline OverrunMark MarkOverrun(std::string* line) {
  const std::lock_guard<std::mutex> lock(internal::g_overrun_mutex);
  if (!internal::g_overrun_task) return OverrunMark::kNoTask;
  const internal::OverrunTask& t = *internal::g_overrun_task;
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t.start).count();
  *line = fmt::format("{} stayed inside one library call {:.1f} s after its start, past --time-limit {:g} s", t.what,
                      elapsed, t.limit_s);
  if (t.again) return OverrunMark::kAgain;
  try {
    WriteFileAtomically(t.marker, fmt::format("elapsed_s={:.6g}\n", elapsed), "--out");
  } catch (const std::exception& e) {
    *line += fmt::format(" (its marker was not written: {})", e.what());
    return OverrunMark::kAgain;  // without the marker a restart would enter the same call again
  }
  return OverrunMark::kMarked;
}

/// Runs `compute` (which returns a RunSummary or a MethodRun) as task
/// `index` of `journal`, named for the watchdog. A task whose run overran
/// its deadline inside one library call in an earlier process (its marker,
/// RecordJournal::Overrun) runs under a deadline passed already: its run
/// driver records time_limit before the first step (solver/run.cc,
/// sundials/sundials_common.cc), with the earlier process' seconds as its
/// wall time. `reference`: the reference task, whose runs go to worker
/// threads that do not share this thread's deadline; a marked reference
/// is not run again but recorded as time_limit at once.
template <class Compute>
auto RunJournalledTask(const RecordJournal& journal, long index, const std::string& what, double limit_s,
                       bool reference, Compute compute) -> decltype(compute()) {
  const std::optional<double> overran = journal.Overrun(index);
  const ScopedOverrunTask named(journal, index, what, limit_s, overran.has_value());
  if (!overran) return compute();
  decltype(compute()) r;
  if (reference) {
    r.status = RunStatus::kTimeLimit;
  } else {
    const ScopedDeadline passed(PassedDeadline());
    r = compute();
  }
  if (r.status == RunStatus::kTimeLimit) {
    r.wall_time_s = *overran;
    r.message = fmt::format("stayed inside one library call (a factorisation or an AMG setup, which no deadline "
                            "check reaches) past --time-limit {:g} s: the process was ended {:.1f} s after the "
                            "run's start and the sweep resumed from its journal",
                            limit_s, *overran);
  }
  return r;
}

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_OVERRUN_H_
