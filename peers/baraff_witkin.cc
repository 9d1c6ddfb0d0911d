// Baraff–Witkin step (Baraff & Witkin 1998, eq. 16–18; Blender's
// implicit_blender.cc, BPH_mass_spring_solve_velocities).
#include "peers/baraff_witkin.h"

#include <chrono>
#include <cmath>

namespace clothbench {
namespace {

TangentOptions TangentSettings(const SolverSpec& s) {
  TangentOptions o;
  o.projection = s.tangent_projection;
  o.include_explicit_terms = s.tangent_explicit_terms;
  o.symmetrize = true;  // CG needs a symmetric matrix (see TangentOptions)
  return o;
}

}  // namespace

namespace {

// Blender's cg_filtered (implicit_blender.cc, commit 1a675d0c): no
// preconditioner (c = r), conjgrad_epsilon = 0.01, conjgrad_looplimit = 100.
SolverSpec AsShipped(SolverSpec s, bool blender) {
  if (blender) {
    s.preconditioner = PreconditionerType::kNone;
    s.cg_tolerance = 0.01;
    s.cg_max_iterations = 100;
    s.cg_reference = CgReference::kFiltered;
  }
  return s;
}

}  // namespace

BaraffWitkin::BaraffWitkin(const ParticleSystem& system, const SolverSpec& solver, BaraffWitkinOptions options)
    : sys_(system),
      opts_(AsShipped(solver, options.blender)),
      blender_(options.blender),
      tangent_(system, TangentSettings(opts_)),
      precond_(opts_.preconditioner),
      contacts_(system) {
  const auto start = std::chrono::steady_clock::now();
  contacts_.set_friction_law(opts_.friction_law);
  contacts_.set_stiction(opts_.friction_cap == FrictionCap::kStiction);
  const int n = system.num_particles();
  if (UsesAlphaPreconditioner(opts_.preconditioner))
    laplacian_ = std::make_unique<SystemMatrix>(system, opts_.preconditioner, opts_.cholesky_ordering,
                                                opts_.contact_factors);
  if (laplacian_) laplacian_->set_amg_frames(opts_.amg_frames);
  precond_.Analyze(tangent_.matrix(), laplacian_ ? &laplacian_->preconditioner() : nullptr);
  work_.Resize(n);
  filter_.Reserve(n);
  for (int p : system.fixed()) filter_.Fix(p);
  for (MatrixN3* m : {&x0_, &v0_, &xm1_, &f_, &rhs_, &x1_, &v1_}) m->setZero(n, 3);
  if (IsImplicit(opts_.friction_law) && contacts_.active()) {
    friction_diagonal_.setZero(n);
    friction_change_.setZero(n);
  }
  vr_.setZero(n, 3);
  br_.setZero(n, 3);
  rhs_r_.setZero(n, 3);
  setup_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

double BaraffWitkin::setup_seconds() const {
  return setup_seconds_ + (laplacian_ ? laplacian_->setup_seconds() : 0.0);
}

void BaraffWitkin::Reset(double t, const MatrixN3& x, const MatrixN3& v) {
  t_ = t;
  x0_ = x;
  v0_ = v;
  filter_.Impose(&v0_);
  have_history_ = false;
  contacts_.Reset();
}

// Row p of J v₁ − b [kg m/s] of the solve just done (J is symmetric: rows
// 3p … 3p+2 are those columns).
Vector3 BaraffWitkin::ResidualRow(int p) const {
  const SparseMatrix& j = tangent_.matrix();
  Vector3 r = -br_.row(p).transpose();
  for (int c = 0; c < 3; ++c)
    for (SparseMatrix::InnerIterator it(j, 3 * p + c); it; ++it) r(c) += it.value() * vr_.data()[it.row()];
  return r;
}

// The forces, friction and right-hand side at the step's start and the
// PCG solve for v₁ (in vr_) under this attempt's filter. Returns false
// with st->status set when the solve fails.
bool BaraffWitkin::SolveVelocities(double h, bool again, StepStats* st) {
  // J v₁ = J v₀ + h (f₀ + h ∂f/∂x v₀)  ⇔  J Δv = h (f₀ + h ∂f/∂x v₀)  (eq. 18).
  // f₀ once per step, kept in f_: a solve again (the active set) changes
  // only the friction, which goes into the right-hand side.
  if (!again) sys_.Forces(t_, x0_, v0_, &f_);
  if (contacts_.active() && opts_.friction_cap == FrictionCap::kSystem) {
    // −tᵀ J_pq t for J's blocks beside particle p's (rows 3p … 3p+2): J is
    // not an M-matrix, so there the system cap is an estimate, not a bound.
    const SparseMatrix& j = tangent_.matrix();
    const auto coupling = [&](int p, const Vector3& t, auto&& visit) {
      // Column 3p lists each neighbour q's rows 3q … 3q+2 in order (full
      // 3×3 blocks); −tᵀ J_qp t once per q (J is symmetric).
      int last = -1;
      for (SparseMatrix::InnerIterator it(j, 3 * p); it; ++it) {
        const int q = static_cast<int>(it.row()) / 3;
        if (q == p || q == last) continue;
        last = q;
        double w = 0.0;
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) w -= t(r) * t(c) * j.coeff(3 * q + r, 3 * p + c);
        visit(q, w);
      }
    };
    contacts_.CapBySystem(coupling);
  }
  rhs_ = f_;
  if (contacts_.active()) rhs_ += contacts_.friction();  // Coulomb friction, explicit (docs/model.md §2.5)
  rhs_ *= h;
  tangent_.AddJacobianProducts(h * h, v0_, 0.0, v0_, &rhs_);
  // FrictionLaw::kImplicit: −c (v₁ − u)_t, h c on J's diagonal (Step) and
  // h c (u − v₀) in the Δv form's right-hand side.
  contacts_.ForEachFrictionDamping([&](int p, double c, const Vector3& u) {
    rhs_.row(p) += (h * c) * (u - v0_.row(p).transpose()).transpose();
  });
  rhs_r_ = v0_;  // v₀ row-major, in rhs_r_'s storage until its own use below
  TangentProduct(tangent_.matrix(), rhs_r_, &br_);
  br_ += rhs_;
  // A solve again of the step starts from the last solve's v₁, which
  // differs only where contacts were released.
  if (!again) vr_ = v0_;

  // η relative to the Δv form's right-hand side b_Δ = h (f₀ + h ∂f/∂x v₀):
  // ‖S_F b_Δ‖ (CgReference::kFixedOnly, with contacts) or ‖S b_Δ‖. The
  // residual b − J v = b_Δ − J Δv is the same in both forms; only the
  // reference norm is the Δv form's.
  rhs_r_ = rhs_;
  if (!(contacts_.active() && opts_.cg_reference == CgReference::kFixedOnly)) filter_.Project(&rhs_r_);
  const double reference =
      contacts_.active() && opts_.cg_reference == CgReference::kFixedOnly ? FreeRowsNorm(rhs_r_, sys_.fixed())
                                                                            : rhs_r_.norm();
  const PcgSummary pcg = FilteredPcg(tangent_.matrix(), br_, filter_, precond_,
                                     PcgOptions{opts_.cg_tolerance, opts_.cg_max_iterations, reference}, &vr_, &work_);
  st->cg_iterations += pcg.iterations;
  st->pcg_status = pcg.status;
  // Blender keeps Vnew = V + dV whatever cg_filtered returned
  // (SIM_mass_spring_solve_velocities); a non-finite solve is still a failure.
  const bool kept = blender_ && pcg.status == PcgStatus::kMaxIterations;
  if (pcg.status != PcgStatus::kConverged && !kept) {
    st->status = pcg.status == PcgStatus::kNonFinite   ? StepStatus::kNonFinite
                 : pcg.status == PcgStatus::kTimeLimit ? StepStatus::kTimeLimit
                                                       : StepStatus::kCgFailed;
    return false;
  }
  return true;
}

// FrictionLaw::kImplicit: J's diagonal += h c_p for this attempt's
// contacts (ContactResponse::ForEachFrictionDamping), replacing those of the
// last call. The preconditioner stays that of J as it was factorised.
void BaraffWitkin::UpdateFrictionDiagonal(double h) {
  if (friction_diagonal_.size() == 0) return;
  friction_change_ = -friction_diagonal_;
  friction_diagonal_.setZero();
  contacts_.ForEachFrictionDamping([&](int p, double c, const Vector3&) { friction_diagonal_(p) = h * c; });
  friction_change_ += friction_diagonal_;
  tangent_.AddToDiagonal(friction_change_);
}

StepStats BaraffWitkin::Step(double h) {
  const auto start = std::chrono::steady_clock::now();
  const double setup_before = setup_seconds();
  StepStats st;
  st.t = t_ + h;
  st.h = h;
  st.updates = 1;
  auto finish = [&]() {
    st.solve_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    st.setup_time = setup_seconds() - setup_before;
    return st;
  };
  if (contacts_.active()) st.colliding = contacts_.SetUp(t_, h, x0_, v0_, have_history_ ? &xm1_ : nullptr, &filter_);
  PrescribeFixedTargets(sys_, t_ + h, &filter_);  // moving fixed particles: their velocity at the step's end

  // J = M − h ∂f/∂v − h² ∂f/∂x at (t₀, x₀, v₀) and its preconditioner.
  {
    // A_α's update and contact adaptation count in laplacian_->setup_seconds();
    // setup_seconds_ holds J's assembly and its preconditioner's own work.
    bool ok = !laplacian_ || (laplacian_->Update(h) && laplacian_->AdaptTo(filter_));
    if (laplacian_) st.preconditioner = laplacian_->preconditioner().ServedBy();
    const auto t0 = std::chrono::steady_clock::now();
    tangent_.Update(t_, x0_, v0_, h);
    friction_diagonal_.setZero();  // Update overwrote J's diagonal
    UpdateFrictionDiagonal(h);
    ok = ok && precond_.Factorize(tangent_.matrix());
    ++rebuilds_;
    setup_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (!ok) {
      st.status = StepStatus::kPreconditionerFailed;
      return finish();
    }
  }
  if (!SolveVelocities(h, /*again=*/false, &st)) return finish();
  // The active set (ContactResponse::ReviseHolds): the step is solved again
  // without the stiction holds whose tangential impulse exceeds μ J_N, and
  // with the implicit friction that left its cone as μ J_N.
  for (int k = 0; contacts_.revises() && k < ContactResponse::kHoldRevisions &&
                  contacts_.ReviseHolds([this](int p) { return ResidualRow(p); }, v0_, vr_, v0_,
                                        opts_.cg_tolerance * FreeRowsNorm(br_, sys_.fixed()), opts_.cg_tolerance);
       ++k) {
    st.colliding = contacts_.SetUpAgain(&filter_);
    PrescribeFixedTargets(sys_, t_ + h, &filter_);
    ++st.updates;
    UpdateFrictionDiagonal(h);  // without the contacts that left the cone
    if (laplacian_ && !laplacian_->AdaptTo(filter_)) {
      st.status = StepStatus::kPreconditionerFailed;
      return finish();
    }
    if (!SolveVelocities(h, /*again=*/true, &st)) return finish();
  }
  v1_ = vr_;
  x1_ = x0_ + h * v1_;
  HoldFixed(sys_, t_ + h, x0_, &x1_, &v1_);
  if (!x1_.allFinite() || !v1_.allFinite()) {
    st.status = StepStatus::kNonFinite;
    return finish();
  }
  if (contacts_.active()) {
    contacts_.SetImplicitFriction(v1_);
    contacts_.ReadImpulses([this](int p) { return ResidualRow(p); }, v0_, v1_, v0_,
                           opts_.cg_tolerance * FreeRowsNorm(br_, sys_.fixed()));
  }
  xm1_.swap(x0_);
  x0_.swap(x1_);
  v0_.swap(v1_);
  t_ += h;
  have_history_ = true;
  return finish();
}

}  // namespace clothbench

