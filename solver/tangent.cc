// J_α = M − αh ∂f/∂v − α²h² ∂f/∂x (docs/model.md §10;
// Baraff & Witkin 1998, eq. 18), assembled from closed-form 3×3 blocks.
#include "solver/tangent.h"

#include <algorithm>
#include <cmath>

namespace clothbench {
namespace {

// The compressed column-major 3N×3N pattern of the block pairs, their
// transposes and the diagonal blocks, every block dense (3×3). Built per
// block column with counting, then sorted and deduplicated per column.
SparseMatrix BlockPattern(int n, const std::vector<BlockPair>& blocks) {
  std::vector<std::size_t> start(static_cast<std::size_t>(n) + 1, 0);
  for (const BlockPair& b : blocks) {
    ++start[static_cast<std::size_t>(b[1]) + 1];
    ++start[static_cast<std::size_t>(b[0]) + 1];
  }
  for (std::size_t p = 0; p < static_cast<std::size_t>(n); ++p) start[p + 1] += start[p] + 1;  // + the diagonal
  std::vector<int> rows(start.back());
  std::vector<std::size_t> fill(start.begin(), start.end() - 1);
  for (int p = 0; p < n; ++p) rows[fill[static_cast<std::size_t>(p)]++] = p;
  for (const BlockPair& b : blocks) {
    rows[fill[static_cast<std::size_t>(b[1])]++] = b[0];
    rows[fill[static_cast<std::size_t>(b[0])]++] = b[1];
  }
  std::vector<int> count(static_cast<std::size_t>(n));
#pragma omp parallel for schedule(static) if (n >= kParallelMinimum)
  for (int p = 0; p < n; ++p) {
    auto first = rows.begin() + static_cast<std::ptrdiff_t>(start[static_cast<std::size_t>(p)]);
    auto last = rows.begin() + static_cast<std::ptrdiff_t>(start[static_cast<std::size_t>(p) + 1]);
    std::sort(first, last);
    count[static_cast<std::size_t>(p)] = static_cast<int>(std::unique(first, last) - first);
  }
  Eigen::Index nnz = 0;
  for (int c : count) nnz += 9 * static_cast<Eigen::Index>(c);
  SparseMatrix m(3 * n, 3 * n);
  m.resizeNonZeros(nnz);
  int* outer = m.outerIndexPtr();
  int* inner = m.innerIndexPtr();
  int pos = 0;
  for (int p = 0; p < n; ++p)
    for (int q = 0; q < 3; ++q) {
      outer[3 * p + q] = pos;
      const std::size_t s = start[static_cast<std::size_t>(p)];
      for (int k = 0; k < count[static_cast<std::size_t>(p)]; ++k)
        for (int r = 0; r < 3; ++r) inner[pos++] = 3 * rows[s + static_cast<std::size_t>(k)] + r;
    }
  outer[3 * n] = pos;
  m.coeffs().setZero();
  return m;
}

}  // namespace

TangentSystem::TangentSystem(const ParticleSystem& system, const TangentOptions& options)
    : sys_(system), options_(options) {
  linear_tension_ = system.scene().material.tension_model == TensionModel::kLinear;
  const int n = system.num_particles();
  const std::vector<Spring>& springs = system.springs();
  std::vector<BlockPair> blocks;
  blocks.reserve(4 * springs.size());
  for (const Spring& s : springs) {
    blocks.push_back({s.a, s.b});
    blocks.push_back({s.a, s.a});
    blocks.push_back({s.b, s.a});
    blocks.push_back({s.b, s.b});
  }
  const std::size_t spring_blocks = blocks.size();
  std::vector<std::size_t> term_begin;
  bool velocity = system.has_tension_damping();
  for (const auto& term : system.terms()) {
    // The virtual springs (model/virtual_springs.h) belong to the
    // tension: in J_α whatever include_explicit_terms says.
    if (options_.include_explicit_terms || term->name() == "virtual_springs") {
      if (term->name() == "tension_nonlinear") continue;  // in the spring blocks
      std::vector<BlockPair> tb;
      term->JacobianBlocks(&tb);
      if (tb.empty()) continue;  // gravity
      terms_.push_back(term.get());
      term_begin.push_back(blocks.size());
      blocks.insert(blocks.end(), tb.begin(), tb.end());
      velocity = velocity || term->depends_on_velocity();
      kv_constant_ = kv_constant_ && !term->depends_on_velocity();
    }
  }
  j_ = BlockPattern(n, blocks);
  const std::vector<int> pos = BlockPositions(j_, blocks);
  spring_pos_.assign(pos.begin(), pos.begin() + static_cast<std::ptrdiff_t>(3 * spring_blocks));
  for (std::size_t k = 0; k < terms_.size(); ++k) {
    const std::size_t end = k + 1 < terms_.size() ? term_begin[k + 1] : blocks.size();
    term_pos_.emplace_back(pos.begin() + static_cast<std::ptrdiff_t>(3 * term_begin[k]),
                           pos.begin() + static_cast<std::ptrdiff_t>(3 * end));
  }
  // The fused sweep's chunks: springs by their end a, term items in
  // proportion (stencil terms have one centre per particle, in particle
  // order); chunks double in size until 64 colours suffice.
  std::vector<std::size_t> items, per_item;
  for (std::size_t k = 0; k < terms_.size(); ++k) {
    items.push_back(terms_[k]->jacobian_items());
    const std::size_t end = k + 1 < terms_.size() ? term_begin[k + 1] : blocks.size();
    per_item.push_back(items.back() ? (end - term_begin[k]) / items.back() : 0);
  }
  const auto item_at = [&](std::size_t k, std::size_t chunk_start) {  // first item of term k in a chunk
    return std::min(items[k], (chunk_start * items[k] + static_cast<std::size_t>(n) - 1) / static_cast<std::size_t>(n));
  };
  for (chunk_ = 512;; chunk_ *= 2) {
    const std::size_t chunks = (static_cast<std::size_t>(n) + chunk_ - 1) / chunk_;
    spring_begin_.assign(chunks + 1, 0);
    for (const Spring& sp : springs) ++spring_begin_[static_cast<std::size_t>(sp.a) / chunk_ + 1];
    for (std::size_t c = 0; c < chunks; ++c) spring_begin_[c + 1] += spring_begin_[c];
    spring_order_.resize(springs.size());
    std::vector<std::size_t> fill(spring_begin_.begin(), spring_begin_.end() - 1);
    for (std::size_t sp = 0; sp < springs.size(); ++sp)
      spring_order_[fill[static_cast<std::size_t>(springs[sp].a) / chunk_]++] = sp;
    item_begin_.assign(terms_.size(), std::vector<std::size_t>(chunks + 1, 0));
    for (std::size_t k = 0; k < terms_.size(); ++k)
      for (std::size_t c = 0; c <= chunks; ++c) item_begin_[k][c] = item_at(k, std::min(c * chunk_, static_cast<std::size_t>(n)));
    const bool ok = colouring_.Build(n, chunks, [&](std::size_t c, auto visit) {
      for (std::size_t q = spring_begin_[c]; q < spring_begin_[c + 1]; ++q) {
        visit(springs[spring_order_[q]].a);
        visit(springs[spring_order_[q]].b);
      }
      for (std::size_t k = 0; k < terms_.size(); ++k)
        for (std::size_t b = term_begin[k] + item_begin_[k][c] * per_item[k];
             b < term_begin[k] + item_begin_[k][c + 1] * per_item[k]; ++b)
          visit(blocks[b][0]);
    });
    if (ok) break;
  }
  kx_.setZero(j_.nonZeros());
  if (velocity) kv_.setZero(j_.nonZeros());
  diag_pos_.resize(3 * static_cast<std::size_t>(n));
  transpose_pos_.resize(static_cast<std::size_t>(j_.nonZeros()));
  const int* outer = j_.outerIndexPtr();
  const int* inner = j_.innerIndexPtr();
#pragma omp parallel for schedule(static) if (n >= kParallelMinimum)
  for (int col = 0; col < 3 * n; ++col)
    for (int e = outer[col]; e < outer[col + 1]; ++e) {
      const int row = inner[e];
      const int* it = std::lower_bound(inner + outer[row], inner + outer[row + 1], col);  // the pattern is symmetric
      transpose_pos_[static_cast<std::size_t>(e)] = static_cast<int>(it - inner);
      if (row == col) diag_pos_[static_cast<std::size_t>(col)] = e;
    }
  if (kv_.size() && kv_constant_) {  // the springs' damping c_e I, once
    Eigen::VectorXd unused = Eigen::VectorXd::Zero(kx_.size());
    for (std::size_t k = 0; k < springs.size(); ++k) AddSpring(k, system.rest_positions(), unused.data(), kv_.data());
  }
}

inline void TangentSystem::AddSpring(std::size_t k, const MatrixN3& x, double* kx, double* kv) const {
  // ∂F_a/∂x_b = s_e [c (I − d̂d̂ᵀ) + d̂d̂ᵀ], c = 1 − l_e/|d| (clamped at 0 with
  // kClamp); ∂F_a/∂x_a is its negative. Damping c_e (v_b − v_a), (3.18):
  // ∂F_a/∂v_b = c_e I.
  const Spring& s = sys_.springs()[k];
  const bool linear = linear_tension_;
  const Vector3 d = (x.row(s.b) - x.row(s.a)).transpose();
  const double len = d.norm();
  const double rest = linear ? 0.0 : s.rest_length;
  double c = len > 0.0 ? 1.0 - rest / len : 1.0;
  if (options_.projection == TangentProjection::kClamp) c = std::max(c, 0.0);
  const Vector3 dh = len > 0.0 ? Vector3(d / len) : Vector3::Zero();
  // The "linear" tension model (zero rest length) has c = 1: s_e I.
  Matrix3 kk = (s.stiffness * (1.0 - c)) * dh * dh.transpose();
  kk.diagonal().array() += s.stiffness * c;
  const int* p = spring_pos_.data() + 12 * k;
  AddBlock(kk, p, kx);
  AddBlock(-kk, p + 3, kx);
  AddBlock(kk, p + 6, kx);
  AddBlock(-kk, p + 9, kx);
  if (kv && s.damping > 0.0) {
    const Matrix3 cd = s.damping * Matrix3::Identity();
    AddBlock(cd, p, kv);
    AddBlock(-cd, p + 3, kv);
    AddBlock(cd, p + 6, kv);
    AddBlock(-cd, p + 9, kv);
  }
}

void TangentSystem::Update(double t, const MatrixN3& x, const MatrixN3& v, double alpha_h) {
  kx_.setZero();
  double* kx = kx_.data();
  double* kv = kv_.size() ? kv_.data() : nullptr;
  if (kv && !kv_constant_) kv_.setZero();
  double* spring_kv = kv_constant_ ? nullptr : kv;
  // One sweep over the chunks: a chunk's springs, then each term's items,
  // while the chunk's entries are in cache.
  colouring_.ForEach(
      [&](std::size_t c) {
        for (std::size_t q = spring_begin_[c]; q < spring_begin_[c + 1]; ++q) AddSpring(spring_order_[q], x, kx, spring_kv);
        for (std::size_t k = 0; k < terms_.size(); ++k)
          terms_[k]->AccumulateJacobian(t, x, v, term_pos_[k].data(), kx, kv, item_begin_[k][c], item_begin_[k][c + 1]);
      },
      sys_.num_particles() >= kBlockParallelMinimum);
  SetAlphaH(alpha_h);
}

void TangentSystem::AddToDiagonal(const Eigen::VectorXd& d) {
  double* vals = j_.valuePtr();
  for (std::size_t k = 0; k < diag_pos_.size(); ++k) vals[diag_pos_[k]] += d(static_cast<Eigen::Index>(k / 3));
}

void TangentSystem::SetAlphaH(double alpha_h) {
  const Eigen::Index nnz = j_.nonZeros();
  const double* kx = kx_.data();
  const double* kv = kv_.size() ? kv_.data() : nullptr;
  // J_α = M − αh ∂f/∂v − α²h² ∂f/∂x, or its symmetric part (J + Jᵀ)/2 if
  // options_.symmetrize (M is diagonal: its own symmetric part), in one pass
  // over the entries; the constant part comes from base_.
  const int* tp = transpose_pos_.data();
  const bool sym = options_.symmetrize;
  const double cx = -alpha_h * alpha_h, cv = -alpha_h;
  if (alpha_h != base_alpha_h_) {
    base_.setZero(nnz);
    if (kv && kv_constant_)
      for (Eigen::Index e = 0; e < nnz; ++e) base_[e] = sym ? 0.5 * cv * (kv[e] + kv[tp[e]]) : cv * kv[tp[e]];
    const Eigen::VectorXd& m = sys_.masses();
    for (std::size_t k = 0; k < diag_pos_.size(); ++k) base_[diag_pos_[k]] += m(static_cast<Eigen::Index>(k / 3));
    base_alpha_h_ = alpha_h;
  }
  double* vals = j_.valuePtr();
  const double* base = base_.data();
  const double* kvar = kv_constant_ ? nullptr : kv;  // ∂f/∂v of this state
  // Separate loops with and without a state-dependent ∂f/∂v, so that the
  // common one (constant ∂f/∂v) has no branch.
  const double hx = 0.5 * cx, hv = 0.5 * cv;
  if (sym && kvar) {
    SymmetricPass<true, true>(hx, hv, kvar);
  } else if (sym && kv) {
    SymmetricPass<false, true>(hx, hv, nullptr);
  } else if (sym) {
    SymmetricPass<false, false>(hx, hv, nullptr);
    const Eigen::VectorXd& m = sys_.masses();
    for (std::size_t k = 0; k < diag_pos_.size(); ++k)
      vals[diag_pos_[k]] = m(static_cast<Eigen::Index>(k / 3)) + vals[diag_pos_[k]];
  } else if (kvar) {  // kx, kv in row storage: entry e of J_α is at tp[e] there
#pragma omp parallel for schedule(static) if (nnz >= 9 * kParallelMinimum)
    for (Eigen::Index e = 0; e < nnz; ++e) vals[e] = base[e] + cx * kx[tp[e]] + cv * kvar[tp[e]];
  } else {
#pragma omp parallel for schedule(static) if (nnz >= 9 * kParallelMinimum)
    for (Eigen::Index e = 0; e < nnz; ++e) vals[e] = base[e] + cx * kx[tp[e]];
  }
  alpha_h_ = alpha_h;
}

template <bool kVelocity, bool kBase>
void TangentSystem::SymmetricPass(double hx, double hv, const double* kvar) {
  // Entry by entry in storage order (streaming reads and writes; the
  // transposed entry of a grid neighbour is a few block columns away, in
  // cache). Measured faster than a pass over block pairs, which writes both
  // blocks of a pair at once (BM_TangentSetAlphaH).
  const Eigen::Index nnz = j_.nonZeros();
  const int* tp = transpose_pos_.data();
  const double* kx = kx_.data();
  const double* base = base_.data();
  double* vals = j_.valuePtr();
#pragma omp parallel for schedule(static) if (nnz >= 9 * kParallelMinimum)
  for (Eigen::Index e = 0; e < nnz; ++e) {
    const int te = tp[e];
    double val = hx * (kx[e] + kx[te]);
    if constexpr (kVelocity) val += hv * (kvar[e] + kvar[te]);
    if constexpr (kBase) val = base[e] + val;
    vals[e] = val;
  }
}

void TangentSystem::AddJacobianProducts(double cx, const MatrixN3& u, double cv, const MatrixN3& w,
                                        MatrixN3* out) const {
  // Row i of K u: row i of the row storage (column i of the arrays).
  const int n3 = static_cast<int>(j_.rows());
  const int* outer = j_.outerIndexPtr();
  const int* inner = j_.innerIndexPtr();
  const bool with_v = cv != 0.0 && kv_.size();
#pragma omp parallel for schedule(static) if (n3 >= 3 * kParallelMinimum)
  for (int i = 0; i < n3; ++i) {
    double sum = 0.0;
    for (int e = outer[i]; e < outer[i + 1]; ++e) {
      const int j = inner[e];
      if (cx != 0.0) sum += cx * kx_[e] * u(j / 3, j % 3);
      if (with_v) sum += cv * kv_[e] * w(j / 3, j % 3);
    }
    (*out)(i / 3, i % 3) += sum;
  }
}

}  // namespace clothbench
