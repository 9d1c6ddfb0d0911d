// CHOLMOD factor of A_F (docs/model.md §5). CHOLMOD is confined to this file.
#include "solver/cholesky.h"

#include "model/interrupt.h"
#include "solver/decoupled.h"

#include <cholmod.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <limits>
#include <vector>

#include <omp.h>

namespace clothbench {

struct CholeskyFactor::Impl {
  cholmod_common common;
  cholmod_sparse* upper = nullptr;   // A_F, upper triangle (stype = 1)
  cholmod_factor* factor = nullptr;  // supernodal where CHOLMOD chooses it: fast (BLAS-3) factorisation
  cholmod_factor* solver = nullptr;  // simplicial LLᵀ copy for the solves (see Factorize)
  std::vector<int> source;           // position in A's values of each entry of `upper`
  std::vector<int> iperm;            // pivot position of each particle (inverse of the factor's Perm)
  std::vector<char> fixed;           // the decoupled fixed particles of A_F
  cholmod_sparse* row = nullptr;     // one column of the matrix (row add, and the pattern for row delete)
  cholmod_sparse* reach = nullptr;   // the pattern of a row of L (row delete)
  // Solve workspaces, reused (cholmod_solve2 allocates them once): lane 0
  // solves columns 0 and 1 (or all three), lane 1 column 2, each with its
  // own Common, on two OpenMP threads.
  struct Lane {
    cholmod_common common;
    cholmod_dense* x = nullptr;
    cholmod_dense* y = nullptr;
    cholmod_dense* e = nullptr;
  };
  std::array<Lane, 2> lanes;
  bool factorized = false;

  // The tree-parallel solve of a fresh simplicial LLᵀ factor (BuildTree,
  // TreeSolve): the elimination tree's upper part `top` (the heaviest
  // subtrees' roots, upward closed) and, below it, disjoint subtrees dealt
  // to two parts; each subtree is a contiguous column range [first, root]
  // (CHOLMOD postorders the tree). Invalid after a row modification.
  struct Tree {
    bool ready = false;
    std::vector<int> perm;                                  // pivot k holds particle perm[k]
    std::array<std::vector<std::array<int, 2>>, 2> ranges;  // per part: [first, root] column ranges
    std::vector<int> top;                                   // the other columns, increasing
    std::vector<int> slot;                                  // per column: its index in top, −1 in a part
    std::vector<double> y;                                  // 3n: the three right-hand sides interleaved
    std::array<std::vector<double>, 2> acc;                 // per part: its updates of the top rows, 3|top|
  } tree;
  void BuildTree();
  void TreeSolve(const MatrixN3& r, MatrixN3* z);

