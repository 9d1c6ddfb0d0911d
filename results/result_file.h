// HDF5 result files (schema kResultSchema, results/run_table.h), written
// through the HDF5 C API. A file is written under "<path>.tmp" (truncating a
// stale one from an earlier crash) and renamed to <path> only by Commit(),
// so an interrupted run never leaves a half file under the final name; the
// destructor removes the .tmp, also when SIGINT/SIGTERM unwinds the writer
// (WriteFrames checks between frames, model/interrupt.h).
#ifndef CLOTHBENCH_RESULTS_RESULT_FILE_H_
#define CLOTHBENCH_RESULTS_RESULT_FILE_H_

#include <array>
#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "model/scene.h"
#include "model/types.h"

namespace clothbench {

/// Thrown when HDF5 fails; the message names the file and the object.
/// A refused or unwritable result file: one line (control characters of
/// the file's own strings, quoted in the message, are escaped).
class ResultError : public std::runtime_error {
 public:
  explicit ResultError(const std::string& what) : std::runtime_error(EscapeControl(what)) {}
};

/// One row of a step_stats table.
struct StepRecord {
  double t;            ///< end of the step [s]
  double h;            ///< step size [s]
  int32_t updates;     ///< fixed-point updates (SUNDIALS rows: BDF order)
  int32_t cg_iterations;
  int32_t status;      ///< 0 = accepted; else the StepStatus code of a rejected attempt
  int32_t colliding;   ///< particles constrained by obstacles (−1 for SUNDIALS rows)
  double solve_time_s; ///< wall time of the attempt in the step engine (SUNDIALS: of the one-step call) [s]
  /// The part of solve_time_s spent building A_α, J_α and their
  /// preconditioners (factorisations, AMG setup, contact factors) [s]; 0
  /// for SUNDIALS rows and in files written before it was stored.
  double setup_time_s;
  /// What preconditioned the step's last solve: 0 the scene's preconditioner
  /// of A_F (and every SUNDIALS row, and files written before it was
  /// stored), 1 the contact factors, 2 the prefiltered AMG, 3 the contact
  /// factor in contact frames.
  int32_t preconditioner;
};

/// One column of a step_stats table: its name, its byte offset in a
/// StepRecord and its type (float64 or int32).
struct StepRecordField {
  const char* name;
  std::size_t offset;
  bool is_double;
};

/// The columns of a step_stats table in file order: the one list the HDF5
/// compound type (results/hdf5_util.h) and the Python module's structured
/// array are made from (docs/guide/results-schema.md, step_stats).
const std::vector<StepRecordField>& StepRecordFields();

class ResultFile {
 public:
  /// Creates "<path>.tmp" (truncating). @throws ResultError.
  explicit ResultFile(const std::string& path);
  /// Removes the temporary file unless Commit() succeeded.
  ~ResultFile();
  ResultFile(const ResultFile&) = delete;
  ResultFile& operator=(const ResultFile&) = delete;

  /// Creates group `path` (e.g. "/runs/<run id>"), parents included.
  void CreateGroup(const std::string& path);
  void SetAttribute(const std::string& object, const std::string& name, const std::string& value);
  void SetAttribute(const std::string& object, const std::string& name, double value);
  void SetAttribute(const std::string& object, const std::string& name, long value);
  /// Scalar UTF-8 string dataset (texts of any size, unlike attributes,
  /// which HDF5 limits to 64 KiB).
  void WriteString(const std::string& path, const std::string& value);
  /// 1-D float64 dataset [n].
  void WriteVector(const std::string& path, const std::vector<double>& values, const std::string& units);
  /// [F, N, 3] float64 from F frames of N×3 (positions [m], velocities [m/s]),
  /// chunked one frame per chunk, compressed with byte shuffle + deflate.
  void WriteFrames(const std::string& path, const std::vector<MatrixN3>& frames, const std::string& units = "m");
  /// Per-frame views of the [F, N, 3] dataset `frames_path`: F virtual
  /// datasets "<view_prefix>k" [N, 3] (HDF5 virtual datasets, no copy), so
  /// that readers which take whole datasets only (XDMF readers: ParaView,
  /// meshio) can address one frame. Intermediate groups are created.
  void WriteFrameViews(const std::string& frames_path, const std::string& view_prefix);
  /// 2-D row-major table [rows, cols] of float64 or int32.
  void WriteTable(const std::string& path, int rows, int cols, const std::vector<double>& values, const std::string& units);
  void WriteTable(const std::string& path, int rows, int cols, const std::vector<int32_t>& values);
  /// 3-D row-major array [d0, d1, d2] of float64 (every value finite).
  void WriteArray3(const std::string& path, const std::array<std::size_t, 3>& dims, const std::vector<double>& values,
                   const std::string& units);
  /// 3-D row-major array [d0, d1, d2] of int32.
  void WriteArray3(const std::string& path, const std::array<std::size_t, 3>& dims, const std::vector<int32_t>& values);
  /// 2-D row-major table [rows, cols] of fixed-length, NUL-padded UTF-8
  /// strings (width: the longest value; h5py reads them as bytes).
  void WriteStrings(const std::string& path, int rows, int cols, const std::vector<std::string>& values);
  /// [F, 3] float64 from F 3-vectors.
  void WriteVectors3(const std::string& path, const std::vector<Vector3>& rows, const std::string& units);
  /// Compound table of StepRecordFields() [S].
  void WriteStepStats(const std::string& path, const std::vector<StepRecord>& rows);
  /// Closes the file, writes its integrity block (SignResultFile) and renames
/// it to its final path. @throws ResultError.
  void Commit();

  const std::string& path() const { return path_; }

 private:
  std::string path_, tmp_path_;
  int64_t file_ = -1;  // hid_t
  bool committed_ = false;
};

/// The file's integrity block: every result file starts with an HDF5 user
/// block of kSignatureBytes holding one text line
/// "clothbench result crc32 XXXXXXXX bytes N", the zlib CRC-32 of bytes
/// [kSignatureBytes, N) and the file size N. ResultReader checks it before
/// HDF5 parses a byte, so a damaged, truncated or later-modified file is
/// refused with one line (HDF5 1.10 itself can crash on damaged metadata:
/// docs/guide/results-schema.md, "Integrity").
inline constexpr std::size_t kSignatureBytes = 512;

/// Writes the integrity block of the HDF5 file at `path` (created with a
/// kSignatureBytes user block, as ResultFile does). @throws ResultError.
void SignResultFile(const std::string& path);

/// Checks the integrity block of a result file read from `file` (at its
/// start) or given as `size` bytes at `data`; `name` names it in messages.
/// @throws ResultError "<name>: <what is wrong>" (one line).
void CheckResultSignature(const std::string& name, std::FILE* file);
void CheckResultSignature(const std::string& name, const unsigned char* data, std::size_t size);

/// Writes the root attributes schema, created, git_commit, host, compiler,
/// build_type and hardware_threads.
void WriteProvenance(ResultFile& file);

/// Host name, compiler, build type and git commit for the root attributes.
std::string HostName();
std::string CompilerId();
std::string BuildType();
std::string GitCommit();
/// Current UTC time, ISO 8601 (e.g. 2026-11-21T15:04:05Z).
std::string NowIso8601Utc();

}  // namespace clothbench

#endif  // CLOTHBENCH_RESULTS_RESULT_FILE_H_
