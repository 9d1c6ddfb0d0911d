#include "harness/reproduce.h"

#include <algorithm>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <toml++/toml.h>

#include "harness/cli_args.h"
#include "harness/methods.h"
#include "harness/output_lock.h"
#include "harness/result_writer.h"

namespace clothbench {
namespace {

namespace fs = std::filesystem;

// The row's method name: its label (without the " eta=…" a sweep over CG
// tolerances appends) with the nonlinear solver always named, so that a
// scene whose solver.nonlinear_solver is newton does not turn a
// fixed-point row into a Newton one.
std::string RowName(const RunRecord& r) {
  const std::string label = r.label.substr(0, r.label.find(' '));
  if (r.nonlinear_solver != "fixed_point") return label;
  const std::size_t slash = label.find('/');
  return slash == std::string::npos ? label + "/fixed_point"
                                    : label.substr(0, slash) + "/fixed_point" + label.substr(slash);
}

// The scene's mesh obstacles named by a relative path (resolved against the
// scene file's folder when the scene is read), each with the file the run
// read: the stored /scene/obstacles/<k> path that ends with it.
std::vector<std::pair<std::string, std::string>> RelativeMeshes(const ResultReader& file, const std::string& toml,
                                                                const std::string& where) {
  std::vector<std::string> stored;
  if (file.Exists("/scene/obstacles"))
    for (const std::string& k : file.Children("/scene/obstacles"))
      if (auto p = file.String("/scene/obstacles/" + k, "path")) stored.push_back(*p);
  toml::table scene;
  try {
    scene = toml::parse(toml);
  } catch (const toml::parse_error& e) {
    throw UsageError(fmt::format("{}: /scene/toml does not parse: {}", where, std::string(e.description())));
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
      throw UsageError(fmt::format("{}: mesh \"{}\" of the scene is not among the stored obstacles (/scene/obstacles)",
                                   where, rel));
    out.emplace_back(rel, *it);
  }
  return out;
}

const RunRecord& FindRun(const ResultReader& file, const RunTable& table, const std::string& run_id) {
  if (run_id == "reference")
    throw UsageError("the reference is not a row; every bench_integrators command with the file's --reference and "
                     "--reference-rtol recomputes it");
  const auto run = std::find_if(table.runs.begin(), table.runs.end(), [&](const RunRecord& r) { return r.id == run_id; });
  if (run == table.runs.end()) {
    std::string ids;
    for (const RunRecord& r : table.runs) ids += (ids.empty() ? "" : ", ") + r.id;
    throw UsageError(fmt::format("no run \"{}\" in {} (runs: {})", run_id, file.path(), ids));
  }
  return *run;
}

// The folder the scene file sat in when the run read its relative meshes:
// each stored mesh path is that folder joined with the relative one.
std::string SceneSource(const std::vector<std::pair<std::string, std::string>>& meshes, const RunTable& table,
                        const std::string& where) {
  if (meshes.empty()) return table.scene_source.empty() ? std::string("<stored>") : table.scene_source;
  std::string folder;
  for (const auto& [rel, stored] : meshes) {
    const std::string f = stored.substr(0, stored.size() - rel.size());
    if (!folder.empty() && f != folder)
      throw UsageError(fmt::format("{}: the stored mesh paths (/scene/obstacles) name two scene folders, \"{}\" and "
                                   "\"{}\"",
                                   where, folder, f));
    folder = f;
  }
  return folder + "scene.toml";
}

}  // namespace

std::string ShellQuote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

RunRequest StoredRunRequest(const ResultReader& file, const RunTable& table, const std::string& run_id) {
  const RunRecord& r = FindRun(file, table, run_id);
  const std::string where = fmt::format("{}: run {}", file.path(), run_id);
  if (!file.Exists("/scene/toml"))
    throw UsageError(fmt::format("{} has no /scene/toml (not a bench_integrators file)", file.path()));
  std::string toml = file.Text("/scene/toml");
  const auto meshes = RelativeMeshes(file, toml, where);
  RunRequest q;
  try {
    q.scene = ParseScene(toml, SceneSource(meshes, table, where));
  } catch (const SceneError& e) {
    throw UsageError(fmt::format("{}: /scene/toml: {}", where, e.what()));
  }
  // A garment starts where its stored sewing phase ended (solver/sewing.h).
  if (q.scene.cloth && !q.scene.cloth->sewn && file.Exists("/scene/sewn_start")) {
    const std::vector<double> x = file.Doubles("/scene/sewn_start");
    if (x.size() != static_cast<std::size_t>(3 * q.scene.num_particles()))
      throw UsageError(fmt::format("{}: /scene/sewn_start has {} values for {} particles", where, x.size(),
                                   q.scene.num_particles()));
    ClothLayout sewn = *q.scene.cloth;
    for (int p = 0; p < q.scene.num_particles(); ++p)
      for (int c = 0; c < 3; ++c) sewn.start(p, c) = x[static_cast<std::size_t>(3 * p + c)];
    if (!sewn.start.allFinite()) throw UsageError(fmt::format("{}: /scene/sewn_start is not finite", where));
    sewn.sewn = true;
    SetCloth(&q.scene, std::move(sewn));
  }
  if (q.scene.num_particles() != table.n_particles)
    throw UsageError(fmt::format("{}: /scene/toml has {} particles, /scene@n_particles {}", where,
                                 q.scene.num_particles(), table.n_particles));
  q.method = RowName(r);
  // Which fields the row reads follows from its label; an unknown label is refused by Resolve.
  std::vector<RowMethod> rows;
  try {
    rows = ExpandMethods({q.method}, {NonlinearSolver::kFixedPoint}, "label");
  } catch (const std::invalid_argument& e) {
    throw UsageError(fmt::format("{}: {}", where, e.what()));
  }
  RowMethod m = rows.front();
  if (q.scene.solver.step_control == StepControl::kError && m.entry->error_control) m.error_control = true;
  const StepKindSpec& kind = SpecOf(m.kind());
  q.SetStep(kind, kind.adaptive() ? r.rtol : r.h, kind.counted() ? r.*kind.count_field : 1);
  if (m.uses_pcg() && !r.preconditioner.empty()) q.preconditioner = r.preconditioner, q.cg_tolerance = r.cg_tolerance;
  if (m.builds_tangent() && !r.tangent_terms.empty()) q.tangent_terms = r.tangent_terms;
  // The method's own settings, stored as its attributes (MethodSetting::attribute).
  for (const MethodSetting& setting : m.entry->settings) {
    const std::string value = setting.attribute.empty() ? "" : r.MethodText(std::string(setting.attribute));
    if (!value.empty() && m.setting(setting.field)) q.settings.emplace_back(setting.field, value);
  }
  if (!r.collision_self.empty()) q.self_contact = r.collision_self;
  q.t_end = table.t_end;
  // The file's frame spacing, so that the frame-based errors (l2, max) are
  // taken at the same instants; none becomes ends, which has the same
  // spacing and keeps the end state to compare.
  q.frames = table.frames == "none" ? "ends" : table.frames.empty() ? "default" : table.frames;
  q.threads = r.threads;
  ResolvedRun run;
  try {
    run = q.Resolve();
  } catch (const std::invalid_argument& e) {
    throw UsageError(fmt::format("{}: {}", where, e.what()));
  }
  // The stored label, integrator, kind and parameters must name this run:
  // an edited label would otherwise recompute another method under the id.
  const std::size_t eta = r.label.find(" eta=");
  const std::string id = run.row.RunId(run.param, run.count) +
                         (eta == std::string::npos ? "" : fmt::format("_eta{:g}", run.spec.cg_tolerance));
  const std::string label = run.row.label() + (eta == std::string::npos ? "" : r.label.substr(eta));
  if (label != r.label || r.integrator != run.row.name() || r.step_kind != run.row.kind())
    throw UsageError(fmt::format("{}: label: the stored label \"{}\", integrator \"{}\" and step_kind \"{}\" do not "
                                 "agree (the label names {}, {})",
                                 where, r.label, r.integrator, r.step_kind, run.row.name(), ToString(run.row.kind())));
  if (id != run_id) {
    const StepKindSpec& k = SpecOf(run.row.kind());
    const std::string field = k.adaptive() ? std::string(k.param)
                              : k.counted() && fmt::format("{:g}", run.param) == fmt::format("{:g}", r.h)
                                  ? std::string(k.count)
                                  : eta != std::string::npos && run_id.find("_eta") != std::string::npos &&
                                            id.substr(0, id.find("_eta")) == run_id.substr(0, run_id.find("_eta"))
                                      ? "cg_tolerance"
                                      : "h";
    throw UsageError(fmt::format("{}: {}: the stored parameters name run \"{}\", not this one", where, field, id));
  }
  return q;
}

}  // namespace clothbench

