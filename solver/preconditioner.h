// The preconditioners of the filtered PCG (docs/model.md §5): IC(0), a
// CHOLMOD factor or a BoomerAMG V-cycle of A_F for the N×N system, their
// adaptation to the contacts (the contact policy, contact_policy.cc), and
// the preconditioner of the 3N×3N tangent system.
#ifndef CLOTHBENCH_SOLVER_PRECONDITIONER_H_
#define CLOTHBENCH_SOLVER_PRECONDITIONER_H_

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <vector>

#include "model/solver_spec.h"
#include "model/types.h"
#include "solver/amg.h"
#include "solver/cholesky.h"
#include "solver/velocity_filter.h"

namespace clothbench {

/// Incomplete Cholesky IC(0) of an SPD sparse matrix: L Lᵀ ≈ A on the lower
/// pattern of A (the thesis' preconditioner, §3.4). A diagonal shift is added
/// and the factorisation repeated if a pivot is not positive.
class IncompleteCholesky0 {
 public:
  /// Sets the pattern (allocates). Must precede Factorize with the same pattern.
  void Analyze(const SparseMatrix& a);
  /// Computes L on the analysed pattern (no allocation). Returns false if no
  /// positive pivots were found even with shifts.
  bool Factorize(const SparseMatrix& a);
  /// z ← (L Lᵀ)⁻¹ r for the three columns in one sweep of L and one of Lᵀ
  /// (each column sees the same operations as a column-by-column solve, so
  /// the result is bit-identical to it). No allocation.
  void Solve(const MatrixN3& r, MatrixN3* z) const;
  /// y ← (L Lᵀ)⁻¹ y for one vector of length n (the 3N tangent system).
  void SolveInPlace(double* y) const;
  double shift() const { return shift_; }

 private:
  template <int K>
  void Sweeps(double* const* y) const;  // forward and backward sweep on K columns

