// The obstacle contact of the particle model in continuous time, as a
// hybrid system (docs/notes/collisions.md, "Contact in continuous time"), for the
// SUNDIALS integrators: each particle is free or slides on one obstacle's
// δ-surface (d − δ = 0, d the signed distance, δ the collision distance).
//
// - Free flight: m a = f.
// - Entry: a free particle's d − δ crosses 0 (a root); its normal velocity
//   relative to the obstacle is removed (an inelastic impact, the h → 0
//   limit of the thesis' (4.4)) and it slides.
// - Sliding: the constraint is held at acceleration level,
//     m a = f + λ n + F_t,   n·(a − a_u) + ṅ·(v − u) = 0,
//   u the obstacle's surface velocity at the particle, a_u its rate along
//   the particle's path and ṅ the rate of the normal along it (the
//   curvature term of a curved or moving obstacle; both by a forward
//   difference over kRateStep). λ ≥ 0 is the normal constraint force.
// - Friction: Coulomb from λ, regularised below the slip velocity v_s:
//   F_t = −c_f λ w_t / max(|w_t|, v_s), w_t the tangential relative
//   velocity (Moreau's sweeping process with a regularised friction law;
//   Stewart & Trinkle 1996 and Brogliato 2016, ch. 5, state the exact
//   Coulomb cone).
// - Release: λ crosses 0 (the constraint would pull): the particle is free.
// - Breaks: a keyframed or frame-sampled motion is piecewise linear, and
//   its surface velocity jumps at the keyframe and frame times
//   (Obstacle::NextBreak), where no rate carries the jump. The integrators
//   stop there, and every particle sliding on a moving obstacle is put back
//   on the δ-surface with no normal velocity relative to the motion's next
//   piece (the mode's d = δ, ḋ = 0); then λ decides, as after an event.
//
// Between events the mode's ODE is smooth; a SUNDIALS integrator locates
// the events with its rootfinding (one root function per free particle:
// d − δ when free, λ when sliding) and restarts after each.
#ifndef CLOTHBENCH_SUNDIALS_HYBRID_CONTACT_H_
#define CLOTHBENCH_SUNDIALS_HYBRID_CONTACT_H_

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "collision/distance_cull.h"
#include "model/particle_system.h"
#include "solver/pcg.h"

namespace clothbench::internal {

class HybridContact {
 public:
  /// Time step of the forward differences of u and n along the path [s].
  static constexpr double kRateStep = 1e-7;
  /// Hysteresis of the events: a free particle enters at d − δ =
  /// −entry_depth [m] (the constructor's, a hundredth of the integrator's
  /// absolute tolerance: below what it resolves), a sliding one is released
  /// at λ = −kReleaseAcceleration m [N] (a pull of 0.1 % of gravity).
  /// Without it a particle grazing the surface with λ ≈ 0 (at the round
  /// table's rim: d − δ = −1e-16 m, λ = −1e-7 N) entered and left
  /// thousands of times at one instant as d − δ's round-off crossed 0, and
  /// particles sliding over the swinging box's edge were released and
  /// caught again at shrinking intervals (17,001 events by t = 0.53 s at
  /// rtol 1e-3; with both thresholds every rtol from 1e-2 to 1e-7 ends ok).
  static constexpr double kReleaseAcceleration = 1e-2;

  /// @param system the model (must outlive this); nothing is allocated
  ///   later than here.
  /// @param entry_depth [m] how far past the δ-surface a free particle's
  ///   entry root lies (hysteresis, above)
  HybridContact(const ParticleSystem& system, double entry_depth);
  /// Whether the scene has obstacles (else nothing here is used).
  bool active() const { return !sys_.obstacles().empty(); }
  /// One root function per particle (fixed particles' is 1).
  int num_roots() const { return sys_.num_particles(); }

