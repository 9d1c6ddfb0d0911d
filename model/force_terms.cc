// Force terms (docs/model.md, thesis Ch. 2). Stencil terms are written once
// as a force kernel templated on the scalar type: with double it gives the
// force, with forward-mode automatic differentiation (Eigen AutoDiffScalar)
// the Jacobian that tests the closed-form Jacobian blocks each kernel
// derives by hand (Blocks(); derivations beside each kernel and in
// docs/model.md, "Closed-form Jacobians").
#include "model/force_terms.h"

#include "model/block_scatter.h"

#include <algorithm>
#include <array>
#include <type_traits>
#include <utility>
#include <cmath>
#include <cstdint>
#include <mutex>
#include <string>

#include <Eigen/Geometry>
#include <unsupported/Eigen/AutoDiff>

namespace clothbench {
namespace {

template <class S>
using V3 = Eigen::Matrix<S, 3, 1>;

template <class S>
S Norm(const V3<S>& a) {
  using std::sqrt;
  return sqrt(a.squaredNorm());
}

// ---------------------------------------------------------------------------
// Patch layout shared by the grid stencils: slot k holds the particle at
// offset kOffsets[k] from the centre. Shorter stencils use a prefix:
// 5 slots = the cross (shear), 9 = the 3×3 box (normals, membrane, wind, air),
// 13 = the radius-2 diamond (thin plate). A missing neighbour (outside the
// grid) is marked invalid and its slot holds the centre particle.
constexpr std::array<std::array<int, 2>, 13> kOffsets = {{{0, 0},
                                                          {1, 0},
                                                          {-1, 0},
                                                          {0, 1},
                                                          {0, -1},
                                                          {1, 1},
                                                          {-1, 1},
                                                          {1, -1},
                                                          {-1, -1},
                                                          {2, 0},
                                                          {-2, 0},
                                                          {0, 2},
                                                          {0, -2}}};

constexpr int Slot(int di, int dj) {
  for (int k = 0; k < 13; ++k)
    if (kOffsets[k][0] == di && kOffsets[k][1] == dj) return k;
  return -1;
}

// The three-point second difference of values at rest distances hp (ahead)
// and hm (behind) from the middle (docs/model.md §2.7): exact for
// quadratics, the uniform (plus − 2 mid + minus)/h² when hp = hm = h.
template <class T>
T SecondDifference(const T& plus, const T& mid, const T& minus, double hp, double hm) {
  return (2.0 / (hp + hm)) * ((plus - mid) / hp - (mid - minus) / hm);
}

// Read-only view of a gathered patch. `rest`, on a curvilinear pattern, holds
// the slots' rest positions in the pattern's plane, from which the second
// differences take their spacings; null on a uniform grid.
template <class S, int K>
struct Patch {
  const std::array<V3<S>, K>& x;
  std::uint32_t valid;
  const std::array<Eigen::Vector2d, K>* rest = nullptr;
  // The rest distance from patch node (di, dj) to node (ei, ej); l on a uniform grid.
  double Spacing(int di, int dj, int ei, int ej, double l) const {
    if (!rest) return l;
    return ((*rest)[static_cast<std::size_t>(Slot(ei, ej))] - (*rest)[static_cast<std::size_t>(Slot(di, dj))]).norm();
  }
  bool Has(int di, int dj) const {
    const int k = Slot(di, dj);
    return k >= 0 && k < K && ((valid >> k) & 1u);
  }
  // Callers check Has() first; an unknown offset falls back to the centre.
  const V3<S>& At(int di, int dj) const {
    const int k = Slot(di, dj);
    return x[static_cast<std::size_t>(k > 0 && k < K ? k : 0)];
  }
  // Second differences along u and v at patch node (di,dj); zero where that
  // node lies on a border normal to the direction (§6.2.1: no bending force
  // normal to a border).
  V3<S> Lu(int di, int dj, double lu) const {
    if (!Has(di - 1, dj) || !Has(di + 1, dj) || !Has(di, dj)) return V3<S>::Zero();
    if (rest)
      return SecondDifference<V3<S>>(At(di + 1, dj), At(di, dj), At(di - 1, dj), Spacing(di, dj, di + 1, dj, lu),
                                     Spacing(di, dj, di - 1, dj, lu));
    return (At(di + 1, dj) - 2.0 * At(di, dj) + At(di - 1, dj)) / (lu * lu);
  }
  V3<S> Lv(int di, int dj, double lv) const {
    if (!Has(di, dj - 1) || !Has(di, dj + 1) || !Has(di, dj)) return V3<S>::Zero();
    if (rest)
      return SecondDifference<V3<S>>(At(di, dj + 1), At(di, dj), At(di, dj - 1), Spacing(di, dj, di, dj + 1, lv),
                                     Spacing(di, dj, di, dj - 1, lv));
    return (At(di, dj + 1) - 2.0 * At(di, dj) + At(di, dj - 1)) / (lv * lv);
  }
  // Unit vertex normal at the centre: mean of the unit normals of the
  // adjacent quads, each from the cross product of its diagonals (docs/model.md §2.3).
  V3<S> Normal() const {
    V3<S> n = V3<S>::Zero();
    for (int s : {1, -1})
      for (int t : {1, -1}) {
        if (!Has(s, 0) || !Has(0, t) || !Has(s, t)) continue;
        V3<S> nf = (At(s, t) - At(0, 0)).cross(At(0, t) - At(s, 0)) * static_cast<double>(s * t);
        n += nf / Norm(nf);
      }
    return n / Norm(n);
  }
};

// The unit vertex normal n̂ of Patch::Normal and the products
// out[k] = G ∂n̂/∂x_k for the 9 slots of the 3×3 box, with G = left(n̂) a
// 3×3 matrix the caller derives from n̂. A quad's normal is nf = st (p × q)
// with p = x_st − x_0, q = x_0t − x_s0, and d(p × q) = −[q]× dp + [p]× dq, so
// ∂nf/∂x_st = −st[q]×, ∂nf/∂x_0 = st[q]×, ∂nf/∂x_0t = st[p]×,
// ∂nf/∂x_s0 = −st[p]×; a normalisation u = w/|w| has ∂u = (I − ûûᵀ)/|w| ∂w,
// once per quad and once for the mean n = Σ nf/|nf|. G is carried through
// the projections from the left (rank-one updates), so each quad costs one
// product with each skew matrix.
template <int K, class LeftOf>
Vector3 NormalJacobian(const Patch<double, K>& patch, LeftOf left, std::array<Matrix3, 9>* out) {
  struct Quad {
    int s, t;
    Vector3 p, q, fh;
    double scale;  // st/|nf|
  };
  std::array<Quad, 4> quads;
  int nq = 0;
  Vector3 n = Vector3::Zero();
  for (int s : {1, -1})
    for (int t : {1, -1}) {
      if (!patch.Has(s, 0) || !patch.Has(0, t) || !patch.Has(s, t)) continue;
      Quad& f = quads[static_cast<std::size_t>(nq++)];
      f.s = s;
      f.t = t;
      f.p = patch.At(s, t) - patch.At(0, 0);
      f.q = patch.At(0, t) - patch.At(s, 0);
      const double st = static_cast<double>(s * t);
      const Vector3 nf = f.p.cross(f.q) * st;
      const double len = nf.norm();
      f.fh = nf / len;
      f.scale = st / len;
      n += f.fh;
    }
  const double len = n.norm();
  const Vector3 nh = n / len;
  Matrix3 g = left(nh);
  g -= (g * nh) * nh.transpose();  // G (I − n̂n̂ᵀ)/|n|
  g /= len;
  for (Matrix3& o : *out) o.setZero();
  for (int k = 0; k < nq; ++k) {
    const Quad& f = quads[static_cast<std::size_t>(k)];
    Matrix3 h = g - (g * f.fh) * f.fh.transpose();  // · (I − f̂f̂ᵀ) st/|nf|
    h *= f.scale;
    // Row i of H [a]× is (H_i × a)ᵀ: three cross products per skew product.
    Matrix3 hq, hp;
    for (int i = 0; i < 3; ++i) {
      const Vector3 r = h.row(i).transpose();
      hq.row(i) = r.cross(f.q).transpose();
      hp.row(i) = r.cross(f.p).transpose();
    }
    (*out)[static_cast<std::size_t>(Slot(f.s, f.t))] -= hq;
    (*out)[0] += hq;
    (*out)[static_cast<std::size_t>(Slot(0, f.t))] += hp;
    (*out)[static_cast<std::size_t>(Slot(f.s, 0))] -= hp;
  }
  return nh;
}

// Per-slot weights of a kernel's linear part: s = Σ_k wx_k x_k + Σ_k wv_k v_k
// (the bending stencils' difference operators; they depend only on which
// neighbours exist, so they are computed once per validity mask).
template <int K>
struct LinearWeights {
  std::array<double, K> x{}, v{};
};

// Scatter made parallel and deterministic: the items (stencil centres or
// springs) write their `outputs` force vectors into a buffer, then each
// particle sums its buffer entries in item order, which is the order of the
// serial scatter loop. `node(item, k)` names the particle of output k;
// AddTo's `negate(entry)` says which entries are subtracted.
struct GatherLists {
  GatherLists() = default;
  // @param with_buffer false: the caller keeps its own values (entries
  // only; ShearKernel's pair buffer)
  template <class NodeOf>
  GatherLists(int num_particles, std::size_t items, int outputs, NodeOf node, bool with_buffer = true) {
    offsets.assign(static_cast<std::size_t>(num_particles) + 1, 0);
    for (std::size_t c = 0; c < items; ++c)
      for (int k = 0; k < outputs; ++k) ++offsets[static_cast<std::size_t>(node(c, k)) + 1];
    for (std::size_t p = 0; p < static_cast<std::size_t>(num_particles); ++p) offsets[p + 1] += offsets[p];
    entries.resize(static_cast<std::size_t>(offsets.back()));
    std::vector<int> fill(offsets.begin(), offsets.end() - 1);
    for (std::size_t c = 0; c < items; ++c)  // item order within each particle's list
      for (int k = 0; k < outputs; ++k)
        entries[static_cast<std::size_t>(fill[static_cast<std::size_t>(node(c, k))]++)] =
            static_cast<int>(c) * outputs + k;
    if (with_buffer) buffer.assign(3 * items * static_cast<std::size_t>(outputs), 0.0);
  }
  // f(p) += Σ buffer entries of p, in item order; `negate(e)` says whether
  // entry e is subtracted.
  template <class Negate>
  void AddTo(MatrixN3* f, Negate negate) const {
    Sum(f, [&](int e) { return std::pair<const double*, bool>(buffer.data() + 3 * static_cast<std::size_t>(e), negate(e)); });
  }
  // f(p) ±= the 3-vector value(e) names (pointer, subtract) for each entry
  // e of p, in item order.
  template <class Value>
  void Sum(MatrixN3* f, Value value) const {
    const auto n = static_cast<std::ptrdiff_t>(offsets.size()) - 1;
    double* f0 = f->col(0).data();
    double* f1 = f->col(1).data();
    double* f2 = f->col(2).data();
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t p = 0; p < n; ++p) {
      double a0 = f0[p], a1 = f1[p], a2 = f2[p];
      for (int q = offsets[static_cast<std::size_t>(p)]; q < offsets[static_cast<std::size_t>(p) + 1]; ++q) {
        const auto [b, subtract] = value(entries[static_cast<std::size_t>(q)]);
        if (subtract) {
          a0 -= b[0];
          a1 -= b[1];
          a2 -= b[2];
        } else {
          a0 += b[0];
          a1 += b[1];
          a2 += b[2];
        }
      }
      f0[p] = a0;
      f1[p] = a1;
      f2[p] = a2;
    }
  }
  void AddTo(MatrixN3* f) const {
    AddTo(f, [](int) { return false; });
  }
  std::vector<int> offsets, entries;
  std::vector<double> buffer;
};

struct ShearKernel;  // its outputs come in pairs (StencilTerm's gather reads them so)

// Generic term over per-centre stencils of K particles; the kernel writes
// forces into the first Kernel::kOutputs slots, and its closed-form
// Jacobian as Kernel::kBlocks 3×3 blocks ∂f_a/∂x_b (and ∂f_a/∂v_b) for the
// slot pairs Kernel::kBlockSlots.
template <class Kernel>
class StencilTerm final : public ForceTerm {
 public:
  static constexpr int K = Kernel::kNodes;
  static constexpr int kBlocks = Kernel::kBlocks;
  struct Centre {
    std::array<int, K> nodes{};
    std::uint32_t valid = 0;
    double weight = 0.0;
  };

