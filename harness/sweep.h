// What a sweep of independent cells (the stability maps, the rows of
// bench_integrators) needs to outgrow
// one machine and one sitting:
//  - SweepComm: MPI (Open MPI, or any MPI under Slurm's srun) when the
//    process was started by a launcher, else one rank without MPI at all;
//    cells are dealt round-robin over the ranks and their results summed
//    onto rank 0, which alone prints and writes.
//  - SweepJournal: `<out>.journal`, one line per finished cell appended as
//    it completes, so that an interrupted sweep rerun with the same
//    arguments computes only the missing cells; RecordJournal: the same for
//    cells that are whole runs, one file each.
// docs/notes/verification.md, "Sweeps on many machines, and resuming them".
#ifndef CLOTHBENCH_HARNESS_SWEEP_H_
#define CLOTHBENCH_HARNESS_SWEEP_H_

#include <fcntl.h>
// The C API only (Open MPI's and MPICH's mpi.h would pull in the deprecated
// C++ bindings, a library of their own).
#define OMPI_SKIP_MPICXX 1
#define MPICH_SKIP_MPICXX 1
#include <mpi.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <fstream>
#include <iterator>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "model/output_file.h"

#include "solver/stability_map.h"

#include "model/scene.h"

namespace clothbench {

/// Exit status of a sweep stopped by --max-cells / --max-runs before its
/// last cell (EX_TEMPFAIL of sysexits.h: rerun to continue).
inline constexpr int kExitPartial = 75;

/// True if a launcher started this process as one rank of a job: Open MPI's
/// mpirun (OMPI_COMM_WORLD_SIZE), PMIx launchers such as Slurm's srun
/// --mpi=pmix (PMIX_RANK) or PMI-1/2 ones such as MPICH's Hydra (PMI_SIZE).
inline bool LaunchedByMpi() {
  return std::getenv("OMPI_COMM_WORLD_SIZE") || std::getenv("PMIX_RANK") || std::getenv("PMI_SIZE");
}

class SweepComm {
 public:
  /// Initialises MPI only when LaunchedByMpi(); otherwise rank 0 of 1.
  SweepComm(int* argc, char*** argv) : mpi_(LaunchedByMpi()) {
    if (!mpi_) return;
    MPI_Init(argc, argv);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
  }
  ~SweepComm() {
    if (mpi_ && !aborted_) MPI_Finalize();
  }
  SweepComm(const SweepComm&) = delete;
  SweepComm& operator=(const SweepComm&) = delete;

  bool mpi() const { return mpi_; }
  int rank() const { return rank_; }
  int size() const { return size_; }
  bool root() const { return rank_ == 0; }
  /// Whether this rank computes cell `k` of the missing ones (round-robin).
  bool Owns(std::size_t k) const { return static_cast<int>(k % static_cast<std::size_t>(size_)) == rank_; }

