// The full (tangent) system of the fully implicit methods' Newton iteration
// and of the Baraff–Witkin step (SPEC §11; Baraff & Witkin 1998, eq. 18):
//   J_α = M − αh ∂f/∂v − α²h² ∂f/∂x,
// a 3N×3N matrix with interleaved index 3p + c, on a fixed sparsity pattern
// (3×3 blocks per particle pair), refreshed in place.
#ifndef CLOTHBENCH_SOLVER_TANGENT_H_
#define CLOTHBENCH_SOLVER_TANGENT_H_

#include <vector>

#include "model/particle_system.h"

namespace clothbench {

// TangentProjection (model/scene.h): how the spring blocks treat
// compression. The exact spring Jacobian (SPEC §2.1) is
// s_e[(1 − l_e/|d|)(I − d̂d̂ᵀ) + d̂d̂ᵀ]; its transverse factor (1 − l_e/|d|)
// is negative for a compressed spring, which makes ∂f/∂x indefinite. kClamp
// uses max(0, 1 − l_e/|d|) (Choi & Ko 2002; Blender's implicit_blender.cc
// drops the Jacobian of compressed springs); kNone is the exact Jacobian.

struct TangentOptions {
  TangentProjection projection = TangentProjection::kClamp;
  /// true: the Jacobians of the explicit stencil terms (shear, bending,
  /// transverse contraction, wind, air; exact, by AutoDiff) enter J_α;
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

/// J_α on a fixed pattern. Update() recomputes the values in place and does
/// not allocate (triplet buffers keep their capacity).
class TangentSystem {
 public:
  /// Builds the pattern from the scene's terms (allocates).
  TangentSystem(const ParticleSystem& system, const TangentOptions& options);

  /// J_α at the state (t, x, v) for the product αh [s].
  /// @param x, v N×3 positions [m] and velocities [m/s].
  void Update(double t, const MatrixN3& x, const MatrixN3& v, double alpha_h);

  /// out += cx (∂f/∂x) u + cv (∂f/∂v) w with the force Jacobians of the last
  /// Update (as assembled: clamped if so, not symmetrised).
  /// @param u, w, out N×3 (row p, column c is entry 3p + c). No allocation.
  void AddJacobianProducts(double cx, const MatrixN3& u, double cv, const MatrixN3& w, MatrixN3* out) const;

  /// The 3N×3N matrix [kg], column-major, both triangles stored.
  const SparseMatrix& matrix() const { return j_; }
  const TangentOptions& options() const { return options_; }

 private:
  // Appends ∂f/∂x and ∂f/∂v of every included term, in a fixed order.
  void Collect(double t, const MatrixN3& x, const MatrixN3& v);

  const ParticleSystem& sys_;
  TangentOptions options_;
  SparseMatrix j_;
  std::vector<Triplet> dfdx_, dfdv_;   // reused buffers (capacity kept)
  std::vector<int> pos_x_, pos_v_;     // value index in j_ of each triplet
  std::vector<int> diag_pos_;          // value index of each diagonal entry (3p + c)
  std::vector<int> upper_pos_, lower_pos_;  // value indices of (i, j) and (j, i), i < j
};

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_TANGENT_H_
