// bench_integrators: integrates a cloth scene with the thesis' integrators at
// several step sizes and with SUNDIALS CVODE, prints one table (steps,
// updates, CG iterations, solver time, e_rms at t_end, observed order) and
// stores everything in HDF5 (docs/model.md §9).
//
//   bench_integrators [--scene FILE.toml] [--integrators LIST] [--h LIST]
//                     [--t-end T] [--reference cvode|ida|none] [--out FILE.h5]
//                     [--reference-rtol R] [--rtols LIST] [--substeps LIST]
//                     [--cg-tolerance ETA] [--cg-tolerances LIST] [--work-precision]

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "bench/cli_args.h"
#include "bench/methods.h"
#include "bench/plot.h"
#include "bench/progress.h"
#include "bench/run_codec.h"
#include "bench/signals.h"
#include "bench/sweep.h"
#include "model/particle_system.h"
#include "model/triangle_mesh.h"
#include "reference/cvode_reference.h"
#include "reference/ida_reference.h"
#include "results/metrics.h"
#include "results/result_file.h"
#include "results/result_reader.h"
#include "results/run_table.h"
#include "results/xdmf.h"
#include "results/work_precision.h"
#include "solver/run.h"

namespace clothbench {
namespace {

// The journal's key: the scene's text and the command's arguments, except
// those that change no result (--max-runs, --plot, --quiet), so that a rerun
// of the same command, sliced or not, finds its journal.
std::string JournalKey(int argc, char** argv, const Scene& scene) {
  std::string key = fmt::format("bench_integrators journal 1 scene={} args=", Fnv1a64(scene.toml));
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--max-runs" || a == "--plot") {
      ++i;
      continue;
    }
    if (a.rfind("--max-runs=", 0) == 0 || a.rfind("--plot=", 0) == 0 || a == "--quiet") continue;
    key += EscapeControl(a) + " ";
  }
  return key;
}

PreconditionerType ParsePreconditioner(const std::string& name) {
  for (PreconditionerType t : {PreconditionerType::kIc0, PreconditionerType::kCholesky, PreconditionerType::kAmg,
                               PreconditionerType::kJacobi, PreconditionerType::kNone})
    if (name == ToString(t)) return t;
  throw UsageError(fmt::format("--preconditioner: \"{}\" must be ic0, cholesky, amg, jacobi or none", name));
}

// Bytes of memory available to this process (MemAvailable of
// /proc/meminfo; 0 if unknown).
double AvailableBytes() {
  std::ifstream in("/proc/meminfo");
  std::string key;
  double kb = 0.0;
  while (in >> key) {
    if (key == "MemAvailable:" && (in >> kb)) return kb * 1024.0;
    in.ignore(1 << 12, '\n');
  }
  return 0.0;
}

// Refuses, before any computing, a run whose frames and solver state would
// not fit in memory. Estimate per particle [bytes]: 24 per N×3 matrix, of
// which the step engine holds ~25 and every kept frame 2 (positions and
// velocities, held for all rows until the file is written); A_α and the
// Laplacians ~200; the CHOLMOD factor ~45 entries × 12 bytes (measured:
// 44.9e6 entries at 10⁶, METIS); the SUNDIALS references a 3N×3N Jacobian
// (~117 entries per particle row triple) and its KLU factor with fill,
// taken as 4 kB per particle (an upper estimate, not a measurement).
// Every attempted step keeps a StepStats in the run and a StepRecord in its
// row until the file is written (`step_records` of all rows, ~100 bytes each).
void CheckMemory(const Scene& scene, const std::vector<RowMethod>& methods, const std::vector<std::size_t>& n_params,
                 std::size_t n_eta, const std::string& reference, double step_records) {
  const double n = scene.num_particles();
  const double frames = static_cast<double>(FrameTimes(scene.t_end, scene.frame_dt).size());
  double rows = 0.0;
  bool sundials = reference != "none" && scene.obstacles.empty();
  bool tangent = false;
  for (std::size_t k = 0; k < methods.size(); ++k) {
    const RowMethod& m = methods[k];
    const double per = static_cast<double>(n_params[k]);
    rows += per * static_cast<double>(m.uses_pcg() ? n_eta : 1);
    if (m.entry->sparse_jacobian) sundials = true;
    if (m.solver == NonlinearSolver::kNewton || m.entry->tangent) tangent = true;
  }
  if (reference != "none") rows += 1.0;
  // (rows + 1): the frames of every row, and one more copy of a row's as the
  // bytes that go to the journal and to rank 0 (bench/run_codec.h).
  double bytes = n * (25.0 * 24.0 + 200.0) + (rows + 1.0) * frames * 2.0 * 24.0 * n + step_records * 100.0;
  if (scene.solver.preconditioner == PreconditionerType::kCholesky) bytes += n * 45.0 * 12.0;
  if (sundials) bytes += n * 4096.0;
  // Newton and Baraff–Witkin rows hold the 3N×3N tangent system J_α with
  // ∂f/∂x, ∂f/∂v, its constant part and transpose positions on its pattern,
  // and its preconditioner: 6.5 kB per particle (measured peak RSS 7.76 GB
  // for baraff_witkin on the 10⁶-particle large_sheet, `/usr/bin/time -v
  // build/bench/bench_integrators --scene large_sheet --integrators
  // baraff_witkin --h 0.01 --reference none --frames none`).
  if (tangent) bytes += n * 6.5e3;
  const double available = AvailableBytes();
  if (available > 0.0 && bytes > 0.8 * available)
    throw UsageError(fmt::format(
        "{}: grid.nu × grid.nv = {} × {} = {:.0f} particles: this run needs about {:.1f} GB ({:.0f} frames × {:.0f} "
        "runs kept, {:.3g} step records), more than 80 % of the {:.1f} GB available; use --frames ends|none, fewer --h/--integrators, "
        "--reference none, or smaller nu/nv",
        scene.source, scene.grid.nu, scene.grid.nv, n, bytes / 1e9, frames, rows, step_records, available / 1e9));
}

using Row = MethodRun;

void WriteEnergy(ResultFile& f, const std::string& g, const EnergySeries& e) {
  f.CreateGroup(g + "/energy");
  f.WriteVector(g + "/energy/kinetic", e.kinetic, "J");
  f.WriteVector(g + "/energy/tension", e.tension, "J");
  f.WriteVector(g + "/energy/shear", e.shear, "J");
  f.WriteVector(g + "/energy/bending", e.bending, "J");
  f.WriteVector(g + "/energy/gravity", e.gravity, "J");
  f.WriteVector(g + "/energy/external_work", e.external_work, "J");
  f.WriteVector(g + "/energy/total", e.total, "J");
  f.WriteVectors3(g + "/momentum", e.momentum, "kg m/s");
}

// Writes a trajectory's frames under group g: "positions" / "velocities"
// [F, N, 3] at every frame (aligned with g/times) when `every_*` is set,
// else "positions_ends" / "velocities_ends" [2, N, 3] at t = 0 and t_end;
// plus per-frame views g/frame_views/<name>_<k> for XDMF readers.
// Double-precision trajectories compress only ~1.2× losslessly, so which
// frames are kept is what sets the file size (docs/results-schema.md).
void WriteTrajectoryFrames(ResultFile& f, const std::string& g, const Trajectory& traj, bool every_position,
                           bool every_velocity) {
  const auto write = [&](const std::vector<MatrixN3>& frames, bool every, const std::string& name,
                         const std::string& units) {
    if (frames.empty()) return;
    const bool all = every || frames.size() <= 2;
    const std::string path = g + "/" + name + (all ? "" : "_ends");
    if (all) f.WriteFrames(path, frames, units);
    else f.WriteFrames(path, {frames.front(), frames.back()}, units);
    f.WriteFrameViews(path, g + "/frame_views/" + name + "_");
  };
  write(traj.positions, every_position, "positions", "m");
  write(traj.velocities, every_velocity, "velocities", "m/s");
}

