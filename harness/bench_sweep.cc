// The sweep of bench_integrators (harness/bench_sweep.h).
#include "harness/bench_sweep.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iterator>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "harness/overrun.h"
#include "harness/table_notes.h"
#include "harness/plot.h"
#include "harness/progress.h"
#include "harness/reference.h"
#include "harness/result_writer.h"
#include "harness/run_codec.h"
#include "harness/side_by_side.h"
#include "harness/thesis_tables.h"
#include "model/particle_system.h"
#include "results/metrics.h"
#include "results/result_file.h"
#include "results/run_records.h"
#include "results/scale_verdict.h"
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

// One run of one row: the method, its CG tolerance, h or rtol, substeps or iterations.
struct RowTask {
  std::size_t mk;  // method
  double eta, param;
  int count;  // substeps (substepped) or iterations (iterated); 1 otherwise
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
    fmt::print(stderr, "bench_integrators: self-convergence reference ({}, h = {:g} s) failed: {}\n",
               SelfConvergenceMethod().name, h_ref, EscapeControl(r.message));
  else
    fmt::print(stderr, "bench_integrators: {} reference at rtol {:g} failed: {}\n", b.reference->label(), b.ref_rtol,
               EscapeControl(r.message));
}

// Rank 0, after every run: errors and energies against the reference, the
// printed tables, the series and the result file; the journal is removed
// once the file is written, and kept (named in the error) if writing fails.
void WriteBench(const BenchRun& b, const ParticleSystem& sys, const std::optional<RunSummary>& ref,
                std::vector<MethodRun>& rows, const SweepComm& comm,
                RecordJournal& journal, const std::vector<std::string>& stop_reasons = {},
                EqualAccuracyTable* wp_out = nullptr) {
  CompareToReference(sys, ref ? &*ref : nullptr, b.scene.t_end, b.error_metric, &rows);
  EqualAccuracyTable wp =
      WorkPrecision(rows, b.targets, b.baseline, b.error_metric, ref ? ref->error_estimate_m : -1.0);
  wp.stop_reasons = stop_reasons;
  const RunTable run_table = MakeRunTable(b.scene, sys, ref, rows, b.frames_mode, ref ? &wp : nullptr,
                                         b.error_metric);
  if (!b.work_precision_only) PrintRunTable(stdout, run_table, RegistryTableNotes());
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
  if (!b.keep_journal) journal.Remove();
  if (wp_out) *wp_out = wp;
  const std::string xdmf = WriteXdmf(b.out);
  fmt::print("results: {}\n", b.out);
  if (!xdmf.empty()) fmt::print("ParaView: {}\n", xdmf);
}

// How a task ended: its status and the time it reached [s].
struct TaskEnd {
  RunStatus status = RunStatus::kOk;
  double t = 0.0;
};

TaskEnd EndOf(const RunSummary& r) {
  const double t = !r.step_stats.empty() ? r.step_stats.back().t
                   : r.trajectory.times.empty() ? 0.0 : r.trajectory.times.back();
  return {r.status, t};
}

// Rank 0: the tasks (0 the reference if any, then the rows) whose entry in
// the journal is missing or fails its check (decoded and range-checked
// before it is trusted; rejected ones are computed again); the stored
// ones' ends into *ends.
std::vector<long> MissingTasks(RecordJournal& journal, long n_tasks, long n_particles, std::map<long, TaskEnd>* ends) {
  const std::vector<long> have = journal.Stored([&](long k, const std::string& bytes) {
    RunSummary run;  // the reference (task 0, if any) and the rows share the codec
    DecodeRun(bytes, n_particles, &run);
    (*ends)[k] = EndOf(run);
  });
  if (journal.rejected() > 0)
    fmt::print(stderr, "bench_integrators: {}: {} stored run{} failed the check (not a regular file, cut short, "
                       "not of this command's key or values out of range; first: {}); computing {} again\n",
               journal.path(), journal.rejected(), journal.rejected() > 1 ? "s" : "",
               EscapeControl(journal.first_rejection()), journal.rejected() > 1 ? "them" : "it");
  std::vector<long> missing;
  for (long k = 0; k < n_tasks; ++k)
    if (!std::binary_search(have.begin(), have.end(), k)) missing.push_back(k);
    else journal.ClearOverrun(k);  // a stored run's repetition overran: the run stays
  return missing;
}

