// Interruption by SIGINT / SIGTERM: the executables' signal handlers record
// the signal; the step loops (after each accepted step) and the result
// writer (between frames) check it and throw Interrupted, so the run stops
// after the current step and unwinding removes the result file's ".tmp".
// Lives in model/, the lowest layer both solver/ and results/ use.
#ifndef CLOTHBENCH_MODEL_INTERRUPT_H_
#define CLOTHBENCH_MODEL_INTERRUPT_H_

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>

namespace clothbench {

/// Thrown where an interruption is noticed; `signal` is the signal number.
struct Interrupted : std::runtime_error {
  explicit Interrupted(int sig) : std::runtime_error("interrupted by signal " + std::to_string(sig)), signal(sig) {}
  int signal;
};

namespace internal {
inline std::atomic<int> g_interrupt_signal{0};  // lock-free: safe to store from a signal handler
}  // namespace internal

/// Records signal `sig` (async-signal-safe: one atomic store).
inline void RequestInterrupt(int sig) { internal::g_interrupt_signal.store(sig, std::memory_order_relaxed); }

/// Whether a signal was recorded (for loops that must clean up before
/// ThrowIfInterrupted).
inline bool InterruptRequested() { return internal::g_interrupt_signal.load(std::memory_order_relaxed) != 0; }

/// @throws Interrupted if a signal was recorded.
inline void ThrowIfInterrupted() {
  if (const int sig = internal::g_interrupt_signal.load(std::memory_order_relaxed)) throw Interrupted(sig);
}

// The wall-clock deadline of the run on this thread (--time-limit): the run
// drivers check it after each step, the loops inside a step (the PCG's
// iterations, XPBD's substeps) before each pass, so that a run stops within
// one iteration of its limit, not one step.
namespace internal {
inline thread_local std::chrono::steady_clock::time_point g_deadline = std::chrono::steady_clock::time_point::max();
// The deadlines of the runs in progress on every thread, for a watchdog
// that sees a run stay inside one library call past its deadline.
inline std::mutex g_active_deadlines_mutex;
inline std::multiset<std::chrono::steady_clock::time_point> g_active_deadlines;
}  // namespace internal

// How long the process has been stopped (SIGSTOP, a suspended job): the
// watchdog of the executables (bench/signals.h) ticks every 20 ms
// (AccountStop); a gap between two ticks of more than kStopGap, or one that
// ends after a SIGCONT (NoteContinued, from its handler), is time the
// process did not run, added to the total. A run reads the total since its
// outermost deadline started, a gap the watchdog has not ticked over yet
// included (the run's thread may resume before the watchdog's).
namespace internal {
inline std::atomic<bool> g_continued{false};       // SIGCONT since the watchdog's last tick
inline std::atomic<long long> g_watch_tick_ns{0};  // the watchdog's last tick (steady clock) [ns]; 0: none
inline std::atomic<long long> g_stopped_ns{0};
inline thread_local long long g_stopped_ns_at_run_start = 0;
inline constexpr long long kStopGapNs = 500'000'000;  // 25 ticks: not a scheduling delay
inline long long SteadyNs(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(t.time_since_epoch()).count();
}
}  // namespace internal

/// Records that the process was continued (async-signal-safe: one atomic store).
inline void NoteContinued() { internal::g_continued.store(true, std::memory_order_relaxed); }

/// The watchdog's tick at `now`: a gap since its last tick longer than
/// kStopGapNs, or any gap after a SIGCONT, is added to the process' stopped
/// time. @return whether it was
inline bool AccountStop(std::chrono::steady_clock::time_point now) {
  const long long now_ns = internal::SteadyNs(now);
  const long long last = internal::g_watch_tick_ns.exchange(now_ns);
  const bool continued = internal::g_continued.exchange(false);
  if (last == 0 || (!continued && now_ns - last < internal::kStopGapNs)) return false;
  internal::g_stopped_ns.fetch_add(now_ns - last, std::memory_order_relaxed);
  return true;
}

/// The time [s] the process was stopped since this thread's run started
/// (its outermost ScopedDeadline), a stop the watchdog has not ticked
/// over yet included: a deadline may pass while the process is stopped.
inline double StoppedSecondsOfRun() {
  long long ns = internal::g_stopped_ns.load(std::memory_order_relaxed) - internal::g_stopped_ns_at_run_start;
  const long long tick = internal::g_watch_tick_ns.load(std::memory_order_relaxed);
  const long long pending = tick != 0 ? internal::SteadyNs(std::chrono::steady_clock::now()) - tick : 0;
  if (internal::g_continued.load(std::memory_order_relaxed) || pending >= internal::kStopGapNs) ns += pending;
  return 1e-9 * static_cast<double>(ns);
}

/// Sets this thread's deadline to `deadline` (or keeps an earlier one) for
/// the object's lifetime, and lists it among the runs in progress
/// (EarliestActiveDeadline).
class ScopedDeadline {
 public:
  explicit ScopedDeadline(std::chrono::steady_clock::time_point deadline) : saved_(internal::g_deadline) {
    if (saved_ == std::chrono::steady_clock::time_point::max())
      internal::g_stopped_ns_at_run_start = internal::g_stopped_ns.load(std::memory_order_relaxed);
    internal::g_deadline = std::min(deadline, saved_);
    if (internal::g_deadline != std::chrono::steady_clock::time_point::max()) {
      const std::lock_guard<std::mutex> lock(internal::g_active_deadlines_mutex);
      // A deadline passed already (PassedDeadline) counts from now.
      listed_ = internal::g_active_deadlines.insert(std::max(internal::g_deadline, std::chrono::steady_clock::now()));
      is_listed_ = true;
    }
  }
  ~ScopedDeadline() {
    if (is_listed_) {
      const std::lock_guard<std::mutex> lock(internal::g_active_deadlines_mutex);
      internal::g_active_deadlines.erase(listed_);
    }
    internal::g_deadline = saved_;
  }
  ScopedDeadline(const ScopedDeadline&) = delete;
  ScopedDeadline& operator=(const ScopedDeadline&) = delete;