  Impl() {
    cholmod_start(&common);
    common.print = 0;
    common.error_handler = nullptr;
    for (Lane& l : lanes) {
      cholmod_start(&l.common);
      l.common.print = 0;
      l.common.error_handler = nullptr;
    }
  }
  ~Impl() {
    for (Lane& l : lanes) {
      cholmod_free_dense(&l.x, &l.common);
      cholmod_free_dense(&l.y, &l.common);
      cholmod_free_dense(&l.e, &l.common);
      cholmod_finish(&l.common);
    }
    cholmod_free_factor(&solver, &common);
    cholmod_free_factor(&factor, &common);
    cholmod_free_sparse(&upper, &common);
    cholmod_free_sparse(&row, &common);
    cholmod_free_sparse(&reach, &common);
    cholmod_finish(&common);
  }
};

// The plan of TreeSolve for the factor the solves use, checked entry by
// entry: a packed, monotonic simplicial LLᵀ factor whose columns hold the
// diagonal first and rows in increasing order, and whose every entry lies
// in its column's subtree range or in `top` (for a column of `top`: in
// `top`). Anything else leaves tree.ready false (CHOLMOD's solve then).
// O(nnz(L)), after each factorisation (a few percent of its time).
void CholeskyFactor::Impl::BuildTree() {
  tree.ready = false;
  const cholmod_factor* l = solver ? solver : factor;
  if (!l || l->is_super || !l->is_ll || !l->is_monotonic || l->xtype != CHOLMOD_REAL || l->itype != CHOLMOD_INT)
    return;
  const int n = static_cast<int>(l->n);
  const int* lp = static_cast<const int*>(l->p);
  const int* li = static_cast<const int*>(l->i);
  const int* lnz = static_cast<const int*>(l->nz);
  std::vector<int> parent(static_cast<std::size_t>(n), -1), first(static_cast<std::size_t>(n));
  std::vector<double> weight(static_cast<std::size_t>(n));
  for (int j = 0; j < n; ++j) {
    const auto uj = static_cast<std::size_t>(j);
    const int b = lp[j], e = lp[j + 1];
    if (e <= b || lnz[j] != e - b || li[b] != j) return;
    for (int q = b + 1; q < e; ++q)
      if (li[q] <= li[q - 1]) return;
    if (e - b > 1) parent[uj] = li[b + 1];
    first[uj] = j;
    weight[uj] += e - b;
  }
  for (int j = 0; j < n; ++j) {  // children before parents: parent > j
    const auto uj = static_cast<std::size_t>(j);
    if (parent[uj] < 0) continue;
    const auto up = static_cast<std::size_t>(parent[uj]);
    weight[up] += weight[uj];
    first[up] = std::min(first[up], first[uj]);
  }
  std::vector<std::vector<int>> children(static_cast<std::size_t>(n));
  std::vector<int> list;
  double total = 0.0;
  for (int j = 0; j < n; ++j) {
    if (parent[static_cast<std::size_t>(j)] >= 0) {
      children[static_cast<std::size_t>(parent[static_cast<std::size_t>(j)])].push_back(j);
    } else {
      list.push_back(j);
      total += weight[static_cast<std::size_t>(j)];
    }
  }
  // Split the heaviest subtree at its root while it holds more than half
  // of the factor (the nested dissection's separators), then deal the
  // subtrees to the two parts, heaviest first to the lighter part.
  std::vector<int> top;
  for (;;) {
    const auto h = std::max_element(list.begin(), list.end(), [&](int a, int b) {
      return weight[static_cast<std::size_t>(a)] < weight[static_cast<std::size_t>(b)];
    });
    if (h == list.end() || weight[static_cast<std::size_t>(*h)] <= 0.5 * total ||
        children[static_cast<std::size_t>(*h)].empty() || static_cast<int>(top.size()) >= n / 8)
      break;
    const int root = *h;
    list.erase(h);
    top.push_back(root);
    for (int c : children[static_cast<std::size_t>(root)]) list.push_back(c);
  }
  std::sort(list.begin(), list.end(), [&](int a, int b) {
    const double wa = weight[static_cast<std::size_t>(a)], wb = weight[static_cast<std::size_t>(b)];
    return wa != wb ? wa > wb : a < b;
  });
  std::array<double, 2> load = {0.0, 0.0};
  std::array<std::vector<std::array<int, 2>>, 2> ranges;
  std::vector<int> owner(static_cast<std::size_t>(n), -1);  // part, or 2 for top
  for (int root : list) {
    const int t = load[1] < load[0] ? 1 : 0;
    load[static_cast<std::size_t>(t)] += weight[static_cast<std::size_t>(root)];
    const int f = first[static_cast<std::size_t>(root)];
    ranges[static_cast<std::size_t>(t)].push_back({f, root});
    for (int j = f; j <= root; ++j) {
      if (owner[static_cast<std::size_t>(j)] != -1) return;  // not a postorder: ranges overlap
      owner[static_cast<std::size_t>(j)] = t;
    }
  }
  std::sort(top.begin(), top.end());
  std::vector<int> slot(static_cast<std::size_t>(n), -1);
  for (std::size_t s = 0; s < top.size(); ++s) {
    const auto u = static_cast<std::size_t>(top[s]);
    if (owner[u] != -1) return;
    owner[u] = 2;
    slot[u] = static_cast<int>(s);
  }
  for (int j = 0; j < n; ++j)
    if (owner[static_cast<std::size_t>(j)] == -1) return;  // a column in no range
  // Every entry below the diagonal: in its column's range, or in top.
  for (int t = 0; t < 2; ++t)
    for (const auto& [f, root] : ranges[static_cast<std::size_t>(t)])
      for (int j = f; j <= root; ++j)
        for (int q = lp[j] + 1; q < lp[j + 1]; ++q)
          if (li[q] > root && slot[static_cast<std::size_t>(li[q])] < 0) return;
  for (int j : top)
    for (int q = lp[j] + 1; q < lp[j + 1]; ++q)
      if (slot[static_cast<std::size_t>(li[q])] < 0) return;
  for (auto& r : ranges) std::sort(r.begin(), r.end());
  tree.perm.assign(static_cast<const int*>(l->Perm), static_cast<const int*>(l->Perm) + n);
  tree.ranges = std::move(ranges);
  tree.top = std::move(top);
  tree.slot = std::move(slot);
  tree.y.assign(3 * static_cast<std::size_t>(n), 0.0);
  for (auto& a : tree.acc) a.assign(3 * tree.top.size(), 0.0);
  tree.ready = true;
}

// z ← A_F⁻¹ r = Pᵀ L⁻ᵀ L⁻¹ P r for the three columns in one pass over L
// each way, the two parts' subtrees on two OpenMP threads:
//  - forward (L y = P r): each part runs its ranges in increasing column
//    order, writing rows of its own range and adding its updates of the
//    top rows to its own accumulator; then the top rows take part 0's and
//    part 1's sums, in that order, and the top columns run serially;
//  - backward (Lᵀ x = y): the top columns serially, in decreasing order,
//    then each part's ranges in decreasing order (they read only their own
//    rows and the finished top rows).
// The order of every operation is fixed by the factor, not by the thread
// count: the result is the same with one thread or two.
void CholeskyFactor::Impl::TreeSolve(const MatrixN3& r, MatrixN3* z) {
  const cholmod_factor* l = solver ? solver : factor;
  const int n = static_cast<int>(l->n);
  const int* lp = static_cast<const int*>(l->p);
  const int* li = static_cast<const int*>(l->i);
  const double* lx = static_cast<const double*>(l->x);
  const int* perm = tree.perm.data();
  const int* slot = tree.slot.data();
  double* y = tree.y.data();
  const double* r0 = r.col(0).data();
  const double* r1 = r.col(1).data();
  const double* r2 = r.col(2).data();
  const bool parallel = n >= kParallelSolveRows;
  const int threads = std::min(2, omp_get_max_threads());  // OMP_NUM_THREADS=1: one core
#pragma omp parallel for num_threads(threads) schedule(static) if (parallel)
  for (int k = 0; k < n; ++k) {
    const int p = perm[k];
    y[3 * k] = r0[p];
    y[3 * k + 1] = r1[p];
    y[3 * k + 2] = r2[p];
  }
  // Forward: y_j ← y_j / L_jj, returned for the updates below it.
  const auto pivot = [&](int j) {
    const double d = lx[lp[j]];
    const std::array<double, 3> yj = {y[3 * j] / d, y[3 * j + 1] / d, y[3 * j + 2] / d};
    std::copy(yj.begin(), yj.end(), y + 3 * j);
    return yj;
  };
#pragma omp parallel for num_threads(threads) schedule(static, 1) if (parallel)
  for (int t = 0; t < 2; ++t) {
    double* acc = tree.acc[static_cast<std::size_t>(t)].data();
    std::fill_n(acc, tree.acc[static_cast<std::size_t>(t)].size(), 0.0);
    for (const auto& [f, root] : tree.ranges[static_cast<std::size_t>(t)])
      for (int j = f; j <= root; ++j) {
        const int b = lp[j], e = lp[j + 1];
        const auto [y0, y1, y2] = pivot(j);
        for (int q = b + 1; q < e; ++q) {
          const int i = li[q];
          const double w = lx[q];
          double* dst = i <= root ? y + 3 * i : acc + 3 * slot[i];
          const double sign = i <= root ? 1.0 : -1.0;  // rows of the range: y −= w y_j; top: acc += w y_j
          dst[0] -= sign * w * y0;
          dst[1] -= sign * w * y1;
          dst[2] -= sign * w * y2;
        }
      }
  }
  const std::size_t nt = tree.top.size();
  for (std::size_t s = 0; s < nt; ++s) {
    double* dst = y + 3 * tree.top[s];
    for (int c = 0; c < 3; ++c) dst[c] -= tree.acc[0][3 * s + static_cast<std::size_t>(c)];
    for (int c = 0; c < 3; ++c) dst[c] -= tree.acc[1][3 * s + static_cast<std::size_t>(c)];
  }
  for (int j : tree.top) {
    const int b = lp[j], e = lp[j + 1];
    const auto [y0, y1, y2] = pivot(j);
    for (int q = b + 1; q < e; ++q) {
      const int i = li[q];
      y[3 * i] -= lx[q] * y0;
      y[3 * i + 1] -= lx[q] * y1;
      y[3 * i + 2] -= lx[q] * y2;
    }
  }
  const auto back = [&](int j) {
    const int b = lp[j], e = lp[j + 1];
    double s0 = y[3 * j], s1 = y[3 * j + 1], s2 = y[3 * j + 2];
    for (int q = b + 1; q < e; ++q) {
      const int i = li[q];
      const double w = lx[q];
      s0 -= w * y[3 * i];
      s1 -= w * y[3 * i + 1];
      s2 -= w * y[3 * i + 2];
    }
    const double d = lx[b];
    y[3 * j] = s0 / d;
    y[3 * j + 1] = s1 / d;
    y[3 * j + 2] = s2 / d;
  };
  for (std::size_t s = nt; s-- > 0;) back(tree.top[s]);
#pragma omp parallel for num_threads(threads) schedule(static, 1) if (parallel)
  for (int t = 0; t < 2; ++t) {
    const auto& ranges = tree.ranges[static_cast<std::size_t>(t)];
    for (std::size_t g = ranges.size(); g-- > 0;)
      for (int j = ranges[g][1]; j >= ranges[g][0]; --j) back(j);
  }
  double* z0 = z->col(0).data();
  double* z1 = z->col(1).data();
  double* z2 = z->col(2).data();
#pragma omp parallel for num_threads(threads) schedule(static) if (parallel)
  for (int k = 0; k < n; ++k) {
    const int p = perm[k];
    z0[p] = y[3 * k];
    z1[p] = y[3 * k + 1];
    z2[p] = y[3 * k + 2];
  }
}

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
  ThrowIfInterrupted();  // Ctrl-C during the ordering (METIS has no callback): raised as it returns
  if (!m.factor || m.common.status != CHOLMOD_OK) return false;
  const int* perm = static_cast<const int*>(m.factor->Perm);
  m.iperm.assign(static_cast<std::size_t>(n), 0);
  for (int k = 0; k < n; ++k) m.iperm[static_cast<std::size_t>(perm[k])] = k;
  m.fixed.assign(static_cast<std::size_t>(n), 0);
  for (int p : fixed) m.fixed[static_cast<std::size_t>(p)] = 1;
  return true;
}

