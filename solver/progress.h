// Progress of the run in flight, for a display such as harness/progress.h.
// The step loop (RunStepper, for every row, SUNDIALS' too) reports the
// simulated time after every accepted step; without a sink that is one
// relaxed atomic load (and one for the interrupt flag).
#ifndef CLOTHBENCH_SOLVER_PROGRESS_H_
#define CLOTHBENCH_SOLVER_PROGRESS_H_

#include <atomic>

#include "model/interrupt.h"

namespace clothbench {

/// Receives the simulated time t [s] after each accepted step.
class ProgressSink {
 public:
  virtual ~ProgressSink() = default;
  virtual void Update(double t) = 0;
};

namespace internal {
inline std::atomic<ProgressSink*> g_progress_sink{nullptr};
inline thread_local bool g_progress_muted = false;
}  // namespace internal

/// Keeps this thread's steps from the sink for the object's lifetime: the
/// display follows one run, that of the main thread.
class ScopedProgressMute {
 public:
  ScopedProgressMute() : saved_(internal::g_progress_muted) { internal::g_progress_muted = true; }
  ~ScopedProgressMute() { internal::g_progress_muted = saved_; }
  ScopedProgressMute(const ScopedProgressMute&) = delete;
  ScopedProgressMute& operator=(const ScopedProgressMute&) = delete;

 private:
  bool saved_;
};

/// Installs `sink` for the process (nullptr: none). Not owned.
inline void SetProgressSink(ProgressSink* sink) { internal::g_progress_sink.store(sink, std::memory_order_relaxed); }

/// Called by the step loops after each accepted step at simulated time t [s].
/// @throws Interrupted if SIGINT or SIGTERM arrived (model/interrupt.h): the
/// run stops after the current step.
inline void ReportProgress(double t) {
  ThrowIfInterrupted();
  if (internal::g_progress_muted) return;
  if (ProgressSink* s = internal::g_progress_sink.load(std::memory_order_relaxed)) s->Update(t);
}

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_PROGRESS_H_
