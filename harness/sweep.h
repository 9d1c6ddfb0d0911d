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
// docs/verification.md, "Sweeps on many machines, and resuming them".
#ifndef CLOTHBENCH_HARNESS_SWEEP_H_
#define CLOTHBENCH_HARNESS_SWEEP_H_

#include <fcntl.h>
// The C API only (Open MPI's and MPICH's mpi.h would pull in the deprecated
// C++ bindings, a library of their own).
#define OMPI_SKIP_MPICXX 1
#define MPICH_SKIP_MPICXX 1
#include <mpi.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>

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
      : path_(std::move(path)), header_(fmt::format("clothbench sweep journal 1 cells={} {}", cells, key)) {
    bool created = true;
    if (comm.root() && !std::filesystem::exists(path_)) {
      std::ofstream out(path_);
      out << header_ << "\n";
      created = static_cast<bool>(out);
    }
    comm.Barrier();  // every rank reaches it, so that none waits for a rank that failed
    if (!created) throw Mismatch(fmt::format("{}: cannot be written", path_));
    std::ifstream in(path_);
    std::string line;
    if (!std::getline(in, line)) throw Mismatch(fmt::format("{}: cannot be read", path_));
    if (line != header_)
      throw Mismatch(fmt::format("{}: was written by a sweep with other arguments (\"{}\", not \"{}\"); rerun that "
                                 "command, or delete the journal to start afresh",
                                 path_, line.substr(0, 200), header_.substr(0, 200)));
    // Complete lines only: a line cut by a crash has no newline and is
    // computed again.
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::size_t start = 0;
    for (std::size_t nl; (nl = text.find('\n', start)) != std::string::npos; start = nl + 1) {
      long index = -1;
      JournalCell c;
      char upd[64], cg[64], ex[64];
      if (std::sscanf(text.c_str() + start, "cell %ld %d %d %63s %63s %63s", &index, &c.outcome, &c.steps, upd, cg,
                      ex) == 6 &&
          index >= 0 && static_cast<std::size_t>(index) < cells) {
        c.updates = std::strtod(upd, nullptr);
        c.cg = std::strtod(cg, nullptr);
        c.excess = std::strtod(ex, nullptr);
        done_[index] = c;
      }
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

  /// Appends cell `index` with one write(2) on an O_APPEND descriptor, so
  /// that lines of several ranks never interleave on a local or cluster
  /// file system with atomic appends (not NFS).
  void Append(long index, const JournalCell& c) {
    const std::string line =
        fmt::format("cell {} {} {} {:a} {:a} {:a}\n", index, c.outcome, c.steps, c.updates, c.cg, c.excess);
    if (::write(fd_, line.data(), line.size()) != static_cast<ssize_t>(line.size()))
      throw std::runtime_error(fmt::format("{}: cannot append a cell", path_));
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
  RecordJournal(std::string path, const std::string& key, const SweepComm& comm) : path_(std::move(path)) {
    namespace fs = std::filesystem;
    bool ok = true;
    std::string found;
    if (comm.root()) {
      std::error_code ec;
      fs::create_directories(path_, ec);
      const fs::path k = fs::path(path_) / "key";
      if (!fs::exists(k)) {
        std::ofstream(k) << key;
      }
      std::ifstream in(k);
      found.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
      ok = !ec && static_cast<bool>(in);
    }
    comm.Barrier();
    if (!comm.root()) return;
    if (!ok) throw SweepJournal::Mismatch(fmt::format("{}: cannot be created or read", path_));
    if (found != key)
      throw SweepJournal::Mismatch(fmt::format("{}: was written by a run with other arguments (\"{}\", not \"{}\"); rerun "
                                               "that command, or delete the folder to start afresh",
                                               path_, found.substr(0, 200), key.substr(0, 200)));
  }

  const std::string& path() const { return path_; }

  /// Rank 0: the indices of the stored cells.
  std::vector<long> Stored() const {
    std::vector<long> out;
    for (const auto& e : std::filesystem::directory_iterator(path_)) {
      const std::string name = e.path().filename().string();
      if (e.path().extension() != ".run") continue;
      char* end = nullptr;
      const long k = std::strtol(name.c_str(), &end, 10);
      if (end && std::string(end) == ".run" && k >= 0) out.push_back(k);
    }
    std::sort(out.begin(), out.end());
    return out;
  }
  std::string Load(long index) const {
    std::ifstream in(Entry(index), std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  void Store(long index, const std::string& bytes) const {
    const std::string tmp = Entry(index) + ".part";
    {
      std::ofstream out(tmp, std::ios::binary);
      out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
      if (!out) throw std::runtime_error(fmt::format("{}: cannot store run {}", path_, index));
    }
    std::filesystem::rename(tmp, Entry(index));
  }
  void Remove() const { std::filesystem::remove_all(path_); }

 private:
  std::string Entry(long index) const { return fmt::format("{}/{}.run", path_, index); }
  std::string path_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_SWEEP_H_