bool CholeskyFactor::DecoupleRow(int p, const SparseMatrix& a) {
  Impl& m = *impl_;
  m.tree.ready = false;  // the row delete changes L (and makes it LDLᵀ)
  cholmod_factor* l = m.solver ? m.solver : m.factor;
  if (!m.factorized || !l || !PrepareRow(a.cols(), a.outerIndexPtr()[p + 1] - a.outerIndexPtr()[p])) return false;
  const auto n = static_cast<size_t>(a.rows());
  const int k = m.iperm[static_cast<std::size_t>(p)];
  // The pattern of row k of L, which the row delete would otherwise search
  // for in columns 0 … k−1 of L (O(nnz(L)) per delete): the reach of
  // A(0:k−1, k) in L's elimination tree (a superset is allowed), cut at k.
  int* rows = static_cast<int*>(m.row->i);
  int nz = 0;
  for (int pos = a.outerIndexPtr()[p]; pos < a.outerIndexPtr()[p + 1]; ++pos) {
    const int i = m.iperm[static_cast<std::size_t>(a.innerIndexPtr()[pos])];
    if (i < k) rows[nz++] = i;
  }
  static_cast<int*>(m.row->p)[0] = 0;
  static_cast<int*>(m.row->p)[1] = nz;
  if (!m.reach) {
    m.reach = cholmod_allocate_sparse(n, 1, n, /*sorted=*/0, /*packed=*/1, /*stype=*/0, CHOLMOD_PATTERN, &m.common);
    if (!m.reach) return false;
  }
  if (nz > 0 && !cholmod_lsolve_pattern(m.row, l, m.reach, &m.common)) return false;
  int* reach = static_cast<int*>(m.reach->i);
  int* reach_p = static_cast<int*>(m.reach->p);
  int kept = 0;
  if (nz > 0)
    for (int q = 0; q < reach_p[1]; ++q)
      if (reach[q] < k) reach[kept++] = reach[q];
  reach_p[0] = 0;
  reach_p[1] = kept;
  if (!cholmod_rowdel(static_cast<size_t>(k), m.reach, l, &m.common) || m.common.status != CHOLMOD_OK) return false;
  // Row and column k of L are now those of the identity, and D(k, k) = 1.
  // Setting D(k, k) = a_pp (the diagonal comes first in a simplicial
  // column) makes the factor that of A_F with p decoupled and its diagonal
  // kept, the factor a refactorisation with p decoupled gives.
  const int* lp = static_cast<const int*>(l->p);
  double diagonal = 0.0;
  for (int pos = a.outerIndexPtr()[p]; pos < a.outerIndexPtr()[p + 1]; ++pos)
    if (a.innerIndexPtr()[pos] == p) diagonal = a.valuePtr()[pos];
  static_cast<double*>(l->x)[lp[k]] = diagonal;
  return true;
}

