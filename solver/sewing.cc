// The sewing phase (solver/sewing.h; docs/model.md §2.9).
#include "solver/sewing.h"

#include <algorithm>
#include <chrono>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "model/particle_system.h"
#include "solver/integrator.h"
#include "solver/run.h"

namespace clothbench {

namespace {

// Sewn cloths by what the phase depends on (the scene text and its step),
// so that the rows of a sweep share one phase.
std::mutex cache_mutex;
std::map<std::string, std::pair<std::shared_ptr<const ClothLayout>, SewingSummary>> cache;

std::string CacheKey(const Scene& s) {
  if (s.toml.empty()) return "";  // a scene built in code: not cached
  return fmt::format("{}\n#h={:a}", s.toml, s.h);
}

}  // namespace

SewingSummary Sew(Scene* scene) {
  SewingSummary out;
  if (!scene->cloth || scene->cloth->sewn || !(scene->sewing_time > 0.0)) return out;
  const std::string key = CacheKey(*scene);
  {
    const std::lock_guard<std::mutex> lock(cache_mutex);
    if (auto it = cache.find(key); !key.empty() && it != cache.end()) {
      scene->cloth = it->second.first;
      return it->second.second;
    }
  }
  const auto wall = std::chrono::steady_clock::now();
  const ClothLayout& target = *scene->cloth;  // merged numbering; start = each pair's midpoint
  // The patterns apart: particle u is unsewn particle u of `target`.
  Scene apart = *scene;
  apart.seams.clear();
  SetCloth(&apart, BuildClothLayout(apart.patterns, {}));
  apart.forces.gravity.setZero();
  apart.forces.wind.reset();
  apart.fixed.clear();
  apart.fixed_specs.clear();
  apart.motions.clear();
  // Without self-contact: the two samples of a pair close onto one point,
  // where their patterns' triangles meet edge to edge.
  apart.collision.reset();
  // A moving body is dressed in its pose at t = 0, held still.
  for (ObstacleSpec& o : apart.obstacles) o = HeldAt(o, 0.0);
  apart.t_end = apart.frame_dt = scene->sewing_time;
  // Every seam sample moves on a straight path to its particle's start
  // (the mean of the samples it merges) over the phase.
  std::vector<int> members(static_cast<std::size_t>(target.num_particles), 0);
  for (int c : target.merged) ++members[static_cast<std::size_t>(c)];
  const MatrixN3& x0 = apart.cloth->start;
  for (int u = 0; u < apart.num_particles(); ++u) {
    const int c = target.merged[static_cast<std::size_t>(u)];
    if (members[static_cast<std::size_t>(c)] < 2) continue;
    FixedMotionSpec m;
    m.particles_spec = "sewing";
    m.particles = {u};
    m.anchor = x0.row(u).transpose();
    m.keyframes = {ObstacleKeyframe{0.0, Vector3::Zero(), Vector3::Zero()},
                   ObstacleKeyframe{scene->sewing_time, (target.start.row(c) - x0.row(u)).transpose(), Vector3::Zero()}};
    apart.fixed.push_back(u);
    apart.motions.push_back(std::move(m));
  }
  const ParticleSystem system(apart);
  SolverSpec spec = apart.solver;
  spec.nonlinear_solver = NonlinearSolver::kNewton;  // robust under the paths' pull at any h
  StepEngine stepper(system, Method::kImplicitEuler, spec);
  RunOptions options;
  options.h = std::min(scene->h, scene->sewing_time);
  options.t_end = options.frame_dt = scene->sewing_time;
  options.solver = &spec;
  const RunSummary run = RunStepper(system, stepper, options);
  if (run.status != RunStatus::kOk || run.trajectory.positions.empty())
    throw SceneError(fmt::format("{}: sewing: the phase ended {}: {}", scene->source, ToString(run.status), run.message));
  const MatrixN3& x = run.trajectory.positions.back();
  // Each particle where its samples ended (they meet, up to round-off).
  ClothLayout sewn = BuildClothLayout(scene->patterns, scene->seams);
  sewn.start.setZero();
  std::vector<int> first(static_cast<std::size_t>(target.num_particles), -1);
  for (int u = 0; u < apart.num_particles(); ++u) {
    const int c = target.merged[static_cast<std::size_t>(u)];
    sewn.start.row(c) += x.row(u) / members[static_cast<std::size_t>(c)];
    if (first[static_cast<std::size_t>(c)] < 0) first[static_cast<std::size_t>(c)] = u;
    out.largest_gap = std::max(out.largest_gap, (x.row(u) - x.row(first[static_cast<std::size_t>(c)])).norm());
  }
  sewn.largest_gap = out.largest_gap;
  sewn.sewn = true;
  SetCloth(scene, std::move(sewn));
  out.steps = static_cast<int>(run.steps);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall).count();
  if (!key.empty()) {
    const std::lock_guard<std::mutex> lock(cache_mutex);
    cache.emplace(key, std::make_pair(scene->cloth, out));
  }
  return out;
}

}  // namespace clothbench
