// CHOLMOD factor of A_F (SPEC §5). CHOLMOD is confined to this file.
#include "solver/cholesky.h"

#include "solver/decoupled.h"

#include <cholmod.h>

#include <algorithm>
#include <cstring>
#include <limits>

namespace clothbench {

struct CholeskyFactor::Impl {
  cholmod_common common;
  cholmod_sparse* upper = nullptr;   // A_F, upper triangle (stype = 1)
  cholmod_factor* factor = nullptr;  // supernodal where CHOLMOD chooses it: fast (BLAS-3) factorisation
  cholmod_factor* solver = nullptr;  // simplicial LLᵀ copy for the solves (see Factorize)
  std::vector<int> source;           // position in A's values of each entry of `upper`
  // Solve workspace, reused (cholmod_solve2 allocates them once).
  cholmod_dense* x = nullptr;
  cholmod_dense* y = nullptr;
  cholmod_dense* e = nullptr;
  bool factorized = false;

  Impl() {
    cholmod_start(&common);
    common.print = 0;
    common.error_handler = nullptr;
  }
  ~Impl() {
    cholmod_free_dense(&x, &common);
    cholmod_free_dense(&y, &common);
    cholmod_free_dense(&e, &common);
    cholmod_free_factor(&solver, &common);
    cholmod_free_factor(&factor, &common);
    cholmod_free_sparse(&upper, &common);
    cholmod_finish(&common);
  }
};

CholeskyFactor::CholeskyFactor() : impl_(std::make_unique<Impl>()) {}
CholeskyFactor::~CholeskyFactor() = default;

bool CholeskyFactor::Analyze(const SparseMatrix& a, const std::vector<int>& fixed, CholeskyOrdering ordering) {
  Impl& m = *impl_;
  cholmod_free_factor(&m.solver, &m.common);
  cholmod_free_factor(&m.factor, &m.common);
  cholmod_free_sparse(&m.upper, &m.common);
  m.factorized = false;
  const int n = static_cast<int>(a.rows());
  // Upper triangle of A_F: entries coupling a fixed particle are left out of
  // the pattern altogether (they are zero in A_F).
  internal::DecoupledPattern pattern = internal::DecoupleFixed(a, fixed, /*upper_only=*/true);
  m.source = std::move(pattern.source);
  const std::vector<int>& colptr = pattern.outer;
  const std::vector<int>& rows = pattern.inner;
  m.upper = cholmod_allocate_sparse(static_cast<size_t>(n), static_cast<size_t>(n), rows.size(), /*sorted=*/1,
                                    /*packed=*/1, /*stype=*/1, CHOLMOD_REAL, &m.common);
  if (!m.upper) return false;
  std::memcpy(m.upper->p, colptr.data(), colptr.size() * sizeof(int));
  std::memcpy(m.upper->i, rows.data(), rows.size() * sizeof(int));
  std::fill_n(static_cast<double*>(m.upper->x), rows.size(), 0.0);
  // One fill-reducing ordering, chosen by the scene (no trial of several),
  // followed by CHOLMOD's weighted postordering.
  m.common.nmethods = 1;
  m.common.method[0].ordering = ordering == CholeskyOrdering::kMetis ? CHOLMOD_METIS : CHOLMOD_AMD;
  m.common.postorder = 1;
  m.common.supernodal = CHOLMOD_AUTO;
  m.factor = cholmod_analyze(m.upper, &m.common);
  return m.factor != nullptr && m.common.status == CHOLMOD_OK;
}

bool CholeskyFactor::Factorize(const SparseMatrix& a) {
  Impl& m = *impl_;
  m.factorized = false;
  if (!m.factor) return false;
  double* dst = static_cast<double*>(m.upper->x);
  const double* src = a.valuePtr();
  for (std::size_t k = 0; k < m.source.size(); ++k) dst[k] = src[m.source[k]];
  const int ok = cholmod_factorize(m.upper, m.factor, &m.common);
  // CHOLMOD_NOT_POSDEF is a warning (status > 0), not an error: check minor.
  if (!ok || m.common.status != CHOLMOD_OK || m.factor->minor < m.factor->n) return false;
  // Solves run on a simplicial LLᵀ copy of the factor. CHOLMOD's supernodal
  // solve calls BLAS once per supernode, with 3 right-hand sides; on A_α's
  // many small supernodes that call overhead dominates (measured with a
  // scratch driver at 10⁶ particles: 0.26 s per 3-column solve against
  // 0.16 s simplicial). The supernodal factor is kept for the next numeric
  // factorisation.
  cholmod_free_factor(&m.solver, &m.common);
  if (m.factor->is_super) {
    m.solver = cholmod_copy_factor(m.factor, &m.common);
    if (!m.solver || !cholmod_change_factor(CHOLMOD_REAL, /*to_ll=*/1, /*to_super=*/0, /*to_packed=*/1,
                                            /*to_monotonic=*/1, m.solver, &m.common))
      return false;
  }
  m.factorized = true;
  return true;
}

void CholeskyFactor::Solve(const MatrixN3& r, MatrixN3* z) const {
  Impl& m = *impl_;
  const auto n = static_cast<size_t>(r.rows());
  cholmod_dense b{};
  b.nrow = n;
  b.ncol = 3;
  b.nzmax = 3 * n;
  b.d = n;
  b.x = const_cast<double*>(r.data());  // read only
  b.z = nullptr;
  b.xtype = CHOLMOD_REAL;
  b.dtype = CHOLMOD_DOUBLE;
  // cholmod_solve2 asks for its workspace Y as 4×n (solves run in chunks
  // of up to 4 columns) but leaves it shaped 3×n, and reallocates a
  // workspace whose shape differs: restoring 4×n (same storage) lets it
  // reuse Y, so a solve allocates nothing.
  if (m.y && m.y->nrow == 3 && m.y->ncol == n && m.y->nzmax >= 4 * n) {
    m.y->nrow = 4;
    m.y->d = 4;
  }
  if (!m.factorized || !cholmod_solve2(CHOLMOD_A, m.solver ? m.solver : m.factor, &b, nullptr, &m.x, nullptr, &m.y, &m.e, &m.common)) {
    z->setConstant(std::numeric_limits<double>::quiet_NaN());  // the PCG reports cg_non_finite
    return;
  }
  std::memcpy(z->data(), m.x->x, 3 * n * sizeof(double));
}

long CholeskyFactor::factor_nonzeros() const {
  const Impl& m = *impl_;
  if (!m.factor) return 0;
  if (m.factor->is_super) {
    // Supernodal: the column counts of the supernodes' lower trapezoids.
    long nnz = 0;
    const int* super = static_cast<const int*>(m.factor->super);
    const int* pi = static_cast<const int*>(m.factor->pi);
    for (size_t s = 0; s < m.factor->nsuper; ++s) {
      const long ncols = super[s + 1] - super[s], nrows = pi[s + 1] - pi[s];
      nnz += ncols * nrows - ncols * (ncols - 1) / 2;
    }
    return nnz;
  }
  long nnz = 0;
  const int* cnt = static_cast<const int*>(m.factor->nz);
  for (size_t k = 0; k < m.factor->n; ++k) nnz += cnt[k];
  return nnz;
}

bool CholeskyFactor::supernodal() const { return impl_->factor && impl_->factor->is_super; }

}  // namespace clothbench
