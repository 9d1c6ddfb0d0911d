// Recomputing one stored run of a result file. The file holds the scene's
// text (/scene/toml) and every setting the run used (its /runs/<id>
// attributes, docs/guide/results-schema.md); StoredRunRequest rebuilds the run's
// RunRequest from them and validates it like any other entry point's, so a
// file whose stored values break a rule is refused before anything runs.
// `clothbench_inspect FILE rerun RUN` runs that request in-process
// (RerunStored); `clothbench_inspect FILE command RUN` prints the same run
// as a POSIX shell script for bench_integrators, every stored string in it
// single-quoted (comments included), so no stored value reaches the shell
// as code.
#ifndef CLOTHBENCH_HARNESS_REPRODUCE_H_
#define CLOTHBENCH_HARNESS_REPRODUCE_H_

#include <string>

#include "harness/methods.h"
#include "harness/run_request.h"
#include "results/result_reader.h"
#include "results/run_records.h"
#include "results/run_table.h"

namespace clothbench {

struct ReproduceOptions {
  std::string bench = "bench_integrators";  ///< the executable the script calls
  std::string dir;                          ///< folder the script writes the scene and result file into
};

/// A word for the POSIX shell: `s` single-quoted, each ' as '\''. Any
/// byte string, newlines included, is passed as one literal word.
std::string ShellQuote(const std::string& s);

/// The request that recomputes run `run_id` of `file`: the stored scene
/// text (relative mesh paths resolved to the files the run read), its row
/// label with the nonlinear solver named, h, rtol or substeps, the
/// preconditioner, CG tolerance, J_α terms, ARKODE table and CVODE
/// settings where the row reads them, t_end, the frames mode (none becomes
/// ends, which keeps the end state) and the thread count.
/// @param file, table the result file and its ReadRunTable
/// @throws UsageError (one line naming the file, the run and the stored
///   attribute) if the file has no such run, the run is the reference, the
///   file has no scene text, the scene text does not parse or has another
///   particle count than /scene@n_particles, the stored label, integrator,
///   step kind and parameters do not name the run's own id, or any stored
///   value breaks a rule of RunRequest
RunRequest StoredRunRequest(const ResultReader& file, const RunTable& table, const std::string& run_id);

/// A POSIX shell script that writes the scene text of `file` to
/// `<dir>/scene.toml` (with links to its mesh files where the scene names
/// them by relative path) and runs bench_integrators with exactly the
/// settings of StoredRunRequest(file, table, run_id). The result,
/// `<dir>/run.h5`, holds that run as its only run; --reference none,
/// --repeat 1. Every value is single-quoted (ShellQuote); the comment's
/// stored strings have their control characters escaped as well.
/// @throws UsageError as StoredRunRequest
std::string ReproduceScript(const ResultReader& file, const RunTable& table, const std::string& run_id,
                            const ReproduceOptions& options);

/// What a rerun of a stored run found.
struct RerunOutcome {
  MethodRun run;              ///< the recomputed run (its id and label the stored ones)
  bool end_state_kept = false;  ///< the file keeps the run's end state (not --frames none)
  bool bit_for_bit = false;   ///< positions and velocities at t_end equal the stored ones exactly
  double max_dx = 0.0, max_dv = 0.0;  ///< largest difference of a coordinate [m], [m/s]
  bool counts_equal = false;  ///< steps, updates, CG iterations and status equal the stored ones
};

/// Recomputes run `run_id` of `file` in-process from StoredRunRequest (no
/// shell): sets the stored OpenMP thread count, runs the row and compares
/// its end state and counts with the stored ones. If `out` is not empty,
/// writes the run as the only run of the result file `out` (reference
/// none), as the script of ReproduceScript would.
/// @throws UsageError as StoredRunRequest, and for an `out` that cannot be
///   written (checked before computing)
RerunOutcome RerunStored(const ResultReader& file, const RunTable& table, const std::string& run_id,
                         const std::string& out);

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_REPRODUCE_H_
