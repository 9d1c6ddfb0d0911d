// Static equilibrium by Newton's method (chapter 2 experiments).
#include "solver/static_solve.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/SparseLU>
#include <fmt/format.h>

namespace clothbench {
namespace {

// Whether every force term has an exact potential (ParticleSystem::
// Energies): tension, shear and gravity do; bending, transverse
// contraction, wind and air do not.
bool Conservative(const ParticleSystem& sys) {
  for (const auto& t : sys.terms()) {
    const std::string_view name = t->name();
    if (name != "tension_nonlinear" && name != "shear" && name != "gravity") return false;
  }
  return true;
}

// Round-off floor of the force residual at positions `pos`: 256 ε times the
// larger of the largest single force contribution (L_K x, F_nl, bending, …)
// and max s_e·max|x| (a spring force inherits s_e times the round-off of
// the absolute positions) [N].
class RoundOffFloor {
 public:
  explicit RoundOffFloor(const ParticleSystem& sys)
      : sys_(sys), v_(MatrixN3::Zero(sys.num_particles(), 3)), term_(sys.num_particles(), 3) {
    for (const Spring& sp : sys.springs()) max_stiffness_ = std::max(max_stiffness_, sp.stiffness);
  }
  double operator()(const MatrixN3& pos) {
    term_.noalias() = sys_.stiffness_laplacian() * pos;
    double scale = std::max(term_.cwiseAbs().maxCoeff(), max_stiffness_ * pos.cwiseAbs().maxCoeff());
    for (const auto& t : sys_.terms()) {
      term_.setZero();
      t->AddForce(0.0, pos, v_, &term_);
      scale = std::max(scale, term_.cwiseAbs().maxCoeff());
    }
    return 256 * std::numeric_limits<double>::epsilon() * scale;
  }

