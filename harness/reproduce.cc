#include "harness/reproduce.h"

#include <algorithm>
#include <filesystem>
#include <sstream>
#include <stdexcept>
#include <vector>

#include <fmt/format.h>
#include <toml++/toml.h>

#include "harness/methods.h"

namespace clothbench {
namespace {

namespace fs = std::filesystem;

// A word for the POSIX shell: single-quoted, ' as '\''.
std::string Quote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

// The row's --integrators item: its label with the nonlinear solver always
// named, so that a scene whose solver.nonlinear_solver is newton does not
// turn a fixed-point row into a Newton one.
std::string RowName(const RunRecord& r) {
  if (r.nonlinear_solver != "fixed_point") return r.label;
  const std::size_t slash = r.label.find('/');
  return slash == std::string::npos ? r.label + "/fixed_point"
                                    : r.label.substr(0, slash) + "/fixed_point" + r.label.substr(slash);
}

// The scene's mesh obstacles named by a relative path (resolved against the
// scene file's folder when the scene is read), each with the file the run
// read: the stored /scene/obstacles/<k> path that ends with it.
std::vector<std::pair<std::string, std::string>> RelativeMeshes(const ResultReader& file, const std::string& toml) {
  std::vector<std::string> stored;
  if (file.Exists("/scene/obstacles"))
    for (const std::string& k : file.Children("/scene/obstacles"))
      if (auto p = file.String("/scene/obstacles/" + k, "path")) stored.push_back(*p);
  toml::table scene;
  try {
    scene = toml::parse(toml);
  } catch (const toml::parse_error& e) {
    throw std::invalid_argument(fmt::format("command: {}: /scene/toml does not parse: {}", file.path(),
                                            std::string(e.description())));
  }
  std::vector<std::pair<std::string, std::string>> out;
  const toml::array* obstacles = scene["obstacle"].as_array();
  if (!obstacles) return out;
  for (const toml::node& node : *obstacles) {
    const toml::table* o = node.as_table();
    if (!o || (*o)["type"].value_or(std::string()) != "mesh") continue;
    const std::string rel = (*o)["path"].value_or(std::string());
    if (rel.empty() || fs::path(rel).is_absolute()) continue;
    const auto it = std::find_if(stored.begin(), stored.end(), [&](const std::string& p) {
      return p.size() >= rel.size() && p.compare(p.size() - rel.size(), rel.size(), rel) == 0;
    });
    if (it == stored.end())
      throw std::invalid_argument(fmt::format("command: {}: mesh \"{}\" of the scene is not among the stored "
                                              "obstacles (/scene/obstacles)",
                                              file.path(), rel));
    out.emplace_back(rel, fs::absolute(*it).lexically_normal().string());
  }
  return out;
}

}  // namespace

std::string ReproduceScript(const ResultReader& file, const RunTable& table, const std::string& run_id,
                            const ReproduceOptions& options) {
  if (run_id == "reference")
    throw std::invalid_argument("command: the reference is not a row; every bench_integrators command with the "
                                "file's --reference and --reference-rtol recomputes it");
  const auto run = std::find_if(table.runs.begin(), table.runs.end(), [&](const RunRecord& r) { return r.id == run_id; });
  if (run == table.runs.end()) {
    std::string ids;
    for (const RunRecord& r : table.runs) ids += (ids.empty() ? "" : ", ") + r.id;
    throw std::invalid_argument(fmt::format("command: no run \"{}\" in {} (runs: {})", run_id, file.path(), ids));
  }
  if (!file.Exists("/scene/toml"))
    throw std::invalid_argument(fmt::format("command: {} has no /scene/toml (not a bench_integrators file)", file.path()));
  const RunRecord& r = *run;
  const std::vector<RowMethod> rows = ExpandMethods({RowName(r)}, {NonlinearSolver::kFixedPoint}, "command");
  const RowMethod& m = rows.front();

  std::string toml = file.Text("/scene/toml");
  if (!toml.empty() && toml.back() != '\n') toml += '\n';
  const auto meshes = RelativeMeshes(file, toml);
  // A mesh path that climbs out of the scene's folder ("../data/x.off")
  // stays inside `dir` if the scene file sits that many folders deeper.
  std::size_t climb = 0;
  for (const auto& [rel, abs] : meshes) {
    std::size_t up = 0;
    for (const fs::path& part : fs::path(rel).lexically_normal())
      if (part == "..") ++up;
    climb = std::max(climb, up);
  }
  fs::path scene_dir = options.dir;
  for (std::size_t k = 0; k < climb; ++k) scene_dir /= "scene.d";
  const std::string scene_file = (scene_dir / "scene.toml").string();
  const std::string out = (fs::path(options.dir) / "run.h5").string();

  std::string delimiter = "CLOTHBENCH_SCENE";
  while (("\n" + toml).find("\n" + delimiter + "\n") != std::string::npos) delimiter += "_";

  std::string s = "#!/bin/sh\n";
  s += fmt::format("# Recomputes run {} of {} (written {} by commit {}, {} build, on {}).\n", r.id, file.path(),
                   table.created, table.git_commit, table.build_type, table.host);
  s += "# The same build and thread count give the same end state bit for bit; the result is the only run of\n";
  s += fmt::format("# {} (clothbench_inspect {} runs).\n", out, Quote(out));
  s += "set -e\n";
  s += fmt::format("mkdir -p {}\n", Quote(scene_dir.string()));
  s += fmt::format("cat > {} <<'{}'\n{}{}\n", Quote(scene_file), delimiter, toml, delimiter);
  for (const auto& [rel, abs] : meshes) {
    const fs::path link = scene_dir / rel;
    s += fmt::format("mkdir -p {} && ln -sfn {} {}\n", Quote(link.parent_path().string()), Quote(abs),
                     Quote(link.string()));
  }
  std::string cmd;
  if (r.threads > 0) cmd += fmt::format("OMP_NUM_THREADS={} ", r.threads);
  cmd += fmt::format("{} --scene {} --integrators {}", Quote(options.bench), Quote(scene_file), Quote(RowName(r)));
  switch (m.kind()) {
    case StepKind::kFixedStep:
      cmd += fmt::format(" --h {}", r.h);
      break;
    case StepKind::kSubstepped:
      cmd += fmt::format(" --h {} --substeps {}", r.h, r.substeps);
      break;
    case StepKind::kAdaptive:
      cmd += fmt::format(" --rtols {}", r.rtol);
      break;
  }
  if (m.uses_pcg() && !r.preconditioner.empty())
    cmd += fmt::format(" --preconditioner {} --cg-tolerance {}", r.preconditioner, r.cg_tolerance);
  if (m.builds_tangent() && !r.tangent_terms.empty()) cmd += fmt::format(" --tangent-terms {}", r.tangent_terms);
  if (m.name() == kArkodeName && m.variant.empty() && !r.arkode_table.empty())
    cmd += fmt::format(" --arkode-table {}", r.arkode_table);
  if (m.name() == "cvode" && !r.sundials_settings.empty())
    cmd += fmt::format(" --cvode-setting {}", Quote(r.sundials_settings));
  // The file's frame spacing, so that the frame-based errors (l2, max) are
  // taken at the same instants; none becomes ends, which has the same
  // spacing and keeps the end state to compare.
  const std::string frames = table.frames == "none" ? "ends" : table.frames.empty() ? "default" : table.frames;
  cmd += fmt::format(" --t-end {} --frames {} --reference none --repeat 1 --quiet --out {}", table.t_end, frames,
                     Quote(out));
  return s + cmd + "\n";
}

}  // namespace clothbench
