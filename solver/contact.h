// Collision response through the velocity filter (docs/model.md §7; thesis (4.3),
// (4.4), §5.1) with explicit Coulomb friction (docs/model.md §2.5), shared by the
// thesis' methods (StepEngine) and the peers that use the same filter
// (Baraff–Witkin). Contacts are set up once per step, from the state at its
// start; the constraint impulses read after the solve decide release and
// friction in the next step.
#ifndef CLOTHBENCH_SOLVER_CONTACT_H_
#define CLOTHBENCH_SOLVER_CONTACT_H_

#include <cstdint>
#include <limits>
#include <vector>

#include "collision/obstacle_contacts.h"
#include "model/particle_system.h"
#include "solver/pcg.h"

namespace clothbench {

/// How a step's predictor carries the past velocity changes (a multistep
/// formula, docs/model.md §4): v̂ − v₀ = d1 (v₀ − v₋₁) + d2 (v₋₁ − v₋₂).
/// Zero: a one-step formula (v̂ = v₀).
struct HistoryCarry {
  double d1 = 0.0, d2 = 0.0;
};

class ContactResponse {
 public:
  /// Allocates the per-particle state (nothing if the scene has no obstacles).
  explicit ContactResponse(const ParticleSystem& system);

  /// Whether the scene has obstacles (otherwise nothing here is ever used).
  bool active() const { return !contacts_.empty(); }
  /// Forgets every contact (a new run).
  void Reset();
  /// A multistep method's rows: keeps, per particle, the contact impulses
  /// of the last `steps` (1 or 2) accepted steps with what the history
  /// carried of them (ReadImpulses' HistoryCarry). Allocates 3·steps N×3
  /// matrices; call before the run.
  void KeepEchoes(int steps);

  /// Rebuilds `filter` for a step of size h [s] from t0 [s]: the fixed
  /// particles, then one direction per colliding particle with the (4.4)
  /// target velocity; computes the friction forces (friction()).
  /// @param x0, v0 N×3 state at t0 [m], [m/s]
  /// @param xm1 N×3 positions one step earlier, or nullptr without history
  /// @return the number of colliding particles (Fig. 4.3). No allocation.
  int SetUp(double t0, double h, const MatrixN3& x0, const MatrixN3& v0, const MatrixN3* xm1, VelocityFilter* filter);
  /// SetUp for a solve again of the same step (after ReviseHolds returned
  /// true): rebuilds `filter` and the friction from the contacts the last
  /// SetUp detected (same t0, h and start state, so detection would find
  /// them again), with this step's releases. No detection, no allocation.
  /// @return the number of colliding particles
  int SetUpAgain(VelocityFilter* filter);