// The rows of Baraff–Witkin at its best and of Blender as it ships, as the
// registry lists them (harness/registry.cc).
#include "solver/method_row.h"

namespace clothbench {

/// baraff_witkin: also measured at h = 0.01, 0.00125, 0.0003125 s alone
/// (`bench_integrators --integrators baraff_witkin --h
/// 0.01,0.00125,0.0003125 --preconditioner P`): solver time 0.124,
/// 0.554, 1.835 s with "cholesky", 0.174, 0.876, 3.149 s with "ic0"
/// (IC(0) of J refactorised every step), 0.230, 0.693, 2.048 s with 3×3
/// block Jacobi and 0.281, 0.635, 1.878 s with none.
/// Its CG tolerance is Blender's conjgrad_epsilon, 10⁻², on the Δv
/// form's ‖S r‖/‖S b_Δ‖ (the scenes' η = 10⁻⁶ is the thesis' velocity-
/// form setting). Measured (`bench_integrators --integrators
/// baraff_witkin --cg-tolerances 1e-6,1e-4,1e-3,1e-2`, default scene):
/// e_rms 2.986e-3 / 2.961e-3 / 3.008e-3 m at h = 0.00125 s and
/// 7.540e-4 / 7.541e-4 / 7.765e-4 m at h = 0.0003125 s for η = 10⁻⁶,
/// 10⁻³, 10⁻² (+0.7 % and +3 % at 10⁻²), solver time 0.537 / 0.433 /
/// 0.388 s and 1.734 / 1.534 / 1.439 s. On the 10⁶-particle sheet the
/// final positions differ from the η = 10⁻⁶ run by 2.1·10⁻⁶ m rms
/// after 1.4·10⁻² m of motion, and a step takes 2.6–2.9 s instead of
/// 6.6–7.6 s (docs/notes/newton.md).
/// J_α of tension and mass only (tangent_explicit_terms = false; shear,
/// bending and the other terms enter f₀ but not J): `bench_integrators
/// --integrators baraff_witkin --h 0.01,0.00125 --tangent-terms all`
/// and `tension` on the default scene: solver time 0.064 / 0.379 s with
/// all terms, 0.032 / 0.163 s with tension (CG iterations 785 / 1655
/// and 796 / 1660), e_rms 2.351e-2 / 3.008e-3 m and 2.206e-2 / 2.781e-3
/// m. At h = 0.01 s on hanging_sheet, wind_sheet, tablecloth,
/// hanging_tablecloth, round_table and swinging_box it takes 0.48–0.53×
/// the solver time with the same CG counts (±3 %) and dE/dt to three
/// digits. The Newton rows keep the scene's: their quadratic
/// convergence needs the whole J (bdf2/newton at h = 0.01 s: 503
/// instead of 300 updates, the same time).
/// Default parameters: 3.0e-3 m at h/8, 7.5e-4 m at h/32 (`bench_integrators
/// --integrators baraff_witkin,blender --h
/// 0.01,0.005,0.0025,0.00125,0.000625,0.0003125`).
MethodEntry BaraffWitkinRow() {
  return {.name = kBaraffWitkinName, .layer = "peers", .collisions = true, .pcg = true, .tangent = true,
          .make = [](const ParticleSystem& sys, const SolverSpec& spec, int, std::string_view) -> std::unique_ptr<Stepper> {
            return std::make_unique<BaraffWitkin>(sys, spec);
          },
          .best_preconditioner = kBestPreconditioner, .best_cg_tolerance = 1e-2, .best_tangent_explicit_terms = false,
          .defaults = {{.modifiers = "", .h_factors = {1.0 / 8, 1.0 / 32}}}};
}

/// blender: Blender's solver as it ships, with its own CG settings, so the
/// scene's η does not apply. Default parameters: 2.8e-3 m at h/8 and
/// 6.4e-4 m at h/32 (the command above).
MethodEntry BlenderRow() {
  return {.name = kBlenderName, .layer = "peers", .collisions = true, .tangent = true,
          .make = [](const ParticleSystem& sys, const SolverSpec& spec, int, std::string_view) -> std::unique_ptr<Stepper> {
            return std::make_unique<BaraffWitkin>(sys, spec, BaraffWitkinOptions{true});
          },
          .defaults = {{.modifiers = "", .h_factors = {1.0 / 8, 1.0 / 32}}}};
}

}  // namespace clothbench
