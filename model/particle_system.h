// The particle model of a scene (docs/model.md §1–2): masses, the stiff linear part
// −L_K x − L_D v (3.19), and the explicit terms g(t, x, v) of the split ODE
// (3.20), assembled from the scene so that a term with zero coefficients is
// never evaluated (docs/model.md §2.6).
#ifndef CLOTHBENCH_MODEL_PARTICLE_SYSTEM_H_
#define CLOTHBENCH_MODEL_PARTICLE_SYSTEM_H_

#include <memory>
#include <string>
#include <vector>

#include "model/force_terms.h"
#include "model/scene.h"
#include "model/types.h"
#include "model/virtual_springs.h"

namespace clothbench {

/// Energies [J] and linear momentum [kg m/s] of a state.
struct EnergyBreakdown {
  double kinetic = 0.0;    ///< ½ Σ m |v|²
  double tension = 0.0;    ///< ½ Σ s_e (|d| − l_e)² (split) or ½ Σ s_e |d|² (linear model)
  double shear = 0.0;      ///< Σ ½ μ γ² lu lv, the energy whose gradient the shear term is (docs/model.md §2.2)
  double bending = 0.0;    ///< ½ Σ lu lv (B_u ⟨s_uu,N⟩² + B_v ⟨s_vv,N⟩²): a diagnostic, see below
  double gravity = 0.0;    ///< −Σ m g·x
  Vector3 momentum = Vector3::Zero();  ///< Σ m v
  /// Kinetic + tension + shear + bending + gravity.
  double total() const { return kinetic + tension + shear + bending + gravity; }
};

class ParticleSystem {
 public:
  /// Builds the model of `scene` (validated by ParseScene).
  explicit ParticleSystem(const Scene& scene);

  const Scene& scene() const { return scene_; }
  int num_particles() const { return n_; }
  /// N×3 rest positions [m]: x_p = origin + i lu u_axis + j lv v_axis on a
  /// grid, a curvilinear pattern's placed samples (PlacePattern).
  const MatrixN3& rest_positions() const { return rest_; }
  /// N lumped masses m_p [kg] (docs/model.md §1).
  const Eigen::VectorXd& masses() const { return mass_; }
  /// L_K: N×N weighted graph Laplacian of the spring stiffnesses s_e [N/m]
  /// (3.19). Off-diagonals −s_e, diagonal the row sums; SPSD.
  const SparseMatrix& stiffness_laplacian() const { return lk_; }
  /// L_D: the same for the damping coefficients c_e [N s/m]; empty (0 nnz)
  /// when d_t = 0.
  const SparseMatrix& damping_laplacian() const { return ld_; }
  bool has_tension_damping() const { return ld_.nonZeros() > 0; }
  /// Springs (u- and v-edges) with s_e, l_e, c_e.
  const std::vector<Spring>& springs() const { return springs_; }
  /// Sorted flat indices of fixed particles; is_fixed(p) for lookup.
  const std::vector<int>& fixed() const { return fixed_; }
  bool is_fixed(int p) const { return fixed_mask_[static_cast<std::size_t>(p)] != 0; }
  /// Whether fixed particles move (`[[constraints.motion]]`, Scene::motions).
  bool has_prescribed_motion() const { return !prescribed_.empty(); }
  /// Calls f(p, x, v) for every moving fixed particle p with its prescribed
  /// position x [m] and velocity v [m/s] at time t [s]: its rest position
  /// moved by its motion's pose (KeyframedMotion). No allocation.
  template <class F>
  void ForEachPrescribed(double t, F&& f) const {
    for (const Prescribed& g : prescribed_) {
      const ObstaclePose pose = g.motion.PoseAt(t);
      for (int p : g.particles) {
        const Vector3 x = pose.ToWorld(rest_.row(p).transpose());
        f(p, x, pose.Velocity(x));
      }
    }
  }
  /// Sets the rows of the moving fixed particles of x [m] and v [m/s] (N×3)
  /// to their prescribed state at t [s] (ForEachPrescribed).
  void Prescribe(double t, MatrixN3* x, MatrixN3* v) const {
    ForEachPrescribed(t, [&](int p, const Vector3& xp, const Vector3& vp) {
      x->row(p) = xp.transpose();
      v->row(p) = vp.transpose();
    });
  }
  /// The rest geometry of the cloth's stencils: the grid's spacings, the
  /// node areas and, on a curvilinear pattern, its rest samples
  /// (CentreRestAt gives a node's).
  const GridGeometry& geometry() const { return geo_; }
  /// Obstacles of the scene (docs/model.md §7); empty: no detection at all.
  const std::vector<Obstacle>& obstacles() const { return obstacles_; }
  /// The force of the thesis' virtual particles (model/virtual_springs.h),
  /// one of terms(), or nullptr if no obstacle asks for them. Its topology
  /// is per-step state that their detection sets before every step
  /// (collision/virtual_particles.h, VirtualParticles::Of), so the pointer
  /// is not const although the system is.
  VirtualSprings* virtual_springs() const { return virtual_; }
  /// The explicit terms in evaluation order.
  const std::vector<std::unique_ptr<ForceTerm>>& terms() const { return terms_; }
  std::vector<std::string> TermNames() const;

