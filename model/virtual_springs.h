// The force of the thesis' virtual particles (thesis §5.4; docs/model.md,
// "Virtual particles"): the springs they split, as one explicit term of the
// model. Where an obstacle's edges pass through the cloth, points on those
// edges are inserted into the cloth's triangles for one step
// (collision/virtual_particles.h finds them). They are not integrated:
// their positions come from the obstacle, their velocities are the
// obstacle's. The ones on cloth edges that are tension springs replace a
// base particle's neighbour in that spring, with the rest length split in
// proportion to the current segment lengths (§5.4):
//
//   an edge P_a P_b with rest length r, split by V_1 … V_k, gives P_a the
//   neighbour V_1 and P_b the neighbour V_k, with rest lengths
//   r_j = r l_j / Σ_i l_i, l_0 = |V_1 − P_a|, …, l_k = |P_b − V_k|.
//
// No force acts on a virtual particle (its reaction is the rigid
// obstacle's) and bending and shear keep the base particles, as in the
// thesis. The spring keeps its constants s_e and c_e, as the thesis
// replaces only the neighbour's position and velocity and the rest length.
//
// The force enters the model as one more explicit term: the virtual
// spring's force minus the original spring's (its linear part −L_K x −
// L_D v and its F_nl), so the model's L_K, L_D and A_α's factor do not
// change (a solver that keeps the linear part implicit moves the split
// springs' couplings out of its matrix for the step: RemovedCoupling). That
// difference, s (x_V − x_q) + c (v_V − v_q) − s (r_j d̂_V − l d̂) on P_p
// (q the replaced neighbour), does not depend on x_p's linear part, and
// its stiffness is s_e, that of F_nl, which every IMEX method already
// takes explicitly.
#ifndef CLOTHBENCH_MODEL_VIRTUAL_SPRINGS_H_
#define CLOTHBENCH_MODEL_VIRTUAL_SPRINGS_H_

#include <memory>
#include <string_view>
#include <vector>

#include "model/force_terms.h"
#include "model/types.h"

namespace clothbench {

/// One virtual particle of the current step (§5.2–5.3).
struct VirtualParticle {
  Vector3 x = Vector3::Zero();  ///< position on the obstacle edge at the update's time [m]
  Vector3 v = Vector3::Zero();  ///< the obstacle's velocity there [m/s]
  int obstacle = 0;             ///< index into ParticleSystem::obstacles()
  int edge = 0;                 ///< the obstacle edge it lies on (Obstacle::Edges); −1 for a crossing RefinedMesh adds
  /// The cloth edge it lies on, particles a < b; −1, −1 if it lies inside
  /// the triangle `face` (an obstacle vertex through the cloth: shown, no force).
  int a = -1, b = -1;
  int face = 0;                 ///< the cloth triangle it was found in (GridTriangles)
  double s = 0.0;               ///< its projection's place on the cloth edge: (1 − s) x_a + s x_b
  /// Its projection V̄ on the cloth [m]: (1 − s) x_a + s x_b on an edge, the
  /// projected point inside the face otherwise.
  Vector3 bar = Vector3::Zero();
};

/// A base particle's tension spring with a virtual neighbour (§5.4).
struct VirtualSpring {
  int spring = 0;             ///< index into ParticleSystem::springs()
  int p = 0, q = 0;           ///< the base particle and the neighbour that is replaced
  int neighbour = 0;          ///< index of the virtual particle that replaces q
  double rest = 0.0;          ///< r_j [m]
};

/// A spring whose ends both have virtual neighbours (§5.4): the coupling
/// of a and b that the linear part −L_K x − L_D v holds and the virtual
/// springs remove. A solver that keeps the linear part implicit removes it
/// from its matrix (L_K(a, b) += s, L_D(a, b) += c) and adds the same
/// products back to the explicit terms, in which this term subtracts them
/// (StepEngine does; the force itself is unchanged).
struct RemovedCoupling {
  int spring = 0;  ///< index into ParticleSystem::springs()
  int a = 0, b = 0;
  double stiffness = 0.0;  ///< s_e [N/m]
  double damping = 0.0;    ///< c_e [N s/m]
};

/// The virtual springs' force correction as an explicit term. Its topology
/// is per-step state that the virtual particles' detection sets
/// (collision/virtual_particles.h, VirtualParticles::Update): the points
/// it found (points()), then SplitSprings; every force evaluation until
/// the next update uses it. Without an update there is no force.
class VirtualSprings : public ForceTerm {
 public:
  /// @param grid_nu, grid_nv the cloth grid; @param springs the model's springs
  /// @param split_tension true if the tension has the split F_nl (rest
  ///        lengths), false for the linear model (docs/model.md §2.1)
  VirtualSprings(int grid_nu, int grid_nv, const std::vector<Spring>& springs, bool split_tension);
  ~VirtualSprings() override;

