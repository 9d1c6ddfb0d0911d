// ValidateResultFile: what a reader checks before it trusts a result file
// (docs/guide/results-schema.md). Every check names the dataset or attribute and
// the rule it broke; the caller (clothbench_inspect, the XDMF writer, the
// fuzz target verify/fuzz/fuzz_result.cc) turns the ResultError into one
// line and exit 2.
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "model/scene.h"
#include "results/result_reader.h"
#include "results/scale_verdict.h"
#include "results/run_records.h"

namespace clothbench {
namespace {

// Attribute texts above this are not from a writer of this schema (scene
// names are at most kMaxSceneNameBytes; messages, ids and settings are
// shorter).
constexpr std::size_t kMaxAttributeBytes = std::size_t{1} << 20;

[[noreturn]] void Broken(const ResultReader& f, const std::string& object, const std::string& rule) {
  throw ResultError(EscapeControl(fmt::format("{}: {}: {}", f.path(), object, rule)));
}

void CheckAttributes(const ResultReader& f, const std::string& object) {
  for (const auto& [name, value] : f.Attributes(object)) {
    if (const double* d = std::get_if<double>(&value); d && !std::isfinite(*d))
      Broken(f, object + "@" + name, fmt::format("{} is not finite (a writer of this schema leaves such values out)", *d));
    if (const std::string* s = std::get_if<std::string>(&value); s && s->size() > kMaxAttributeBytes)
      Broken(f, object + "@" + name, fmt::format("{} bytes, above the {} a writer produces", s->size(),
                                                 kMaxAttributeBytes));
  }
}

std::vector<std::size_t> ShapeOf(const ResultReader& f, const std::string& dataset, std::size_t rank) {
  const std::vector<std::size_t> shape = f.Shape(dataset);
  if (shape.size() != rank) Broken(f, dataset, fmt::format("rank {}, {} expected", shape.size(), rank));
  return shape;
}

std::vector<double> FiniteDoubles(const ResultReader& f, const std::string& dataset) {
  std::vector<double> v = f.Doubles(dataset);
  for (std::size_t k = 0; k < v.size(); ++k)
    if (!std::isfinite(v[k])) Broken(f, dataset, fmt::format("[{}] = {} is not finite", k, v[k]));
  return v;
}

// times [F]: finite and non-decreasing; the count every per-frame dataset
// of the group must match.
std::size_t CheckTimes(const ResultReader& f, const std::string& g) {
  const std::string d = g + "/times";
  ShapeOf(f, d, 1);
  const std::vector<double> t = FiniteDoubles(f, d);
  for (std::size_t k = 1; k < t.size(); ++k)
    if (!(t[k] >= t[k - 1])) Broken(f, d, fmt::format("decreases at [{}] ({} after {})", k, t[k], t[k - 1]));
  return t.size();
}

void CheckRun(const ResultReader& f, const std::string& g, long n_particles) {
  CheckAttributes(f, g);
  const bool has_times = f.Exists(g + "/times");
  const std::size_t frames = has_times ? CheckTimes(f, g) : 0;
  for (const char* name : {"positions", "velocities", "positions_ends", "velocities_ends"}) {
    const std::string d = g + "/" + name;
    if (!f.Exists(d)) continue;
    if (!has_times) Broken(f, d, "stored without " + g + "/times");
    const std::vector<std::size_t> s = ShapeOf(f, d, 3);
    const bool ends = std::string(name).ends_with("_ends");
    const std::size_t want = ends ? 2 : frames;
    if (s[0] != want || s[1] != static_cast<std::size_t>(n_particles) || s[2] != 3)
      Broken(f, d, fmt::format("shape [{}, {}, {}], [{}, {}, 3] expected (times has {}, /scene@n_particles is {})", s[0],
                               s[1], s[2], want, n_particles, frames, n_particles));
    if (ends && frames == 0) Broken(f, g + "/times", "empty, but " + d + " holds the end frames");
    CheckAttributes(f, d);
  }
  if (f.Exists(g + "/energy")) {
    for (const std::string& c : f.Children(g + "/energy")) {
      const std::string d = g + "/energy/" + c;
      const std::vector<std::size_t> s = ShapeOf(f, d, 1);
      if (s[0] != frames) Broken(f, d, fmt::format("{} values, {} frames in times", s[0], frames));
      FiniteDoubles(f, d);
    }
  }
  if (f.Exists(g + "/momentum")) {
    const std::vector<std::size_t> s = ShapeOf(f, g + "/momentum", 2);
    if (s[0] != frames || s[1] != 3) Broken(f, g + "/momentum", fmt::format("shape [{}, {}], [{}, 3] expected", s[0], s[1], frames));
    FiniteDoubles(f, g + "/momentum");
  }
  if (f.Exists(g + "/step_stats")) {
    ShapeOf(f, g + "/step_stats", 1);
    const std::vector<StepRecord> steps = f.StepStats(g + "/step_stats");
    for (std::size_t k = 0; k < steps.size(); ++k) {
      const StepRecord& r = steps[k];
      if (!std::isfinite(r.t) || !(r.h >= 0.0) || !std::isfinite(r.h) || !std::isfinite(r.solve_time_s) ||
          !std::isfinite(r.setup_time_s))
        Broken(f, g + "/step_stats", fmt::format("row {}: t, h or a time is not finite (h must be ≥ 0)", k));
      if (r.preconditioner < 0 || r.preconditioner > 3)
        Broken(f, g + "/step_stats", fmt::format("row {}: preconditioner {} is not 0, 1, 2 or 3", k, r.preconditioner));
    }
  }
  if (f.Exists(g + "/penetration")) {
    for (const std::string& c : f.Children(g + "/penetration")) {
      const std::string d = g + "/penetration/" + c;
      const std::vector<std::size_t> s = ShapeOf(f, d, 2);
      if (s[0] != frames) Broken(f, d, fmt::format("{} rows, {} frames in times", s[0], frames));
      FiniteDoubles(f, d);
    }
  }
}

// The stability maps under `group` (/stress/<scene>/<method id>, an id's
// "/" nesting groups): every dataset [h × stiffness], outcome and
// steps_completed non-negative integers, the rest finite.
void CheckStressMaps(const ResultReader& f, const std::string& group, std::size_t hs, std::size_t stiff, int depth) {
  if (depth > 8) Broken(f, group, "nested deeper than a method id");
  for (const std::string& name : f.Children(group)) {
    const std::string d = group + "/" + name;
    if (!f.Children(d).empty()) {
      CheckStressMaps(f, d, hs, stiff, depth + 1);
      continue;
    }
    const std::vector<std::size_t> s = ShapeOf(f, d, 2);
    if (s[0] != hs || s[1] != stiff)
      Broken(f, d, fmt::format("shape [{}, {}], [{}, {}] expected (/stress/h × /stress/stiffness)", s[0], s[1], hs,
                               stiff));
    if (name == "outcome" || name == "steps_completed") {
      for (int32_t v : f.Ints(d))
        if (v < 0) Broken(f, d, fmt::format("{} is negative", v));
    } else {
      FiniteDoubles(f, d);
    }
  }
}

}  // namespace

RunTable ValidateResultFile(const ResultReader& f) {
  CheckAttributes(f, "/");
  long n = 0;
  if (f.Exists("/scene")) {
    CheckAttributes(f, "/scene");
    const std::optional<long> np = f.Long("/scene", "n_particles");
    if (!np || *np < 1 || static_cast<double>(*np) > kMaxParticles)
      Broken(f, "/scene@n_particles", fmt::format("must be an integer in [1, {:g}]", kMaxParticles));
    n = *np;
    const long fixed = f.Long("/scene", "n_fixed").value_or(0);
    if (fixed < 0 || fixed > n) Broken(f, "/scene@n_fixed", fmt::format("{} is not in [0, n_particles = {}]", fixed, n));
    if (f.Exists("/scene/faces")) {
      const std::vector<std::size_t> s = ShapeOf(f, "/scene/faces", 2);
      if (s[1] != 4) Broken(f, "/scene/faces", fmt::format("shape [{}, {}], [Q, 4] expected", s[0], s[1]));
      const std::vector<int32_t> faces = f.Ints("/scene/faces");
      for (std::size_t k = 0; k < faces.size(); ++k)
        if (faces[k] < 0 || faces[k] >= n)
          Broken(f, "/scene/faces", fmt::format("[{}, {}] = {} is not a particle index (0 … {})", k / 4, k % 4,
                                                faces[k], n - 1));
    }
    if (f.Exists("/scene/obstacles")) {
      for (const std::string& k : f.Children("/scene/obstacles")) {
        const std::string o = "/scene/obstacles/" + k;
        const std::vector<std::size_t> v = ShapeOf(f, o + "/vertices", 2);
        const std::vector<std::size_t> t = ShapeOf(f, o + "/triangles", 2);
        if (v[1] != 3 || t[1] != 3) Broken(f, o, "vertices and triangles must be [V, 3] and [T, 3]");
        FiniteDoubles(f, o + "/vertices");
        for (int32_t i : f.Ints(o + "/triangles"))
          if (i < 0 || static_cast<std::size_t>(i) >= v[0])
            Broken(f, o + "/triangles", fmt::format("{} is not a vertex index (0 … {})", i, v[0] - 1));
        if (f.Exists(o + "/positions")) {  // a deforming obstacle's surface at `times`
          const std::vector<std::size_t> x = ShapeOf(f, o + "/positions", 3);
          if (x[1] != v[0] || x[2] != 3) Broken(f, o + "/positions", fmt::format("must be [F, {}, 3]", v[0]));
          if (CheckTimes(f, o) != x[0]) Broken(f, o + "/times", "must hold one time per positions frame");
          FiniteDoubles(f, o + "/positions");
        }
      }
    }
  }
  const bool runs = f.Exists("/runs") || f.Exists("/reference");
  if (runs && !f.Exists("/scene")) Broken(f, "/scene", "missing, but the file holds runs");
  if (f.Exists("/reference")) CheckRun(f, "/reference", n);
  for (const std::string& id : f.Children("/runs")) CheckRun(f, "/runs/" + id, n);
  if (f.Exists("/scale_verdict")) {
    CheckAttributes(f, "/scale_verdict");
    (void)ReadScaleVerdict(f);  // shapes, labels and values
  }
  if (f.Exists("/work_precision")) {
    CheckAttributes(f, "/work_precision");
    for (const char* d : {"targets", "solver_time", "ratio", "min_error"})
      if (f.Exists(std::string("/work_precision/") + d)) FiniteDoubles(f, std::string("/work_precision/") + d);
  }
  if (f.Exists("/stress")) {
    CheckAttributes(f, "/stress");
    const std::size_t stiff = ShapeOf(f, "/stress/stiffness", 1)[0], hs = ShapeOf(f, "/stress/h", 1)[0];
    FiniteDoubles(f, "/stress/stiffness");
    FiniteDoubles(f, "/stress/h");
    for (const std::string& scene : f.Children("/stress"))
      if (scene != "stiffness" && scene != "h") CheckStressMaps(f, "/stress/" + scene, hs, stiff, 0);
  }
  // The run table as every reader reads it: its datasets present and
  // consistent (the equal-accuracy table's cells, labels and indices).
  RunTable table = ReadRunTable(f);
  if (f.Exists("/scene/toml")) (void)f.Text("/scene/toml");
  return table;
}

}  // namespace clothbench
