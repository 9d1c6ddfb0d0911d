// Baraff & Witkin (1998), "Large steps in cloth simulation", as production
// cloth solvers run it (Blender's implicit_blender.cc): implicit Euler
// linearised once per step with the full force Jacobians (eq. 16–18),
//   (M − h ∂f/∂v − h² ∂f/∂x) Δv = h (f₀ + h ∂f/∂x v₀),   x₁ = x₀ + h (v₀ + Δv),
// solved by the same filtered PCG, velocity filter S and (4.4) target as the
// thesis' methods (docs/model.md §5, §7), with the same explicit Coulomb friction.
// A peer of the thesis' integrators, not one of them (docs/model.md §10).
#ifndef CLOTHBENCH_PEERS_BARAFF_WITKIN_H_
#define CLOTHBENCH_PEERS_BARAFF_WITKIN_H_

#include <memory>
#include <string_view>

#include "model/particle_system.h"
#include "solver/contact.h"
#include "solver/integrator.h"
#include "solver/pcg.h"
#include "solver/tangent.h"

namespace clothbench {

/// The integrator names used by the executables and result files: the
/// method at its best, and Blender's solver as it ships.
inline constexpr std::string_view kBaraffWitkinName = "baraff_witkin";
inline constexpr std::string_view kBlenderName = "blender";

struct BaraffWitkinOptions {
  /// Blender's cg_filtered as it ships (BaraffWitkin); false: the scene's
  /// solver settings.
  bool blender = false;
};

/// One linearised implicit Euler step per time step (order 1).
///
/// Conventions, where they differ between Blender and this harness:
///  - Force model: the scene's (tension with rest length and isotropic
///    damping c_e(v_b − v_a), shear, bending, transverse, wind, air), so the
///    row solves the same ODE as every other row. Blender's springs are
///    dropped entirely while compressed (unless "resist compression") and
///    damp only along the spring, c (v·d̂) d̂.
///  - Compressed springs in the Jacobian: the transverse factor is clamped
///    at 0 (tangent_projection = "clamp", Choi & Ko 2002), keeping the axial
///    stiffness s_e d̂d̂ᵀ; Blender zeroes the whole Jacobian of a compressed
///    spring, consistent with its force being zero there.
///  - Shear, bending and the other stencil terms enter ∂f/∂x exactly
///    (AutoDiff) when tangent_explicit_terms is true; Blender models them as
///    springs with spring Jacobians. J is symmetrised, (J + Jᵀ)/2, for CG.
///  - The CG stop: ‖S r‖ ≤ η ‖S_F b_Δ‖ in the Δv form, b_Δ = h (f₀ + h ∂f/∂x v₀)
///    (Baraff & Witkin's and Blender's right-hand side; the velocity form's
///    b = J v₀ + b_Δ would be dominated by the momentum M v₀), with the
///    η and preconditioner of the SolverSpec it is given (the default run
///    gives it Blender's η = 10⁻², the A_α factor and J_α of tension and mass
///    only: BaraffWitkinRow); a step whose CG fails is rejected. The CG
///    starts from Δv = 0, as Blender's does (a warm start from the last Δv
///    changes the method at a loose η: docs/notes/newton.md).
///  - `blender` (BaraffWitkinOptions::blender) is the solver as Blender ships it
///    (implicit_blender.cc at commit 1a675d0c, cg_filtered and
///    SIM_mass_spring_solve_velocities): no preconditioner,
///    conjgrad_epsilon = 0.01 on ‖S r‖/‖S B‖, conjgrad_looplimit = 100, and
///    Vnew = V + dV whatever cg_filtered returned, so an unconverged Δv is
///    kept (StepStats::pcg_status = kMaxIterations on an accepted step). It
///    differs from Blender in double precision (Blender: float), in the
///    force model above, and in solving for v₁ = v₀ + Δv (the same system).
///  - Unknown: v₁ = v₀ + Δv (the filter prescribes velocities, Blender's z
///    prescribes Δv); the same linear system.
class BaraffWitkin : public Stepper {
 public:
  /// @param system the model (must outlive the stepper)
  /// @param solver cg_tolerance, cg_max_iterations, preconditioner,
  ///        cg_reference, tangent_projection, tangent_explicit_terms
  BaraffWitkin(const ParticleSystem& system, const SolverSpec& solver, BaraffWitkinOptions options = {});

  void Reset(double t, const MatrixN3& x, const MatrixN3& v) override;
  /// One step of size h [s]: status kCgFailed / kPreconditionerFailed /
  /// kNonFinite on failure (the state is then unchanged). No allocation.
  StepStats Step(double h) override;
  double t() const override { return t_; }
  void SetTime(double t) override { t_ = t; }
  const MatrixN3& x() const override { return x0_; }
  const MatrixN3& v() const override { return v0_; }
  bool single_update() const override { return true; }
  int matrix_rebuilds() const override { return rebuilds_; }
  double setup_seconds() const override;
  double contact_detection_seconds() const override { return contacts_.setup_seconds(); }
  const ContactResponse::Work* contact_work() const override {
    return contacts_.active() ? &contacts_.work() : nullptr;
  }
  bool corrects_state() const override { return true; }
  bool follows_prescribed_motion() const override { return true; }
  void CorrectState(const MatrixN3& x, const MatrixN3& v) override {
    x0_ = x;
    v0_ = v;
  }

 private:
  // One linear solve of the step (eq. 18) into vr_; `again`: a solve again
  // of the same step (the active set), from the last solve's vr_.
  bool SolveVelocities(double h, bool again, StepStats* st);
  void UpdateFrictionDiagonal(double h);
  Vector3 ResidualRow(int p) const;
  const ParticleSystem& sys_;
  SolverSpec opts_;
  bool blender_ = false;
  TangentSystem tangent_;
  std::unique_ptr<SystemMatrix> laplacian_;  // A_α's preconditioner ("cholesky", "amg" only)
  TangentPreconditioner precond_;
  TangentPcgWorkspace work_;
  VelocityFilter filter_;
  ContactResponse contacts_;
  Eigen::VectorXd friction_diagonal_;  // FrictionLaw::kImplicit: h c_p on J's diagonal [kg] (N; empty otherwise)
  Eigen::VectorXd friction_change_;    // scratch of UpdateFrictionDiagonal
  double t_ = 0.0;
  bool have_history_ = false;
  int rebuilds_ = 0;
  double setup_seconds_ = 0.0;
  MatrixN3 x0_, v0_, xm1_, f_, rhs_, x1_, v1_;
  MatrixN3R vr_, br_, rhs_r_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_PEERS_BARAFF_WITKIN_H_
