// XPBD with substeps: extended position-based dynamics (Macklin, Müller,
// Chentanez 2016, "XPBD: position-based simulation of compliant constrained
// dynamics") in the "small steps" scheme (Macklin, Storey, Lu, Terdiman,
// Chentanez, Jeschke, Müller 2019, Algorithm 1): a frame step h is split into
// n substeps Δt = h/n with one constraint sweep each (docs/model.md §10). The model is
// the scene's, expressed as constraints where it has a constraint form:
//  - tension: each spring a distance constraint C = |x_b − x_a| − l_e with
//    compliance α = 1/s_e (energy ½ s_e C², the same as §2.1);
//  - tension damping c_e (v_b − v_a) (docs/model.md §2.1, isotropic as in the model):
//    the damping term of XPBD Eq. 26 on the vector constraint C = x_b − x_a
//    with β = c_e and zero stiffness (α → ∞), ProjectDamper. Eq. 26's
//    damping on the distance constraint itself would damp only along the
//    spring: a different model, whose trajectories do not converge to the
//    reference's as Δt shrinks;
//  - shear (μ > 0): one constraint per particle, C = γ_ij of docs/model.md §2.2, with
//    α = 1/(μ lu lv) (energy ½ μ γ² lu lv) and β = d_s lu lv;
//  - everything else (bending, transverse contraction, gravity, wind, air)
//    as explicit forces in the velocity prediction (explicit_terms());
//  - obstacles: the inequality C = d(x) − δ ≥ 0 on the signed distance d,
//    with zero compliance, and Coulomb friction on the tangential
//    displacement (peers/position_contacts.h);
//  - self-contact (`[collision] self = true`): point–triangle and edge–edge
//    inequality constraints with zero compliance in every substep
//    (peers/position_contacts.h, PositionSelfContact);
//  - fixed particles have inverse mass 0.
#ifndef CLOTHBENCH_PEERS_XPBD_H_
#define CLOTHBENCH_PEERS_XPBD_H_

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "model/particle_system.h"
#include "peers/position_contacts.h"
#include "solver/integrator.h"

namespace clothbench {

/// The integrator name used by the executables and result files.
inline constexpr std::string_view kXpbdName = "xpbd";

/// XPBD, one Gauss–Seidel constraint sweep per substep (order 1 in Δt).
class Xpbd : public Stepper {
 public:
  /// @param system the model (must outlive the stepper)
  /// @param substeps n ≥ 1, substeps per Step(h)
  /// @throws std::invalid_argument if substeps < 1
  Xpbd(const ParticleSystem& system, int substeps);

  void Reset(double t, const MatrixN3& x, const MatrixN3& v) override;
  /// One frame step of size h [s]: n substeps Δt = h/n. stats.updates = n
  /// (constraint sweeps), cg_iterations = 0, colliding = particles on an
  /// obstacle in the last substep. Status kNonFinite (state unchanged) if
  /// the state becomes non-finite. No allocation.
  StepStats Step(double h) override;
  double t() const override { return t_; }
  void SetTime(double t) override { t_ = t; }
  const MatrixN3& x() const override { return x0_; }
  const MatrixN3& v() const override { return v0_; }
  bool single_update() const override { return true; }
  int matrix_rebuilds() const override { return 0; }
  double setup_seconds() const override { return 0.0; }
  const SelfContactStats* own_self_contact() const override { return self_ ? &self_->stats() : nullptr; }
  /// Moving fixed particles are kinematic: at their prescribed position at
  /// every substep's end.
  bool follows_prescribed_motion() const override { return true; }

  int substeps() const { return substeps_; }
  /// The scene's force terms applied explicitly in the prediction (all but
  /// the tension and, with μ > 0, the shear constraints), e.g. "gravity",
  /// "bend_thin_plate".
  const std::vector<std::string>& explicit_terms() const { return explicit_names_; }
  /// Whether shear is a constraint (μ > 0) rather than an explicit force.
  bool shear_constraint() const { return shear_.size() > 0; }

  /// One XPBD projection of a distance constraint C = |p_b − p_a| − l with
  /// compliance α [m/N] and damping β [N s/m] over a substep Δt [s], with
  /// λ = 0 (one iteration per substep), XPBD Eq. 18 and 26:
  ///   α̃ = α/Δt², γ = α̃ β Δt,
  ///   Δλ = (−C − γ ∇C·(p − x)) / ((1 + γ)(w_a + w_b) + α̃),
  ///   p_a −= w_a n Δλ, p_b += w_b n Δλ,   n = (p_b − p_a)/|p_b − p_a|.
  /// @param pa,pb predicted positions [m], updated; @param xa,xb positions
  /// at the substep's start [m]; @param wa,wb inverse masses [1/kg].
  /// @return Δλ [N s²] (0 if |p_b − p_a| = 0 or wa + wb = 0)
  static double ProjectDistance(Vector3* pa, Vector3* pb, const Vector3& xa, const Vector3& xb, double wa, double wb,
                                double rest_length, double compliance, double damping, double dt);

  /// The damping of XPBD Eq. 26 on the linear vector constraint
  /// C = p_b − p_a (∇C M⁻¹ ∇Cᵀ = (w_a + w_b) I) in the limit α → ∞ of zero
  /// stiffness, where γ/α̃ = β Δt and the C/α̃ term vanishes:
  ///   Δλ = −β Δt ((p_b − x_b) − (p_a − x_a)) / (1 + β Δt (w_a + w_b)),
  ///   p_a −= w_a Δλ, p_b += w_b Δλ:
  /// an implicit damper c_e (v_b − v_a) with β = c_e [N s/m].
  /// @return Δλ [N s²] (3-vector)
  static Vector3 ProjectDamper(Vector3* pa, Vector3* pb, const Vector3& xa, const Vector3& xb, double wa, double wb,
                               double damping, double dt);

 private:
  struct Distance {
    int a, b;
    double rest_length, compliance, damping;  // l_e [m], 1/s_e [m/N] (0: no stiffness), c_e [N s/m]
  };
  // γ_ij at particle c over its cross (c, r, l, u, d); a missing neighbour is
  // c itself and its spacing halves (docs/model.md §2.2).
  // A cross of the shear constraint C = γ − γ₀ (CentreRest): on a
  // curvilinear pattern its compliance is 1/(μ A) and its damping d_s A,
  // the shared values times compliance_scale = 1/A and area_scale = A;
  // on a uniform grid both scales are 1.
  struct ShearCross {
    std::array<int, 5> nodes;
    double du, dv;
    double gamma0 = 0.0, compliance_scale = 1.0, area_scale = 1.0;
  };
  void PredictionForces(double t, const MatrixN3& x, const MatrixN3& v, MatrixN3* f) const;
  void ProjectShear(double dt);

  const ParticleSystem& sys_;
  int substeps_;
  double t_ = 0.0;
  Eigen::VectorXd w_;                    // inverse masses, 0 for fixed particles
  std::vector<Distance> distance_;       // springs with s_e > 0 or c_e > 0
  bool has_dampers_ = false;             // some c_e > 0
  std::vector<ShearCross> shear_;        // empty unless μ > 0
  double shear_compliance_ = 0.0, shear_damping_ = 0.0;
  std::vector<const ForceTerm*> explicit_;
  std::vector<std::string> explicit_names_;
  MatrixN3 x0_, v0_, x_, v_, p_, f_;
  std::optional<PositionSelfContact> self_;  // `[collision] self = true`
  ObstacleProximity proximity_;              // the obstacles' entries of each substep
};

}  // namespace clothbench

#endif  // CLOTHBENCH_PEERS_XPBD_H_
