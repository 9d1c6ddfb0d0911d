// The kernel threads of a run on a machine that other processes share
// (docs/notes/performance.md, "Parallel regions on a busy machine").
//
// A parallel region ends at a barrier: when another process holds one of
// the cores, the team's thread on that core is descheduled for a scheduler
// time slice and the region waits for it, while its partner spins. With
// the many short regions of a step at 10^4 particles, two threads beside a
// busy process took 1.4-2.7x the time of one thread. Between steps, the
// budget measures the cores the other processes used over the last
// interval (/proc/stat's busy time less this process' /proc/self/stat) and
// runs the next steps on the cores that are left: min(requested,
// max(1, round(cores - others))). Every kernel gives the same bits on any
// number of OpenMP threads (verify/thread_budget_test.cc), so a change of
// team size changes timings only. The BLAS under CHOLMOD's supernodal
// factor (OpenBLAS' own pthreads, started from OMP_NUM_THREADS at load)
// keeps its threads: its factor's bits depend on their number.
#ifndef CLOTHBENCH_SOLVER_THREAD_BUDGET_H_
#define CLOTHBENCH_SOLVER_THREAD_BUDGET_H_

#include <chrono>
#include <functional>

namespace clothbench {

/// The CPU time used so far [s]: by the whole machine (every core's busy
/// time) and by this process (all its threads), at a steady-clock time.
struct CpuTimes {
  double wall = 0.0;  ///< steady clock [s]
  double machine = 0.0;
  double process = 0.0;
  bool valid = false;  ///< false where /proc cannot be read (then the budget keeps the requested threads)
};

/// Reads /proc/stat (the cores of this process' affinity mask) and
/// /proc/self/stat without allocating.
CpuTimes ReadCpuTimes();

/// Sets the OpenMP threads of a run's kernels between its steps, as
/// described above; restores the requested count when destroyed. A run
/// that starts within 2 s of another budget's decision (a sweep's next run,
/// a repeat's next timing) starts on that decision's threads.
class ThreadBudget {
 public:
  /// @param requested the run's threads; 0: omp_get_max_threads at its start
  /// @param cores the cores the process may use; 0: omp_get_num_procs
  /// @param probe the CPU times' source (tests plant a load here)
  explicit ThreadBudget(int requested = 0, int cores = 0, std::function<CpuTimes()> probe = ReadCpuTimes);
  ~ThreadBudget();
  ThreadBudget(const ThreadBudget&) = delete;
  ThreadBudget& operator=(const ThreadBudget&) = delete;

  /// Called between steps: after each interval of at least kInterval wall
  /// time, the other processes' cores over it decide the next steps' threads.
  void Update();
  /// Forces the next Update to measure (tests).
  void ExpireInterval() { last_ = Clock::now() - 2 * kInterval; }

  int threads() const { return threads_; }
  /// The fewest threads any step of the run used.
  int fewest() const { return fewest_; }

  /// The interval of the measurement: 10 of /proc's 100 Hz ticks per core.
  static constexpr std::chrono::milliseconds kInterval{100};

 private:
  using Clock = std::chrono::steady_clock;
  void SetThreads(int threads);
  int requested_, cores_, threads_, fewest_;
  bool shared_ = false;  ///< reads /proc: starts on, and leaves, the process' last decision
  std::function<CpuTimes()> probe_;
  CpuTimes before_;
  Clock::time_point last_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_THREAD_BUDGET_H_