// Row task t of method m as the progress line and the watchdog name it.
std::string RowTaskName(const RowMethod& m, const RowTask& t) {
  const StepKindSpec& k = SpecOf(m.kind());
  if (k.adaptive()) return fmt::format("{} rtol {:g}", m.label(), t.param);
  std::string name = fmt::format("{} h = {:g} s", m.label(), t.param);
  if (k.counted()) name += fmt::format("{}{}", k.progress_separator, t.count);
  return name;
}

// Why task `k` (of tasks, the rows' after n_ref) is not started, if an
// earlier task of its row and CG tolerance at a coarser or equal rung (a
// larger or equal h or rtol, and no more substeps or iterations) ended
// time_limit or was not started: a finer rung costs at least as much, as
// --sweep-to-targets takes it (RefineStop). ends: the tasks' ends known so far.
std::optional<std::string> FinerThanAStop(const BenchRun& b, const std::vector<RowTask>& tasks, long n_ref, long k,
                                          const std::map<long, TaskEnd>& ends) {
  const RowTask& t = tasks[static_cast<std::size_t>(k - n_ref)];
  for (long j = n_ref; j < k; ++j) {
    const RowTask& u = tasks[static_cast<std::size_t>(j - n_ref)];
    if (u.mk != t.mk || u.eta != t.eta || u.param < t.param || u.count > t.count) continue;
    const auto e = ends.find(j);
    if (e == ends.end()) continue;
    const RowMethod& m = b.methods[t.mk];
    if (e->second.status == RunStatus::kTimeLimit)
      return fmt::format("not started: {} is finer than {}, which ended time_limit at t = {:.3g} s of {:g} s "
                         "(--time-limit {:g} s); a finer rung costs at least as much (--start-predicted runs it)",
                         RowTaskName(m, t), RowTaskName(m, u), e->second.t, b.scene.t_end, b.time_limit);
    if (e->second.status == RunStatus::kNotStarted)
      return fmt::format("not started: {} is finer than {}, which was not started (--start-predicted runs it)",
                         RowTaskName(m, t), RowTaskName(m, u));
  }
  return std::nullopt;
}

