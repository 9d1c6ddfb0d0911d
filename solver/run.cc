// Run driver (docs/model.md §6).
#include "solver/run.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>

#include <fmt/format.h>
#include <omp.h>

#include "collision/edge_projection.h"
#include "collision/self_intersection.h"
#include "collision/virtual_particles.h"
#include "model/interrupt.h"
#include "solver/hermite.h"
#include "solver/progress.h"
#include "solver/scheme.h"
#include "solver/thread_budget.h"
#include "collision/cloth_mesh.h"

namespace clothbench {

bool CountCrossings(const std::vector<std::array<int, 3>>& triangles, const MatrixN3& x, double t, bool self_contact,
                    RunSummary* sum) {
  const std::vector<std::pair<int, int>> pairs = SelfIntersections(x, triangles);
  sum->trajectory.crossing_pairs.push_back(static_cast<int32_t>(pairs.size()));
  if (!self_contact || pairs.empty()) return true;
  sum->status = RunStatus::kSelfIntersection;
  sum->message = fmt::format("the cloth crosses itself at t = {:.6g} s: {} crossing triangle pair{} (first: triangles "
                             "{} and {}) despite self-contact",
                             t, pairs.size(), pairs.size() > 1 ? "s" : "", pairs[0].first, pairs[0].second);
  return false;
}

std::vector<double> FrameTimes(double t_end, double frame_dt) {
  std::vector<double> times;
  const long k = static_cast<long>(std::floor(t_end / frame_dt + 1e-9));
  for (long i = 0; i <= k; ++i) times.push_back(static_cast<double>(i) * frame_dt);
  if (t_end - times.back() > 1e-9 * t_end) times.push_back(t_end);
  else times.back() = t_end;
  return times;
}

bool RunOptions::IsValid(std::string* error) const {
  auto fail = [error](std::string msg) {
    if (error) *error = std::move(msg);
    return false;
  };
  if (!(h > 0.0) || !std::isfinite(h)) return fail(fmt::format("h = {} must be a positive number", h));
  if (!(t_end > 0.0) || !std::isfinite(t_end)) return fail(fmt::format("t_end = {} must be a positive number", t_end));
  if (!(frame_dt > 0.0) || frame_dt > t_end) return fail(fmt::format("frame_dt = {} must be in (0, t_end]", frame_dt));
  return true;
}

namespace {

// Cubic Hermite interpolation of positions (and its derivative for the
// velocities) inside a step, exact at both ends (s = 1 returns x1, v1). Its
// position error O(h⁴) is below every method's.
void Hermite(const MatrixN3& x0, const MatrixN3& v0, const MatrixN3& x1, const MatrixN3& v1, double h, double s,
             MatrixN3* x, MatrixN3* v) {
  if (s >= 1.0) {
    *x = x1;
    *v = v1;
    return;
  }
  const HermiteWeights w = HermitePositionWeights(s, h);
  *x = w.x0 * x0 + w.v0 * v0 + w.x1 * x1 + w.v1 * v1;
  const double s2 = s * s;
  const double d00 = 6 * s2 - 6 * s, d10 = 3 * s2 - 4 * s + 1, d11 = 3 * s2 - 2 * s;
  *v = (d00 / h) * x0 + d10 * v0 - (d00 / h) * x1 + d11 * v1;
}

// Power of the non-conservative external forces Σ f_ext·v [W].
double ExternalPower(const ParticleSystem& sys, double t, const MatrixN3& x, const MatrixN3& v, MatrixN3* scratch) {
  scratch->setZero();
  sys.AddExternalForces(t, x, v, scratch);
  return (scratch->array() * v.array()).sum();
}

}  // namespace

namespace {

// The largest speed [m/s] of a keyframed obstacle's surface within reach of
// the cloth (distance R from its anchor), over its keyframe segments: the
// anchor's speed plus |ω| R on each (both constant on a segment); of a
// deforming shape's vertices over the run, t in [0, t_end] [s] (a
// motion-capture clip's T-pose frame before the run does not count).
double ObstacleSpeed(const Obstacle& o, double reach, double t_end) {
  const std::vector<ObstacleKeyframe>& keys = o.spec().keyframes;
  double v = o.MaxVertexSpeedBetween(0.0, t_end);  // a deforming shape (it has no keyframes)
  for (std::size_t k = 0; k + 1 < keys.size(); ++k) {
    const ObstaclePose pose = o.PoseAt(0.5 * (keys[k].t + keys[k + 1].t));
    v = std::max(v, pose.linear_velocity.norm() + pose.angular_velocity.norm() * (reach + pose.translation.norm()));
  }
  return v;
}

}  // namespace

BlowUpGuard::BlowUpGuard(const ParticleSystem& system, const MatrixN3& x0, const MatrixN3& v0, double t_end)
    : sys_(system), proximity_(system),
      path_cull_(system.obstacles(), system.obstacles().empty() ? 0 : static_cast<std::size_t>(system.num_particles())) {
  const Scene& s = system.scene();
  const double g = s.forces.gravity.norm();
  const double diagonal = std::hypot(s.grid.size[0], s.grid.size[1]);
  // Heights along −g (any direction when g = 0).
  const Vector3 up = g > 0.0 ? Vector3(-s.forces.gravity / g) : Vector3::UnitZ();
  const Eigen::VectorXd height = x0 * up;
  const double extent = height.size() ? height.maxCoeff() - height.minCoeff() : 0.0;
  const double drop = extent + (system.fixed().empty() ? 0.5 * g * t_end * t_end : diagonal);
  const double k0 = 0.5 * (system.masses().array() * v0.rowwise().squaredNorm().array()).sum();
  // A floor for scenes without gravity: the whole sheet at 1 m/s.
  const double v_floor = 1.0;
  e_scale_ = system.masses().sum() * (g * drop + 0.5 * v_floor * v_floor) + k0;
  double v_obstacle = 0.0;
  for (const Obstacle& o : system.obstacles()) {
    if (!o.moving()) continue;
    const ObstaclePose rest = o.PoseAt(0.0);
    double reach = 0.0;  // from the anchor to the cloth, plus the sheet's diagonal
    for (int p = 0; p < x0.rows(); ++p)
      reach = std::max(reach, (x0.row(p).transpose() - rest.anchor - rest.translation).norm());
    v_obstacle = std::max(v_obstacle, ObstacleSpeed(o, reach + diagonal, t_end));
  }
  double v_wind = 0.0;
  if (const auto& w = s.forces.wind) v_wind = w->direction.norm() * (std::abs(w->constant) + 1.0);
  const double v0_max = v0.rows() ? v0.rowwise().norm().maxCoeff() : 0.0;
  v_bound_ = std::sqrt(2.0 * g * drop) + v_floor + v0_max + v_wind + std::min(v_obstacle, kMaxObstacleSpeed);
  e0_ = system.Energies(x0, v0).total();
}

ExternalWork::ExternalWork(const ParticleSystem& system, const MatrixN3& x0, const MatrixN3& v0) : sys_(system) {
  if (!system.has_external_work()) return;
  f_ext_.resize(system.num_particles(), 3);
  power_ = ExternalPower(system, 0.0, x0, v0, &f_ext_);
}

double ExternalWork::Advance(double dt, double t, const MatrixN3& x, const MatrixN3& v) {
  if (!sys_.has_external_work()) return work_;
  const double power = ExternalPower(sys_, t, x, v, &f_ext_);
  work_ += 0.5 * dt * (power_ + power);
  power_ = power;
  return work_;
}

void BlowUpGuard::StoreMargins(RunRecord* record) const {
  record->energy_gain_ratio = gain_ratio_;
  record->speed_ratio = speed_ratio_;
  record->penetration_ratio = depth_ratio_;
}

bool BlowUpGuard::CheckFrame(double t, const MatrixN3& x, const MatrixN3& v, RunStatus* status,
                             std::string* message) {
  if (!x.allFinite() || !v.allFinite()) {
    *status = RunStatus::kNonFinite;
    *message = fmt::format("the state became non-finite by t = {:.6g} s", t);
    return false;
  }
  for (std::size_t k = 0; k < sys_.obstacles().size(); ++k) {
    const Obstacle& o = sys_.obstacles()[k];
    const Penetration p = proximity_.PenetrationOf(static_cast<int>(k), o.PoseAt(t), x);
    const double delta = o.spec().collision_distance;
    depth_ratio_ = std::max(depth_ratio_, p.max_depth / delta);
    if (p.max_depth > delta) {
      *status = RunStatus::kPenetration;
      *message = fmt::format("particle {} lies {:.3g} m inside obstacle {} ({}) at t = {:.6g} s, deeper than its "
                             "collision distance {:g} m",
                             p.deepest, p.max_depth, k, o.shape().type(), t, delta);
      return false;
    }
  }
  return true;
}

bool BlowUpGuard::CheckPath(double t0, const MatrixN3& x0, double t1, const MatrixN3& x1, RunStatus* status,
                            std::string* message) {
  for (std::size_t k = 0; k < sys_.obstacles().size(); ++k) {
    const Obstacle& o = sys_.obstacles()[k];
    const ObstaclePose pose = o.PoseAt(t1);
    // A moving obstacle: the path relative to it, from where its motion
    // carries x₀ to x₁ (a particle the obstacle swept past is on the path).
    // A deforming shape carries x₀ by at most (t₁ − t₀) times its largest
    // vertex speed within the step, so the cull (1-Lipschitz bounds)
    // decides before that costs a closest-point query.
    ObstaclePose pose0;
    if (o.moving()) pose0 = o.PoseAt(t0);
    const double shift = pose0.deformed ? (t1 - t0) * o.MaxVertexSpeedBetween(t0, t1) : 0.0;
    path_cull_.Advance(k, pose);
    for (int p = 0; p < x1.rows(); ++p) {
      const Vector3 b = x1.row(p).transpose(), start = x0.row(p).transpose();
      const std::size_t pk = static_cast<std::size_t>(p);
      if (pose0.deformed && path_cull_.Bound(k, pk, start) + path_cull_.Bound(k, pk, b) - shift > (b - start).norm() + shift)
        continue;
      const Vector3 a = o.moving() ? o.Carried(pose0, pose, start, t1 - t0) : start;
      const double length = (b - a).norm();
      if (!(length > 0.0)) continue;
      if (path_cull_.Bound(k, pk, a) + path_cull_.Bound(k, pk, b) > length) continue;
      Vector3 direction;
      const double d1 = o.SignedDistance(pose, b, &direction);
      path_cull_.Record(k, pk, b, d1);
      if (!(d1 > 0.0)) continue;  // ends inside or on it: contact, or CheckFrame's penetration
      const double d0 = o.SignedDistance(pose, a, &direction);
      if (!(d0 > 0.0) || d0 + d1 > length) continue;
      const std::optional<SegmentHit> entry = o.FirstHit(pose, a, b), exit = o.FirstHit(pose, b, a);
      // Through to the other side: it leaves through a face turned away from
      // the one it entered by (normals at more than 120°), not across a
      // corner or a cap it only clipped.
      if (!entry || !exit || entry->normal.dot(exit->normal) > -0.5) continue;
      *status = RunStatus::kTunnelled;
      *message = fmt::format("particle {} passed through obstacle {} ({}) in the step from t = {:.6g} s to {:.6g} s: "
                             "its path of {:.3g} m enters the obstacle {:.3g} m along it, leaves it through the other "
                             "side and ends {:.3g} m outside",
                             p, k, o.shape().type(), t0, t1, length, entry->s * length, d1);
      return false;
    }
  }
  return true;
}

bool BlowUpGuard::Check(double t, const MatrixN3& x, const MatrixN3& v, double external_work,
                        std::optional<double> contact_work, RunStatus* status, std::string* message) {
  if (!x.allFinite() || !v.allFinite()) {
    *status = RunStatus::kNonFinite;
    *message = fmt::format("the state became non-finite by t = {:.6g} s", t);
    return false;
  }
  double e = sys_.Energies(x, v).total();
  // The virtual springs of the step just taken (the topology of its start).
  if (const VirtualSprings* vp = sys_.virtual_springs()) e += vp->TensionEnergyChange(x);
  if (!std::isfinite(e) || !std::isfinite(external_work) || (contact_work && !std::isfinite(*contact_work))) {
    *status = RunStatus::kNonFinite;
    *message = fmt::format("the energy became non-finite by t = {:.6g} s", t);
    return false;
  }
  const bool balance_closed = !open_balance_ && (contact_work || sys_.obstacles().empty());
  const double gain = e - e0_ - external_work - contact_work.value_or(0.0);
  if (balance_closed) gain_ratio_ = std::max({gain_ratio_, 0.0, gain / e_scale_});  // the gain at t = 0 is 0
  if (balance_closed && gain > kEnergyGainFactor * e_scale_) {
    *status = RunStatus::kEnergyGrowth;
    *message = fmt::format("energy gain E - E(0) - W_ext - W_contact = {:.3e} J at t = {:.6g} s exceeds {:g} E_scale "
                           "= {:.3e} J (the drop's potential energy and the initial kinetic energy)",
                           gain, t, kEnergyGainFactor, kEnergyGainFactor * e_scale_);
    return false;
  }
  return CheckSpeed(t, v, status, message);
}

bool BlowUpGuard::CheckSpeed(double t, const MatrixN3& v, RunStatus* status, std::string* message) {
  int fastest = 0;
  const double speed = v.rows() ? v.rowwise().norm().maxCoeff(&fastest) : 0.0;
  speed_ratio_ = std::max(speed_ratio_, speed / v_bound_);
  if (speed > kSpeedFactor * v_bound_) {
    *status = RunStatus::kSpeed;
    *message = fmt::format("particle {} moves at {:.3g} m/s at t = {:.6g} s, above {:g} v_bound = {:.3g} m/s (free "
                           "fall over the scene's drop, initial, wind and obstacle speeds)",
                           fastest, speed, t, kSpeedFactor, kSpeedFactor * v_bound_);
    return false;
  }
  return true;
}

RunSummary RunIntegrator(const ParticleSystem& system, Method method, const RunOptions& options) {
  std::string why;
  if (!options.IsValid(&why) || !system.scene().solver.IsValid(&why)) {
    RunSummary sum;
    sum.status = RunStatus::kInvalidOptions;
    sum.message = why;
    return sum;
  }
  StepEngine engine(system, method, system.scene().solver);
  return RunStepper(system, engine, options);
}

namespace {

// Options the run cannot step with: sum's status "invalid_options" and
// the reason. @return true if refused
bool RefusedOptions(const RunOptions& options, const SolverSpec& spec, Stepper& engine, RunSummary* sum) {
  std::string why;
  if (!options.IsValid(&why) || !spec.IsValid(&why)) {
    sum->status = RunStatus::kInvalidOptions;
    sum->message = why;
    return true;
  }
  if (spec.step_control == StepControl::kError && !engine.estimates_error() && !engine.internal_steps()) {
    sum->status = RunStatus::kInvalidOptions;
    std::string methods;  // the schemes with an error estimate (Scheme::error_controlled)
    for (Method m : kEngineMethods)
      if (SchemeOf(m).error_controlled()) methods += (methods.empty() ? "" : ", ") + std::string(ToString(m));
    sum->message = "solver.step_control = \"error\" needs a method with a local error estimate (" + methods + ")";
    return true;
  }
  return false;
}

// The run's wall-time and step limits after `attempts` steps at `elapsed`
// seconds. @return true (sum failed with time_limit or step_limit) if past one
bool PastLimits(const StepStats& st, const RunOptions& options, double t, long attempts, double elapsed,
                RunSummary* sum) {
  ThrowIfInterrupted();  // Ctrl-C ends the loops inside a step as a deadline would (model/interrupt.h)
  const auto fail = [&](RunStatus status, std::string message) {
    sum->status = status;
    sum->message = std::move(message);
    return true;
  };
  if (st.status == StepStatus::kTimeLimit || CancelRequested() ||
      (options.limits.time_limit_s > 0.0 && elapsed > options.limits.time_limit_s))
    return fail(RunStatus::kTimeLimit, TimeLimitMessage(options.limits.time_limit_s, t, attempts));
  if (attempts >= options.limits.max_steps && t < options.t_end - 1e-12 * options.t_end)
    return fail(RunStatus::kStepLimit, fmt::format("{} step attempts reached t = {:.6g} s of t_end = {:g} s (the limit is {})",
                                          attempts, t, options.t_end, options.limits.max_steps));
  return false;
}

// The frames a run keeps and the work series beside them: allocated before
// the step loop, filled by Hermite interpolation inside each step, trimmed
// to the frames reached.
class FrameRecorder {
 public:
  /// @param self_contact whether the scene asks for self-contact (a
  ///        crossing frame then ends the run)
  /// @param response the self-contact response whose work is recorded, or nullptr
  FrameRecorder(const ParticleSystem& system, Stepper& engine, const RunOptions& options, bool self_contact,
                const SelfContactResponse* response, RunSummary* sum)
      : frames_(FrameTimes(options.t_end, options.frame_dt)),
        dense_(engine.internal_steps()),
        track_work_(system.has_external_work()),
        track_contact_(engine.contact_work() != nullptr),
        virtual_(VirtualParticles::Of(system)),
        self_contact_(self_contact),
        response_(response),
        sum_(sum) {
    if (system.scene().collision) triangles_ = SceneTriangles(system.scene()).vertices;
    Trajectory& tr = sum->trajectory;
    tr.times.reserve(frames_.size());
    tr.positions.assign(frames_.size(), MatrixN3(system.num_particles(), 3));
    tr.velocities.assign(frames_.size(), MatrixN3(system.num_particles(), 3));
    if (track_work_) tr.external_work.assign(frames_.size(), 0.0);
    if (track_contact_)
      for (auto* w : {&tr.contact_work_holding, &tr.contact_work_pulling, &tr.contact_work_friction})
        w->assign(frames_.size(), 0.0);
    if (!triangles_.empty()) tr.crossing_pairs.reserve(frames_.size());
    if (response_) tr.contact_work_self.assign(frames_.size(), 0.0);
    tr.times.push_back(0.0);
    tr.positions[0] = engine.x();
    tr.velocities[0] = engine.v();
    if (!triangles_.empty()) tr.crossing_pairs.push_back(static_cast<int32_t>(SelfIntersections(engine.x(), triangles_).size()));
    if (virtual_) {
      virtual_->Update(0.0, engine.x());
      virtual_->RecordFrame(engine.x(), &tr.virtual_particles);
    }
  }