  void Barrier() const {
    if (mpi_ && size_ > 1) MPI_Barrier(MPI_COMM_WORLD);
  }
  /// Element-wise sum over the ranks onto rank 0. Each cell is filled by
  /// exactly one rank and is 0 on the others, so the sum is that rank's
  /// value bit for bit.
  void SumToRoot(std::vector<double>* v) const {
    if (!mpi_ || size_ == 1) return;
    std::vector<double> out(v->size(), 0.0);
    MPI_Reduce(v->data(), out.data(), static_cast<int>(v->size()), MPI_DOUBLE, MPI_SUM, 0, MPI_COMM_WORLD);
    if (root()) *v = std::move(out);
  }
  void SumToRoot(std::vector<int32_t>* v) const {
    if (!mpi_ || size_ == 1) return;
    std::vector<int32_t> out(v->size(), 0);
    MPI_Reduce(v->data(), out.data(), static_cast<int>(v->size()), MPI_INT32_T, MPI_SUM, 0, MPI_COMM_WORLD);
    if (root()) *v = std::move(out);
  }
  /// Rank 0's `v` on every rank.
  void Broadcast(std::vector<long>* v) const {
    if (!mpi_ || size_ == 1) return;
    long n = static_cast<long>(v->size());
    MPI_Bcast(&n, 1, MPI_LONG, 0, MPI_COMM_WORLD);
    v->resize(static_cast<std::size_t>(n));
    MPI_Bcast(v->data(), static_cast<int>(n), MPI_LONG, 0, MPI_COMM_WORLD);
  }
  /// Rank 0's (index, bytes) records on every rank.
  void Broadcast(std::vector<std::pair<long, std::string>>* records) const {
    if (!mpi_ || size_ == 1) return;
    long count = static_cast<long>(records->size());
    MPI_Bcast(&count, 1, MPI_LONG, 0, MPI_COMM_WORLD);
    records->resize(static_cast<std::size_t>(count));
    for (auto& [index, bytes] : *records) {
      long head[2] = {index, static_cast<long>(bytes.size())};
      MPI_Bcast(head, 2, MPI_LONG, 0, MPI_COMM_WORLD);
      index = head[0];
      bytes.resize(static_cast<std::size_t>(head[1]));
      for (std::size_t at = 0; at < bytes.size(); at += kPiece)
        MPI_Bcast(bytes.data() + at, static_cast<int>(std::min(kPiece, bytes.size() - at)), MPI_BYTE, 0, MPI_COMM_WORLD);
    }
  }
  /// Every rank's (index, bytes) records onto rank 0, which returns all of
  /// them (its own included) in rank order; the other ranks return none.
  /// Records travel in pieces of at most kPiece bytes.
  std::vector<std::pair<long, std::string>> GatherToRoot(std::vector<std::pair<long, std::string>> mine) const {
    if (!mpi_ || size_ == 1) return mine;
    const auto send = [](const char* data, std::size_t n) {
      for (std::size_t at = 0; at < n; at += kPiece)
        MPI_Send(data + at, static_cast<int>(std::min(kPiece, n - at)), MPI_BYTE, 0, 0, MPI_COMM_WORLD);
    };
    if (!root()) {
      long count = static_cast<long>(mine.size());
      MPI_Send(&count, 1, MPI_LONG, 0, 0, MPI_COMM_WORLD);
      for (const auto& [index, bytes] : mine) {
        const long head[2] = {index, static_cast<long>(bytes.size())};
        MPI_Send(head, 2, MPI_LONG, 0, 0, MPI_COMM_WORLD);
        send(bytes.data(), bytes.size());
      }
      return {};
    }
    for (int r = 1; r < size_; ++r) {
      long count = 0;
      MPI_Recv(&count, 1, MPI_LONG, r, 0, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
      for (long k = 0; k < count; ++k) {
        long head[2] = {0, 0};
        MPI_Recv(head, 2, MPI_LONG, r, 0, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        std::string bytes(static_cast<std::size_t>(head[1]), '\0');
        for (std::size_t at = 0; at < bytes.size(); at += kPiece)
          MPI_Recv(bytes.data() + at, static_cast<int>(std::min(kPiece, bytes.size() - at)), MPI_BYTE, r, 0,
                   MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        mine.emplace_back(head[0], std::move(bytes));
      }
    }
    return mine;
  }
  /// Rank 0's exit status `status`, on every rank: each rank returns it
  /// from main, so the launcher sees one status from the whole job. (A rank
  /// that exits 0 beside one that exits 75 or 1 leaves the job's status to
  /// the order in which the launcher notices them.) Every rank calls it
  /// once, after its last other message; a rank that throws instead calls
  /// Abort, which ends the ranks waiting here.
  int RootStatus(int status) const {
    if (!mpi_ || size_ == 1) return status;
    MPI_Bcast(&status, 1, MPI_INT, 0, MPI_COMM_WORLD);
    return status;
  }
  /// Ends every rank of the job with `code` (a rank that stops alone would
  /// leave the others waiting in SumToRoot).
  [[noreturn]] void Abort(int code) {
    aborted_ = true;
    std::fflush(nullptr);
    if (mpi_ && size_ > 1) MPI_Abort(MPI_COMM_WORLD, code);
    std::exit(code);
  }

 private:
  /// Largest message of the byte transfers (MPI counts are int).
  static constexpr std::size_t kPiece = std::size_t{1} << 30;
  bool mpi_ = false, aborted_ = false;
  int rank_ = 0, size_ = 1;
};

/// One finished cell as the journal stores it: the integers and the three
/// doubles bit for bit (hexadecimal floating point, %a).
/// CRC-32 (zlib's) of `key`, a newline and `content`: the journals' check
/// that an entry is whole and belongs to this command.
inline uint32_t JournalChecksum(const std::string& key, std::string_view content) {
  uLong crc = ::crc32(0L, Z_NULL, 0);
  crc = ::crc32(crc, reinterpret_cast<const Bytef*>(key.data()), static_cast<uInt>(key.size()));
  crc = ::crc32(crc, reinterpret_cast<const Bytef*>("\n"), 1);
  for (std::size_t at = 0; at < content.size(); at += 1u << 30) {
    const std::size_t n = std::min<std::size_t>(content.size() - at, 1u << 30);
    crc = ::crc32(crc, reinterpret_cast<const Bytef*>(content.data() + at), static_cast<uInt>(n));
  }
  return static_cast<uint32_t>(crc);
}

/// Reads a journal file that must be a regular file: opened with
/// O_NOFOLLOW and O_NONBLOCK (a symlink, FIFO or device is refused and
/// nothing blocks), checked by fstat. @return false with `why` set if not.
inline bool ReadRegularFile(const std::string& path, std::string* text, std::string* why) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    *why = errno == ELOOP ? "is a symbolic link" : std::string("cannot be opened: ") + std::strerror(errno);
    return false;
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    *why = "is not a regular file";
    return false;
  }
  text->resize(static_cast<std::size_t>(st.st_size));
  std::size_t got = 0;
  while (got < text->size()) {
    const ssize_t n = ::read(fd, text->data() + got, text->size() - got);
    if (n <= 0) break;
    got += static_cast<std::size_t>(n);
  }
  ::close(fd);
  if (got != text->size()) {
    *why = "cannot be read";
    return false;
  }
  return true;
}

struct JournalCell {
  int32_t outcome = 0, steps = 0;
  double updates = 0.0, cg = 0.0, excess = 0.0;
};

/// FNV-1a 64 of a text, for the journal's key (scene texts).
inline std::string Fnv1a64(const std::string& text) {
  uint64_t h = 1469598103934665603ull;
  for (unsigned char c : text) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return fmt::format("{:016x}", h);
}

class SweepJournal {
 public:
  /// Thrown for a journal written by other arguments, or unreadable: one
  /// line naming the journal (exit 2).
  struct Mismatch : std::runtime_error {
    using std::runtime_error::runtime_error;
  };

