#include "results/contained_read.h"

#include <poll.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include <fmt/format.h>

#include "model/interrupt.h"
#include "model/scene.h"
#include "results/run_records.h"
#include "results/run_table.h"

namespace clothbench {

void ReadWholeFile(const ResultReader& f) {
  ValidateResultFile(f);
  ReadValidatedFile(f);
}

void ReadValidatedFile(const ResultReader& f) {
  const RunTable t = ReadRunTable(f);
  if (std::FILE* null = std::fopen("/dev/null", "w")) {
    PrintRunTable(null, t);
    if (t.work_precision) PrintWorkPrecision(null, *t.work_precision);
    std::fclose(null);
  }
  std::vector<std::string> groups = {"/"};
  for (const char* top : {"/scene", "/reference", "/runs", "/stress", "/table", "/work_precision"})
    if (f.Exists(top)) groups.push_back(top);
  if (f.Exists("/runs"))
    for (const std::string& id : f.Children("/runs")) groups.push_back("/runs/" + id);
  for (const char* top : {"/stress", "/table"})
    if (f.Exists(top))
      for (const std::string& c : f.Children(top)) {
        groups.push_back(std::string(top) + "/" + c);
        for (const std::string& s : f.Children(std::string(top) + "/" + c))
          groups.push_back(std::string(top) + "/" + c + "/" + s);
      }
  if (f.Exists("/scene/obstacles"))
    for (const std::string& k : f.Children("/scene/obstacles")) groups.push_back("/scene/obstacles/" + k);
  if (f.Exists("/scene/faces")) f.Ints("/scene/faces");
  if (f.Exists("/scene/toml")) f.Text("/scene/toml");
  for (const std::string& g : groups) {
    f.Attributes(g);
    for (const char* name : {"positions", "velocities", "positions_ends", "velocities_ends"}) {
      const std::string d = g + "/" + name;
      if (!f.Exists(d)) continue;
      const std::vector<std::size_t> shape = f.Shape(d);
      for (std::size_t k = 0; !shape.empty() && k < shape[0]; ++k) f.Frame(d, k);
    }
    if (f.Exists(g + "/step_stats")) f.StepStats(g + "/step_stats");
    if (f.Exists(g + "/times")) f.Doubles(g + "/times");
  }
}

double ContainedReadDeadline(const std::string& path) {
  struct stat st {};
  const double bytes = ::stat(path.c_str(), &st) == 0 ? static_cast<double>(st.st_size) : 0.0;
  return 20.0 + bytes / 10e6;
}

void CheckReadableInChild(const std::string& path, double timeout_s) {
  if (!(timeout_s > 0.0)) timeout_s = ContainedReadDeadline(path);
  int fds[2];
  if (::pipe(fds) != 0) throw std::runtime_error(fmt::format("{}: cannot create a pipe: {}", path, std::strerror(errno)));
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    throw std::runtime_error(fmt::format("{}: cannot start a process to read it: {}", path, std::strerror(errno)));
  }
  if (pid == 0) {  // the child: read, report a refusal through the pipe, never return
    ::close(fds[0]);
    for (int sig : {SIGSEGV, SIGBUS, SIGABRT, SIGILL, SIGFPE}) std::signal(sig, SIG_DFL);
    int code = 0;
    std::string message;
    try {
      const ResultReader f(path);
      ReadWholeFile(f);
    } catch (const ResultError& e) {
      message = e.what();
      code = 2;
    } catch (const std::bad_alloc&) {
      message = fmt::format("{}: a dimension or size needs more memory than the machine has (a damaged file)", path);
      code = 2;
    } catch (const std::exception& e) {
      message = fmt::format("{}: {}", path, e.what());
      code = 3;
    }
    for (std::size_t done = 0; done < message.size();) {
      const ssize_t n = ::write(fds[1], message.data() + done, message.size() - done);
      if (n <= 0) break;
      done += static_cast<std::size_t>(n);
    }
    ::_exit(code);
  }
  ::close(fds[1]);
  // The child's refusal, until it closes the pipe (exits) or the time is up
  // (HDF5 looping on a damaged header): then it is killed.
  std::string message;
  char buf[4096];
  bool timed_out = false;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      timed_out = true;
      break;
    }
    if (InterruptRequested()) break;  // Ctrl-C: the child is killed, Interrupted thrown below
    pollfd p{fds[0], POLLIN, 0};
    const int ready = ::poll(&p, 1, static_cast<int>(std::min<long long>(left.count(), 1000)));
    if (ready < 0 && errno == EINTR) continue;
    if (ready <= 0) continue;
    const ssize_t n = ::read(fds[0], buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    message.append(buf, static_cast<std::size_t>(n));
  }
  ::close(fds[0]);
  const bool interrupted = InterruptRequested() && !timed_out;
  if (timed_out || interrupted) ::kill(pid, SIGKILL);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (interrupted) ThrowIfInterrupted();
  if (timed_out)
    throw ResultError(EscapeControl(fmt::format("{}: reading it did not end within {:g} s (the HDF5 library looping "
                                                "on a damaged file?)",
                                                path, timeout_s)));
  if (WIFSIGNALED(status))
    throw ResultError(EscapeControl(fmt::format("{}: reading it crashed the HDF5 library ({}): the file is damaged "
                                                "although its integrity block matches (edited and signed again?)",
                                                path, strsignal(WTERMSIG(status)))));
  if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return;
  if (WIFEXITED(status) && WEXITSTATUS(status) == 2) throw ResultError(EscapeControl(message));
  throw std::runtime_error(message.empty() ? fmt::format("{}: the process reading it failed", path) : message);
}

}  // namespace clothbench