  SparseMatrix l_;               // lower triangle, diagonal first in each column
  std::vector<int> diag_pos_;    // index of the diagonal entry of column k in l_
  double shift_ = 0.0;
};

/// What the contact factors of "cholesky" and the prefiltered hierarchy of
/// "amg" did (Preconditioner::AdaptTo).
struct ContactFactorStats {
  long refactorizations = 0;  ///< numeric factorisations of an axis factor; setups of the prefiltered hierarchy
  long modifications = 0;     ///< row deletes and adds on the axis factors; finest-level updates of a kept prefiltered hierarchy
  long fallbacks = 0;         ///< failed setups of the prefiltered hierarchy (A_F's served instead)
  double seconds = 0.0;       ///< their wall time [s]
  /// Of `seconds`: the refactorisations' (setups') and the row changes' (finest-level updates') [s].
  double refactor_seconds = 0.0, modify_seconds = 0.0;
  /// V-cycles of the prefiltered hierarchy applied, and their wall time [s].
  long v_cycles = 0;
  double v_cycle_seconds = 0.0;
  int decoupled[3] = {0, 0, 0};  ///< contacts decoupled in each column's factor (last AdaptTo; "cholesky")
  /// Setups of the prefiltered hierarchy in nearest-axis and in spread frames
  /// (Preconditioner::FrameMode).
  long frame_setups[2] = {0, 0};
  /// Contacts whose normal is farther than acos(Preconditioner::kFrameSnap)
  /// from every coordinate axis (last AdaptTo; prefiltered AMG).
  int off_axis = 0;
  /// The V-cycle factor of the last setup (AmgPreconditioner::SystemCycleFactor);
  /// NaN unless measured (Preconditioner::AmgDiagnostics).
  double cycle_factor = std::numeric_limits<double>::quiet_NaN();
};

/// Preconditioner for the filtered PCG (docs/model.md §5): none, Jacobi (diag(A) ⊗ I₃,
/// the block-diagonal 3×3 of A ⊗ I₃), IC(0) of A, a CHOLMOD factor of A_F or
/// one BoomerAMG V-cycle on A_F (A_F: A with the fixed particles' rows and
/// columns decoupled, see CholeskyFactor). Movable, not copyable.
///
/// Contact factors ("cholesky" with contact_factors): a contact constrains
/// one direction n of a particle. Where n is (nearly) a coordinate axis c,
/// the filtered system S A S + (I − S) is, in column c, A with that
/// particle decoupled, as a fixed particle is in every column. So column c
/// is preconditioned with a factor of A_F that also decouples the contacts
/// along axis c (the same symbolic analysis, refactorised), and the other
/// columns with A_F's: for axis-aligned contacts the preconditioner is the
/// exact inverse and the PCG converges in one iteration, as without
/// contacts. Contacts whose normal is farther than acos(kContactAxisCosine)
/// from every axis stay coupled (the factor then preconditions them), as do
/// those of an axis with fewer than kContactAxisShare·N contacts. The
/// factors follow the contacts step by step: by row deletes and adds
/// (CHOLMOD's Modify module) while few rows change (kModifyRowsPerSqrtN),
/// else by a refactorisation.
///
/// Contact frames (contact factors, "cholesky" and "auto"): where many
/// contacts are tilted off every axis, each particle p gets a frame R_p
/// whose column z is its contact's normal (a free particle's: its nearest
/// contact's, smoothed as the prefiltered AMG's spread frames), and P⁻¹ r =
/// R (F_x⁻¹, F_y⁻¹, F_z⁻¹) Rᵀ r with A_F's factor in the tangent columns
/// and, in column z, the factor with every contact decoupled. It is exact
/// where the frames are constant (the tilted plane, SBDF(2): 7 CG per
/// contact step with the axis factors, 1 in frames at 10⁴; 34 and 1 at
/// 10⁵) and approximates a_pq R_pᵀ R_q by a_pq I where they turn (the
/// sphere: 21 → 9 CG at 10⁴, 126 → 11 at 10⁵). They serve whenever at
/// least kContactAxisShare·N contacts are off every axis by more than
/// acos(kFrameSnap). A choice between them and the axis factors by
/// measured cost (the axis factors took 12 CG on the avatar at 10⁴ against
/// the frames' 15) had to try the axis factors, and on round_table_1m that
/// one trial step took 289 CG and 69.5 s, the rest of the 0.3 s run 81 s
/// (docs/notes/performance.md, "Contact frames").
///
/// Prefiltered AMG ("amg" with contact_factors; Tamstorf, Jones & McCormick
/// 2015): with contacts, one V-cycle of BoomerAMG in systems mode on the
/// 3N×3N filtered matrix K = S A S + (I − S) itself, in per-particle frames
/// (a contact's normal is one unknown, decoupled; FrameMode), instead of A_F's
/// hierarchy on each column. Every constraint, tilted or not, is built in;
/// the V-cycle is an approximate inverse, as A_F's is without contacts. The
/// hierarchy is kept while the contacts do not change, and while the extra
/// V-cycles of a kept hierarchy stay below a setup's cost (kSetupVCycles);
/// a kept hierarchy's finest level is given the current K
/// (its smoother sees the current constraints, its coarse levels are the
/// setup's).
class Preconditioner {
 public:
  /// |n_c| at and above which a contact normal n counts as axis c's.
  static constexpr double kContactAxisCosine = 0.9;
  /// An axis gets a factor of its own once at least this share of the
  /// particles are in contact along it (docs/notes/performance.md).
  static constexpr double kContactAxisShare = 0.02;
  /// Contact factors: changed rows applied by row deletes and adds up to
  /// this times √N, else a refactorisation. The measured break-even (mean
  /// time of a refactorisation over that of one row change, SBDF(2) on the
  /// round table, contact_replay) is 6.5 √N at N = 10⁴ and 4.3 √N at 10⁵
  /// (docs/notes/performance.md).
  static constexpr double kModifyRowsPerSqrtN = 4.0;
  /// Prefiltered AMG: a setup costs this many V-cycles (measured mean 13.8
  /// at N = 10⁴ and 13.5 at 10⁵ on the round table, contact_replay;
  /// docs/notes/performance.md): a kept hierarchy is rebuilt once its extra
  /// V-cycles reach it.
  static constexpr double kSetupVCycles = 12.0;
  /// Prefiltered AMG: a particle's constraint has changed when its S_p
  /// changed by more than this (max-norm; a direction turned by ≈ this [rad]).
  static constexpr double kSystemTurn = 1e-3;
  /// Prefiltered AMG: the hierarchy is rebuilt whenever more than this share
  /// of the contacts changed (kept for the half of the contacts it was
  /// built for, it cost 80 CG iterations instead of 10: test
  /// PrefilteredHierarchySeesTiltedContacts).
  static constexpr double kSystemKeepShare = 0.05;
  /// Prefiltered AMG: the frames of free particles. hypre interpolates each
  /// unknown from the same unknown of its neighbours, and a jump between
  /// neighbouring frames breaks that: with free particles in the world frame
  /// beside tilted contacts the iterations grow with N (tilted half of a
  /// sheet: 13 / 17 / 25 / 30 CG at 50² / 100² / 200² / 300² particles,
  /// against 7 / 7 / 13 / 13 for axis-aligned contacts). At a setup each free
  /// particle takes the direction of its nearest contact, and this many
  /// Jacobi sweeps turn the seams between regions of different contacts
  /// gradually (round_table_100k over the impact: 25.4 CG per step in world
  /// frames, 16.8 with nearest directions alone, 11.6 with 20 sweeps;
  /// docs/notes/performance.md, "Prefiltered AMG").
  static constexpr int kFrameSweeps = 20;
  /// Prefiltered AMG: the frames of a setup.
  /// - kNearestAxis: a contact's frame takes the axis nearest to its normal
  ///   to the normal; free particles stay in the world frame.
  /// - kSpread: a contact's frame takes e_z to its normal, and the free
  ///   particles' frames are spread from the contacts' (kFrameSweeps).
  /// Spread frames win while the contacts change (round_table_1m's impact:
  /// 13.6 CG per step against 73.0), nearest-axis ones at rest (16.1
  /// against 50.4): each setup takes the mode with the fewer V-cycles per
  /// solve over the last hierarchy built with it, and a hierarchy that
  /// needs more than the other mode's last is rebuilt at once
  /// (docs/notes/performance.md, "Prefiltered AMG").
  enum class FrameMode { kNearestAxis = 0, kSpread = 1 };
  /// Prefiltered AMG: the frame rule (SolverSpec::amg_frames). Before the
  /// first AdaptTo.
  void set_amg_frames(AmgFrames frames) {
    amg_frames_ = frames;
    frame_mode_ = frames == AmgFrames::kNearestAxis ? FrameMode::kNearestAxis : FrameMode::kSpread;
  }
  /// The other mode's record of V-cycles per solve is multiplied by this at
  /// each setup, so that it is tried again.
  static constexpr double kFrameModeDecay = 0.9;
  /// Prefiltered AMG diagnostics (contact_replay; off in every run):
  /// - cycle_factor: each setup measures its hierarchy's V-cycle factor,
  ///   40 cycles (ContactFactorStats::cycle_factor; the setup time excludes it).
  /// - axis_normals: the hierarchy is built, in world frames, for every
  ///   contact's normal replaced by its nearest coordinate axis: on purpose
  ///   not the filtered system the PCG solves, to measure the V-cycle of the
  ///   same contact set without tilted constraints.
  /// - frames_only: the hierarchy is built for A_α alone (no constraint,
  ///   S = I) in the contact frames the frame rule gives: Rᵀ A R, on purpose
  ///   not the filtered system, to measure what the frames' rotations alone
  ///   cost the V-cycle (in world frames, with axis_normals, it is A_α's).
  struct AmgDiagnostics {
    bool cycle_factor = false;
    bool axis_normals = false;
    bool frames_only = false;
  };
  void set_amg_diagnostics(AmgDiagnostics d) { amg_diagnostics_ = d; }
  /// V-cycles of AmgDiagnostics::cycle_factor.
  static constexpr int kDiagnosticCycles = 40;
  /// A free particle whose direction is within this cosine of e_z keeps the
  /// world frame (its blocks stay a_pq I, not full 3×3 ones).
  static constexpr double kFrameSnap = 0.999;

