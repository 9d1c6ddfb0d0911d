// Filtered PCG (docs/model.md §5, thesis Alg. 7) and its sparse products.
#include "solver/pcg.h"

#include "model/interrupt.h"

#include <chrono>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <omp.h>

namespace clothbench {

std::string_view ToString(PcgStatus s) {
  switch (s) {
    case PcgStatus::kConverged: return "converged";
    case PcgStatus::kMaxIterations: return "cg_max_iterations";
    case PcgStatus::kBreakdown: return "cg_breakdown";
    case PcgStatus::kNonFinite: return "cg_non_finite";
    case PcgStatus::kTimeLimit: return "time_limit";
  }
  return "?";
}

// ---------------------------------------------------------------------------
namespace {

// y(j,:) = start(j,:) ± Σ_i A(i,j) x(i,:), the terms in ascending i, on K
// columns of length n (K = 3: the N×3 columns; K = 1: one 3N vector): the
// same operations, in the same order, as Eigen's column-major sparse ×
// dense product (which scatters column j of A into y), so the result is
// bit-identical to `y = a * x` (sign +1, no start) and `y -= a * x`.
// A symmetric A's column j is its row j.
template <int K, bool kSubtract>
void ProductKernel(const SparseMatrix& a, const double* const* x, const double* const* start, double* const* y) {
  const int n = static_cast<int>(a.cols());
  const int* outer = a.outerIndexPtr();
  const int* inner = a.innerIndexPtr();
  const double* val = a.valuePtr();
#pragma omp parallel for schedule(static) if (n >= kParallelMinimum)
  for (int j = 0; j < n; ++j) {
    double acc[K];
    for (int c = 0; c < K; ++c) acc[c] = start ? start[c][j] : 0.0;
    for (int p = outer[j]; p < outer[j + 1]; ++p) {
      const int i = inner[p];
      const double v = val[p];
      for (int c = 0; c < K; ++c) {
        if constexpr (kSubtract)
          acc[c] -= v * x[c][i];
        else
          acc[c] += v * x[c][i];
      }
    }
    for (int c = 0; c < K; ++c) y[c][j] = acc[c];
  }
}

// The two operators of the filtered PCG: r = b − A v (Residual) and
// q = A p (Apply).
struct LaplacianOperator {  // N×N A applied to the three columns of an N×3 matrix
  const SparseMatrix& a;
  void Residual(const MatrixN3& b, const MatrixN3& v, MatrixN3* r) const {
    const double* const x[3] = {v.col(0).data(), v.col(1).data(), v.col(2).data()};
    const double* const s[3] = {b.col(0).data(), b.col(1).data(), b.col(2).data()};
    double* const y[3] = {r->col(0).data(), r->col(1).data(), r->col(2).data()};
    ProductKernel<3, true>(a, x, s, y);
  }
  void Apply(const MatrixN3& p, MatrixN3* q) const { SymmetricProduct(a, p, q); }
};

struct TangentOperator {  // 3N×3N J on the 3N vector stored in an N×3 row-major matrix
  const SparseMatrix& j;
  void Residual(const MatrixN3R& b, const MatrixN3R& v, MatrixN3R* r) const {
    const double* const x[1] = {v.data()};
    const double* const s[1] = {b.data()};
    double* const y[1] = {r->data()};
    ProductKernel<1, true>(j, x, s, y);
  }
  void Apply(const MatrixN3R& p, MatrixN3R* q) const { TangentProduct(j, p, q); }
};

}  // namespace

void SymmetricProduct(const SparseMatrix& a, const MatrixN3& x, MatrixN3* y) {
  const double* const xc[3] = {x.col(0).data(), x.col(1).data(), x.col(2).data()};
  double* const yc[3] = {y->col(0).data(), y->col(1).data(), y->col(2).data()};
  ProductKernel<3, false>(a, xc, nullptr, yc);
}

void TangentProduct(const SparseMatrix& j, const MatrixN3R& x, MatrixN3R* y) {
  const double* const xc[1] = {x.data()};
  double* const yc[1] = {y->data()};
  ProductKernel<1, false>(j, xc, nullptr, yc);
}

// ---------------------------------------------------------------------------
// Alg. 7 with the Ascher–Boxerman initialisation: v ← S v + (I − S) z first,
// so that CG runs on the projected system S A S y = S(b − A v₀) and the
// preconditioner S P⁻¹ S stays symmetric. Projections after the
// preconditioner (Alg. 7 line 6) and after A·p (line 10).
// One algorithm for both systems: Op is LaplacianOperator or TangentOperator,
// Pre the matching preconditioner, Vec MatrixN3 or MatrixN3R.
namespace {

template <class Vec, class Op, class Pre>
PcgSummary FilteredPcgImpl(const Op& op, const Vec& b, const VelocityFilter& filter, const Pre& precond,
                           const PcgOptions& options, Vec* v, PcgWorkspaceT<Vec>* w) {
  PcgSummary s;
  const bool filtered = !filter.empty();
  Vec& r = w->r;
  Vec& z = w->z;
  Vec& p = w->p;
  Vec& q = w->q;

  if (filtered) filter.Impose(v);
  // ‖S b‖ for the stopping rule (docs/model.md §5), unless the caller gave its own.
  if (options.rhs_norm >= 0.0) {
    s.rhs_norm = options.rhs_norm;
  } else {
    s.rhs_norm = filtered ? filter.ProjectedNorm(b) : b.norm();
  }
  const double threshold = std::max(options.tolerance * s.rhs_norm, options.residual_floor);

  op.Residual(b, *v, &r);  // line 2: r = S(b − A v)
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
  double rho = (r.array() * z.array()).sum();
  p.swap(z);  // p = z without a copy: z is overwritten by the next Apply
  if (z.rows() != p.rows()) z.resizeLike(p);
  for (int k = 0; k < options.max_iterations; ++k) {
    op.Apply(p, &q);  // line 9
    if (filtered) filter.Project(&q);  // line 10
    const double pq = (p.array() * q.array()).sum();
    if (!(pq > 0.0)) {
      s.status = std::isfinite(pq) ? PcgStatus::kBreakdown : PcgStatus::kNonFinite;
      s.iterations = k;
      return s;
    }
    const double alpha = rho / pq;  // line 11
    // Lines 12 and 13 and ‖r‖ in one pass over the 3N entries.
    {
      double* vd = v->data();
      double* rd = r.data();
      const double* pd = p.data();
      const double* qd = q.data();
      const std::ptrdiff_t m = static_cast<std::ptrdiff_t>(r.size());
      double rr = 0.0;
      for (std::ptrdiff_t i = 0; i < m; ++i) {
        vd[i] += alpha * pd[i];
        rd[i] -= alpha * qd[i];
        rr += rd[i] * rd[i];
      }
      rnorm = std::sqrt(rr);
    }
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
    if (DeadlinePassed()) {  // the run's --time-limit (model/interrupt.h)
      s.status = PcgStatus::kTimeLimit;
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

}  // namespace

PcgSummary FilteredPcg(const SparseMatrix& a, const MatrixN3& b, const VelocityFilter& filter,
                       const Preconditioner& precond, const PcgOptions& options, MatrixN3* v, PcgWorkspace* work) {
  return FilteredPcgImpl(LaplacianOperator{a}, b, filter, precond, options, v, work);
}

PcgSummary FilteredPcg(const SparseMatrix& j, const MatrixN3R& b, const VelocityFilter& filter,
                       const TangentPreconditioner& precond, const PcgOptions& options, MatrixN3R* v,
                       TangentPcgWorkspace* work) {
  return FilteredPcgImpl(TangentOperator{j}, b, filter, precond, options, v, work);
}

}  // namespace clothbench