// The table's content as plain data (results/run_table.h): what is printed
// and what the file stores, so that clothbench_inspect can print it again.
RunTable MakeRunTable(const Scene& scene, const ParticleSystem& sys, const std::optional<RunSummary>& ref,
                      const ReferenceOptions& ref_opts, const std::vector<Row>& rows, const std::string& frames_mode,
                      const EqualAccuracyTable* wp) {
  RunTable t;
  t.created = NowIso8601Utc();
  t.git_commit = GitCommit();
  t.host = HostName();
  t.compiler = CompilerId();
  t.build_type = BuildType();
  t.hardware_threads = static_cast<long>(std::thread::hardware_concurrency());
  t.scene_name = scene.name;
  t.scene_source = scene.source;
  for (const std::string& term : sys.TermNames()) t.explicit_terms += (t.explicit_terms.empty() ? "" : ",") + term;
  t.frames = frames_mode;
  t.n_particles = static_cast<long>(sys.num_particles());
  t.n_fixed = static_cast<long>(sys.fixed().size());
  t.t_end = scene.t_end;
  t.frame_dt = scene.frame_dt;
  t.h = scene.h;
  t.numerical_stiffness = scene.NumericalStiffness(scene.h);
  t.cg_tolerance = scene.solver.cg_tolerance;
  t.cg_reference = ToString(scene.solver.cg_reference);
  t.preconditioner = ToString(scene.solver.preconditioner);
  t.predictor = ToString(scene.solver.predictor);
  t.max_updates = scene.solver.max_updates;
  if (ref) {
    ReferenceRecord rr;
    rr.integrator = ref->integrator;
    if (ref->integrator == "bdf2_self_convergence") rr.h = ref->h;
    else rr.rtol = ref_opts.rtol;
    rr.steps = ref->steps;
    rr.wall_time_s = ref->wall_time_in_seconds;
    const EnergySeries e = ComputeEnergies(sys, ref->trajectory);
    if (e.t.size() >= 2 && std::isfinite(e.Rate())) rr.energy_rate_W = e.Rate();
    t.reference = rr;
  }
  for (const Row& r : rows) {
    RunRecord q;
    q.id = r.id;
    q.label = r.label;
    q.integrator = r.method;
    q.layer = r.layer;
    q.step_kind = ToString(r.kind);
    q.nonlinear_solver = r.nonlinear_solver;
    if (r.cg_tolerance > 0.0)
      q.preconditioner = r.preconditioner.empty() ? std::string(ToString(scene.solver.preconditioner)) : r.preconditioner;
    q.h = r.h;
    q.rtol = r.rtol;
    q.substeps = r.substeps;
    q.cg_tolerance = r.cg_tolerance;
    q.constraints = r.constraints;
    q.explicit_terms = r.explicit_terms;
    q.status = r.ok ? "ok" : r.status;
    q.message = r.message;
    q.steps = r.steps;
    q.updates = r.updates;
    q.cg_iterations = r.cg;
    q.rejected = r.rejected;
    q.cg_unconverged = r.cg_unconverged;
    q.error_test_failures = r.error_test_failures;
    q.solver_time_s = r.solver_time;
    q.wall_time_s = r.wall_time;
    q.setup_time_s = r.setup_time;
    q.numerical_stiffness = r.stiffness;
    if (r.err) {
      q.error_rms_m = r.err->rms_at_end;
      q.error_max_m = r.err->rms_max;
      q.error_mean_m = r.err->mean_at_end;
    }
    if (r.order && std::isfinite(*r.order)) q.observed_order = r.order;
    if (r.ok && r.energy.t.size() >= 2 && std::isfinite(r.energy.Rate())) q.energy_rate_W = r.energy.Rate();
    t.runs.push_back(std::move(q));
  }
  if (wp) t.work_precision = *wp;
  return t;
}

void WriteResults(const std::string& path, const Scene& scene, const ParticleSystem& sys,
                  const std::optional<RunSummary>& ref, const ReferenceOptions& ref_opts, const std::vector<Row>& rows,
                  const RunTable& table, long mpi_ranks) {
  const std::string& frames_mode = table.frames;
  const bool write_frames = frames_mode != "none";
  ResultFile f(path);
  WriteProvenance(f);
  f.SetAttribute("/", "mpi_ranks", mpi_ranks);
  f.CreateGroup("/scene");
  WriteSceneRecord(f, table);
  f.WriteString("/scene/toml", scene.toml);  // a dataset: scene files of any size
  // The grid's quads, once: (i, j), (i+1, j), (i+1, j+1), (i, j+1), 0-based
  // particle indices, counter-clockwise in (u, v).
  {
    const int nu = scene.grid.nu, nv = scene.grid.nv;
    std::vector<int32_t> faces;
    faces.reserve(static_cast<std::size_t>(4 * (nu - 1) * (nv - 1)));
    for (int j = 0; j + 1 < nv; ++j)
      for (int i = 0; i + 1 < nu; ++i)
        for (int q : {scene.Index(i, j), scene.Index(i + 1, j), scene.Index(i + 1, j + 1), scene.Index(i, j + 1)})
          faces.push_back(q);
    f.WriteTable("/scene/faces", (nu - 1) * (nv - 1), 4, faces);
  }
  // Triangle-mesh obstacles, placed (scale, rotate, translate; keyframed
  // motion not applied), for the XDMF file.
  for (std::size_t k = 0; k < sys.obstacles().size(); ++k)
    if (const TriangleMesh* mesh = sys.obstacles()[k].mesh()) {
      const std::string o = fmt::format("/scene/obstacles/{}", k);
      std::vector<double> vertices;
      std::vector<int32_t> triangles;
      mesh->Export(&vertices, &triangles);
      f.CreateGroup(o);
      f.SetAttribute(o, "path", sys.obstacles()[k].spec().path);
      f.WriteTable(o + "/vertices", static_cast<int>(vertices.size() / 3), 3, vertices, "m");
      f.WriteTable(o + "/triangles", static_cast<int>(triangles.size() / 3), 3, triangles);
    }
  if (ref) {
    f.CreateGroup("/reference");
    f.SetAttribute("/reference", "integrator", ref->integrator);
    if (ref->integrator == "bdf2_self_convergence") {
      f.SetAttribute("/reference", "h", ref->h);
      f.SetAttribute("/reference", "cg_tolerance", 1e-10);
    } else {
      f.SetAttribute("/reference", "rtol", ref_opts.rtol);
      f.SetAttribute("/reference", "atol", ref_opts.atol > 0 ? ref_opts.atol : ref_opts.rtol);
    }
    f.SetAttribute("/reference", "wall_time_s", ref->wall_time_in_seconds);
    f.SetAttribute("/reference", "solver_time_s", ref->solver_time_in_seconds);
    f.SetAttribute("/reference", "steps", static_cast<long>(ref->steps));
    f.SetAttribute("/reference", "fixed_point_updates", ref->fixed_point_updates);
    f.SetAttribute("/reference", "cg_iterations", ref->cg_iterations);
    if (const auto& s = ref->sundials)
      for (auto [name, v] : {std::pair{"nst", s->nst}, {"nfe", s->nfe}, {"nni", s->nni}, {"nli", s->nli},
                             {"netf", s->netf}, {"ncfn", s->ncfn}, {"nje", s->nje}, {"nsetups", s->nsetups}})
        f.SetAttribute("/reference", name, v);
    if (table.reference->energy_rate_W) f.SetAttribute("/reference", "energy_rate_W", *table.reference->energy_rate_W);
    f.WriteVector("/reference/times", ref->trajectory.times, "s");
    if (write_frames)
      WriteTrajectoryFrames(f, "/reference", ref->trajectory, true, frames_mode == "all" || frames_mode == "ends");
    WriteEnergy(f, "/reference", ComputeEnergies(sys, ref->trajectory));
    std::vector<StepRecord> st;
    for (const StepStats& s : ref->step_stats)
      st.push_back({s.t, s.h, s.updates, s.cg_iterations, static_cast<int32_t>(s.status), s.colliding, s.solve_time});
    f.WriteStepStats("/reference/step_stats", st);
  }
  f.CreateGroup("/runs");
  std::string last_label;
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const Row& r = rows[k];
    const std::string g = "/runs/" + r.id;
    f.CreateGroup(g);
    WriteRunRecord(f, g, table.runs[k]);
    if (r.sundials) {
      for (auto [name, v] : {std::pair{"nst", r.sundials->nst}, {"nfe", r.sundials->nfe}, {"nfe_i", r.sundials->nfe_i},
                             {"nni", r.sundials->nni}, {"nli", r.sundials->nli}, {"netf", r.sundials->netf},
                             {"ncfn", r.sundials->ncfn}, {"nje", r.sundials->nje}, {"nsetups", r.sundials->nsetups}})
        if (v >= 0) f.SetAttribute(g, name, v);
    }
    if (!r.sundials_settings.empty()) f.SetAttribute(g, "sundials_settings", r.sundials_settings);
    if (r.cg_tolerance > 0.0) {
      f.SetAttribute(g, "cg_reference", std::string(ToString(scene.solver.cg_reference)));
      f.SetAttribute(g, "preconditioner",
                     r.preconditioner.empty() ? std::string(ToString(scene.solver.preconditioner)) : r.preconditioner);
      f.SetAttribute(g, "predictor", std::string(ToString(scene.solver.predictor)));
      f.SetAttribute(g, "step_control", std::string(ToString(scene.solver.step_control)));
    }
    f.WriteVector(g + "/times", r.traj.times, "s");
    // --frames default: every frame of each label's first row (its largest
    // h or rtol, where its motion differs most from the reference), the ends
    // of the others.
    const bool first_of_label = r.label != last_label;
    last_label = r.label;
    if (write_frames)
      WriteTrajectoryFrames(f, g, r.traj,
                            frames_mode == "all" || frames_mode == "positions" || frames_mode == "ends" ||
                                (frames_mode == "default" && first_of_label),
                            frames_mode == "all" || frames_mode == "ends");
    WriteEnergy(f, g, r.energy);
    if (!sys.obstacles().empty()) {
      const PenetrationSeries pen = ComputePenetration(sys, r.traj);
      const int frames = static_cast<int>(r.traj.times.size());
      f.CreateGroup(g + "/penetration");
      f.WriteTable(g + "/penetration/max_depth", frames, pen.obstacles, pen.max_depth, "m");
      f.WriteTable(g + "/penetration/mean_depth", frames, pen.obstacles, pen.mean_depth, "m");
      f.WriteTable(g + "/penetration/close_count", frames, pen.obstacles, pen.close);
    }
    f.WriteStepStats(g + "/step_stats", r.steps_table);
    if (!r.bdf_order.empty()) f.WriteVector(g + "/method_order", r.bdf_order, "");
  }
  if (table.work_precision) WriteWorkPrecision(f, *table.work_precision);
  f.Commit();
}

