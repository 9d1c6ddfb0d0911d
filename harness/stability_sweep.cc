#include "harness/stability_sweep.h"

#include <algorithm>
#include <type_traits>

#include <fmt/format.h>

#include "model/interrupt.h"
#include "results/result_file.h"
#include "solver/stability_map.h"

namespace clothbench {

// The cells not yet in the journal (at most `max_cells`, 0: all), dealt
// round-robin over the ranks, each appended to the journal when done; the
// journalled ones taken from it on rank 0; everything summed onto rank 0.
// @return the results, and in *partial whether --max-cells left cells out
CellResults ComputeCells(const SweepPlan& p, SweepJournal& journal, long max_cells, SweepComm& comm, bool* partial) {
  const std::size_t n = p.cells.size();
  CellResults r(n);
  std::vector<std::size_t> missing;
  for (std::size_t k = 0; k < n; ++k) {
    const auto it = journal.done().find(static_cast<long>(k));
    if (it == journal.done().end()) {
      missing.push_back(k);
    } else if (comm.root()) {  // summed onto rank 0: only rank 0 contributes journalled cells
      r.outcome[k] = it->second.outcome;
      r.done[k] = it->second.steps;
      r.upd[k] = it->second.updates;
      r.cgs[k] = it->second.cg;
      r.excess[k] = it->second.excess;
    }
  }
  // Rank 0's list for every rank: the ranks read the journal after one
  // barrier, and rank 0 may append its first cells before another rank
  // has read it; a rank with a shorter list would deal the cells
  // differently (cells computed twice, others never).
  {
    std::vector<long> list(missing.begin(), missing.end());
    comm.Broadcast(&list);
    missing.assign(list.begin(), list.end());
  }
  const std::size_t to_compute =
      max_cells > 0 ? std::min(missing.size(), static_cast<std::size_t>(max_cells)) : missing.size();
  if (comm.root() && (missing.size() < n || comm.size() > 1 || to_compute < missing.size()))
    fmt::print("{} of {} cells from {}; computing {} on {} rank{}\n", n - missing.size(), n, journal.path(),
               to_compute, comm.size(), comm.size() > 1 ? "s" : "");
  for (std::size_t j = 0; j < to_compute; ++j) {
    if (!comm.Owns(j)) continue;
    ThrowIfInterrupted();  // between cells; the journal keeps the finished ones
    const std::size_t k = missing[j];
    const CellSpec& cs = p.cells[k];
    const RowMethod& m = p.methods[cs.method];
    const StabilityCell c = RunStabilityCell(
        p.scenes[cs.scene], [&m](const ParticleSystem& sys, const SolverSpec& spec) { return m.Make(sys, spec); },
        cs.h, cs.stiffness, p.steps);
    r.outcome[k] = c.outcome;
    r.done[k] = c.steps;
    r.upd[k] = c.updates_per_step;
    r.cgs[k] = c.cg_per_step;
    r.excess[k] = c.energy_excess;
    journal.Append(static_cast<long>(k), {c.outcome, c.steps, c.updates_per_step, c.cg_per_step, c.energy_excess});
  }
  comm.SumToRoot(&r.outcome);
  comm.SumToRoot(&r.done);
  comm.SumToRoot(&r.upd);
  comm.SumToRoot(&r.cgs);
  comm.SumToRoot(&r.excess);
  if (comm.root() && to_compute < missing.size())
    fmt::print("stopped after {} cells (--max-cells): {} of {} done; rerun the same command to continue ({})\n",
               to_compute, n - missing.size() + to_compute, n, journal.path());
  *partial = to_compute < missing.size();
  return r;
}

// Prints the maps and writes the result file `out` (rank 0).
void WriteMaps(const SweepPlan& p, const CellResults& r, const std::string& out, const SweepComm& comm) {
  const std::vector<double>& stiff = p.stiff;
  const std::vector<double>& hs = p.hs;
  const int steps = p.steps, side = p.side;
  const std::vector<int32_t>& outcome = r.outcome;
  const std::vector<int32_t>& done = r.done;
  const std::vector<double>& upd = r.upd;
  const std::vector<double>& cgs = r.cgs;
  const std::vector<double>& excess = r.excess;
  ResultFile f(out);
  WriteProvenance(f);
  f.SetAttribute("/", "mpi_ranks", static_cast<long>(comm.size()));
  f.CreateGroup("/stress");
  f.WriteVector("/stress/stiffness", stiff, "");
  f.WriteVector("/stress/h", hs, "s");
  f.SetAttribute("/stress", "steps", static_cast<long>(steps));
  f.SetAttribute("/stress", "side", static_cast<long>(side));
  f.SetAttribute("/stress", "outcome_codes", std::string(kStabilityOutcomeCodes));
  f.SetAttribute("/stress", "bounded_margin", std::string("E(t) - W_ext(t) <= E(0) + 1e-3 sum(m)|g| diag"));
  const int nh = static_cast<int>(hs.size()), ns = static_cast<int>(stiff.size());
  const std::size_t per_map = hs.size() * stiff.size();
  std::size_t k0 = 0;  // first cell of the current map
  for (const Scene& scene : p.scenes) {
    fmt::print("\n{} ({}×{} particles, {} steps per cell, max_updates 30, cg_tolerance 1e-6, no retries)\n",
               scene.name, side, side, steps);
    fmt::print("cells: ok U/C = bounded, U updates and C CG iterations per step; at step n: GROW@n energy growth, "
               "NaN@n non-finite state, CG@n PCG failed, FP@n fixed point not converged in 30 updates, FPdiv@n fixed "
               "point diverged, NW@n Newton not converged in 30 updates, NWdiv@n Newton diverged, SPD@n a particle "
               "faster than twice the speed bound, PEN@n a particle deeper than delta inside an obstacle "
               "(docs/model.md, \"Blow-up statuses\")\n");
    for (const RowMethod& m : p.methods) {
      fmt::print("\n{:<24} {:>8}", m.label(), "h \\ S");
      for (double s : stiff) fmt::print(" {:>12g}", s);
      fmt::print("\n");
      for (std::size_t i = 0; i < hs.size(); ++i) {
        fmt::print("{:<24} {:>8g}", "", hs[i]);
        for (std::size_t j = 0; j < stiff.size(); ++j) {
          const std::size_t k = k0 + i * stiff.size() + j;
          StabilityCell c;
          c.outcome = outcome[k];
          c.steps = done[k];
          c.updates_per_step = upd[k];
          c.cg_per_step = cgs[k];
          fmt::print(" {:>12}", StabilityCellText(c));
        }
        fmt::print("\n");
      }
      const auto slice = [&](const auto& v) {
        using T = typename std::decay_t<decltype(v)>::value_type;
        return std::vector<T>(v.begin() + static_cast<std::ptrdiff_t>(k0),
                              v.begin() + static_cast<std::ptrdiff_t>(k0 + per_map));
      };
      const std::string g = fmt::format("/stress/{}/{}", scene.name, m.id());
      f.CreateGroup(g);
      f.WriteTable(g + "/outcome", nh, ns, slice(outcome));
      f.WriteTable(g + "/steps_completed", nh, ns, slice(done));
      f.WriteTable(g + "/updates_per_step", nh, ns, slice(upd), "");
      f.WriteTable(g + "/cg_per_step", nh, ns, slice(cgs), "");
      f.WriteTable(g + "/energy_excess", nh, ns, slice(excess), "");
      k0 += per_map;
    }
  }
  f.Commit();
}

}  // namespace clothbench
