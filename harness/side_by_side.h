// Runs that no table times, side by side: a reference's checks (its error
// estimate at rtol/10 and the cross-check's refinement, docs/notes/collisions.md
// "The contact reference"). Two runs at a time on one kernel thread each
// finish sooner than one after the other on two: at 10⁴ particles two
// concurrent BDF(2) runs took 32 s each against 26 s alone on two threads.
#ifndef CLOTHBENCH_HARNESS_SIDE_BY_SIDE_H_
#define CLOTHBENCH_HARNESS_SIDE_BY_SIDE_H_

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

#include "solver/run.h"

namespace clothbench {

/// A queue of runs worked off in submission order by `workers` threads,
/// each with one kernel thread (SetKernelThreads(1)) and no progress
/// display. With 0 workers a run is computed on the calling thread when it
/// is taken. A run's result depends only on its inputs and the one kernel
/// thread, not on what ran beside it.
class SideBySide {
 public:
  /// @param workers 0 (computed when taken, on the caller's kernel threads) or more
  explicit SideBySide(int workers);
  /// Cancels every run not taken and joins the workers.
  ~SideBySide();
  SideBySide(const SideBySide&) = delete;
  SideBySide& operator=(const SideBySide&) = delete;

  /// Queues `run`. @return its index, 0, 1, … in submission order
  std::size_t Submit(std::function<RunSummary()> run);
  /// Waits for run `i` (computing it here without workers) and moves it
  /// out; a cancelled run that never started has status kTimeLimit.
  /// @throws what the run threw (Interrupted on SIGINT/SIGTERM)
  RunSummary Take(std::size_t i);
  /// Cancels runs `first` … `last` − 1 (default: to the end): queued ones
  /// do not start, running ones end at their next deadline check
  /// (model/interrupt.h, ScopedCancel).
  void Cancel(std::size_t first, std::size_t last = static_cast<std::size_t>(-1));

 private:
  enum class State { kQueued, kRunning, kDone };
  struct Task {
    std::function<RunSummary()> run;
    State state = State::kQueued;
    std::atomic<bool> cancel{false};
    RunSummary result;
    std::exception_ptr error;
  };
  void Work();
  void Compute(Task& t);

  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<Task> tasks_;  // stable addresses
  std::size_t next_ = 0;    // the first queued task
  bool stopping_ = false;
  std::vector<std::thread> workers_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_SIDE_BY_SIDE_H_