bool CholeskyFactor::PrepareRow(long n, long nnz) {
  Impl& m = *impl_;
  if (m.row && m.row->nzmax >= static_cast<size_t>(nnz)) return true;
  cholmod_free_sparse(&m.row, &m.common);
  m.row = cholmod_allocate_sparse(static_cast<size_t>(n), 1, static_cast<size_t>(std::max(nnz, 32L)), /*sorted=*/0,
                                  /*packed=*/1, /*stype=*/0, CHOLMOD_REAL, &m.common);
  return m.row != nullptr;
}

bool CholeskyFactor::CoupleRow(int p, const SparseMatrix& a, const std::vector<char>& decoupled) {
  Impl& m = *impl_;
  m.tree.ready = false;  // the row add changes L
  cholmod_factor* l = m.solver ? m.solver : m.factor;
  if (!m.factorized || !l) return false;
  const int begin = a.outerIndexPtr()[p], end = a.outerIndexPtr()[p + 1];
  if (!PrepareRow(a.cols(), end - begin)) return false;
  // Column p of A_F with the decoupled particles' entries left out, in the
  // factor's (permuted) numbering.
  int* rows = static_cast<int*>(m.row->i);
  double* vals = static_cast<double*>(m.row->x);
  int nz = 0;
  for (int pos = begin; pos < end; ++pos) {
    const int q = a.innerIndexPtr()[pos];
    const auto uq = static_cast<std::size_t>(q);
    if (q != p && (decoupled[uq] || m.fixed[uq])) continue;
    rows[nz] = m.iperm[uq];
    vals[nz++] = a.valuePtr()[pos];
  }
  static_cast<int*>(m.row->p)[0] = 0;
  static_cast<int*>(m.row->p)[1] = nz;
  return cholmod_rowadd(static_cast<size_t>(m.iperm[static_cast<std::size_t>(p)]), m.row, l, &m.common) != 0 &&
         m.common.status == CHOLMOD_OK;
}