  /// The contact policy ("auto"). Without contacts the Cholesky factor of
  /// A_F serves (exact: one CG iteration). In contact, each AdaptTo chooses
  /// between the factor with contact factors and the prefiltered AMG by the
  /// counted cost of the steps each has served, in units of one CG
  /// iteration that reads one factor (A_F's factor alone: 1; with contact
  /// factors or in contact frames each further distinct factor a lane
  /// reads adds 1, so a step in frames counts 2 per CG iteration: measured
  /// 13.5 ms against 6.5 ms with A_F's factor alone at 10⁵, sphere and
  /// avatar drapes on 2 threads): a V-cycle iteration costs
  /// VCycleIterations(N) of them, a hierarchy setup kAutoSetupVCycles
  /// V-cycle iterations, a contact-factor refactorisation
  /// kRefactorIterations and a row change kRefactorIterations /
  /// (kModifyRowsPerSqrtN √N). Counts, not times, so
  /// that a run is the same on every repetition. A mode's cost is an
  /// exponential mean over its current stay (kAutoRecent); a mode that is
  /// left keeps its stay's least step cost, which decays by kAutoDecay
  /// per step, so that it is tried again, and an untried AMG starts from
  /// kAmgPriorIterations V-cycles per step. A stay lasts at least
  /// kAutoMinStay steps unless its cost exceeds the other's record by
  /// kAutoAbort. ServedBy() tells what served a step. (docs/notes/performance.md,
  /// "The contact policy".)
  /// A V-cycle iteration of the prefiltered AMG in one-factor CG
  /// iterations (each with the product and vector work of a CG
  /// iteration), measured on the sphere drape in contact (SBDF(2), step
  /// time less setup over CG iterations) against CG iterations in contact
  /// frames, which read two factors: 3.1 ms against 0.43 ms at N = 10⁴
  /// (7.2 frames iterations, 14.4 units), 27 ms against 13.5 ms at 10⁵ (2.0,
  /// 4.0 units); fitted as 14.4 (10⁴/N)^0.556, at least 4.
  static double VCycleIterations(double n) { return std::max(4.0, 14.4 * std::pow(1e4 / n, 0.556)); }
  /// A prefiltered hierarchy's setup in V-cycle iterations (the same runs:
  /// 0.034 s at 10⁴ = 11, 0.17 s at 10⁵ = 6.3).
  static constexpr double kAutoSetupVCycles = 8.0;
  /// A refactorisation of a contact factor in one-factor CG iterations
  /// (0.14 s against 13.5 ms for a two-factor iteration at 10⁵: 20; about
  /// 50 at 10⁴).
  static constexpr double kRefactorIterations = 30.0;
  static constexpr double kAutoDecay = 0.97;
  /// Weight of the latest step in the current mode's cost (an exponential
  /// mean, so that a cost that grows over the stay is seen within a few
  /// steps).
  static constexpr double kAutoRecent = 0.5;
  static constexpr double kAmgPriorIterations = 12.0;
  static constexpr int kAutoMinStay = 2;
  static constexpr double kAutoAbort = 2.0;
  /// What Apply uses now: 0 the preconditioner of A_F (its factor or
  /// hierarchy, or IC(0), Jacobi, none), 1 a contact factor in at least
  /// one column, 2 the prefiltered AMG, 3 the contact factor in contact
  /// frames (StepStats::preconditioner).
  int ServedBy() const {
    if (system_used_) return 2;
    if (cf_frames_) return 3;
    return axis_used_[0] || axis_used_[1] || axis_used_[2] ? 1 : 0;
  }
  /// Applications so far, each counted in reads of one factor (the contact
  /// policy's unit: 1 with A_F's factor alone, a V-cycle or any other
  /// preconditioner; 2 in contact frames or with one contact factor; 3
  /// with two).
  long factor_reads() const { return applications_; }
  /// Contact frames: the share of the contacts that, added or released
  /// since the frames were last spread, makes them spread again.
  static constexpr double kRespreadShare = 0.05;
  /// Contact factors in contact frames: whether they may serve (default
  /// true; false: the axis factors alone, for comparisons). Before the
  /// first AdaptTo.
  void set_frame_factors(bool on) { frame_factors_ = on; }