  /// Keeps the frames inside (t_start, t_start + step] of the step from
  /// (x0, v0) to the engine's state, with the external work (work0 → work1)
  /// and the contact work (from StartStep's to the engine's) at their instants.
  /// @return false (sum's status and message set) if a frame fails `guard`
  /// Notes the contact work series' values at the start of a step.
  void StartStep(const Stepper& engine) {
    if (track_contact_) contact0_ = *engine.contact_work();
    if (response_) self_work0_ = response_->stats().work;
  }

  bool Keep(const Stepper& engine, const MatrixN3& x0, const MatrixN3& v0, double t_start, double step, double work0,
            double work1, BlowUpGuard& guard) {
    Trajectory& tr = sum_->trajectory;
    const std::size_t first = next_;
    // A stepper's own dense output takes the frames within round-off of
    // the step's end (1e-12 s) from the next step's.
    while (next_ < frames_.size() && frames_[next_] <= engine.t() + (dense_ ? 1e-12 : 1e-9 * step)) {
      // A frame at (or within round-off past) the step's end is its state.
      const double s = frames_[next_] >= engine.t() ? 1.0 : (frames_[next_] - t_start) / step;
      if (!FrameState(engine, x0, v0, step, s)) return false;
      // A frame that fails the guard is not kept (the run keeps the ones before).
      if (!guard.CheckFrame(frames_[next_], tr.positions[next_], tr.velocities[next_], &sum_->status, &sum_->message))
        return false;
      const double sc = std::min(s, 1.0);
      if (track_work_) tr.external_work[next_] = work0 + sc * (work1 - work0);
      if (track_contact_) {
        const ContactResponse::Work& contact1 = *engine.contact_work();  // at its end
        tr.contact_work_holding[next_] = contact0_.holding + sc * (contact1.holding - contact0_.holding);
        tr.contact_work_pulling[next_] = contact0_.pulling + sc * (contact1.pulling - contact0_.pulling);
        tr.contact_work_friction[next_] = contact0_.friction + sc * (contact1.friction - contact0_.friction);
      }
      if (response_) tr.contact_work_self[next_] = self_work0_ + sc * (response_->stats().work - self_work0_);
      if (virtual_) {  // the frame's own virtual particles (the next step's, if the frame ends a step)
        virtual_->Update(frames_[next_], tr.positions[next_]);
        virtual_->RecordFrame(tr.positions[next_], &tr.virtual_particles);
      }
      tr.times.push_back(frames_[next_]);
      ++next_;
      if (!triangles_.empty() && !CountCrossings(tr.positions[next_ - 1], frames_[next_ - 1])) return false;
    }
    // With the stepper's own steps, back to the step's end: the next step's topology.
    if (virtual_ && dense_ && next_ != first) virtual_->Update(engine.t(), engine.x());
    return true;
  }