  /// @param planes on a curvilinear pattern, each centre's slots' rest
  /// positions in the pattern's plane [m] (GridPlanes); empty on a uniform
  /// grid. A linear kernel then has one weight set per centre, a kernel
  /// with rest data (Kernel::RestOf) its data per centre.
  StencilTerm(std::string name, Kernel kernel, std::vector<Centre> centres, int num_particles,
              const std::vector<std::array<Eigen::Vector2d, K>>& planes = {})
      : name_(std::move(name)), kernel_(std::move(kernel)), centres_(std::move(centres)) {
    if constexpr (std::is_same_v<Kernel, ShearKernel>) {
      // Outputs 1–4 only (the centre's output 0 is always zero), their
      // values read from the per-centre pair (ShearKernel::Pair).
      if (static_cast<int>(centres_.size()) >= kParallelMinimum) {
        gather_ = GatherLists(
            num_particles, centres_.size(), 4,
            [this](std::size_t c, int k) { return centres_[c].nodes[static_cast<std::size_t>(k) + 1]; }, false);
        pairs_.assign(6 * centres_.size(), 0.0);
      }
    } else if (Kernel::kOutputs > 1 && static_cast<int>(centres_.size()) >= kParallelMinimum) {
      gather_ = GatherLists(num_particles, centres_.size(), Kernel::kOutputs,
                            [this](std::size_t c, int k) { return centres_[c].nodes[static_cast<std::size_t>(k)]; });
    }
    if constexpr (kHasRest) {
      rest_.reserve(planes.size());
      for (std::size_t c = 0; c < planes.size(); ++c) rest_.push_back(Kernel::RestOf(centres_[c].valid, planes[c]));
    }
    if constexpr (Kernel::kLinear) {
      weight_set_.resize(centres_.size());
      if (!planes.empty()) {  // a curvilinear pattern: one weight set per centre
        curvilinear_ = true;
        weights_.reserve(centres_.size());
        for (std::size_t c = 0; c < centres_.size(); ++c) {
          weights_.push_back(kernel_.Weights(centres_[c].valid, &planes[c]));
          weight_set_[c] = static_cast<int>(c);
        }
        return;
      }
      // One weight set per validity mask (a grid has a few dozen).
      std::vector<std::uint32_t> masks;
      for (std::size_t c = 0; c < centres_.size(); ++c) {
        const std::uint32_t m = centres_[c].valid;
        std::size_t k = 0;
        while (k < masks.size() && masks[k] != m) ++k;
        if (k == masks.size()) {
          masks.push_back(m);
          weights_.push_back(kernel_.Weights(m));
        }
        weight_set_[c] = static_cast<int>(k);
      }
    }
  }

  std::string_view name() const override { return name_; }
  bool depends_on_velocity() const override { return kernel_.uses_velocity(); }

  /// A linear kernel on GridCentres of an nu × nv grid: the centres whose
  /// K slots all exist (2 ≤ i < nu − 2 for the thin plate, 1 ≤ i < nu − 1
  /// for the membrane, the same in j) are evaluated row by row
  /// (AddInterior), the others one by one (Evaluate).
  void UseGridRows(int nu, int nv) {
    static_assert(Kernel::kLinear);
    constexpr int r = K == 13 ? 2 : 1;
    nu_ = nu;
    const std::uint32_t full = (1u << K) - 1u;
    full_weights_ = kernel_.Weights(full);
    interior_rows_ = std::max(0, nv - 2 * r);
    if (nu - 2 * r <= 0) interior_rows_ = 0;
    border_.clear();
    for (std::size_t c = 0; c < centres_.size(); ++c) {
      const int i = static_cast<int>(c) % nu, j = static_cast<int>(c) / nu;
      if (interior_rows_ == 0 || i < r || i >= nu - r || j < r || j >= nv - r) border_.push_back(c);
    }
  }

  // Serial below kParallelMinimum centres. Above it, the centres are split
  // over the OpenMP threads: a kernel with one output writes only its own
  // centre particle; one with several writes its outputs to a buffer, and
  // each particle then sums its entries in centre order. Either way every
  // force is summed in the serial order: bit-identical for any thread count.
  void AddForce(double t, const MatrixN3& x, const MatrixN3& v, MatrixN3* f) const override {
    if constexpr (Kernel::kLinear) {
      if (!border_.empty() || interior_rows_ > 0) {
        AddInterior(x, v, f);
        for (std::size_t c : border_) {
          std::array<Vector3, 1> fs;
          Evaluate(t, x, v, c, &fs);
          f->row(centres_[c].nodes[0]) += fs[0].transpose();
        }
        return;
      }
    }
    const auto n = static_cast<std::ptrdiff_t>(centres_.size());
    if (n < kParallelMinimum) {
      for (std::ptrdiff_t c = 0; c < n; ++c) {
        std::array<Vector3, Kernel::kOutputs> fs;
        Evaluate(t, x, v, static_cast<std::size_t>(c), &fs);
        for (int k = 0; k < Kernel::kOutputs; ++k) f->row(centres_[static_cast<std::size_t>(c)].nodes[k]) += fs[k].transpose();
      }
      return;
    }
    if constexpr (std::is_same_v<Kernel, ShearKernel>) {
      // Per centre the pair (fu, fv): outputs 1–4 are −fu, +fu, −fv, +fv.
      // Each particle then sums its entries in centre order, as the
      // buffered gather below does (a − fu is a + (−fu) to the bit).
      double* pairs = pairs_.data();
      const bool with_v = kernel_.uses_velocity();
#pragma omp parallel for schedule(static)
      for (std::ptrdiff_t c = 0; c < n; ++c) {
        const Centre& ce = centres_[static_cast<std::size_t>(c)];
        std::array<Vector3, 5> xs, vs;
        for (std::size_t k = 0; k < 5; ++k) {
          xs[k] = x.row(ce.nodes[k]).transpose();
          if (with_v) vs[k] = v.row(ce.nodes[k]).transpose();
          else vs[k].setZero();
        }
        Vector3 fu, fv;
        kernel_.template Pair<double>(ce.valid, RestOf(static_cast<std::size_t>(c)), xs, vs, &fu, &fv);
        Eigen::Map<Vector3>(pairs + 6 * c) = fu;
        Eigen::Map<Vector3>(pairs + 6 * c + 3) = fv;
      }
      gather_.Sum(f, [pairs](int e) {
        const int k = e & 3;  // output k + 1: −fu, +fu, −fv, +fv
        return std::pair<const double*, bool>(pairs + 6 * static_cast<std::size_t>(e >> 2) + (k < 2 ? 0 : 3),
                                              (k & 1) == 0);
      });
    } else if constexpr (Kernel::kOutputs == 1) {
#pragma omp parallel for schedule(static)
      for (std::ptrdiff_t c = 0; c < n; ++c) {
        std::array<Vector3, 1> fs;
        Evaluate(t, x, v, static_cast<std::size_t>(c), &fs);
        f->row(centres_[static_cast<std::size_t>(c)].nodes[0]) += fs[0].transpose();
      }
    } else {
      double* buffer = gather_.buffer.data();
#pragma omp parallel for schedule(static)
      for (std::ptrdiff_t c = 0; c < n; ++c) {
        std::array<Vector3, Kernel::kOutputs> fs;
        Evaluate(t, x, v, static_cast<std::size_t>(c), &fs);
        for (int k = 0; k < Kernel::kOutputs; ++k)
          Eigen::Map<Vector3>(buffer + 3 * (c * Kernel::kOutputs + k)) = fs[static_cast<std::size_t>(k)];
      }
      gather_.AddTo(f);
    }
  }

  // Closed-form blocks as triplets: every centre writes its fixed number of
  // triplets at its own offset, so the centres run on the OpenMP threads
  // with a result independent of the thread count. A kernel that does not
  // use v emits no dfdv triplets (the pattern never changes).
  void AddJacobian(double t, const MatrixN3& x, const MatrixN3& v, std::vector<Triplet>* dfdx,
                   std::vector<Triplet>* dfdv) const override {
    constexpr std::size_t kPer = static_cast<std::size_t>(kBlocks) * 9;
    const bool with_v = kernel_.uses_velocity();
    const std::size_t bx = dfdx->size(), bv = dfdv->size();
    dfdx->resize(bx + centres_.size() * kPer);
    if (with_v) dfdv->resize(bv + centres_.size() * kPer);
    Triplet* out_x = dfdx->data() + bx;
    Triplet* out_v = with_v ? dfdv->data() + bv : nullptr;
    const auto n = static_cast<std::ptrdiff_t>(centres_.size());
#pragma omp parallel for schedule(static) if (n >= kBlockParallelMinimum)
    for (std::ptrdiff_t ci = 0; ci < n; ++ci) {
      const Centre& c = centres_[static_cast<std::size_t>(ci)];
      std::array<Matrix3, kBlocks> jx, jv;
      Blocks(t, x, v, static_cast<std::size_t>(ci), &jx, &jv);
      std::size_t pos = static_cast<std::size_t>(ci) * kPer;
      for (int k = 0; k < kBlocks; ++k) {
        const int row = 3 * c.nodes[Kernel::kBlockSlots[k][0]], col = 3 * c.nodes[Kernel::kBlockSlots[k][1]];
        for (int r = 0; r < 3; ++r)
          for (int q = 0; q < 3; ++q, ++pos) {
            out_x[pos] = Triplet(row + r, col + q, jx[k](r, q));
            if (with_v) out_v[pos] = Triplet(row + r, col + q, jv[k](r, q));
          }
      }
    }
  }

