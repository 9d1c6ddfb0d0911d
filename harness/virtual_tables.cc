// Table 5.1 and Fig. 5.15 of the thesis beside ours (harness/virtual_tables.h).
#include "harness/virtual_tables.h"

#include <algorithm>
#include <array>
#include <memory>
#include <cmath>
#include <string>
#include <string_view>
#include <vector>

#include <fmt/format.h>

#include "collision/shapes/triangle_mesh.h"
#include "collision/virtual_particles.h"
#include "model/particle_system.h"
#include "results/result_file.h"
#include "solver/run.h"
#include "collision/cloth_mesh.h"
#include "harness/methods.h"

namespace clothbench {

namespace {

// The thesis' Table 5.1 (R10000, 180 MHz), per step averaged over 1 s.
struct ThesisRow {
  const char* scene;
  const char* example;
  double projection_ms, topology_ms, combined_ms;
};
constexpr std::array<ThesisRow, 3> kTable51{{{"virtual_round_table", "round table", 38.5, 38.0, 76.5},
                                             {"virtual_square_table", "square table", 24.0, 147.5, 171.5},
                                             {"virtual_ball", "ball", 150.5, 83.5, 234.0}}};

// A cloth surface: vertices and triangles.
struct Surface {
  std::vector<Vector3> vertices;
  std::vector<std::array<int, 3>> triangles;
};

// The cloth at positions x as its base triangles, or refined by the
// virtual particles of the run's last update (at x).
Surface ClothSurface(const ParticleSystem& sys, const MatrixN3& x) {
  Surface s;
  for (int p = 0; p < x.rows(); ++p) s.vertices.emplace_back(x.row(p).transpose());
  if (VirtualParticles* vp = VirtualParticles::Of(sys)) {
    vp->Update(sys.scene().t_end, x);
    vp->RefinedMesh(x, &s.triangles);
    for (const VirtualParticle& p : vp->particles()) s.vertices.push_back(p.x);
    return s;
  }
  const ClothTriangles t = SceneTriangles(sys.scene());
  s.triangles = t.vertices;
  return s;
}

// Points on a barycentric grid of step 1/k on every triangle.
template <class F>
void Sample(const Surface& s, int k, F visit) {
  for (const auto& t : s.triangles) {
    const Vector3& a = s.vertices[static_cast<std::size_t>(t[0])];
    const Vector3& b = s.vertices[static_cast<std::size_t>(t[1])];
    const Vector3& c = s.vertices[static_cast<std::size_t>(t[2])];
    for (int i = 0; i <= k; ++i)
      for (int j = 0; i + j <= k; ++j) visit(Vector3(a + (b - a) * (double(i) / k) + (c - a) * (double(j) / k)));
  }
}

struct Distances {
  double hausdorff = 0.0, rms = 0.0;  // [m]
};

// Hausdorff (both ways) and the rms of the distances from `fine`'s samples
// to `coarse` (the coarse surface resampled through the fine one).
Distances Compare(const Surface& coarse, const Surface& fine) {
  const TriangleMesh cm(coarse.vertices, coarse.triangles), fm(fine.vertices, fine.triangles);
  Distances d;
  double sum = 0.0;
  long count = 0;
  Vector3 dir;
  Sample(fine, 4, [&](const Vector3& p) {
    const double e = std::abs(cm.SignedDistance(p, &dir));
    d.hausdorff = std::max(d.hausdorff, e);
    sum += e * e;
    ++count;
  });
  Sample(coarse, 4, [&](const Vector3& p) { d.hausdorff = std::max(d.hausdorff, std::abs(fm.SignedDistance(p, &dir))); });
  d.rms = count > 0 ? std::sqrt(sum / static_cast<double>(count)) : 0.0;
  return d;
}

// The deepest sample of the surface's faces inside the obstacles [m].
double DeepestInside(const ParticleSystem& sys, const Surface& s) {
  double deepest = 0.0;
  Vector3 dir;
  Sample(s, 8, [&](const Vector3& p) {
    for (const Obstacle& o : sys.obstacles()) deepest = std::max(deepest, -o.SignedDistance(sys.scene().t_end, p, &dir));
  });
  return deepest;
}

}  // namespace

namespace {

// A run of the method that ran the thesis' `experiment`
// (MethodEntry::thesis_experiments) on `sys` with its scene's solver settings.
RunSummary RunThesisMethod(const ParticleSystem& sys, std::string_view experiment, const RunOptions& options) {
  const MethodEntry& e = ThesisExperimentMethod(experiment);
  const std::unique_ptr<Stepper> stepper = e.make(sys, sys.scene().solver, 1, "");
  return RunStepper(sys, *stepper, options);
}

}  // namespace

int RunTable51(std::string out) {
  if (out.empty()) out = "out/table_5_1.h5";
  fmt::print("Table 5.1 — the cost of the virtual particles per step, averaged over the run (implicit Euler with "
             "Newton's method, a frame every step); thesis: R10000, 180 MHz\n");
  fmt::print("{:<13} {:>9} {:>6} {:>8} | {:>13} {:>11} {:>11} | {:>13} {:>11} {:>11} | {:>9} {:>8}\n", "example",
             "particles", "edges", "virtual", "projection_ms", "topology_ms", "combined_ms", "thesis_proj", "thesis_top",
             "thesis_comb", "base_ms", "comb/base");
  ResultFile f(out);
  WriteProvenance(f);
  f.CreateGroup("/table");
  f.SetAttribute("/table", "name", std::string("Table 5.1"));
  int status = 0;
  for (const ThesisRow& row : kTable51) {
    Scene s = BuiltinScene(row.scene);
    s.frame_dt = s.h;
    s.solver.nonlinear_solver = NonlinearSolver::kNewton;
    const ParticleSystem sys(s);
    const RunSummary r = RunThesisMethod(sys, "Table 5.1", {s.h, s.t_end, s.frame_dt});
    const VirtualParticles* vp = VirtualParticles::Of(sys);
    const double updates = static_cast<double>(std::max(1L, vp->updates()));
    const double frames = static_cast<double>(std::max(1L, vp->triangulations()));
    const double projection = 1e3 * vp->projection_seconds() / updates;
    const double topology = 1e3 * (vp->springs_seconds() / updates + vp->triangulation_seconds() / frames);
    const double steps = static_cast<double>(std::max(1L, r.steps));
    const double base = 1e3 * (r.solver_time_s - vp->projection_seconds() - vp->springs_seconds()) / steps;
    const auto& offsets = r.trajectory.virtual_particles.offsets;
    const double virtual_mean =
        offsets.size() > 1 ? static_cast<double>(offsets.back()) / static_cast<double>(offsets.size() - 1) : 0.0;
    std::vector<Vector3> v;
    std::vector<std::array<int, 2>> e;
    sys.obstacles().front().Edges(ObstaclePose{}, &v, &e);
    fmt::print("{:<13} {:>9} {:>6} {:>8.1f} | {:>13.3f} {:>11.3f} {:>11.3f} | {:>13.1f} {:>11.1f} {:>11.1f} | {:>9.3f} "
               "{:>8.2f}{}\n",
               row.example, sys.num_particles(), e.size(), virtual_mean, projection, topology, projection + topology,
               row.projection_ms, row.topology_ms, row.combined_ms, base, (projection + topology) / base,
               r.ok() ? "" : fmt::format("  ({}: {})", r.status, r.message));
    if (!r.ok()) status = 1;
    const std::string g = std::string("/table/") + row.scene;
    f.CreateGroup(g);
    f.SetAttribute(g, "example", std::string(row.example));
    f.SetAttribute(g, "status", std::string(ToString(r.status)));
    f.SetAttribute(g, "particles", static_cast<long>(sys.num_particles()));
    f.SetAttribute(g, "obstacle_edges", static_cast<long>(e.size()));
    f.SetAttribute(g, "steps", r.steps);
    f.SetAttribute(g, "virtual_particles_mean", virtual_mean);
    f.SetAttribute(g, "projection_ms", projection);
    f.SetAttribute(g, "topology_ms", topology);
    f.SetAttribute(g, "combined_ms", projection + topology);
    f.SetAttribute(g, "base_step_ms", base);
    f.SetAttribute(g, "thesis_projection_ms", row.projection_ms);
    f.SetAttribute(g, "thesis_topology_ms", row.topology_ms);
    f.SetAttribute(g, "thesis_combined_ms", row.combined_ms);
    f.WriteString(g + "/scene_toml", s.toml);
  }
  fmt::print("topology: ordering the points on the cloth edges and splitting the rest lengths, and the constrained "
             "Delaunay triangulation of every face with virtual particles (CGAL; the thesis: Triangle)\n"
             "base_ms: the step's solver time without the virtual particles; results: {}\n",
             out);
  f.Commit();
  return status;
}

int RunFig515(std::string out) {
  if (out.empty()) out = "out/fig_5_15.h5";
  const Scene coarse = BuiltinScene("virtual_square_table");
  Scene plain = coarse;
  for (ObstacleSpec& o : plain.obstacles) o.virtual_particles = false;
  struct Case {
    std::string label;
    Scene scene;
  };
  std::vector<Case> cases{{"400 + virtual particles", coarse}, {"400", plain}};
  for (long n : {2500L, 10000L}) {
    Scene fine = RefineGrid(plain, n);
    // A step in proportion to the spacing: at the coarse h the 10,000-
    // particle drape gains energy (SBDF(2), d = 1 N s/m: energy_growth at
    // t = 0.21 s).
    fine.h = coarse.h * static_cast<double>(coarse.grid.nu - 1) / static_cast<double>(fine.grid.nu - 1);
    fine.h = coarse.t_end / std::ceil(coarse.t_end / fine.h);
    cases.push_back({fmt::format("{}", fine.grid.nu * fine.grid.nv), fine});
  }
  fmt::print("Fig. 5.15 — the square table's drape at t = {:g} s (SBDF(2), h = {:g} s at 400 particles, in "
             "proportion to the spacing above): each surface against the 2,500- and 10,000-particle drapes without "
             "virtual particles\n",
             coarse.t_end, coarse.h);
  std::vector<Surface> surfaces;
  std::vector<double> solver_s, depth;
  std::vector<std::string> status;
  for (Case& c : cases) {
    c.scene.frame_dt = c.scene.t_end;
    const ParticleSystem sys(c.scene);
    const RunSummary r = RunThesisMethod(sys, "Fig. 5.15", {c.scene.h, c.scene.t_end, c.scene.frame_dt});
    surfaces.push_back(ClothSurface(sys, r.trajectory.positions.back()));
    solver_s.push_back(r.solver_time_s);
    depth.push_back(DeepestInside(sys, surfaces.back()));
    status.push_back(r.ok() ? std::string(ToString(r.status)) : fmt::format("{}: {}", r.status, r.message));
  }
  fmt::print("{:<24} {:>8} {:>9} {:>12} {:>11} {:>13} {:>12} {:>12} {:>10}  {}\n", "cloth", "h_s", "solver_s", "H_2500_mm",
             "rms_2500_mm", "H_10000_mm", "rms_10000_mm", "depth_mm", "triangles", "status");
  ResultFile f(out);
  WriteProvenance(f);
  f.CreateGroup("/fig_5_15");
  for (std::size_t k = 0; k < cases.size(); ++k) {
    const Distances d2 = k == 2 ? Distances{} : Compare(surfaces[k], surfaces[2]);
    const Distances d4 = k == 3 ? Distances{} : Compare(surfaces[k], surfaces[3]);
    fmt::print("{:<24} {:>8.5f} {:>9.3f} {:>12.2f} {:>11.2f} {:>13.2f} {:>12.2f} {:>12.2f} {:>10}  {}\n", cases[k].label,
               cases[k].scene.h, solver_s[k], 1e3 * d2.hausdorff, 1e3 * d2.rms, 1e3 * d4.hausdorff, 1e3 * d4.rms, 1e3 * depth[k],
               surfaces[k].triangles.size(), status[k]);
    const std::string g = fmt::format("/fig_5_15/{}", k);
    f.CreateGroup(g);
    f.SetAttribute(g, "cloth", cases[k].label);
    f.SetAttribute(g, "status", status[k]);
    f.SetAttribute(g, "particles", static_cast<long>(cases[k].scene.grid.nu * cases[k].scene.grid.nv));
    f.SetAttribute(g, "solver_time_s", solver_s[k]);
    f.SetAttribute(g, "h", cases[k].scene.h);
    f.SetAttribute(g, "hausdorff_2500_m", d2.hausdorff);
    f.SetAttribute(g, "rms_2500_m", d2.rms);
    f.SetAttribute(g, "hausdorff_10000_m", d4.hausdorff);
    f.SetAttribute(g, "rms_10000_m", d4.rms);
    f.SetAttribute(g, "penetration_m", depth[k]);
    std::vector<double> xyz;
    for (const Vector3& p : surfaces[k].vertices) xyz.insert(xyz.end(), {p.x(), p.y(), p.z()});
    std::vector<int32_t> tri;
    for (const auto& t : surfaces[k].triangles) tri.insert(tri.end(), t.begin(), t.end());
    f.WriteTable(g + "/vertices", static_cast<int>(surfaces[k].vertices.size()), 3, xyz, "m");
    f.WriteTable(g + "/triangles", static_cast<int>(surfaces[k].triangles.size()), 3, tri);
    f.WriteString(g + "/scene_toml", cases[k].scene.toml);
  }
  fmt::print("H: Hausdorff distance (both ways), rms: of the fine surface's samples to this one, depth: the deepest "
             "point of its faces inside the table; results: {}\n",
             out);
  f.Commit();
  return 0;
}

}  // namespace clothbench
