// The sweep of bench_integrators (harness/bench_sweep.h).
#include "harness/bench_sweep.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iterator>
#include <map>
#include <optional>

#include <fmt/format.h>

#include "harness/plot.h"
#include "harness/progress.h"
#include "harness/result_writer.h"
#include "harness/run_codec.h"
#include "harness/thesis_tables.h"
#include "model/particle_system.h"
#include "results/metrics.h"
#include "results/run_table.h"
#include "results/xdmf.h"

namespace clothbench {

void RepeatTimings(MethodRun* r, int repeat, double* budget, const std::function<MethodRun()>& run_again) {
  std::vector<double> times = {r->solver_time_s};
  const int k = repeat > 0 ? repeat : (r->solver_time_s < 2.0 ? 3 : 1);
  while (r->ok() && static_cast<int>(times.size()) < k && (repeat > 0 || *budget >= r->wall_time_s)) {
    const auto start = std::chrono::steady_clock::now();
    const MethodRun again = run_again();
    *budget -= std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (!again.ok() || again.steps != r->steps || again.trajectory.positions.size() != r->trajectory.positions.size() ||
        again.trajectory.positions.back() != r->trajectory.positions.back() ||
        again.trajectory.velocities.back() != r->trajectory.velocities.back())
      throw std::runtime_error(fmt::format("{}: timing {} of {} did not reproduce the first run's end state bit for "
                                           "bit (steps {} vs {}, status {})",
                                           r->id, times.size() + 1, k, again.steps, r->steps, again.status));
    times.push_back(again.solver_time_s);
  }
  std::sort(times.begin(), times.end());
  r->repeats = static_cast<long>(times.size());
  r->solver_time_s = times.front();
  r->solver_time_s_median =
      times.size() % 2 ? times[times.size() / 2] : 0.5 * (times[times.size() / 2 - 1] + times[times.size() / 2]);
  r->solver_time_s_max = times.back();
}

// One run of one row: the method, its CG tolerance, h or rtol, substeps.
struct RowTask {
  std::size_t mk;  // method
  double eta, param;
  int substeps;
};

// The rows' runs in table order (rows that use the PCG once per η).
std::vector<RowTask> RowTasks(const BenchRun& b) {
  std::vector<RowTask> tasks;
  for (std::size_t mk = 0; mk < b.methods.size(); ++mk)
    for (double eta : b.methods[mk].uses_pcg() ? b.etas : std::vector<double>{b.scene.solver.cg_tolerance})
      for (const auto& [p, n] : b.plan.params[mk]) tasks.push_back({mk, eta, p, n});
  return tasks;
}

void ReportReferenceFailure(const BenchRun& b, bool self_convergence, double h_ref, const RunSummary& r) {
  if (self_convergence)
    fmt::print(stderr, "bench_integrators: self-convergence reference (bdf2, h = {:g} s) failed: {}\n", h_ref,
               EscapeControl(r.message));
  else
    fmt::print(stderr, "bench_integrators: {} reference at rtol {:g} failed: {}\n", b.reference->label(), b.ref_rtol,
               EscapeControl(r.message));
}

// Rank 0, after every run: errors and energies against the reference, the
// printed tables, the series and the result file; the journal is removed
// once the file is written, and kept (named in the error) if writing fails.
void WriteBench(const BenchRun& b, const ParticleSystem& sys, const std::optional<RunSummary>& ref,
                std::vector<MethodRun>& rows, const SweepComm& comm,
                RecordJournal& journal) {
  CompareToReference(sys, ref ? &*ref : nullptr, b.scene.t_end, b.error_metric, &rows);
  const EqualAccuracyTable wp =
      WorkPrecision(rows, b.targets, b.baseline, b.error_metric, ref ? ref->error_estimate_m : -1.0);
  const RunTable run_table = MakeRunTable(b.scene, sys, ref, rows, b.frames_mode, ref ? &wp : nullptr,
                                         b.error_metric);
  if (!b.work_precision_only) PrintRunTable(stdout, run_table);
  if (ref) PrintWorkPrecision(stdout, wp);
  try {
    if (!b.series.empty()) WriteSeries(b.series, rows);
    WriteResults(b.out, b.scene, sys, ref, rows, run_table, comm.size());
  } catch (const Interrupted&) {
    throw;
  } catch (const std::exception& e) {
    // A full disk or a file-size limit at write time: the .tmp is gone
    // (ResultFile unwinds), a .part never outlives its Store; the finished
    // runs' entries are whole and checksummed, so a rerun writes the file
    // without computing them again.
    const std::size_t kept = journal.Stored().size();
    if (kept == 0) journal.Remove();
    throw std::runtime_error(
        kept ? fmt::format("{}; no result file written; the {} finished runs stay in {}: free space and rerun the same "
                           "command to write it without computing them again",
                           e.what(), kept, journal.path())
             : fmt::format("{}; no result file written", e.what()));
  }
  journal.Remove();
  const std::string xdmf = WriteXdmf(b.out);
  fmt::print("results: {}\n", b.out);
  if (!xdmf.empty()) fmt::print("ParaView: {}\n", xdmf);
}

// Rank 0: the tasks (0 the reference if any, then the rows) whose entry in
// the journal is missing or fails its check (decoded and range-checked
// before it is trusted; rejected ones are computed again).
std::vector<long> MissingTasks(RecordJournal& journal, long n_tasks, long n_particles) {
  const std::vector<long> have = journal.Stored([&](long, const std::string& bytes) {
    RunSummary run;  // the reference (task 0, if any) and the rows share the codec
    DecodeRun(bytes, n_particles, &run);
  });
  if (journal.rejected() > 0)
    fmt::print(stderr, "bench_integrators: {}: {} stored run{} failed the check (not a regular file, cut short, "
                       "not of this command's key or values out of range; first: {}); computing {} again\n",
               journal.path(), journal.rejected(), journal.rejected() > 1 ? "s" : "",
               EscapeControl(journal.first_rejection()), journal.rejected() > 1 ? "them" : "it");
  std::vector<long> missing;
  for (long k = 0; k < n_tasks; ++k)
    if (!std::binary_search(have.begin(), have.end(), k)) missing.push_back(k);
  return missing;
}

// Rank 0: the reference (task 0, if any) and every row in task order, each
// from this rank's results, another rank's bytes or the journal.
// @throws std::runtime_error naming the journal if a stored entry is damaged
void AssembleRuns(std::vector<std::pair<long, std::string>> received, RecordJournal& journal, long n_ref,
                  std::size_t n_rows, long n_particles, std::map<long, RunSummary>* own_ref,
                  std::map<long, MethodRun>* own_rows, std::optional<RunSummary>* ref, std::vector<MethodRun>* rows) {
  std::map<long, std::string> bytes_of(std::make_move_iterator(received.begin()),
                                       std::make_move_iterator(received.end()));
  const auto bytes = [&](long k) {
    const auto it = bytes_of.find(k);
    return it != bytes_of.end() ? std::move(it->second) : journal.Load(k);
  };
  if (n_ref) {
    try {
      if (own_ref->count(0)) {
        *ref = std::move(own_ref->at(0));
      } else {
        ref->emplace();
        DecodeRun(bytes(0), n_particles, &**ref);
      }
    } catch (const std::runtime_error& e) {
      throw std::runtime_error(fmt::format("{}: run 0: {}; delete the folder and rerun", journal.path(), e.what()));
    }
    if (!(*ref)->ok()) return;  // the caller reports it
  }
  for (std::size_t i = 0; i < n_rows; ++i) {
    const long k = n_ref + static_cast<long>(i);
    try {
      rows->push_back(own_rows->count(k) ? std::move(own_rows->at(k)) : DecodeRun(bytes(k), n_particles));
    } catch (const std::runtime_error& e) {
      throw std::runtime_error(fmt::format("{}: run {}: {}; delete the folder and rerun", journal.path(), k, e.what()));
    }
  }
}

// The sweep: the reference (task 0, if any) and every row in table order.
// Under mpirun/srun the tasks are dealt over the ranks and rank 0
// assembles, prints and writes; every finished task is journalled in
// <out>.journal/, so that the same command rerun after an interruption
// computes only the missing ones (harness/sweep.h).
int RunBench(const BenchRun& b, SweepComm& comm) {
  using Row = MethodRun;
  const std::vector<RowTask> row_tasks = RowTasks(b);
  const long n_ref = b.reference ? 1 : 0;
  const long n_tasks = n_ref + static_cast<long>(row_tasks.size());
  // The model last: it loads the mesh obstacles, whose errors are refusals
  // too; the journal exists only for a run that is not refused.
  const ParticleSystem sys(b.scene);
  RecordJournal journal(b.out + ".journal", b.journal_key, comm);
  std::vector<long> missing = comm.root() ? MissingTasks(journal, n_tasks, sys.num_particles())
                                          : std::vector<long>{};
  const std::size_t stored = comm.root() ? static_cast<std::size_t>(n_tasks) - missing.size() : 0;
  comm.Broadcast(&missing);
  const std::size_t to_compute =
      b.max_runs > 0 ? std::min(missing.size(), static_cast<std::size_t>(b.max_runs)) : missing.size();
  if (comm.root() && (stored > 0 || comm.size() > 1 || to_compute < missing.size()))
    fmt::print("{} of {} runs from {}; computing {} on {} rank{}\n", stored, n_tasks, journal.path(), to_compute,
               comm.size(), comm.size() > 1 ? "s" : "");

  TerminalProgress progress(!b.quiet && comm.root());
  double budget = b.time_budget;
  RunLimits limits;
  limits.time_limit_s = b.time_limit;
  // CVODE and IDA have no collision response: on obstacle scenes the
  // reference is a self-convergence run, BDF(2) at h_min/32 (without
  // --h: h/256) with tight CG and fixed-point tolerances.
  const bool self_convergence = !sys.obstacles().empty();
  const double h_ref = (b.hs.empty() ? b.scene.h / 8.0 : *std::min_element(b.hs.begin(), b.hs.end())) / 32.0;
  const auto reference_failed = [&](const RunSummary& r) {
    if (journal.Stored().empty()) journal.Remove();  // nothing to resume
    ReportReferenceFailure(b, self_convergence, h_ref, r);
    return 1;
  };
  const RunContext ctx{b.arkode_table, limits, "", b.preconditioner_from_cli, b.cg_tolerance_from_cli,
                       b.tangent_terms_from_cli, b.cvode};
  std::map<long, RunSummary> own_ref;
  std::map<long, Row> own_rows;
  std::vector<std::pair<long, std::string>> outgoing;
  bool journal_ok = true;
  const auto journal_store = [&](long k, const std::string& bytes) {
    if (!journal_ok) return;
    try {
      journal.Store(k, bytes);
    } catch (const std::exception& e) {  // a full disk ends journalling, not the run
      journal_ok = false;
      fmt::print(stderr, "bench_integrators: {}; continuing without the journal\n", EscapeControl(e.what()));
    }
  };
  const auto task_spec = [&](const RowTask& t) {
    SolverSpec spec = b.scene.solver;
    spec.cg_tolerance = t.eta;
    return spec;
  };
  std::vector<std::pair<long, Row>> computed;  // this rank's rows, before their repetitions
  for (std::size_t j = 0; j < to_compute; ++j) {
    if (!comm.Owns(j)) continue;
    const long k = missing[j];
    if (k < n_ref) {
      RunSummary r;
      if (self_convergence) {
        progress.Start(fmt::format("reference bdf2 h = {:g} s", h_ref), b.scene.t_end);
        r = SelfConvergenceReference(b.scene, h_ref);
        if (r.ok()) {  // its own error: against the same run at 2 h_ref
          progress.Start(fmt::format("reference bdf2 h = {:g} s (self-convergence)", 2.0 * h_ref), b.scene.t_end);
          const RunSummary coarse = SelfConvergenceReference(b.scene, 2.0 * h_ref);
          const std::optional<TrajectoryErrors> e =
              coarse.ok() ? CompareTrajectories(coarse.trajectory, r.trajectory) : std::nullopt;
          if (e && std::isfinite(e->Of(b.error_metric))) r.error_estimate_m = e->Of(b.error_metric);
        }
      } else {
        r = RunReference(sys, b.scene, *b.reference, b.ref_rtol, ctx, b.error_metric, [&](double rtol) {
          progress.Start(fmt::format("reference {} rtol {:g}{}", b.reference->label(), rtol,
                                     rtol < b.ref_rtol ? " (its error estimate)" : ""),
                         b.scene.t_end);
        });
      }
      if (!r.ok() && comm.size() == 1) return reference_failed(r);  // serial: before any row
      std::string bytes = EncodeRun(r);
      if (r.ok()) journal_store(k, bytes);  // a failed reference is computed again by a rerun
      if (comm.root()) own_ref.emplace(k, std::move(r));
      else outgoing.emplace_back(k, std::move(bytes));
      continue;
    }
    const RowTask& t = row_tasks[static_cast<std::size_t>(k - n_ref)];
    const RowMethod& m = b.methods[t.mk];
    const SolverSpec spec = task_spec(t);
    progress.Start(m.kind() == StepKind::kAdaptive     ? fmt::format("{} rtol {:g}", m.label(), t.param)
                   : m.kind() == StepKind::kSubstepped ? fmt::format("{} h = {:g} s/{}", m.label(), t.param, t.substeps)
                                                       : fmt::format("{} h = {:g} s", m.label(), t.param),
                   b.scene.t_end);
    Row r = m.Run(sys, b.scene, spec, t.param, ctx, t.substeps);
    if (b.etas.size() > 1 && m.uses_pcg()) {
      r.id += fmt::format("_eta{:g}", t.eta);
      r.label += fmt::format(" eta={:g}", t.eta);
    }
    journal_store(k, EncodeRun(r));
    computed.push_back({k, std::move(r)});
  }
  progress.Finish();
  // The repetitions, cheapest runs first: within --time-budget the short
  // runs, whose timings vary most, get their three timings whatever their
  // place in the table.
  std::sort(computed.begin(), computed.end(),
            [](const auto& a, const auto& c) { return a.second.wall_time_s < c.second.wall_time_s; });
  for (auto& [k, r] : computed) {
    const RowTask& t = row_tasks[static_cast<std::size_t>(k - n_ref)];
    RepeatTimings(&r, b.repeat, &budget, [&] { return b.methods[t.mk].Run(sys, b.scene, task_spec(t), t.param, ctx, t.substeps); });
    if (r.repeats > 1) journal_store(k, EncodeRun(r));
    if (comm.root()) own_rows.emplace(k, std::move(r));
    else outgoing.emplace_back(k, EncodeRun(r));
  }
  std::vector<std::pair<long, std::string>> received = comm.GatherToRoot(std::move(outgoing));
  if (!comm.root()) return 0;
  if (to_compute < missing.size()) {
    fmt::print("stopped after {} runs (--max-runs): {} of {} done; rerun the same command to continue ({})\n",
               to_compute, stored + to_compute, n_tasks, journal.path());
    return kExitPartial;
  }
  std::optional<RunSummary> ref;
  std::vector<Row> rows;
  AssembleRuns(std::move(received), journal, n_ref, row_tasks.size(), sys.num_particles(), &own_ref, &own_rows, &ref,
               &rows);
  if (ref && !ref->ok()) return reference_failed(*ref);
  WriteBench(b, sys, ref, rows, comm, journal);
  if (!b.plot_dir.empty()) Plot("bench_integrators", b.out, b.plot_dir);
  return 0;
}

}  // namespace clothbench
