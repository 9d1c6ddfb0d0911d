// The full (tangent) system of the fully implicit methods' Newton iteration
// and of the Baraff–Witkin step (docs/model.md §10; Baraff & Witkin 1998, eq. 18):
//   J_α = M − αh ∂f/∂v − α²h² ∂f/∂x,
// a 3N×3N matrix with interleaved index 3p + c, on a fixed sparsity pattern
// (3×3 blocks per particle pair), refreshed in place.
#ifndef CLOTHBENCH_SOLVER_TANGENT_H_
#define CLOTHBENCH_SOLVER_TANGENT_H_

#include <vector>

#include "model/block_scatter.h"
#include "model/particle_system.h"

namespace clothbench {

// TangentProjection (model/scene.h): how the spring blocks treat
// compression. The exact spring Jacobian (docs/model.md §2.1) is
// s_e[(1 − l_e/|d|)(I − d̂d̂ᵀ) + d̂d̂ᵀ]; its transverse factor (1 − l_e/|d|)
// is negative for a compressed spring, which makes ∂f/∂x indefinite. kClamp
// uses max(0, 1 − l_e/|d|) (Choi & Ko 2002; Blender's implicit_blender.cc
// drops the Jacobian of compressed springs); kNone is the exact Jacobian.

struct TangentOptions {
  TangentProjection projection = TangentProjection::kClamp;
  /// true: the Jacobians of the explicit stencil terms (shear, bending,
  /// transverse contraction, wind, air; exact, in closed form) enter J_α;
  /// false: only tension (springs and their damping) and the mass.
  bool include_explicit_terms = true;
  /// true: store the symmetric part (J_α + J_αᵀ)/2, the matrix a conjugate
  /// gradient solver needs. J_α is exactly symmetric for tension, shear and
  /// bending (∂f/∂x of a potential, linear damping); the transverse
  /// contraction and the air forces are not potential forces and make it
  /// slightly non-symmetric (measured relative asymmetry 4e-7 … 4e-5 on the
  /// thesis scenes, verify/tangent_test.cc). A Newton iteration with the
  /// symmetric part still converges to the exact solution (its residual is
  /// the exact one), at a linear rate of the order of that asymmetry.
  bool symmetrize = false;
};

/// J_α on a fixed pattern. Update() recomputes the values in place from the
/// closed-form Jacobian blocks of the springs and the force terms
/// (ForceTerm::AccumulateJacobian), accumulated straight into the pattern
/// through value positions computed once: no triplets, no sorting, no
/// allocation; threaded and bit-identical for any thread count.
class TangentSystem {
 public:
  /// Builds the pattern from the blocks of the scene's terms (allocates).
  TangentSystem(const ParticleSystem& system, const TangentOptions& options);

  /// J_α at the state (t, x, v) for the product αh [s].
  /// @param x, v N×3 positions [m] and velocities [m/s].
  void Update(double t, const MatrixN3& x, const MatrixN3& v, double alpha_h);

  /// J_α for another αh [s] with the force Jacobians of the last Update
  /// (one pass over the entries; CVODE's γ changes without a Jacobian
  /// evaluation). No allocation.
  void SetAlphaH(double alpha_h);
  /// The αh of the current matrix [s].
  double alpha_h() const { return alpha_h_; }
  /// Adds d_p [kg] to the three diagonal entries of each particle p (a
  /// term of the Newton matrix that is not a force Jacobian: the hybrid
  /// contact's friction, sundials/hybrid_contact.h). SetAlphaH and Update
  /// overwrite it. @param d N values. No allocation.
  void AddToDiagonal(const Eigen::VectorXd& d);

  /// out += cx (∂f/∂x) u + cv (∂f/∂v) w with the force Jacobians of the last
  /// Update (as assembled: clamped if so, not symmetrised).
  /// @param u, w, out N×3 (row p, column c is entry 3p + c). No allocation.
  void AddJacobianProducts(double cx, const MatrixN3& u, double cv, const MatrixN3& w, MatrixN3* out) const;

  /// The 3N×3N matrix [kg], column-major, both triangles stored.
  const SparseMatrix& matrix() const { return j_; }
  const TangentOptions& options() const { return options_; }

 private:
  const ParticleSystem& sys_;
  TangentOptions options_;
  SparseMatrix j_;
  // ∂f/∂x [N/m] and ∂f/∂v [N s/m] on j_'s pattern in row storage (entry e
  // of column j, row i of j_'s arrays holds ∂f_j/∂x_i: a force term's
  // blocks of one row particle lie together). kv_ is empty when
  // nothing depends on v, and constant (the springs' damping, set once) when
  // no explicit term in J_α depends on v.
  Eigen::VectorXd kx_, kv_;
  bool kv_constant_ = true;
  // M − αh ∂f/∂v with a constant ∂f/∂v (symmetrised if so) for base_alpha_h_:
  // what J_α adds to −α²h² ∂f/∂x, kept while αh does not change.
  Eigen::VectorXd base_;
  double base_alpha_h_ = -1.0;
  double alpha_h_ = -1.0;
  // Adds spring k's stiffness blocks at x to kx (and its damping blocks to
  // kv if not null).
  void AddSpring(std::size_t k, const MatrixN3& x, double* kx, double* kv) const;
  bool linear_tension_ = false;  // tension_model = "linear": zero rest length
  std::vector<const ForceTerm*> terms_;      // the explicit terms that enter J_α
  std::vector<std::vector<int>> term_pos_;   // their block positions
  std::vector<int> spring_pos_;              // 4 blocks per spring
  // The fused sweep: chunks of chunk_ particles; chunk k holds the springs
  // spring_order_[spring_begin_[k] … spring_begin_[k+1]) (by their end a)
  // and items item_begin_[t][k] … item_begin_[t][k+1] of term t.
  std::size_t chunk_ = 0;
  std::vector<std::size_t> spring_begin_, spring_order_;
  std::vector<std::vector<std::size_t>> item_begin_;
  ChunkColouring colouring_;
  std::vector<int> diag_pos_;                // value index of each diagonal entry (3p + c)
  std::vector<int> transpose_pos_;           // value index of (j, i) for the entry (i, j)
  // The symmetric part's pass over the entries. Without ∂f/∂v (kv_ empty) base_ is the diagonal mass only: the pass
  // skips it (kBase false) and the masses are added after.
  template <bool kVelocity, bool kBase>
  void SymmetricPass(double hx, double hv, const double* kvar);
};

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_TANGENT_H_