  /// Modes at time t from the state (x, v): a particle within δ of an
  /// obstacle (d − δ ≤ 1e-9 m) slides on it if its constraint force would
  /// push (λ ≥ 0), else it is free. Also forgets the events.
  void Initialize(double t, const MatrixN3& x, const MatrixN3& v);

  /// Adds to `f` (the model's forces at (t, x, v), N×3 [N]) the sliding
  /// particles' constraint forces λ n and friction, and keeps λ.
  void AddContactForces(double t, const MatrixN3& x, const MatrixN3& v, MatrixN3* f);

  /// The IMEX split of the sliding particles' dynamics (ARKODE's rows).
  /// With the model's forces f = f_I + f_E (implicit and explicit parts),
  /// a sliding particle obeys m a = S (f_I + f_E) + m c n + F_t, where
  /// S = I − n nᵀ, c = n·a_u − ṅ·(v − u) is the constraint's normal
  /// acceleration and F_t the friction from λ = m c − n·f. SplitExplicit
  /// replaces each sliding particle's row of `fe` (f_E at (t, x, v), N×3
  /// [N]) by S f_E + m c n; the other rows stay.
  void SplitExplicit(double t, const MatrixN3& x, const MatrixN3& v, MatrixN3* fe) const;
  /// Replaces each sliding particle's row of `fi` (f_I at (t, x, v), N×3
  /// [N]) by S f_I + F_t, with λ from fi + fe (`fe` the unsplit explicit
  /// forces); keeps the normals and friction rates (friction_rates()).
  void SplitImplicit(double t, const MatrixN3& x, const MatrixN3& v, const MatrixN3& fe, MatrixN3* fi);
  /// Whether any particle slides.
  bool any_sliding() const;

  /// The root functions g[p] at (t, x, v) with `f` the model's forces
  /// without contact (AddContactForces not applied): d − δ + entry_depth
  /// (the nearest obstacle) for a free particle, λ + kReleaseAcceleration m
  /// [N] for a sliding one, 1 for a fixed one. A free particle far from a
  /// mesh obstacle takes a lower bound of its d in place of d (FreeGap).
  void Roots(double t, const MatrixN3& x, const MatrixN3& v, const MatrixN3& f, double* g);
  /// The distance cull of the free particles' root functions. SUNDIALS'
  /// rootfinding (CVODE, IDA, ARKODE) reads the values of the root
  /// functions that change sign between two evaluations only (the sign
  /// changes and, among them, the secant's ratio). A free particle that
  /// cannot reach its entry depth before the next evaluation needs a
  /// positive value, not its distance: where the distance cull's lower
  /// bound of its distance to a mesh or skeleton obstacle
  /// (collision/distance_cull.h) exceeds δ by kCullMargin δ plus its reach
  /// within the step horizon (set_step_horizon; twice |v| H + ½ |f/m| H²,
  /// plus H times the obstacle's largest vertex speed within H of t), the
  /// root function takes that bound. The runs are then the runs with every
  /// distance exact.
  static constexpr double kCullMargin = 1.0;
  /// The integrators' largest step growth: ARKODE's default (its
  /// ARKStepSetMaxGrowth, 20; CVODE's is 10 and IDA's 2) after their
  /// first step (10⁴ there).
  static constexpr double kStepGrowth = 20.0;
  /// The step horizon H [s]: an upper bound of the time between a root
  /// evaluation and any other that the rootfinding pairs with it. Within
  /// the step just taken (`at_step_end` false: the rootfinding's own
  /// evaluations) that is its length `last_step` [s]. At its end (or at a
  /// (re)start, `steps` = 0 steps since it) also the next step: at most
  /// `max_step` [s] (the integrator's bound, if it has one) and, from the
  /// second step on, kStepGrowth times the last one (+∞ before: the first
  /// step's growth is 10⁴). +∞ (no cull) also after Initialize.
  void set_step_horizon(long steps, double last_step, bool at_step_end, double max_step) {
    const double h = std::abs(last_step);
    const double next = std::min(steps >= 2 ? kStepGrowth * h : std::numeric_limits<double>::infinity(), max_step);
    horizon_ = at_step_end || steps == 0 ? std::max(h, next) : h;
  }
  /// An integrator's getters (CVODE's CVodeGetNumSteps, CVodeGetLastStep,
  /// CVodeGetCurrentTime; IDA's and ARKStep's).
  struct StepGetters {
    int (*num_steps)(void*, long*);
    int (*last_step)(void*, double*);
    int (*current_time)(void*, double*);
  };
  /// The same for an evaluation at t [s] from the integrator's counters,
  /// less its step count at its last restart (ARKStepReset keeps them).
  void set_step_horizon(void* mem, const StepGetters& get, double t, long steps_at_restart = 0,
                        double max_step = std::numeric_limits<double>::infinity()) {
    long steps = 0;
    double last = 0.0, t_n = 0.0;
    if (get.num_steps(mem, &steps) < 0 || get.last_step(mem, &last) < 0 || get.current_time(mem, &t_n) < 0)
      steps = steps_at_restart;  // unknown: no cull
    set_step_horizon(steps - steps_at_restart, last, t >= t_n, max_step);
  }
  /// Turns the distance cull of Roots on (the default) or off (every
  /// distance exact; for the test of its values).
  void set_distance_cull(bool on) { cull_.set_enabled(on); }
  /// Distances Roots bounded instead of querying since construction.
  long culled() const { return culled_; }

