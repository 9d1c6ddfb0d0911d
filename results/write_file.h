// The one writer of whole files (results/, harness/, bench/): a temporary,
// fsync'ed and renamed, removed on every failure path.
#ifndef CLOTHBENCH_RESULTS_WRITE_FILE_H_
#define CLOTHBENCH_RESULTS_WRITE_FILE_H_

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <string>
#include <string_view>

#include <fmt/format.h>

#include "model/scene.h"

namespace clothbench {

/// Writes `bytes` to `path` as the project's one writer of whole files:
/// through `<path>.tmp` (created exclusively, written, fsync'ed, closed)
/// and a rename over `path`; the temporary is removed on every failure
/// path. The caller holds `<path>.lock` (harness/output_lock.h) from
/// before its computation, whose probe refused an existing `path` that is
/// not a regular file. Used for contact_replay's states, the XDMF files
/// and the Fig. 4.3 series; result files go through ResultFile (HDF5),
/// which writes its own temporary the same way.
/// @throws std::runtime_error "<option>: <path>: <errno text>" (a full
///   disk: "No space left on device") if a step fails
inline void WriteFileAtomically(const std::string& path, std::string_view bytes, const std::string& option) {
  const std::string tmp = path + ".tmp";
  const auto fail = [&](const char* what, int err) {
    ::unlink(tmp.c_str());
    return std::runtime_error(
        fmt::format("{}: \"{}\": {} failed: {}", option, EscapeControl(path), what, std::strerror(err)));
  };
  ::unlink(tmp.c_str());  // a leftover of a process that was killed (the caller holds the lock)
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOFOLLOW, 0644);
  if (fd < 0) throw fail("creating the temporary file", errno);
  for (std::size_t done = 0; done < bytes.size();) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = n < 0 ? errno : EIO;
      ::close(fd);
      throw fail("writing", err);
    }
    done += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) {
    const int err = errno;
    ::close(fd);
    throw fail("writing", err);
  }
  if (::close(fd) != 0) throw fail("writing", errno);
  if (::rename(tmp.c_str(), path.c_str()) != 0) throw fail("renaming the temporary file", errno);
}

}  // namespace clothbench

#endif  // CLOTHBENCH_RESULTS_WRITE_FILE_H_