  /// Event location (docs/notes/collisions.md, "Error control through contact
  /// events"), for the error-controlled methods: with a tolerance ε > 0
  /// [m], SetUp constrains no particle for a predicted entry more than ε
  /// away; the step runs free, Crossing finds where it crossed into the
  /// collision area, the step is set up again up to there, and
  /// ApplyJumps applies the entries' jumps. 0 (the default) turns it off.
  void set_event_tolerance(double tolerance) { event_tolerance_ = tolerance; }
  /// The friction law (model/solver_spec.h, FrictionLaw): the thesis'
  /// explicit capped impulse (the default) or the regularised Coulomb law.
  void set_friction_law(FrictionLaw law) { friction_law_ = law; }
  /// FrictionCap::kStiction (model/solver_spec.h): a contact whose friction
  /// the mass cap would stop is held by the filter in all three directions
  /// instead of by an explicit impulse; it slides in the next step once
  /// the tangential impulse that held it exceeds μ J_N.
  void set_stiction(bool on) { stiction_ = on; }
  /// Whether a step's solve may be revised (ReviseHolds): stiction may hold
  /// contacts (set_stiction), or the implicit friction may leave its cone
  /// (FrictionLaw::kImplicit); and the scene has obstacles.
  bool revises() const { return (stiction_ || IsImplicit(friction_law_)) && active(); }
  /// The active set's solves of one step beyond the first, at most.
  static constexpr int kHoldRevisions = 8;
  /// The earliest fraction θ ∈ (0, 1] of the step from t0 over h [s] at
  /// which a particle free in it (the last SetUp constrained it not, and it
  /// started outside the collision area) reaches d = δ, among those ending
  /// deeper than δ − ε: by bisection on d − δ along the cubic Hermite
  /// interpolant of (x0, v0) → (x1, v1) (N×3 [m], [m/s]), to a relative
  /// 1e-12 of h. 1 when none crossed.
  double Crossing(double t0, double h, const MatrixN3& x0, const MatrixN3& v0, const MatrixN3& x1,
                  const MatrixN3& v1) const;
  /// The jumps at the end t [s] of an accepted step under event location:
  /// - entries: every particle free in the step that started outside the
  ///   collision area and ends within ε of it (approaching) or inside it
  ///   is put onto the δ-surface of its nearest obstacle, its normal
  ///   velocity relative to the obstacle is removed if it approaches (an
  ///   inelastic impact, the h → 0 limit of (4.4)), and it is in contact
  ///   from the next step on; the impact's work is added to work().holding;
  /// - drift: a contact more than ε off its δ-surface is put back onto it
  ///   (in place of (4.4)'s relaxation velocity ω_r (δ − d)/h, which grows
  ///   as h shrinks).
  /// x, v: N×3 state at t [m], [m/s], changed in place. @return the number of jumps
  int ApplyJumps(double t, MatrixN3* x, MatrixN3* v);

  /// Whether particle p's friction in this step is capped: it stops the
  /// particle's tangential velocity relative to the obstacle (stick), a
  /// jump of the response like an impact's (or, with stiction, the filter
  /// holds it).
  bool sticks(int p) const { return active() && contacts_[static_cast<std::size_t>(p)].sticks; }

  /// Coulomb friction forces of the step [N], N×3 (explicit; docs/model.md §2.5).
  const MatrixN3& friction() const { return friction_; }
  /// FrictionLaw::kImplicit (model/solver_spec.h): visits f(p, c, u) for
  /// each contact whose friction in this step is the force −c (v₁ − u)_t,
  /// c = μ J_N/(h max(|w_t|, kStickVelocity)) [kg/s] and u the obstacle's
  /// velocity there [m/s]. The stepper adds h c to its matrix's diagonal at
  /// p and h c u to its right-hand side: the filter removes the normal part
  /// of both, so the isotropic diagonal acts along the tangent plane alone.
  /// Between SetUp and the solve; nothing under the other laws.
  template <class F>
  void ForEachFrictionDamping(F&& f) const {
    if (!IsImplicit(friction_law_)) return;
    for (int p = 0; p < sys_.num_particles(); ++p) {
      const Contact& c = contacts_[static_cast<std::size_t>(p)];
      if (c.obstacle >= 0 && c.friction_damping > 0.0) f(p, c.friction_damping, c.v_obstacle);
    }
  }
  /// FrictionLaw::kImplicit: sets friction() to the forces −c (v₁ − u)_t
  /// of the solved v₁ (N×3 [m/s]), for ReadImpulses' work and the record.
  /// After the solve, before ReadImpulses; nothing under the other laws.
  void SetImplicitFriction(const MatrixN3& v1);

