// The preconditioners of the filtered PCG (preconditioner.h): IC(0), the
// N×N preconditioner's analysis, factorisation and application, and the
// tangent preconditioner. Their adaptation to the contacts is
// contact_policy.cc.
#include "solver/preconditioner.h"

#include <chrono>
#include <cmath>

#include <Eigen/Cholesky>
#include <omp.h>

namespace clothbench {

void IncompleteCholesky0::Analyze(const SparseMatrix& a) {
  l_ = a.triangularView<Eigen::Lower>();
  l_.makeCompressed();
  diag_pos_.assign(static_cast<std::size_t>(l_.cols()), -1);
  for (int k = 0; k < l_.cols(); ++k) {
    const int start = l_.outerIndexPtr()[k];
    // Eigen keeps row indices sorted, so the diagonal is first in column k.
    if (start < l_.outerIndexPtr()[k + 1] && l_.innerIndexPtr()[start] == k) diag_pos_[static_cast<std::size_t>(k)] = start;
  }
}

bool IncompleteCholesky0::Factorize(const SparseMatrix& a) {
  const int n = static_cast<int>(a.cols());
  const int* outer = l_.outerIndexPtr();
  const int* inner = l_.innerIndexPtr();
  double* val = l_.valuePtr();
  for (int k = 0; k < n; ++k)
    if (diag_pos_[static_cast<std::size_t>(k)] < 0) return false;  // structurally zero pivot
  shift_ = 0.0;
  for (int attempt = 0; attempt < 20; ++attempt) {
    // Copy the lower triangle of A (same pattern) into L, with the shift.
    {
      int pos = 0;
      for (int k = 0; k < n; ++k)
        for (SparseMatrix::InnerIterator it(a, k); it; ++it) {
          if (it.row() < k) continue;
          val[pos] = it.value() * (it.row() == k ? 1.0 + shift_ : 1.0);
          ++pos;
        }
    }
    bool ok = true;
    for (int k = 0; k < n && ok; ++k) {
      const int dk = diag_pos_[static_cast<std::size_t>(k)];
      if (!(val[dk] > 0.0)) {
        ok = false;
        break;
      }
      const double lkk = std::sqrt(val[dk]);
      val[dk] = lkk;
      for (int p = dk + 1; p < outer[k + 1]; ++p) val[p] /= lkk;
      // Right-looking update restricted to the pattern: L(i,j) −= L(i,k) L(j,k).
      for (int pj = dk + 1; pj < outer[k + 1]; ++pj) {
        const int j = inner[pj];
        const double ljk = val[pj];
        int q = outer[j];
        for (int pi = pj; pi < outer[k + 1]; ++pi) {
          const int i = inner[pi];
          while (q < outer[j + 1] && inner[q] < i) ++q;
          if (q < outer[j + 1] && inner[q] == i) val[q] -= val[pi] * ljk;
        }
      }
    }
    if (ok) return true;
    shift_ = shift_ == 0.0 ? 1e-3 : 2.0 * shift_;  // Manteuffel shift
  }
  return false;
}

// Forward sweep L y = r (column-oriented) and backward sweep Lᵀ z = y on K
// columns at once; every column sees the operations of a one-column solve.
template <int K>
void IncompleteCholesky0::Sweeps(double* const* y) const {
  const int n = static_cast<int>(l_.cols());
  const int* outer = l_.outerIndexPtr();
  const int* inner = l_.innerIndexPtr();
  const double* val = l_.valuePtr();
  for (int k = 0; k < n; ++k) {
    const double d = val[outer[k]];
    double a[K];
    for (int c = 0; c < K; ++c) y[c][k] = a[c] = y[c][k] / d;
    for (int p = outer[k] + 1; p < outer[k + 1]; ++p) {
      const int i = inner[p];
      const double l = val[p];
      for (int c = 0; c < K; ++c) y[c][i] -= l * a[c];
    }
  }
  for (int k = n - 1; k >= 0; --k) {
    double s[K];
    for (int c = 0; c < K; ++c) s[c] = y[c][k];
    for (int p = outer[k] + 1; p < outer[k + 1]; ++p) {
      const int i = inner[p];
      const double l = val[p];
      for (int c = 0; c < K; ++c) s[c] -= l * y[c][i];
    }
    const double d = val[outer[k]];
    for (int c = 0; c < K; ++c) y[c][k] = s[c] / d;
  }
}

void IncompleteCholesky0::Solve(const MatrixN3& r, MatrixN3* z) const {
  *z = r;
  double* const y[3] = {z->col(0).data(), z->col(1).data(), z->col(2).data()};
  Sweeps<3>(y);
}

void IncompleteCholesky0::SolveInPlace(double* y) const {
  double* const cols[1] = {y};
  Sweeps<1>(cols);
}

// ---------------------------------------------------------------------------
Preconditioner::Preconditioner(PreconditionerType type, CholeskyOrdering ordering, bool contact_factors)
    : type_(type == PreconditionerType::kAuto ? PreconditionerType::kCholesky : type),
      ordering_(ordering),
      contact_factors_(contact_factors && (type == PreconditionerType::kCholesky || type == PreconditionerType::kAmg ||
                                           type == PreconditionerType::kAuto)),
      auto_(type == PreconditionerType::kAuto) {
  // Started here, not in Analyze: MPI's start-up (≈0.3 s, once per process)
  // is not part of the setup time of A's preconditioner.
  if (type_ == PreconditionerType::kAmg) amg_ = std::make_unique<AmgPreconditioner>();
}
Preconditioner::~Preconditioner() = default;
Preconditioner::Preconditioner(Preconditioner&&) noexcept = default;
Preconditioner& Preconditioner::operator=(Preconditioner&&) noexcept = default;

bool Preconditioner::Analyze(const SparseMatrix& a, const std::vector<int>& fixed) {
  switch (type_) {
    case PreconditionerType::kNone: return true;
    case PreconditionerType::kJacobi: inv_diag_.resize(a.rows()); return true;
    case PreconditionerType::kIc0: ic0_.Analyze(a); return true;
    case PreconditionerType::kCholesky:
      if (!cholesky_) cholesky_ = std::make_unique<CholeskyFactor>();
      if (contact_factors_)
        for (int c = 0; c < 3; ++c) {
          axis_factor_[c].reset();
          axis_set_[c].assign(static_cast<std::size_t>(a.rows()), 0);
          axis_want_[c].assign(static_cast<std::size_t>(a.rows()), 0);
          axis_valid_[c] = axis_used_[c] = false;
        }
      return cholesky_->Analyze(a, fixed, ordering_);
    case PreconditionerType::kAmg: return amg_->Analyze(a, fixed);  // amg_ made by the constructor
    case PreconditionerType::kAuto: break;  // never type_ (kCholesky with auto_)
  }
  return false;
}

double Preconditioner::RefactorIterations(int n) const {
  switch (type_) {
    case PreconditionerType::kNone:
    case PreconditionerType::kJacobi: return 0.0;
    case PreconditionerType::kIc0: return 1.0;
    case PreconditionerType::kAmg: return kAutoSetupVCycles * VCycleIterations(n);
    case PreconditionerType::kCholesky:
    case PreconditionerType::kAuto: break;
  }
  const long nnz = factor_nonzeros();
  if (!cholesky_ || nnz <= 0) return kRefactorIterations;
  const int factors = 1 + axis_used_[0] + axis_used_[1] + axis_used_[2];
  return factors * cholesky_->factorization_flops() / (12.0 * static_cast<double>(nnz));
}

bool Preconditioner::Factorize(const SparseMatrix& a) {
  switch (type_) {
    case PreconditionerType::kNone: return true;
    case PreconditionerType::kJacobi:
      for (int k = 0; k < a.rows(); ++k) inv_diag_(k) = 1.0 / a.coeff(k, k);
      return inv_diag_.allFinite();
    case PreconditionerType::kIc0: return ic0_.Factorize(a);
    case PreconditionerType::kCholesky:
      axis_valid_ = {false, false, false};  // new values of A: the contact factors are stale
      axis_used_ = {false, false, false};
      cf_frames_ = false;
      system_valid_ = system_used_ = false;  // and "auto"'s prefiltered hierarchy
      return cholesky_ && cholesky_->Factorize(a);
    case PreconditionerType::kAmg:
      system_valid_ = system_used_ = false;  // new values of A: the system hierarchy is stale
      return amg_ && amg_->Factorize(a);
    case PreconditionerType::kAuto: break;  // never type_
  }
  return false;
}

void Preconditioner::ApplySystem(const MatrixN3& r, MatrixN3* z) const {
  const auto t0 = std::chrono::steady_clock::now();
  rotated_r_.resize(r.rows(), 3);
  rotated_z_.resize(r.rows(), 3);
  for (Eigen::Index p = 0; p < r.rows(); ++p) rotated_r_.row(p) = r.row(p) * frames_[static_cast<std::size_t>(p)];
  amg_->SolveSystem(rotated_r_, &rotated_z_);
  for (Eigen::Index p = 0; p < r.rows(); ++p)
    z->row(p) = rotated_z_.row(p) * frames_[static_cast<std::size_t>(p)].transpose();
  ++contact_stats_.v_cycles;
  contact_stats_.v_cycle_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void Preconditioner::Apply(const MatrixN3& r, MatrixN3* z) const {
  // Counted in reads of one factor (the contact policy's unit): one here,
  // one more per further distinct factor of the contact lanes below.
  ++applications_;
  if (auto_ && system_used_) {
    ApplySystem(r, z);
    return;
  }
  switch (type_) {
    case PreconditionerType::kNone: *z = r; break;
    case PreconditionerType::kJacobi: z->noalias() = inv_diag_.asDiagonal() * r; break;
    case PreconditionerType::kIc0: ic0_.Solve(r, z); break;
    case PreconditionerType::kCholesky: {
      if (!axis_used_[0] && !axis_used_[1] && !axis_used_[2]) {
        cholesky_->Solve(r, z);
        break;
      }
      // In contact frames: r rotated into each particle's frame (r_p R_p),
      // column z with the contacts decoupled, z rotated back in place.
      const MatrixN3* in = &r;
      if (cf_frames_) {
        rotated_r_ = r;
#pragma omp parallel for schedule(static) if (r.rows() >= kParallelSolveRows)
        for (Eigen::Index p = 0; p < r.rows(); ++p)
          if (cf_rotated_[static_cast<std::size_t>(p)])
            rotated_r_.row(p) = r.row(p) * cf_frame_[static_cast<std::size_t>(p)];
        in = &rotated_r_;
      }
      // Each column with its own factor; lane 0 solves columns 0 and 1,
      // lane 1 column 2, on two threads at scale (as CholeskyFactor::Solve).
      const CholeskyFactor* f[3];
      for (std::size_t c = 0; c < 3; ++c) f[c] = axis_used_[c] ? axis_factor_[c].get() : cholesky_.get();
      applications_ += (f[1] != f[0]) + (f[2] != f[0] && f[2] != f[1]);
      const bool split = r.rows() >= kParallelSolveRows && omp_get_max_threads() >= 2;
#pragma omp parallel for num_threads(2) schedule(static, 1) if (split)
      for (int lane = 0; lane < 2; ++lane) {
        if (lane == 0) {
          if (f[0] == f[1]) {
            f[0]->SolveColumns(*in, z, 0, 2, 0);
          } else {
            f[0]->SolveColumns(*in, z, 0, 1, 0);
            f[1]->SolveColumns(*in, z, 1, 1, 0);
          }
        } else {
          f[2]->SolveColumns(*in, z, 2, 1, 1);
        }
      }
      if (cf_frames_) {
#pragma omp parallel for schedule(static) if (r.rows() >= kParallelSolveRows)
        for (Eigen::Index p = 0; p < r.rows(); ++p)
          if (cf_rotated_[static_cast<std::size_t>(p)]) {
            const Eigen::RowVector3d local = z->row(p);
            z->row(p) = local * cf_frame_[static_cast<std::size_t>(p)].transpose();
          }
      }
      break;
    }
    case PreconditionerType::kAmg:
      if (system_used_)
        ApplySystem(r, z);
      else
        amg_->Solve(r, z);
      break;
    case PreconditionerType::kAuto: break;  // never type_ (kCholesky with auto_)
  }
}

// ---------------------------------------------------------------------------
void TangentPreconditioner::Analyze(const SparseMatrix& j, const Preconditioner* laplacian) {
  const int n = static_cast<int>(j.cols()) / 3;
  laplacian_ = laplacian;
  switch (type_) {
    case PreconditionerType::kJacobi:
      block_inv_.assign(static_cast<std::size_t>(n), Eigen::Matrix3d::Identity());
      block_pos_.assign(static_cast<std::size_t>(9 * n), -1);
      for (int col = 0; col < 3 * n; ++col)
        for (int pos = j.outerIndexPtr()[col]; pos < j.outerIndexPtr()[col + 1]; ++pos) {
          const int row = j.innerIndexPtr()[pos];
          if (row / 3 == col / 3) block_pos_[static_cast<std::size_t>(9 * (col / 3) + 3 * (row % 3) + col % 3)] = pos;
        }
      break;
    case PreconditionerType::kIc0: ic0_.Analyze(j); break;
    case PreconditionerType::kCholesky:
    case PreconditionerType::kAmg:
    case PreconditionerType::kAuto:
      rc_.resize(n, 3);
      zc_.resize(n, 3);
      break;
    case PreconditionerType::kNone: break;
  }
}

bool TangentPreconditioner::Factorize(const SparseMatrix& j) {
  switch (type_) {
    case PreconditionerType::kJacobi: {
      const double* val = j.valuePtr();
      for (std::size_t p = 0; p < block_inv_.size(); ++p) {
        Eigen::Matrix3d b;
        for (int k = 0; k < 9; ++k) {
          const int pos = block_pos_[9 * p + static_cast<std::size_t>(k)];
          b(k / 3, k % 3) = pos >= 0 ? val[pos] : 0.0;
        }
        const Eigen::LLT<Eigen::Matrix3d> llt(0.5 * (b + b.transpose()));
        if (llt.info() != Eigen::Success) return false;
        block_inv_[p] = llt.solve(Eigen::Matrix3d::Identity());
      }
      return true;
    }
    case PreconditionerType::kIc0: return ic0_.Factorize(j);
    case PreconditionerType::kCholesky:
    case PreconditionerType::kAmg:
    case PreconditionerType::kAuto: return laplacian_ != nullptr;
    case PreconditionerType::kNone: return true;
  }
  return false;
}

void TangentPreconditioner::Apply(const MatrixN3R& r, MatrixN3R* z) const {
  switch (type_) {
    case PreconditionerType::kJacobi:
      for (std::size_t p = 0; p < block_inv_.size(); ++p) {
        const auto i = static_cast<Eigen::Index>(p);
        z->row(i).noalias() = r.row(i) * block_inv_[p];  // symmetric blocks
      }
      break;
    case PreconditionerType::kIc0:
      *z = r;
      ic0_.SolveInPlace(z->data());
      break;
    case PreconditionerType::kCholesky:
    case PreconditionerType::kAmg:
    case PreconditionerType::kAuto:
      rc_ = r;  // layout change only
      laplacian_->Apply(rc_, &zc_);
      *z = zc_;
      break;
    case PreconditionerType::kNone: *z = r; break;
  }
}

}  // namespace clothbench