  // Forward-mode AutoDiff over the stencil's positions, and over its
  // velocities only if the kernel uses them (damping, wind, air): the
  // derivative vectors are then half as long. Emits the triplets of every
  // (output, node) slot pair, so its pattern is a superset of AddJacobian's.
  void AddJacobianAutoDiff(double t, const MatrixN3& x, const MatrixN3& v, std::vector<Triplet>* dfdx,
                           std::vector<Triplet>* dfdv) const override {
    if (kernel_.uses_velocity())
      JacobianPass<true>(t, x, v, dfdx, dfdv);
    else
      JacobianPass<false>(t, x, v, dfdx, dfdv);
  }

  void JacobianBlocks(std::vector<BlockPair>* blocks) const override {
    blocks->reserve(blocks->size() + centres_.size() * static_cast<std::size_t>(kBlocks));
    for (const Centre& c : centres_)
      for (int k = 0; k < kBlocks; ++k)
        blocks->push_back({c.nodes[Kernel::kBlockSlots[k][0]], c.nodes[Kernel::kBlockSlots[k][1]]});
  }

  std::size_t jacobian_items() const override { return centres_.size(); }

  void AccumulateJacobian(double t, const MatrixN3& x, const MatrixN3& v, const int* pos, double* dfdx,
                          double* dfdv, std::size_t first, std::size_t last) const override {
    const bool with_v = kernel_.uses_velocity();
    for (std::size_t ci = first; ci < last; ++ci) {
      std::array<Matrix3, kBlocks> jx, jv;
      Blocks(t, x, v, ci, &jx, &jv);
      const int* p = pos + 3 * static_cast<std::size_t>(kBlocks) * ci;
      for (int k = 0; k < kBlocks; ++k) AddBlock(jx[static_cast<std::size_t>(k)], p + 3 * k, dfdx);
      if (with_v)
        for (int k = 0; k < kBlocks; ++k) AddBlock(jv[static_cast<std::size_t>(k)], p + 3 * k, dfdv);
    }
  }

  // The centres whose outputs land on each particle (shear: outputs 1–4,
  // its output 0 is always zero), in centre order.
  void PrepareParticleForces(int num_particles) const override {
    std::call_once(particle_once_, [&] {
      particle_items_ = GatherLists(
          num_particles, centres_.size(), kParticleOutputs,
          [this](std::size_t c, int k) { return centres_[c].nodes[static_cast<std::size_t>(k + kFirstOutput)]; },
          false);
    });
  }

  // Each centre that writes p is evaluated once: its outputs on p summed,
  // and its blocks (output on p, node p).
  // The bending kernels (linear, one output) through ProjectedParticle and
  // shear through its ParticleTerms form only the blocks on p.
  void AddParticleForce(double t, const MatrixN3& x, const MatrixN3& v, int p, Vector3* f, Matrix3* dfdx,
                        Matrix3* dfdv) const override {
    const bool with_v = kernel_.uses_velocity();
    const std::vector<int>& entries = particle_items_.entries;
    const int end = particle_items_.offsets[static_cast<std::size_t>(p) + 1];
    for (int q = particle_items_.offsets[static_cast<std::size_t>(p)]; q < end;) {
      const int c = entries[static_cast<std::size_t>(q)] / kParticleOutputs;
      std::uint32_t outputs = 0;
      for (; q < end && entries[static_cast<std::size_t>(q)] / kParticleOutputs == c; ++q)
        outputs |= 1u << (entries[static_cast<std::size_t>(q)] % kParticleOutputs + kFirstOutput);
      const Centre& centre = centres_[static_cast<std::size_t>(c)];
      if constexpr (Kernel::kLinear || requires { Kernel::kParticleTerms; }) {
        std::array<Vector3, K> xs, vs;
        std::uint32_t nodes = 0;
        for (std::size_t k = 0; k < static_cast<std::size_t>(K); ++k) {
          xs[k] = x.row(centre.nodes[k]).transpose();
          vs[k] = with_v ? Vector3(v.row(centre.nodes[k]).transpose()) : Vector3::Zero();
          nodes |= static_cast<std::uint32_t>(centre.nodes[k] == p) << k;
        }
        if constexpr (Kernel::kLinear)
          ProjectedParticle<K>(Kernel::kProjectionSign, centre.weight,
                               weights_[static_cast<std::size_t>(weight_set_[static_cast<std::size_t>(c)])],
                               Patch<double, K>{xs, centre.valid}, vs, kernel_.damping != 0.0, nodes, f, dfdx, dfdv);
        else
          kernel_.ParticleTerms(centre.valid, RestOf(static_cast<std::size_t>(c)), xs, vs, outputs, nodes, f, dfdx, dfdv);
        continue;
      }
      std::array<Vector3, Kernel::kOutputs> fs;
      Evaluate(t, x, v, static_cast<std::size_t>(c), &fs);
      for (int o = 0; o < Kernel::kOutputs; ++o)
        if ((outputs >> o) & 1u) *f += fs[static_cast<std::size_t>(o)];
      std::array<Matrix3, kBlocks> jx, jv;
      Blocks(t, x, v, static_cast<std::size_t>(c), &jx, &jv);
      for (int k = 0; k < kBlocks; ++k) {
        if (!((outputs >> Kernel::kBlockSlots[k][0]) & 1u) || centre.nodes[Kernel::kBlockSlots[k][1]] != p) continue;
        *dfdx += jx[static_cast<std::size_t>(k)];
        if (with_v) *dfdv += jv[static_cast<std::size_t>(k)];
      }
    }
  }

 private:
  static constexpr int kFirstOutput = std::is_same_v<Kernel, ShearKernel> ? 1 : 0;
  static constexpr bool kHasRest = requires { Kernel::kRest; };
  // The centre's rest data (Kernel::RestOf) on a curvilinear pattern; null on a uniform grid.
  const double* RestOf(std::size_t c) const { return rest_.empty() ? nullptr : rest_[c].data(); }
  // f_0 += ±A (s·n̂) n̂ of a linear kernel from centre ci's weights (the
  // force the AutoDiff pass differentiates on a curvilinear pattern).
  template <class S>
  void LinearForce(std::size_t ci, const std::array<V3<S>, K>& xs, const std::array<V3<S>, K>& vs, V3<S>* f0) const {
    const LinearWeights<K>& w = weights_[static_cast<std::size_t>(weight_set_[ci])];
    V3<S> s = V3<S>::Zero();
    for (std::size_t k = 0; k < static_cast<std::size_t>(K); ++k) {
      s += w.x[k] * xs[k];
      if (kernel_.damping != 0.0) s += w.v[k] * vs[k];
    }
    const V3<S> n = Patch<S, K>{xs, centres_[ci].valid}.Normal();
    *f0 += (Kernel::kProjectionSign * s.dot(n) * centres_[ci].weight) * n;
  }
  static constexpr int kParticleOutputs = Kernel::kOutputs - kFirstOutput;
  void Blocks(double t, const MatrixN3& x, const MatrixN3& v, std::size_t ci, std::array<Matrix3, kBlocks>* jx,
              std::array<Matrix3, kBlocks>* jv) const {
    const Centre& c = centres_[ci];
    std::array<Vector3, K> xs, vs;
    const bool with_v = kernel_.uses_velocity();
    for (int k = 0; k < K; ++k) {
      xs[static_cast<std::size_t>(k)] = x.row(c.nodes[static_cast<std::size_t>(k)]).transpose();
      // v only where the kernel reads it (damping, air); else unread.
      vs[static_cast<std::size_t>(k)] =
          with_v ? Vector3(v.row(c.nodes[static_cast<std::size_t>(k)]).transpose()) : Vector3::Zero();
    }
    const LinearWeights<K>* w = nullptr;
    if constexpr (Kernel::kLinear) w = &weights_[static_cast<std::size_t>(weight_set_[ci])];
    kernel_.Blocks(t, c.valid, c.weight, RestOf(ci), w, xs, vs, *jx, *jv);
  }

  template <bool kVelocity>
  void JacobianPass(double t, const MatrixN3& x, const MatrixN3& v, std::vector<Triplet>* dfdx,
                    std::vector<Triplet>* dfdv) const {
    constexpr int D = kVelocity ? 6 * K : 3 * K;
    using Derivs = Eigen::Matrix<double, D, 1>;
    using AD = Eigen::AutoDiffScalar<Derivs>;
    constexpr std::size_t kPer = static_cast<std::size_t>(Kernel::kOutputs) * 9 * K;
    const std::size_t bx = dfdx->size(), bv = dfdv->size();
    dfdx->resize(bx + centres_.size() * kPer);
    if constexpr (kVelocity) dfdv->resize(bv + centres_.size() * kPer);
    Triplet* out_x = dfdx->data() + bx;
    [[maybe_unused]] Triplet* out_v = kVelocity ? dfdv->data() + bv : nullptr;
    const auto n = static_cast<std::ptrdiff_t>(centres_.size());
#pragma omp parallel for schedule(static) if (n >= 256)
    for (std::ptrdiff_t ci = 0; ci < n; ++ci) {
      const Centre& c = centres_[static_cast<std::size_t>(ci)];
      std::array<V3<AD>, K> xs, vs, fs;
      for (int k = 0; k < K; ++k)
        for (int r = 0; r < 3; ++r) {
          xs[k](r) = AD(x(c.nodes[k], r), D, 3 * k + r);
          if constexpr (kVelocity)
            vs[k](r) = AD(v(c.nodes[k], r), D, 3 * K + 3 * k + r);
          else
            vs[k](r) = AD(v(c.nodes[k], r));  // a constant: zero derivatives
          fs[k](r) = AD(0.0);
        }
      if constexpr (Kernel::kLinear) {
        if (curvilinear_) {  // the per-centre weights: the slots' rest positions are not kept
          LinearForce<AD>(static_cast<std::size_t>(ci), xs, vs, &fs[0]);
        } else {
          kernel_.template Evaluate<AD>(t, c.valid, c.weight, nullptr, xs, vs, fs);
        }
      } else {
        kernel_.template Evaluate<AD>(t, c.valid, c.weight, RestOf(static_cast<std::size_t>(ci)), xs, vs, fs);
      }
      std::size_t pos = static_cast<std::size_t>(ci) * kPer;
      for (int a = 0; a < Kernel::kOutputs; ++a)
        for (int r = 0; r < 3; ++r) {
          const Derivs& d = fs[a](r).derivatives();
          const int row = 3 * c.nodes[a] + r;
          for (int b = 0; b < K; ++b)
            for (int cc = 0; cc < 3; ++cc, ++pos) {
              const int col = 3 * c.nodes[b] + cc;
              out_x[pos] = Triplet(row, col, d(3 * b + cc));
              if constexpr (kVelocity) out_v[pos] = Triplet(row, col, d(3 * K + 3 * b + cc));
            }
        }
    }
  }

