// Result writing of bench_integrators: the run table, the HDF5 file
// (docs/guide/results-schema.md), the Fig. 4.3 series and the equal-accuracy table.
#include "harness/result_writer.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "collision/obstacle_proximity.h"
#include "collision/shapes/triangle_mesh.h"
#include "results/metrics.h"
#include "results/result_file.h"
#include "results/result_reader.h"
#include "results/run_records.h"
#include "model/output_file.h"
#include "results/work_precision.h"

namespace clothbench {

using Row = MethodRun;


void WriteEnergy(ResultFile& f, const std::string& g, const EnergySeries& e) {
  f.CreateGroup(g + "/energy");
  for (const EnergyField& field : EnergySeriesFields())
    if (field.Stored(e)) f.WriteVector(g + "/energy/" + field.name, e.*field.member, "J");
  f.WriteVectors3(g + "/momentum", e.momentum, "kg m/s");
}

// A SUNDIALS run's counters as attributes of group g (those it counted).
void WriteSundialsStats(ResultFile& f, const std::string& g, const SundialsStats& s) {
  for (auto [name, v] : {std::pair{"nst", s.nst}, {"nfe", s.nfe}, {"nfe_i", s.nfe_i}, {"nni", s.nni}, {"nli", s.nli},
                         {"netf", s.netf}, {"ncfn", s.ncfn}, {"nje", s.nje}, {"nsetups", s.nsetups}})
    if (v >= 0) f.SetAttribute(g, name, v);
}

// A run's self-contact data under group g (docs/guide/results-schema.md): the
// crossing triangle pairs of every frame, where counted, and the response's
// counters and times as attributes of g/self_contact.
void WriteSelfContact(ResultFile& f, const std::string& g, const RunSummary& r) {
  const std::vector<int32_t>& crossings = r.trajectory.crossing_pairs;
  if (!crossings.empty()) f.WriteTable(g + "/crossing_pairs", static_cast<int>(crossings.size()), 1, crossings);
  if (!r.self_contact) return;
  const SelfContactStats& s = *r.self_contact;
  const std::string sc = g + "/self_contact";
  f.CreateGroup(sc);
  for (const auto& [name, v] : s.Counts()) f.SetAttribute(sc, name, v);
  f.SetAttribute(sc, "detection_s", s.detection_seconds);
  f.SetAttribute(sc, "response_s", s.response_seconds);
  f.SetAttribute(sc, "work_J", s.work);
}

// Writes a trajectory's frames under group g: "positions" / "velocities"
// [F, N, 3] at every frame (aligned with g/times) when `every_*` is set,
// else "positions_ends" / "velocities_ends" [2, N, 3] at t = 0 and t_end;
// plus per-frame views g/frame_views/<name>_<k> for XDMF readers.
// Double-precision trajectories compress only ~1.2× losslessly, so which
// frames are kept is what sets the file size (docs/guide/results-schema.md).
void WriteTrajectoryFrames(ResultFile& f, const std::string& g, const Trajectory& traj, bool every_position,
                           bool every_velocity) {
  const auto write = [&](const std::vector<MatrixN3>& frames, bool every, const std::string& name,
                         const std::string& units) {
    if (frames.empty()) return;
    // A trajectory cut to its ends (KeepOnlyStoredFrames) holds 2 frames for more times.
    const bool all = frames.size() == traj.times.size() && (every || frames.size() <= 2);
    const std::string path = g + "/" + name + (all ? "" : "_ends");
    if (all) f.WriteFrames(path, frames, units);
    else f.WriteFrames(path, {frames.front(), frames.back()}, units);
    f.WriteFrameViews(path, g + "/frame_views/" + name + "_");
  };
  write(traj.positions, every_position, "positions", "m");
  write(traj.velocities, every_velocity, "velocities", "m/s");
  // The thesis' virtual particles of every frame (model/trajectory.h).
  const VirtualFrames& v = traj.virtual_particles;
  if (v.empty()) return;
  const std::string vg = g + "/virtual_particles";
  f.CreateGroup(vg);
  const auto rows = [](const std::vector<int32_t>& values, int cols) { return static_cast<int>(values.size()) / cols; };
  f.WriteTable(vg + "/offsets", rows(v.offsets, 1), 1, v.offsets);
  f.WriteTable(vg + "/positions", static_cast<int>(v.x.size() / 3), 3, v.x, "m");
  f.WriteTable(vg + "/cloth_edge", rows(v.cloth_edge, 2), 2, v.cloth_edge);
  f.WriteTable(vg + "/obstacle_edge", rows(v.obstacle_edge, 2), 2, v.obstacle_edge);
  f.WriteTable(vg + "/face_offsets", rows(v.face_offsets, 1), 1, v.face_offsets);
  f.WriteTable(vg + "/faces", rows(v.faces, 3), 3, v.faces);
  f.WriteVector(vg + "/tension_energy", v.tension_energy, "J");
}

// The table's content as plain data (results/run_table.h): what is printed
// and what the file stores, so that clothbench_inspect can print it again.
void CompareToReference(const ParticleSystem& sys, const RunSummary* ref, double t_end, ErrorMetric metric,
                        std::vector<MethodRun>* rows) {
  const auto step = [&](const MethodRun& q) {
    const StepKindSpec& k = SpecOf(q.kind());
    if (k.adaptive()) return q.steps > 0 ? t_end / static_cast<double>(q.steps) : 0.0;
    return k.count_divides_h && q.*k.count_field > 0 ? q.h / static_cast<double>(q.*k.count_field) : q.h;
  };
  for (std::size_t i = 0; i < rows->size(); ++i) {
    MethodRun& r = (*rows)[i];
    // A run whose frames were cut to what the file keeps (KeepOnlyStoredFrames)
    // was compared before: its energies and errors stand.
    const Trajectory& tr = r.trajectory;
    const bool compared = tr.positions.size() != tr.times.size() || tr.velocities.size() != tr.times.size();
    // The energies of every frame a run kept, a failed run's too (its frames
    // passed the blow-up guard, so they are finite): the file's energy
    // series is as long as its times. dE/dt and the contact power are an ok
    // run's only.
    if (!compared) {
      r.energy = ComputeEnergies(sys, r.trajectory);
      if (r.ok()) {
        if (r.energy.t.size() >= 2 && std::isfinite(r.energy.Rate())) r.energy_rate_W = r.energy.Rate();
        if (std::isfinite(r.energy.ContactPower())) r.contact_power_W = r.energy.ContactPower();
      }
    }
    if (ref && r.ok() && !compared) r.err = CompareTrajectories(r.trajectory, ref->trajectory);
    if (r.err) {  // only where they exist: no NaN is ever written
      r.error_final_m = r.err->rms_at_end;
      r.error_l2_m = r.err->rms_l2;
      r.error_max_m = r.err->rms_max;
      r.error_mean_m = r.err->mean_at_end;
      r.error_final_mps = r.err->v_rms_at_end;
      r.error_l2_mps = r.err->v_rms_l2;
      r.error_max_mps = r.err->v_rms_max;
    }
    if (i == 0) continue;
    const MethodRun& p = (*rows)[i - 1];
    if (p.label == r.label && r.err && p.err && step(p) != step(r) && step(r) > 0.0 && step(p) > 0.0) {
      const double order = ObservedOrder(step(p), p.err->Of(metric), step(r), r.err->Of(metric));
      if (std::isfinite(order)) r.observed_order = order;
    }
  }
}

RunTable MakeRunTable(const Scene& scene, const ParticleSystem& sys, const std::optional<RunSummary>& ref,
                      const std::vector<Row>& rows, const std::string& frames_mode,
                      const EqualAccuracyTable* wp, ErrorMetric metric) {
  RunTable t;
  t.error_metric = std::string(ToString(metric));
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
  t.amg_frames = ToString(scene.solver.amg_frames);
  t.max_updates = scene.solver.max_updates;
  const SolverSpec& sv = scene.solver;
  t.cholesky_ordering = ToString(sv.cholesky_ordering);
  t.contact_factors = sv.contact_factors ? "true" : "false";
  t.tangent_projection = ToString(sv.tangent_projection);
  t.newton_jacobian = ToString(sv.newton_jacobian);
  t.contact_history = ToString(sv.contact_history);
  t.friction_law = ToString(sv.friction_law);
  t.friction_cap = ToString(sv.friction_cap);
  t.controller_updates = std::to_string(sv.controller_updates[0]) + "," + std::to_string(sv.controller_updates[1]);
  t.cg_max_iterations = sv.cg_max_iterations;
  t.max_rejections = sv.max_rejections;
  t.fixed_point_tolerance = sv.fixed_point_tolerance;
  t.step_factor = sv.step_factor;
  t.h_min = sv.h_min;
  t.h_max = sv.h_max;
  if (ref) {
    // The reference's record as its run filled it (CVODE/IDA adaptive at
    // its rtol and atol, or the fixed-step self-convergence run), under the id
    // "reference", with its energies.
    RunRecord rr = *ref;
    NameReference(scene, &rr);
    const EnergySeries e = ComputeEnergies(sys, ref->trajectory);
    if (e.t.size() >= 2 && std::isfinite(e.Rate())) rr.energy_rate_W = e.Rate();
    if (std::isfinite(e.ContactPower())) rr.contact_power_W = e.ContactPower();
    t.reference = rr;
  }
  t.runs.assign(rows.begin(), rows.end());  // the records (CompareToReference filled errors and energies)
  if (wp) t.work_precision = *wp;
  return t;
}

namespace {

// The cloth's quads, once: (i, j), (i+1, j), (i+1, j+1), (i, j+1), 0-based
// particle indices, counter-clockwise in (u, v); on a cloth of patterns
// every pattern's, in the sewn cloth's numbering (ClothLayout::quads). And
// a garment's sewn start (solver/sewing.h): every run starts from it, and a
// rerun reads it instead of sewing again.
void WriteCloth(ResultFile& f, const Scene& scene) {
  const int nu = scene.grid.nu, nv = scene.grid.nv;
  std::vector<int32_t> faces;
  if (scene.cloth) {
    for (const std::array<int, 4>& q : scene.cloth->quads) faces.insert(faces.end(), q.begin(), q.end());
  } else {
    faces.reserve(static_cast<std::size_t>(4 * (nu - 1) * (nv - 1)));
    for (int j = 0; j + 1 < nv; ++j)
      for (int i = 0; i + 1 < nu; ++i)
        for (int q : {scene.Index(i, j), scene.Index(i + 1, j), scene.Index(i + 1, j + 1), scene.Index(i, j + 1)})
          faces.push_back(q);
  }
  f.WriteTable("/scene/faces", static_cast<int>(faces.size() / 4), 4, faces);
  if (scene.cloth && scene.sewing_time > 0.0) {
    const MatrixN3& x = scene.cloth->start;
    std::vector<double> rows(static_cast<std::size_t>(x.size()));
    for (Eigen::Index p = 0; p < x.rows(); ++p)
      for (int c = 0; c < 3; ++c) rows[static_cast<std::size_t>(3 * p + c)] = x(p, c);
    f.WriteTable("/scene/sewn_start", static_cast<int>(x.rows()), 3, rows, "m");
    f.SetAttribute("/scene/sewn_start", "largest_gap_m", scene.cloth->largest_gap);
  }
}

// Triangle-mesh obstacles, placed (scale, rotate, translate; keyframed
// motion not applied), for the XDMF file; and the polyhedron and edges of
// every obstacle with virtual particles (Obstacle::Surface, ::Edges at
// rest), which their frames' obstacle_edge indices refer to. A deforming
// obstacle (a mesh sequence, a skeleton) is stored at t = 0, and its
// surface at frame times as `times` and `positions` [F, V, 3] for the
// report page and ParaView: every frame_dt, or every k-th where F·V
// would pass kMaxBodyPoints (a picture of the motion, not its data).
void WriteObstacles(ResultFile& f, const Scene& scene, const ParticleSystem& sys) {
  constexpr double kMaxBodyPoints = 2.5e5;  // 6 MB of doubles
  for (std::size_t k = 0; k < sys.obstacles().size(); ++k) {
    const Obstacle& obstacle = sys.obstacles()[k];
    const TriangleMesh* mesh = obstacle.mesh();
    const bool deforms = obstacle.shape().deforms();
    const bool body = deforms || scene.obstacles[k].shape->deforms();  // or one `held` still
    if (!mesh && !obstacle.spec().virtual_particles && !body) continue;
    const std::string o = fmt::format("/scene/obstacles/{}", k);
    std::vector<double> vertices;
    std::vector<int32_t> triangles;
    std::vector<Vector3> points;
    std::vector<std::array<int, 3>> faces;
    if (deforms) {
      obstacle.PoseAt(0.0).deformed->Surface(&points, &faces);
    } else if (mesh && !body) {
      mesh->Export(&vertices, &triangles);
    } else {
      obstacle.Surface(&points, &faces);
    }
    for (const Vector3& p : points) vertices.insert(vertices.end(), {p.x(), p.y(), p.z()});
    for (const auto& t : faces) triangles.insert(triangles.end(), t.begin(), t.end());
    f.CreateGroup(o);
    // Absolute, so that the file names the mesh wherever it is read
    // (clothbench_inspect's command links it next to the scene file).
    if (mesh && !body) f.SetAttribute(o, "path", std::filesystem::absolute(obstacle.shape().file()).lexically_normal().string());
    f.WriteTable(o + "/vertices", static_cast<int>(vertices.size() / 3), 3, vertices, "m");
    f.WriteTable(o + "/triangles", static_cast<int>(triangles.size() / 3), 3, triangles);
    if (deforms && !points.empty() && scene.frame_dt > 0.0) {
      const double frames = std::floor(scene.t_end / scene.frame_dt + 1e-9) + 1.0;
      const double stride = std::max(1.0, std::ceil(frames * static_cast<double>(points.size()) / kMaxBodyPoints));
      std::vector<double> times;
      for (double j = 0.0; j * stride * scene.frame_dt < scene.t_end - 1e-9 * scene.frame_dt; j += 1.0)
        times.push_back(j * stride * scene.frame_dt);
      times.push_back(scene.t_end);
      std::vector<MatrixN3> at;
      for (const double t : times) {
        obstacle.PoseAt(t).deformed->Surface(&points, &faces);
        MatrixN3& x = at.emplace_back(static_cast<Eigen::Index>(points.size()), 3);
        for (std::size_t i = 0; i < points.size(); ++i) x.row(static_cast<Eigen::Index>(i)) = points[i].transpose();
      }
      f.WriteVector(o + "/times", times, "s");
      f.WriteFrames(o + "/positions", at);
      f.WriteFrameViews(o + "/positions", o + "/frame_views/positions_");
    }
    if (obstacle.spec().virtual_particles) {
      std::vector<Vector3> points;
      std::vector<std::array<int, 2>> edges;
      obstacle.Edges(ObstaclePose{}, &points, &edges);
      std::vector<int32_t> flat;
      for (const auto& e : edges) flat.insert(flat.end(), e.begin(), e.end());
      f.WriteTable(o + "/edges", static_cast<int>(edges.size()), 2, flat);
    }
  }
}

}  // namespace

void WriteResults(const std::string& path, const Scene& scene, const ParticleSystem& sys,
                  const std::optional<RunSummary>& ref, const std::vector<Row>& rows,
                  const RunTable& table, long mpi_ranks) {
  const std::string& frames_mode = table.frames;
  const bool write_frames = frames_mode != "none";
  ResultFile f(path);
  WriteProvenance(f);
  f.SetAttribute("/", "mpi_ranks", mpi_ranks);
  f.SetAttribute("/", "error_metric", table.error_metric);
  f.CreateGroup("/scene");
  WriteSceneRecord(f, table);
  f.WriteString("/scene/toml", scene.toml);  // a dataset: scene files of any size
  WriteCloth(f, scene);
  WriteObstacles(f, scene, sys);
  if (ref) {
    f.CreateGroup("/reference");
    WriteRunRecord(f, "/reference", *table.reference);
    if (ref->sundials) WriteSundialsStats(f, "/reference", *ref->sundials);
    f.WriteVector("/reference/times", ref->trajectory.times, "s");
    if (write_frames)
      WriteTrajectoryFrames(f, "/reference", ref->trajectory, true, frames_mode == "all" || frames_mode == "ends");
    WriteEnergy(f, "/reference", ComputeEnergies(sys, ref->trajectory));
    f.WriteStepStats("/reference/step_stats", StepRecords(*ref));
  }
  f.CreateGroup("/runs");
  std::string last_label;
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const Row& r = rows[k];
    const std::string g = "/runs/" + r.id;
    f.CreateGroup(g);
    WriteRunRecord(f, g, table.runs[k]);
    if (r.sundials) WriteSundialsStats(f, g, *r.sundials);
    f.WriteVector(g + "/times", r.trajectory.times, "s");
    // --frames default: every frame of each label's first row (its largest
    // h or rtol, where its motion differs most from the reference), the ends
    // of the others.
    const bool first_of_label = r.label != last_label;
    last_label = r.label;
    if (write_frames)
      WriteTrajectoryFrames(f, g, r.trajectory,
                            frames_mode == "all" || frames_mode == "positions" || frames_mode == "ends" ||
                                (frames_mode == "default" && first_of_label),
                            frames_mode == "all" || frames_mode == "ends");
    WriteEnergy(f, g, r.energy);
    WriteSelfContact(f, g, r);
    if (!sys.obstacles().empty()) {
      // The frames' penetration with the distance cull of the position
      // adapter: the same values, without a query for the particles far
      // from an obstacle since the last frame.
      ObstacleProximity proximity(sys);
      const PenetrationSeries pen =
          ComputePenetration(sys, r.trajectory, [&](int obstacle, const ObstaclePose& pose, const MatrixN3& x) {
            return proximity.PenetrationOf(obstacle, pose, x);
          });
      const int frames = static_cast<int>(r.trajectory.times.size());
      f.CreateGroup(g + "/penetration");
      f.WriteTable(g + "/penetration/max_depth", frames, pen.obstacles, pen.max_depth, "m");
      f.WriteTable(g + "/penetration/mean_depth", frames, pen.obstacles, pen.mean_depth, "m");
      f.WriteTable(g + "/penetration/close_count", frames, pen.obstacles, pen.close);
    }
    f.WriteStepStats(g + "/step_stats", StepRecords(r));
    if (r.sundials) f.WriteVector(g + "/method_order", MethodOrders(r), "");
  }
  if (table.work_precision) WriteWorkPrecision(f, *table.work_precision);
  f.Commit();
}

