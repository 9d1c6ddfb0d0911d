// Refusing a run that would not fit in memory, before any computing.
#ifndef CLOTHBENCH_HARNESS_MEMORY_CHECK_H_
#define CLOTHBENCH_HARNESS_MEMORY_CHECK_H_

#include <optional>
#include <string>
#include <vector>

#include "harness/methods.h"
#include "model/scene.h"

namespace clothbench {

/// Bytes of memory available to this process (MemAvailable of
/// /proc/meminfo; 0 if unknown).
double AvailableBytes();

/// Bytes free to this process on the file system holding `path` (statvfs;
/// 0 if unknown).
double FreeDiskBytes(const std::string& path);

/// @throws UsageError naming the scene and the estimate if the run's frames
/// and solver state (methods × parameter counts × CG tolerances, the
/// reference row if any, `step_records` step records) would take more than 80 % of
/// the available memory, or, with `out` given, if its journal and result
/// file (each about the frames and step records) would not fit on the
/// disk holding `out`.
void CheckMemory(const Scene& scene, const std::vector<RowMethod>& methods, const std::vector<std::size_t>& n_params,
                 std::size_t n_eta, const std::optional<RowMethod>& reference, double step_records,
                 const std::string& out = "");

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_MEMORY_CHECK_H_