  // The force of centre `ci`. A linear kernel (the bending models) takes
  // its curvature s = Σ_k wx_k x_k (+ Σ_k wv_k v_k with damping) from the
  // per-mask weights that its Jacobian uses (WeightsOf: the same operator
  // as Stiff/Damp, summed in slot order) and projects it on the normal:
  // one multiply-add per slot instead of the nested second differences,
  // and v is read only with damping.
  void Evaluate(double t, const MatrixN3& x, const MatrixN3& v, std::size_t ci,
                std::array<Vector3, Kernel::kOutputs>* out) const {
    const Centre& c = centres_[ci];
    if constexpr (Kernel::kLinear) {
      const LinearWeights<K>& w = weights_[static_cast<std::size_t>(weight_set_[ci])];
      std::array<Vector3, K> xs;
      Vector3 s = Vector3::Zero();
      for (std::size_t k = 0; k < static_cast<std::size_t>(K); ++k) {
        xs[k] = x.row(c.nodes[k]).transpose();
        s += w.x[k] * xs[k];
      }
      if (kernel_.damping != 0.0)
        for (std::size_t k = 0; k < static_cast<std::size_t>(K); ++k) s += w.v[k] * v.row(c.nodes[k]).transpose();
      const Vector3 n = Patch<double, K>{xs, c.valid}.Normal();
      (*out)[0] = (Kernel::kProjectionSign * s.dot(n) * c.weight) * n;
      return;
    }
    std::array<Vector3, K> xs, vs, fs;
    const bool with_v = kernel_.uses_velocity();  // else v is not read (the kernel does not)
    for (int k = 0; k < K; ++k) {
      xs[k] = x.row(c.nodes[k]).transpose();
      if (with_v) vs[k] = v.row(c.nodes[k]).transpose();
      else vs[k].setZero();
      fs[k].setZero();
    }
    kernel_.template Evaluate<double>(t, c.valid, c.weight, RestOf(ci), xs, vs, fs);
    for (int k = 0; k < Kernel::kOutputs; ++k) (*out)[static_cast<std::size_t>(k)] = fs[static_cast<std::size_t>(k)];
  }

  // The interior centres (UseGridRows), one grid row after another: the
  // curvature s = Σ_k wx_k x_{p+o_k} (+ Σ_k wv_k v_{p+o_k}) with the full
  // mask's weights and flat offsets o_k = di + nu·dj, the unit normal as
  // Patch::Normal (the four quads' unit normals in the same order, their
  // sum normalised; each normalisation one division and three products), and f_p += ±A (s·n̂) n̂. The loop over i reads
  // contiguous columns, so the compiler vectorises it; each centre writes
  // only its own particle, so rows run on the OpenMP threads with a result
  // independent of the thread count.
  void AddInterior(const MatrixN3& x, const MatrixN3& v, MatrixN3* f) const {
    constexpr int r = K == 13 ? 2 : 1;
    const std::ptrdiff_t nu = nu_;
    std::array<std::ptrdiff_t, K> off{};
    for (std::size_t k = 0; k < static_cast<std::size_t>(K); ++k) off[k] = kOffsets[k][0] + nu * kOffsets[k][1];
    const std::array<double, K> wx = full_weights_.x, wv = full_weights_.v;
    const double scale = Kernel::kProjectionSign * (kernel_.lu * kernel_.lv);
    const bool damp = kernel_.damping != 0.0;
    const double* __restrict x0 = x.col(0).data();
    const double* __restrict x1 = x.col(1).data();
    const double* __restrict x2 = x.col(2).data();
    const double* __restrict v0 = v.col(0).data();
    const double* __restrict v1 = v.col(1).data();
    const double* __restrict v2 = v.col(2).data();
    double* __restrict f0 = f->col(0).data();
    double* __restrict f1 = f->col(1).data();
    double* __restrict f2 = f->col(2).data();
    const std::ptrdiff_t rows = interior_rows_;
#pragma omp parallel for schedule(static) if (rows * nu >= kParallelMinimum)
    for (std::ptrdiff_t jr = 0; jr < rows; ++jr) {
      const std::ptrdiff_t first = (jr + r) * nu + r, last = (jr + r) * nu + nu - r;
      for (std::ptrdiff_t p = first; p < last; ++p) {
        double s0 = 0.0, s1 = 0.0, s2 = 0.0;
        for (std::size_t k = 0; k < static_cast<std::size_t>(K); ++k) {
          s0 += wx[k] * x0[p + off[k]];
          s1 += wx[k] * x1[p + off[k]];
          s2 += wx[k] * x2[p + off[k]];
        }
        if (damp)
          for (std::size_t k = 0; k < static_cast<std::size_t>(K); ++k) {
            s0 += wv[k] * v0[p + off[k]];
            s1 += wv[k] * v1[p + off[k]];
            s2 += wv[k] * v2[p + off[k]];
          }
        double n0 = 0.0, n1 = 0.0, n2 = 0.0;
        for (int si : {1, -1})
          for (int ti : {1, -1}) {
            const std::ptrdiff_t pst = p + si + ti * nu, pt = p + ti * nu, ps = p + si;
            const double a0 = x0[pst] - x0[p], a1 = x1[pst] - x1[p], a2 = x2[pst] - x2[p];
            const double b0 = x0[pt] - x0[ps], b1 = x1[pt] - x1[ps], b2 = x2[pt] - x2[ps];
            const double st = static_cast<double>(si * ti);
            const double c0 = (a1 * b2 - a2 * b1) * st, c1 = (a2 * b0 - a0 * b2) * st, c2 = (a0 * b1 - a1 * b0) * st;
            const double inv = 1.0 / std::sqrt(c0 * c0 + c1 * c1 + c2 * c2);
            n0 += c0 * inv;
            n1 += c1 * inv;
            n2 += c2 * inv;
          }
        const double inv = 1.0 / std::sqrt(n0 * n0 + n1 * n1 + n2 * n2);
        n0 *= inv;
        n1 *= inv;
        n2 *= inv;
        const double d = (s0 * n0 + s1 * n1 + s2 * n2) * scale;
        f0[p] += d * n0;
        f1[p] += d * n1;
        f2[p] += d * n2;
      }
    }
  }

