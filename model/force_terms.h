// Force terms of the particle model (docs/model.md §2). The particle system assembles
// only the terms a scene needs (docs/model.md §2.6): a term with zero coefficients is
// never constructed, so it costs nothing per step.
#ifndef CLOTHBENCH_MODEL_FORCE_TERMS_H_
#define CLOTHBENCH_MODEL_FORCE_TERMS_H_

#include <memory>
#include <string_view>
#include <vector>

#include "model/scene.h"
#include "model/types.h"

namespace clothbench {

/// One explicit force term g_k(t, x, v) of the split ODE (3.20).
class ForceTerm {
 public:
  virtual ~ForceTerm() = default;
  /// Short stable name, e.g. "tension_nonlinear", "shear", "bend_thin_plate".
  virtual std::string_view name() const = 0;
  /// f += g_k(t, x, v).
  /// @param t time [s]; @param x N×3 positions [m]; @param v N×3 velocities [m/s]
  /// @param f N×3 forces [N], accumulated into. Does not allocate.
  virtual void AddForce(double t, const MatrixN3& x, const MatrixN3& v, MatrixN3* f) const = 0;
  /// Appends the exact Jacobian of g_k, in closed form: ∂g/∂x [N/m] and
  /// ∂g/∂v [N s/m] as 3N×3N triplets with interleaved index 3p + c.
  /// Duplicates are to be summed. The triplet pattern does not depend on
  /// (t, x, v), so a sparse factorisation can keep its symbolic analysis.
  virtual void AddJacobian(double t, const MatrixN3& x, const MatrixN3& v, std::vector<Triplet>* dfdx,
                           std::vector<Triplet>* dfdv) const = 0;
  /// The same Jacobian by forward-mode automatic differentiation of the
  /// force kernel (Eigen's AutoDiffScalar), on the same triplet pattern: the
  /// test oracle of the closed forms. Terms whose force is written by hand
  /// (springs, gravity) return their closed form.
  virtual void AddJacobianAutoDiff(double t, const MatrixN3& x, const MatrixN3& v, std::vector<Triplet>* dfdx,
                                   std::vector<Triplet>* dfdv) const {
    AddJacobian(t, x, v, dfdx, dfdv);
  }
  /// True if g_k depends on v (damping, air): AccumulateJacobian then writes
  /// ∂g/∂v.
  virtual bool depends_on_velocity() const = 0;
  /// A force independent of t, x and v (gravity): its N×3 values [N], so
  /// that a sum can start from them instead of from zero; nullptr otherwise.
  virtual const MatrixN3* constant_force() const { return nullptr; }
  /// Appends the (row particle, column particle) pairs of the 3×3 blocks
  /// that AccumulateJacobian writes, item by item (stencil centres in
  /// particle order, springs), the same number per item. Fixed for the term.
  virtual void JacobianBlocks(std::vector<BlockPair>* blocks) const = 0;
  /// The number of items whose blocks JacobianBlocks lists.
  virtual std::size_t jacobian_items() const = 0;
  /// Adds the blocks of items [first, last) of ∂g/∂x into `dfdx` and, if
  /// depends_on_velocity(), of ∂g/∂v into `dfdv`: value arrays of a
  /// compressed row-major 3N×3N matrix, block k of JacobianBlocks() at
  /// row positions pos[3k … 3k+2] (BlockPositions, AddBlock). Closed form, serial (the
  /// caller runs item ranges that write disjoint rows on its threads); no
  /// allocation. @param t [s]; @param x, v N×3 [m], [m/s]
  virtual void AccumulateJacobian(double t, const MatrixN3& x, const MatrixN3& v, const int* pos, double* dfdx,
                                  double* dfdv, std::size_t first, std::size_t last) const = 0;
  /// Builds, once, the lists of the items that write each particle, which
  /// AddParticleForce reads (vertex-block methods, peers/vbd.h, call it;
  /// other methods never pay for the lists). Thread safe.
  /// @param num_particles N
  virtual void PrepareParticleForces(int num_particles) const = 0;
  /// The force of this term on particle p and the diagonal blocks of its
  /// Jacobian: f += g_k,p(t, x, v) [N], dfdx += ∂g_k,p/∂x_p [N/m] and, if
  /// depends_on_velocity(), dfdv += ∂g_k,p/∂v_p [N s/m]: row p of AddForce
  /// and block (p, p) of AccumulateJacobian, from the items that write p
  /// (summed in item order, so f may differ from AddForce's row in the last
  /// bits). Needs PrepareParticleForces; no allocation; concurrent calls
  /// for different p are safe. @param x, v N×3 [m], [m/s]
  virtual void AddParticleForce(double t, const MatrixN3& x, const MatrixN3& v, int p, Vector3* f, Matrix3* dfdx,
                                Matrix3* dfdv) const = 0;
};

/// One spring of the tension model (docs/model.md §2.1): a u- or v-edge.
struct Spring {
  int a = 0, b = 0;           ///< particle indices
  double stiffness = 0.0;     ///< s_e = k_u lv/lu (u-edge) or k_v lu/lv [N/m]
  double rest_length = 0.0;   ///< l_e [m]
  double damping = 0.0;       ///< c_e = d_t lv/lu or d_t lu/lv [N s/m]
};

/// Per-particle data the stencil terms need.
struct GridGeometry {
  int nu = 0, nv = 0;
  double lu = 0.0, lv = 0.0;       ///< rest spacings [m] of a uniform grid
  Eigen::VectorXd area;            ///< node areas [m²] (m_p/ρ)
  /// The cloth of patterns (Scene::cloth): every stencil then takes its
  /// particles and rest geometry from its blocks (docs/model.md §2.7–2.8);
  /// null: the uniform nu × nv grid of lu, lv.
  std::shared_ptr<const ClothLayout> cloth;
  bool curvilinear() const { return cloth != nullptr; }
};

/// The rest geometry of the stencil centred on node (i, j) of a grid
/// (docs/model.md §2.7). The chords run between the node's u- and
/// v-neighbours; a missing neighbour (the border) is the node itself.
struct CentreRest {
  double du = 0.0, dv = 0.0;  ///< |X_r − X_l|, |X_u − X_d| [m]; uniform: lu·c_u, lv·c_v
  /// The node's cell area |(X_r − X_l)/c_u × (X_u − X_d)/c_v| [m²] (c_u, c_v
  /// the neighbours present along u, v); uniform: lu·lv at every node.
  double area = 0.0;
  /// The rest shear γ₀ = ⟨X_r − X_l, X_u − X_d⟩/(du dv), the cosine of the
  /// rest angle between the threads; uniform: 0.
  double gamma0 = 0.0;
};
/// CentreRest of node (i, j), 0 ≤ i < nu, 0 ≤ j < nv, of a uniform `geo`.
CentreRest CentreRestAt(const GridGeometry& geo, int i, int j);
/// CentreRest of node (i, j) of a pattern's block, from its frame's rest
/// positions (across a seam, the other side's nodes).
CentreRest CentreRestAt(const ClothBlock& block, int i, int j);

/// Calls f(block, i, j, p) for every stencil centre of `cloth` in order:
/// each block's nodes that own their stencils (ClothBlock::owner), row by
/// row, p the node's particle.
template <class F>
void ForEachCentre(const ClothLayout& cloth, F&& f) {
  for (const ClothBlock& b : cloth.blocks)
    for (int j = 0; j < b.nv; ++j)
      for (int i = 0; i < b.nu; ++i)
        if (b.owner[static_cast<std::size_t>(i + b.nu * j)]) f(b, i, j, b.At(i, j));
}

/// The shear and bending energies [J] of x (N×3 [m]) on the curvilinear
/// pattern of `geo` (docs/model.md §2.7): Σ ½ μ (γ − γ₀)² A and
/// Σ ½ A (B_u ⟨s_uu, n̂⟩² + B_v ⟨s_vv, n̂⟩²), the second differences with
/// each node's rest spacings (ParticleSystem::Energies on such a pattern).
/// @param mu μ [N/m]; @param bu, bv B_u, B_v
void CurvilinearEnergies(const GridGeometry& geo, double mu, double bu, double bv, const MatrixN3& x, double* shear,
                         double* bending);

/// F_nl = −s_e l_e d/|d| per spring: the explicit part of the IMEX split of
/// tension (docs/model.md §2.1; thesis §3.3.3, Desbrun et al.).
std::unique_ptr<ForceTerm> MakeTensionNonlinear(std::vector<Spring> springs, int num_particles);
/// Gravity m_p g (§2.6).
std::unique_ptr<ForceTerm> MakeGravity(const Eigen::VectorXd& masses, const Vector3& g);
/// Shear in energy form E_s = Σ ½ μ (γ − γ₀)² A (A = lu lv on a uniform grid) with viscosity d_s γ̇ (docs/model.md §2.2, (2.16), (2.21)).
std::unique_ptr<ForceTerm> MakeShear(const GridGeometry& geo, double mu, double damping);
/// Membrane bending F = ⟨B_u s_uu + B_v s_vv + d_b Δv, N⟩N lu lv (docs/model.md §2.3, (2.25), Alg. 3).
std::unique_ptr<ForceTerm> MakeMembraneBend(const GridGeometry& geo, double bu, double bv, double damping);
/// Thin-plate bending F = −⟨B_u s_uuuu + (B_u+B_v) s_uuvv + B_v s_vvvv + d_b Δ²v, N⟩N lu lv
/// (docs/model.md §2.3, (2.26), Alg. 4).
std::unique_ptr<ForceTerm> MakeThinPlateBend(const GridGeometry& geo, double bu, double bv, double damping);
/// Transverse contraction σ_11 += C ε_22, σ_22 += C ε_11 (docs/model.md §2.4, (2.22), Alg. 5).
std::unique_ptr<ForceTerm> MakeTransverse(const GridGeometry& geo, double c1122);
/// Wind (2.35, 2.36).
std::unique_ptr<ForceTerm> MakeWind(const GridGeometry& geo, const WindSpec& wind);
/// Air resistance (2.37): −c_air |⟨v,N⟩| v/|v| per area.
std::unique_ptr<ForceTerm> MakeAirResistance(const GridGeometry& geo, double c_air);

}  // namespace clothbench

#endif  // CLOTHBENCH_MODEL_FORCE_TERMS_H_
