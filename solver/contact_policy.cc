// The contact policy of the N×N preconditioner (preconditioner.h,
// Preconditioner::AdaptTo): contact factors, contact frames and the
// prefiltered AMG hierarchy, and the measured choice between them
// (docs/notes/performance.md, "Contact frames").
#include "solver/preconditioner.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <omp.h>

namespace clothbench {

namespace {

// The smallest rotation taking the unit vector e to the unit vector u
// (Rodrigues' formula; u = −e is not taken).
Eigen::Matrix3d SmallestRotation(const Vector3& e, const Vector3& u) {
  const Vector3 v = e.cross(u);
  const double s2 = v.squaredNorm();
  if (s2 == 0.0) return Eigen::Matrix3d::Identity();
  Eigen::Matrix3d vx;
  vx << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return Eigen::Matrix3d::Identity() + vx + vx * vx * ((1.0 - e.dot(u)) / s2);
}

// The nearest-axis contact frame of a normal n: the smallest rotation R
// that takes the axis c nearest to n to ±n, so that in K̂ = Rᵀ K R the
// constrained direction is unknown 3p + c alone, and the tangent
// directions stay the unknowns of the other two axes.
Eigen::Matrix3d ContactFrame(const Vector3& n) {
  int c = 0;
  n.cwiseAbs().maxCoeff(&c);
  return SmallestRotation(Vector3::Unit(c), n(c) < 0.0 ? Vector3(-n) : n);
}

// A contact's direction: its (first) normal, turned into the upper
// half-space where it points mostly down (S_p depends on n nᵀ alone).
Vector3 ContactDirection(const Eigen::Matrix3d& dirs) {
  return dirs(2, 0) < -0.5 ? Vector3(-dirs.col(0)) : Vector3(dirs.col(0));
}

}  // namespace

bool Preconditioner::AdaptAmgTo(const SparseMatrix& a, const VelocityFilter& filter) {
  const int n = static_cast<int>(a.rows());
  const int contacts = ContactProjectors(filter, n);
  if (contacts == 0) {  // only the fixed particles: A_F's hierarchy is exact
    system_used_ = false;
    return true;
  }
  // Rebuild or keep: a kept hierarchy is that of a slightly different K and
  // costs CG iterations. The V-cycles beyond those of the first solve after
  // the last setup are counted (Apply counts them), and the hierarchy is
  // rebuilt once they, plus what the next kept step is expected to cost,
  // reach the cost of a setup, kSetupVCycles V-cycles. Counts, not times:
  // the choice, and so the run, is the same on every repetition. A
  // hierarchy is never kept over more than kSystemKeepShare of the contacts
  // changed.
  if (system_valid_) {
    const long applications = contact_stats_.v_cycles - applications_at_adapt_;
    if (solves_since_setup_ == 1) baseline_applications_ = applications;
    if (solves_since_setup_ >= 1)
      stale_cycles_ += static_cast<double>(std::max(0L, applications - baseline_applications_));
  }
  applications_at_adapt_ = contact_stats_.v_cycles;
  // A hierarchy that needs more V-cycles per solve than the other frame
  // mode's last one did is rebuilt at once (and so in the other mode):
  // trying a mode again costs one solve. So is the first hierarchy that has
  // been applied while the other mode is untried: a run that starts in
  // contact tries both modes in its first two solves (a replay of
  // round_table_1m at rest otherwise stayed in spread frames, 47–55 CG per
  // step, until the contacts changed; nearest-axis frames need 10–21).
  const auto mode = static_cast<std::size_t>(frame_mode_);
  const long applied = contact_stats_.v_cycles - applications_at_setup_;
  const bool losing = amg_frames_ == AmgFrames::kAdaptive && system_valid_ && solves_since_setup_ >= 1 &&
                      applied > 0 &&
                      (mode_measured_[1 - mode] == 0.0 ||
                       static_cast<double>(applied) / solves_since_setup_ > mode_measured_[1 - mode]);
  // The contacts of the finest level (the hierarchy's, or those of its
  // last update) are the current ones: nothing to do.
  bool moved = !system_valid_ || losing;
  for (std::size_t p = 0; p < s_now_.size() && !moved; ++p)
    moved = (s_now_[p] - fine_s_[p]).cwiseAbs().maxCoeff() > kSystemTurn;
  if (!moved) {
    ++solves_since_setup_;
    system_used_ = true;
    return true;
  }
  // Contacts changed since the setup (counted only once the finest level's
  // have moved: a resting step with a constant contact set skips the scan).
  int changed = 0;
  if (system_valid_)
    for (std::size_t p = 0; p < s_now_.size(); ++p)
      changed += (s_now_[p] - system_s_[p]).cwiseAbs().maxCoeff() > kSystemTurn;
  if (system_valid_ && !losing && changed <= kSystemKeepShare * contacts &&
      stale_cycles_ + stale_rate_ < kSetupVCycles) {
    // Kept with changed contacts: the finest level gets the current K (in
    // the current contact frames); the coarse levels and the interpolation
    // stay the hierarchy's (AmgPreconditioner::UpdateSystemFineLevel). If
    // hypre fails, a setup follows.
    const auto t0 = std::chrono::steady_clock::now();
    SetFrames(a, filter, /*smooth=*/false);
    AssembleSystem(a, s_now_);
    const bool updated = amg_->UpdateSystemFineLevel(n, k_start_, k_cols_, k_values_);
    const double dt = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    contact_stats_.seconds += dt;
    contact_stats_.modify_seconds += dt;
    if (updated) {
      fine_s_ = s_now_;
      ++contact_stats_.modifications;
      ++solves_since_setup_;
      system_used_ = true;
      return true;
    }
  }
  SetUpContactHierarchy(a, filter);
  return true;
}

int Preconditioner::ContactProjectors(const VelocityFilter& filter, int n) {
  if (static_cast<int>(s_now_.size()) != n) {
    s_now_.assign(static_cast<std::size_t>(n), Eigen::Matrix3d::Identity());
    system_s_.assign(static_cast<std::size_t>(n), Eigen::Matrix3d::Identity());
    fine_s_.assign(static_cast<std::size_t>(n), Eigen::Matrix3d::Identity());
    system_valid_ = false;
  }
  for (auto& s : s_now_) s.setIdentity();
  int contacts = 0, off_axis = 0;
  filter.ForEachConstraint([&](int p, int count, const Eigen::Matrix3d& dirs) {
    Eigen::Matrix3d& s = s_now_[static_cast<std::size_t>(p)];
    int c = 0;
    if (count == 1) off_axis += dirs.col(0).cwiseAbs().maxCoeff(&c) < kFrameSnap;
    if (amg_diagnostics_.frames_only) {  // S = I: the contacts set only the frames
      contacts += count < 3;
      return;
    }
    if (count == 1 && amg_diagnostics_.axis_normals) {  // the normal rounded to its nearest axis c
      s(c, c) = 0.0;
      ++contacts;
      return;
    }
    for (int k = 0; k < count; ++k) s -= dirs.col(k) * dirs.col(k).transpose();
    contacts += count < 3;
  });
  contact_stats_.off_axis = off_axis;
  return contacts;
}

void Preconditioner::SetUpContactHierarchy(const SparseMatrix& a, const VelocityFilter& filter) {
  const int n = static_cast<int>(a.rows());
  const auto mode = static_cast<std::size_t>(frame_mode_);
  const auto t0 = std::chrono::steady_clock::now();
  // The frames of this setup: the mode with the fewer V-cycles per solve
  // over the last hierarchy built with it. The other mode's record decays
  // by kFrameModeDecay at each setup, so that it is tried again once the
  // contacts have moved on (an untried mode is tried first).
  if (system_valid_ && solves_since_setup_ > 0) {
    mode_measured_[mode] = mode_rate_[mode] =
        static_cast<double>(contact_stats_.v_cycles - applications_at_setup_) / solves_since_setup_;
    mode_rate_[1 - mode] *= kFrameModeDecay;
    if (amg_frames_ == AmgFrames::kAdaptive && mode_rate_[1 - mode] < mode_rate_[mode])
      frame_mode_ = mode == 0 ? FrameMode::kSpread : FrameMode::kNearestAxis;
  }
  applications_at_setup_ = contact_stats_.v_cycles;
  ++contact_stats_.frame_setups[static_cast<std::size_t>(frame_mode_)];
  system_s_.swap(s_now_);
  fine_s_ = system_s_;
  SetFrames(a, filter, /*smooth=*/true);
  AssembleSystem(a, system_s_);
  // If the setup fails, A_F's hierarchy (which preconditions every filter)
  // serves until the next setup.
  system_valid_ = amg_->FactorizeSystem(n, k_start_, k_cols_, k_values_);
  if (!system_valid_) ++contact_stats_.fallbacks;
  const double dt = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (amg_diagnostics_.cycle_factor && system_valid_)
    contact_stats_.cycle_factor = amg_->SystemCycleFactor(kDiagnosticCycles);
  // The expected cost of a kept step: the mean over those since the last
  // setup, or, if none was kept, 0.9 of the last estimate (so that keeping
  // is tried again once the contacts settle).
  stale_rate_ = solves_since_setup_ > 1 ? stale_cycles_ / (solves_since_setup_ - 1) : 0.9 * stale_rate_;
  stale_cycles_ = 0.0;
  solves_since_setup_ = 1;
  contact_stats_.seconds += dt;
  contact_stats_.refactor_seconds += dt;
  ++contact_stats_.refactorizations;
  system_used_ = system_valid_;
}

void Preconditioner::SetFrames(const SparseMatrix& a, const VelocityFilter& filter, bool smooth) {
  const std::size_t n = system_s_.size();
  if (field_.size() != n) {
    field_.assign(n, Vector3::UnitZ());
    held_.assign(n, 0);
    frames_.assign(n, Eigen::Matrix3d::Identity());
  }
  if (amg_diagnostics_.axis_normals) {  // the normals are axes: world frames
    for (auto& f : frames_) f.setIdentity();
    return;
  }
  std::fill(held_.begin(), held_.end(), 0);
  if (frame_mode_ == FrameMode::kNearestAxis) {
    // Contact frames only (ContactFrame), at a setup and at an update; free
    // particles in the world frame.
    for (auto& f : frames_) f.setIdentity();
    filter.ForEachConstraint([&](int p, int count, const Eigen::Matrix3d& dirs) {
      if (count == 1) frames_[static_cast<std::size_t>(p)] = ContactFrame(dirs.col(0));
    });
    return;
  }
  if (!smooth) {
    // A finest-level update: the coarse levels keep the setup's frames, so
    // only the contacts' frames move, each turned by the smallest rotation
    // that takes its constrained unknown (R_p e_z) to its current normal.
    filter.ForEachConstraint([&](int p, int count, const Eigen::Matrix3d& dirs) {
      const auto i = static_cast<std::size_t>(p);
      held_[i] = 1;
      if (count != 1) return;
      field_[i] = ContactDirection(dirs);
      frames_[i] = SmallestRotation(frames_[i].col(2), field_[i]) * frames_[i];
    });
    return;
  }
  SpreadDirections(a, filter, /*flip=*/true, &field_);
  for (std::size_t p = 0; p < n; ++p)
    frames_[p] = !held_[p] && field_[p].z() > kFrameSnap ? Eigen::Matrix3d::Identity()
                                                         : SmallestRotation(Vector3::UnitZ(), field_[p]);
}

void Preconditioner::SpreadDirections(const SparseMatrix& a, const VelocityFilter& filter, bool flip,
                                      std::vector<Vector3>* field) {
  // Every free particle first takes the direction of its nearest contact (a
  // breadth-first search from all contacts over A's graph), so that a
  // hanging part keeps the frame of the contacts it hangs from instead of
  // returning to the world frame; kFrameSweeps Jacobi sweeps then turn the
  // seams between regions of different contacts gradually. A free particle
  // no contact reaches keeps e_z.
  const std::size_t n = static_cast<std::size_t>(a.rows());
  std::vector<Vector3>& f = *field;
  f.assign(n, Vector3::UnitZ());
  held_.assign(n, 0);
  reached_.assign(n, 0);
  queue_.clear();
  filter.ForEachConstraint([&](int p, int count, const Eigen::Matrix3d& dirs) {
    const auto i = static_cast<std::size_t>(p);
    held_[i] = count >= 3 ? 2 : 1;
    reached_[i] = 1;
    if (count != 1) return;  // fixed (or two directions): keeps e_z and is no source
    f[i] = flip ? ContactDirection(dirs) : Vector3(dirs.col(0));
    queue_.push_back(p);
  });
  const int* outer = a.outerIndexPtr();
  const int* inner = a.innerIndexPtr();
  for (std::size_t head = 0; head < queue_.size(); ++head) {
    const int p = queue_[head];
    for (int pos = outer[p]; pos < outer[p + 1]; ++pos) {
      const auto q = static_cast<std::size_t>(inner[pos]);
      if (reached_[q]) continue;
      reached_[q] = 1;
      f[q] = f[static_cast<std::size_t>(p)];
      queue_.push_back(inner[pos]);
    }
  }
  next_field_.resize(n);
  for (int sweep = 0; sweep < kFrameSweeps; ++sweep) {
    // Each particle from the last sweep's field alone: the same bits for
    // any thread count.
#pragma omp parallel for schedule(static) if (n >= kParallelSolveRows)
    for (std::ptrdiff_t pi = 0; pi < static_cast<std::ptrdiff_t>(n); ++pi) {
      const auto p = static_cast<std::size_t>(pi);
      next_field_[p] = f[p];
      if (held_[p]) continue;
      Vector3 sum = Vector3::Zero();
      // A fixed particle's direction (decoupled in A_F, its frame is free)
      // does not pull its neighbours'.
      for (int pos = outer[p]; pos < outer[p + 1]; ++pos)
        if (held_[static_cast<std::size_t>(inner[pos])] != 2) sum += f[static_cast<std::size_t>(inner[pos])];
      const double length = sum.norm();
      if (length > 0.0) next_field_[p] = sum / length;
    }
    f.swap(next_field_);
  }
}

void Preconditioner::AssembleSystem(const SparseMatrix& a, const std::vector<Eigen::Matrix3d>& s) {
  const int n = static_cast<int>(a.rows());
  // K̂ = Rᵀ (S A S + (I − S)) R: block (p, q) is a_pq R_pᵀ S_p S_q R_q, block
  // (p, p) is R_pᵀ (a_pp S_p + I − S_p) R_p, and between two free particles
  // a_pq I. Round-off of the rotations (below 1e-13 of a block) is dropped.
  k_start_.assign(static_cast<std::size_t>(3 * n) + 1, 0);
  k_cols_.clear();
  k_values_.clear();
  const int* outer = a.outerIndexPtr();
  const int* inner = a.innerIndexPtr();
  const double* val = a.valuePtr();
  plain_.resize(static_cast<std::size_t>(n));
  for (std::size_t p = 0; p < plain_.size(); ++p) plain_[p] = s[p].isIdentity(0.0) && frames_[p].isIdentity(0.0);
  for (int p = 0; p < n; ++p) {
    const Eigen::Matrix3d& sp = s[static_cast<std::size_t>(p)];
    const bool free_p = plain_[static_cast<std::size_t>(p)];
    // The blocks of row p, each computed once for its three rows (empty
    // while p and all its neighbours are free).
    blocks_.clear();
    bool all_free = free_p;
    for (int pos = outer[p]; pos < outer[p + 1] && all_free; ++pos)
      all_free = plain_[static_cast<std::size_t>(inner[pos])];
    if (!all_free)
      for (int pos = outer[p]; pos < outer[p + 1]; ++pos) {
        const int q = inner[pos];
        const Eigen::Matrix3d& sq = s[static_cast<std::size_t>(q)];
        Eigen::Matrix3d block = val[pos] * sp * sq;
        if (q == p) block += Eigen::Matrix3d::Identity() - sp;
        if (!(free_p && plain_[static_cast<std::size_t>(q)])) {
          block = frames_[static_cast<std::size_t>(p)].transpose() * block * frames_[static_cast<std::size_t>(q)];
          const double tiny = 1e-13 * block.cwiseAbs().maxCoeff();
          block = block.unaryExpr([tiny](double x) { return std::abs(x) <= tiny ? 0.0 : x; });
        }
        blocks_.push_back(block);
      }
    for (int r = 0; r < 3; ++r) {
      for (int pos = outer[p]; pos < outer[p + 1]; ++pos) {
        const int q = inner[pos];
        if (all_free || (free_p && plain_[static_cast<std::size_t>(q)])) {
          k_cols_.push_back(3 * q + r);
          k_values_.push_back(val[pos]);
          continue;
        }
        const Eigen::Matrix3d& block = blocks_[static_cast<std::size_t>(pos - outer[p])];
        for (int c = 0; c < 3; ++c)
          if (block(r, c) != 0.0 || (q == p && c == r)) {
            k_cols_.push_back(3 * q + c);
            k_values_.push_back(block(r, c));
          }
      }
      k_start_[static_cast<std::size_t>(3 * p + r) + 1] = static_cast<int>(k_cols_.size());
    }
  }
}

bool Preconditioner::AdaptTo(const SparseMatrix& a, const VelocityFilter& filter) {
  if (auto_) return AdaptAutoTo(a, filter);
  if (contact_factors_ && type_ == PreconditionerType::kAmg) return AdaptAmgTo(a, filter);
  return AdaptFactorsTo(a, filter);
}

// The contact policy (pcg.h, "The contact policy"): the step since the last AdaptTo
// is counted to the mode that served it, then the mode of the next step is
// chosen and adapted to the filter.
bool Preconditioner::AdaptAutoTo(const SparseMatrix& a, const VelocityFilter& filter) {
  if (!contact_factors_) return true;  // contact_factors = false: the factor alone
  const double n = static_cast<double>(a.rows());
  const double cycle = VCycleIterations(n);
  ModeChoice& c = auto_choice_;
  const auto [apps, setups, changes] = CountSince(&c);
  // A finest-level update of a kept hierarchy costs about a V-cycle.
  if (c.counting)
    c.Count(c.mode == 1 ? cycle * (apps + kAutoSetupVCycles * setups + changes)
                        : apps + kRefactorIterations * (setups + changes / (kModifyRowsPerSqrtN * std::sqrt(n))));
  int contacts = 0;
  filter.ForEachConstraint([&](int, int count, const Eigen::Matrix3d&) { contacts += count < 3; });
  if (contacts == 0) {  // A_F's factor is exact
    c.counting = false;
    axis_used_ = {false, false, false};
    cf_frames_ = false;
    system_used_ = false;
    return true;
  }
  if (c.counting) c.Choose(c.record[1 - c.mode] >= 0.0 ? c.record[1 - c.mode] : cycle * kAmgPriorIterations);
  c.counting = true;
  if (c.mode == 1) {
    axis_used_ = {false, false, false};
    cf_frames_ = false;
    if (!amg_) amg_ = std::make_unique<AmgPreconditioner>();
    if (!AdaptAmgTo(a, filter)) return false;
    // A failed setup (hypre, or a V-cycle that is not finite) leaves
    // system_used_ false: the contact factors serve this step.
    if (system_used_) return true;
  }
  system_used_ = false;
  return AdaptFactorsTo(a, filter);
}

std::array<double, 3> Preconditioner::CountSince(ModeChoice* c) const {
  const std::array<double, 3> since = {static_cast<double>(applications_ - c->applications_at),
                                       static_cast<double>(contact_stats_.refactorizations - c->refactorizations_at),
                                       static_cast<double>(contact_stats_.modifications - c->modifications_at)};
  c->applications_at = applications_;
  c->refactorizations_at = contact_stats_.refactorizations;
  c->modifications_at = contact_stats_.modifications;
  return since;
}

void Preconditioner::ModeChoice::Count(double cost) {
  record[mode] = stay_steps == 0 ? cost : kAutoRecent * cost + (1.0 - kAutoRecent) * record[mode];
  stay_least = stay_steps == 0 ? cost : std::min(stay_least, cost);
  ++stay_steps;
  if (record[1 - mode] >= 0.0) record[1 - mode] *= kAutoDecay;
}

void Preconditioner::ModeChoice::Choose(double other) {
  const bool settled = stay_steps >= kAutoMinStay || (other >= 0.0 && record[mode] > kAutoAbort * other);
  if (!settled || other >= record[mode]) return;
  record[mode] = stay_least;
  mode = 1 - mode;
  stay_steps = 0;
}

bool Preconditioner::AdaptFactorsTo(const SparseMatrix& a, const VelocityFilter& filter) {
  if (!contact_factors_ || !cholesky_) return true;
  const double n = static_cast<double>(a.rows());
  // Contact frames once the contacts off every axis (by more than
  // acos(kFrameSnap)) are as many as an axis factor needs (pcg.h, "Contact
  // frames").
  int tilted = 0;
  filter.ForEachConstraint([&](int, int count, const Eigen::Matrix3d& dirs) {
    tilted += count == 1 && dirs.col(0).cwiseAbs().maxCoeff() < kFrameSnap;
  });
  const bool frames = frame_factors_ && tilted >= kContactAxisShare * n;
  int want[3] = {0, 0, 0};
  for (auto& w : axis_want_) std::fill(w.begin(), w.end(), 0);
  filter.ForEachConstraint([&](int p, int count, const Eigen::Matrix3d& dirs) {
    if (count >= 3) return;  // fixed: decoupled in A_F already
    if (frames) {  // the first direction; a second is left to the PCG
      axis_want_[2][static_cast<std::size_t>(p)] = 1;
      ++want[2];
      return;
    }
    for (int k = 0; k < count; ++k) {
      int c = 0;
      if (dirs.col(k).cwiseAbs().maxCoeff(&c) < kContactAxisCosine) continue;
      char& w = axis_want_[static_cast<std::size_t>(c)][static_cast<std::size_t>(p)];
      if (!w) ++want[c];
      w = 1;
    }
  });
  using Clock = std::chrono::steady_clock;
  const auto seconds_since = [](Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); };
  bool refactorised = false;
  const long modifications_before = contact_stats_.modifications;
  for (std::size_t c = 0; c < 3; ++c) {
    contact_stats_.decoupled[c] = want[c];
    // An axis with few contacts keeps A_F's factor: a factor of its own
    // would cost a factorisation for little gain.
    if (want[c] < kContactAxisShare * n) {
      axis_used_[c] = false;
      continue;
    }
    int added = 0, released = 0;
    if (axis_valid_[c])
      for (std::size_t p = 0; p < axis_set_[c].size(); ++p) {
        added += axis_want_[c][p] && !axis_set_[c][p];
        released += axis_set_[c][p] && !axis_want_[c][p];
      }
    // Released contacts are coupled back at once: left decoupled (their
    // diagonal as the preconditioner there) they cost more CG iterations
    // than their row adds (docs/notes/performance.md, "Contact factors").
    const int changes = added + released;
    // Changes are applied as row deletes and adds while that is cheaper than
    // a refactorisation: up to kModifyRowsPerSqrtN·√N changed rows. Counts,
    // not times: the choice, and so the run, is the same on every repetition.
    const bool modify = axis_valid_[c] && changes > 0 && changes <= kModifyRowsPerSqrtN * std::sqrt(n);
    if (modify) {
      const auto t0 = Clock::now();
      std::vector<char>& set = axis_set_[c];
      const std::vector<char>& w = axis_want_[c];
      bool ok = true;
      // New contacts first, so that released ones are added back against
      // the final set.
      for (std::size_t p = 0; p < set.size() && ok; ++p)
        if (w[p] && !set[p]) {
          ok = axis_factor_[c]->DecoupleRow(static_cast<int>(p), a);
          set[p] = 1;
        }
      for (std::size_t p = 0; p < set.size() && ok; ++p)
        if (!w[p] && set[p]) {
          set[p] = 0;
          ok = axis_factor_[c]->CoupleRow(static_cast<int>(p), a, set);
        }
      const double dt = seconds_since(t0);
      contact_stats_.modifications += changes;
      contact_stats_.seconds += dt;
      contact_stats_.modify_seconds += dt;
      if (!ok) axis_valid_[c] = false;  // refactorised below
    }
    if (!axis_valid_[c] || (changes > 0 && !modify)) {
      const auto t0 = Clock::now();
      if (!axis_factor_[c]) axis_factor_[c] = cholesky_->CloneAnalysis();
      axis_set_[c].swap(axis_want_[c]);
      axis_valid_[c] = axis_factor_[c] && axis_factor_[c]->Factorize(a, &axis_set_[c]);
      const double dt = seconds_since(t0);
      contact_stats_.seconds += dt;
      contact_stats_.refactor_seconds += dt;
      ++contact_stats_.refactorizations;
      refactorised = true;
      if (!axis_valid_[c]) return false;
    }
    axis_used_[c] = true;
  }
  if (frames && axis_used_[2]) {
    // The frames are spread again with every refactorisation and once the
    // contacts added and released since the last spread exceed
    // kRespreadShare of the contacts: turning only the contacts' frames
    // leaves the free particles' beside them as they were, and over 0.3 s of
    // the sphere drape at 10⁵ particles those seams grew to 60, 197 and 691
    // CG per step (12–15 with the frames spread again).
    cf_changes_since_spread_ += contact_stats_.modifications - modifications_before;
    const bool spread =
        refactorised || !cf_frames_ || static_cast<double>(cf_changes_since_spread_) > kRespreadShare * want[2];
    SetFactorFrames(a, filter, spread);
    if (spread) cf_changes_since_spread_ = 0;
    cf_frames_ = true;
  } else {
    cf_frames_ = false;
  }
  return true;
}