 private:
  const ParticleSystem& sys_;
  MatrixN3 v_, term_;
  double max_stiffness_ = 0.0;
};

}  // namespace

StaticSummary SolveStatic(const ParticleSystem& sys, const std::vector<int>& constrained, const StaticOptions& opt,
                          MatrixN3* x) {
  const int n = sys.num_particles();
  // Map coordinates 3p + c to unknowns.
  std::vector<int> index(static_cast<std::size_t>(3 * n), -1);
  std::vector<char> held(static_cast<std::size_t>(3 * n), 0);
  for (int p : sys.fixed())
    for (int c = 0; c < 3; ++c) held[static_cast<std::size_t>(3 * p + c)] = 1;
  for (int k : constrained) held[static_cast<std::size_t>(k)] = 1;
  int m = 0;
  for (int k = 0; k < 3 * n; ++k)
    if (!held[static_cast<std::size_t>(k)]) index[static_cast<std::size_t>(k)] = m++;

  const MatrixN3 v = MatrixN3::Zero(n, 3);
  MatrixN3 f(n, 3), trial(n, 3);
  const double load = std::max(1e-300, (sys.masses() * sys.scene().forces.gravity.norm()).maxCoeff());
  auto residual = [&](const MatrixN3& pos, Eigen::VectorXd* r) {
    sys.Forces(0.0, pos, v, &f);
    r->resize(m);
    for (int k = 0; k < 3 * n; ++k)
      if (index[static_cast<std::size_t>(k)] >= 0) (*r)(index[static_cast<std::size_t>(k)]) = f(k / 3, k % 3);
  };

  StaticSummary s;
  const bool conservative = Conservative(sys);
  RoundOffFloor floor_at(sys);
  Eigen::VectorXd r, r_trial;
  residual(*x, &r);
  std::vector<Triplet> dfdx, dfdv, kt;
  Eigen::SparseLU<SparseMatrix> lu;

  // Levenberg–Marquardt shift λ = rel·max|K_ii|, adapted: ÷10 after a full
  // step, ×10 when the line search had to backtrack, ×100 and retry when it
  // failed (round-off in zero-stiffness directions is amplified by 1/λ).
  double rel = opt.shift;
  for (int it = 0; it < opt.max_iterations; ++it) {
    s.iterations = it;
    s.residual = r.cwiseAbs().maxCoeff();
    s.threshold = std::max(opt.tolerance * load, floor_at(*x));
    if (s.residual <= s.threshold) {
      s.converged = true;
      return s;
    }
    dfdx.clear();
    dfdv.clear();
    sys.ForceJacobian(0.0, *x, v, &dfdx, &dfdv);
    kt.clear();
    double diag = 0.0;
    for (const Triplet& e : dfdx) {
      const int a = index[static_cast<std::size_t>(e.row())], b = index[static_cast<std::size_t>(e.col())];
      if (a < 0 || b < 0) continue;
      kt.emplace_back(a, b, -e.value());  // K = −∂f/∂x
      if (a == b) diag = std::max(diag, std::abs(e.value()));
    }
    const std::size_t base = kt.size();
    bool accepted = false;
    for (int attempt = 0; attempt < 8 && !accepted; ++attempt) {
      kt.resize(base);
      for (int a = 0; a < m; ++a) kt.emplace_back(a, a, rel * diag);
      SparseMatrix k(m, m);
      k.setFromTriplets(kt.begin(), kt.end());
      k.makeCompressed();
      lu.compute(k);
      if (lu.info() != Eigen::Success) {
        rel *= 100.0;
        continue;
      }
      const Eigen::VectorXd dx = lu.solve(r);
      if (dx.allFinite() && dx.cwiseAbs().maxCoeff() <= opt.step_tolerance && s.residual <= 1e-6 * load) {
        s.converged = true;
        return s;
      }
      // Backtracking: Armijo on the energy when the forces have an exact
      // potential (it penalises stretching stiff fibres quartically in α, the
      // residual norm only quadratically), else on ‖f‖₂.
      double alpha = 1.0;
      const double e0 = conservative ? sys.Energies(*x, v).total() : 0.0;
      const double slope = conservative ? -r.dot(dx) : 0.0;  // dE/dα at α = 0
      for (int ls = 0; ls < 30; ++ls, alpha *= 0.5) {
        trial = *x;
        for (int k2 = 0; k2 < 3 * n; ++k2)
          if (index[static_cast<std::size_t>(k2)] >= 0)
            trial(k2 / 3, k2 % 3) += alpha * dx(index[static_cast<std::size_t>(k2)]);
        residual(trial, &r_trial);
        if (!r_trial.allFinite()) continue;
        // Near the solution the energy's decrease, ~½ |f|²/k, falls below
        // its round-off (~1e-16 |E|): a step that leaves the energy within
        // that round-off is then judged by ‖f‖₂ as well.
        const bool decreases = r_trial.norm() < r.norm() * (1.0 - 1e-4 * alpha);
        bool ok = decreases;
        if (conservative && slope < 0.0) {
          const double e1 = sys.Energies(trial, v).total();
          ok = e1 <= e0 + 1e-4 * alpha * slope || (decreases && std::abs(e1 - e0) <= 1e-13 * std::abs(e0));
        }
        if (ok) {
          accepted = true;
          break;
        }
      }
      if (accepted) {
        rel = alpha == 1.0 ? std::max(rel / 10.0, 1e-14) : std::min(rel * 10.0, 1e-2);
      } else {
        rel = std::min(rel * 100.0, 1.0);
      }
    }
    if (!accepted) {
      s.message = fmt::format("line search failed at iteration {}, max|f| = {:.3e} N (threshold {:.3e} N)", it,
                              s.residual, s.threshold);
      return s;
    }
    *x = trial;
    r = r_trial;
  }
  s.residual = r.cwiseAbs().maxCoeff();
  s.threshold = std::max(opt.tolerance * load, floor_at(*x));
  s.converged = s.residual <= s.threshold;
  if (!s.converged) s.message = fmt::format("no convergence in {} iterations, max|f| = {:.3e} N", opt.max_iterations, s.residual);
  return s;
}

}  // namespace clothbench
