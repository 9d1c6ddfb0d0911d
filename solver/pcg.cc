// Filtered PCG and its preconditioners (SPEC §5, thesis Alg. 7).
#include "solver/pcg.h"

#include <cmath>

namespace clothbench {

std::string_view ToString(PcgStatus s) {
  switch (s) {
    case PcgStatus::kConverged: return "converged";
    case PcgStatus::kMaxIterations: return "cg_max_iterations";
    case PcgStatus::kBreakdown: return "cg_breakdown";
    case PcgStatus::kNonFinite: return "cg_non_finite";
  }
  return "?";
}

// ---------------------------------------------------------------------------
VelocityFilter::Entry* VelocityFilter::Find(int p) {
  const auto k = static_cast<std::size_t>(p);
  if (k < slot_.size()) return slot_[k] >= 0 ? &entries_[static_cast<std::size_t>(slot_[k])] : nullptr;
  for (Entry& e : entries_)  // without Reserve: linear search
    if (e.particle == p) return &e;
  return nullptr;
}

void VelocityFilter::Fix(int p, const Vector3& target) {
  if (static_cast<std::size_t>(p) < slot_.size()) slot_[static_cast<std::size_t>(p)] = size();
  entries_.push_back({p, 3, Eigen::Matrix3d::Identity(), target});
}

// A particle's entry is found through slot_ in O(1). A linear search made
// the contact setup quadratic in the number of contacts (bench_scaling,
// 30 % patch at 10⁶ particles: 157 s per SBDF(2) step before, 20 s after).
void VelocityFilter::Constrain(int p, const Vector3& dir, double target) {
  if (Entry* found = Find(p)) {
    Entry& e = *found;
    if (e.count == 3) return;
    Vector3 d = dir;
    for (int k = 0; k < e.count; ++k) d -= e.dirs.col(k).dot(d) * e.dirs.col(k);
    if (d.norm() < 1e-12) return;
    e.dirs.col(e.count) = d.normalized();
    e.targets(e.count) = target;
    ++e.count;
    return;
  }
  if (static_cast<std::size_t>(p) < slot_.size()) slot_[static_cast<std::size_t>(p)] = size();
  Entry e{p, 1, Eigen::Matrix3d::Zero(), Vector3::Zero()};
  e.dirs.col(0) = dir.normalized();
  e.targets(0) = target;
  entries_.push_back(e);
}

void VelocityFilter::Project(MatrixN3* v) const {
  for (const Entry& e : entries_) {
    if (e.count == 3) {
      v->row(e.particle).setZero();
      continue;
    }
    Vector3 x = v->row(e.particle).transpose();
    for (int k = 0; k < e.count; ++k) x -= e.dirs.col(k).dot(x) * e.dirs.col(k);
    v->row(e.particle) = x.transpose();
  }
}

void VelocityFilter::Impose(MatrixN3* v) const {
  for (const Entry& e : entries_) {
    if (e.count == 3) {
      v->row(e.particle) = e.targets.transpose();  // dirs = I
      continue;
    }
    Vector3 x = v->row(e.particle).transpose();
    for (int k = 0; k < e.count; ++k) x += (e.targets(k) - e.dirs.col(k).dot(x)) * e.dirs.col(k);
    v->row(e.particle) = x.transpose();
  }
}

// ---------------------------------------------------------------------------
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

void IncompleteCholesky0::Solve(const MatrixN3& r, MatrixN3* z) const {
  const int n = static_cast<int>(l_.cols());
  const int* outer = l_.outerIndexPtr();
  const int* inner = l_.innerIndexPtr();
  const double* val = l_.valuePtr();
  *z = r;
  double* y0 = z->col(0).data();
  double* y1 = z->col(1).data();
  double* y2 = z->col(2).data();
  for (int k = 0; k < n; ++k) {  // L y = r (column-oriented), three columns per entry of L
    const double d = val[outer[k]];
    const double a0 = y0[k] / d, a1 = y1[k] / d, a2 = y2[k] / d;
    y0[k] = a0;
    y1[k] = a1;
    y2[k] = a2;
    for (int p = outer[k] + 1; p < outer[k + 1]; ++p) {
      const int i = inner[p];
      const double l = val[p];
      y0[i] -= l * a0;
      y1[i] -= l * a1;
      y2[i] -= l * a2;
    }
  }
  for (int k = n - 1; k >= 0; --k) {  // Lᵀ z = y
    double s0 = y0[k], s1 = y1[k], s2 = y2[k];
    for (int p = outer[k] + 1; p < outer[k + 1]; ++p) {
      const int i = inner[p];
      const double l = val[p];
      s0 -= l * y0[i];
      s1 -= l * y1[i];
      s2 -= l * y2[i];
    }
    const double d = val[outer[k]];
    y0[k] = s0 / d;
    y1[k] = s1 / d;
    y2[k] = s2 / d;
  }
}

// ---------------------------------------------------------------------------
Preconditioner::Preconditioner(PreconditionerType type, CholeskyOrdering ordering) : type_(type), ordering_(ordering) {
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
      return cholesky_->Analyze(a, fixed, ordering_);
    case PreconditionerType::kAmg: return amg_->Analyze(a, fixed);  // amg_ made by the constructor
  }
  return false;
}

bool Preconditioner::Factorize(const SparseMatrix& a) {
  switch (type_) {
    case PreconditionerType::kNone: return true;
    case PreconditionerType::kJacobi:
      for (int k = 0; k < a.rows(); ++k) inv_diag_(k) = 1.0 / a.coeff(k, k);
      return inv_diag_.allFinite();
    case PreconditionerType::kIc0: return ic0_.Factorize(a);
    case PreconditionerType::kCholesky: return cholesky_ && cholesky_->Factorize(a);
    case PreconditionerType::kAmg: return amg_ && amg_->Factorize(a);
  }
  return false;
}

