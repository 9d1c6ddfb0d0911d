#include "harness/run_request.h"

#include <algorithm>
#include <cstdlib>
#include <cmath>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "harness/cli_args.h"
#include "harness/memory_check.h"
#include "harness/sweep.h"
#include "solver/sewing.h"

namespace clothbench {

std::string SceneHash(const Scene& scene) {
  return Fnv1a64(fmt::format("{}\nt_end={:.17g} frame_dt={:.17g}", scene.toml, scene.t_end, scene.frame_dt));
}

std::string RunRequest::Field(std::string_view field) const {
  for (const auto& [k, name] : renamed)
    if (k == field) return name;
  if (names == FieldNames::kKeyword) return std::string(field);
  static const std::pair<std::string_view, std::string_view> kOptions[] = {
      {"method", "--integrators"},       {"h", "--h"},
      {"rtol", "--rtols"},               {"substeps", "--substeps"},        {"iterations", "--iterations"},
      {"cg_tolerance", "--cg-tolerance"}, {"preconditioner", "--preconditioner"},
      {"tangent_terms", "--tangent-terms"}, {"t_end", "--t-end"},
      {"frames", "--frames"},            {"threads", "OMP_NUM_THREADS"},
      {"time_limit", "--time-limit"},    {"repeat", "--repeat"},
      {"time_budget", "--time-budget"},  {"reference", "--reference"},
      {"self_contact", "--self-contact"}};
  for (const auto& [k, o] : kOptions)
    if (k == field) return std::string(o);
  if (const MethodSetting* setting = FindSetting(field)) return std::string(setting->option);
  return std::string(field);
}

namespace {

UsageError Fail(const RunRequest& q, std::string_view field, const std::string& rule) {
  return UsageError(fmt::format("{}: {}", q.Field(field), rule));
}

// Refuses option `field` of q if row m does not read it (RowOptions()).
void RefuseUnread(const RunRequest& q, const RowMethod& m, std::string_view field) {
  const RowOption& o = RowOptionOf(field);
  if (!o.reads(m)) throw Fail(q, field, fmt::format("{} does not read it (it applies to {})", m.label(), RowsReading(o)));
}

}  // namespace

void CheckThreadEnvironment() {
  const char* env = std::getenv("OMP_NUM_THREADS");
  if (!env) return;
  // OpenMP's form: a count, or a comma-separated list of counts (one per
  // nesting level); every count as the request's `threads` rule has it.
  const std::string text = env;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = text.find(',', start);
    const std::string item = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    const bool digits = !item.empty() && item.size() <= 7 &&
                        std::all_of(item.begin(), item.end(), [](char c) { return c >= '0' && c <= '9'; });
    const long n = digits ? std::stol(item) : -1;
    if (n < 1 || n > kMaxThreads)
      throw UsageError(fmt::format("OMP_NUM_THREADS: \"{}\" must be a whole number of threads from 1 to {} (or a "
                                   "comma-separated list of them)",
                                   EscapeControl(text.substr(0, 40)), kMaxThreads));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
}

namespace {

// t_end (and with it frame_dt and h) and the frames mode.
// self_contact: "on" or "off" over the scene's [collision] (RunRequest).
void ApplySelfContact(const RunRequest& q, Scene* s) {
  if (!q.self_contact) return;
  if (*q.self_contact != "on" && *q.self_contact != "off")
    throw Fail(q, "self_contact", fmt::format("\"{}\" must be on or off", EscapeControl(*q.self_contact)));
  SelfCollisionSpec spec = s->collision.value_or(SelfCollisionSpec{});
  spec.self = *q.self_contact == "on";
  if (spec.self)
    if (const std::string why = SelfContactThicknessRule(*s, spec.thickness); !why.empty())
      throw Fail(q, "self_contact", fmt::format("on: the thickness {:g} m {} (set [collision] thickness in the scene)",
                                                spec.thickness, why));
  s->collision = spec;
}

void ApplyTimes(const RunRequest& q, Scene* s) {
  if (q.t_end) {
    if (!std::isfinite(*q.t_end) || !(*q.t_end > 0.0) || *q.t_end > 1e6)
      throw Fail(q, "t_end", fmt::format("{:g} s must be a number in (0, 1e6]", *q.t_end));
    s->t_end = *q.t_end;
    s->frame_dt = std::min(s->frame_dt, s->t_end);
    s->h = std::min(s->h, s->t_end);
  }
  try {
    CheckRunLength(*s, q.Field("t_end"));
  } catch (const SceneError& e) {
    throw UsageError(e.what());
  }
  static const char* const kFrames[] = {"default", "all", "positions", "ends", "none"};
  if (std::find(std::begin(kFrames), std::end(kFrames), q.frames) == std::end(kFrames))
    throw Fail(q, "frames", fmt::format("\"{}\" must be default, all, positions, ends or none", EscapeControl(q.frames)));
  if (q.frames == "ends" || q.frames == "none") s->frame_dt = s->t_end;
}

// The values of cg_tolerance and tangent_terms (whether a row reads them is
// checked against the row).
void CheckCgTolerance(const RunRequest& q) {
  if (q.cg_tolerance && !(*q.cg_tolerance > 0.0 && *q.cg_tolerance < 1.0))
    throw Fail(q, "cg_tolerance", fmt::format("{:g} must be in (0, 1)", *q.cg_tolerance));
}
void CheckTangentTerms(const RunRequest& q) {
  if (q.tangent_terms && *q.tangent_terms != "all" && *q.tangent_terms != "tension")
    throw Fail(q, "tangent_terms", fmt::format("\"{}\" must be all or tension", EscapeControl(*q.tangent_terms)));
}

// Time limit, repetitions and timing budget.
void CheckTimes(const RunRequest& q) {
  if (!std::isfinite(q.time_limit) || !(q.time_limit > 0.0) || q.time_limit > 1e7)
    throw Fail(q, "time_limit", fmt::format("{:g} s must be a number in (0, 1e7]", q.time_limit));
  if (q.repeat && (*q.repeat < 1 || *q.repeat > 1000))
    throw Fail(q, "repeat", fmt::format("{} must be a whole number from 1 to 1000", *q.repeat));
  if (!std::isfinite(q.time_budget) || !(q.time_budget >= 0.0) || q.time_budget > 1e6)
    throw Fail(q, "time_budget", fmt::format("{:g} s must be a number in [0, 1e6]", q.time_budget));
}

// The one registry row the method names, on the scene's step control.
RowMethod ResolveRow(const RunRequest& q, const Scene& s) {
  std::vector<RowMethod> rows;
  try {
    rows = ExpandMethods({q.method}, {s.solver.nonlinear_solver}, q.Field("method"));
    AdoptSceneStepControl(s.solver, &rows, /*named=*/true, q.Field("method"));
  } catch (const std::invalid_argument& e) {
    throw UsageError(EscapeControl(e.what()));
  }
  if (rows.size() != 1)
    throw Fail(q, "method", fmt::format("\"{}\" names {} rows; name one", EscapeControl(q.method), rows.size()));
  return rows.front();
}

// h, rtol, substeps and iterations, each only where the row reads it.
void ResolveStep(const RunRequest& q, ResolvedRun* out) {
  const RowMethod& m = out->row;
  const Scene& s = out->scene;
  const std::string label = m.label();
  const StepKindSpec& kind = SpecOf(m.kind());
  if (kind.adaptive()) {
    if (q.h) throw Fail(q, "h", fmt::format("{} is adaptive: it reads rtol, not h", label));
    double r = 0.0;
    if (q.rtol) r = *q.rtol;
    else if (m.error_control && s.solver.step_control == StepControl::kError) r = s.solver.rtol;
    else throw Fail(q, "rtol", fmt::format("{} is adaptive: give rtol", label));
    CheckTolerance(r, q.Field("rtol"));
    out->param = r;
  } else {
    if (q.rtol) RefuseUnread(q, m, "rtol");
    if (!q.h) throw Fail(q, "h", fmt::format("{} steps with h: give h [s]", label));
    if (!std::isfinite(*q.h) || !(*q.h > 0.0)) throw Fail(q, "h", fmt::format("{:g} s is not a positive number", *q.h));
    if (*q.h > s.t_end) throw Fail(q, "h", fmt::format("{:g} s is larger than t_end = {:g} s", *q.h, s.t_end));
    out->param = *q.h;
  }
  if (q.substeps) {
    RefuseUnread(q, m, "substeps");
    if (*q.substeps < 1 || *q.substeps > 1000000)
      throw Fail(q, "substeps", fmt::format("{} must be a whole number from 1 to 1e6", *q.substeps));
    out->count = static_cast<int>(*q.substeps);
  }
  if (q.iterations) {
    RefuseUnread(q, m, "iterations");
    if (*q.iterations < 1 || *q.iterations > 1000000)
      throw Fail(q, "iterations", fmt::format("{} must be a whole number from 1 to 1e6", *q.iterations));
    out->count = static_cast<int>(*q.iterations);
  }
  const double step = kind.count_divides_h ? out->param / out->count : out->param;
  if (!kind.adaptive() && s.t_end / step > kMaxStepsPerRun)
    throw Fail(q, "h", fmt::format("t_end/h = {:g}/{:g} = {:.3g} steps exceeds the limit of {:g}", s.t_end, step,
                                   s.t_end / step, kMaxStepsPerRun));
}

// The solver options, each only where the row reads it, into the scene's
// solver settings and the run's context.
void ApplyOptions(const RunRequest& q, ResolvedRun* out) {
  const RowMethod& m = out->row;
  SolverSpec& solver = out->scene.solver;
  const std::string label = m.label();
  if (q.cg_tolerance) {
    RefuseUnread(q, m, "cg_tolerance");
    CheckCgTolerance(q);
    solver.cg_tolerance = *q.cg_tolerance;
    out->ctx.cg_tolerance_from_cli = true;
  }
  if (q.preconditioner) {
    RefuseUnread(q, m, "preconditioner");
    solver.preconditioner = ParsePreconditioner(EscapeControl(*q.preconditioner), q.Field("preconditioner"));
    out->ctx.preconditioner_from_cli = true;
  }
  if (q.tangent_terms) {
    RefuseUnread(q, m, "tangent_terms");
    CheckTangentTerms(q);
    solver.tangent_explicit_terms = *q.tangent_terms == "all";
    out->ctx.tangent_terms_from_cli = true;
  }
  for (const auto& [field, value] : q.settings) {
    const MethodSetting* setting = FindSetting(field);
    if (!setting) throw Fail(q, field, "is not a setting of any method");
    RefuseUnread(q, m, field);
    if (const std::string why = setting->check(value); !why.empty()) throw Fail(q, field, EscapeControl(why));
    out->ctx.settings.emplace_back(field, value);
  }
}

// Threads, time limit, repetitions and the reference's scene.
void CheckLimits(const RunRequest& q, ResolvedRun* out) {
  if (q.threads < 0 || q.threads > kMaxThreads)
    throw Fail(q, "threads", fmt::format("{} must be 0 (the process' own) or from 1 to {}", q.threads, kMaxThreads));
  if (q.threads == 0) CheckThreadEnvironment();
  CheckTimes(q);
  out->ctx.limits.time_limit_s = q.time_limit;
  if (q.reference_scene && *q.reference_scene != SceneHash(out->scene))
    throw Fail(q, "reference",
               "was computed on another scene, t_end or frame spacing than this run's (scene hash " +
                   EscapeControl(*q.reference_scene) + ", this run's " + SceneHash(out->scene) + ")");
}

}  // namespace

ResolvedRun RunRequest::Resolve() const {
  ResolvedRun out;
  out.scene = scene;
  ApplyTimes(*this, &out.scene);
  ApplySelfContact(*this, &out.scene);
  out.row = ResolveRow(*this, out.scene);
  ResolveStep(*this, &out);
  ApplyOptions(*this, &out);
  CheckLimits(*this, &out);
  out.spec = out.scene.solver;
  // The one run's memory, before anything is computed, at every door
  // (bench_integrators checks its whole plan as well): its step records
  // are one per step of a fixed-step row, unknown (0) for adaptive ones.
  const double records = SpecOf(out.row.kind()).adaptive() ? 0.0 : out.scene.t_end / out.param;
  CheckMemory(out.scene, {out.row}, {1}, 1, std::nullopt, records);
  Sew(&out.scene);  // a garment's sewing phase, once per scene (solver/sewing.h)
  return out;
}

Scene RunRequest::SweepScene() const {
  Scene s = scene;
  ApplyTimes(*this, &s);
  ApplySelfContact(*this, &s);
  CheckCgTolerance(*this);
  CheckTangentTerms(*this);
  CheckTimes(*this);
  if (cg_tolerance) s.solver.cg_tolerance = *cg_tolerance;
  if (preconditioner) s.solver.preconditioner = ParsePreconditioner(EscapeControl(*preconditioner), Field("preconditioner"));
  if (tangent_terms) s.solver.tangent_explicit_terms = *tangent_terms == "all";
  Sew(&s);  // a garment's sewing phase, once per scene (solver/sewing.h)
  return s;
}

void RunRequest::Validate() const { (void)Resolve(); }


}  // namespace clothbench