// Fig. 4.3: per-step CG iterations and colliding particles as CSV, and a
// summary: the first impact, CG per step in the 0.1 s after it, and
// fixed-point updates and CG per step over the last 0.3 s (resting contact).
void WriteSeries(const std::string& path, const std::vector<Row>& rows) {
  std::string csv = "integrator,h,t,step_h,updates,cg_iterations,colliding,status\n";
  fmt::print("\nFig. 4.3 series: {}\n{:<24} {:>8} {:>10} {:>16} {:>16} {:>16} {:>14}\n", path, "integrator", "h",
             "impact_s", "cg/step impact", "upd/step last .3s", "cg/step last .3s", "colliding end");
  for (const Row& r : rows) {
    if (!SpecOf(r.kind()).plain()) continue;
    double impact = -1.0, t_last = r.step_stats.empty() ? 0.0 : r.step_stats.back().t;
    long cg_a = 0, n_a = 0, upd_b = 0, cg_b = 0, n_b = 0;
    for (const StepStats& s : r.step_stats) {
      csv += fmt::format("{},{:g},{:.6f},{:.6g},{},{},{},{}\n", r.label, r.h, s.t, s.h, s.updates, s.cg_iterations,
                         s.colliding, static_cast<int>(s.status));
      if (s.status != StepStatus::kOk) continue;
      if (impact < 0.0 && s.colliding > 0) impact = s.t;
      if (impact >= 0.0 && s.t <= impact + 0.1) cg_a += s.cg_iterations, ++n_a;
      if (s.t > t_last - 0.3) upd_b += s.updates, cg_b += s.cg_iterations, ++n_b;
    }
    const double steps_b = n_b ? static_cast<double>(n_b) : 1.0;
    // A run that did not end ok is named so: its columns cover the steps before it stopped.
    fmt::print("{:<24} {:>8g} {:>10} {:>16} {:>16.1f} {:>16.1f} {:>14}{}\n", r.label, r.h,
               impact < 0 ? "none" : fmt::format("{:.2f}", impact),
               n_a ? fmt::format("{:.1f}", static_cast<double>(cg_a) / static_cast<double>(n_a)) : "",
               static_cast<double>(upd_b) / steps_b, static_cast<double>(cg_b) / steps_b,
               r.step_stats.empty() ? 0 : r.step_stats.back().colliding,
               r.ok() ? std::string() : fmt::format("  {} (stopped at t = {:.3g} s)", r.status, t_last));
  }
  WriteFileAtomically(path, csv, "--series");
}