namespace clothbench {

std::string ReproduceScript(const ResultReader& file, const RunTable& table, const std::string& run_id,
                            const ReproduceOptions& options) {
  const RunRequest q = StoredRunRequest(file, table, run_id);
  std::string toml = q.scene.toml;
  if (!toml.empty() && toml.back() != '\n') toml += '\n';
  const auto meshes = RelativeMeshes(file, toml, file.path());
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

  // The scene text goes through a quoted here-document (no expansion), ended
  // by a delimiter line that the text does not contain.
  std::string delimiter = "CLOTHBENCH_SCENE";
  while (("\n" + toml).find("\n" + delimiter + "\n") != std::string::npos) delimiter += "_";
  // Comment words: quoted, and control characters escaped so that no stored
  // newline ends the comment.
  const auto word = [](const std::string& s) { return ShellQuote(EscapeControl(s)); };
  const auto number = [](double v) { return ShellQuote(fmt::format("{}", v)); };

  std::string s = "#!/bin/sh\n";
  s += fmt::format("# Recomputes run {} of {} (written {} by commit {}, {} build, on {}).\n", word(run_id),
                   word(file.path()), word(table.created), word(table.git_commit), word(table.build_type),
                   word(table.host));
  s += "# The same build and thread count give the same end state bit for bit; the result is the only run of\n";
  s += fmt::format("# {} (clothbench_inspect {} runs).\n", word(out), word(out));
  s += "set -e\n";
  s += fmt::format("mkdir -p -- {}\n", ShellQuote(scene_dir.string()));
  s += fmt::format("cat > {} <<'{}'\n{}{}\n", ShellQuote(scene_file), delimiter, toml, delimiter);
  for (const auto& [rel, abs] : meshes) {
    const fs::path link = scene_dir / rel;
    s += fmt::format("mkdir -p -- {} && ln -sfn -- {} {}\n", ShellQuote(link.parent_path().string()),
                     ShellQuote(fs::absolute(abs).lexically_normal().string()), ShellQuote(link.string()));
  }
  std::string cmd;
  if (q.threads > 0) cmd += fmt::format("OMP_NUM_THREADS={} ", ShellQuote(std::to_string(q.threads)));
  cmd += fmt::format("{} --scene {} --integrators {}", ShellQuote(options.bench), ShellQuote(scene_file),
                     ShellQuote(q.method));
  if (q.h) cmd += fmt::format(" --h {}", number(*q.h));
  if (q.substeps) cmd += fmt::format(" --substeps {}", ShellQuote(std::to_string(*q.substeps)));
  if (q.iterations) cmd += fmt::format(" --iterations {}", ShellQuote(std::to_string(*q.iterations)));
  if (q.rtol) cmd += fmt::format(" --rtols {}", number(*q.rtol));
  if (q.preconditioner) cmd += fmt::format(" --preconditioner {}", ShellQuote(*q.preconditioner));
  if (q.cg_tolerance) cmd += fmt::format(" --cg-tolerance {}", number(*q.cg_tolerance));
  if (q.tangent_terms) cmd += fmt::format(" --tangent-terms {}", ShellQuote(*q.tangent_terms));
  for (const auto& [field, value] : q.settings)  // fields of the registry's settings (ReadRun)
    cmd += fmt::format(" {} {}", FindSetting(field)->option, ShellQuote(value));
  if (q.self_contact) cmd += fmt::format(" --self-contact {}", ShellQuote(*q.self_contact));
  cmd += fmt::format(" --t-end {} --frames {} --reference none --repeat 1 --quiet --out {}", number(*q.t_end),
                     ShellQuote(q.frames), ShellQuote(out));
  return s + cmd + "\n";
}

}  // namespace clothbench