 private:
  std::chrono::steady_clock::time_point saved_;
  std::multiset<std::chrono::steady_clock::time_point>::iterator listed_;
  bool is_listed_ = false;
};

/// The earliest deadline of the runs in progress on any thread (max if no
/// run with a deadline is in progress; a run started past its deadline
/// lists its start). A run past it that has not ended
/// is inside work that checks no deadline: one library call (a KLU or
/// CHOLMOD factorisation, a BoomerAMG setup). bench/signals.h's watchdog
/// reads it.
inline std::chrono::steady_clock::time_point EarliestActiveDeadline() {
  const std::lock_guard<std::mutex> lock(internal::g_active_deadlines_mutex);
  return internal::g_active_deadlines.empty() ? std::chrono::steady_clock::time_point::max()
                                              : *internal::g_active_deadlines.begin();
}

/// A deadline that has passed already: the run of a task whose library
/// call overran its deadline in an earlier process (harness/sweep.h,
/// RecordJournal::Overrun) runs under it, so that it records time_limit
/// before its first step instead of entering the call again.
inline std::chrono::steady_clock::time_point PassedDeadline() { return std::chrono::steady_clock::time_point::min(); }

/// The deadline `limit_s` seconds [s] after `start`; none (max) for a limit
/// ≤ 0, and at most 10⁸ s ahead (the clock's range is ~3·10¹¹ s).
inline std::chrono::steady_clock::time_point RunDeadline(std::chrono::steady_clock::time_point start, double limit_s) {
  if (!(limit_s > 0.0)) return std::chrono::steady_clock::time_point::max();
  return start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                     std::chrono::duration<double>(std::min(limit_s, 1e8)));
}

// A flag that ends the runs of this thread as a passed deadline does: set
// by another thread when the run is no longer needed (a speculative run of
// harness/side_by_side.h).
namespace internal {
inline thread_local const std::atomic<bool>* g_cancel = nullptr;
}  // namespace internal

/// Makes `cancel` end this thread's runs (a deadline that another thread
/// sets) for the object's lifetime.
class ScopedCancel {
 public:
  explicit ScopedCancel(const std::atomic<bool>* cancel) : saved_(internal::g_cancel) { internal::g_cancel = cancel; }
  ~ScopedCancel() { internal::g_cancel = saved_; }
  ScopedCancel(const ScopedCancel&) = delete;
  ScopedCancel& operator=(const ScopedCancel&) = delete;

 private:
  const std::atomic<bool>* saved_;
};

/// Whether this thread's runs were cancelled (ScopedCancel).
inline bool CancelRequested() {
  const std::atomic<bool>* c = internal::g_cancel;
  return c != nullptr && c->load(std::memory_order_relaxed);
}

/// True once this thread's deadline has passed (false without one), once
/// its runs were cancelled, or once SIGINT/SIGTERM arrived: the loops inside
/// a step (the PCG's iterations, VBD's, PD's and XPBD's iterations and
/// substeps, the setups) end at any, and the step loop then throws
/// Interrupted (ThrowIfInterrupted) instead of recording a time limit.
inline bool DeadlinePassed() {
  if (InterruptRequested() || CancelRequested()) return true;
  return internal::g_deadline != std::chrono::steady_clock::time_point::max() &&
         std::chrono::steady_clock::now() >= internal::g_deadline;
}

}  // namespace clothbench

#endif  // CLOTHBENCH_MODEL_INTERRUPT_H_