void Preconditioner::Apply(const MatrixN3& r, MatrixN3* z) const {
  switch (type_) {
    case PreconditionerType::kNone: *z = r; break;
    case PreconditionerType::kJacobi: z->noalias() = inv_diag_.asDiagonal() * r; break;
    case PreconditionerType::kIc0: ic0_.Solve(r, z); break;
    case PreconditionerType::kCholesky: cholesky_->Solve(r, z); break;
    case PreconditionerType::kAmg: amg_->Solve(r, z); break;
  }
}

// ---------------------------------------------------------------------------
namespace {

// y(j,:) = start(j,:) ± Σ_i A(i,j) x(i,:), the terms in ascending i: the
// same operations, in the same order, as Eigen's column-major sparse ×
// dense product (which scatters column j of A into y), so the result is
// bit-identical to `y = a * x` (sign +1, no start) and `y -= a * x`.
template <bool kSubtract>
void ProductKernel(const SparseMatrix& a, const MatrixN3& x, const MatrixN3* start, MatrixN3* y) {
  const int n = static_cast<int>(a.cols());
  const int* outer = a.outerIndexPtr();
  const int* inner = a.innerIndexPtr();
  const double* val = a.valuePtr();
  const double* x0 = x.col(0).data();
  const double* x1 = x.col(1).data();
  const double* x2 = x.col(2).data();
  double* y0 = y->col(0).data();
  double* y1 = y->col(1).data();
  double* y2 = y->col(2).data();
  const double* s0 = start ? start->col(0).data() : nullptr;
  const double* s1 = start ? start->col(1).data() : nullptr;
  const double* s2 = start ? start->col(2).data() : nullptr;
#pragma omp parallel for schedule(static) if (n >= kParallelMinimum)
  for (int j = 0; j < n; ++j) {
    double a0 = s0 ? s0[j] : 0.0, a1 = s1 ? s1[j] : 0.0, a2 = s2 ? s2[j] : 0.0;
    for (int p = outer[j]; p < outer[j + 1]; ++p) {
      const int i = inner[p];
      const double v = val[p];
      if constexpr (kSubtract) {
        a0 -= v * x0[i];
        a1 -= v * x1[i];
        a2 -= v * x2[i];
      } else {
        a0 += v * x0[i];
        a1 += v * x1[i];
        a2 += v * x2[i];
      }
    }
    y0[j] = a0;
    y1[j] = a1;
    y2[j] = a2;
  }
}

}  // namespace

void SymmetricProduct(const SparseMatrix& a, const MatrixN3& x, MatrixN3* y) {
  ProductKernel<false>(a, x, nullptr, y);
}

// ---------------------------------------------------------------------------
// Alg. 7 with the Ascher–Boxerman initialisation: v ← S v + (I − S) z first,
// so that CG runs on the projected system S A S y = S(b − A v₀) and the
// preconditioner S P⁻¹ S stays symmetric. Projections after the
// preconditioner (Alg. 7 line 6) and after A·p (line 10).
PcgSummary FilteredPcg(const SparseMatrix& a, const MatrixN3& b, const VelocityFilter& filter,
                       const Preconditioner& precond, const PcgOptions& options, MatrixN3* v, PcgWorkspace* w) {
  PcgSummary s;
  const bool filtered = !filter.empty();
  MatrixN3& r = w->r;
  MatrixN3& z = w->z;
  MatrixN3& p = w->p;
  MatrixN3& q = w->q;

  if (filtered) filter.Impose(v);
  // ‖S b‖ for the stopping rule (SPEC §5), unless the caller gave its own.
  if (options.rhs_norm >= 0.0) {
    s.rhs_norm = options.rhs_norm;
  } else {
    r = b;
    if (filtered) filter.Project(&r);
    s.rhs_norm = r.norm();
  }
  const double threshold = options.tolerance * s.rhs_norm;

  ProductKernel<true>(a, *v, &b, &r);  // line 2: r = S(b − A v)
  if (filtered) filter.Project(&r);
  double rnorm = r.norm();
  s.iterations = 0;
  s.residual_norm = rnorm;
  if (!std::isfinite(rnorm)) {
    s.status = PcgStatus::kNonFinite;
    return s;
  }
  if (rnorm <= threshold) {
    s.status = PcgStatus::kConverged;
    return s;
  }
  precond.Apply(r, &z);  // line 5
  if (filtered) filter.Project(&z);  // line 6
  p = z;
  double rho = (r.array() * z.array()).sum();
  for (int k = 0; k < options.max_iterations; ++k) {
    SymmetricProduct(a, p, &q);  // line 9
    if (filtered) filter.Project(&q);  // line 10
    const double pq = (p.array() * q.array()).sum();
    if (!(pq > 0.0)) {
      s.status = std::isfinite(pq) ? PcgStatus::kBreakdown : PcgStatus::kNonFinite;
      s.iterations = k;
      return s;
    }
    const double alpha = rho / pq;  // line 11
    *v += alpha * p;                // line 12
    r -= alpha * q;                 // line 13
    rnorm = r.norm();
    s.iterations = k + 1;
    s.residual_norm = rnorm;
    if (!std::isfinite(rnorm)) {
      s.status = PcgStatus::kNonFinite;
      return s;
    }
    if (rnorm <= threshold) {
      s.status = PcgStatus::kConverged;
      return s;
    }
    precond.Apply(r, &z);
    if (filtered) filter.Project(&z);
    const double rho_new = (r.array() * z.array()).sum();
    p = z + (rho_new / rho) * p;  // line 8
    rho = rho_new;
  }
  s.status = PcgStatus::kMaxIterations;
  return s;
}

}  // namespace clothbench
