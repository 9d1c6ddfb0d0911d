#include "model/output_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <string_view>
#include <utility>

#include <fmt/format.h>

#include "model/scene.h"

namespace clothbench {
namespace {

struct InputFile {
  dev_t dev;
  ino_t ino;
  std::string path;  // absolute, lexically normal
};

std::mutex& InputsMutex() {
  static std::mutex m;
  return m;
}
std::vector<InputFile>& Inputs() {
  static std::vector<InputFile> inputs;
  return inputs;
}

// The absolute, lexically normal form of `path` with its existing part's
// links resolved (weakly_canonical); `path` itself if that fails.
std::string Normal(const std::string& path) {
  std::error_code ec;
  std::filesystem::path p = std::filesystem::weakly_canonical(path, ec);
  if (ec) p = std::filesystem::absolute(path, ec).lexically_normal();
  return ec ? path : p.string();
}

// "is a symbolic link", "is a FIFO", … for a file that is not regular.
std::string KindOf(mode_t mode) {
  if (S_ISLNK(mode)) return "is a symbolic link";
  if (S_ISDIR(mode)) return "is a folder";
  if (S_ISFIFO(mode)) return "is a FIFO";
  if (S_ISCHR(mode) || S_ISBLK(mode)) return "is a device";
  if (S_ISSOCK(mode)) return "is a socket";
  return "is not a regular file";
}

OutputRefused Refuse(const std::string& option, const std::string& path, const std::string& rule) {
  return OutputRefused(fmt::format("{}: \"{}\" {}", option, EscapeControl(path), rule));
}

// Refuses `path` if it exists and is not a regular file (not followed).
void RequireAbsentOrRegular(const std::string& path, const std::string& option, const std::string& what) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return;
    throw Refuse(option, path, fmt::format("cannot be used: {}", std::strerror(errno)));
  }
  if (!S_ISREG(st.st_mode))
    throw Refuse(option, path, fmt::format("{}{}; an output is written only over a regular file, never through a link",
                                           what, KindOf(st.st_mode)));
}

// The project's own bookkeeping files: a writer's lock "<out>.lock", its
// temporaries "<target>.tmp", a sweep's journal "<out>.journal" (a folder
// of bench_integrators, a file of stress_stability) and everything inside
// a journal folder. Another command given one of them as its output would
// replace a running command's lock or journal (its file deleted when that
// command finishes, or its resume broken). "" if `normal` (absolute,
// links of its existing part resolved) is none of them, else the rule.
std::string ProjectFileRule(const std::string& normal) {
  const std::filesystem::path p(normal);
  const std::string name = p.filename().string();
  static constexpr std::pair<std::string_view, std::string_view> kOwned[] = {
      {".lock", "lock file"}, {".tmp", "temporary file"}, {".journal", "journal"}, {".overrun", "journal entry"}};
  for (const auto& [suffix, what] : kOwned)
    if (name.ends_with(suffix))
      return fmt::format("names a {} of clothbench (a name ending in \"{}\"), which only its writer creates and "
                         "removes",
                         what, suffix);
  for (std::filesystem::path folder = p.parent_path(); !folder.empty() && folder != folder.root_path();
       folder = folder.parent_path())
    if (folder.filename().string().ends_with(".journal"))
      return fmt::format("lies inside the journal \"{}\" of another output, which only its sweep writes and removes",
                         EscapeControl(folder.string()));
  return "";
}

}  // namespace

void NoteInputFile(const std::string& path) {
  struct stat st {};
  if (path.empty() || ::stat(path.c_str(), &st) != 0) return;
  const std::string normal = Normal(path);
  std::lock_guard<std::mutex> guard(InputsMutex());
  for (const InputFile& in : Inputs())
    if (in.dev == st.st_dev && in.ino == st.st_ino && in.path == normal) return;  // noted before
  Inputs().push_back({st.st_dev, st.st_ino, normal});
}

void ClearInputFiles() {
  std::lock_guard<std::mutex> guard(InputsMutex());
  Inputs().clear();
}

std::string TemporaryOf(const std::string& target) { return target + ".tmp"; }

void CheckOutputTarget(const std::string& target, const std::string& option, const std::vector<std::string>& others) {
  if (target.empty()) throw OutputRefused(fmt::format("{}: must not be empty", option));
  RequireAbsentOrRegular(target, option, "");
  RequireAbsentOrRegular(TemporaryOf(target), option, "(its temporary) ");
  struct stat st {};
  const bool exists = ::stat(target.c_str(), &st) == 0;
  const std::string normal = Normal(target);
  if (const std::string rule = ProjectFileRule(normal); !rule.empty()) throw Refuse(option, target, rule);
  {
    std::lock_guard<std::mutex> guard(InputsMutex());
    for (const InputFile& in : Inputs())
      if ((exists && in.dev == st.st_dev && in.ino == st.st_ino) || in.path == normal)
        throw Refuse(option, target, fmt::format("is an input of this command (\"{}\"); writing it would destroy it",
                                                 EscapeControl(in.path)));
  }
  for (const std::string& other : others) {
    if (other.empty()) continue;
    struct stat so {};
    if ((exists && ::stat(other.c_str(), &so) == 0 && so.st_dev == st.st_dev && so.st_ino == st.st_ino) ||
        Normal(other) == normal)
      throw Refuse(option, target, fmt::format("is also another output of this command (\"{}\")", EscapeControl(other)));
  }
}

void FreeTemporaryName(const std::string& target, const std::string& option) {
  const std::string tmp = TemporaryOf(target);
  RequireAbsentOrRegular(tmp, option, "(its temporary) ");
  ::unlink(tmp.c_str());  // a regular leftover of a killed writer (the caller holds the output's lock)
}

int CreateTemporary(const std::string& target, const std::string& option) {
  const std::string tmp = TemporaryOf(target);
  FreeTemporaryName(target, option);
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0644);
  if (fd < 0) {
    const int err = errno;
    if (err == EEXIST || err == ELOOP) RequireAbsentOrRegular(tmp, option, "(its temporary) ");
    throw std::runtime_error(fmt::format("{}: \"{}\": creating the temporary file failed: {}", option,
                                         EscapeControl(target), std::strerror(err)));
  }
  return fd;
}

void CommitTemporary(const std::string& target, const std::string& option) {
  const std::string tmp = TemporaryOf(target);
  try {
    RequireAbsentOrRegular(target, option, "");
  } catch (...) {
    ::unlink(tmp.c_str());
    throw;
  }
  if (::rename(tmp.c_str(), target.c_str()) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    throw std::runtime_error(fmt::format("{}: \"{}\": renaming the temporary file failed: {}", option,
                                         EscapeControl(target), std::strerror(err)));
  }
}

void WriteFileAtomically(const std::string& target, std::string_view bytes, const std::string& option) {
  const std::string tmp = TemporaryOf(target);
  const int fd = CreateTemporary(target, option);
  const auto fail = [&](const char* what, int err) {
    ::close(fd);
    ::unlink(tmp.c_str());
    return std::runtime_error(
        fmt::format("{}: \"{}\": {} failed: {}", option, EscapeControl(target), what, std::strerror(err)));
  };
  for (std::size_t done = 0; done < bytes.size();) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) throw fail("writing", n < 0 ? errno : EIO);
    done += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) throw fail("writing", errno);
  if (::close(fd) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    throw std::runtime_error(
        fmt::format("{}: \"{}\": writing failed: {}", option, EscapeControl(target), std::strerror(err)));
  }
  CommitTemporary(target, option);
}

}  // namespace clothbench