  std::string name_;
  Kernel kernel_;
  std::vector<Centre> centres_;
  int nu_ = 0;                      // UseGridRows: the grid's nu
  std::ptrdiff_t interior_rows_ = 0;  // rows of interior centres (0: every centre through Evaluate)
  std::vector<std::size_t> border_;   // the other centres, in order
  LinearWeights<K> full_weights_;     // of the mask with every slot
  mutable GatherLists gather_;  // kOutputs > 1 and many centres only
  mutable std::vector<double> pairs_;  // ShearKernel with many centres: (fu, fv) per centre
  std::vector<LinearWeights<K>> weights_;  // Kernel::kLinear only: one set per validity mask
  std::vector<int> weight_set_;            // of each centre
  bool curvilinear_ = false;               // Kernel::kLinear: weights per centre (a curvilinear pattern)
  std::vector<std::array<double, 4>> rest_;  // Kernel::RestOf per centre on a curvilinear pattern
  mutable std::once_flag particle_once_;   // PrepareParticleForces
  mutable GatherLists particle_items_;     // entries c·kParticleOutputs + (output − kFirstOutput)
};

// Builds one centre per particle with the first K patch slots; on a cloth
// of patterns, per owned node of each block, and (if `planes`) the slots'
// rest positions in the node's pattern plane (a missing slot holds the
// centre's particle and position).
template <class Kernel>
std::vector<typename StencilTerm<Kernel>::Centre> GridCentres(
    const GridGeometry& geo, std::vector<std::array<Eigen::Vector2d, Kernel::kNodes>>* planes = nullptr) {
  constexpr int K = Kernel::kNodes;
  std::vector<typename StencilTerm<Kernel>::Centre> out;
  if (geo.curvilinear()) {
    ForEachCentre(*geo.cloth, [&](const ClothBlock& b, int i, int j, int p) {
      typename StencilTerm<Kernel>::Centre c;
      std::array<Eigen::Vector2d, K> rest;
      for (std::size_t k = 0; k < static_cast<std::size_t>(K); ++k) {
        const int q = b.At(i + kOffsets[k][0], j + kOffsets[k][1]);
        c.valid |= static_cast<std::uint32_t>(q >= 0) << k;
        c.nodes[k] = q >= 0 ? q : p;
        rest[k] = b.rest[static_cast<std::size_t>(q >= 0 ? b.Cell(i + kOffsets[k][0], j + kOffsets[k][1]) : b.Cell(i, j))];
      }
      if constexpr (Kernel::kLinear) c.weight = CentreRestAt(b, i, j).area;
      else c.weight = geo.area(p);
      out.push_back(c);
      if (planes) planes->push_back(rest);
    });
    return out;
  }
  out.reserve(static_cast<std::size_t>(geo.nu) * geo.nv);
  for (int j = 0; j < geo.nv; ++j)
    for (int i = 0; i < geo.nu; ++i) {
      typename StencilTerm<Kernel>::Centre c;
      const int p = i + geo.nu * j;
      for (int k = 0; k < K; ++k) {
        const int ii = i + kOffsets[k][0], jj = j + kOffsets[k][1];
        if (ii >= 0 && ii < geo.nu && jj >= 0 && jj < geo.nv) {
          c.nodes[k] = ii + geo.nu * jj;
          c.valid |= 1u << k;
        } else {
          c.nodes[k] = p;
        }
      }
      // The bending terms' A (docs/model.md §2.3); the others' node area.
      if constexpr (Kernel::kLinear) c.weight = geo.lu * geo.lv;
      else c.weight = geo.area(p);
      out.push_back(c);
    }
  return out;
}

// A stencil term on the centres of `geo`, with their rest geometry on a
// curvilinear pattern.
template <class Kernel>
std::unique_ptr<StencilTerm<Kernel>> MakeGridTerm(std::string name, Kernel kernel, const GridGeometry& geo) {
  std::vector<std::array<Eigen::Vector2d, Kernel::kNodes>> planes;
  constexpr bool kRestData = Kernel::kLinear || requires { Kernel::kRest; };
  auto centres = GridCentres<Kernel>(geo, kRestData ? &planes : nullptr);
  const int n = geo.curvilinear() ? geo.cloth->num_particles : geo.nu * geo.nv;
  return std::make_unique<StencilTerm<Kernel>>(std::move(name), std::move(kernel), std::move(centres), n, planes);
}

// Slot pairs (output, node) of a kernel whose single output is the centre.
template <int K>
constexpr std::array<std::array<int, 2>, K> CentreRowSlots() {
  std::array<std::array<int, 2>, K> out{};
  for (int k = 0; k < K; ++k) out[static_cast<std::size_t>(k)] = {0, k};
  return out;
}

// --- Shear, energy form (thesis (2.16), (2.21)) ----------------------------
// γ = ⟨a, b⟩, a = (x_r − x_l)/Δu, b = (x_u − x_d)/Δv, one-sided on the border
// (missing neighbour := centre, spacing halves). E = ½ μ γ² lu lv and the
// Rayleigh dissipation ½ d_s γ̇² lu lv give F = −(μ γ + d_s γ̇) lu lv ∂γ/∂x.
//
// Jacobian: with σ = μ a·b + d_s (ȧ·b + a·ḃ), s = σ lu lv and the slot
// weights ea = ∂a/∂x_k = (0, 1/Δu, −1/Δu, 0, 0), eb = (0, 0, 0, 1/Δv, −1/Δv),
// ∂σ/∂x_k = ea_k (μ b + d_s ḃ) + eb_k (μ a + d_s ȧ), ∂σ/∂v_k = d_s (ea_k b + eb_k a).
// Output o has f_o = c_o s u_o (c = −1/Δu, 1/Δu, −1/Δv, 1/Δv; u = b, b, a, a), so
// ∂f_o/∂x_k = c_o (lu lv u_o ∂σ/∂x_kᵀ + s ∂u_o/∂x_k I) and ∂f_o/∂v_k = c_o lu lv u_o ∂σ/∂v_kᵀ.
struct ShearKernel {
  static constexpr int kNodes = 5;    // centre, r, l, u, d
  static constexpr int kOutputs = 5;
  static constexpr bool kLinear = false;
  static constexpr int kBlocks = 16;  // outputs r, l, u, d × nodes r, l, u, d (the centre enters no term)
  static constexpr std::array<std::array<int, 2>, 16> kBlockSlots = {
      {{1, 1}, {1, 2}, {1, 3}, {1, 4}, {2, 1}, {2, 2}, {2, 3}, {2, 4},
       {3, 1}, {3, 2}, {3, 3}, {3, 4}, {4, 1}, {4, 2}, {4, 3}, {4, 4}}};
  bool uses_velocity() const { return damping != 0.0; }  ///< whether f depends on v
  double mu, damping, lu, lv;
  // On a curvilinear pattern, per centre: du, dv, A and γ₀ (CentreRest),
  // from the rest positions of its slots (missing slots hold the centre's).
  static constexpr bool kRest = true;
  static std::array<double, 4> RestOf(std::uint32_t valid, const std::array<Eigen::Vector2d, 5>& X) {
    const Eigen::Vector2d eu = X[1] - X[2], ev = X[3] - X[4];
    const double cu = ((valid >> 1) & 1u) + ((valid >> 2) & 1u), cv = ((valid >> 3) & 1u) + ((valid >> 4) & 1u);
    const double du = eu.norm(), dv = ev.norm();
    return {du, dv, std::abs(eu.x() * ev.y() - eu.y() * ev.x()) / (cu * cv), eu.dot(ev) / (du * dv)};
  }
  // The pair fu = s b/Δu, fv = s a/Δv (s = σ lu lv) of the centre's
  // outputs: f_r = −fu, f_l = +fu, f_u = −fv, f_d = +fv. Two divisions per
  // centre: the spacings' reciprocals.
  template <class S>
  void Pair(std::uint32_t valid, const double* rest, const std::array<V3<S>, 5>& x, const std::array<V3<S>, 5>& v,
            V3<S>* fu, V3<S>* fv) const {
    const double iu = 1.0 / (rest ? rest[0] : lu * (((valid >> 1) & 1u) + ((valid >> 2) & 1u)));
    const double iv = 1.0 / (rest ? rest[1] : lv * (((valid >> 3) & 1u) + ((valid >> 4) & 1u)));
    const V3<S> a = (x[1] - x[2]) * iu, b = (x[3] - x[4]) * iv;
    S sigma = mu * (a.dot(b) - (rest ? rest[3] : 0.0));
    if (damping != 0.0) sigma += damping * (((v[1] - v[2]) * iu).dot(b) + a.dot((v[3] - v[4]) * iv));
    const S s = sigma * (rest ? rest[2] : lu * lv);
    *fu = (s * iu) * b;
    *fv = (s * iv) * a;
  }
  template <class S>
  void Evaluate(double, std::uint32_t valid, double, const double* rest, const std::array<V3<S>, 5>& x, const std::array<V3<S>, 5>& v,
                std::array<V3<S>, 5>& f) const {
    V3<S> fu, fv;
    Pair<S>(valid, rest, x, v, &fu, &fv);
    f[1] -= fu;
    f[2] += fu;
    f[3] -= fv;
    f[4] += fv;
  }
  // The quantities of the Jacobian (comment above) at one centre: the
  // spacings, a, b and their rates, s = σ lu lv, the slot weights ea, eb,
  // ∂σ/∂a, ∂σ/∂b and the output coefficients c.
  struct Strain {
    double du, dv, area, s;
    Vector3 a, b, ga, gb;
    std::array<double, 5> ea, eb, c;
  };
  Strain StrainAt(std::uint32_t valid, const double* rest, const std::array<Vector3, 5>& x,
                  const std::array<Vector3, 5>& v) const {
    Strain st;
    st.du = rest ? rest[0] : lu * (((valid >> 1) & 1u) + ((valid >> 2) & 1u));
    st.dv = rest ? rest[1] : lv * (((valid >> 3) & 1u) + ((valid >> 4) & 1u));
    st.a = (x[1] - x[2]) / st.du;
    st.b = (x[3] - x[4]) / st.dv;
    const Vector3 ad = (v[1] - v[2]) / st.du, bd = (v[3] - v[4]) / st.dv;
    double sigma = mu * (st.a.dot(st.b) - (rest ? rest[3] : 0.0));
    if (damping != 0.0) sigma += damping * (ad.dot(st.b) + st.a.dot(bd));
    st.area = rest ? rest[2] : lu * lv;
    st.s = sigma * st.area;
    const double iu = 1.0 / st.du, iv = 1.0 / st.dv;
    st.ea = {0.0, iu, -iu, 0.0, 0.0};
    st.eb = {0.0, 0.0, 0.0, iv, -iv};
    st.c = {0.0, -iu, iu, -iv, iv};
    st.ga = mu * st.b + damping * bd;  // ∂σ/∂a
    st.gb = mu * st.a + damping * ad;  // ∂σ/∂b
    return st;
  }
  // For one particle (vertex-block methods): f += Σ f_o over the outputs o
  // in `outputs`, and the blocks (o, k) of Blocks for o in `outputs` and k
  // in `nodes` (the slots that hold the particle), without the others.
  static constexpr bool kParticleTerms = true;
  void ParticleTerms(std::uint32_t valid, const double* rest, const std::array<Vector3, 5>& x, const std::array<Vector3, 5>& v,
                     std::uint32_t outputs, std::uint32_t nodes, Vector3* f, Matrix3* jx, Matrix3* jv) const {
    const Strain st = StrainAt(valid, rest, x, v);
    // Σ over k in nodes of ∂σ/∂x_k (and of the slot weights), the same for every output.
    double sa = 0.0, sb = 0.0;
    for (int k = 1; k <= 4; ++k)
      if ((nodes >> k) & 1u) {
        sa += st.ea[k];
        sb += st.eb[k];
      }
    const Vector3 px = sa * st.ga + sb * st.gb, pv = sa * st.b + sb * st.a;
    for (int o = 1; o <= 4; ++o) {
      if (!((outputs >> o) & 1u)) continue;
      const Vector3& u = o <= 2 ? st.b : st.a;
      *f += (st.c[o] * st.s) * u;
      jx->noalias() += (st.c[o] * st.area) * u * px.transpose();
      jx->diagonal().array() += st.c[o] * st.s * (o <= 2 ? sb : sa);
      if (damping != 0.0) jv->noalias() += (st.c[o] * st.area * damping) * u * pv.transpose();
    }
  }
  void Blocks(double, std::uint32_t valid, double, const double* rest, const LinearWeights<5>*, const std::array<Vector3, 5>& x,
              const std::array<Vector3, 5>& v, std::array<Matrix3, 16>& jx, std::array<Matrix3, 16>& jv) const {
    const Strain st = StrainAt(valid, rest, x, v);
    for (int o = 1; o <= 4; ++o) {
      const Vector3& u = o <= 2 ? st.b : st.a;
      const std::array<double, 5>& eu = o <= 2 ? st.eb : st.ea;
      for (int k = 1; k <= 4; ++k) {
        const std::size_t blk = static_cast<std::size_t>(4 * (o - 1) + (k - 1));
        const Vector3 px = st.ea[k] * st.ga + st.eb[k] * st.gb;
        jx[blk].noalias() = (st.c[o] * st.area) * u * px.transpose();
        jx[blk].diagonal().array() += st.c[o] * st.s * eu[k];
        if (damping != 0.0)
          jv[blk].noalias() = (st.c[o] * st.area * damping) * u * (st.ea[k] * st.b + st.eb[k] * st.a).transpose();
      }
    }
  }
};

// --- Normal-projected bending, the membrane (2.25, Alg. 3) and thin-plate
// (2.26, Alg. 4) models ------------------------------------------------------
// Both are f_0 = ±A (s·n̂) n̂ with A = lu lv and s = Σ_k wx_k x_k + Σ_k wv_k v_k
// linear in the stencil (the curvature operator and its viscosity), so
// ∂f_0/∂x_k = ±A (wx_k n̂n̂ᵀ + (n̂ sᵀ + (s·n̂) I) ∂n̂/∂x_k) and
// ∂f_0/∂v_k = ±A wv_k n̂n̂ᵀ (∂n̂/∂x_k from NormalJacobian, zero outside
// the 3×3 box).
// The curvature s = Σ_k wx_k x_k (+ Σ_k wv_k v_k), the unit normal n̂ and
// gdn[k] = ±A (n̂ sᵀ + (s·n̂) I) ∂n̂/∂x_k for the 3×3 box, shared by the
// blocks and the per-particle terms below.
template <int K>
Vector3 ProjectedNormal(double c, const LinearWeights<K>& w, const Patch<double, K>& px,
                        const std::array<Vector3, K>& v, bool damping, Vector3* s, std::array<Matrix3, 9>* gdn) {
  s->setZero();  // the linear part from its weights (a missing slot has weight 0)
  for (std::size_t k = 0; k < static_cast<std::size_t>(K); ++k) *s += w.x[k] * px.x[k];
  if (damping)
    for (std::size_t k = 0; k < static_cast<std::size_t>(K); ++k) *s += w.v[k] * v[k];
  return NormalJacobian(
      px,
      [&](const Vector3& nh) {
        Matrix3 m = nh * s->transpose();
        m.diagonal().array() += s->dot(nh);
        return Matrix3(c * m);
      },
      gdn);
}

template <int K>
void ProjectedBlocks(double sign, double area, const LinearWeights<K>& w, const Patch<double, K>& px,
                     const std::array<Vector3, K>& v, bool damping, std::array<Matrix3, K>& jx,
                     std::array<Matrix3, K>& jv) {
  const double c = sign * area;
  Vector3 s;
  std::array<Matrix3, 9> gdn;
  const Vector3 n = ProjectedNormal<K>(c, w, px, v, damping, &s, &gdn);
  const Matrix3 nn = n * n.transpose();
  for (std::size_t k = 0; k < static_cast<std::size_t>(K); ++k) {
    jx[k] = (c * w.x[k]) * nn;
    if (k < 9) jx[k] += gdn[k];
    if (damping) jv[k] = (c * w.v[k]) * nn;
  }
}

// The same force and blocks for one particle (vertex-block methods): f_0
// and Σ_k ∂f_0/∂x_k, ∂f_0/∂v_k over the slots k in `nodes` (the slots that
// hold the particle), without forming the other blocks.
template <int K>
void ProjectedParticle(double sign, double area, const LinearWeights<K>& w, const Patch<double, K>& px,
                       const std::array<Vector3, K>& v, bool damping, std::uint32_t nodes, Vector3* f, Matrix3* jx,
                       Matrix3* jv) {
  const double c = sign * area;
  Vector3 s;
  std::array<Matrix3, 9> gdn;
  const Vector3 n = ProjectedNormal<K>(c, w, px, v, damping, &s, &gdn);
  *f += (c * s.dot(n)) * n;
  const Matrix3 nn = n * n.transpose();
  double wx = 0.0, wv = 0.0;
  for (std::size_t k = 0; k < static_cast<std::size_t>(K); ++k) {
    if (!((nodes >> k) & 1u)) continue;
    wx += w.x[k];
    wv += w.v[k];
    if (k < 9) *jx += gdn[k];
  }
  *jx += (c * wx) * nn;
  if (damping) *jv += (c * wv) * nn;
}

// Weights of a kernel's linear part: its Stiff/Damp operator on unit
// vectors in slot k.
template <int K, class Kernel>
LinearWeights<K> WeightsOf(const Kernel& kernel, std::uint32_t valid, const std::array<Eigen::Vector2d, K>* rest) {
  LinearWeights<K> w;
  for (int k = 0; k < K; ++k) {
    std::array<Vector3, K> e;
    for (Vector3& ek : e) ek.setZero();
    e[static_cast<std::size_t>(k)] = Vector3::UnitX();
    const Patch<double, K> p{e, valid, rest};
    w.x[static_cast<std::size_t>(k)] = kernel.template Stiff<double>(p).x();
    w.v[static_cast<std::size_t>(k)] = kernel.template Damp<double>(p).x();
  }
  return w;
}

// --- Membrane bending (2.25), Alg. 3 ----------------------------------------
struct MembraneKernel {
  static constexpr int kNodes = 9;
  static constexpr int kOutputs = 1;
  static constexpr bool kLinear = true;
  static constexpr double kProjectionSign = 1.0;  ///< f_0 = +A (s·n̂) n̂
  static constexpr int kBlocks = 9;
  static constexpr std::array<std::array<int, 2>, 9> kBlockSlots = CentreRowSlots<9>();
  bool uses_velocity() const { return damping != 0.0; }  ///< whether f depends on v
  double bu, bv, damping, lu, lv;
  template <class S>
  V3<S> Stiff(const Patch<S, 9>& px) const {
    return bu * px.Lu(0, 0, lu) + bv * px.Lv(0, 0, lv);
  }
  template <class S>
  V3<S> Damp(const Patch<S, 9>& pv) const {
    return damping * (pv.Lu(0, 0, lu) + pv.Lv(0, 0, lv));
  }
  LinearWeights<9> Weights(std::uint32_t valid, const std::array<Eigen::Vector2d, 9>* rest = nullptr) const {
    return WeightsOf<9>(*this, valid, rest);
  }
  template <class S>
  void Evaluate(double, std::uint32_t valid, double area, const double*, const std::array<V3<S>, 9>& x,
                const std::array<V3<S>, 9>& v, std::array<V3<S>, 9>& f) const {
    const Patch<S, 9> px{x, valid}, pv{v, valid};
    V3<S> s = Stiff(px);
    if (damping != 0.0) s += Damp(pv);
    const V3<S> n = px.Normal();
    f[0] += (s.dot(n) * area) * n;
  }
  void Blocks(double, std::uint32_t valid, double area, const double*, const LinearWeights<9>* w,
              const std::array<Vector3, 9>& x, const std::array<Vector3, 9>& v, std::array<Matrix3, 9>& jx,
              std::array<Matrix3, 9>& jv) const {
    ProjectedBlocks<9>(kProjectionSign, area, *w, Patch<double, 9>{x, valid}, v, damping != 0.0, jx, jv);
  }
};

// --- Thin-plate bending (2.26), Alg. 4 --------------------------------------
// S = B_u ∂uu R + B_v ∂vv R with R = (∂uu + ∂vv) x, which expands to
// B_u s_uuuu + (B_u+B_v) s_uuvv + B_v s_vvvv; viscosity d_b Δ²v.
struct ThinPlateKernel {
  static constexpr int kNodes = 13;
  static constexpr int kOutputs = 1;
  static constexpr bool kLinear = true;
  static constexpr double kProjectionSign = -1.0;  ///< f_0 = −A (s·n̂) n̂
  static constexpr int kBlocks = 13;
  static constexpr std::array<std::array<int, 2>, 13> kBlockSlots = CentreRowSlots<13>();
  bool uses_velocity() const { return damping != 0.0; }  ///< whether f depends on v
  double bu, bv, damping, lu, lv;