// Fig. 4.3: per-step CG iterations and colliding particles as CSV, and a
// summary: the first impact, CG per step in the 0.1 s after it, and
// fixed-point updates and CG per step over the last 0.3 s (resting contact).
void WriteSeries(const std::string& path, const std::vector<Row>& rows) {
  std::ofstream csv(path);
  if (!csv) throw std::runtime_error(fmt::format("--series: cannot write \"{}\"", path));
  csv << "integrator,h,t,step_h,updates,cg_iterations,colliding,status\n";
  fmt::print("\nFig. 4.3 series: {}\n{:<24} {:>8} {:>10} {:>16} {:>16} {:>16} {:>14}\n", path, "integrator", "h",
             "impact_s", "cg/step impact", "upd/step last .3s", "cg/step last .3s", "colliding end");
  for (const Row& r : rows) {
    if (r.kind != StepKind::kFixedStep) continue;
    double impact = -1.0, t_last = r.steps_table.empty() ? 0.0 : r.steps_table.back().t;
    long cg_a = 0, n_a = 0, upd_b = 0, cg_b = 0, n_b = 0;
    for (const StepRecord& s : r.steps_table) {
      csv << fmt::format("{},{:g},{:.6f},{:.6g},{},{},{},{}\n", r.label, r.h, s.t, s.h, s.updates, s.cg_iterations,
                         s.colliding, s.status);
      if (s.status != 0) continue;
      if (impact < 0.0 && s.colliding > 0) impact = s.t;
      if (impact >= 0.0 && s.t <= impact + 0.1) cg_a += s.cg_iterations, ++n_a;
      if (s.t > t_last - 0.3) upd_b += s.updates, cg_b += s.cg_iterations, ++n_b;
    }
    const double steps_b = n_b ? static_cast<double>(n_b) : 1.0;
    fmt::print("{:<24} {:>8g} {:>10} {:>16} {:>16.1f} {:>16.1f} {:>14}\n", r.label, r.h,
               impact < 0 ? "none" : fmt::format("{:.2f}", impact),
               n_a ? fmt::format("{:.1f}", static_cast<double>(cg_a) / static_cast<double>(n_a)) : "",
               static_cast<double>(upd_b) / steps_b, static_cast<double>(cg_b) / steps_b,
               r.steps_table.empty() ? 0 : r.steps_table.back().colliding);
  }
}

std::string Sci(double v) { return fmt::format("{:.3e}", v); }

// The equal-accuracy table (docs/work-precision.md): each row label's
// (solver time, e_rms at t_end) points in run order (h or rtol decreasing).
EqualAccuracyTable WorkPrecision(const std::vector<Row>& rows, const std::vector<double>& targets) {
  std::vector<std::string> labels;
  std::vector<std::vector<WorkPoint>> points;
  for (const Row& r : rows) {
    auto it = std::find(labels.begin(), labels.end(), r.label);
    if (it == labels.end()) {
      labels.push_back(r.label);
      points.emplace_back();
      it = labels.end() - 1;
    }
    if (r.ok && r.err) points[static_cast<std::size_t>(it - labels.begin())].push_back({r.solver_time, r.err->rms_at_end});
  }
  return BuildEqualAccuracyTable(labels, points, targets, "cvode");
}

// A tight self-convergence reference for obstacle scenes, where CVODE and
// IDA have no collision response: BDF(2) at h_ref with CG tolerance 1e-10,
// fixed-point tolerance 1e-12 m/s and up to 200 updates per step.
RunSummary SelfConvergenceReference(const Scene& scene, double h_ref) {
  Scene tight = scene;
  tight.solver.cg_tolerance = 1e-10;
  tight.solver.fixed_point_tolerance = 1e-12;
  tight.solver.max_updates = 200;
  const ParticleSystem tight_sys(tight);
  RunSummary r = RunIntegrator(tight_sys, Method::kBdf2, {h_ref, scene.t_end, scene.frame_dt});
  r.integrator = "bdf2_self_convergence";
  r.h = h_ref;
  return r;
}