  /// The events at a root time t: for every particle with found[p] ≠ 0, a
  /// free one enters (its normal relative velocity is removed and its
  /// distance set to δ), a sliding one is released; so does any free
  /// particle past its entry depth. At a break (`at_break`: t is a
  /// NextBreak of an obstacle) every particle sliding on a moving obstacle
  /// is put back on its δ-surface and its normal velocity relative to the
  /// obstacle's next piece of motion is removed. Then every sliding
  /// particle whose λ at the new state is below the release threshold is
  /// released. `force` evaluates the model's forces at a state. Returns
  /// the number of mode changes.
  template <class Forces>
  int ApplyEvents(double t, const int* found, bool at_break, MatrixN3* x, MatrixN3* v, Forces&& force) {
    return Jump(t, found, at_break ? Resettle::kMoving : Resettle::kNone, x, v, force);
  }
  /// After the self-contact response changed (x, v) at t (N×3 [m], [m/s];
  /// docs/notes/collisions.md, "Self-contact under SUNDIALS"): every
  /// sliding particle it moved inside the δ-surface is put back on it and
  /// its inward normal velocity relative to the obstacle removed, one it
  /// moved off the surface is released, a free one it moved past its entry
  /// depth enters; then λ decides, as after an event. Returns the number
  /// of mode changes.
  template <class Forces>
  int AfterCorrection(double t, MatrixN3* x, MatrixN3* v, Forces&& force) {
    return Jump(t, no_roots_.data(), Resettle::kEvery, x, v, force);
  }
  /// The same with the model's forces (ParticleSystem::Forces); nothing
  /// on a scene without obstacles.
  int AfterCorrection(double t, MatrixN3* x, MatrixN3* v) {
    if (!active()) return 0;
    return AfterCorrection(t, x, v, [this](double s, const MatrixN3& xs, const MatrixN3& vs, MatrixN3* f) {
      sys_.Forces(s, xs, vs, f);
    });
  }

  /// Calls f(p, n) for every sliding particle with its unit normal n at (t, x).
  template <class F>
  void ForEachSliding(F&& f) const {
    for (int p = 0; p < sys_.num_particles(); ++p)
      if (mode_[static_cast<std::size_t>(p)] >= 0) f(p, normal_.row(p).transpose());
  }
  /// Per particle, the rate of its friction force with its tangential
  /// velocity at the last AddContactForces, c_f λ / max(|w_t|, v_s) [kg/s]
  /// (0 for a free particle): what a Newton matrix adds to its diagonal.
  const Eigen::VectorXd& friction_rates() const { return friction_rate_; }
  /// The event times so far [s].
  const std::vector<double>& event_times() const { return event_times_; }
  /// Mode changes so far (entries and releases).
  long mode_changes() const { return mode_changes_; }