  /// `path`: "<out>.journal"; `key`: one line of the sweep's canonical
  /// arguments; `cells`: the number of cells. Rank 0 creates the file with
  /// its header if it does not exist; every rank then reads it after
  /// `comm.Barrier()`. @throws Mismatch if the header is not this key.
  SweepJournal(std::string path, std::string key, std::size_t cells, const SweepComm& comm)
      : path_(std::move(path)), header_(fmt::format("clothbench sweep journal 2 cells={} {}", cells, key)) {
    std::string create_error;
    std::error_code ec;
    if (comm.root() && std::filesystem::is_regular_file(std::filesystem::symlink_status(path_, ec)) &&
        std::filesystem::file_size(path_, ec) == 0)
      std::filesystem::remove(path_, ec);  // an empty journal (an older build's, on a full disk) holds no work
    if (comm.root() && !std::filesystem::exists(std::filesystem::symlink_status(path_, ec))) {
      try {  // whole or absent: a full disk leaves no empty journal behind
        WriteFileAtomically(path_, header_ + "\n", "--out");
      } catch (const std::exception& e) {
        create_error = e.what();
      }
    }
    std::vector<long> failed{create_error.empty() ? 0L : 1L};
    comm.Broadcast(&failed);  // every rank reaches it, so that none waits for a rank that failed
    if (failed[0] != 0)
      throw std::runtime_error(comm.root() ? create_error : fmt::format("{}: cannot be created on rank 0", path_));
    std::string all, why;
    if (!ReadRegularFile(path_, &all, &why)) throw Mismatch(fmt::format("{}: {}", path_, why));
    const std::size_t first = all.find('\n');
    const std::string line = all.substr(0, first);
    if (line != header_)
      throw Mismatch(fmt::format("{}: was written by a sweep with other arguments (\"{}\", not \"{}\"); rerun that "
                                 "command, or delete the journal to start afresh",
                                 path_, EscapeControl(line.substr(0, 200)), header_.substr(0, 200)));
    // Complete lines only, each with its checksum (of the header and the
    // line) and values in range: a line cut by a crash or altered is
    // computed again, never decoded.
    std::size_t start = first == std::string::npos ? all.size() : first + 1;
    for (std::size_t nl; (nl = all.find('\n', start)) != std::string::npos; start = nl + 1) {
      const std::string_view entry(all.data() + start, nl - start);
      const std::size_t at = entry.rfind(" crc=");
      long index = -1;
      JournalCell c;
      char upd[64], cg[64], ex[64];
      unsigned crc = 0;
      const bool ok =
          at != std::string_view::npos && std::sscanf(all.c_str() + start + at, " crc=%8x", &crc) == 1 &&
          crc == JournalChecksum(header_, entry.substr(0, at)) &&
          std::sscanf(all.c_str() + start, "cell %ld %d %d %63s %63s %63s", &index, &c.outcome, &c.steps, upd, cg,
                      ex) == 6 &&
          index >= 0 && static_cast<std::size_t>(index) < cells && c.outcome >= 0 && c.outcome <= kPenetration && c.steps >= 0;
      if (ok) {
        c.updates = std::strtod(upd, nullptr);
        c.cg = std::strtod(cg, nullptr);
        c.excess = std::strtod(ex, nullptr);
      }
      if (!ok || !std::isfinite(c.updates) || !std::isfinite(c.cg) || !std::isfinite(c.excess)) {
        ++rejected_;
        continue;
      }
      done_[index] = c;
    }
    fd_ = ::open(path_.c_str(), O_WRONLY | O_APPEND);
    if (fd_ < 0) throw Mismatch(fmt::format("{}: cannot be opened for appending", path_));
  }
  ~SweepJournal() {
    if (fd_ >= 0) ::close(fd_);
  }
  SweepJournal(const SweepJournal&) = delete;
  SweepJournal& operator=(const SweepJournal&) = delete;