  template <class S>
  static V3<S> BiLaplacian(const Patch<S, 13>& p, double wu, double wv, double lu, double lv) {
    // Second differences of R = Lu + Lv at the centre, zero normal to a border.
    auto R = [&](int di, int dj) { return V3<S>(p.Lu(di, dj, lu) + p.Lv(di, dj, lv)); };
    V3<S> out = V3<S>::Zero();
    if (p.rest) {  // a curvilinear pattern: the outer differences with the centre's own spacings
      if (wu != 0.0 && p.Has(1, 0) && p.Has(-1, 0))
        out += wu * SecondDifference<V3<S>>(R(1, 0), R(0, 0), R(-1, 0), p.Spacing(0, 0, 1, 0, lu), p.Spacing(0, 0, -1, 0, lu));
      if (wv != 0.0 && p.Has(0, 1) && p.Has(0, -1))
        out += wv * SecondDifference<V3<S>>(R(0, 1), R(0, 0), R(0, -1), p.Spacing(0, 0, 0, 1, lv), p.Spacing(0, 0, 0, -1, lv));
      return out;
    }
    if (wu != 0.0 && p.Has(1, 0) && p.Has(-1, 0)) out += wu * (R(1, 0) - 2.0 * R(0, 0) + R(-1, 0)) / (lu * lu);
    if (wv != 0.0 && p.Has(0, 1) && p.Has(0, -1)) out += wv * (R(0, 1) - 2.0 * R(0, 0) + R(0, -1)) / (lv * lv);
    return out;
  }
  template <class S>
  V3<S> Stiff(const Patch<S, 13>& px) const {
    return BiLaplacian(px, bu, bv, lu, lv);
  }
  template <class S>
  V3<S> Damp(const Patch<S, 13>& pv) const {
    return BiLaplacian(pv, damping, damping, lu, lv);
  }
  LinearWeights<13> Weights(std::uint32_t valid, const std::array<Eigen::Vector2d, 13>* rest = nullptr) const {
    return WeightsOf<13>(*this, valid, rest);
  }

