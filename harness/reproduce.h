// The bench_integrators command that recomputes one stored run of a result
// file: `clothbench_inspect FILE command RUN` prints it. The file holds the
// scene's text (/scene/toml) and every setting the run used (its /runs/<id>
// attributes, docs/results-schema.md); the command writes the scene to a
// file and passes each setting as the option that sets it, so that the run
// is computed again bit for bit on the same build and thread count.
#ifndef CLOTHBENCH_HARNESS_REPRODUCE_H_
#define CLOTHBENCH_HARNESS_REPRODUCE_H_

#include <string>

#include "results/result_reader.h"
#include "results/run_table.h"

namespace clothbench {

struct ReproduceOptions {
  std::string bench = "bench_integrators";  ///< the executable the script calls
  std::string dir;                          ///< folder the script writes the scene and result file into
};

/// A POSIX shell script that writes the scene text of `file` to
/// `<dir>/scene.toml` (with links to its mesh files where the scene names
/// them by relative path) and runs bench_integrators with exactly the
/// settings of run `run_id`: its row label (nonlinear solver named), its h,
/// rtol or substeps, the preconditioner, CG tolerance, J_α terms, ARKODE
/// table and CVODE settings where the row reads them, t_end, the frame
/// spacing, and OMP_NUM_THREADS. The result, `<dir>/run.h5`, holds that
/// run as its only run; --reference none, --repeat 1.
/// @param file, table the result file and its ReadRunTable
/// @throws std::invalid_argument (one line) if the file has no such run, the
///   run is the reference, or the file has no scene text
std::string ReproduceScript(const ResultReader& file, const RunTable& table, const std::string& run_id,
                            const ReproduceOptions& options);

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_REPRODUCE_H_
