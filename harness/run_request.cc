#include "harness/run_request.h"

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "harness/cli_args.h"
#include "harness/sweep.h"

namespace clothbench {
namespace {

// The registry's methods with `flag` set, for messages ("cvode, ida").
std::string RowsThat(bool MethodEntry::*flag) {
  std::string out;
  for (const MethodEntry& e : Registry())
    if (e.*flag) out += (out.empty() ? "" : ", ") + std::string(e.name);
  return out;
}

std::string RowsOfKind(StepKind kind) {
  std::string out;
  for (const MethodEntry& e : Registry())
    if (e.kind == kind) out += (out.empty() ? "" : ", ") + std::string(e.name);
  return out;
}

}  // namespace

std::string SceneHash(const Scene& scene) {
  return Fnv1a64(fmt::format("{}\nt_end={:.17g} frame_dt={:.17g}", scene.toml, scene.t_end, scene.frame_dt));
}

std::string RunRequest::Field(std::string_view field) const {
  for (const auto& [k, name] : renamed)
    if (k == field) return name;
  if (names == FieldNames::kKeyword) return std::string(field);
  static const std::pair<std::string_view, std::string_view> kOptions[] = {
      {"method", "--integrators"},       {"h", "--h"},
      {"rtol", "--rtols"},               {"substeps", "--substeps"},
      {"cg_tolerance", "--cg-tolerance"}, {"preconditioner", "--preconditioner"},
      {"tangent_terms", "--tangent-terms"}, {"arkode_table", "--arkode-table"},
      {"cvode_setting", "--cvode-setting"}, {"t_end", "--t-end"},
      {"frames", "--frames"},            {"threads", "OMP_NUM_THREADS"},
      {"time_limit", "--time-limit"},    {"repeat", "--repeat"},
      {"time_budget", "--time-budget"},  {"reference", "--reference"}};
  for (const auto& [k, o] : kOptions)
    if (k == field) return std::string(o);
  return std::string(field);
}

ResolvedRun RunRequest::Resolve() const {
  const auto fail = [this](std::string_view field, const std::string& rule) {
    return UsageError(fmt::format("{}: {}", Field(field), rule));
  };
  ResolvedRun out;
  out.scene = scene;
  Scene& s = out.scene;
  if (t_end) {
    if (!std::isfinite(*t_end) || !(*t_end > 0.0) || *t_end > 1e6)
      throw fail("t_end", fmt::format("{:g} s must be a number in (0, 1e6]", *t_end));
    s.t_end = *t_end;
    s.frame_dt = std::min(s.frame_dt, s.t_end);
    s.h = std::min(s.h, s.t_end);
  }
  try {
    CheckRunLength(s, Field("t_end"));
  } catch (const SceneError& e) {
    throw UsageError(e.what());
  }
  static const char* const kFrames[] = {"default", "all", "positions", "ends", "none"};
  if (std::find(std::begin(kFrames), std::end(kFrames), frames) == std::end(kFrames))
    throw fail("frames", fmt::format("\"{}\" must be default, all, positions, ends or none", EscapeControl(frames)));
  if (frames == "ends" || frames == "none") s.frame_dt = s.t_end;

  std::vector<RowMethod> rows;
  try {
    rows = ExpandMethods({method}, {s.solver.nonlinear_solver}, Field("method"));
    AdoptSceneStepControl(s.solver, &rows, /*named=*/true, Field("method"));
  } catch (const std::invalid_argument& e) {
    throw UsageError(EscapeControl(e.what()));
  }
  if (rows.size() != 1)
    throw fail("method", fmt::format("\"{}\" names {} rows; name one", EscapeControl(method), rows.size()));
  out.row = rows.front();
  const RowMethod& m = out.row;
  const std::string label = m.label();
  const bool adaptive = m.kind() == StepKind::kAdaptive;

  // h, rtol, substeps: each only where the row reads it.
  if (adaptive) {
    if (h) throw fail("h", fmt::format("{} is adaptive: it reads rtol, not h", label));
    double r = 0.0;
    if (rtol) r = *rtol;
    else if (m.error_control && s.solver.step_control == StepControl::kError) r = s.solver.rtol;
    else throw fail("rtol", fmt::format("{} is adaptive: give rtol", label));
    CheckTolerance(r, Field("rtol"));
    out.param = r;
  } else {
    if (rtol) throw fail("rtol", fmt::format("{} steps with h: it reads h, not rtol", label));
    if (!h) throw fail("h", fmt::format("{} steps with h: give h [s]", label));
    if (!std::isfinite(*h) || !(*h > 0.0)) throw fail("h", fmt::format("{:g} s is not a positive number", *h));
    if (*h > s.t_end) throw fail("h", fmt::format("{:g} s is larger than t_end = {:g} s", *h, s.t_end));
    out.param = *h;
  }
  if (substeps) {
    if (m.kind() != StepKind::kSubstepped)
      throw fail("substeps", fmt::format("{} is not substepped (substepped rows: {})", label, RowsOfKind(StepKind::kSubstepped)));
    if (*substeps < 1 || *substeps > 1000000)
      throw fail("substeps", fmt::format("{} must be a whole number from 1 to 1e6", *substeps));
    out.substeps = static_cast<int>(*substeps);
  }
  if (!adaptive && s.t_end / (out.param / out.substeps) > kMaxStepsPerRun)
    throw fail("h", fmt::format("t_end/h = {:g}/{:g} = {:.3g} steps exceeds the limit of {:g}", s.t_end,
                                out.param / out.substeps, s.t_end / (out.param / out.substeps), kMaxStepsPerRun));

  // Solver options: each only where the row reads it.
  if (cg_tolerance) {
    if (!m.uses_pcg()) throw fail("cg_tolerance", fmt::format("{} does not solve with the PCG", label));
    if (!(*cg_tolerance > 0.0 && *cg_tolerance < 1.0))
      throw fail("cg_tolerance", fmt::format("{:g} must be in (0, 1)", *cg_tolerance));
    s.solver.cg_tolerance = *cg_tolerance;
    out.ctx.cg_tolerance_from_cli = true;
  }
  if (preconditioner) {
    if (!m.uses_pcg()) throw fail("preconditioner", fmt::format("{} does not solve with the PCG", label));
    s.solver.preconditioner = ParsePreconditioner(EscapeControl(*preconditioner), Field("preconditioner"));
    out.ctx.preconditioner_from_cli = true;
  }
  if (tangent_terms) {
    if (!m.builds_tangent())
      throw fail("tangent_terms", fmt::format("{} does not build J_alpha (rows that do: Newton rows, {})", label,
                                              RowsThat(&MethodEntry::tangent)));
    if (*tangent_terms != "all" && *tangent_terms != "tension")
      throw fail("tangent_terms", fmt::format("\"{}\" must be all or tension", EscapeControl(*tangent_terms)));
    s.solver.tangent_explicit_terms = *tangent_terms == "all";
    out.ctx.tangent_terms_from_cli = true;
  }
  if (arkode_table) {
    if (!m.reads_arkode_table())
      throw fail("arkode_table", fmt::format("{} does not read it (arkode rows without a variant do)", label));
    const auto& tables = ArkodeTableNames();
    if (std::find(tables.begin(), tables.end(), *arkode_table) == tables.end()) {
      std::string known;
      for (const std::string& t : tables) known += (known.empty() ? "" : ", ") + t;
      throw fail("arkode_table", fmt::format("\"{}\" must be one of {}", EscapeControl(*arkode_table), known));
    }
    out.ctx.arkode_table = *arkode_table;
  }
  if (cvode_setting) {
    if (!m.entry->cvode_settings)
      throw fail("cvode_setting", fmt::format("{} does not read it ({} rows do)", label, RowsThat(&MethodEntry::cvode_settings)));
    if (!cvode_setting->empty())
      for (const std::string& kv : SplitList(*cvode_setting, Field("cvode_setting"))) {
        const std::size_t eq = kv.find('=');
        std::string why;
        if (eq == std::string::npos || !out.ctx.cvode.Set(kv.substr(0, eq), kv.substr(eq + 1), &why))
          throw fail("cvode_setting",
                     EscapeControl(why.empty() ? "\"" + kv + "\" is not KEY=VALUE" : why));
      }
  }

  // Limits.
  if (threads < 0 || threads > kMaxThreads)
    throw fail("threads", fmt::format("{} must be 0 (the process' own) or from 1 to {}", threads, kMaxThreads));
  if (!std::isfinite(time_limit) || !(time_limit > 0.0) || time_limit > 1e7)
    throw fail("time_limit", fmt::format("{:g} s must be a number in (0, 1e7]", time_limit));
  out.ctx.limits.time_limit_s = time_limit;
  if (repeat && (*repeat < 1 || *repeat > 1000))
    throw fail("repeat", fmt::format("{} must be a whole number from 1 to 1000", *repeat));
  if (!std::isfinite(time_budget) || !(time_budget >= 0.0) || time_budget > 1e6)
    throw fail("time_budget", fmt::format("{:g} s must be a number in [0, 1e6]", time_budget));
  if (reference_scene && *reference_scene != SceneHash(s))
    throw fail("reference", "was computed on another scene, t_end or frame spacing than this run's (scene hash " +
                                EscapeControl(*reference_scene) + ", this run's " + SceneHash(s) + ")");
  out.spec = s.solver;
  return out;
}

void RunRequest::Validate() const { (void)Resolve(); }

bool RunRequest::IsValid(std::string* error) const {
  try {
    Validate();
    return true;
  } catch (const std::invalid_argument& e) {
    if (error) *error = e.what();
    return false;
  }
}

}  // namespace clothbench