  template <class S>
  void Evaluate(double, std::uint32_t valid, double area, const double*, const std::array<V3<S>, 13>& x,
                const std::array<V3<S>, 13>& v, std::array<V3<S>, 13>& f) const {
    const Patch<S, 13> px{x, valid};
    V3<S> s = Stiff(px);
    if (damping != 0.0) s += Damp(Patch<S, 13>{v, valid});
    const V3<S> n = px.Normal();
    f[0] -= (s.dot(n) * area) * n;
  }
  void Blocks(double, std::uint32_t valid, double area, const double*, const LinearWeights<13>* w,
              const std::array<Vector3, 13>& x, const std::array<Vector3, 13>& v, std::array<Matrix3, 13>& jx,
              std::array<Matrix3, 13>& jv) const {
    ProjectedBlocks<13>(kProjectionSign, area, *w, Patch<double, 13>{x, valid}, v, damping != 0.0, jx, jv);
  }
};

// --- Transverse contraction (2.22), Alg. 5 ----------------------------------
// Slots: centre i, its u-neighbour j (left, right on the border), its
// v-neighbour k (lower j−1, upper on the border). τ1 = C ε_11 acts along the
// v-edge (i,k), τ2 = C ε_22 along the u-edge (i,j).
//
// Jacobian: with du = x_j − x_i, dv = x_k − x_i and unit vectors û, v̂,
// f_u = τ1 v̂ and f_v = τ2 û have ∂f_u/∂du = (C/lu) v̂ûᵀ,
// ∂f_u/∂dv = τ1 (I − v̂v̂ᵀ)/|dv|, ∂f_v/∂du = τ2 (I − ûûᵀ)/|du|,
// ∂f_v/∂dv = (C/lv) ûv̂ᵀ; f_i = f_u + f_v, f_j = −f_v, f_k = −f_u.
struct TransverseKernel {
  static constexpr int kNodes = 3;
  static constexpr int kOutputs = 3;
  static constexpr bool kLinear = false;
  static constexpr int kBlocks = 9;
  static constexpr std::array<std::array<int, 2>, 9> kBlockSlots = {
      {{0, 0}, {0, 1}, {0, 2}, {1, 0}, {1, 1}, {1, 2}, {2, 0}, {2, 1}, {2, 2}}};
  bool uses_velocity() const { return false; }  ///< whether f depends on v
  double c1122, lu, lv;
  // On a curvilinear pattern, per centre: the rest lengths of its u- and
  // v-edge, in place of lu and lv.
  static constexpr bool kRest = true;
  static std::array<double, 4> RestOf(std::uint32_t, const std::array<Eigen::Vector2d, 3>& X) {
    return {(X[1] - X[0]).norm(), (X[2] - X[0]).norm(), 0.0, 0.0};
  }
  template <class S>
  void Evaluate(double, std::uint32_t, double, const double* rest, const std::array<V3<S>, 3>& x,
                const std::array<V3<S>, 3>&, std::array<V3<S>, 3>& f) const {
    const double ru = rest ? rest[0] : lu, rv = rest ? rest[1] : lv;  // rest lengths
    const V3<S> du = x[1] - x[0], dv = x[2] - x[0];
    const S nu = Norm(du), nv = Norm(dv);
    const S tau1 = c1122 * (nu / ru - 1.0);  // C ε_11 → stress along v
    const S tau2 = c1122 * (nv / rv - 1.0);  // C ε_22 → stress along u
    const V3<S> fu = tau1 * dv / nv, fv = tau2 * du / nu;
    f[0] += fu + fv;
    f[2] -= fu;
    f[1] -= fv;
  }
  void Blocks(double, std::uint32_t, double, const double* rest, const LinearWeights<3>*,
              const std::array<Vector3, 3>& x, const std::array<Vector3, 3>&, std::array<Matrix3, 9>& jx,
              std::array<Matrix3, 9>&) const {
    const double ru = rest ? rest[0] : lu, rv = rest ? rest[1] : lv;  // rest lengths
    const Vector3 du = x[1] - x[0], dv = x[2] - x[0];
    const double nu = du.norm(), nv = dv.norm();
    const Vector3 uh = du / nu, vh = dv / nv;
    const double tau1 = c1122 * (nu / ru - 1.0), tau2 = c1122 * (nv / rv - 1.0);
    const Matrix3 fu_du = (c1122 / ru) * vh * uh.transpose();
    const Matrix3 fu_dv = (tau1 / nv) * (Matrix3::Identity() - vh * vh.transpose());
    const Matrix3 fv_du = (tau2 / nu) * (Matrix3::Identity() - uh * uh.transpose());
    const Matrix3 fv_dv = (c1122 / rv) * uh * vh.transpose();
    // ∂f_u, ∂f_v with respect to x_i (slot 0), x_j (1), x_k (2).
    const Matrix3 fu[3] = {-(fu_du + fu_dv), fu_du, fu_dv};
    const Matrix3 fv[3] = {-(fv_du + fv_dv), fv_du, fv_dv};
    for (int b = 0; b < 3; ++b) {
      jx[static_cast<std::size_t>(b)] = fu[b] + fv[b];   // f_i
      jx[static_cast<std::size_t>(3 + b)] = -fv[b];      // f_j
      jx[static_cast<std::size_t>(6 + b)] = -fu[b];      // f_k
    }
  }
};

// --- Wind (2.35, 2.36) ------------------------------------------------------
// f_0 = A ((d − l)(f_w·n̂) n̂ + l f_w) with drag d, lift l, node area A, so
// ∂f_0/∂x_k = A (d − l)(n̂ f_wᵀ + (f_w·n̂) I) ∂n̂/∂x_k.
struct WindKernel {
  static constexpr int kNodes = 9;
  static constexpr int kOutputs = 1;
  static constexpr bool kLinear = false;
  static constexpr int kBlocks = 9;
  static constexpr std::array<std::array<int, 2>, 9> kBlockSlots = CentreRowSlots<9>();
  bool uses_velocity() const { return false; }  ///< whether f depends on v
  WindSpec w;
  Vector3 Field(double t) const { return (w.constant + std::sin(w.angular_frequency * t)) * w.direction; }
  template <class S>
  void Evaluate(double t, std::uint32_t valid, double area, const double*, const std::array<V3<S>, 9>& x,
                const std::array<V3<S>, 9>&,
                std::array<V3<S>, 9>& f) const {
    const Vector3 fw = Field(t);
    const V3<S> n = Patch<S, 9>{x, valid}.Normal();
    const S fn = n.dot(fw.cast<S>());
    const V3<S> normal = fn * n;
    f[0] += area * (w.drag * normal + w.lift * (fw.cast<S>() - normal));
  }
  void Blocks(double t, std::uint32_t valid, double area, const double*, const LinearWeights<9>*,
              const std::array<Vector3, 9>& x,
              const std::array<Vector3, 9>&, std::array<Matrix3, 9>& jx, std::array<Matrix3, 9>&) const {
    const Vector3 fw = Field(t);
    const double c = area * (w.drag - w.lift);
    NormalJacobian(
        Patch<double, 9>{x, valid},
        [&](const Vector3& n) {
          Matrix3 m = n * fw.transpose();
          m.diagonal().array() += fw.dot(n);
          return Matrix3(c * m);
        },
        &jx);
  }
};

// --- Air resistance (2.37): always opposes v (thesis §2.5) ------------------
// f_0 = −c A |q| v̂ with q = v·n̂, v̂ = v/|v|, so with σ = sign q (+1 at 0, as
// AutoDiff's |·|): ∂f_0/∂x_k = −c A σ v̂ (vᵀ ∂n̂/∂x_k) and
// ∂f_0/∂v_0 = −c A (σ v̂ n̂ᵀ + (|q|/|v|)(I − v̂v̂ᵀ)).
struct AirKernel {
  static constexpr int kNodes = 9;
  static constexpr int kOutputs = 1;
  static constexpr bool kLinear = false;
  static constexpr int kBlocks = 9;
  static constexpr std::array<std::array<int, 2>, 9> kBlockSlots = CentreRowSlots<9>();
  bool uses_velocity() const { return true; }  ///< whether f depends on v
  double c_air;
  template <class S>
  void Evaluate(double, std::uint32_t valid, double area, const double*, const std::array<V3<S>, 9>& x,
                const std::array<V3<S>, 9>& v,
                std::array<V3<S>, 9>& f) const {
    using std::abs;
    const S speed = Norm(v[0]);
    if (!(speed > 1e-12)) return;  // v/|v| undefined at rest; the force is 0 there
    const V3<S> n = Patch<S, 9>{x, valid}.Normal();
    f[0] -= (c_air * area * abs(v[0].dot(n)) / speed) * v[0];
  }
  void Blocks(double, std::uint32_t valid, double area, const double*, const LinearWeights<9>*,
              const std::array<Vector3, 9>& x,
              const std::array<Vector3, 9>& v, std::array<Matrix3, 9>& jx, std::array<Matrix3, 9>& jv) const {
    for (std::size_t k = 0; k < 9; ++k) {
      jx[k].setZero();
      jv[k].setZero();
    }
    const double speed = v[0].norm();
    if (!(speed > 1e-12)) return;
    const Vector3 vh = v[0] / speed;
    const double c = c_air * area;
    double q = 0.0, sigma = 1.0;
    const Vector3 n = NormalJacobian(
        Patch<double, 9>{x, valid},
        [&](const Vector3& nh) {
          q = v[0].dot(nh);
          sigma = q < 0.0 ? -1.0 : 1.0;
          return Matrix3((-c * sigma) * vh * v[0].transpose());
        },
        &jx);
    jv[0] = (-c * sigma) * vh * n.transpose() - (c * std::abs(q) / speed) * (Matrix3::Identity() - vh * vh.transpose());
  }
};

// --- Springs: nonlinear part of the IMEX split (docs/model.md §2.1) -----------------
class TensionNonlinear final : public ForceTerm {
 public:
  // F_nl on a (docs/model.md §2.1): −s_e l_e d/|d|, d = x_b − x_a.
  static Vector3 Force(const MatrixN3& x, const Spring& s) {
    const Vector3 d = (x.row(s.b) - x.row(s.a)).transpose();
    return (-s.stiffness * s.rest_length / d.norm()) * d;
  }
  TensionNonlinear(std::vector<Spring> springs, int num_particles) : springs_(std::move(springs)) {
    auto end = [this](std::size_t s, int k) { return k == 0 ? springs_[s].a : springs_[s].b; };
    if (static_cast<std::ptrdiff_t>(springs_.size()) >= kParallelMinimum)
      gather_ = GatherLists(num_particles, springs_.size(), 2, end);
  }
  std::string_view name() const override { return "tension_nonlinear"; }
  bool depends_on_velocity() const override { return false; }
  // ∂F_nl,a/∂x_b = −s_e l_e (I − d̂d̂ᵀ)/|d|; ∂/∂x_a is its negative.
  static Matrix3 Block(const MatrixN3& x, const Spring& s) {
    const Vector3 d = (x.row(s.b) - x.row(s.a)).transpose();
    const double len = d.norm();
    const Vector3 dh = d / len;
    return (-s.stiffness * s.rest_length / len) * (Matrix3::Identity() - dh * dh.transpose());
  }
  // Blocks (a, b), (a, a), (b, a), (b, b) of every spring.
  void JacobianBlocks(std::vector<BlockPair>* blocks) const override {
    for (const Spring& s : springs_) {
      blocks->push_back({s.a, s.b});
      blocks->push_back({s.a, s.a});
      blocks->push_back({s.b, s.a});
      blocks->push_back({s.b, s.b});
    }
  }
  std::size_t jacobian_items() const override { return springs_.size(); }
  void AccumulateJacobian(double, const MatrixN3& x, const MatrixN3&, const int* pos, double* dfdx, double*,
                          std::size_t first, std::size_t last) const override {
    for (std::size_t k = first; k < last; ++k) {
      const Matrix3 kab = Block(x, springs_[k]);
      const int* p = pos + 12 * k;
      AddBlock(kab, p, dfdx);
      AddBlock(-kab, p + 3, dfdx);
      AddBlock(kab, p + 6, dfdx);
      AddBlock(-kab, p + 9, dfdx);
    }
  }
  // Serial for few springs; else per-spring forces on the OpenMP threads,
  // gathered per particle in spring order (bit-identical, see GatherLists).
  void AddForce(double, const MatrixN3& x, const MatrixN3&, MatrixN3* f) const override {
    const auto n = static_cast<std::ptrdiff_t>(springs_.size());
    if (n < kParallelMinimum) {
      for (const Spring& s : springs_) {
        const Vector3 fa = Force(x, s);
        f->row(s.a) += fa.transpose();
        f->row(s.b) -= fa.transpose();
      }
      return;
    }
    double* buffer = gather_.buffer.data();
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t k = 0; k < n; ++k) {
      const Vector3 fa = Force(x, springs_[static_cast<std::size_t>(k)]);
      Eigen::Map<Vector3>(buffer + 6 * k) = fa;  // output 0: +F on a
      Eigen::Map<Vector3>(buffer + 6 * k + 3) = fa;  // output 1: −F on b
    }
    gather_.AddTo(f, [](int e) { return (e & 1) != 0; });
  }
  void AddJacobian(double, const MatrixN3& x, const MatrixN3&, std::vector<Triplet>* dfdx,
                   std::vector<Triplet>*) const override {
    for (const Spring& s : springs_) {
      const Matrix3 kab = Block(x, s);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) {
          dfdx->emplace_back(3 * s.a + r, 3 * s.b + c, kab(r, c));
          dfdx->emplace_back(3 * s.a + r, 3 * s.a + c, -kab(r, c));
          dfdx->emplace_back(3 * s.b + r, 3 * s.a + c, kab(r, c));
          dfdx->emplace_back(3 * s.b + r, 3 * s.b + c, -kab(r, c));
        }
    }
  }
  void PrepareParticleForces(int num_particles) const override {
    std::call_once(particle_once_, [&] {
      particle_springs_ = GatherLists(
          num_particles, springs_.size(), 2, [this](std::size_t s, int k) { return k == 0 ? springs_[s].a : springs_[s].b; },
          false);
    });
  }
  // F_nl on a is +Force, on b −Force; both diagonal blocks are −Block.
  void AddParticleForce(double, const MatrixN3& x, const MatrixN3&, int p, Vector3* f, Matrix3* dfdx,
                        Matrix3*) const override {
    for (int q = particle_springs_.offsets[static_cast<std::size_t>(p)];
         q < particle_springs_.offsets[static_cast<std::size_t>(p) + 1]; ++q) {
      const int e = particle_springs_.entries[static_cast<std::size_t>(q)];
      const Spring& s = springs_[static_cast<std::size_t>(e >> 1)];
      if ((e & 1) == 0) *f += Force(x, s);
      else *f -= Force(x, s);
      *dfdx -= Block(x, s);
    }
  }

 private:
  std::vector<Spring> springs_;
  mutable GatherLists gather_;  // many springs only
  mutable std::once_flag particle_once_;  // PrepareParticleForces
  mutable GatherLists particle_springs_;  // entries 2·spring + end (0: a, 1: b)
};

