// The stability maps' sweep (stress_stability): cells of scenes x rows x
// h x numerical stiffness, computed over MPI ranks with a journal, printed
// as maps and written to a result file (docs/notes/verification.md).
#ifndef CLOTHBENCH_HARNESS_STABILITY_SWEEP_H_
#define CLOTHBENCH_HARNESS_STABILITY_SWEEP_H_

#include <cstdint>
#include <string>
#include <vector>

#include "harness/methods.h"
#include "harness/sweep.h"
#include "model/scene.h"

namespace clothbench {

/// One cell of the sweep, in the order of the printed maps.
struct CellSpec {
  std::size_t scene, method;
  double h, stiffness;
};

/// What the sweep maps: scenes × rows × h × stiffness, and the cell settings.
struct SweepPlan {
  std::vector<Scene> scenes;
  std::vector<RowMethod> methods;
  std::vector<double> stiff, hs;
  int steps = 200, side = 10;
  std::vector<CellSpec> cells;  ///< in the order of the printed maps
  std::string key;              ///< the journal's key: every argument that changes a cell's result
};

/// Every cell's result (summed onto rank 0).
struct CellResults {
  explicit CellResults(std::size_t n) : outcome(n, 0), done(n, 0), upd(n, 0.0), cgs(n, 0.0), excess(n, 0.0) {}
  std::vector<int32_t> outcome, done;
  std::vector<double> upd, cgs, excess;
};

/// The cells not yet in `journal` (at most `max_cells`, 0: all), dealt
/// round-robin over the ranks, each appended to the journal when done; the
/// journalled ones taken from it on rank 0; everything summed onto rank 0.
/// @return the results, and in *partial whether `max_cells` left cells out
/// @throws Interrupted between cells (the journal keeps the finished ones)
CellResults ComputeCells(const SweepPlan& p, SweepJournal& journal, long max_cells, SweepComm& comm, bool* partial);

/// Prints the maps and writes the result file `out` (rank 0; docs/guide/results-schema.md, /stress).
/// @throws ResultError if the file cannot be written
void WriteMaps(const SweepPlan& p, const CellResults& r, const std::string& out, const SweepComm& comm);

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_STABILITY_SWEEP_H_