  /// Frame next_'s state at the fraction s of the step from (x0, v0): the
  /// stepper's dense output, else cubic Hermite interpolation; inside a
  /// step that ended at a contact event, to the state before its jumps.
  /// The last frame, a frame at the step's end and every frame of a
  /// stepper that stops at the frames are its state.
  bool FrameState(const Stepper& engine, const MatrixN3& x0, const MatrixN3& v0, double step, double s) {
    Trajectory& tr = sum_->trajectory;
    if (dense_) {
      if (next_ + 1 == frames_.size() || frames_[next_] == engine.t() || dense_->stops_at_frames()) {
        tr.positions[next_] = engine.x();
        tr.velocities[next_] = engine.v();
        return true;
      }
      return dense_->StateAt(frames_[next_], &tr.positions[next_], &tr.velocities[next_], &sum_->status,
                             &sum_->message);
    }
    const MatrixN3 *x1 = &engine.x(), *v1 = &engine.v();
    engine.LeftLimit(&x1, &v1);
    if (s < 1.0)
      Hermite(x0, v0, *x1, *v1, step, s, &tr.positions[next_], &tr.velocities[next_]);
    else
      Hermite(x0, v0, engine.x(), engine.v(), step, s, &tr.positions[next_], &tr.velocities[next_]);
    return true;
  }