class Gravity final : public ForceTerm {
 public:
  Gravity(const Eigen::VectorXd& m, const Vector3& g) : force_(m * g.transpose()) {}
  std::string_view name() const override { return "gravity"; }
  void AddForce(double, const MatrixN3&, const MatrixN3&, MatrixN3* f) const override { *f += force_; }
  const MatrixN3* constant_force() const override { return &force_; }
  void AddJacobian(double, const MatrixN3&, const MatrixN3&, std::vector<Triplet>*, std::vector<Triplet>*) const override {}
  bool depends_on_velocity() const override { return false; }
  void JacobianBlocks(std::vector<BlockPair>*) const override {}
  std::size_t jacobian_items() const override { return 0; }
  void AccumulateJacobian(double, const MatrixN3&, const MatrixN3&, const int*, double*, double*, std::size_t,
                          std::size_t) const override {}
  void PrepareParticleForces(int) const override {}
  void AddParticleForce(double, const MatrixN3&, const MatrixN3&, int p, Vector3* f, Matrix3*, Matrix3*) const override {
    *f += force_.row(p).transpose();
  }

 private:
  MatrixN3 force_;
};

}  // namespace

std::unique_ptr<ForceTerm> MakeTensionNonlinear(std::vector<Spring> springs, int num_particles) {
  return std::make_unique<TensionNonlinear>(std::move(springs), num_particles);
}

std::unique_ptr<ForceTerm> MakeGravity(const Eigen::VectorXd& masses, const Vector3& g) {
  return std::make_unique<Gravity>(masses, g);
}

CentreRest CentreRestAt(const GridGeometry& geo, int i, int j) {
  const int cu = (i > 0) + (i + 1 < geo.nu), cv = (j > 0) + (j + 1 < geo.nv);
  return {geo.lu * cu, geo.lv * cv, geo.lu * geo.lv, 0.0};
}

CentreRest CentreRestAt(const ClothBlock& b, int i, int j) {
  std::array<Eigen::Vector2d, 5> x;
  std::uint32_t valid = 0;
  for (std::size_t k = 0; k < 5; ++k) {
    const int di = kOffsets[k][0], dj = kOffsets[k][1];
    const bool in = b.At(i + di, j + dj) >= 0;
    valid |= static_cast<std::uint32_t>(in) << k;
    x[k] = b.rest[static_cast<std::size_t>(in ? b.Cell(i + di, j + dj) : b.Cell(i, j))];
  }
  const std::array<double, 4> r = ShearKernel::RestOf(valid, x);
  return {r[0], r[1], r[2], r[3]};
}

void CurvilinearEnergies(const GridGeometry& geo, double mu, double bu, double bv, const MatrixN3& x, double* shear,
                         double* bending) {
  *shear = *bending = 0.0;
  ForEachCentre(*geo.cloth, [&](const ClothBlock& b, int i, int j, int p) {
    std::array<Vector3, 9> xs;
    std::array<Eigen::Vector2d, 9> rest;
    std::uint32_t valid = 0;
    for (std::size_t k = 0; k < 9; ++k) {
      const int q = b.At(i + kOffsets[k][0], j + kOffsets[k][1]);
      valid |= static_cast<std::uint32_t>(q >= 0) << k;
      xs[k] = x.row(q >= 0 ? q : p).transpose();
      rest[k] = b.rest[static_cast<std::size_t>(q >= 0 ? b.Cell(i + kOffsets[k][0], j + kOffsets[k][1]) : b.Cell(i, j))];
    }
    const CentreRest r = CentreRestAt(b, i, j);
    if (mu != 0.0) {
      const double gamma = ((xs[1] - xs[2]) / r.du).dot((xs[3] - xs[4]) / r.dv) - r.gamma0;
      *shear += 0.5 * mu * gamma * gamma * r.area;
    }
    if (bu != 0.0 || bv != 0.0) {
      const Patch<double, 9> patch{xs, valid, &rest};
      const Vector3 n = patch.Normal();
      const double kuu = patch.Lu(0, 0, 0.0).dot(n), kvv = patch.Lv(0, 0, 0.0).dot(n);
      *bending += 0.5 * r.area * (bu * kuu * kuu + bv * kvv * kvv);
    }
  });
}

std::unique_ptr<ForceTerm> MakeShear(const GridGeometry& geo, double mu, double damping) {
  return MakeGridTerm("shear", ShearKernel{mu, damping, geo.lu, geo.lv}, geo);
}

std::unique_ptr<ForceTerm> MakeMembraneBend(const GridGeometry& geo, double bu, double bv, double damping) {
  auto term = MakeGridTerm("bend_membrane", MembraneKernel{bu, bv, damping, geo.lu, geo.lv}, geo);
  if (!geo.curvilinear()) term->UseGridRows(geo.nu, geo.nv);
  return term;
}

std::unique_ptr<ForceTerm> MakeThinPlateBend(const GridGeometry& geo, double bu, double bv, double damping) {
  auto term = MakeGridTerm("bend_thin_plate", ThinPlateKernel{bu, bv, damping, geo.lu, geo.lv}, geo);
  if (!geo.curvilinear()) term->UseGridRows(geo.nu, geo.nv);
  return term;
}

std::unique_ptr<ForceTerm> MakeTransverse(const GridGeometry& geo, double c1122) {
  // Slots: the centre, its u-neighbour (left, right on a border), its
  // v-neighbour (lower, upper on a border); on patterns also their rest positions.
  std::vector<StencilTerm<TransverseKernel>::Centre> centres;
  std::vector<std::array<Eigen::Vector2d, 3>> planes;
  if (geo.curvilinear()) {
    ForEachCentre(*geo.cloth, [&](const ClothBlock& b, int i, int j, int p) {
      StencilTerm<TransverseKernel>::Centre c;
      const int di = b.At(i - 1, j) >= 0 ? -1 : 1, dj = b.At(i, j - 1) >= 0 ? -1 : 1;
      c.nodes = {p, b.At(i + di, j), b.At(i, j + dj)};
      c.valid = 7u;
      c.weight = geo.area(p);
      centres.push_back(c);
      planes.push_back({b.rest[static_cast<std::size_t>(b.Cell(i, j))], b.rest[static_cast<std::size_t>(b.Cell(i + di, j))],
                        b.rest[static_cast<std::size_t>(b.Cell(i, j + dj))]});
    });
    return std::make_unique<StencilTerm<TransverseKernel>>("transverse", TransverseKernel{c1122, geo.lu, geo.lv},
                                                           std::move(centres), geo.cloth->num_particles, planes);
  }
  for (int j = 0; j < geo.nv; ++j)
    for (int i = 0; i < geo.nu; ++i) {
      StencilTerm<TransverseKernel>::Centre c;
      c.nodes[0] = i + geo.nu * j;
      c.nodes[1] = (i > 0 ? i - 1 : i + 1) + geo.nu * j;
      c.nodes[2] = i + geo.nu * (j > 0 ? j - 1 : j + 1);
      c.valid = 7u;
      c.weight = geo.area(c.nodes[0]);
      centres.push_back(c);
    }
  return std::make_unique<StencilTerm<TransverseKernel>>("transverse", TransverseKernel{c1122, geo.lu, geo.lv},
                                                         std::move(centres), geo.nu * geo.nv);
}

std::unique_ptr<ForceTerm> MakeWind(const GridGeometry& geo, const WindSpec& wind) {
  return MakeGridTerm("wind", WindKernel{wind}, geo);
}

std::unique_ptr<ForceTerm> MakeAirResistance(const GridGeometry& geo, double c_air) {
  return MakeGridTerm("air", AirKernel{c_air}, geo);
}

}  // namespace clothbench