// The reference task's --time-limit [s].
double ReferenceTimeLimit(const BenchRun& b) {
  return b.reference_time_limit > 0.0 ? b.reference_time_limit : b.time_limit;
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

// The self-convergence run's step on obstacle scenes (the reference with
// virtual particles, the cross-check otherwise): BDF(2) at h_min/32
// (without --h: h/256).
double SelfConvergenceStep(const BenchRun& b) {
  return (b.hs.empty() ? b.scene.h / 8.0 : *std::min_element(b.hs.begin(), b.hs.end())) / 32.0;
}

// The reference's request from the command (harness/reference.h).
ReferenceTask ReferenceTaskOf(const BenchRun& b, double h_ref, TerminalProgress& progress) {
  ReferenceTask t;
  t.scene = &b.scene;
  t.row = b.reference ? &*b.reference : nullptr;
  t.rtol = b.ref_rtol;
  t.h_ref = h_ref;
  t.time_limit_s = b.reference_time_limit;
  t.metric = b.error_metric;
  t.targets = b.targets;
  t.started = [&progress](const std::string& what, double t_end) { progress.Start(what, t_end); };
  return t;
}

// The rows' context: the command's limits and the settings it named.
RunContext ContextOf(const BenchRun& b) {
  RunLimits limits;
  limits.time_limit_s = b.time_limit;
  return RunContext{limits, b.preconditioner_from_cli, b.cg_tolerance_from_cli, b.tangent_terms_from_cli,
                    !b.start_predicted, b.settings};
}

// --sweep-to-targets (docs/notes/work-precision.md, "Sweeps driven by the
// targets"): each method's h (fixed-step), substeps (substepped) or rtol
// (adaptive) is chosen run by run from the errors against the reference.
// From the scene's h (1 substep; rtol 1e-4) it coarsens (h × 2, rtol × 10)
// once if its start reached --time-limit, and while its coarsest run is ok,
// already meets the largest target and took no longer than the run it
// coarsened, so that the largest target is bracketed, then refines (h / 2, substeps × 2,
// rtol / 10) until its finest ok run meets the smallest target, a run fails
// after an ok one, a run reaches --time-limit, two refinements in a row gain
// less than 20 % each (stalled), or the ladder's end. Each method's reason
// is stored and printed with the equal-accuracy table. The decisions follow
// from bit-reproducible errors, so the task indices are the same in every
// run of the command and the journal resumes an interrupted sweep.
constexpr int kMaxCoarsenings = 4, kMaxRunsPerMethod = 14;

// One rung of a method's ladder: index 0 is the start, negative coarser.
struct Rung {
  double param;  // h [s] (fixed-step, iterated; substepped: the frame step) or rtol
  int count;  // substeps (substepped) or iterations (iterated); 1 otherwise
};

Rung RungOf(const RowMethod& m, const Scene& scene, int index) {
  const StepKindSpec& k = SpecOf(m.kind());
  if (k.adaptive()) return {1e-4 * std::pow(10.0, -index), 1};
  if (k.counted()) return {scene.h, 1 << std::max(0, index)};
  return {scene.h * std::pow(2.0, -index), 1};
}

// Whether rung `index` exists: h at most t_end/4 and at least h/4096;
// substeps or iterations 1 … 1024; rtol 1e-1 … 10 × the reference's rtol.
bool RungExists(const RowMethod& m, const BenchRun& b, int index) {
  const Rung r = RungOf(m, b.scene, index);
  const StepKindSpec& k = SpecOf(m.kind());
  if (k.adaptive()) return r.param <= 0.1 * (1.0 + 1e-9) && r.param >= 10.0 * b.ref_rtol * (1.0 - 1e-9);
  if (k.counted()) return index >= 0 && r.count <= 1024;
  return r.param <= 0.25 * b.scene.t_end && r.param >= b.scene.h / 4096.0;
}

std::string RungName(const RowMethod& m, const Rung& r) {
  const StepKindSpec& k = SpecOf(m.kind());
  if (k.adaptive()) return fmt::format("rtol {:g}", r.param);
  if (k.counted()) return fmt::format("{} {}", r.count, k.count);
  return fmt::format("h = {:g} s", r.param);
}

double PredictedWallTime(StepKind kind, double last_s, double before_s) {
  if (!(last_s > 0.0)) return 0.0;
  if (!SpecOf(kind).adaptive()) return 2.0 * last_s;
  if (!(before_s > 0.0)) return 0.0;
  return last_s * std::max(1.0, last_s / before_s);
}

// A method's runs keep in memory only the frames the result file keeps
// (docs/guide/results-schema.md, "Which frames are kept"), once each run's errors
// and energies against the reference are computed: with --frames default
// or positions the velocities at t = 0 and t_end, with --frames default
// also the positions at the ends, but for the method's first (coarsest)
// run, whose positions the file keeps at every frame. On scenes with
// obstacles every position stays: the file's penetration series is
// computed from them when it is written. A --sizes sweep then holds one
// run's frames per method and the reference's, not every run's.
void KeepOnlyStoredFrames(std::map<int, MethodRun>* runs, const std::string& frames_mode, bool keep_positions) {
  const auto ends = [](std::vector<MatrixN3>* frames) {
    if (frames->size() <= 2) return;
    std::vector<MatrixN3> kept{std::move(frames->front()), std::move(frames->back())};
    frames->swap(kept);  // the other frames' memory is freed with `kept`
  };
  for (auto& [index, r] : *runs) {
    if (!r.ok() || !r.err) continue;  // not compared (failed, or no reference)
    if (frames_mode == "default" || frames_mode == "positions") ends(&r.trajectory.velocities);
    if (frames_mode == "default" && !keep_positions && index != runs->begin()->first) ends(&r.trajectory.positions);
  }
}

// The last start of `starts` at fewer than `particles` (starts.end() if none).
std::vector<SizeHistory::Start>::const_iterator LastSmaller(const std::vector<SizeHistory::Start>& starts,
                                                            long particles) {
  auto it = starts.end();
  while (it != starts.begin() && std::prev(it)->particles >= particles) --it;
  return it == starts.begin() ? starts.end() : std::prev(it);
}

double PredictedStartTime(const std::vector<SizeHistory::Start>& starts, long particles) {
  const auto at = LastSmaller(starts, particles);
  if (at == starts.end() || !(at->wall_time_s > 0.0)) return 0.0;
  const SizeHistory::Start& last = *at;
  double p = 1.0;
  if (at != starts.begin()) {
    const SizeHistory::Start& before = *std::prev(at);
    if (before.wall_time_s > 0.0 && last.particles > before.particles)
      p = std::max(1.0, std::log(last.wall_time_s / before.wall_time_s) /
                            std::log(static_cast<double>(last.particles) / static_cast<double>(before.particles)));
  }
  return last.wall_time_s * std::pow(static_cast<double>(particles) / static_cast<double>(last.particles), p);
}

// --sizes: method m's runs of ladder rung `rung` at the smaller sizes
// (nullptr for a single size).
std::vector<SizeHistory::Start>* HistoryOf(const BenchRun& b, const RowMethod& m, int rung) {
  return b.size_history ? &b.size_history->runs[fmt::format("{}@{}", m.label(), rung)] : nullptr;
}

// --sizes: method m's wall time at rung `rung` and this size, predicted
// from its runs of that rung at the smaller sizes (0: none).
double SizePrediction(const BenchRun& b, const RowMethod& m, int rung, long particles) {
  const std::vector<SizeHistory::Start>* h = HistoryOf(b, m, rung);
  return h ? PredictedStartTime(*h, particles) : 0.0;
}

// Why rung `rung` is predicted past --time-limit from the smaller sizes.
std::string SizePredictionReason(const BenchRun& b, const RowMethod& m, int rung, long particles) {
  const std::vector<SizeHistory::Start>& h = *HistoryOf(b, m, rung);
  const SizeHistory::Start& last = *LastSmaller(h, particles);
  return fmt::format("{} predicted past --time-limit {:g} s (about {:.3g} s from {:.1f} s{} at {} particles)",
                     RungName(m, RungOf(m, b.scene, rung)), b.time_limit, SizePrediction(b, m, rung, particles),
                     last.wall_time_s,
                     last.predicted   ? ", itself predicted"
                     : last.timed_out ? ", its time limit"
                     : last.ok        ? ""
                                      : ", a failed run",
                     last.particles);
}

// --sizes: a start predicted past --time-limit from the method's runs of
// that rung at the smaller sizes is not run (it would cost the whole limit,
// and inside one library call, a KLU factorisation at 10⁵ particles, the
// limit is noticed only 5 s after it: harness/overrun.h). As a start that
// reached the limit does, the method then starts from the next cheaper
// rung, down the ladder's coarsenings, at the first one predicted within
// the limit (or without a prediction); the refinement from there stops
// before a rung the smaller sizes predict past the limit (RefineStop).
// The predictions follow from the smaller sizes' stored runs, so a resumed
// sweep decides the same.
// @return the rung to start from (0 or coarser), or nullopt: not started,
//   the reason appended to *reasons; the rungs skipped join the history
//   with their predictions
std::optional<int> StartRung(const BenchRun& b, const RowMethod& m, long particles, std::vector<std::string>* reasons) {
  const auto past_limit = [&](int rung) {
    return b.time_limit > 0.0 && SizePrediction(b, m, rung, particles) > b.time_limit;
  };
  int rung = 0;
  while (past_limit(rung) && rung > -kMaxCoarsenings && RungExists(m, b, rung - 1)) --rung;
  const bool started = !past_limit(rung);
  if (!started)  // before the predictions join the history
    reasons->push_back(fmt::format("{}: not started: {}{}", m.label(), SizePredictionReason(b, m, 0, particles),
                                   rung < 0 ? "; the cheapest, " + SizePredictionReason(b, m, rung, particles)
                                            : std::string()));
  const int last_skipped = started ? rung + 1 : rung;
  for (int skipped = 0; skipped >= last_skipped; --skipped)
    HistoryOf(b, m, skipped)->push_back({particles, SizePrediction(b, m, skipped, particles), false, true});
  return started ? std::optional<int>(rung) : std::nullopt;
}

// --sizes: the method's runs at this size join its history, each in place
// of its rung's prediction at this size, if any.
void RecordSizeHistory(const BenchRun& b, const RowMethod& m, long particles, const std::map<int, MethodRun>& runs) {
  for (const auto& [index, r] : runs)
    if (std::vector<SizeHistory::Start>* h = HistoryOf(b, m, index)) {
      const bool timed_out = r.status == RunStatus::kTimeLimit;
      const SizeHistory::Start ran{particles, timed_out ? std::max(r.wall_time_s, b.time_limit) : r.wall_time_s,
                                   r.ok(), false, timed_out};
      if (!h->empty() && h->back().particles == particles) h->back() = ran;
      else h->push_back(ran);
    }
}

// --sweep-to-targets: why method m's refinement stops at rung `hi` (its
// runs so far and the errors of the ok ones), or nullopt to run rung hi + 1:
// a run past --time-limit, a failure after an ok coarser run, every target
// met, two refinements that gained less than 20 % each, the ladder's end
// (or kMaxRunsPerMethod), or the next rung predicted past --time-limit.
std::optional<std::string> RefineStop(const BenchRun& b, const RowMethod& m, const std::map<int, MethodRun>& runs,
                                      const std::map<int, double>& error, int hi, long particles) {
  const double smallest = *std::min_element(b.targets.begin(), b.targets.end());
  const MethodRun& f = runs.at(hi);
  const auto rung = [&](int i) { return RungName(m, RungOf(m, b.scene, i)); };
  const auto err = [&](int i) { return error.at(i); };
  const bool any_ok = !error.empty();
  if (f.status == RunStatus::kTimeLimit) return fmt::format("time_limit at {}", rung(hi));
  // Predicted past the limits: every finer rung costs at least as much.
  if (f.status == RunStatus::kNotStarted) return fmt::format("not started at {}", rung(hi));
  if (!f.ok() && any_ok && error.begin()->first < hi) return fmt::format("failed ({}) at {}", f.status, rung(hi));
  if (f.ok() && error.count(hi) && err(hi) <= smallest) return std::string("targets met");
  if (error.count(hi) && error.count(hi - 1) && error.count(hi - 2) && err(hi) > 0.8 * err(hi - 1) &&
      err(hi - 1) > 0.8 * err(hi - 2))
    return fmt::format("stalled at {:.1e} m (two refinements gained less than 20 % each)", err(hi));
  if (!RungExists(m, b, hi + 1) || static_cast<int>(runs.size()) >= kMaxRunsPerMethod)
    return any_ok ? fmt::format("the ladder ends at {}", rung(hi))
                  : fmt::format("no run ended ok, down to {} ({} there)", rung(hi), f.status);
  const auto before = runs.find(hi - 1);
  const double predicted =
      f.ok() ? PredictedWallTime(m.kind(), f.wall_time_s,
                                 before != runs.end() && before->second.ok() ? before->second.wall_time_s : 0.0)
             : 0.0;
  if (b.time_limit > 0.0 && predicted > b.time_limit)
    return fmt::format("{} predicted past --time-limit {:g} s (about {:.0f} s from {:.1f} s at {})", rung(hi + 1),
                       b.time_limit, predicted, f.wall_time_s, rung(hi));
  // Without two runs at this size to predict from, the smaller sizes' runs
  // of the next rung do (--sizes).
  if (!(predicted > 0.0) && b.time_limit > 0.0 && SizePrediction(b, m, hi + 1, particles) > b.time_limit)
    return SizePredictionReason(b, m, hi + 1, particles);
  return std::nullopt;
}

int RunTargetSweep(const BenchRun& b, SweepComm& comm, EqualAccuracyTable* wp) {
  const ParticleSystem sys(b.scene);
  RecordJournal journal(b.out + ".journal", b.journal_key, comm);
  std::vector<long> have = journal.Stored([&](long, const std::string& bytes) {
    RunSummary run;
    DecodeRun(bytes, sys.num_particles(), &run);
  });
  TerminalProgress progress(!b.quiet);
  double budget = b.time_budget;
  const RunContext ctx = ContextOf(b);
  const double h_ref = SelfConvergenceStep(b);
  long next = 0;
  // Task `k`: from the journal if stored, else computed and stored.
  const auto task = [&](const std::string& what, auto compute, auto* out) {
    const long k = next++;
    if (std::binary_search(have.begin(), have.end(), k)) {
      DecodeRun(journal.Load(k), sys.num_particles(), out);
    } else {
      *out = RunJournalledTask(journal, k, what, k == 0 ? ReferenceTimeLimit(b) : b.time_limit, k == 0, compute);
      if (out->ok() || k > 0) journal.Store(k, EncodeRun(*out));
    }
    journal.ClearOverrun(k);
  };
  RunSummary ref;
  task("the reference", [&] { return ComputeReference(ReferenceTaskOf(b, h_ref, progress), sys, ctx); }, &ref);
  if (!ref.ok()) {
    if (journal.Stored().empty()) journal.Remove();
    ReportReferenceFailure(b, SelfConvergenceIsReference(sys), h_ref, ref);
    return 1;
  }
  const double largest = *std::max_element(b.targets.begin(), b.targets.end());
  const long particles = sys.num_particles();
  std::vector<MethodRun> rows;
  std::vector<std::string> reasons;
  for (const RowMethod& m : b.methods) {
    SolverSpec spec = b.scene.solver;
    spec.cg_tolerance = b.etas.front();
    std::map<int, MethodRun> runs;
    std::map<int, double> error;  // of the ok runs
    const auto run = [&](int index) {
      const Rung r = RungOf(m, b.scene, index);
      MethodRun& out = runs[index];
      const std::string what = fmt::format("{} {}", m.label(), RungName(m, r));
      task(
          what,
          [&] {
            progress.Start(what, b.scene.t_end);
            MethodRun first = m.Run(sys, b.scene, spec, r.param, ctx, r.count);
            RepeatTimings(&first, b.repeat, &budget, [&] { return m.Run(sys, b.scene, spec, r.param, ctx, r.count); });
            return first;
          },
          &out);
      if (!out.ok()) return;
      std::vector<MethodRun> one;  // moved in and out: no copy of the trajectory
      one.push_back(std::move(out));
      CompareToReference(sys, &ref, b.scene.t_end, b.error_metric, &one);
      out = std::move(one[0]);
      if (const std::optional<double> e = out.Error(ToString(b.error_metric)); e && std::isfinite(*e))
        error[index] = *e;
      KeepOnlyStoredFrames(&runs, b.frames_mode, !sys.obstacles().empty());
    };
    const std::optional<int> start = StartRung(b, m, particles, &reasons);
    if (!start) continue;
    run(*start);
    int lo = *start, hi = *start;
    // A start past --time-limit tries the next cheaper rung once.
    if (runs[lo].status == RunStatus::kTimeLimit && lo > -kMaxCoarsenings && RungExists(m, b, lo - 1)) run(--lo);
    // A coarsening that cost more than the run it coarsened (rejected
    // attempts, more updates per step) ends the coarsening: the cheapest ok
    // run already meets the largest target ('≤' in the table).
    const auto coarsening_paid = [&] {
      const auto finer = runs.find(lo + 1);
      return lo == 0 || finer == runs.end() || !finer->second.ok() ||
             runs[lo].wall_time_s <= finer->second.wall_time_s;
    };
    while (error.count(lo) && error[lo] <= largest && coarsening_paid() && lo > -kMaxCoarsenings &&
           RungExists(m, b, lo - 1) && static_cast<int>(runs.size()) < kMaxRunsPerMethod)
      run(--lo);
    std::optional<std::string> reason;
    while (!(reason = RefineStop(b, m, runs, error, hi, particles))) run(++hi);
    progress.Finish();
    reasons.push_back(fmt::format("{}: {} ({} runs)", m.label(), *reason, runs.size()));
    RecordSizeHistory(b, m, particles, runs);
    for (auto& [index, r] : runs) rows.push_back(std::move(r));
  }
  WriteBench(b, sys, ref, rows, comm, journal, reasons, wp);
  if (!b.plot_dir.empty()) Plot("bench_integrators", b.out, b.plot_dir);
  return b.report ? Report("bench_integrators", b.out) : 0;
}

// The sweep: the reference (task 0, if any) and every row in table order.
// Under mpirun/srun the tasks are dealt over the ranks and rank 0
// assembles, prints and writes; every finished task is journalled in
// <out>.journal/, so that the same command rerun after an interruption
// computes only the missing ones (harness/sweep.h).
int RunBench(const BenchRun& b, SweepComm& comm, EqualAccuracyTable* wp) {
  if (b.sweep_to_targets) return RunTargetSweep(b, comm, wp);
  using Row = MethodRun;
  const std::vector<RowTask> row_tasks = RowTasks(b);
  const long n_ref = b.reference ? 1 : 0;
  const long n_tasks = n_ref + static_cast<long>(row_tasks.size());
  // The model last: it loads the mesh obstacles, whose errors are refusals
  // too; the journal exists only for a run that is not refused.
  const ParticleSystem sys(b.scene);
  RecordJournal journal(b.out + ".journal", b.journal_key, comm);
  std::map<long, TaskEnd> ends;  // of the tasks stored or computed by this rank
  std::vector<long> missing = comm.root() ? MissingTasks(journal, n_tasks, sys.num_particles(), &ends)
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
  const bool self_convergence = SelfConvergenceIsReference(sys);
  const double h_ref = SelfConvergenceStep(b);
  const auto reference_failed = [&](const RunSummary& r) {
    if (journal.Stored().empty()) journal.Remove();  // nothing to resume
    ReportReferenceFailure(b, self_convergence, h_ref, r);
    return 1;
  };
  const RunContext ctx = ContextOf(b);
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
      RunSummary r = RunJournalledTask(journal, k, "the reference", ReferenceTimeLimit(b), true,
                                       [&] { return ComputeReference(ReferenceTaskOf(b, h_ref, progress), sys, ctx); });
      journal.ClearOverrun(k);
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
    const std::string what = RowTaskName(m, t);
    // Serial runs only: a rank does not see the other ranks' ends in time.
    const std::optional<std::string> finer =
        ctx.refuse_predicted && comm.size() == 1 ? FinerThanAStop(b, row_tasks, n_ref, k, ends) : std::nullopt;
    if (!finer) progress.Start(what, b.scene.t_end);
    Row r = finer ? m.NotStarted(b.scene, spec, t.param, ctx, t.count, *finer)
                  : RunJournalledTask(journal, k, what, b.time_limit, false,
                                      [&] { return m.Run(sys, b.scene, spec, t.param, ctx, t.count); });
    ends[k] = EndOf(r);
    if (b.etas.size() > 1 && m.uses_pcg()) {
      r.id += fmt::format("_eta{:g}", t.eta);
      r.label += fmt::format(" eta={:g}", t.eta);
    }
    journal_store(k, EncodeRun(r));
    journal.ClearOverrun(k);
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
    // A repetition that overruns inside a library call: the rerun keeps
    // the stored first run (its marker is removed unread, MissingTasks).
    const ScopedOverrunTask named(journal, k, r.label + " (repetition)", b.time_limit, false);
    RepeatTimings(&r, b.repeat, &budget, [&] { return b.methods[t.mk].Run(sys, b.scene, task_spec(t), t.param, ctx, t.count); });
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
  WriteBench(b, sys, ref, rows, comm, journal, {}, wp);
  if (!b.plot_dir.empty()) Plot("bench_integrators", b.out, b.plot_dir);
  return b.report ? Report("bench_integrators", b.out) : 0;
}

int RunSizes(const std::vector<BenchRun>& runs, const std::vector<long>& sizes, const std::string& out,
             const std::string& plot_dir, SweepComm& comm, bool report) {
  std::vector<EqualAccuracyTable> tables;
  std::vector<std::string> files;
  bool no_page = false;  // a size's --report page was not written
  for (std::size_t s = 0; s < runs.size(); ++s) {
    const BenchRun& b = runs[s];
    fmt::print("\n== N = {} ({}×{} particles, {}) ==\n", b.scene.num_particles(), b.scene.grid.nu, b.scene.grid.nv,
               b.scene.name);
    std::fflush(stdout);
    EqualAccuracyTable wp;
    const int status = RunBench(b, comm, &wp);
    if (status == kExitNoPage) {
      no_page = true;  // the size's file is complete: the verdict goes on
    } else if (status != 0) {
      fmt::print(stderr, "bench_integrators: --sizes: size {} ({} particles) ended with status {}; no verdict "
                         "written (the finished sizes' runs stay in their journals: rerun the same command)\n",
                 sizes[s], b.scene.num_particles(), status);
      return status;
    }
    tables.push_back(std::move(wp));
    files.push_back(std::filesystem::path(b.out).filename().string());
  }
  std::vector<long> particles;
  for (const BenchRun& b : runs) particles.push_back(b.scene.num_particles());
  const ScaleVerdict verdict = BuildScaleVerdict(particles, tables, files);
  PrintScaleVerdict(stdout, verdict);
  {
    ResultFile f(out);
    WriteProvenance(f);
    f.SetAttribute("/", "mpi_ranks", static_cast<long>(comm.size()));
    f.SetAttribute("/", "error_metric", verdict.metric);
    for (std::size_t s = 0; s < runs.size(); ++s) {
      const std::string g = fmt::format("/sizes/n{}", particles[s]);
      f.CreateGroup(g);
      f.SetAttribute(g, "n_particles", particles[s]);
      f.SetAttribute(g, "nu", static_cast<long>(runs[s].scene.grid.nu));
      f.SetAttribute(g, "nv", static_cast<long>(runs[s].scene.grid.nv));
      f.SetAttribute(g, "scene_name", runs[s].scene.name);
      f.SetAttribute(g, "result_file", files[s]);
      f.WriteString(g + "/scene_toml", runs[s].scene.toml);
      WriteWorkPrecision(f, tables[s], g + "/work_precision");
    }
    WriteScaleVerdict(f, verdict);
    f.Commit();
  }
  // The sizes' journals served a resumed --sizes run; the verdict is written.
  for (const BenchRun& b : runs) {
    std::error_code ec;
    std::filesystem::remove_all(b.out + ".journal", ec);
  }
  fmt::print("scale verdict: {}\n", out);
  if (!plot_dir.empty()) Plot("bench_integrators", out, plot_dir);
  const int page = report ? Report("bench_integrators", out) : 0;
  return no_page ? kExitNoPage : page;
}

}  // namespace clothbench
