// The run table's notes on each kind of row and on the reference
// (results/run_table.h, RunTableNotes), from the method registry's side:
// the results layer prints them and names no method itself.
#ifndef CLOTHBENCH_HARNESS_TABLE_NOTES_H_
#define CLOTHBENCH_HARNESS_TABLE_NOTES_H_

#include "results/run_table.h"

namespace clothbench {

/// The notes bench_integrators and clothbench_inspect print under a run
/// table: the h|rtol legend, what updates and CG iterations count for the
/// substepped (xpbd), iterated (pd, vbd) and SUNDIALS rows, and the
/// reference line (a self-convergence BDF(2) run on obstacle scenes, CVODE
/// or IDA with the reduced velocity solve or KLU otherwise).
const RunTableNotes& RegistryTableNotes();

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_TABLE_NOTES_H_