  explicit Preconditioner(PreconditionerType type = PreconditionerType::kIc0,
                          CholeskyOrdering ordering = CholeskyOrdering::kMetis, bool contact_factors = false);
  ~Preconditioner();
  Preconditioner(Preconditioner&&) noexcept;
  Preconditioner& operator=(Preconditioner&&) noexcept;
  PreconditionerType type() const { return auto_ ? PreconditionerType::kAuto : type_; }
  /// Symbolic phase for the pattern of `a` (allocates). @param fixed sorted
  /// fixed particles (used by "cholesky" and "amg"). @return false if the
  /// library failed.
  bool Analyze(const SparseMatrix& a, const std::vector<int>& fixed = {});
  /// Numeric phase for the values of `a`; false if it failed (not SPD).
  bool Factorize(const SparseMatrix& a);
  /// Makes the contact factors match the constraints of `filter` (after
  /// Factorize with the same `a`); nothing for other types or without
  /// contact_factors. Allocates when a contact axis is first seen and when a
  /// factor is refactorised. @return false if a factorisation failed.
  bool AdaptTo(const SparseMatrix& a, const VelocityFilter& filter);
  const ContactFactorStats& contact_stats() const { return contact_stats_; }
  /// z ← P⁻¹ r. @param r, z N×3. No allocation (after the first call).
  void Apply(const MatrixN3& r, MatrixN3* z) const;
  /// What Factorize costs, in the contact policy's unit, one CG iteration
  /// that reads one factor: for the Cholesky factor its flops over a
  /// solve's (two triangular solves of three columns, 12 per nonzero of
  /// L), times one plus the contact factors in use (Factorize makes them
  /// stale, AdaptTo factorises them again); IC(0) about one iteration; the
  /// AMG a hierarchy's setup, kAutoSetupVCycles V-cycles; 0 for Jacobi and
  /// none. @param n the matrix's rows.
  double RefactorIterations(int n) const;
  /// Nonzeros of the Cholesky factor (0 for other types).
  long factor_nonzeros() const { return cholesky_ ? cholesky_->factor_nonzeros() : 0; }
  /// Levels of the AMG hierarchy (0 for other types).
  int amg_levels() const { return amg_ ? amg_->levels() : 0; }