bool CholeskyFactor::Factorize(const SparseMatrix& a) { return Factorize(a, nullptr); }

std::unique_ptr<CholeskyFactor> CholeskyFactor::CloneAnalysis() const {
  const Impl& m = *impl_;
  if (!m.factor || !m.upper) return nullptr;
  auto out = std::make_unique<CholeskyFactor>();
  Impl& c = *out->impl_;
  c.upper = cholmod_copy_sparse(m.upper, &c.common);
  c.factor = cholmod_copy_factor(m.factor, &c.common);
  c.source = m.source;
  c.iperm = m.iperm;
  c.fixed = m.fixed;
  if (!c.upper || !c.factor) return nullptr;
  return out;
}

bool CholeskyFactor::Factorize(const SparseMatrix& a, const std::vector<char>* decoupled) {
  Impl& m = *impl_;
  m.factorized = false;
  if (!m.factor) return false;
  double* dst = static_cast<double*>(m.upper->x);
  const double* src = a.valuePtr();
  for (std::size_t k = 0; k < m.source.size(); ++k) dst[k] = src[m.source[k]];
  if (decoupled) {
    // Zero every off-diagonal entry of the upper triangle that couples a
    // decoupled particle: the factor is then that of A_F with those rows
    // and columns decoupled, on the same symbolic pattern.
    const int* colptr = static_cast<const int*>(m.upper->p);
    const int* rows = static_cast<const int*>(m.upper->i);
    const std::vector<char>& d = *decoupled;
    for (std::size_t j = 0; j < m.upper->ncol; ++j)
      for (int pos = colptr[j]; pos < colptr[j + 1]; ++pos) {
        const auto i = static_cast<std::size_t>(rows[pos]);
        if (i != j && (d[i] || d[j])) dst[pos] = 0.0;
      }
  }
  const int ok = cholmod_factorize(m.upper, m.factor, &m.common);
  ThrowIfInterrupted();  // Ctrl-C during the factorisation (no callback in CHOLMOD): raised as it returns
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
  m.BuildTree();
  return true;
}