 private:
  // Signed distance to obstacle k at (t, p) and its unit normal.
  double Distance(int k, double t, const Vector3& p, Vector3* n) const;
  // Whether the root functions cull obstacle k: a mesh or skeleton (DistanceCull)
  // without a rigid keyframed motion, which has no speed bound here.
  bool Culls(std::size_t k) const { return cull_.culls(k) && sys_.obstacles()[k].spec().keyframes.empty(); }
  // Free particle p's d − δ at (t, x) [m] from its nearest obstacle, or a
  // lower bound of it where that exceeds the cull's margin (kCullMargin)
  // and `reach` [m], how far it may move within the step horizon.
  double FreeGap(double t, int p, const Vector3& x, double reach);
  // The nearest obstacle to p at t: index, and d − δ.
  int Nearest(double t, const Vector3& p, double* gap) const;
  // A lower bound of particle p's d − δ at x [m] from the distance cull's
  // anchors at the cull's last Advance (−∞ where an obstacle is not culled).
  double GapBound(int p, const Vector3& x) const;
  // λ of particle p sliding on obstacle k at (t, x_p, v_p) with f_p the
  // model's force on it; also its normal n, relative velocity w and (if
  // asked) its signed distance [m].
  double Lambda(int k, double t, int p, const Vector3& x, const Vector3& v, const Vector3& f, Vector3* n,
                Vector3* w, double* distance = nullptr) const;
  // What particle p's last Lambda computed apart from its force: kept for
  // a call at the same (k, t, x, v), which gives the same bits (ARKODE's
  // two right-hand sides split the same stage).
  struct LambdaQueries {
    int k = -1;  // −1: none kept
    double t = 0.0;
    Vector3 x, v;
    double d = 0.0;   // signed distance [m]
    Vector3 n, w;     // normal, velocity relative to the surface [m/s]
    double mc = 0.0;  // λ with no force [N]: m (n·a_u − ṅ·w)
  };
  // Which sliding particles a jump puts back on their δ-surface.
  enum class Resettle { kNone, kMoving, kEvery };
  template <class Forces>
  int Jump(double t, const int* found, Resettle resettle, MatrixN3* x, MatrixN3* v, Forces&& force);
  // At a break at t: every particle sliding on a moving obstacle back on
  // its δ-surface, without normal velocity relative to it; returns how many.
  int Reimpose(double t, MatrixN3* x, MatrixN3* v) const;
  // Particle p at d − δ = gap from obstacle k (unit normal n) onto its
  // δ-surface, without inward normal velocity relative to it.
  void OntoSurface(int k, double t, int p, double gap, const Vector3& n, MatrixN3* x, MatrixN3* v) const;
  // After a correction at t: every sliding particle inside its δ-surface
  // back on it (OntoSurface), and every one beyond its entry depth outside
  // it released; returns how many moved or were released.
  int Resettled(double t, MatrixN3* x, MatrixN3* v);
  // The regularised Coulomb force on particle p sliding on obstacle k with
  // normal force λ, normal n and relative velocity w; keeps its rate.
  Vector3 Friction(int k, int p, double lambda, const Vector3& n, const Vector3& w);

  // A mode within ApplyEvents only: released at this event by its λ root
  // (the same found[p] is no entry root).
  static constexpr int kJustReleased = -2;

