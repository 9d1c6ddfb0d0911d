// A one-line progress display on stderr for long runs (Debian packages no
// C++ progress-bar library): the method, its h, simulated against final
// time, elapsed and estimated remaining wall time. Shown only when stderr is
// a terminal and a run has taken more than 2 s; redrawn at most 5 times a
// second; the line is cleared when the run ends.
#ifndef CLOTHBENCH_HARNESS_PROGRESS_H_
#define CLOTHBENCH_HARNESS_PROGRESS_H_

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <string>

#include <fmt/format.h>

#include "solver/progress.h"

namespace clothbench {

class TerminalProgress : public ProgressSink {
 public:
  using Clock = std::chrono::steady_clock;

  /// @param enabled false (--quiet) or stderr not a terminal: shows nothing.
  explicit TerminalProgress(bool enabled) : enabled_(enabled && ::isatty(STDERR_FILENO) == 1) {
    if (enabled_) SetProgressSink(this);
  }
  ~TerminalProgress() override {
    Finish();
    if (enabled_) SetProgressSink(nullptr);
  }
  TerminalProgress(const TerminalProgress&) = delete;
  TerminalProgress& operator=(const TerminalProgress&) = delete;

  /// A new run: `what` names it ("bdf2/newton h = 0.01 s"), up to t_end [s].
  void Start(const std::string& what, double t_end) {
    Finish();
    what_ = what;
    t_end_ = t_end;
    start_ = last_ = Clock::now();
  }

  /// Clears the line if one was drawn.
  void Finish() {
    if (drawn_) std::fputs("\r\x1b[K", stderr), std::fflush(stderr);
    drawn_ = false;
  }

  void Update(double t) override {
    const Clock::time_point now = Clock::now();
    const double elapsed = std::chrono::duration<double>(now - start_).count();
    if (elapsed < 2.0 || std::chrono::duration<double>(now - last_).count() < 0.2) return;
    last_ = now;
    const double fraction = t_end_ > 0.0 ? t / t_end_ : 0.0;
    const std::string eta = fraction > 0.0 ? fmt::format("{:.0f} s", elapsed * (1.0 - fraction) / fraction) : "?";
    fmt::print(stderr, "\r{}: t = {:.4g} / {:g} s ({:.0f} %), {:.0f} s elapsed, ~{} left\x1b[K", what_, t, t_end_,
               100.0 * fraction, elapsed, eta);
    std::fflush(stderr);
    drawn_ = true;
  }

 private:
  bool enabled_;
  bool drawn_ = false;
  std::string what_;
  double t_end_ = 0.0;
  Clock::time_point start_, last_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_PROGRESS_H_
