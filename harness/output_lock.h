// One writer per output: the executables that write a result file hold an
// exclusive lock on <out>.lock from before their first computation until
// they exit, so that two processes given the same --out cannot interleave
// their journals or replace each other's file.
#ifndef CLOTHBENCH_HARNESS_OUTPUT_LOCK_H_
#define CLOTHBENCH_HARNESS_OUTPUT_LOCK_H_

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "harness/cli_args.h"
#include "harness/sweep.h"
#include "model/output_file.h"

namespace clothbench {

/// Runs `probe` (a check that touches the file system or reads the
/// machine's state: a probe file created and removed, a folder, the free
/// memory) on rank 0 alone and throws its UsageError on every rank. Probes
/// of several ranks would collide (one rank's O_EXCL probe finds the
/// other's file) or disagree, and a rank that refused alone would return
/// while the others wait for its results in the sweep's gathers.
template <class Probe>
void ProbeOnRoot(const SweepComm& comm, Probe&& probe) {
  std::string why;
  if (comm.root()) {
    try {
      probe();
    } catch (const UsageError& e) {
      why = e.what();
    }
  }
  std::vector<long> failed{why.empty() ? 0L : 1L};
  comm.Broadcast(&failed);
  if (failed[0] != 0) throw UsageError(comm.root() ? why : std::string("refused on rank 0"));
}

namespace internal {
// The output locks this process holds (descriptor, device, inode), for a
// restart of the same command by execv (KeepOutputLocksAcrossExec).
struct HeldLock {
  int fd;
  dev_t dev;
  ino_t ino;
};
inline std::mutex g_held_locks_mutex;
inline std::vector<HeldLock> g_held_locks;
inline constexpr const char* kHeldLocksVariable = "CLOTHBENCH_HELD_LOCKS";

// The locks an earlier image of this process passed on through execv
// ("fd:dev:ino;…"), read once and removed from the environment, so that
// no child process inherits the variable.
inline std::vector<HeldLock>& InheritedLocks() {
  static std::vector<HeldLock> inherited = [] {
    std::vector<HeldLock> out;
    const char* v = std::getenv(kHeldLocksVariable);
    if (v == nullptr) return out;
    std::istringstream in(v);
    std::string item;
    while (std::getline(in, item, ';')) {
      long fd = -1;
      unsigned long long dev = 0, ino = 0;
      if (std::sscanf(item.c_str(), "%ld:%llu:%llu", &fd, &dev, &ino) == 3 && fd >= 0)
        out.push_back({static_cast<int>(fd), static_cast<dev_t>(dev), static_cast<ino_t>(ino)});
    }
    ::unsetenv(kHeldLocksVariable);
    return out;
  }();
  return inherited;
}
}  // namespace internal

/// Before the watchdog restarts the command in the same process (execv,
/// bench/signals.h): every held output lock's descriptor stays open across
/// the exec and is named in the environment, so that the restarted
/// command takes over its locks (OutputLock) instead of releasing them
/// for a moment in which another command could take the same --out.
/// Called on the watchdog's thread, just before execv.
inline void KeepOutputLocksAcrossExec() {
  const std::lock_guard<std::mutex> lock(internal::g_held_locks_mutex);
  std::string v;
  for (const internal::HeldLock& h : internal::g_held_locks) {
    const int flags = ::fcntl(h.fd, F_GETFD);
    if (flags < 0 || ::fcntl(h.fd, F_SETFD, flags & ~FD_CLOEXEC) != 0) continue;
    v += fmt::format("{}:{}:{};", h.fd, static_cast<unsigned long long>(h.dev), static_cast<unsigned long long>(h.ino));
  }
  ::setenv(internal::kHeldLocksVariable, v.c_str(), 1);
}

/// An exclusive flock(2) on `<out>.lock`, taken by rank 0 (which then
/// probes the output's paths, CheckOutputPaths) and held until destruction;
/// the kernel also releases it when the process ends in any other way. The file holds the holder's
/// pid, which a refused process names; it is removed on release (a process
/// that opened it just before checks, after locking, that the path still
/// names the file it locked, and starts over if not).
class OutputLock {
 public:
  /// @throws UsageError (exit 2) on every rank if another process holds the
  /// lock (naming --out and the pid), the lock file cannot be created, or
  /// CheckOutputPaths refuses a path (its message on rank 0).
  /// @param journal_folder whether the command's journal <out>.journal is a
  /// folder (bench_integrators) or a file (stress_stability)
  OutputLock(const std::string& out, const SweepComm& comm, bool journal_folder = true) : path_(out + ".lock") {
    // One rank probes the paths (probes of several would collide) and locks.
    const std::string why = comm.root() ? Take(out, journal_folder) : std::string();
    std::vector<long> failed{why.empty() ? 0L : 1L};
    comm.Broadcast(&failed);
    if (failed[0] != 0)
      throw UsageError(comm.root() ? why : fmt::format("--out: \"{}\" refused on rank 0", out));
  }
  /// The same in a process without ranks (clothbench_inspect rerun, the
  /// Python module's write_results), the path named `option` in messages.
  /// @throws UsageError as above
  OutputLock(const std::string& out, bool journal_folder, std::string option)
      : path_(out + ".lock"), option_(std::move(option)) {
    const std::string why = Take(out, journal_folder);
    if (!why.empty()) throw UsageError(why);
  }
  ~OutputLock() { Release(); }
  OutputLock(const OutputLock&) = delete;
  OutputLock& operator=(const OutputLock&) = delete;

