// Reading result files (HDF5 C API): the counterpart of ResultFile, used by
// clothbench_inspect, the XDMF writer and the tests, so that the schema
// (docs/guide/results-schema.md) is exercised in both directions.
#ifndef CLOTHBENCH_RESULTS_RESULT_READER_H_
#define CLOTHBENCH_RESULTS_RESULT_READER_H_

#include <cstdint>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "model/types.h"
#include "results/result_file.h"
#include "results/run_table.h"

namespace clothbench {

/// A scalar attribute: string, integer or floating point.
using AttributeValue = std::variant<std::string, long, double>;

class ResultReader {
 public:
  /// Opens `path` read-only and checks its schema.
  /// @throws ResultError (one line naming the file) if the file cannot be
  /// opened, is not a clothbench result file, or has a schema other than
  /// kResultSchema (the message names both versions).
  explicit ResultReader(const std::string& path);
  /// Opens an in-memory file image of `size` bytes (copied; HDF5's core
  /// driver), named `name` in messages: the fuzz target's entry.
  /// @throws ResultError as above.
  ResultReader(const std::string& name, const void* image, std::size_t size);
  ~ResultReader();
  ResultReader(const ResultReader&) = delete;
  ResultReader& operator=(const ResultReader&) = delete;

  const std::string& path() const { return path_; }
  /// True if the group or dataset exists (parents included).
  bool Exists(const std::string& object) const;
  /// The children of a group in creation order (run order for /runs).
  std::vector<std::string> Children(const std::string& group) const;
  /// All scalar attributes of an object, in creation order.
  std::vector<std::pair<std::string, AttributeValue>> Attributes(const std::string& object) const;
  std::optional<std::string> String(const std::string& object, const std::string& name) const;
  std::optional<double> Double(const std::string& object, const std::string& name) const;
  std::optional<long> Long(const std::string& object, const std::string& name) const;
  /// The extent of a dataset ([F, N, 3] for frames).
  std::vector<std::size_t> Shape(const std::string& dataset) const;
  /// Any float dataset flattened row-major. @throws ResultError if missing.
  std::vector<double> Doubles(const std::string& dataset) const;
  /// Any integer dataset flattened row-major. @throws ResultError if missing.
  std::vector<int32_t> Ints(const std::string& dataset) const;
  /// A scalar string dataset (ResultFile::WriteString: /scene/toml), its
  /// trailing NUL padding removed. @throws ResultError if missing or not a
  /// string.
  std::string Text(const std::string& dataset) const;
  /// A table of fixed-length strings (ResultFile::WriteStrings), flattened
  /// row-major, each value's NUL padding removed. @throws ResultError if
  /// missing or not fixed-length strings.
  std::vector<std::string> Strings(const std::string& dataset) const;
  /// Frame k of an [F, N, 3] dataset as N×3. @throws ResultError if k ≥ F or a value is not finite.
  MatrixN3 Frame(const std::string& dataset, std::size_t k) const;
  /// A step_stats table. @throws ResultError if missing.
  std::vector<StepRecord> StepStats(const std::string& dataset) const;

 private:
  void CheckSchema();  // closes the file and throws ResultError unless schema == kResultSchema

  std::string path_;
  int64_t file_ = -1;  // hid_t
};

/// Checks what readers rely on before they read (docs/guide/results-schema.md):
/// ranks and extents against each other (per-frame datasets against
/// times and /scene@n_particles, face indices against n_particles, triangle
/// indices against the vertex count, /stress maps against their axes),
/// finite values of the small datasets and attributes, non-decreasing times
/// and attribute sizes. Frame values are checked when read (Frame).
/// @return the file's run table (ReadRunTable), read as part of the checks
/// @throws ResultError "<file>: <dataset or object@attribute>: <rule>".
RunTable ValidateResultFile(const ResultReader& file);

}  // namespace clothbench

#endif  // CLOTHBENCH_RESULTS_RESULT_READER_H_