void Preconditioner::SetFactorFrames(const SparseMatrix& a, const VelocityFilter& filter, bool spread) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::size_t n = static_cast<std::size_t>(a.rows());
  if (spread || cf_frame_.size() != n) {
    // With the factor refactorised: every particle's frame from the spread
    // contact normals (SpreadDirections, outward as the obstacles give
    // them), R_p = Q(u, d_p) Q(e_z, u) with Q(e, d) the smallest rotation
    // taking e to d and u the contacts' mean normal, so that R_p e_z = d_p
    // and the frames turn smoothly everywhere except near d_p = −u, the
    // direction fewest contacts face. (Turning each normal into the upper
    // half-space, as the prefiltered AMG's frames do, made the frames jump
    // where a drape wraps past a sphere's lower half: 308 CG per step.)
    SpreadDirections(a, filter, /*flip=*/false, &cf_field_);
    Vector3 u = Vector3::Zero();
    filter.ForEachConstraint([&](int, int count, const Eigen::Matrix3d& dirs) {
      if (count < 3) u += dirs.col(0);
    });
    u = u.norm() > 0.0 ? Vector3(u.normalized()) : Vector3::UnitZ();
    const Eigen::Matrix3d to_u = SmallestRotation(Vector3::UnitZ(), u);
    cf_frame_.resize(n);
    cf_rotated_.resize(n);
#pragma omp parallel for schedule(static) if (n >= kParallelSolveRows)
    for (std::ptrdiff_t pi = 0; pi < static_cast<std::ptrdiff_t>(n); ++pi) {
      const auto p = static_cast<std::size_t>(pi);
      const bool plain = !held_[p] && cf_field_[p].z() > kFrameSnap;
      cf_frame_[p] = plain ? Eigen::Matrix3d::Identity() : Eigen::Matrix3d(SmallestRotation(u, cf_field_[p]) * to_u);
      cf_rotated_[p] = !plain;
    }
  } else {
    // Between refactorisations only the contacts' frames turn, each by the
    // smallest rotation that takes its column z (R_p e_z) to its normal.
    filter.ForEachConstraint([&](int p, int count, const Eigen::Matrix3d& dirs) {
      if (count >= 3) return;
      const auto i = static_cast<std::size_t>(p);
      cf_frame_[i] = SmallestRotation(cf_frame_[i].col(2), dirs.col(0)) * cf_frame_[i];
      cf_rotated_[i] = 1;
    });
  }
  const double dt = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  contact_stats_.seconds += dt;
  contact_stats_.modify_seconds += dt;
}

}  // namespace clothbench