  const std::string& path() const { return path_; }
  /// Cells finished by earlier runs, by index.
  const std::map<long, JournalCell>& done() const { return done_; }
  /// Complete lines that failed their checksum or range check (computed again).
  long rejected() const { return rejected_; }

  /// Appends cell `index` with one write(2) on an O_APPEND descriptor, so
  /// that lines of several ranks never interleave on a local or cluster
  /// file system with atomic appends (not NFS).
  void Append(long index, const JournalCell& c) {
    std::string line = fmt::format("cell {} {} {} {:a} {:a} {:a}", index, c.outcome, c.steps, c.updates, c.cg, c.excess);
    line += fmt::format(" crc={:08x}\n", JournalChecksum(header_, line));
    if (::write(fd_, line.data(), line.size()) != static_cast<ssize_t>(line.size()))
      throw std::runtime_error(fmt::format("{}: cannot append a cell: {}", path_, std::strerror(errno)));
  }
  /// After a failure: removes the journal at `path` if it holds no finished
  /// cell (a header alone is no work to resume from). @return whether a
  /// journal with finished cells is kept there.
  static bool KeepIfFinishedWork(const std::string& path) {
    std::string all, why;
    if (!ReadRegularFile(path, &all, &why)) return false;  // absent, or not ours to remove
    if (all.find("\ncell ") != std::string::npos) return true;
    std::error_code ec;
    std::filesystem::remove(path, ec);
    return false;
  }
  /// Removes the journal (the sweep's file is complete).
  void Remove() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
    std::filesystem::remove(path_);
  }

