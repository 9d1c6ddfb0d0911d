// Reading an untrusted result file where the HDF5 library cannot take the
// reader down. A file that passes its integrity check may still have been
// edited and signed again; HDF5 1.10 itself crashes on some damaged object
// headers and link tables (SIGSEGV in H5Literate's dense-link iteration,
// found by verify/fuzz/fuzz_result.cc). CheckReadableInChild reads the
// whole file once in a child process: if the child dies, the file is
// refused with a ResultError, and the caller (clothbench_inspect, the
// Python module's read_results) reports exit 2 or ValueError, one line.
#ifndef CLOTHBENCH_RESULTS_CONTAINED_READ_H_
#define CLOTHBENCH_RESULTS_CONTAINED_READ_H_

#include <string>

#include "results/result_reader.h"

namespace clothbench {

/// Reads everything a reader of the file may read: ValidateResultFile, the
/// run table (printed to nowhere), every group's attributes, every frame,
/// the faces, step tables, times and the scene text.
/// @throws ResultError naming the dataset or attribute that breaks a rule
void ReadWholeFile(const ResultReader& file);
/// ReadWholeFile after the caller's own ValidateResultFile on the same
/// open file. (HDF5 reads a damaged file's headers differently a second
/// time: validate once per open file.)
void ReadValidatedFile(const ResultReader& file);

/// The deadline of CheckReadableInChild for `path` [s]: 20 s plus the
/// file's size at 10 MB/s (ReadWholeFile inflates every frame).
double ContainedReadDeadline(const std::string& path);

/// Opens `path` and runs ReadWholeFile on it in a child process (fork),
/// killed after `timeout_s` seconds (≤ 0: ContainedReadDeadline), or at
/// once on SIGINT/SIGTERM (then Interrupted is thrown). Returns if the
/// child read it whole.
/// @throws ResultError (one line naming `path`) with the child's refusal,
///   or, if the child was killed by a signal (the HDF5 library crashed on
///   a damaged file) or did not end in time, a line saying so;
///   std::runtime_error if no child process could be started
void CheckReadableInChild(const std::string& path, double timeout_s = 0.0);

}  // namespace clothbench

#endif  // CLOTHBENCH_RESULTS_CONTAINED_READ_H_
