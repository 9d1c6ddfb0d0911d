// Chebyshev semi-iterative acceleration of a fixed-iteration solver
// (Wang 2015, "A Chebyshev semi-iterative approach for accelerating
// projective and position-based dynamics", ACM TOG 34(6), Eq. 10–12; the
// same schedule is Vertex Block Descent's §3.8), shared by pd/chebyshev
// and vbd/chebyshev (docs/model.md §10).
#ifndef CLOTHBENCH_PEERS_CHEBYSHEV_H_
#define CLOTHBENCH_PEERS_CHEBYSHEV_H_

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include <Eigen/Core>

namespace clothbench {

/// The acceleration's settings: with u^k the iterate and û the plain
/// iteration's result from u^k,
///   u^{k+1} = ω_{k+1} (γ (û − u^k) + u^k − u^{k−1}) + u^{k−1},
///   ω = 1 for k < delay, ω = 2/(2 − ρ²) at k = delay, then ω ← 4/(4 − ρ² ω).
struct ChebyshevSettings {
  bool on = false;
  /// Spectral radius of the plain iteration, in [0, 1); 0: measured at the
  /// first step of each h (ChebyshevRho).
  double rho = 0.0;
  double gamma = 1.0;  ///< under-relaxation γ in (0, 1]
  int delay = 1;       ///< plain iterations before ω leaves 1 (Wang's S)
  /// Adaptive restart (O'Donoghue & Candès 2015, "Adaptive restart for
  /// accelerated gradient schemes", Found. Comput. Math. 15: the gradient
  /// scheme): when the plain iteration's increment ‖û − u^k‖ exceeds the one
  /// at which the acceleration (re)started, the iteration has lost all the
  /// progress the acceleration made; the step then keeps the plain result û,
  /// and ω starts again from 1 after `delay` plain iterations. Chebyshev's
  /// schedule bounds the error only for a spectrum in [−ρ, ρ]; a
  /// Gauss–Seidel iteration (VBD) has complex eigenvalues, and a ρ near 1
  /// measured from its increments lets a few modes grow (docs/model.md §10).
  /// The last iteration of a step keeps its plain result as well: no later
  /// sweep would show whether its extrapolation lost progress.
  bool restart = false;

  /// True if the settings are in their ranges (or the acceleration is off).
  bool valid() const { return !on || (rho >= 0.0 && rho < 1.0 && gamma > 0.0 && gamma <= 1.0 && delay >= 1); }
  /// The iterations of a k_max-iteration step that can take ω ≠ 1: those
  /// from `delay` on, less the last with the restart on (it keeps its plain
  /// result). With none, ρ is not used and need not be measured.
  int ExtrapolatedIterations(int k_max) const {
    return on ? std::max(0, k_max - delay - (restart ? 1 : 0)) : 0;
  }
  /// ω of iteration k (0-based) after ω = `omega` at k − 1, for ρ = `rho`.
  double Omega(int k, double rho_used, double omega) const {
    if (k < delay) return 1.0;
    return k == delay ? 2.0 / (2.0 - rho_used * rho_used) : 4.0 / (4.0 - rho_used * rho_used * omega);
  }
};

/// The noise level of ChebyshevRho for velocity iterates: an increment Δv
/// whose displacement h Δv is below 1e-13 of the positions x₀ (N×3
/// Frobenius norms) is round-off.
inline double VelocityNoise(double position_norm, double h) { return 1e-13 * position_norm / h; }

/// Plain iterations from which ChebyshevRho measures ρ.
inline constexpr int kChebyshevRhoIterations = 32;

/// The contraction ρ of a plain iteration from its increments
/// ‖u^{k+1} − u^k‖: the geometric mean of the ratios of consecutive
/// increments over the last half, leaving out increments at or below
/// `noise` (round-off of the state: a sheet at rest has increments of
/// 1e-17 whose ratios are near 1 and would make ω amplify round-off). An
/// iteration that has converged to round-off, or does not contract, gives
/// no usable ρ: 0 (ω then stays 1, and only γ's under-relaxation acts).
inline double ChebyshevRho(const std::vector<double>& increments, double noise) {
  double log_sum = 0.0;
  int count = 0;
  for (std::size_t k = increments.size() / 2; k < increments.size(); ++k)
    if (k > 0 && increments[k - 1] > noise && increments[k] > noise) {
      log_sum += std::log(increments[k] / increments[k - 1]);
      ++count;
    }
  const double rho = count > 0 ? std::exp(log_sum / count) : 0.0;
  return rho > 0.0 && rho < 1.0 ? rho : 0.0;
}

/// How a stepper measures ρ from the plain iterations of its first step
/// at each h.
enum class RhoEstimate {
  kIncrementRatio,  ///< ChebyshevRho on a fixed number of increment norms (a power iteration)
  kKrylov,          ///< KrylovRho on sketches of the increments
};

/// The spectral radius ρ of a plain iteration from its increments δ_k =
/// u^{k+1} − u^k, which a linear iteration u ← G u + c maps as δ_{k+1} =
/// G δ_k: the largest |λ| of G on the Krylov space the increments span,
/// by exact dynamic mode decomposition (Schmid 2010, J. Fluid Mech. 656,
/// §2.2; Tu et al. 2014, J. Comput. Dyn. 1(2), Alg. 2). The Ritz values
/// of a Krylov space reach the extreme eigenvalues in about the square
/// root of the iterations a power iteration needs: on the default scene at
/// h = 0.01 s, 96 VBD sweeps give 0.98392 where the increment ratio needs
/// 512 for 0.98397 (docs/model.md §10).
///
/// Each pair (δ_j, δ_{j+1}) is scaled by 1/‖δ_j‖ (the relation holds for
/// any scaling of a pair; it keeps the slowly decaying late increments
/// from being lost beside the first). Singular values of the scaled
/// snapshot matrix below 1e-6 of the largest are dropped (the iteration
/// is linear only to about that level: its first increments are
/// perturbations of 1e-4 of the spacing), and so are eigenvalues whose
/// mode carries under 1 % of the last increment (spurious modes of the
/// truncation). An eigenvalue at or above 1 is no contraction.
///
/// @param sketch p×m, column k a fixed selection of δ_k's coordinates
///   (p ≥ m; the same selection in every column)
/// @param m the columns in use (the first m), at least 3
/// @return ρ in (0, 1), or 0 if no eigenvalue qualifies (ω then stays 1)
double KrylovRho(const Eigen::MatrixXd& sketch, int m);

}  // namespace clothbench

#endif  // CLOTHBENCH_PEERS_CHEBYSHEV_H_