 private:
  std::string path_, header_;
  std::map<long, JournalCell> done_;
  long rejected_ = 0;
  int fd_ = -1;
};

/// The journal of a sweep whose cells are whole runs (bench_integrators):
/// the folder `<out>.journal/` with `key` (the sweep's canonical arguments)
/// and one `<index>.run` per finished cell, written to a temporary name and
/// renamed, so that a cell is either complete or absent. Rank 0 creates and
/// reads it; every rank stores its own cells (a file system all ranks
/// share, as the output folder is on a cluster).
class RecordJournal {
 public:
  /// @throws SweepJournal::Mismatch if the folder holds another key.
  RecordJournal(std::string path, const std::string& key, const SweepComm& comm) : path_(std::move(path)), key_(key) {
    namespace fs = std::filesystem;
    std::string problem;
    if (comm.root()) {
      std::error_code ec;
      const fs::path k = fs::path(path_) / "key";
      const bool existed = fs::exists(fs::symlink_status(path_, ec));
      if (existed && !fs::is_directory(fs::symlink_status(path_, ec))) {
        problem = "is not a folder";
      } else {
        fs::create_directories(path_, ec);
        if (ec) problem = "cannot be created: " + ec.message();
        // A new (or empty) folder gets the key; an existing one with
        // entries but no key is not a journal of this command.
        if (problem.empty() && !fs::exists(fs::symlink_status(k, ec))) {
          if (existed && !fs::is_empty(path_, ec)) {
            problem = "has no key file (a damaged journal or another program's folder); delete it to start afresh";
          } else {
            try {
              WriteFileAtomically(k.string(), key, "--out");
            } catch (const std::exception& e) {
              problem = fmt::format("cannot be written: {}", e.what());
              if (!existed) fs::remove(path_, ec);  // the empty folder this call made
            }
          }
        }
        std::string found, why;
        if (problem.empty() && !ReadRegularFile(k.string(), &found, &why)) problem = "key file " + why;
        if (problem.empty() && found != key)
          problem = fmt::format("was written by a run with other arguments, or by a build whose records differ "
                                "(\"{}\", not \"{}\"); rerun that command with that build, or delete the folder to "
                                "start afresh",
                                EscapeControl(found.substr(0, 200)), key.substr(0, 200));
      }
    }
    std::vector<long> failed{problem.empty() ? 0L : 1L};
    comm.Broadcast(&failed);
    if (failed[0] != 0)
      throw SweepJournal::Mismatch(comm.root() ? fmt::format("{}: {}", path_, problem)
                                               : fmt::format("{}: refused by rank 0", path_));
  }

  const std::string& path() const { return path_; }