  /// FrictionCap::kSystem (model/solver_spec.h): caps each contact's
  /// friction impulse at a_t|v_t| instead of m|v_t|, with a_t the mass p
  /// drags through the star of its couplings in the step's matrix along
  /// the unit tangent t of v_t,
  ///   a_t = m_p + Σ_q w_q m_q/(m_q + w_q),  w_q the coupling where positive.
  /// This is 1/(B⁻¹)_pp for B = M plus only p's couplings; for A_α (an
  /// M-matrix: M plus graph Laplacians) B ≤ A, so (A⁻¹)_pp ≤ (B⁻¹)_pp and the
  /// cap lies between m and the impulse that stops p in the solve: it
  /// cannot reverse p alone. It is not a joint bound: neighbours capped in
  /// the same step add their impulses, and a region that slides as one
  /// receives more than stops it (docs/notes/collisions.md, "The friction
  /// cap"). Between SetUp and the read of friction(); also
  /// updates sticks(). No allocation.
  /// @param coupling callable coupling(p, t, visit) that calls visit(q, w)
  ///        for each neighbour q ≠ p with w = −tᵀA_pq t [kg]
  template <class Coupling>
  void CapBySystem(Coupling&& coupling) {
    if (!active()) return;
    const Eigen::VectorXd& mass = sys_.masses();
    for (int p = 0; p < sys_.num_particles(); ++p) {
      const Contact& c = contacts_[static_cast<std::size_t>(p)];
      if (c.obstacle < 0 || !(c.friction_limit > 0.0)) continue;
      const double speed = c.slip.norm();
      if (!(speed > 0.0)) continue;  // no friction, sticks already set
      double a = mass(p);
      coupling(p, Vector3(c.slip / speed), [&](int q, double w) {
        if (w > 0.0) a += w * mass(q) / (mass(q) + w);
      });
      CapFriction(p, a);
    }
  }

  /// After a successful solve: the impulse that holds each contact,
  ///   J_hold = ⟨r_p − m_p (v₁ − v̂)_p, D⟩,
  /// with r_p the particle's row of the solved system's residual (A v − b;
  /// its constraint impulse) and v̂ the method's momentum predictor, so that
  /// J_hold = −h ⟨f, D⟩: the force the obstacle carries, without the
  /// momentum of the target velocity. The full constraint impulse r_p·D
  /// also carries that momentum, which slows as a particle relaxes to the
  /// border; reading it as "pulling" released resting cloth every few steps
  /// (measured on a flat cloth on a plane), so release and friction use J_hold.
  /// @param residual_row callable p → Vector3 r_p [kg m/s]
  /// @param v1, vhat N×3 [m/s]
  /// @param release_tolerance a contact is released when J_hold is below
  ///        −release_tolerance [kg m/s] (the PCG's own residual, η‖S_F b‖)
  ///
  /// Also adds the step's work of the contact response to work(): the
  /// impulse I of a force on particle p over the step, times its mean
  /// velocity, ⟨I, (v₀ + v₁)/2⟩ (the trapezoidal rule for ∫ f·v dt). The
  /// constraint impulse is ⟨r_p, D⟩ D: holding (> 0, the obstacle pushes:
  /// negative work where it stops an impact, contact being inelastic,
  /// positive where the (4.4) position correction pushes a particle out) or
  /// pulling (< 0: the constraint drags a particle toward the obstacle in
  /// the step before its release). The friction impulse is h f_friction
  /// (FrictionLaw::kImplicit: its force at v₁, SetImplicitFriction). For a
  /// particle alone, ⟨I, (v₀ + v₁)/2⟩ is exactly its kinetic energy's
  /// change m(|v₁|² − |v₀|²)/2 under the impulse I.
  /// A multistep method weights a step's forces by β (BDF(2): 2/3) and
  /// carries part of each past velocity change into v̂ (`carry`): its
  /// impulses count with what its history carries of them into the later
  /// steps, J_n = I_n + d₁ J_{n−1} + d₂ J_{n−2} (docs/model.md §7, the
  /// contact work; needs KeepEchoes), so that the impulses of all forces sum to
  /// each step's momentum change M(v₁ − v₀).
  /// @param v0 N×3 velocities at the start of the step [m/s]
  /// @param carry the step's d₁, d₂ (zero: a one-step formula)
  ///
  /// Called once per accepted step: the next SetUp starts from this
  /// state; a SetUp not preceded by it (a rejected or shortened attempt)
  /// starts again from the state the last one started from.
  template <class RowResidual>
  void ReadImpulses(RowResidual&& residual_row, const MatrixN3& v0, const MatrixN3& v1, const MatrixN3& vhat,
                    double release_tolerance, const HistoryCarry& carry = HistoryCarry{}) {
    const Eigen::VectorXd& mass = sys_.masses();
    accepted_ = true;
    h_read_ = h_;
    for (int p = 0; p < sys_.num_particles(); ++p) {
      Contact& c = contacts_[static_cast<std::size_t>(p)];
      StepImpulses in;
      if (c.obstacle < 0) {
        c.impulse = 0.0;
        if (echoes_.empty()) continue;  // no impulse, and no history carries one
      } else {
        const Vector3 inertia = mass(p) * (v1.row(p) - vhat.row(p)).transpose();
        const Vector3 r = residual_row(p);
        // Under FrictionLaw::kImplicit the row also holds the friction's
        // h c (v₁ − u), whose normal part is no constraint impulse.
        const double full = r.dot(c.direction) - h_ * c.friction_damping *
                                                     (v1.row(p).transpose() - c.v_obstacle).dot(c.direction);
        c.impulse = full - inertia.dot(c.direction);
        (full >= 0.0 ? in.holding : in.pulling) = full * c.direction;
        in.friction = h_ * friction_.row(p).transpose();
        if (c.held) {
          // From the step's start state: the inertia of a multistep
          // predictor v̂ ≠ v₀ is not the hold's.
          const Vector3 from_start = r + mass(p) * (vhat.row(p) - v0.row(p)).transpose();
          in.friction += ReadHold(p, r, from_start, release_tolerance);
        }
      }
      AddWork(p, &in, 0.5 * (v0.row(p) + v1.row(p)).transpose(), carry);
    }
    release_tolerance_ = release_tolerance;
  }

