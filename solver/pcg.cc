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
void VelocityFilter::Fix(int p, const Vector3& target) {
  entries_.push_back({p, 3, Eigen::Matrix3d::Identity(), target});
}

void VelocityFilter::Constrain(int p, const Vector3& dir, double target) {
  for (Entry& e : entries_) {
    if (e.particle != p) continue;
    if (e.count == 3) return;
    Vector3 d = dir;
    for (int k = 0; k < e.count; ++k) d -= e.dirs.col(k).dot(d) * e.dirs.col(k);
    if (d.norm() < 1e-12) return;
    e.dirs.col(e.count) = d.normalized();
    e.targets(e.count) = target;
    ++e.count;
    return;
  }
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
  for (int c = 0; c < 3; ++c) {
    double* y = z->col(c).data();
    for (int k = 0; k < n; ++k) {  // L y = r (column-oriented)
      const double yk = y[k] / val[outer[k]];
      y[k] = yk;
      for (int p = outer[k] + 1; p < outer[k + 1]; ++p) y[inner[p]] -= val[p] * yk;
    }
    for (int k = n - 1; k >= 0; --k) {  // Lᵀ z = y
      double s = y[k];
      for (int p = outer[k] + 1; p < outer[k + 1]; ++p) s -= val[p] * y[inner[p]];
      y[k] = s / val[outer[k]];
    }
  }
}

// ---------------------------------------------------------------------------
void Preconditioner::Analyze(const SparseMatrix& a) {
  if (type_ == PreconditionerType::kJacobi) inv_diag_.resize(a.rows());
  if (type_ == PreconditionerType::kIc0) ic0_.Analyze(a);
}

bool Preconditioner::Factorize(const SparseMatrix& a) {
  if (type_ == PreconditionerType::kJacobi) {
    for (int k = 0; k < a.rows(); ++k) inv_diag_(k) = 1.0 / a.coeff(k, k);
    return inv_diag_.allFinite();
  }
  if (type_ == PreconditionerType::kIc0) return ic0_.Factorize(a);
  return true;
}

void Preconditioner::Apply(const MatrixN3& r, MatrixN3* z) const {
  switch (type_) {
    case PreconditionerType::kNone: *z = r; break;
    case PreconditionerType::kJacobi: z->noalias() = inv_diag_.asDiagonal() * r; break;
    case PreconditionerType::kIc0: ic0_.Solve(r, z); break;
  }
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

  r = b;  // line 2: r = S(b − A v)
  r.noalias() -= a * (*v);
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
    q.noalias() = a * p;  // line 9
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
