// The thesis' Tables 3.1 and 3.2 beside ours (docs/notes/thesis-tables.md).
#include "harness/thesis_tables.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "harness/cli_args.h"
#include "harness/methods.h"
#include "harness/output_lock.h"
#include "harness/run_codec.h"
#include "harness/side_by_side.h"
#include "results/metrics.h"
#include "results/result_file.h"
#include "results/run_records.h"
#include "solver/run.h"
#include "solver/sewing.h"

namespace clothbench {
namespace {

std::string Sci(double v) { return fmt::format("{:.3e}", v); }

}  // namespace

namespace {

// Thesis tables (docs/model.md §9): Table 3.1 (BDF(2), tablecloth, (k, d) sweep) and
// Table 3.2 (all five methods on the tablecloth, 1 s, and on the sewn
// dress on the avatar, 5 s). Printed beside the thesis' OCR numbers, once per CG tolerance
// η, with e_rms at t_end against a self-convergence reference (BDF(2) at
// h/64 on the tablecloth, h/16 on the dress, tight tolerances), and
// written to HDF5.
struct ThesisRow {
  std::string_view method;  // its registry name
  double k, d;
  long updates, cg;
  double time_s;  // < 0: not given
};

// mean |log10(ours/thesis)| over the updates and CG counts of the rows:
// how far a CG tolerance puts our counts from the thesis' (0: equal).
struct CountDistance {
  double sum = 0.0;
  int terms = 0;
  void Add(long ours, long thesis) {
    if (ours <= 0 || thesis <= 0) return;
    sum += std::abs(std::log10(static_cast<double>(ours) / static_cast<double>(thesis)));
    ++terms;
  }
  double mean() const { return terms ? sum / terms : 0.0; }
};

}  // namespace

namespace {

// One block of rows on `scene` (k and d taken from each row), one table per η.
struct Block {
  std::string scene_name;
  Scene scene;
  std::vector<ThesisRow> rows;
  double h_ref;
};

// A reference's end on every rank: ok, message and the positions at t_end.
struct RefEnd {
  bool ok = false;
  std::string message;
  MatrixN3 x_end;
};

struct RowTask {
  std::size_t eta, b, i;
  RowMethod m;
};

// The table is a sweep in two phases, each dealt over the MPI ranks
// (harness/sweep.h): first the references, one per (block, k, d), whose
// end positions every rank then has; then every (η, row, method) run,
// whose counters and e_rms go to rank 0, which prints and writes.
struct ThesisSweep {
  std::vector<Block> blocks;
  std::vector<std::pair<std::size_t, std::size_t>> ref_keys;  // (block, first row with that k, d)
  std::vector<std::vector<std::size_t>> ref_of;               // ref_of[b][i]: row i's reference in ref_keys
  std::vector<RefEnd> refs;
  std::vector<RowTask> tasks;  // one per (η, block, row, method), in print order
  std::vector<std::pair<RunSummary, double>> row_results;  // rank 0: each task's run and e_rms (< 0: none)