  /// The active set, after a solve and before its step is finished.
  /// FrictionLaw::kImplicit: every contact whose implicit friction impulse
  /// h c |(v₁ − u)_t| exceeds μ J_N (1 + cone_tolerance) (its slip grew
  /// past the step's start and v_ε: Coulomb's cone is left) slides for the
  /// rest of the step, with μ J_N against that slip, explicit.
  /// FrictionLaw::kImplicitIterated: every contact that still slides
  /// (|(v₁ − u)_t| > v_ε) with less than μ J_N (1 − cone_tolerance) takes
  /// its rate from that slip in the next solve. The
  /// tolerance is relative to the contact's own μ J_N: one against the
  /// system's η‖S_F b‖ would keep, once the sheet moves fast and h is small,
  /// every contact in the cone whose excess μ J_N Δ|v_t|/|v_t| is O(h²),
  /// from a time that scales with h (docs/notes/collisions.md, "Implicit
  /// friction"). A release in error only applies Coulomb's μ J_N at the
  /// cone's edge, and costs a solve.
  /// Stiction: every held contact whose tangential constraint impulse J_t (the
  /// tangential part of its residual row, as in ReadImpulses; against its
  /// normal holding impulse J_N of this solve) exceeds
  /// μ J_N + release_tolerance is released for this step: the next SetUp
  /// of the same step does not hold it and applies μ J_N (of the last
  /// step) along J_t instead; and a released contact whose friction points
  /// along its slip relative to the obstacle in v1 gets no friction for the
  /// rest of the step. @param release_tolerance η‖S_F b‖ [kg m/s]
  /// @param cone_tolerance η (relative) @return whether any changed (then
  /// the step is solved again). Nothing unless revises(). No allocation.
  template <class RowResidual, class V0, class V1, class VHat>
  bool ReviseHolds(RowResidual&& residual_row, const V0& v0, const V1& v1, const VHat& vhat,
                   double release_tolerance, double cone_tolerance) {
    if (!revises()) return false;
    bool any = false;
    const Eigen::VectorXd& mass = sys_.masses();
    for (int p = 0; p < sys_.num_particles(); ++p) {
      const Contact& c = contacts_[static_cast<std::size_t>(p)];
      if (c.friction_damping > 0.0) {
        any |= LeavesCone(p, Vector3(v1.row(p).transpose()), cone_tolerance);
        continue;
      }
      if (!c.held) {
        any |= StopPushingRelease(p, Vector3(v1.row(p).transpose()));
        continue;
      }
      const Vector3 r = residual_row(p);
      const Vector3 from_start = r + mass(p) * (vhat.row(p) - v0.row(p)).transpose();  // as in ReadImpulses
      const Vector3 tangential = from_start - from_start.dot(c.direction) * c.direction;
      const double normal = (r - mass(p) * (v1.row(p) - vhat.row(p)).transpose()).dot(c.direction);
      const double mu = sys_.obstacles()[static_cast<std::size_t>(c.obstacle)].spec().friction;
      if (!(tangential.norm() > mu * std::max(normal, 0.0) + release_tolerance)) continue;
      released_[static_cast<std::size_t>(p)] = tangential.normalized();
      any = true;
    }
    return any;
  }

