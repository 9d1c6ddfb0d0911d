// Filtered preconditioned conjugate gradients (docs/model.md §5; thesis Alg. 7,
// Baraff & Witkin 1998, in the form of Ascher & Boxerman 2003) for
//   S (A v − b) = 0,   (I − S) v = z                                   (4.3)
// where S is the per-particle velocity filter and A is either
//   - an N×N SPD matrix applied to the three coordinate columns (A ⊗ I₃):
//     the thesis' A_α, on N×3 column-major data (MatrixN3), or
//   - a 3N×3N SPD matrix with interleaved index 3p + c: the tangent system
//     J_α of the Newton iteration and of Baraff–Witkin (solver/tangent.h),
//     on N×3 row-major data (MatrixN3R, whose storage is that 3N vector).
// Both are one algorithm, FilteredPcg over an operator (pcg.cc). The filter
// is solver/velocity_filter.h, the preconditioners solver/preconditioner.h.
#ifndef CLOTHBENCH_SOLVER_PCG_H_
#define CLOTHBENCH_SOLVER_PCG_H_

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <string_view>
#include <vector>

#include "model/solver_spec.h"
#include "model/types.h"
#include "solver/preconditioner.h"
#include "solver/velocity_filter.h"

namespace clothbench {



/// y ← A x for a symmetric N×N A applied to the three columns of x in one
/// pass over A (row j of A is its column j). Rows are split over the OpenMP
/// threads; every entry of y is summed in the same order whatever the
/// thread count, so the result is bit-for-bit reproducible.
/// @param a N×N symmetric, @param x, y N×3 (y must not alias x).
void SymmetricProduct(const SparseMatrix& a, const MatrixN3& x, MatrixN3* y);

/// ‖S_F b‖₂: the 2-norm of b over the particles not in `fixed` (the
/// reference of the PCG tolerance with CgReference::kFixedOnly, docs/model.md §5).
/// @param b N×3 (MatrixN3 or MatrixN3R) @param fixed particle indices
template <class M>
double FreeRowsNorm(const M& b, const std::vector<int>& fixed) {
  double sum = b.squaredNorm();
  for (int p : fixed) sum -= b.row(p).squaredNorm();
  return std::sqrt(std::max(sum, 0.0));
}

/// y ← J x for a symmetric 3N×3N J (interleaved index 3p + c) on the 3N
/// vectors stored in N×3 row-major matrices; reproducible like
/// SymmetricProduct. @param x, y N×3 row-major (y must not alias x).
void TangentProduct(const SparseMatrix& j, const MatrixN3R& x, MatrixN3R* y);

enum class PcgStatus { kConverged, kMaxIterations, kBreakdown, kNonFinite, kTimeLimit };
std::string_view ToString(PcgStatus s);

struct PcgOptions {
  double tolerance = 1e-6;  ///< η: stop when ‖r‖₂ ≤ η ‖S b‖₂ (2-norm over all 3N entries)
  int max_iterations = 1000;
  /// If ≥ 0: the norm η is relative to instead of ‖S b‖₂ [units of b]
  /// (the step engine passes ‖S_F b‖₂, see CgReference).
  double rhs_norm = -1.0;
  /// Absolute floor of the stopping threshold [units of b]: stop when
  /// ‖r‖₂ ≤ max(η ‖S b‖₂, residual_floor). The step engine passes the
  /// round-off of b (RoundOffFloor); 0: none.
  double residual_floor = 0.0;
};

/// The round-off of a right-hand side b = b₀ + βh g [units of b]:
/// 32 ε (‖b₀‖₂ + βh ‖g‖₂), with b₀_norm = ‖b₀‖₂ and hg_norm = βh ‖g‖₂.
/// Where the summands cancel, as the linear tension's h L_K x̂ in b₀ and the
/// nonlinear tension in g do on cloth at rest without external forces, ‖b‖
/// is itself this round-off (measured 2–8 ε (‖b₀‖ + βh‖g‖) on a 10×10 sheet
/// at h = 0.01–0.16 s), and a residual relative to ‖b‖ cannot fall below
/// it: every update needs PCG iterations, Alg. 6's "0 iterations" never
/// comes, and the step is rejected after max_updates. The factor 32 = 2⁵
/// covers the measured 8 and the sum of a few such vectors (the change of b
/// between two updates); it matters only where ‖b‖ < 32 ε (‖b₀‖ + βh‖g‖)/η,
/// 7·10⁻⁹ (‖b₀‖ + βh‖g‖) at η = 10⁻⁶ — never on a scene that moves or hangs
/// under gravity (there ‖b‖ ≥ m‖g_grav‖h, 5·10⁻⁵ of it on the default sheet).
inline double RoundOffFloor(double b0_norm, double hg_norm) {
  constexpr double kFactor = 32.0;
  return kFactor * std::numeric_limits<double>::epsilon() * (b0_norm + hg_norm);
}

struct PcgSummary {
  PcgStatus status = PcgStatus::kBreakdown;
  int iterations = -1;          ///< CG iterations; 0 if the guess already met the tolerance
  double residual_norm = -1.0;  ///< final ‖S(b − A v)‖₂ [units of b]
  double rhs_norm = -1.0;       ///< the norm the tolerance was relative to (‖S b‖₂ by default)
};

/// Scratch vectors of the PCG, allocated once for N particles.
/// @tparam Vec MatrixN3 (N×N systems) or MatrixN3R (3N×3N systems).
template <class Vec>
struct PcgWorkspaceT {
  explicit PcgWorkspaceT(int n = 0) { Resize(n); }
  void Resize(int n) {
    r.resize(n, 3);
    z.resize(n, 3);
    p.resize(n, 3);
    q.resize(n, 3);
  }
  Vec r, z, p, q;
};
using PcgWorkspace = PcgWorkspaceT<MatrixN3>;
using TangentPcgWorkspace = PcgWorkspaceT<MatrixN3R>;


/// Solves S(A v − b) = 0, (I − S) v = z by filtered PCG (the N×N path).
/// @param a       N×N SPD matrix [kg] (applied to the 3 columns)
/// @param b       N×3 right-hand side [kg m/s]
/// @param filter  constraints; empty means none (no projection is applied)
/// @param precond factorised preconditioner of `a`
/// @param v       N×3 [m/s]: initial guess in, solution out
/// @param work    scratch of size N (no allocation inside)
/// @return status, iterations and residual. Never throws.
PcgSummary FilteredPcg(const SparseMatrix& a, const MatrixN3& b, const VelocityFilter& filter,
                       const Preconditioner& precond, const PcgOptions& options, MatrixN3* v, PcgWorkspace* work);

/// The same filtered PCG on the 3N×3N tangent system (Newton iteration,
/// Baraff–Witkin).
/// @param j       3N×3N symmetric positive definite [kg], interleaved index 3p + c,
///                both triangles stored
/// @param b, v    N×3 row-major (3N vectors) [kg m/s], [m/s]
/// Same return, no allocation, never throws.
PcgSummary FilteredPcg(const SparseMatrix& j, const MatrixN3R& b, const VelocityFilter& filter,
                       const TangentPreconditioner& precond, const PcgOptions& options, MatrixN3R* v,
                       TangentPcgWorkspace* work);

}  // namespace clothbench

#endif  // CLOTHBENCH_SOLVER_PCG_H_