namespace {

// X = L⁻ᵀ L⁻¹ B for `ncol` columns of B starting at `col0` (column-major,
// leading dimension n). cholmod_solve2 asks for its workspace Y as 4×n
// (solves run in chunks of up to 4 columns) but leaves it shaped ncol×n,
// and reallocates a workspace whose shape differs: restoring 4×n (same
// storage) lets it reuse Y, so a solve allocates nothing after the first.
bool CholmodSolve(cholmod_factor* l, const double* b_data, std::size_t n, std::size_t ncol, cholmod_common* common,
                  cholmod_dense** x, cholmod_dense** y, cholmod_dense** e) {
  cholmod_dense b{};
  b.nrow = n;
  b.ncol = ncol;
  b.nzmax = ncol * n;
  b.d = n;
  b.x = const_cast<double*>(b_data);  // read only
  b.z = nullptr;
  b.xtype = CHOLMOD_REAL;
  b.dtype = CHOLMOD_DOUBLE;
  if (*y && (*y)->nrow == ncol && (*y)->ncol == n && (*y)->nzmax >= 4 * n) {
    (*y)->nrow = 4;
    (*y)->d = 4;
  }
  return cholmod_solve2(CHOLMOD_A, l, &b, nullptr, x, nullptr, y, e, common) != 0;
}

}  // namespace

bool CholeskyFactor::SolveColumns(const MatrixN3& r, MatrixN3* z, int col0, int ncol, int lane) const {
  Impl& m = *impl_;
  const auto n = static_cast<std::size_t>(r.rows());
  const auto c0 = static_cast<std::size_t>(col0), nc = static_cast<std::size_t>(ncol);
  Impl::Lane& ln = m.lanes[static_cast<std::size_t>(lane)];
  const bool ok =
      m.factorized && CholmodSolve(m.solver ? m.solver : m.factor, r.data() + c0 * n, n, nc, &ln.common, &ln.x, &ln.y, &ln.e);
  if (ok) std::memcpy(z->data() + c0 * n, ln.x->x, nc * n * sizeof(double));
  else std::fill_n(z->data() + c0 * n, nc * n, std::numeric_limits<double>::quiet_NaN());
  return ok;
}

void CholeskyFactor::Solve(const MatrixN3& r, MatrixN3* z) const {
  Impl& m = *impl_;
  if (m.factorized && m.tree.ready) {
    m.TreeSolve(r, z);
    return;
  }
  const auto n = static_cast<std::size_t>(r.rows());
  // The columns are independent solves with the same L. CHOLMOD's
  // simplicial solve is one thread and latency-bound (scalar loop with
  // indirect addressing), so two threads, one on columns 0–1 and one on
  // column 2, each reading L, take about half the time
  // (docs/notes/performance.md, BM_StepParts). Each lane has its own Common and
  // workspaces; L is only read.
  const bool split = n >= kParallelSolveRows && omp_get_max_threads() >= 2;
  bool ok[2] = {m.factorized, m.factorized};
  if (m.factorized) {
#pragma omp parallel for num_threads(2) schedule(static, 1) if (split)
    for (int lane = 0; lane < 2; ++lane) {
      if (lane == 1 && !split) continue;
      ok[lane] = SolveColumns(r, z, lane == 0 ? 0 : 2, split ? (lane == 0 ? 2 : 1) : 3, lane);
    }
  }
  if (!ok[0] || !ok[1]) z->setConstant(std::numeric_limits<double>::quiet_NaN());  // the PCG reports cg_non_finite
}

double CholeskyFactor::factorization_flops() const { return impl_->factor ? impl_->common.fl : 0.0; }

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

bool CholeskyFactor::tree_solve() const { return impl_->factorized && impl_->tree.ready; }

}  // namespace clothbench