std::string Sci(double v) { return fmt::format("{:.3e}", v); }

void NameReference(const Scene& scene, RunRecord* ref) {
  ref->id = "reference";
  ref->numerical_stiffness = scene.NumericalStiffness(ref->h > 0.0 ? ref->h : scene.h);
}

std::vector<StepRecord> StepRecords(const RunSummary& run) {
  std::vector<StepRecord> out;
  out.reserve(run.step_stats.size());
  for (const StepStats& st : run.step_stats)
    out.push_back({st.t, st.h, st.updates, st.cg_iterations, static_cast<int32_t>(st.status), st.colliding,
                   st.solve_time, st.setup_time, st.preconditioner});
  return out;
}

std::vector<double> MethodOrders(const RunSummary& run) {
  std::vector<double> out;
  out.reserve(run.step_stats.size());
  for (const StepStats& st : run.step_stats) out.push_back(st.error_order);
  return out;
}

// The equal-accuracy table (docs/notes/work-precision.md) of the rows' records,
// after CompareToReference filled their errors.
EqualAccuracyTable WorkPrecision(const std::vector<Row>& rows, const std::vector<double>& targets,
                                 const std::string& baseline, ErrorMetric metric, double reference_error) {
  std::vector<const RunRecord*> records;
  for (const Row& r : rows) records.push_back(&r);
  return WorkPrecisionOf(records, targets, baseline, ToString(metric), reference_error);
}


}  // namespace clothbench