  /// Work of the contact response since the last Reset [J] (ReadImpulses).
  struct Work {
    double holding = 0.0;   ///< of the constraint impulses that push (stopping impacts, position correction)
    double pulling = 0.0;   ///< of those that pull (constraints held in the step before their release)
    double friction = 0.0;  ///< of the Coulomb friction impulses
    double total() const { return holding + pulling + friction; }  ///< W_contact [J]
  };
  const Work& work() const { return work_; }

  /// Exact signed-distance queries SetUp made and skipped since Reset (the
  /// distance cull of mesh obstacles: a query is skipped where a lower bound
  /// of the distance rules out every contact test).
  long distance_queries() const { return detection_.queries(); }
  /// Turns the distance cull off (every query exact; for the test that the
  /// cull changes no contact).
  void set_distance_cull(bool on) { detection_.set_distance_cull(on); }
  long culled_queries() const { return detection_.culled(); }
  /// Wall time of SetUp since Reset [s]: the collision detection (distance
  /// queries, the cull) and the filter's constraints.
  double setup_seconds() const { return seconds_; }

 private:
  struct Contact {
    int obstacle = -1;            // obstacle index, −1: none
    Vector3 direction = Vector3::Zero();
    double impulse = 0.0;         // holding impulse of the last step [kg m/s] (ReadImpulses)
    bool sticks = false;          // this step's friction stops its tangential velocity (CappedFriction's cap)
    bool entry = false;           // set by a predicted entry (test 3), not by the area: never released
    bool held = false;            // stiction: the filter holds it in all three directions in this step
    bool slides = false;          // stiction: its last hold needed more than μ J_N, so it slides next
    Vector3 hold_direction = Vector3::Zero();  // of the last hold's tangential impulse
    Vector3 v_obstacle = Vector3::Zero();      // the obstacle's velocity at the contact [m/s]
    double last_slip = std::numeric_limits<double>::infinity();  // |v_t| at the last step's start [m/s]; ∞: none
    double friction_damping = 0.0;  // FrictionLaw::kImplicit: μ J_N/(h max(|v_t|, v_ε)) [kg/s]
    double friction_limit = 0.0;  // this step's friction impulse before its cap, μ J_N [kg m/s]; 0: none
    Vector3 slip = Vector3::Zero();  // v_t relative to the obstacle at the step's start [m/s]
  };
  const ParticleSystem& sys_;
  std::vector<Contact> contacts_;
  double release_tolerance_ = 0.0;         // of the last solve [kg m/s]
  double h_ = 0.0;                         // step of the last SetUp [s]
  Work work_;                              // since Reset
  ObstacleDetection detection_;            // the contacts of each SetUp (tests 1–3)
  double seconds_ = 0.0;                   // SetUp's wall time since Reset [s]
  // Event location: its tolerance [m] (0: off).
  double event_tolerance_ = 0.0;
  FrictionLaw friction_law_ = FrictionLaw::kExplicit;
  bool stiction_ = false;
  // Per particle, the direction of the friction of a contact released in
  // this step (ReviseHolds: a stiction hold beyond μ J_N, or an implicit
  // friction beyond its cone), zero if none; cleared when a new step begins.
  std::vector<Vector3> released_;
  // Released in this step, and its friction pushed it along its slip in a
  // solve (ReviseHolds): no friction for the rest of the step.
  std::vector<uint8_t> frictionless_;
  // FrictionLaw::kImplicitIterated: per particle, the slip [m/s] of the
  // last solve of this step whose friction stayed below μ J_N while it slid
  // (LeavesCone), from which the next solve takes its rate; 0: the slip at
  // the step's start.
  std::vector<double> rate_slip_;
  // The state the last SetUp started from, and whether a step was
  // accepted since (ReadImpulses): an attempt after a rejected one starts
  // from it again. h_read_: the step whose impulses were read [s].
  bool accepted_ = true;
  double h_read_ = 0.0;
  std::vector<Contact> contacts_backup_;
  // friction_ row p of the contact's impulse capped at a [kg] times |v_t|.
  void CapFriction(int p, double a);
  // Stiction: a held contact's constraint impulse r [kg m/s] (its row of the
  // residual) and the same from the step's start state, r + m(v̂ − v₀)
  // (`from_start`; its tangential part J_t is the friction impulse that
  // held the particle, its slip's momentum included): the contact slides
  // in the next step when |J_t| > μ J_N + release_tolerance. Returns r's
  // tangential part [kg m/s] (friction's impulse).
  Vector3 ReadHold(int p, const Vector3& r, const Vector3& from_start, double release_tolerance);
  // One particle's contact impulses of a step [kg m/s], by kind of work.
  struct StepImpulses {
    Vector3 holding = Vector3::Zero(), pulling = Vector3::Zero(), friction = Vector3::Zero();
  };
  // Adds the history's carry (KeepEchoes) to *in, keeps it for the next
  // steps and adds its work ⟨I, mean⟩ [J] to work_ (ReadImpulses).
  void AddWork(int p, StepImpulses* in, const Vector3& mean, const HistoryCarry& carry);
  // KeepEchoes: the impulses J of the last accepted steps, [0] the last.
  struct Echo {
    MatrixN3 holding, pulling, friction;
  };
  std::vector<Echo> echoes_;
  // FrictionLaw::kImplicit: whether contact p's friction −c (v₁ − u)_t
  // exceeds μ J_N (1 + tolerance); then it slides for the rest of the step
  // (released_ along −(v₁ − u)_t). kImplicitIterated also: whether it
  // still slides (|(v₁ − u)_t| > v_ε) below μ J_N (1 − tolerance); then
  // the next solve takes its rate from that slip (rate_slip_).
  bool LeavesCone(int p, const Vector3& v1, double relative_tolerance);
  // A contact released in this step whose friction points along
  // its slip relative to the obstacle at v1 [m/s] pushed it; it gets no
  // friction for the rest of the step. Returns whether that is new.
  bool StopPushingRelease(int p, const Vector3& v1);
  // Contact c's velocity v [m/s] relative to its obstacle, its tangential part.
  static Vector3 TangentialSlip(const Contact& c, const Vector3& v) {
    const Vector3 w = v - c.v_obstacle;
    return w - w.dot(c.direction) * c.direction;
  }
  // SetUp's work: every free particle's contact with the obstacles at the
  // step's start (detected_), then the response to them (Respond).
  void Detect(double t0, double h, const MatrixN3& x_start, const MatrixN3& v_start, const MatrixN3* xm1);
  int Respond(double h, VelocityFilter* filter);
  // Per particle, its contact of the last SetUp (particle −1: none); a
  // solve again of the step (SetUpAgain) responds to them again.
  std::vector<ObstacleContact> detected_;
  MatrixN3 friction_;                      // Coulomb friction forces [N], explicit
};

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_CONTACT_H_