  /// g = Σ explicit terms (F_nl, shear, bend, transverse, external) at (t,x,v).
  /// @param x,v N×3 [m], [m/s]; @param g N×3 [N], overwritten. No allocation.
  void ExplicitForces(double t, const MatrixN3& x, const MatrixN3& v, MatrixN3* g) const;
  /// Total force f = −L_K x − L_D v + g (3.20). @param f N×3 [N], overwritten.
  void Forces(double t, const MatrixN3& x, const MatrixN3& v, MatrixN3* f) const;
  /// Exact sparse Jacobians of the total force, 3N×3N with index 3p + c:
  /// ∂f/∂x [N/m] and ∂f/∂v [N s/m] as triplets (duplicates sum). The triplet
  /// pattern is independent of the state.
  void ForceJacobian(double t, const MatrixN3& x, const MatrixN3& v, std::vector<Triplet>* dfdx,
                     std::vector<Triplet>* dfdv) const;

  /// Prepares ParticleForce (each term's per-particle lists, built once;
  /// thread safe). Vertex-block methods (peers/vbd.h) call it.
  void PrepareParticleForces() const;
  /// The total force on particle p and the diagonal blocks of its Jacobian:
  /// f = −(L_K x)_p − (L_D v)_p + g_p(t, x, v) [N], dfdx = ∂f_p/∂x_p [N/m],
  /// dfdv = ∂f_p/∂v_p [N s/m] (3.19, 3.20; the blocks (p, p) of
  /// ForceJacobian), overwritten. Needs PrepareParticleForces; no
  /// allocation; concurrent calls for different p are safe.
  /// @param t [s]; @param x, v N×3 [m], [m/s]; @param p particle index
  void ParticleForce(double t, const MatrixN3& x, const MatrixN3& v, int p, Vector3* f, Matrix3* dfdx,
                     Matrix3* dfdv) const;
  /// The particle graph of the force: q is a neighbour of p (and p of q)
  /// if f_p reads x_q or v_q, i.e. ForceJacobian has a block (p, q) or
  /// (q, p), p ≠ q. Sorted lists in compressed form: the neighbours of p
  /// are neighbours[offsets[p] … offsets[p + 1]). Built on each call.
  void ParticleGraph(std::vector<int>* offsets, std::vector<int>* neighbours) const;

  /// Energies and momentum of (x, v). The tension is that of the base
  /// springs; with virtual particles the springs they split have the
  /// energy VirtualSprings::TensionEnergyChange adds, for the topology
  /// of the state it was computed at (the run driver's guard and the
  /// frames add it; model/trajectory.h). Tension, shear and gravity are exact
  /// potentials of their forces. The bending value is the normal-curvature
  /// energy of (2.25)/(2.26) evaluated with the discrete second differences;
  /// the projected bending forces (Alg. 3/4) are not its exact gradient, so
  /// energy balances that must close exactly are checked without bending.
  EnergyBreakdown Energies(const MatrixN3& x, const MatrixN3& v) const;

  /// True if the scene has non-conservative external forces (wind, air),
  /// whose work the run driver integrates.
  bool has_external_work() const { return external_terms_.size() > 0; }
  /// f += the non-conservative external forces (wind, air) at (t, x, v).
  void AddExternalForces(double t, const MatrixN3& x, const MatrixN3& v, MatrixN3* f) const;

 private:
  // The rest positions, masses and springs of a curvilinear pattern.
  void CurvilinearCloth(const Scene& scene);
  Scene scene_;
  int n_ = 0;
  MatrixN3 rest_;
  Eigen::VectorXd mass_;
  std::vector<Spring> springs_;
  SparseMatrix lk_, ld_;
  std::vector<int> fixed_;
  std::vector<char> fixed_mask_;
  std::vector<std::unique_ptr<ForceTerm>> terms_;
  std::vector<const ForceTerm*> external_terms_;  // wind, air (owned by terms_)
  std::vector<Obstacle> obstacles_;
  struct Prescribed {
    std::vector<int> particles;
    KeyframedMotion motion;
  };
  std::vector<Prescribed> prescribed_;  // Scene::motions
  VirtualSprings* virtual_ = nullptr;  // owned by terms_
  GridGeometry geo_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_MODEL_PARTICLE_SYSTEM_H_