  /// The frame's crossing triangle pairs into the trajectory; with the
  /// self-contact response on, a crossing ends the run (the frame is kept).
  bool CountCrossings(const MatrixN3& x, double t) {
    return clothbench::CountCrossings(triangles_, x, t, self_contact_, sum_);
  }

  /// A failed run keeps the frames it reached.
  void Trim() {
    Trajectory& tr = sum_->trajectory;
    tr.positions.resize(next_);
    tr.velocities.resize(next_);
    if (track_work_) tr.external_work.resize(next_);
    if (track_contact_)
      for (auto* w : {&tr.contact_work_holding, &tr.contact_work_pulling, &tr.contact_work_friction}) w->resize(next_);
    if (response_) tr.contact_work_self.resize(next_);
  }

 private:
  std::vector<double> frames_;
  InternalSteps* dense_;  // the stepper's dense output, or nullptr (Hermite)
  bool track_work_, track_contact_;
  VirtualParticles* virtual_;
  bool self_contact_;
  const SelfContactResponse* response_;
  ContactResponse::Work contact0_;  // at the start of the step
  double self_work0_ = 0.0;
  std::vector<std::array<int, 3>> triangles_;  // the cloth's, if its frames are checked for crossings
  RunSummary* sum_;
  std::size_t next_ = 1;
};

// Self-contact on a scene with `[collision] self = true`: the stepper's
// own (Stepper::own_self_contact, the position-based peers) and/or the
// response (collision/self_contact_response.h) that corrects every
// accepted step's end state, for the steppers that take a correction
// (projective dynamics has both: its impulses, then the response as the
// fail-safe).
class SelfContactStage {
 public:
  SelfContactStage(const ParticleSystem& system, Stepper& engine) : sys_(system), engine_(engine) {
    const auto& collision = system.scene().collision;
    active_ = collision && collision->self;
    if (active_ && engine.corrects_state())
      response_.emplace(system, collision->thickness);
    counts_own_ = engine.internal_steps() != nullptr;  // InternalSteps::counted_contact_work
  }
  /// Whether the scene asks for self-contact.
  bool active() const { return active_; }
  /// True (sum's status and message set) if the scene has self-contact and
  /// the stepper neither has its own nor takes a correction.
  bool Refuses(RunSummary* sum) const {
    if (!active_ || response_ || engine_.own_self_contact()) return false;
    sum->status = RunStatus::kUnsupportedScene;
    sum->message = "collision.self = true: this method has no self-contact response (docs/notes/collisions.md, "
                   "\"Self-contact\")";
    return true;
  }
  const SelfContactResponse* response() const { return response_ ? &*response_ : nullptr; }
  /// The counters of the self-contact that acted (both summed), or nothing.
  std::optional<SelfContactStats> stats() const {
    const SelfContactStats* own = engine_.own_self_contact();
    if (!response_ && !own) return std::nullopt;
    SelfContactStats s = response_ ? response_->stats() : SelfContactStats{};
    if (own) s += *own;
    return s;
  }
  double work() const { return response_ ? response_->stats().work : 0.0; }
  /// Corrects the step of size h from x_prev to the engine's state; its wall time [s].
  double Correct(double h, const MatrixN3& x_prev, Stepper& engine) {
    if (!response_) return 0.0;
    const auto start = std::chrono::steady_clock::now();
    x_ = engine.x();
    v_ = engine.v();
    // A step that ended at contact events moved its arrivals onto the
    // obstacles' δ-surfaces after the solve (Stepper::LeftLimit): the
    // response corrects the solve's motion, from the start moved by the
    // same jumps, so a jump is not an approach of 1/h.
    const MatrixN3 *x_left = nullptr, *v_left = nullptr;
    if (engine.LeftLimit(&x_left, &v_left)) {
      start_ = x_prev + (x_ - *x_left);
      response_->Respond(h, start_, &x_, &v_);
    } else {
      response_->Respond(h, x_prev, &x_, &v_);
    }
    engine.CorrectState(x_, v_);
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  /// W_contact for the blow-up guard: the engine's contact work, plus the
  /// self-contact's where the obstacles' is counted or there are none.
  /// Nothing where a stepper's own self-contact does uncounted work.
  std::optional<double> ContactWork(Stepper& engine) const {
    const ContactResponse::Work* contact = engine.contact_work();
    std::optional<double> total = contact ? std::optional(contact->total()) : std::nullopt;
    if (const InternalSteps* internal = engine.internal_steps()) total = total.value_or(0.0) + internal->counted_contact_work();
    if (response_ && (contact || sys_.obstacles().empty())) total = total.value_or(0.0) + work();
    return total;
  }
  /// Whether the energy balance misses work the stepper does not count.
  bool uncounted_work() const { return active_ && !response_ && !counts_own_; }

 private:
  const ParticleSystem& sys_;
  const Stepper& engine_;
  bool active_ = false;
  bool counts_own_ = false;  // the stepper counts its own self-contact's work
  std::optional<SelfContactResponse> response_;
  MatrixN3 x_, v_;  // the corrected state (allocated at the first step)
  MatrixN3 start_;  // the step's start moved by its contact events' jumps
};

// The next step's end and size. Fixed steps (docs/model.md, "Fixed
// steps"): the step is h itself, the same double every step, and the clock
// is set to n·h after each step instead of summing h, so αh, and with it
// A_α and its preconditioner, stays bit-equal from step to step. The last
// step is a whole h when t_end = n·h to within 1e-9 h, else the remainder
// t_end − n·h. Off the grid (step control, or after a rejection) the step
// is h up to t_end.
void PlanStep(bool on_grid, double t_start, long fixed_step_index, double h_nominal, double h, double t_end,
              double* target, double* step) {
  if (on_grid) {
    *target = static_cast<double>(fixed_step_index + 1) * h_nominal;
    const bool at_grid_point = t_start == static_cast<double>(fixed_step_index) * h_nominal;
    *step = at_grid_point ? h_nominal : *target - t_start;
    if (*target > t_end - 1e-9 * h_nominal) {
      if (!at_grid_point || std::abs(*target - t_end) > 1e-9 * h_nominal) *step = t_end - t_start;
      *target = t_end;
    }
  } else {
    *target = t_start + h;
    if (*target > t_end - 1e-9 * h) *target = t_end;
    *step = *target - t_start;
  }
}

// A failed step: the next h, or false (sum's status and message set) once
// the retries are used up or h falls below h_floor.
bool Retry(const StepStats& st, double step, double t, const SolverSpec& spec, double h_floor, bool contacts,
           int consecutive_rejections, double* h, RunSummary* sum) {
  *h = step / spec.step_factor;
  if (st.status == StepStatus::kErrorTestFailed) {
    // Error test failed: h ← h·max(0.2, 0.9 err^(−1/(q+1))) (Hairer, Nørsett
    // & Wanner, Solving ODEs I, §II.4, (4.13)).
    ++sum->error_test_failures;
    *h = step * std::max(0.2, 0.9 * std::pow(st.error_norm, -1.0 / (st.error_order + 1)));
    // With contacts, from the second failure of a step on, h shrinks at
    // least fivefold (CVODE's ETAMXF = 0.2 once nef ≥ SMALL_NEF = 2;
    // Hindmarsh et al. 2005): the stiff transient after a contact event
    // has an error that hardly falls with h until h resolves it, and small
    // decrements used up the retries (measured on round_table at rtol
    // 1e-7). Without obstacles the rule above alone holds, as measured.
    if (contacts && consecutive_rejections >= 2) *h = std::min(*h, 0.2 * step);
  }
  if (consecutive_rejections <= spec.max_rejections && *h >= h_floor) return true;
  sum->status = RunStatusOf(st.status);
  sum->message = fmt::format("step at t = {:.6g} s failed ({}) after {} retries, last h = {:.3g} s", t,
                             ToString(st.status), consecutive_rejections - 1, step);
  if (st.pcg_status == PcgStatus::kMaxIterations)
    sum->message += fmt::format(": the PCG reached solver.cg_max_iterations = {} (raise it or choose another "
                                "preconditioner)",
                                spec.cg_max_iterations);
  return false;
}

// PI controller (Gustafsson 1991; Hairer, Nørsett & Wanner, Solving ODEs I,
// §IV.2 (2.43c) and DOPRI5's defaults β = 0.04, safety 0.9):
// h ← h·0.9·err^(−(1/k − 0.75β))·err_prev^β, k = q + 1, the factor in
// [0.2, 2]: variable-step BDF(2) is zero-stable only for ω = h_n/h_{n−1}
// < 1 + √2 (Grigorieff 1983), and no growth right after a rejection.
double ErrorControlledStep(const StepStats& st, double step, double h_max, bool after_rejection, double* err_prev) {
  constexpr double kBeta = 0.04;
  const double err = std::max(st.error_norm, 1e-4);
  const double k = st.error_order + 1;
  double fac = 0.9 * std::pow(err, -(1.0 / k - 0.75 * kBeta)) * std::pow(*err_prev, kBeta);
  fac = std::clamp(fac, 0.2, 2.0);
  if (after_rejection) fac = std::min(fac, 1.0);
  *err_prev = err;
  return std::min(step * fac, h_max);
}

// The thesis' iteration controller: h shrinks when the fixed point needed
// more than controller_updates[1] updates, grows below controller_updates[0].
double IterationControlledStep(const StepStats& st, double step, double h, double h_max, const SolverSpec& spec,
                               bool single_update) {
  if (!single_update && st.updates > spec.controller_updates[1]) return step / spec.step_factor;
  if (!single_update && st.updates < spec.controller_updates[0]) return std::min(step * spec.step_factor, h_max);
  return std::max(h, step);
}

// The smallest step: h_min, except under error control, where only
// round-off bounds it (CVODE's default hmin = 0) and the retries end a step
// whose error test cannot pass: resolving the stiff transient after a
// contact event takes steps far below 1e-6 s (SolverSpec::h_min).
double StepFloor(const SolverSpec& spec, double t_end) {
  if (spec.step_control != StepControl::kError) return spec.h_min;
  return 16.0 * std::numeric_limits<double>::epsilon() * t_end;
}

// After a rejection, fixed steps return to the grid n·h at the next multiple.
void ReturnToGrid(double t, double h_nominal, double* h, long* fixed_step_index) {
  *h = h_nominal;
  *fixed_step_index = static_cast<long>(std::floor(t / h_nominal + 1e-9));
  const double next = static_cast<double>(*fixed_step_index + 1) * h_nominal;
  if (next - t < 1e-9 * h_nominal) ++*fixed_step_index;
}

// The run's totals after its loop: the solver time (with the virtual
// particles' projection and springs, part of every step; their
// triangulation for the frames is display, not counted), the guard's
// margins, rebuilds, setup and wall time.
void FinishRun(const Stepper& engine, const BlowUpGuard& guard, const VirtualParticles* virtual_particles,
               double solver_seconds, std::chrono::steady_clock::time_point wall_start, RunSummary* sum) {
  if (virtual_particles) solver_seconds += virtual_particles->projection_seconds() + virtual_particles->springs_seconds();
  guard.StoreMargins(sum);
  sum->matrix_rebuilds = engine.matrix_rebuilds();
  if (engine.events() >= 0) sum->events = engine.events();
  sum->solver_time_s = sum->solver_time_s_median = sum->solver_time_s_max = solver_seconds;  // one timing
  sum->setup_time_s = engine.setup_seconds();
  sum->contact_detection_time_s = engine.contact_detection_seconds();
  sum->wall_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
}

// True (sum's status and message set) if the scene moves fixed particles
// (`[[constraints.motion]]`) and the stepper does not follow the motion.
bool RefusesMotion(const ParticleSystem& system, const Stepper& engine, RunSummary* sum) {
  if (!system.has_prescribed_motion() || engine.follows_prescribed_motion()) return false;
  sum->status = RunStatus::kUnsupportedScene;
  sum->message = "constraints.motion: this method does not move fixed particles along a prescribed motion "
                 "(docs/guide/scenes.md, \"Moving fixed particles\")";
  return true;
}

// True (sum's status and message set) if the scene asks for a friction law
// other than the thesis' explicit one at an obstacle with friction, and the
// stepper applies the explicit law only.
bool RefusesFrictionLaw(const ParticleSystem& system, const SolverSpec& spec, const Stepper& engine,
                        RunSummary* sum) {
  if (spec.friction_law == FrictionLaw::kExplicit || !engine.explicit_friction_only()) return false;
  const auto& obstacles = system.obstacles();
  if (std::none_of(obstacles.begin(), obstacles.end(), [](const Obstacle& o) { return o.spec().friction > 0.0; }))
    return false;
  sum->status = RunStatus::kUnsupportedScene;
  sum->message = fmt::format("solver.friction_law = \"{}\": this method applies the explicit friction of "
                             "docs/model.md §2.5 only (docs/notes/collisions.md, \"Friction laws\")",
                             ToString(spec.friction_law));
  return true;
}

// Puts the engine at rest at t = 0; the scene's virtual particles, if any.
// They start empty, before Reset evaluates any force (the error estimate's
// initial slope): the last run's topology would leak into this one.
VirtualParticles* ResetToRest(const ParticleSystem& system, Stepper& engine) {
  VirtualParticles* const virtual_particles = VirtualParticles::Of(system);
  if (virtual_particles) virtual_particles->Clear();
  MatrixN3 x = system.rest_positions(), v = MatrixN3::Zero(system.num_particles(), 3);
  system.Prescribe(0.0, &x, &v);  // moving fixed particles start on their motion
  engine.Reset(0.0, x, v);
  return virtual_particles;
}

}  // namespace

namespace {

// The step size h [s] after an accepted step of `step` [s], one rule per
// step control: the error controller (PI, on err_prev) where the step did
// not end at an event (which says nothing of the error at h), the
// iteration controller, or back to the grid of h_nominal after a
// rejection (fixed steps).
void NextStepSize(const SolverSpec& spec, const std::vector<StepStats>& stats, double step, double h_max,
                  double h_nominal, bool shortened, const Stepper& engine, double* h, double* err_prev,
                  long* fixed_step_index) {
  const StepStats& st = stats.back();
  if (spec.step_control == StepControl::kError) {
    const bool after_rejection = stats.size() >= 2 && stats[stats.size() - 2].status != StepStatus::kOk;
    if (!shortened) *h = ErrorControlledStep(st, step, h_max, after_rejection, err_prev);
  } else if (spec.step_control != StepControl::kFixed) {
    *h = IterationControlledStep(st, step, *h, h_max, spec, engine.single_update());
  } else if (*h < h_nominal) {
    ReturnToGrid(engine.t(), h_nominal, h, fixed_step_index);
  }
}

}  // namespace

std::string TimeLimitMessage(double limit_s, double t, long steps) {
  const double stopped = StoppedSecondsOfRun();
  return fmt::format("wall time past --time-limit {:g} s at t = {:.6g} s after {} steps{}", limit_s, t, steps,
                     stopped >= 0.05 ? fmt::format("; the process was stopped (SIGSTOP, a suspended job) for {:.1f} s "
                                                   "of that wall time",
                                                   stopped)
                                     : std::string());
}

namespace {

// An accepted step's end, from the checks to the frames: the external work
// by the trapezoidal rule on the step (second order), the state and the
// path against the guard, then the frames inside the step; for a stepper
// that chooses its own steps, its jumps after the frames (or before them,
// where it stops at every frame). @return false (sum's status and message
// set) if the run ends here
bool FinishStep(Stepper& engine, const SelfContactStage& self_contact, const MatrixN3& x_prev, const MatrixN3& v_prev,
                double t_start, double step, ExternalWork& external, BlowUpGuard& guard, FrameRecorder& recorder,
                double* solver_seconds, RunSummary* sum) {
  const double work0 = external.work();
  const double work = external.Advance(step, engine.t(), engine.x(), engine.v());
  if (!guard.Check(engine.t(), engine.x(), engine.v(), work, self_contact.ContactWork(engine), &sum->status,
                   &sum->message) ||
      !guard.CheckPath(t_start, x_prev, engine.t(), engine.x(), &sum->status, &sum->message))
    return false;
  InternalSteps* const internal = engine.internal_steps();
  const bool frames_first = !internal || !internal->stops_at_frames();
  if (frames_first && !recorder.Keep(engine, x_prev, v_prev, t_start, step, work0, work, guard)) return false;
  if (!internal) return true;
  const auto start = std::chrono::steady_clock::now();
  const bool ok = internal->EndStep(&sum->status, &sum->message);
  *solver_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return ok && (frames_first || recorder.Keep(engine, x_prev, v_prev, t_start, step, work0, work, guard));
}

// Before each step too: a run started past its deadline (PassedDeadline,
// its library call overran in an earlier process) takes no step.
// @return true (sum's status time_limit) if the deadline has passed
bool StartsPastDeadline(const RunOptions& options, double t, long attempts, RunSummary* sum) {
  if (!DeadlinePassed()) return false;
  ThrowIfInterrupted();
  sum->status = RunStatus::kTimeLimit;
  sum->message = TimeLimitMessage(options.limits.time_limit_s, t, attempts);
  return true;
}

}  // namespace

RunSummary RunStepper(const ParticleSystem& system, Stepper& engine, const RunOptions& options) {
  RunSummary sum;
  RunStepper(system, engine, options, &sum);
  return sum;
}

void RunStepper(const ParticleSystem& system, Stepper& engine, const RunOptions& options, RunSummary* out) {
  using Clock = std::chrono::steady_clock;
  const auto wall_start = Clock::now();
  // Checked inside the steps too (PCG iterations, substeps): a long step
  // stops at the limit, not after it.
  const ScopedDeadline deadline(RunDeadline(wall_start, options.limits.time_limit_s));
  const SolverSpec& spec = options.solver ? *options.solver : system.scene().solver;
  RunSummary& sum = *out;
  if (RefusedOptions(options, spec, engine, &sum)) return;
  // Error-test failures count only under error control (−1: not applicable).
  sum.error_test_failures = spec.step_control == StepControl::kError ? 0 : -1;
  double solver_seconds = 0.0;
  if (RefusesMotion(system, engine, &sum)) return;
  if (RefusesFrictionLaw(system, spec, engine, &sum)) return;
  engine.PlanRun(options.t_end, options.h);
  VirtualParticles* const virtual_particles = ResetToRest(system, engine);
  SelfContactStage self_contact(system, engine);
  if (self_contact.Refuses(&sum)) return;
  // Frames, work series and step statistics are allocated before the loop.
  FrameRecorder recorder(system, engine, options, self_contact.active(), self_contact.response(), &sum);
  ExternalWork external(system, engine.x(), engine.v());
  sum.step_stats.reserve(static_cast<std::size_t>(
      std::min(std::ceil(options.t_end / options.h), static_cast<double>(options.limits.max_steps))) + 64);
  BlowUpGuard guard(system, engine.x(), engine.v(), options.t_end);
  // The response's work, or a prescribed motion's, is not in the balance.
  if (self_contact.uncounted_work() || system.has_prescribed_motion()) guard.OpenBalance();
  long attempts = 0;
  ThreadBudget threads;
  InternalSteps* const internal = engine.internal_steps();  // a SUNDIALS row: it chooses its steps

  MatrixN3 x_prev = engine.x(), v_prev = engine.v();
  const double h_nominal = options.h;
  const bool error_control = spec.step_control == StepControl::kError;
  const double h_max = spec.h_max > 0.0 ? spec.h_max : error_control ? options.t_end : h_nominal;
  const bool controlled = spec.step_control != StepControl::kFixed || internal;
  const double h_floor = StepFloor(spec, options.t_end);
  double err_prev = 1.0;  // the PI controller's previous error norm
  double h = h_nominal;
  int consecutive_rejections = 0;
  long fixed_step_index = 0;  // fixed steps land on n·h exactly (no drift)
  sum.status = RunStatus::kOk;
  // The end: within round-off of t_end, relative; a stepper with its own
  // steps has stored its last frame within 1e-12 s of it (FrameRecorder).
  const double t_last = options.t_end - (internal ? 1e-12 : 1e-12 * options.t_end);

  while (engine.t() < t_last) {
    if (StartsPastDeadline(options, engine.t(), attempts, &sum)) break;
    threads.Update();  // fewer threads while other processes hold cores
    // After a rejection the driver steps with the reduced h and returns to
    // the grid at its next point (ReturnToGrid).
    const bool on_grid = !controlled && consecutive_rejections == 0;
    const double t_start = engine.t();
    double target = 0.0, step = 0.0;
    PlanStep(on_grid, t_start, fixed_step_index, h_nominal, h, options.t_end, &target, &step);

    x_prev = engine.x();
    v_prev = engine.v();
    recorder.StartStep(engine);
    // The thesis' virtual particles of this step, from its initial state
    // (§5.2–5.4): every force evaluation of the step uses them. A frame at
    // the last step's end has computed them already; their time is added
    // to the solver time after the loop, wherever they were computed. A
    // stepper with its own steps has them from the last step's end.
    if (virtual_particles && !internal) virtual_particles->Update(t_start, engine.x());
    const auto t0 = Clock::now();
    StepStats st = engine.Step(step);
    solver_seconds += std::chrono::duration<double>(Clock::now() - t0).count();
    const bool shortened = st.h > 0.0 && st.h < step;  // it ended at a located contact event
    if (shortened) step = st.h;
    if (internal) step = engine.t() - t_start;  // its own internal step
    sum.updates += st.updates;
    sum.cg_iterations += st.cg_iterations;
    sum.step_stats.push_back(st);
    ++attempts;
    if (PastLimits(st, options, engine.t(), attempts, std::chrono::duration<double>(Clock::now() - wall_start).count(),
                   &sum))
      break;
    if (st.status != StepStatus::kOk) {
      if (internal) {  // the library's own retries are used up
        internal->Failure(&sum.status, &sum.message);
        break;
      }
      ++sum.rejected;
      ++consecutive_rejections;
      const bool contacts = engine.contact_work() != nullptr;
      if (!Retry(st, step, engine.t(), spec, h_floor, contacts, consecutive_rejections, &h, &sum)) break;
      continue;
    }
    if (!engine.x().allFinite() || !engine.v().allFinite()) {
      sum.status = RunStatus::kNonFinite;
      sum.message = fmt::format("the state became non-finite in the step to t = {:.6g} s", engine.t());
      break;
    }
    solver_seconds += self_contact.Correct(step, x_prev, engine);
    ++sum.steps;
    if (st.pcg_status != PcgStatus::kConverged) ++sum.cg_unconverged;  // kept by the stepper
    if (on_grid) {
      engine.SetTime(target);  // n·h, not the running sum
      sum.step_stats.back().t = target;
      ++fixed_step_index;
    }
    consecutive_rejections = 0;
    ReportProgress(engine.t());
    // A stepper with its own steps: the next step's virtual particles from
    // this step's end, before its checks (whose energy has their springs)
    // and its jumps (whose restart evaluates the forces).
    if (virtual_particles && internal) virtual_particles->Update(engine.t(), engine.x());
    if (!FinishStep(engine, self_contact, x_prev, v_prev, t_start, step, external, guard, recorder, &solver_seconds,
                    &sum))
      break;
    if (!internal)
      NextStepSize(spec, sum.step_stats, step, h_max, h_nominal, shortened, engine, &h, &err_prev, &fixed_step_index);
  }
  recorder.Trim();
  FinishRun(engine, guard, virtual_particles, solver_seconds, wall_start, &sum);
  if (const auto stats = self_contact.stats()) sum.self_contact = *stats;
  sum.threads_fewest = threads.fewest();
}

int KernelThreads() { return omp_get_max_threads(); }

void SetKernelThreads(int threads) { omp_set_num_threads(threads); }

}  // namespace clothbench
