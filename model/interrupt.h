// Interruption by SIGINT / SIGTERM: the executables' signal handlers record
// the signal; the step loops (after each accepted step) and the result
// writer (between frames) check it and throw Interrupted, so the run stops
// after the current step and unwinding removes the result file's ".tmp".
// Lives in model/, the lowest layer both solver/ and results/ use.
#ifndef CLOTHBENCH_MODEL_INTERRUPT_H_
#define CLOTHBENCH_MODEL_INTERRUPT_H_

#include <atomic>
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

/// @throws Interrupted if a signal was recorded.
inline void ThrowIfInterrupted() {
  if (const int sig = internal::g_interrupt_signal.load(std::memory_order_relaxed)) throw Interrupted(sig);
}

}  // namespace clothbench

#endif  // CLOTHBENCH_MODEL_INTERRUPT_H_