  Scene SceneOf(std::size_t b, const ThesisRow& tr) const {
    Scene s = blocks[b].scene;
    s.material.tension = {tr.k, tr.k};
    s.material.tension_damping = tr.d;
    return s;
  }
};

// The thesis' rows of Table `which` in blocks on `base` (the tablecloth),
// and for 3.2 the sewn dress'. @throws UsageError for another table
std::vector<Block> ThesisBlocks(const std::string& which, const Scene& base,
                                std::optional<PreconditionerType> preconditioner) {
  if (which != "3.1" && which != "3.2")
    throw UsageError(fmt::format("--table: \"{}\" must be one of 3.1, 3.2, 5.1, 5.15", which));
  // The rows each method lists (MethodEntry::thesis_rows), in the registry's
  // order; a k or d < 0 is the scene's.
  const auto rows_on = [&which](std::string_view scene, const Scene& s) {
    std::vector<ThesisRow> rows;
    for (const MethodEntry& e : Registry())
      for (const ThesisTableRow& r : e.thesis_rows)
        if (r.table == which && r.scene == scene)
          rows.push_back({e.name, r.k < 0 ? s.material.tension[0] : r.k, r.d < 0 ? s.material.tension_damping : r.d,
                          r.updates, r.cg, r.time_s});
    return rows;
  };
  std::vector<Block> blocks = {{"tablecloth", base, rows_on("tablecloth", base), base.h / 64.0}};
  if (which == "3.2") {
    // Dress rows: the sewn dress (scenes/dress.toml) on the avatar, 5 s;
    // its sewing phase runs once, before the reference and the rows.
    Scene av = BuiltinScene("dress");
    if (preconditioner) av.solver.preconditioner = *preconditioner;
    Sew(&av);
    blocks.push_back({"dress", av, rows_on("dress", av), av.h / 16.0});
  }
  return blocks;
}

// Phase 1: one self-convergence reference per (block, k, d); its end
// (ok, message, positions at t_end) reaches every rank.
void ComputeReferences(ThesisSweep& t, SweepComm& comm) {
  t.ref_of.assign(t.blocks.size(), {});
  for (std::size_t b = 0; b < t.blocks.size(); ++b)
    for (std::size_t i = 0; i < t.blocks[b].rows.size(); ++i) {
      const ThesisRow& tr = t.blocks[b].rows[i];
      std::size_t j = 0;
      while (j < i && !(t.blocks[b].rows[j].k == tr.k && t.blocks[b].rows[j].d == tr.d)) ++j;
      if (j < i) {
        t.ref_of[b].push_back(t.ref_of[b][j]);
        continue;
      }
      t.ref_keys.emplace_back(b, i);
      t.ref_of[b].push_back(t.ref_keys.size() - 1);
    }
  std::vector<std::pair<long, std::string>> mine;
  for (std::size_t j = 0; j < t.ref_keys.size(); ++j) {
    if (!comm.Owns(j)) continue;
    const auto [b, i] = t.ref_keys[j];
    const RunSummary r = SelfConvergenceReference(t.SceneOf(b, t.blocks[b].rows[i]), t.blocks[b].h_ref);
    ByteWriter w;
    w.Pod<uint8_t>(r.ok());
    w.Str(r.message);
    w.Frames({r.trajectory.positions.empty() ? MatrixN3() : r.trajectory.positions.back()});
    mine.emplace_back(static_cast<long>(j), w.Take());
  }
  std::vector<std::pair<long, std::string>> refs_bytes = comm.GatherToRoot(std::move(mine));
  comm.Broadcast(&refs_bytes);
  t.refs.assign(t.ref_keys.size(), RefEnd());
  for (const auto& [j, bytes] : refs_bytes) {
    ByteReader r(bytes);
    RefEnd& e = t.refs[static_cast<std::size_t>(j)];
    e.ok = r.Pod<uint8_t>() != 0;
    e.message = r.Str();
    e.x_end = r.Frames().at(0);
  }
}

// Phase 2: every (η, block, row, method) run; rank 0 gathers each run's
// record and e_rms at t_end against its row's reference.
void ComputeRows(ThesisSweep& t, const std::vector<NonlinearSolver>& solvers, const std::vector<double>& etas,
                 SweepComm& comm) {
  for (std::size_t e = 0; e < etas.size(); ++e)
    for (std::size_t b = 0; b < t.blocks.size(); ++b)
      for (std::size_t i = 0; i < t.blocks[b].rows.size(); ++i)
        for (const RowMethod& m : ExpandMethods({std::string(t.blocks[b].rows[i].method)}, solvers, "--table"))
          t.tasks.push_back({e, b, i, m});
  std::vector<std::pair<long, std::string>> mine;
  for (std::size_t k = 0; k < t.tasks.size(); ++k) {
    if (!comm.Owns(k)) continue;
    const RowTask& task = t.tasks[k];
    Scene s = t.SceneOf(task.b, t.blocks[task.b].rows[task.i]);
    s.solver.cg_tolerance = etas[task.eta];
    const ParticleSystem sys(s);
    const std::unique_ptr<Stepper> stepper = task.m.Make(sys, s.solver);
    RunSummary r = RunStepper(sys, *stepper, {s.h, s.t_end, s.frame_dt});
    // e_rms at t_end against the row's reference (a complete run has every frame).
    double err = -1.0;
    const RefEnd& ref = t.refs[t.ref_of[task.b][task.i]];
    if (r.ok() && ref.ok && !r.trajectory.positions.empty()) {
      const double e = ErrorRms(r.trajectory.positions.back(), ref.x_end);
      if (std::isfinite(e)) err = e;
    }
    r.trajectory = Trajectory();
    r.step_stats.clear();
    ByteWriter w;
    w.Str(EncodeRun(r));
    w.Pod(err);
    mine.emplace_back(static_cast<long>(k), w.Take());
  }
  std::vector<std::pair<long, std::string>> results = comm.GatherToRoot(std::move(mine));
  if (!comm.root()) return;
  t.row_results.resize(t.tasks.size());
  for (const auto& [k, bytes] : results) {
    ByteReader r(bytes);
    // Frames are not sent (trajectory cleared above): N does not matter.
    auto& [row, err] = t.row_results[static_cast<std::size_t>(k)];
    DecodeRun(r.Str(), 0, &row);
    err = r.Pod<double>();
  }
}

// Rank 0: prints the tables beside the thesis' numbers and writes `out`.
void WriteThesisTable(const std::string& which, const std::string& out, const Scene& base,
                      const std::vector<double>& etas, const ThesisSweep& t, const SweepComm& comm) {
  fmt::print("Table {} — tablecloth (scenes/tablecloth.toml: 20×20, 0.04 m, rho = 1, h = {:g} s, {:g} s, "
             "preconditioner {}); thesis numbers from the OCR (docs/model.md §9, thesis: IC(0)), thesis machine: "
             "Pentium III 660 MHz\n",
             which, base.h, base.t_end, ToString(base.solver.preconditioner));
  if (which == "3.2") fmt::print("k = 9000 N/m: the thesis gives numerical stiffness ~5.6e2 (k illegible)\n");
  for (std::size_t j = 0; j < t.ref_keys.size(); ++j)
    if (!t.refs[j].ok) {
      const auto [b, i] = t.ref_keys[j];
      fmt::print(stderr, "bench_integrators: reference ({}, h = {:g} s) on {} k = {:g}, d = {:g} failed: {}\n",
                 SelfConvergenceMethod().name, t.blocks[b].h_ref, t.blocks[b].scene_name, t.blocks[b].rows[i].k, t.blocks[b].rows[i].d, t.refs[j].message);
    }
  ResultFile f(out);
  WriteProvenance(f);
  f.SetAttribute("/", "mpi_ranks", static_cast<long>(comm.size()));
  f.CreateGroup("/table");
  f.SetAttribute("/table", "name", std::string("Table ") + which);
  f.WriteString("/table/scene_toml", base.toml);
  f.SetAttribute("/table", "preconditioner", std::string(ToString(base.solver.preconditioner)));
  f.WriteVector("/table/cg_tolerances", etas, "");
  int index = 0;
  // One HDF5 group per row: our counts and error beside the thesis'.
  auto write_row = [&](const std::string& scene_name, PreconditionerType scene_preconditioner, double h,
                       const ThesisRow& tr, const RowMethod& m, double eta,
                       const RunSummary& r, std::optional<double> err, double h_ref) {
    const std::string g = fmt::format("/table/row{}", index++);
    f.CreateGroup(g);
    // The row's record as every result file stores a run's
    // (RunRecordFields), then what only a thesis row has.
    RunRecord rec = r;
    rec.label = m.label();
    rec.integrator = m.name();
    rec.layer = std::string(m.entry->layer);
    rec.step_kind = m.kind();
    if (m.fully_implicit()) rec.nonlinear_solver = std::string(ToString(m.solver));
    rec.h = h;
    rec.cg_tolerance = eta;
    rec.preconditioner = std::string(ToString(scene_preconditioner));
    rec.error_final_m = err;
    WriteRunRecord(f, g, rec);
    f.SetAttribute(g, "scene", scene_name);
    f.SetAttribute(g, "k", tr.k);
    f.SetAttribute(g, "d", tr.d);
    if (err) f.SetAttribute(g, "reference_h", h_ref);
    f.SetAttribute(g, "thesis_updates", tr.updates);
    f.SetAttribute(g, "thesis_cg_iterations", tr.cg);
    if (tr.time_s > 0) f.SetAttribute(g, "thesis_solver_time_s", tr.time_s);
  };
  std::size_t k = 0;
  for (std::size_t e = 0; e < etas.size(); ++e) {
    const double eta = etas[e];
    CountDistance distance;
    fmt::print("\ncg_tolerance = {:g}\n", eta);
    for (std::size_t b = 0; b < t.blocks.size(); ++b) {
      const Block& blk = t.blocks[b];
      if (b > 0)
        fmt::print("\nDress (scenes/dress.toml: two patterns sewn on CGAL's man.off, {} particles (thesis: 1310), "
                   "self-contact, k = {:g} N/m, d = {:g} N s/m, {:g} s, h = {:g} s)\n",
                   blk.scene.num_particles(), blk.scene.material.tension[0], blk.scene.material.tension_damping,
                   blk.scene.t_end, blk.scene.h);
      fmt::print("{:<24} {:>8} {:>6} | {:>8} {:>7} {:>9} | {:>8} {:>7} {:>9} {:>7} {:>10} | {:>6} {}\n", "method",
                 "k_N/m", "d", "thesis_u", "thes_cg", "thesis_s", "updates", "cg", "solver_s", "ratio", "e_rms_m",
                 "rej", "status");
      for (std::size_t i = 0; i < blk.rows.size(); ++i) {
        const ThesisRow& tr = blk.rows[i];
        for (; k < t.tasks.size() && t.tasks[k].eta == e && t.tasks[k].b == b && t.tasks[k].i == i; ++k) {
          const RowMethod& m = t.tasks[k].m;
          const auto& [r, e_rms] = t.row_results[k];
          const std::optional<double> err = e_rms >= 0.0 ? std::optional(e_rms) : std::nullopt;
          if (r.ok()) {
            distance.Add(r.updates, tr.updates);
            distance.Add(r.cg_iterations, tr.cg);
          }
          const std::string ratio = tr.time_s > 0 ? fmt::format("{:.3f}", r.solver_time_s / tr.time_s) : "";
          fmt::print("{:<24} {:>8g} {:>6g} | {:>8} {:>7} {:>9} | {:>8} {:>7} {:>9.3f} {:>7} {:>10} | {:>6} {}\n",
                     m.label(), tr.k, tr.d, tr.updates, tr.cg, tr.time_s > 0 ? fmt::format("{:.2f}", tr.time_s) : "",
                     r.updates, r.cg_iterations, r.solver_time_s, ratio,
                     err ? Sci(*err) : "", r.rejected, r.status);
          write_row(blk.scene_name, blk.scene.solver.preconditioner, blk.scene.h, tr, m, eta, r, err, blk.h_ref);
        }
      }
    }
    fmt::print("distance to the thesis' counts at cg_tolerance {:g}: mean |log10(ours/thesis)| over updates and CG = "
               "{:.3f} ({} counts)\n",
               eta, distance.mean(), distance.terms);
  }
  f.Commit();
  fmt::print("\nratio = our solver time / thesis solver time. e_rms_m: at t_end against BDF(2) at h/64 (tablecloth) or "
             "h/16 (dress) with cg_tolerance 1e-10 and fixed-point tolerance 1e-12 m/s.\nmachine: {}, {}, {} MPI "
             "rank{}, commit {}\nresults: {}\n",
             HostName(), CompilerId(), comm.size(), comm.size() > 1 ? "s" : "", GitCommit(), out);
}

}  // namespace

int RunThesisTable(const std::string& which, std::string out, std::optional<PreconditionerType> preconditioner,
                   std::vector<NonlinearSolver> solvers, std::vector<double> etas, SweepComm& comm) {
  Scene base = BuiltinScene("tablecloth");
  if (preconditioner) base.solver.preconditioner = *preconditioner;
  ThesisSweep t;
  t.blocks = ThesisBlocks(which, base, preconditioner);
  if (out.empty()) out = fmt::format("out/table_{}.h5", which == "3.1" ? "3_1" : "3_2");
  if (etas.empty()) etas = {base.solver.cg_tolerance};
  if (solvers.empty()) solvers = {base.solver.nonlinear_solver};
  ProbeOnRoot(comm, [&out] { CheckOutputPaths(out); });
  ComputeReferences(t, comm);
  ComputeRows(t, solvers, etas, comm);
  if (comm.root()) WriteThesisTable(which, out, base, etas, t, comm);
  return 0;
}

}  // namespace clothbench
