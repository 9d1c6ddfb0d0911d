// SIGINT / SIGTERM for the executables: the handler only records the signal
// (model/interrupt.h); the run stops after the current step, the result
// file's .tmp is removed while unwinding, and Main exits 128 + signal
// (130 for SIGINT, 143 for SIGTERM) with one line.
#ifndef CLOTHBENCH_BENCH_SIGNALS_H_
#define CLOTHBENCH_BENCH_SIGNALS_H_

#include <csignal>

#include "model/interrupt.h"

namespace clothbench {

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
}

inline const char* SignalName(int sig) { return sig == SIGINT ? "SIGINT" : sig == SIGTERM ? "SIGTERM" : "a signal"; }

}  // namespace clothbench

#endif  // CLOTHBENCH_BENCH_SIGNALS_H_