  /// Forgets the topology: no virtual particles, no force.
  void ClearTopology();
  /// The points of the update under way (the detection appends them,
  /// found from both faces of a cloth edge or several times inside a face),
  /// and after SplitSprings the virtual particles.
  std::vector<VirtualParticle>& points() { return particles_; }
  /// §5.4: keeps one point per (cloth edge, obstacle edge) and per point
  /// inside a face, orders the points of each cloth edge from a to b and
  /// splits the springs at the N×3 positions x [m] of time t [s].
  void SplitSprings(double t, const MatrixN3& x);
  /// The index of the virtual particle that candidate c (as found in a
  /// face) became, −1 if none.
  int Find(const VirtualParticle& c) const;

  const std::vector<VirtualParticle>& particles() const { return particles_; }
  const std::vector<VirtualSpring>& virtual_springs() const { return sides_; }
  /// The tension energy of the virtual springs minus that of the springs
  /// they replace, at positions x [m] (virtual particles where the update
  /// put them) [J]: ½ s (|x_V − x_p| − r_j)² per side against ½ s (|d| − l)²
  /// per split spring (without the rest lengths for the linear model).
  double TensionEnergyChange(const MatrixN3& x) const;
  /// The springs split this step, once each.
  const std::vector<RemovedCoupling>& removed_couplings() const { return couplings_; }
  /// g.row(a) += s x.row(b) + c v.row(b) and the same with a and b swapped,
  /// for every removed coupling: the explicit terms of a solver whose
  /// implicit matrix has the couplings removed. @param x, v, g N×3
  void AddRemovedCouplings(const MatrixN3& x, const MatrixN3& v, MatrixN3* g) const;
  /// out.row(a) += w x.row(b) and the same with a and b swapped, with w = s
  /// (stiffness) or c (damping): (ΔL x) for the removed couplings, ΔL(a, b) = w.
  void AddCouplingProduct(bool damping, const MatrixN3& x, MatrixN3* out) const;

  /// What finds the points: the detection of collision/ (VirtualParticles),
  /// which this term owns once it is attached, so that every entry point
  /// that holds the model reaches the same one.
  class Detection {
   public:
    virtual ~Detection() = default;
  };
  Detection* detection() const { return detection_.get(); }
  void Attach(std::unique_ptr<Detection> detection) { detection_ = std::move(detection); }

  // ForceTerm: the virtual springs' force minus the original springs'.
  std::string_view name() const override { return "virtual_springs"; }
  void AddForce(double t, const MatrixN3& x, const MatrixN3& v, MatrixN3* f) const override;
  void AddJacobian(double t, const MatrixN3& x, const MatrixN3& v, std::vector<Triplet>* dfdx,
                   std::vector<Triplet>* dfdv) const override;
  bool depends_on_velocity() const override { return damped_; }
  void JacobianBlocks(std::vector<BlockPair>* blocks) const override;
  std::size_t jacobian_items() const override { return springs_.size(); }
  void AccumulateJacobian(double t, const MatrixN3& x, const MatrixN3& v, const int* pos, double* dfdx,
                          double* dfdv, std::size_t first, std::size_t last) const override;
  void PrepareParticleForces(int) const override {}  // the lists are built by SplitSprings
  void AddParticleForce(double t, const MatrixN3& x, const MatrixN3& v, int p, Vector3* f, Matrix3* dfdx,
                        Matrix3* dfdv) const override;

 private:
  /// The virtual particle `k`'s position at time t [s] (it moves with the obstacle) [m].
  Vector3 PositionAt(int k, double t) const;
  /// Side `k`'s force correction on its particle p and its blocks
  /// ∂/∂x_p, ∂/∂x_q (∂/∂v_q is −c I).
  void SideTerms(const VirtualSpring& side, double t, const MatrixN3& x, const MatrixN3& v, Vector3* f,
                 Matrix3* dp, Matrix3* dq) const;

  int nu_ = 0;
  std::vector<Spring> springs_;
  std::vector<int> u_spring_, v_spring_;  // spring index of the u-/v-edge starting at particle p, −1 if none
  bool split_ = true, damped_ = false;
  double t_update_ = 0.0;  // the time of the last SplitSprings
  std::vector<VirtualParticle> particles_;
  std::vector<VirtualSpring> sides_;
  std::vector<RemovedCoupling> couplings_;
  std::vector<int> spring_side_;  // 2 per spring: the side of P_a, of P_b (index into sides_), −1
  std::vector<int> first_side_, next_side_;  // sides of each particle, a linked list
  std::unique_ptr<Detection> detection_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_MODEL_VIRTUAL_SPRINGS_H_
