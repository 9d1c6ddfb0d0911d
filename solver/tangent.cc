// J_α = M − αh ∂f/∂v − α²h² ∂f/∂x (SPEC §2.1, §11; Baraff & Witkin 1998).
#include "solver/tangent.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace clothbench {
namespace {

// Value index of entry (row, col) in a compressed column-major matrix.
int Position(const SparseMatrix& m, int row, int col) {
  const int* begin = m.innerIndexPtr() + m.outerIndexPtr()[col];
  const int* end = m.innerIndexPtr() + m.outerIndexPtr()[col + 1];
  const int* it = std::lower_bound(begin, end, row);
  // Every entry looked up is in the pattern by construction; a miss would
  // write into another entry, so it is a logic error.
  if (it == end || *it != row) throw std::logic_error("TangentSystem: entry outside the pattern");
  return static_cast<int>(it - m.innerIndexPtr());
}

}  // namespace

TangentSystem::TangentSystem(const ParticleSystem& system, const TangentOptions& options)
    : sys_(system), options_(options) {
  const int n3 = 3 * system.num_particles();
  Collect(0.0, system.rest_positions(), MatrixN3::Zero(system.num_particles(), 3));
  // Pattern: ∂f/∂x, ∂f/∂v, the diagonal, and the transpose of all (so that
  // the symmetric part lives on the same pattern), each set of triplets
  // reduced to a sparse matrix first: no copy of the triplet lists (at 10⁶
  // particles they hold several hundred million entries).
  SparseMatrix px(n3, n3), pv(n3, n3), eye(n3, n3);
  px.setFromTriplets(dfdx_.begin(), dfdx_.end());
  pv.setFromTriplets(dfdv_.begin(), dfdv_.end());
  eye.setIdentity();
  SparseMatrix sum = px + pv + eye;
  px = SparseMatrix();
  pv = SparseMatrix();
  j_ = SparseMatrix(sum.transpose()) + sum;
  j_.makeCompressed();
  j_.coeffs().setZero();
  pos_x_.resize(dfdx_.size());
  pos_v_.resize(dfdv_.size());
  for (std::size_t k = 0; k < dfdx_.size(); ++k) pos_x_[k] = Position(j_, dfdx_[k].row(), dfdx_[k].col());
  for (std::size_t k = 0; k < dfdv_.size(); ++k) pos_v_[k] = Position(j_, dfdv_[k].row(), dfdv_[k].col());
  diag_pos_.resize(static_cast<std::size_t>(n3));
  for (int k = 0; k < n3; ++k) diag_pos_[static_cast<std::size_t>(k)] = Position(j_, k, k);
  if (options_.symmetrize)
    for (int col = 0; col < n3; ++col)
      for (int pos = j_.outerIndexPtr()[col]; pos < j_.outerIndexPtr()[col + 1]; ++pos)
        if (j_.innerIndexPtr()[pos] < col) {
          upper_pos_.push_back(pos);
          lower_pos_.push_back(Position(j_, col, j_.innerIndexPtr()[pos]));
        }
}

void TangentSystem::Collect(double t, const MatrixN3& x, const MatrixN3& v) {
  dfdx_.clear();
  dfdv_.clear();
  const bool linear = sys_.scene().material.tension_model == TensionModel::kLinear;
  // Springs: ∂F_a/∂x_b = s_e [c (I − d̂d̂ᵀ) + d̂d̂ᵀ], c = 1 − l_e/|d| (clamped
  // at 0 with kClamp); ∂F_a/∂x_a is its negative. Damping c_e (v_b − v_a),
  // (3.18): ∂F_a/∂v_b = c_e I.
  for (const Spring& s : sys_.springs()) {
    const Vector3 d = (x.row(s.b) - x.row(s.a)).transpose();
    const double len = d.norm();
    const double rest = linear ? 0.0 : s.rest_length;
    double c = len > 0.0 ? 1.0 - rest / len : 1.0;
    if (options_.projection == TangentProjection::kClamp) c = std::max(c, 0.0);
    const Vector3 dh = len > 0.0 ? Vector3(d / len) : Vector3::Zero();
    const Eigen::Matrix3d dd = dh * dh.transpose();
    // The "linear" tension model (zero rest length) has c = 1: s_e I.
    const Eigen::Matrix3d kk = s.stiffness * (c * (Eigen::Matrix3d::Identity() - dd) + dd);
    for (int r = 0; r < 3; ++r)
      for (int q = 0; q < 3; ++q) {
        dfdx_.emplace_back(3 * s.a + r, 3 * s.b + q, kk(r, q));
        dfdx_.emplace_back(3 * s.a + r, 3 * s.a + q, -kk(r, q));
        dfdx_.emplace_back(3 * s.b + r, 3 * s.a + q, kk(r, q));
        dfdx_.emplace_back(3 * s.b + r, 3 * s.b + q, -kk(r, q));
      }
    if (s.damping > 0.0)
      for (int r = 0; r < 3; ++r) {
        dfdv_.emplace_back(3 * s.a + r, 3 * s.b + r, s.damping);
        dfdv_.emplace_back(3 * s.a + r, 3 * s.a + r, -s.damping);
        dfdv_.emplace_back(3 * s.b + r, 3 * s.a + r, s.damping);
        dfdv_.emplace_back(3 * s.b + r, 3 * s.b + r, -s.damping);
      }
  }
  if (!options_.include_explicit_terms) return;
  for (const auto& term : sys_.terms()) {
    if (term->name() == "tension_nonlinear") continue;  // in the spring blocks above
    term->AddJacobian(t, x, v, &dfdx_, &dfdv_);
  }
}

void TangentSystem::Update(double t, const MatrixN3& x, const MatrixN3& v, double alpha_h) {
  Collect(t, x, v);
  Eigen::Map<Eigen::VectorXd> vals(j_.valuePtr(), j_.nonZeros());
  vals.setZero();
  const double cx = -alpha_h * alpha_h, cv = -alpha_h;
  for (std::size_t k = 0; k < dfdx_.size(); ++k) vals(pos_x_[k]) += cx * dfdx_[k].value();
  for (std::size_t k = 0; k < dfdv_.size(); ++k) vals(pos_v_[k]) += cv * dfdv_[k].value();
  const Eigen::VectorXd& m = sys_.masses();
  for (std::size_t k = 0; k < diag_pos_.size(); ++k) vals(diag_pos_[k]) += m(static_cast<Eigen::Index>(k / 3));
  for (std::size_t k = 0; k < upper_pos_.size(); ++k) {  // (J + Jᵀ)/2 if options_.symmetrize
    const double mean = 0.5 * (vals(upper_pos_[k]) + vals(lower_pos_[k]));
    vals(upper_pos_[k]) = vals(lower_pos_[k]) = mean;
  }
}

void TangentSystem::AddJacobianProducts(double cx, const MatrixN3& u, double cv, const MatrixN3& w,
                                        MatrixN3* out) const {
  if (cx != 0.0)
    for (const Triplet& e : dfdx_) (*out)(e.row() / 3, e.row() % 3) += cx * e.value() * u(e.col() / 3, e.col() % 3);
  if (cv != 0.0)
    for (const Triplet& e : dfdv_) (*out)(e.row() / 3, e.row() % 3) += cv * e.value() * w(e.col() / 3, e.col() % 3);
}

}  // namespace clothbench