namespace clothbench {

RerunOutcome RerunStored(const ResultReader& file, const RunTable& table, const std::string& run_id,
                         const std::string& out) {
  const RunRequest q = StoredRunRequest(file, table, run_id);
  const ResolvedRun run = q.Resolve();
  const RunRecord& stored = FindRun(file, table, run_id);
  std::optional<OutputLock> lock;  // on <out>.lock, from before the computation to the file's rename
  if (!out.empty()) lock.emplace(out, /*journal_folder=*/true, "--out");
  if (q.threads > 0) SetKernelThreads(static_cast<int>(q.threads));
  const ParticleSystem sys(run.scene);
  RerunOutcome o;
  o.run = run.row.Run(sys, run.scene, run.spec, run.param, run.ctx, run.count);
  o.run.id = stored.id;  // a sweep over CG tolerances named it with its η
  o.run.label = stored.label;
  const std::string g = "/runs/" + run_id;
  const std::string xs = file.Exists(g + "/positions") ? g + "/positions" : g + "/positions_ends";
  const std::string vs = file.Exists(g + "/velocities") ? g + "/velocities" : g + "/velocities_ends";
  o.end_state_kept = file.Exists(xs) && file.Exists(vs) && !o.run.trajectory.positions.empty();
  if (o.end_state_kept) {
    const MatrixN3 x = file.Frame(xs, file.Shape(xs)[0] - 1), v = file.Frame(vs, file.Shape(vs)[0] - 1);
    const MatrixN3 &y = o.run.trajectory.positions.back(), &w = o.run.trajectory.velocities.back();
    if (x.rows() == y.rows() && v.rows() == w.rows()) {
      o.bit_for_bit = x == y && v == w;
      o.max_dx = (x - y).cwiseAbs().maxCoeff();
      o.max_dv = (v - w).cwiseAbs().maxCoeff();
    }
  }
  o.counts_equal = o.run.steps == stored.steps && o.run.updates == stored.updates &&
                   o.run.cg_iterations == stored.cg_iterations && o.run.status == stored.status;
  if (!out.empty()) {
    std::vector<MethodRun> rows;
    rows.push_back(o.run);
    // The stored file's metric (validated), so that the rerun's file names the same one.
    const ErrorMetric metric = ParseErrorMetric(table.error_metric).value_or(DefaultErrorMetric(run.scene));
    CompareToReference(sys, nullptr, run.scene.t_end, metric, &rows);
    const RunTable t = MakeRunTable(run.scene, sys, std::nullopt, rows, q.frames, nullptr, metric);
    WriteResults(out, run.scene, sys, std::nullopt, rows, t, 1);
  }
  return o;
}

}  // namespace clothbench