 private:
  PreconditionerType type_;
  CholeskyOrdering ordering_;
  Eigen::VectorXd inv_diag_;
  IncompleteCholesky0 ic0_;
  std::unique_ptr<CholeskyFactor> cholesky_;
  std::unique_ptr<AmgPreconditioner> amg_;
  // Contact factors: per column c, a factor with the contacts along axis c
  // decoupled (their set as factorised), the current contacts (scratch),
  // whether it is factorised for A's current values and used by Apply.
  bool contact_factors_ = false;
  std::array<std::unique_ptr<CholeskyFactor>, 3> axis_factor_;
  std::array<std::vector<char>, 3> axis_set_, axis_want_;
  std::array<bool, 3> axis_valid_{}, axis_used_{};
  mutable ContactFactorStats contact_stats_;  // Apply counts and times the V-cycles
  // Prefiltered AMG ("amg" with contact_factors): the CSR rows of
  // K = S A S + (I − S), whether the hierarchy is current for A's values
  // and used by Apply.
  bool AdaptAmgTo(const SparseMatrix& a, const VelocityFilter& filter);
  /// The contact projectors S = I − Σ n nᵀ of `filter`'s constraints into
  /// s_now_ (sized for n particles). @return the contacts that constrain
  /// fewer than three directions (the fixed particles are A_F's)
  int ContactProjectors(const VelocityFilter& filter, int n);
  /// A new hierarchy of the contact system in the frame mode the measured
  /// V-cycles favour (the setup path of AdaptAmgTo).
  void SetUpContactHierarchy(const SparseMatrix& a, const VelocityFilter& filter);
  // frames_ for the constraints of `filter` (with `smooth`, at a setup, the
  // free particles' directions spread again from the contacts first; at a
  // finest-level update only the contacts' frames turn); the CSR rows of K
  // for the S_p of `s` in those frames.
  void SetFrames(const SparseMatrix& a, const VelocityFilter& filter, bool smooth);
  void AssembleSystem(const SparseMatrix& a, const std::vector<Eigen::Matrix3d>& s);
  // S_p of each particle (identity: free) as the hierarchy was built, now
  // (scratch), and as its finest level was last given.
  std::vector<Eigen::Matrix3d> system_s_, s_now_, fine_s_;
  std::vector<int> k_start_, k_cols_;
  std::vector<Eigen::Matrix3d> blocks_;  // AssembleSystem's scratch: the blocks of one row
  std::vector<double> k_values_;
  // The frames: a direction per particle (a contact's normal; for a free
  // particle its nearest contact's, then kFrameSweeps Jacobi sweeps of its
  // neighbours' mean), whether the filter holds the particle, and R_p taking
  // e_z to the direction (identity for a free particle within kFrameSnap of
  // e_z). reached_, queue_: the breadth-first search of SetFrames.
  // plain_: S_p = R_p = I (AssembleSystem).
  std::vector<Vector3> field_, next_field_;
  std::vector<char> held_, plain_, reached_;
  std::vector<int> queue_;
  std::vector<Eigen::Matrix3d> frames_;
  mutable MatrixN3 rotated_r_, rotated_z_;
  bool system_valid_ = false, system_used_ = false;
  // The rebuild rule (AdaptAmgTo), on contact_stats_.v_cycles (the V-cycles
  // applied): the count at the last AdaptTo, solves since the last setup,
  // the V-cycles of the first of them, the V-cycles beyond that count since
  // the setup, and those expected of the next kept step.
  long applications_at_adapt_ = 0, baseline_applications_ = 0;
  int solves_since_setup_ = 0;
  double stale_cycles_ = 0.0, stale_rate_ = 0.0;
  // The frame rule: the current mode, each mode's V-cycles per solve over
  // its last hierarchy (0: untried) as measured and as decayed since, and
  // the V-cycle count at the setup.
  AmgFrames amg_frames_ = AmgFrames::kAdaptive;
  AmgDiagnostics amg_diagnostics_;
  FrameMode frame_mode_ = FrameMode::kSpread;
  double mode_measured_[2] = {0.0, 0.0}, mode_rate_[2] = {0.0, 0.0};
  long applications_at_setup_ = 0;
  // A measured choice between two modes (the contact policy's between the
  // contact factors [0] and the prefiltered AMG [1]): the current mode,
  // each mode's cost record (CG iterations with the factor per step; < 0:
  // untried): the current mode's an exponential mean of its stay's steps
  // (kAutoRecent), a mode left behind its stay's least step (a stay that
  // met an impact is not remembered by the impact); the current stay's
  // least step cost and its steps, whether the step since the last call is
  // counted, and the counters at that call.
  struct ModeChoice {
    std::size_t mode = 0;
    double record[2] = {-1.0, -1.0};
    double stay_least = 0.0;
    int stay_steps = 0;
    bool counting = false;
    long applications_at = 0, refactorizations_at = 0, modifications_at = 0;
    // Counts a step of `cost` to the current mode; the other's record decays
    // by kAutoDecay.
    void Count(double cost);
    // Leaves the current mode for the other, whose record is `other` (< 0:
    // untried), once the stay has lasted kAutoMinStay steps or costs
    // kAutoAbort times `other`, if `other` is lower.
    void Choose(double other);
  };
  // The applications, setups (refactorisations) and row changes since the
  // last call for `c`, whose counters move to now.
  std::array<double, 3> CountSince(ModeChoice* c) const;
  // The contact policy ("auto"; type_ is then kCholesky and auto_ true;
  // without contact_factors it is the factor alone), and the Apply count.
  bool auto_ = false;
  ModeChoice auto_choice_;
  mutable long applications_ = 0;
  bool AdaptFactorsTo(const SparseMatrix& a, const VelocityFilter& filter);
  // Contact factors in contact frames (AdaptFactorsTo): whether they may
  // serve (set_frame_factors); whether Apply rotates into the frames, the
  // contacts changed since they were last spread, each particle's frame
  // R_p and direction, and whether R_p ≠ I. SetFactorFrames' `spread`: all
  // frames from SpreadDirections, else only the contacts' turned to their
  // normals.
  bool frame_factors_ = true;
  bool cf_frames_ = false;
  long cf_changes_since_spread_ = 0;
  std::vector<Eigen::Matrix3d> cf_frame_;
  std::vector<Vector3> cf_field_;
  std::vector<char> cf_rotated_;
  void SetFactorFrames(const SparseMatrix& a, const VelocityFilter& filter, bool spread);
  // The directions of SetFrames' spread frames into `field` (held_: the
  // particles the filter holds); `flip`: each contact's normal turned into
  // the upper half-space where it points mostly down (ContactDirection).
  void SpreadDirections(const SparseMatrix& a, const VelocityFilter& filter, bool flip, std::vector<Vector3>* field);
  bool AdaptAutoTo(const SparseMatrix& a, const VelocityFilter& filter);
  void ApplySystem(const MatrixN3& r, MatrixN3* z) const;  // one V-cycle of the prefiltered hierarchy
};

/// Preconditioner of the 3N×3N tangent system J_α (solver/tangent.h), chosen
/// by the scene's `preconditioner`:
///   "jacobi"   → block Jacobi: the inverse of each particle's 3×3 diagonal block of J_α;
///   "ic0"      → IC(0) of J_α (scalar, on its 3N×3N pattern);
///   "cholesky", "amg" → the N×N preconditioner of A_α (its CHOLMOD factor or
///                BoomerAMG V-cycle, applied to the three columns): A_α is J_α
///                without the explicit terms' Jacobian and the transverse spring
///                stiffness, SPD, and already factorised while αh is constant,
///                so J_α's values change without a refactorisation;
///   "none"     → identity.
/// Movable, not copyable.
class TangentPreconditioner {
 public:
  explicit TangentPreconditioner(PreconditionerType type = PreconditionerType::kJacobi) : type_(type) {}
  PreconditionerType type() const { return type_; }
  /// Symbolic phase for the pattern of J (3N×3N). Allocates.
  /// @param laplacian the factorised A_α preconditioner ("cholesky", "amg"; must
  ///        outlive this object and be kept current by its owner)
  void Analyze(const SparseMatrix& j, const Preconditioner* laplacian);
  /// Numeric phase for the values of J. @return false if a block or pivot is
  /// not positive definite (or non-finite).
  bool Factorize(const SparseMatrix& j);
  /// z ← P⁻¹ r. @param r, z N×3 row-major (3N vectors). No allocation.
  void Apply(const MatrixN3R& r, MatrixN3R* z) const;

 private:
  PreconditionerType type_;
  std::vector<Eigen::Matrix3d> block_inv_;  // block Jacobi
  std::vector<int> block_pos_;              // value index of J(3p+r, 3p+c), 9 per particle
  IncompleteCholesky0 ic0_;
  const Preconditioner* laplacian_ = nullptr;
  mutable MatrixN3 rc_, zc_;                // column-major scratch for the A_α path
};

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_PRECONDITIONER_H_
