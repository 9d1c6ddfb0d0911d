// What a sweep of independent cells (the stability maps) needs to outgrow
// one machine and one sitting:
//  - SweepComm: MPI (Open MPI, or any MPI under Slurm's srun) when the
//    process was started by a launcher, else one rank without MPI at all;
//    cells are dealt round-robin over the ranks and their results summed
//    onto rank 0, which alone prints and writes.
//  - SweepJournal: `<out>.journal`, one line per finished cell appended as
//    it completes, so that an interrupted sweep rerun with the same
//    arguments computes only the missing cells.
// docs/verification.md, "Sweeps on many machines, and resuming them".
#ifndef CLOTHBENCH_BENCH_SWEEP_H_
#define CLOTHBENCH_BENCH_SWEEP_H_

#include <fcntl.h>
// The C API only (Open MPI's and MPICH's mpi.h would pull in the deprecated
// C++ bindings, a library of their own).
#define OMPI_SKIP_MPICXX 1
#define MPICH_SKIP_MPICXX 1
#include <mpi.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include <fmt/format.h>

namespace clothbench {

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
  /// Ends every rank of the job with `code` (a rank that stops alone would
  /// leave the others waiting in SumToRoot).
  [[noreturn]] void Abort(int code) {
    aborted_ = true;
    std::fflush(nullptr);
    if (mpi_ && size_ > 1) MPI_Abort(MPI_COMM_WORLD, code);
    std::exit(code);
  }

 private:
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

}  // namespace clothbench

#endif  // CLOTHBENCH_BENCH_SWEEP_H_