  const ParticleSystem& sys_;
  double entry_depth_;
  std::vector<int> mode_;     // per particle: −1 free, else the obstacle it slides on
  mutable std::vector<LambdaQueries> lambda_queries_;  // per particle
  MatrixN3 normal_;           // sliding particles' normals at the last AddContactForces/Initialize
  std::vector<double> event_times_;
  long mode_changes_ = 0;
  MatrixN3 f_work_;
  Eigen::VectorXd friction_rate_;
  std::vector<int> no_roots_;  // found[p] = 0 for every particle
  DistanceCull cull_;          // of the free particles' root functions
  long culled_ = 0;
  double horizon_ = std::numeric_limits<double>::infinity();  // set_step_horizon [s]
  std::vector<double> obstacle_reach_;  // per obstacle: its vertices' reach within H of the evaluation [m]
};

template <class Forces>
int HybridContact::Jump(double t, const int* found, Resettle resettle, MatrixN3* x, MatrixN3* v, Forces&& force) {
  for (std::size_t k = 0; k < sys_.obstacles().size(); ++k)
    if (Culls(k) && sys_.obstacles()[k].moving()) cull_.Advance(k, sys_.obstacles()[k].PoseAt(t));
  int changes = 0;
  for (int p = 0; p < sys_.num_particles(); ++p) {
    int& mode = mode_[static_cast<std::size_t>(p)];
    if (found[p] && mode >= 0 && !sys_.is_fixed(p)) {  // release
      mode = kJustReleased;  // no entry below: its root was its λ's
      friction_rate_(p) = 0.0;
      ++changes;
    }
  }
  // Entries: the roots found, and any free particle the jumps left past
  // its entry depth (no root would catch it once the integrator restarts).
  // A particle released now leaves from the δ-surface: if it drifted past
  // its entry depth while it slid, it is put back there, free.
  for (int p = 0; p < sys_.num_particles(); ++p) {
    int& mode = mode_[static_cast<std::size_t>(p)];
    const bool released = mode == kJustReleased;
    if (released) mode = -1;
    if (mode >= 0 || sys_.is_fixed(p)) continue;
    const bool entry_root = found[p] && !released;  // a released particle's root was its λ's
    // Where the cull's bound already puts it above its entry depth, the
    // exact gap would too.
    if (!entry_root && GapBound(p, x->row(p).transpose()) + entry_depth_ >= 0.0) continue;
    double gap = 0.0;
    const int k = Nearest(t, x->row(p).transpose(), &gap);
    if (k < 0 || (!entry_root && gap + entry_depth_ >= 0.0)) continue;
    Vector3 n;
    Distance(k, t, x->row(p).transpose(), &n);
    OntoSurface(k, t, p, gap, n, x, v);  // an inelastic impact
    if (released) continue;
    mode = k;
    ++changes;
  }
  const int reimposed = resettle == Resettle::kMoving  ? Reimpose(t, x, v)
                        : resettle == Resettle::kEvery ? Resettled(t, x, v)
                                                       : 0;
  if (changes == 0 && reimposed == 0) return 0;
  // Every sliding particle slides on only if its constraint force pushes
  // after the jumps: a neighbour's impact changes the damping force on a
  // particle, and its λ can jump below the release threshold, where no
  // root would catch it after the restart (on the swinging box a particle
  // stayed held to the side for 1.5 s at λ = −0.05 N).
  force(t, *x, *v, &f_work_);
  for (int p = 0; p < sys_.num_particles(); ++p) {
    int& mode = mode_[static_cast<std::size_t>(p)];
    if (mode < 0) continue;
    Vector3 n, w;
    const double lam = Lambda(mode, t, p, x->row(p).transpose(), v->row(p).transpose(), f_work_.row(p).transpose(), &n, &w);
    if (lam < -kReleaseAcceleration * sys_.masses()(p)) {
      mode = -1;
      friction_rate_(p) = 0.0;
      ++changes;
    } else {
      normal_.row(p) = n.transpose();
    }
  }
  if (changes == 0) return 0;
  event_times_.push_back(t);
  mode_changes_ += changes;
  return changes;
}

}  // namespace clothbench::internal

#endif  // CLOTHBENCH_SUNDIALS_HYBRID_CONTACT_H_
