// Internal to clothbench::results: what the HDF5 writer and reader share.
#ifndef CLOTHBENCH_RESULTS_HDF5_UTIL_H_
#define CLOTHBENCH_RESULTS_HDF5_UTIL_H_

#include <hdf5.h>

#include "results/result_file.h"

namespace clothbench::internal {

// Called before the first HDF5 call of a ResultFile or ResultReader: HDF5
// registers no atexit handler. Its H5_term_library crashes (SIGSEGV in
// H5F__close_cb, HDF5 1.10.8) on a file whose H5Fclose failed, e.g. on a
// full disk; every file is closed explicitly, so there is nothing for it to
// flush. Returns immediately after the first call.
inline void NoAtExit() {
  static const bool done = [] {
    H5dont_atexit();  // fails harmlessly if the library is already initialised (h5py in the same process)
    return true;
  }();
  (void)done;
}

// Closes an HDF5 handle when it goes out of scope.
struct Handle {
  hid_t id;
  herr_t (*close)(hid_t);
  ~Handle() {
    if (id >= 0) close(id);
  }
};

// The compound type of a step_stats row (StepRecord) in memory; close with
// H5Tclose.
inline hid_t StepRecordType() {
  const hid_t t = H5Tcreate(H5T_COMPOUND, sizeof(StepRecord));
  for (const StepRecordField& c : StepRecordFields())
    H5Tinsert(t, c.name, c.offset, c.is_double ? H5T_NATIVE_DOUBLE : H5T_NATIVE_INT32);
  return t;
}

}  // namespace clothbench::internal

#endif  // CLOTHBENCH_RESULTS_HDF5_UTIL_H_