// Thesis tables (docs/model.md §9): Table 3.1 (BDF(2), tablecloth, (k, d) sweep) and
// Table 3.2 (all five methods on the tablecloth, 1 s, and on the avatar
// drape, 5 s). Printed beside the thesis' OCR numbers, once per CG tolerance
// η, with e_rms at t_end against a self-convergence reference (BDF(2) at
// h/64 on the tablecloth, h/16 on the avatar, tight tolerances), and
// written to HDF5.
struct ThesisRow {
  std::string method;
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

int RunThesisTable(const std::string& which, std::string out, std::optional<PreconditionerType> preconditioner,
                   std::vector<NonlinearSolver> solvers, std::vector<double> etas, SweepComm& comm) {
  std::vector<ThesisRow> rows;
  if (which == "3.1") {
    rows = {{"bdf2", 1e4, 160, 803, 1160, -1}, {"bdf2", 1e4, 1600, 198, 538, -1}, {"bdf2", 1e5, 1600, 377, 566, -1},
            {"bdf2", 1e3, 1600, 52, 52, -1}};
  } else if (which == "3.2") {
    rows = {{"imex_euler", 9000, 50, 100, 745, 1.69},    {"implicit_euler", 9000, 50, 206, 1038, 3.06},
            {"sbdf2", 9000, 50, 100, 304, 1.57},         {"bdf2", 9000, 50, 122, 857, 2.57},
            {"implicit_midpoint", 9000, 50, 494, 813, 4.39}};
  } else {
    throw UsageError(fmt::format("--table: \"{}\" must be 3.1 or 3.2", which));
  }
  if (out.empty()) out = fmt::format("out/table_{}.h5", which == "3.1" ? "3_1" : "3_2");
  Scene base = BuiltinScene("tablecloth");
  if (preconditioner) base.solver.preconditioner = *preconditioner;
  if (etas.empty()) etas = {base.solver.cg_tolerance};
  if (solvers.empty()) solvers = {base.solver.nonlinear_solver};
  CheckOutputFolder(out);
  // One block of rows on `s` (k and d taken from each row), one table per η.
  struct Block {
    std::string scene_name;
    Scene scene;
    std::vector<ThesisRow> rows;
    double h_ref;
  };
  std::vector<Block> blocks = {{"tablecloth", base, rows, base.h / 64.0}};
  if (which == "3.2") {
    // Dress rows: the avatar drape (scenes/avatar_drape.toml), 5 s.
    Scene av = BuiltinScene("avatar_drape");
    if (preconditioner) av.solver.preconditioner = *preconditioner;
    const double kd = av.material.tension[0], dd = av.material.tension_damping;
    blocks.push_back({"avatar_drape", av,
                      {{"imex_euler", kd, dd, 500, 17198, 152.7},
                       {"implicit_euler", kd, dd, 1654, 21424, 204.9},
                       {"sbdf2", kd, dd, 500, 15360, 169.5},
                       {"bdf2", kd, dd, 1431, 19307, 194.4},
                       {"implicit_midpoint", kd, dd, 2078, 15877, 211.3}},
                      av.h / 16.0});
  }
  const auto scene_of = [&](std::size_t b, const ThesisRow& tr) {
    Scene s = blocks[b].scene;
    s.material.tension = {tr.k, tr.k};
    s.material.tension_damping = tr.d;
    return s;
  };
  // The table is a sweep in two phases, each dealt over the MPI ranks
  // (bench/sweep.h): first the references, one per (block, k, d), whose
  // end positions every rank then has; then every (η, row, method) run,
  // whose counters and e_rms go to rank 0, which prints and writes.
  // ref_of[b][i] indexes row i's reference in `ref_keys`.
  std::vector<std::pair<std::size_t, std::size_t>> ref_keys;  // (block, first row with that k, d)
  std::vector<std::vector<std::size_t>> ref_of(blocks.size());
  for (std::size_t b = 0; b < blocks.size(); ++b)
    for (std::size_t i = 0; i < blocks[b].rows.size(); ++i) {
      const ThesisRow& tr = blocks[b].rows[i];
      std::size_t j = 0;
      while (j < i && !(blocks[b].rows[j].k == tr.k && blocks[b].rows[j].d == tr.d)) ++j;
      if (j < i) {
        ref_of[b].push_back(ref_of[b][j]);
        continue;
      }
      ref_keys.emplace_back(b, i);
      ref_of[b].push_back(ref_keys.size() - 1);
    }
  // A reference as bytes: ok, message and the positions at t_end.
  std::vector<std::pair<long, std::string>> mine;
  for (std::size_t j = 0; j < ref_keys.size(); ++j) {
    if (!comm.Owns(j)) continue;
    const auto [b, i] = ref_keys[j];
    const RunSummary r = SelfConvergenceReference(scene_of(b, blocks[b].rows[i]), blocks[b].h_ref);
    ByteWriter w;
    w.Pod<uint8_t>(r.ok);
    w.Str(r.message);
    w.Frames({r.trajectory.positions.empty() ? MatrixN3() : r.trajectory.positions.back()});
    mine.emplace_back(static_cast<long>(j), w.Take());
  }
  std::vector<std::pair<long, std::string>> refs_bytes = comm.GatherToRoot(std::move(mine));
  comm.Broadcast(&refs_bytes);
  struct RefEnd {
    bool ok = false;
    std::string message;
    MatrixN3 x_end;
  };
  std::vector<RefEnd> refs(ref_keys.size());
  for (const auto& [j, bytes] : refs_bytes) {
    ByteReader r(bytes);
    RefEnd& e = refs[static_cast<std::size_t>(j)];
    e.ok = r.Pod<uint8_t>() != 0;
    e.message = r.Str();
    e.x_end = r.Frames().at(0);
  }
  // Phase 2: one task per (η, block, row, method) in print order.
  struct RowTask {
    std::size_t eta, b, i;
    RowMethod m;
  };
  std::vector<RowTask> tasks;
  for (std::size_t e = 0; e < etas.size(); ++e)
    for (std::size_t b = 0; b < blocks.size(); ++b)
      for (std::size_t i = 0; i < blocks[b].rows.size(); ++i)
        for (const RowMethod& m : ExpandMethods({blocks[b].rows[i].method}, solvers, "--table"))
          tasks.push_back({e, b, i, m});
  mine.clear();
  for (std::size_t k = 0; k < tasks.size(); ++k) {
    if (!comm.Owns(k)) continue;
    const RowTask& t = tasks[k];
    Scene s = scene_of(t.b, blocks[t.b].rows[t.i]);
    s.solver.cg_tolerance = etas[t.eta];
    const ParticleSystem sys(s);
    const std::unique_ptr<Stepper> stepper = t.m.Make(sys, s.solver);
    RunSummary r = RunStepper(sys, *stepper, {s.h, s.t_end, s.frame_dt});
    // e_rms at t_end against the row's reference (a complete run has every frame).
    double err = -1.0;
    const RefEnd& ref = refs[ref_of[t.b][t.i]];
    if (r.ok && ref.ok && !r.trajectory.positions.empty()) {
      const double e = ErrorRms(r.trajectory.positions.back(), ref.x_end);
      if (std::isfinite(e)) err = e;
    }
    r.trajectory = Trajectory();
    r.step_stats.clear();
    ByteWriter w;
    w.Str(EncodeSummary(r));
    w.Pod(err);
    mine.emplace_back(static_cast<long>(k), w.Take());
  }
  std::vector<std::pair<long, std::string>> results = comm.GatherToRoot(std::move(mine));
  if (!comm.root()) return 0;
  std::vector<std::pair<RunSummary, double>> row_results(tasks.size());
  for (const auto& [k, bytes] : results) {
    ByteReader r(bytes);
    row_results[static_cast<std::size_t>(k)] = {DecodeSummary(r.Str()), r.Pod<double>()};
  }

  fmt::print("Table {} — tablecloth (scenes/tablecloth.toml: 20×20, 0.04 m, rho = 1, h = {:g} s, {:g} s, "
             "preconditioner {}); thesis numbers from the OCR (docs/model.md §9, thesis: IC(0)), thesis machine: "
             "Pentium III 660 MHz\n",
             which, base.h, base.t_end, ToString(base.solver.preconditioner));
  if (which == "3.2") fmt::print("k = 9000 N/m: the thesis gives numerical stiffness ~5.6e2 (k illegible)\n");
  for (std::size_t j = 0; j < ref_keys.size(); ++j)
    if (!refs[j].ok) {
      const auto [b, i] = ref_keys[j];
      fmt::print(stderr, "bench_integrators: reference (bdf2, h = {:g} s) on {} k = {:g}, d = {:g} failed: {}\n",
                 blocks[b].h_ref, blocks[b].scene_name, blocks[b].rows[i].k, blocks[b].rows[i].d, refs[j].message);
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
  auto write_row = [&](const std::string& scene_name, const ThesisRow& tr, const RowMethod& m, double eta,
                       const RunSummary& r, std::optional<double> err, double h_ref) {
    const std::string g = fmt::format("/table/row{}", index++);
    f.CreateGroup(g);
    f.SetAttribute(g, "scene", scene_name);
    f.SetAttribute(g, "integrator", tr.method);
    f.SetAttribute(g, "label", m.label());
    if (m.fully_implicit()) f.SetAttribute(g, "nonlinear_solver", std::string(ToString(m.solver)));
    f.SetAttribute(g, "k", tr.k);
    f.SetAttribute(g, "d", tr.d);
    f.SetAttribute(g, "cg_tolerance", eta);
    f.SetAttribute(g, "status", r.status);
    f.SetAttribute(g, "steps", static_cast<long>(r.steps));
    f.SetAttribute(g, "rejected_steps", static_cast<long>(r.rejected_steps));
    f.SetAttribute(g, "fixed_point_updates", r.fixed_point_updates);
    f.SetAttribute(g, "cg_iterations", r.cg_iterations);
    f.SetAttribute(g, "solver_time_s", r.solver_time_in_seconds);
    if (err) {
      f.SetAttribute(g, "error_rms_m", *err);
      f.SetAttribute(g, "reference_h", h_ref);
    }
    f.SetAttribute(g, "thesis_updates", tr.updates);
    f.SetAttribute(g, "thesis_cg_iterations", tr.cg);
    if (tr.time_s > 0) f.SetAttribute(g, "thesis_solver_time_s", tr.time_s);
  };
  std::size_t k = 0;
  for (std::size_t e = 0; e < etas.size(); ++e) {
    const double eta = etas[e];
    CountDistance distance;
    fmt::print("\ncg_tolerance = {:g}\n", eta);
    for (std::size_t b = 0; b < blocks.size(); ++b) {
      const Block& blk = blocks[b];
      if (b > 0)
        fmt::print("\nDress → avatar_drape (scenes/avatar_drape.toml: 36×36 = 1296 particles on CGAL's man.off, k = "
                   "{:g} N/m, d = {:g} N s/m, {:g} s, h = {:g} s)\n",
                   blk.scene.material.tension[0], blk.scene.material.tension_damping, blk.scene.t_end, blk.scene.h);
      fmt::print("{:<24} {:>8} {:>6} | {:>8} {:>7} {:>9} | {:>8} {:>7} {:>9} {:>7} {:>10} | {:>6} {}\n", "method",
                 "k_N/m", "d", "thesis_u", "thes_cg", "thesis_s", "updates", "cg", "solver_s", "ratio", "e_rms_m",
                 "rej", "status");
      for (std::size_t i = 0; i < blk.rows.size(); ++i) {
        const ThesisRow& tr = blk.rows[i];
        for (; k < tasks.size() && tasks[k].eta == e && tasks[k].b == b && tasks[k].i == i; ++k) {
          const RowMethod& m = tasks[k].m;
          const auto& [r, e_rms] = row_results[k];
          const std::optional<double> err = e_rms >= 0.0 ? std::optional(e_rms) : std::nullopt;
          if (r.ok) {
            distance.Add(r.fixed_point_updates, tr.updates);
            distance.Add(r.cg_iterations, tr.cg);
          }
          const std::string ratio = tr.time_s > 0 ? fmt::format("{:.3f}", r.solver_time_in_seconds / tr.time_s) : "";
          fmt::print("{:<24} {:>8g} {:>6g} | {:>8} {:>7} {:>9} | {:>8} {:>7} {:>9.3f} {:>7} {:>10} | {:>6} {}\n",
                     m.label(), tr.k, tr.d, tr.updates, tr.cg, tr.time_s > 0 ? fmt::format("{:.2f}", tr.time_s) : "",
                     r.fixed_point_updates, r.cg_iterations, r.solver_time_in_seconds, ratio,
                     err ? Sci(*err) : "", r.rejected_steps, r.status);
          write_row(blk.scene_name, tr, m, eta, r, err, blk.h_ref);
        }
      }
    }
    fmt::print("distance to the thesis' counts at cg_tolerance {:g}: mean |log10(ours/thesis)| over updates and CG = "
               "{:.3f} ({} counts)\n",
               eta, distance.mean(), distance.terms);
  }
  f.Commit();
  fmt::print("\nratio = our solver time / thesis solver time. e_rms_m: at t_end against BDF(2) at h/64 (tablecloth) or "
             "h/16 (avatar) with cg_tolerance 1e-10 and fixed-point tolerance 1e-12 m/s.\nmachine: {}, {}, {} MPI "
             "rank{}, commit {}\nresults: {}\n",
             HostName(), CompilerId(), comm.size(), comm.size() > 1 ? "s" : "", GitCommit(), out);
  return 0;
}

int Main(int argc, char** argv) {
  SweepComm comm(&argc, &argv);
  CLI::App app{"clothbench: integrators of implicit cloth simulation against a SUNDIALS CVODE reference"};
  std::string scene_path, integrators_arg, h_arg, reference = "cvode", out, rtols_arg;
  double t_end = 0.0, ref_rtol = 1e-10, cg_tolerance = 0.0, time_limit = RunLimits().time_limit_s;
  std::string series, table, preconditioner, frames_mode = "default", nonlinear_arg, plot_dir;
  std::string arkode_table = "ARK324L2SA", targets_arg = "1e-2,1e-3,1e-4", cg_tolerances_arg, substeps_arg = "1,4,16,64";
  bool work_precision_only = false, quiet = false;
  long max_runs = 0;
  app.add_option("--scene", scene_path,
                 "scene file (TOML) or built-in name (swinging_sheet, hanging_sheet, wind_sheet); default swinging_sheet");
  app.add_option("--integrators", integrators_arg,
                 "comma-separated: imex_euler,implicit_euler,sbdf2,bdf2,implicit_midpoint,sbdf3,symplectic_euler,"
                 "baraff_witkin,blender,xpbd,arkode,cvode,ida; a fully implicit method may name its nonlinear solver "
                 "(bdf2/newton), sbdf2 and bdf2 may run under error control (sbdf2/error, bdf2/newton/error), "
                 "arkode may name a higher-order IMEX pair (arkode/ark4: ARK436L2SA, arkode/ark5: ARK548L2SA), "
                 "cvode solves its Newton systems reduced to the velocities with the PCG (cvode/klu: KLU on the "
                 "first-order system) (default: the five methods, the Newton variants of implicit_euler, bdf2 and "
                 "implicit_midpoint, sbdf3, baraff_witkin, blender, xpbd, sbdf2/error, bdf2/newton/error, arkode, arkode/ark4, "
                 "arkode/ark5, cvode and cvode/klu)");
  app.add_option("--nonlinear-solver", nonlinear_arg,
                 "comma-separated fixed_point,newton: one row per solver for implicit_euler, bdf2 and "
                 "implicit_midpoint (default: the scene's solver.nonlinear_solver); also for --table");
  app.add_option("--h", h_arg,
                 "comma-separated step sizes [s] of every fixed-step row and frame steps of the substepped rows "
                 "(default: per method, multiples of the scene's h chosen so that the default scene's runs bracket "
                 "e_rms = 1e-3 m; docs/work-precision.md)");
  app.add_option("--t-end", t_end, "end time [s] (default: the scene's t_end)");
  app.add_option("--reference", reference, "cvode | ida | none");
  app.add_option("--reference-rtol", ref_rtol, "rtol (= atol) of the reference (default 1e-10)");
  std::string cvode_setting_arg;
  app.add_option("--cvode-setting", cvode_setting_arg,
                 "comma-separated KEY=VALUE setup knobs of the cvode rows (CVODE's defaults otherwise): "
                 "lsetup_frequency=20, jac_eval_frequency=51, dgmax_lsetup=0.3, stab_lim_det=0, eps_lin=0.05, atol_v_scale=1 (atol of the velocities over that of the positions); "
                 "stored as the runs' sundials_settings");
  app.add_option("--rtols", rtols_arg,
                 "rtol (= atol) list of the adaptive rows: cvode, ida, arkode, sbdf2/error, bdf2/error (default "
                 "1e-2,…,1e-7; arkode 1e-2,…,1e-6)");
  app.add_option("--substeps", substeps_arg,
                 "comma-separated substeps per frame step of the substepped rows (xpbd): one row per h and value "
                 "(default 1,4,16,64)");
  app.add_option("--arkode-table", arkode_table,
                 "ARKODE IMEX pair: ARK324L2SA (default), ARK436L2SA, ARK437L2SA, ARK548L2SA, ARK548L2SAb");
  app.add_option("--targets", targets_arg, "e_rms targets [m] of the equal-accuracy table (default 1e-2,1e-3,1e-4)");
  app.add_option("--cg-tolerances", cg_tolerances_arg,
                 "comma-separated CG tolerances: every method that uses the PCG runs once per value (a second "
                 "axis of the work-precision table)");
  app.add_flag("--work-precision", work_precision_only,
               "print only the equal-accuracy table (it is also printed under the default table)");
  app.add_option("--cg-tolerance", cg_tolerance, "override the scene's solver.cg_tolerance (PCG stop ‖r‖ ≤ η‖Sb‖)");
  app.add_option("--preconditioner", preconditioner,
                 "override the scene's solver.preconditioner: ic0 | cholesky | amg | jacobi | none");
  app.add_option("--frames", frames_mode,
                 "which frames the file keeps (errors and energies always use every frame_dt): default: positions "
                 "every frame_dt for the reference and each method's first row, at t = 0 and t_end for the other "
                 "rows, velocities at t = 0 and t_end | all: positions and velocities every frame_dt | positions: "
                 "positions every frame_dt, velocities at the ends | ends: only t = 0 and t_end are computed and "
                 "kept (errors and energies at the ends) | none: no frame datasets (errors at t_end still computed)");
  app.add_option("--series", series,
                 "write every step (t, h, updates, CG iterations, colliding particles) as CSV to FILE and print the "
                 "impact / resting-contact summary (thesis Fig. 4.3)");
  app.add_option("--table", table,
                 "print the thesis' Table 3.1 or 3.2 beside ours with e_rms against a self-convergence reference, "
                 "once per --cg-tolerances value (and write HDF5)");
  app.add_option("--out", out, "result file (default: out/<scene>.h5)");
  app.add_option("--max-runs", max_runs,
                 "compute at most N runs (the reference counts as one) not yet in <out>.journal/, then stop with exit "
                 "status 75 and keep the journal; rerun the same command to continue")
      ->check(CLI::Range(1L, 1000000000L));
  app.add_option("--time-limit", time_limit,
                 "wall-time budget of each run [s] (default 3600): a run past it ends with status time_limit and the "
                 "other rows still run and are written");
  app.add_flag("--quiet", quiet, "no progress line on stderr (it is shown only when stderr is a terminal and a run takes "
                                 "more than 2 s)");
  app.add_option("--plot", plot_dir,
                 "after writing the results, draw them into DIR with scripts/plot (work-precision, observed order, "
                 "energy, Fig. 4.3 on obstacle scenes; PNG and SVG)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return comm.root() ? app.exit(e) : 0;
  } catch (const CLI::ParseError& e) {
    if (comm.root()) fmt::print(stderr, "bench_integrators: {}\n", EscapeControl(e.what()));
    return 2;
  }
  InstallInterruptHandlers();
  // Every rank refuses the same input; rank 0 says so.
  const auto refuse = [&comm](const std::string& what) {
    if (comm.root()) fmt::print(stderr, "bench_integrators: {}\n", EscapeControl(what));
    return 2;
  };

  try {
    std::vector<NonlinearSolver> solvers;
    try {
      if (app.count("--nonlinear-solver"))
        for (const std::string& n : SplitList(nonlinear_arg)) solvers.push_back(ParseNonlinearSolver(n, "--nonlinear-solver"));
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
    std::vector<double> etas;
    if (app.count("--cg-tolerances")) {
      etas = ParsePositiveList(cg_tolerances_arg, "--cg-tolerances");
      for (double e : etas)
        if (!(e < 1.0)) throw UsageError(fmt::format("--cg-tolerances: {:g} must be in (0, 1)", e));
    }
    if (!table.empty())
      return RunThesisTable(table, out,
                            app.count("--preconditioner") ? std::optional(ParsePreconditioner(preconditioner))
                                                          : std::nullopt,
                            solvers, etas, comm);
    // Validate everything before computing anything.
    Scene scene = scene_path.empty() ? DefaultScene() : LoadSceneOrBuiltin(scene_path);
    if (app.count("--t-end")) {
      if (!std::isfinite(t_end) || !(t_end > 0.0) || t_end > 1e6)
        throw UsageError(fmt::format("--t-end: {} is not a number in (0, 1e6] s", t_end));
      scene.t_end = t_end;
      scene.frame_dt = std::min(scene.frame_dt, t_end);
      scene.h = std::min(scene.h, t_end);
      CheckRunLength(scene, fmt::format("--t-end {:g} on {}", t_end, scene.source));
    }
    if (!std::isfinite(time_limit) || !(time_limit > 0.0))
      throw UsageError(fmt::format("--time-limit: {} is not a positive number of seconds", time_limit));
    if (app.count("--cg-tolerance")) {
      if (!(cg_tolerance > 0.0 && cg_tolerance < 1.0))
        throw UsageError(fmt::format("--cg-tolerance: {} must be in (0, 1)", cg_tolerance));
      scene.solver.cg_tolerance = cg_tolerance;
    }
    if (app.count("--preconditioner")) scene.solver.preconditioner = ParsePreconditioner(preconditioner);
    if (frames_mode != "default" && frames_mode != "positions" && frames_mode != "all" && frames_mode != "ends" &&
        frames_mode != "none")
      throw UsageError(fmt::format("--frames: \"{}\" must be default, all, positions, ends or none", frames_mode));
    // ends/none keep t = 0 and t_end only (frame_dt = t_end); none also
    // leaves the frame datasets out of the file.
    if (frames_mode == "ends" || frames_mode == "none") scene.frame_dt = scene.t_end;
    if (reference != "cvode" && reference != "ida" && reference != "none")
      throw UsageError(fmt::format("--reference: \"{}\" must be cvode, ida or none", reference));
    if (!(ref_rtol > 0.0) || !std::isfinite(ref_rtol)) throw UsageError("--reference-rtol: must be a positive number");
    CvodeSettings cvode_settings;
    if (app.count("--cvode-setting"))
      for (const std::string& kv : SplitList(cvode_setting_arg)) {
        const std::size_t eq = kv.find('=');
        std::string why;
        if (eq == std::string::npos || !cvode_settings.Set(kv.substr(0, eq), kv.substr(eq + 1), &why))
          throw UsageError(fmt::format("--cvode-setting: {}", why.empty() ? "\"" + kv + "\" is not KEY=VALUE" : why));
      }
    std::vector<std::string> names;
    if (integrators_arg.empty()) {
      // The five methods with the scene's nonlinear solver, each fully
      // implicit one also with Newton, Baraff–Witkin and CVODE.
      for (Method m : AllMethods()) {
        names.emplace_back(ToString(m));
        if (IsFullyImplicit(m) && !app.count("--nonlinear-solver") &&
            scene.solver.nonlinear_solver != NonlinearSolver::kNewton)
          names.push_back(std::string(ToString(m)) + "/newton");
      }
      names.emplace_back(ToString(Method::kSbdf3));
      names.emplace_back(kBaraffWitkinName);
      names.emplace_back(kBlenderName);
      names.emplace_back(kXpbdName);
      names.emplace_back("sbdf2/error");
      names.emplace_back("bdf2/newton/error");
      names.emplace_back(kArkodeName);
      names.emplace_back(std::string(kArkodeName) + "/ark4");
      names.emplace_back(std::string(kArkodeName) + "/ark5");
      names.emplace_back("cvode");
      names.emplace_back("cvode/klu");
    } else {
      names = SplitList(integrators_arg);
    }
    if (solvers.empty()) solvers = {scene.solver.nonlinear_solver};
    std::vector<RowMethod> methods;
    try {
      methods = ExpandMethods(names, solvers, "--integrators");
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
    for (std::size_t a = 0; a < methods.size(); ++a)
      for (std::size_t b = 0; b < a; ++b)
        if (methods[a].label() == methods[b].label())
          throw UsageError(fmt::format("--integrators: {} is listed twice (with --nonlinear-solver, \"bdf2\" also "
                                       "names bdf2/newton)",
                                       methods[a].label()));
    if (std::find(ArkodeTableNames().begin(), ArkodeTableNames().end(), arkode_table) == ArkodeTableNames().end()) {
      std::string known;
      for (const std::string& t : ArkodeTableNames()) known += (known.empty() ? "" : ", ") + t;
      throw UsageError(fmt::format("--arkode-table: \"{}\" must be one of {}", arkode_table, known));
    }
    const std::vector<double> targets = ParsePositiveList(targets_arg, "--targets");
    if (etas.empty()) etas = {scene.solver.cg_tolerance};
    std::vector<double> hs = h_arg.empty() ? std::vector<double>{} : ParsePositiveList(h_arg, "--h");
    for (double h : hs)
      if (h > scene.t_end) throw UsageError(fmt::format("--h: {:g} s is larger than t_end = {:g} s", h, scene.t_end));
    const std::vector<double> rtols =
        app.count("--rtols") ? ParsePositiveList(rtols_arg, "--rtols") : std::vector<double>{};
    std::vector<int> substeps;
    for (double n : ParsePositiveList(substeps_arg, "--substeps")) {
      if (n != std::floor(n) || n > 1e6)
        throw UsageError(fmt::format("--substeps: {:g} must be a whole number from 1 to 1e6", n));
      substeps.push_back(static_cast<int>(n));
    }
    // Each row's (param, substeps) in run order: h or rtol decreasing;
    // substepped rows by their substep h/n decreasing (ties: larger frame
    // step first), so that consecutive rows refine one step size. Without
    // --h / --rtols, each method's defaults (DefaultRowParams).
    std::vector<std::vector<std::pair<double, int>>> params(methods.size());
    std::vector<std::size_t> n_params;
    double step_records = 0.0;  // fixed-step and substepped rows; adaptive ones take far fewer
    for (std::size_t k = 0; k < methods.size(); ++k) {
      const RowMethod& m = methods[k];
      const DefaultParams d = DefaultRowParams(m);
      std::vector<double> mh = hs;
      if (mh.empty())
        for (double f : d.h_factors)
          if (f * scene.h <= scene.t_end) mh.push_back(f * scene.h);
      if (mh.empty()) mh = {scene.h};
      std::sort(mh.begin(), mh.end(), std::greater<>());
      auto& ps = params[k];
      if (m.kind() == StepKind::kSubstepped) {
        for (double h : mh)
          for (int n : substeps) ps.emplace_back(h, n);
        std::stable_sort(ps.begin(), ps.end(),
                         [](const auto& a, const auto& b) { return a.first / a.second > b.first / b.second; });
      } else if (m.kind() == StepKind::kFixedStep) {
        for (double h : mh) ps.emplace_back(h, 1);
      } else {
        for (double r : rtols.empty() ? d.rtols : rtols) ps.emplace_back(r, 1);
      }
      n_params.push_back(ps.size());
      // The longest fixed-step or substepped run must stay within the step limit.
      if (m.kind() != StepKind::kAdaptive)
        for (const auto& [h, n] : ps) {
          step_records += std::ceil(scene.t_end / h * n) * static_cast<double>(m.uses_pcg() ? etas.size() : 1);
          if (scene.t_end / h * n > kMaxStepsPerRun)
            throw UsageError(fmt::format("{}: {} at h = {:g} s{} needs t_end/h = {:.3g} steps, more than the limit of "
                                         "{:g} (solver/run.h, RunLimits)",
                                         hs.empty() ? "scene h" : (n > 1 ? "--h/--substeps" : "--h"), m.label(), h,
                                         n > 1 ? fmt::format(" with {} substeps", n) : "", scene.t_end / h * n,
                                         kMaxStepsPerRun));
        }
    }
    CheckMemory(scene, methods, n_params, etas.size(), reference, step_records);
    if (!plot_dir.empty()) {
      try {
        CheckPlotDir(plot_dir);
      } catch (const std::invalid_argument& e) {
        throw UsageError(e.what());
      }
    }
    if (out.empty()) out = fmt::format("out/{}.h5", scene.name);
    CheckOutputFolder(out);

    // The sweep: the reference (task 0, if any) and every row in table
    // order. Under mpirun/srun the tasks are dealt over the ranks and rank 0
    // assembles, prints and writes; every finished task is journalled in
    // <out>.journal/, so that the same command rerun after an interruption
    // computes only the missing ones (bench/sweep.h).
    struct RowTask {
      std::size_t mk, block;  // method; block of rows whose observed orders chain (method, η)
      double eta, param;
      int substeps;
    };
    std::vector<RowTask> row_tasks;
    {
      std::size_t block = 0;
      for (std::size_t mk = 0; mk < methods.size(); ++mk)
        for (double eta : methods[mk].uses_pcg() ? etas : std::vector<double>{scene.solver.cg_tolerance}) {
          for (const auto& [p, n] : params[mk]) row_tasks.push_back({mk, block, eta, p, n});
          ++block;
        }
    }
    const long n_ref = reference != "none" ? 1 : 0;
    const long n_tasks = n_ref + static_cast<long>(row_tasks.size());
    // The model last: it loads the mesh obstacles, whose errors are refusals
    // too; the journal exists only for a run that is not refused.
    const ParticleSystem sys(scene);
    RecordJournal journal(out + ".journal", JournalKey(argc, argv, scene), comm);
    std::vector<long> missing;
    std::size_t stored = 0;
    if (comm.root()) {
      const std::vector<long> have = journal.Stored();
      for (long k = 0; k < n_tasks; ++k)
        if (!std::binary_search(have.begin(), have.end(), k)) missing.push_back(k);
      stored = static_cast<std::size_t>(n_tasks) - missing.size();
    }
    comm.Broadcast(&missing);
    const std::size_t to_compute =
        max_runs > 0 ? std::min(missing.size(), static_cast<std::size_t>(max_runs)) : missing.size();
    if (comm.root() && (stored > 0 || comm.size() > 1 || to_compute < missing.size()))
      fmt::print("{} of {} runs from {}; computing {} on {} rank{}\n", stored, n_tasks, journal.path(), to_compute,
                 comm.size(), comm.size() > 1 ? "s" : "");

    TerminalProgress progress(!quiet && comm.root());
    RunLimits limits;
    limits.time_limit_s = time_limit;
    ReferenceOptions ref_opts{ref_rtol, -1.0, 5, scene.t_end, scene.frame_dt, limits};
    // CVODE and IDA have no collision response: on obstacle scenes the
    // reference is a self-convergence run, BDF(2) at h_min/16 (without
    // --h: h/128) with tight CG and fixed-point tolerances.
    const bool self_convergence = !sys.obstacles().empty();
    const double h_ref = (hs.empty() ? scene.h / 8.0 : *std::min_element(hs.begin(), hs.end())) / 16.0;
    const auto reference_failed = [&](const RunSummary& r) {
      if (journal.Stored().empty()) journal.Remove();  // nothing to resume
      if (self_convergence)
        fmt::print(stderr, "bench_integrators: self-convergence reference (bdf2, h = {:g} s) failed: {}\n", h_ref,
                   r.message);
      else
        fmt::print(stderr, "bench_integrators: {} reference at rtol {:g} failed: {}\n", reference, ref_rtol, r.message);
      return 1;
    };
    const RunContext ctx{arkode_table, limits, "", app.count("--preconditioner") > 0, cvode_settings};
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
    for (std::size_t j = 0; j < to_compute; ++j) {
      if (!comm.Owns(j)) continue;
      const long k = missing[j];
      if (k < n_ref) {
        RunSummary r;
        if (self_convergence) {
          progress.Start(fmt::format("reference bdf2 h = {:g} s", h_ref), scene.t_end);
          r = SelfConvergenceReference(scene, h_ref);
        } else {
          progress.Start(fmt::format("reference {} rtol {:g}", reference, ref_rtol), scene.t_end);
          r = reference == "ida" ? RunIda(sys, ref_opts) : RunCvode(sys, ref_opts);
        }
        if (!r.ok && comm.size() == 1) return reference_failed(r);  // serial: before any row
        std::string bytes = EncodeSummary(r);
        if (r.ok) journal_store(k, bytes);  // a failed reference is computed again by a rerun
        if (comm.root()) own_ref.emplace(k, std::move(r));
        else outgoing.emplace_back(k, std::move(bytes));
        continue;
      }
      const RowTask& t = row_tasks[static_cast<std::size_t>(k - n_ref)];
      const RowMethod& m = methods[t.mk];
      SolverSpec spec = scene.solver;
      spec.cg_tolerance = t.eta;
      progress.Start(m.kind() == StepKind::kAdaptive     ? fmt::format("{} rtol {:g}", m.label(), t.param)
                     : m.kind() == StepKind::kSubstepped ? fmt::format("{} h = {:g} s/{}", m.label(), t.param, t.substeps)
                                                         : fmt::format("{} h = {:g} s", m.label(), t.param),
                     scene.t_end);
      Row r = m.Run(sys, scene, spec, t.param, ctx, t.substeps);
      if (etas.size() > 1 && m.uses_pcg()) {
        r.id += fmt::format("_eta{:g}", t.eta);
        r.label += fmt::format(" eta={:g}", t.eta);
      }
      std::string bytes = EncodeRun(r);
      journal_store(k, bytes);
      if (comm.root()) own_rows.emplace(k, std::move(r));
      else outgoing.emplace_back(k, std::move(bytes));
    }
    progress.Finish();
    std::vector<std::pair<long, std::string>> received = comm.GatherToRoot(std::move(outgoing));
    if (!comm.root()) return 0;
    if (to_compute < missing.size()) {
      fmt::print("stopped after {} runs (--max-runs): {} of {} done; rerun the same command to continue ({})\n",
                 to_compute, stored + to_compute, n_tasks, journal.path());
      return kExitPartial;
    }
    // Assemble in task order: own results, then other ranks', then the journal's.
    std::map<long, std::string> bytes_of(std::make_move_iterator(received.begin()),
                                         std::make_move_iterator(received.end()));
    const auto bytes = [&](long k) {
      const auto it = bytes_of.find(k);
      return it != bytes_of.end() ? std::move(it->second) : journal.Load(k);
    };
    std::optional<RunSummary> ref;
    if (n_ref) {
      try {
        ref = own_ref.count(0) ? std::move(own_ref.at(0)) : DecodeSummary(bytes(0));
      } catch (const std::runtime_error& e) {
        throw std::runtime_error(fmt::format("{}: run 0: {}; delete the folder and rerun", journal.path(), e.what()));
      }
      if (!ref->ok) return reference_failed(*ref);
    }
    std::vector<Row> rows;
    for (std::size_t i = 0; i < row_tasks.size(); ++i) {
      const long k = n_ref + static_cast<long>(i);
      try {
        rows.push_back(own_rows.count(k) ? std::move(own_rows.at(k)) : DecodeRun(bytes(k)));
      } catch (const std::runtime_error& e) {
        throw std::runtime_error(fmt::format("{}: run {}: {}; delete the folder and rerun", journal.path(), k, e.what()));
      }
      Row& r = rows.back();
      if (r.ok) r.energy = ComputeEnergies(sys, r.traj);
      if (ref && r.ok) r.err = CompareTrajectories(r.traj.positions, ref->trajectory.positions);
      // Observed order against the (sub)step h/n within one block, and for
      // adaptive rows against the mean accepted step t_end/steps; none
      // between two rows with the same one.
      const bool adaptive = methods[row_tasks[i].mk].kind() == StepKind::kAdaptive;
      const auto step = [&](const Row& q) {
        if (adaptive) return q.steps > 0 ? scene.t_end / static_cast<double>(q.steps) : 0.0;
        return q.substeps > 0 ? q.h / q.substeps : q.h;
      };
      if (i > 0 && row_tasks[i - 1].block == row_tasks[i].block && r.err && rows[i - 1].err &&
          step(rows[i - 1]) != step(r) && step(r) > 0.0 && step(rows[i - 1]) > 0.0)
        r.order = ObservedOrder(step(rows[i - 1]), rows[i - 1].err->rms_at_end, step(r), r.err->rms_at_end);
    }
    const EqualAccuracyTable wp = WorkPrecision(rows, targets);
    const RunTable run_table = MakeRunTable(scene, sys, ref, ref_opts, rows, frames_mode, ref ? &wp : nullptr);
    if (!work_precision_only) PrintRunTable(stdout, run_table);
    if (ref) PrintWorkPrecision(stdout, wp);
    if (!series.empty()) WriteSeries(series, rows);
    WriteResults(out, scene, sys, ref, ref_opts, rows, run_table, comm.size());
    journal.Remove();
    const std::string xdmf = WriteXdmf(out);
    fmt::print("results: {}\n", out);
    if (!xdmf.empty()) fmt::print("ParaView: {}\n", xdmf);
    if (!plot_dir.empty()) Plot("bench_integrators", out, plot_dir);
    return 0;
  } catch (const UsageError& e) {
    return refuse(e.what());
  } catch (const SceneError& e) {
    return refuse(e.what());
  } catch (const SweepJournal::Mismatch& e) {
    return refuse(e.what());
  } catch (const Interrupted& e) {
    if (comm.root())
      fmt::print(stderr, "bench_integrators: interrupted by {}; no result file written, finished runs kept in {}.journal\n",
                 SignalName(e.signal), out);
    comm.Abort(128 + e.signal);
  } catch (const std::bad_alloc&) {
    fmt::print(stderr, "bench_integrators: out of memory although the run fitted the memory estimate; no result file "
                       "written (use --frames ends|none or fewer rows)\n");
    comm.Abort(1);
  } catch (const std::exception& e) {
    fmt::print(stderr, "bench_integrators: {}{}\n", comm.mpi() ? fmt::format("rank {}: ", comm.rank()) : "",
               EscapeControl(e.what()));
    comm.Abort(1);
  }
}

}  // namespace
}  // namespace clothbench

int main(int argc, char** argv) { return clothbench::Main(argc, argv); }