  /// Rank 0: the indices of the stored cells whose entries are regular
  /// files, whole and of this key (checksum) and, if `check` is given, whose
  /// content it accepts (it throws std::exception otherwise: values out of
  /// range); the others are removed and counted in rejected(), so that they
  /// are computed again.
  std::vector<long> Stored(const std::function<void(long, const std::string&)>& check = {}) {
    std::vector<long> out;
    for (const auto& e : std::filesystem::directory_iterator(path_)) {
      const std::string name = e.path().filename().string();
      if (e.path().extension() != ".run") continue;
      char* end = nullptr;
      const long k = std::strtol(name.c_str(), &end, 10);
      if (!end || std::string(end) != ".run" || k < 0) continue;
      std::string bytes, why;
      bool ok = Read(k, &bytes, &why);
      if (ok && check) {
        try {
          check(k, bytes);
        } catch (const std::exception& x) {
          ok = false;
          why = x.what();
        }
      }
      if (!ok && first_rejection_.empty()) first_rejection_ = fmt::format("{}: {}", name, why);
      if (ok) {
        out.push_back(k);
      } else {
        ++rejected_;
        std::error_code ec;
        std::filesystem::remove(e.path(), ec);  // a FIFO or symlink entry goes too (not what it points to)
      }
    }
    std::sort(out.begin(), out.end());
    return out;
  }
  long rejected() const { return rejected_; }
  /// The first rejected entry and why ("3.run: fails its checksum").
  const std::string& first_rejection() const { return first_rejection_; }
  /// The content of entry `index`. @throws std::runtime_error if it is not
  /// a regular file or fails its checksum.
  std::string Load(long index) const {
    std::string bytes, why;
    if (!Read(index, &bytes, &why)) throw std::runtime_error(fmt::format("{}: {}", Entry(index), why));
    return bytes;
  }
  /// Stores entry `index`: a header with its checksum (of the key and the
  /// content) and length, then the content, written to a temporary name and
  /// renamed.
  void Store(long index, const std::string& bytes) const {
    WriteFileAtomically(Entry(index),
                        fmt::format("clothbench run crc={:08x} bytes={}\n", JournalChecksum(key_, bytes), bytes.size()) +
                            bytes,
                        "--out");
  }
  /// After a failure: removes the journal folder at `path` if it holds no
  /// finished run (only its key and temporaries). @return whether a
  /// journal with finished runs is kept there.
  static bool KeepIfFinishedWork(const std::string& path) {
    namespace fs = std::filesystem;
    std::error_code ec;
    if (!fs::is_directory(fs::symlink_status(path, ec))) return false;
    for (const auto& e : fs::directory_iterator(path, ec)) {
      const std::string name = e.path().filename().string();
      if (e.path().extension() == ".run") return true;
      if (name != "key" && !name.ends_with(".tmp")) return true;  // not ours: left alone
    }
    fs::remove_all(path, ec);
    return false;
  }
  void Remove() const { std::filesystem::remove_all(path_); }

  /// The marker a watchdog leaves when the run of task `index` stayed
  /// inside one library call past its --time-limit and the process was
  /// ended (harness/overrun.h): `<index>.overrun`.
  std::string OverrunEntry(long index) const { return fmt::format("{}/{}.overrun", path_, index); }
  /// The seconds [s] from the start of task `index` to the end of the
  /// process that its marker records, or nullopt without a readable marker
  /// (none, a link, or not "elapsed_s=<seconds>"). Rank 0 and the rank
  /// that computes the task read it (the journal's shared folder).
  std::optional<double> Overrun(long index) const {
    std::string text, why;
    if (!ReadRegularFile(OverrunEntry(index), &text, &why)) return std::nullopt;
    double elapsed = 0.0;
    if (std::sscanf(text.c_str(), "elapsed_s=%lf", &elapsed) != 1 || !std::isfinite(elapsed) || elapsed < 0.0)
      return std::nullopt;
    return elapsed;
  }
  /// Removes task `index`'s marker (its record is stored).
  void ClearOverrun(long index) const {
    std::error_code ec;
    std::filesystem::remove(OverrunEntry(index), ec);
  }

 private:
  std::string Entry(long index) const { return fmt::format("{}/{}.run", path_, index); }
  bool Read(long index, std::string* bytes, std::string* why) const {
    std::string text;
    if (!ReadRegularFile(Entry(index), &text, why)) return false;
    const std::size_t nl = text.find('\n');
    unsigned crc = 0;
    unsigned long long size = 0;
    if (nl == std::string::npos || std::sscanf(text.c_str(), "clothbench run crc=%8x bytes=%llu", &crc, &size) != 2 ||
        size != text.size() - nl - 1) {
      *why = "is not a whole journal entry (header or length)";
      return false;
    }
    *bytes = text.substr(nl + 1);
    if (crc != JournalChecksum(key_, *bytes)) {
      *why = "fails its checksum";
      return false;
    }
    return true;
  }
  std::string path_, key_, first_rejection_;
  long rejected_ = 0;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_SWEEP_H_