  /// Removes the lock file and releases the lock (idempotent): for the exit
  /// paths that leave by std::exit, before it.
  void Release() {
    if (fd_ < 0) return;
    {
      const std::lock_guard<std::mutex> lock(internal::g_held_locks_mutex);
      std::erase_if(internal::g_held_locks, [&](const internal::HeldLock& h) { return h.fd == fd_; });
    }
    ::unlink(path_.c_str());
    ::close(fd_);
    fd_ = -1;
  }

 private:
  // Locks and probes the paths: "" on success, else the refusal.
  std::string Take(const std::string& out, bool journal_folder) {
    // The lock first (its folder created), so that a second writer is
    // named as such, whatever the first one's files look like meanwhile.
    std::error_code ec;
    if (const auto folder = std::filesystem::path(out).parent_path(); !folder.empty())
      std::filesystem::create_directories(folder, ec);
    try {
      std::string why = Acquire(out);
      // Unless another writer holds the lock, the path checks name the
      // reason more precisely (a folder that cannot be created, a name
      // too long) than the failed lock file does.
      if (why.empty() || !held_by_other_) CheckOutputPaths(out, journal_folder, option_);
      return why;
    } catch (const UsageError& e) {
      Release();
      return e.what();
    }
  }

  // "" on success, else the refusal.
  std::string Acquire(const std::string& out) {
    for (int attempt = 0; attempt < 8; ++attempt) {
      int fd = ::open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW | O_NONBLOCK, 0644);
      if (fd < 0)
        return fmt::format("{}: cannot create the lock file \"{}\": {}", option_, path_, std::strerror(errno));
      struct stat st {};
      if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
        ::close(fd);
        return fmt::format("{}: the lock file \"{}\" is not a regular file", option_, path_);
      }
      // The lock this command held before the watchdog restarted it
      // (KeepOutputLocksAcrossExec): taken over, never released between.
      for (const internal::HeldLock& h : internal::InheritedLocks()) {
        struct stat held {};
        if (h.dev != st.st_dev || h.ino != st.st_ino || ::fstat(h.fd, &held) != 0 || held.st_dev != st.st_dev ||
            held.st_ino != st.st_ino)
          continue;
        ::close(fd);
        fd = h.fd;
        ::fcntl(fd, F_SETFD, FD_CLOEXEC);
        break;
      }
      if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
        char buf[32] = {};
        const ssize_t n = ::pread(fd, buf, sizeof(buf) - 1, 0);
        ::close(fd);
        const std::string pid = n > 0 ? std::string(buf, static_cast<std::size_t>(n)) : std::string("unknown");
        held_by_other_ = true;
        return fmt::format("{0}: \"{1}\" is being written by process {2} (it holds \"{3}\"); wait for it to end or "
                           "choose another {0}",
                           option_, out, EscapeControl(pid), path_);
      }
      // Still the file at the path (not one a releasing holder has just
      // removed)?
      struct stat now {};
      if (::stat(path_.c_str(), &now) != 0 || now.st_ino != st.st_ino || now.st_dev != st.st_dev) {
        ::close(fd);
        continue;
      }
      const std::string pid = std::to_string(::getpid());
      if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, pid.data(), pid.size(), 0) != static_cast<ssize_t>(pid.size())) {
        const int err = errno;
        ::unlink(path_.c_str());  // ours (locked): a full disk leaves no empty lock file behind
        ::close(fd);
        errno = err;
        return fmt::format("{}: cannot write the lock file \"{}\": {}", option_, path_, std::strerror(errno));
      }
      fd_ = fd;
      const std::lock_guard<std::mutex> lock(internal::g_held_locks_mutex);
      internal::g_held_locks.push_back({fd, st.st_dev, st.st_ino});
      return "";
    }
    return fmt::format("{}: the lock file \"{}\" kept being replaced by other processes", option_, path_);
  }

  std::string path_;
  std::string option_ = "--out";
  int fd_ = -1;
  bool held_by_other_ = false;  // Acquire failed because another process holds the lock
};

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_OUTPUT_LOCK_H_
