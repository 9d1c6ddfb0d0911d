// Force terms (SPEC §2). Stencil terms are written once as a kernel templated
// on the scalar type: with double it gives the force, with forward-mode
// automatic differentiation (Eigen AutoDiffScalar) the exact Jacobian blocks.
#include "model/force_terms.h"

#include <array>
#include <cmath>
#include <cstdint>
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

// Read-only view of a gathered patch.
template <class S, int K>
struct Patch {
  const std::array<V3<S>, K>& x;
  std::uint32_t valid;
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
    return (At(di + 1, dj) - 2.0 * At(di, dj) + At(di - 1, dj)) / (lu * lu);
  }
  V3<S> Lv(int di, int dj, double lv) const {
    if (!Has(di, dj - 1) || !Has(di, dj + 1) || !Has(di, dj)) return V3<S>::Zero();
    return (At(di, dj + 1) - 2.0 * At(di, dj) + At(di, dj - 1)) / (lv * lv);
  }
  // Unit vertex normal at the centre: mean of the unit normals of the
  // adjacent quads, each from the cross product of its diagonals (SPEC §2.3).
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

// Scatter made parallel and deterministic: the items (stencil centres or
// springs) write their `outputs` force vectors into a buffer, then each
// particle sums its buffer entries in item order, which is the order of the
// serial scatter loop. `node(item, k)` names the particle of output k;
// AddTo's `negate(entry)` says which entries are subtracted.
struct GatherLists {
  GatherLists() = default;
  template <class NodeOf>
  GatherLists(int num_particles, std::size_t items, int outputs, NodeOf node) {
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
    buffer.assign(3 * items * static_cast<std::size_t>(outputs), 0.0);
  }
  // f(p) += Σ buffer entries of p, in item order; `negate(e)` says whether
  // entry e is subtracted.
  template <class Negate>
  void AddTo(MatrixN3* f, Negate negate) const {
    const auto n = static_cast<std::ptrdiff_t>(offsets.size()) - 1;
    double* f0 = f->col(0).data();
    double* f1 = f->col(1).data();
    double* f2 = f->col(2).data();
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t p = 0; p < n; ++p) {
      double a0 = f0[p], a1 = f1[p], a2 = f2[p];
      for (int q = offsets[static_cast<std::size_t>(p)]; q < offsets[static_cast<std::size_t>(p) + 1]; ++q) {
        const int e = entries[static_cast<std::size_t>(q)];
        const double* b = buffer.data() + 3 * static_cast<std::size_t>(e);
        if (negate(e)) {
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

// Generic term over per-centre stencils of K particles; the kernel writes
// forces into the first Kernel::kOutputs slots.
template <class Kernel>
class StencilTerm final : public ForceTerm {
 public:
  static constexpr int K = Kernel::kNodes;
  struct Centre {
    std::array<int, K> nodes{};
    std::uint32_t valid = 0;
    double weight = 0.0;
  };

  StencilTerm(std::string name, Kernel kernel, std::vector<Centre> centres, int num_particles)
      : name_(std::move(name)), kernel_(std::move(kernel)), centres_(std::move(centres)) {
    if (Kernel::kOutputs > 1 && static_cast<int>(centres_.size()) >= kParallelMinimum)
      gather_ = GatherLists(num_particles, centres_.size(), Kernel::kOutputs,
                            [this](std::size_t c, int k) { return centres_[c].nodes[static_cast<std::size_t>(k)]; });
  }

  std::string_view name() const override { return name_; }

  // Serial below kParallelMinimum centres. Above it, the centres are split
  // over the OpenMP threads: a kernel with one output writes only its own
  // centre particle; one with several writes its outputs to a buffer, and
  // each particle then sums its entries in centre order. Either way every
  // force is summed in the serial order: bit-identical for any thread count.
  void AddForce(double t, const MatrixN3& x, const MatrixN3& v, MatrixN3* f) const override {
    const auto n = static_cast<std::ptrdiff_t>(centres_.size());
    if (n < kParallelMinimum) {
      for (std::ptrdiff_t c = 0; c < n; ++c) {
        std::array<Vector3, Kernel::kOutputs> fs;
        Evaluate(t, x, v, centres_[static_cast<std::size_t>(c)], &fs);
        for (int k = 0; k < Kernel::kOutputs; ++k) f->row(centres_[static_cast<std::size_t>(c)].nodes[k]) += fs[k].transpose();
      }
      return;
    }
    if constexpr (Kernel::kOutputs == 1) {
#pragma omp parallel for schedule(static)
      for (std::ptrdiff_t c = 0; c < n; ++c) {
        std::array<Vector3, 1> fs;
        Evaluate(t, x, v, centres_[static_cast<std::size_t>(c)], &fs);
        f->row(centres_[static_cast<std::size_t>(c)].nodes[0]) += fs[0].transpose();
      }
    } else {
      double* buffer = gather_.buffer.data();
#pragma omp parallel for schedule(static)
      for (std::ptrdiff_t c = 0; c < n; ++c) {
        std::array<Vector3, Kernel::kOutputs> fs;
        Evaluate(t, x, v, centres_[static_cast<std::size_t>(c)], &fs);
        for (int k = 0; k < Kernel::kOutputs; ++k)
          Eigen::Map<Vector3>(buffer + 3 * (c * Kernel::kOutputs + k)) = fs[static_cast<std::size_t>(k)];
      }
      gather_.AddTo(f);
    }
  }

  // Forward-mode AutoDiff over the stencil's positions, and over its
  // velocities only if the kernel uses them (damping, wind, air): the
  // derivative vectors are then half as long, and so is the cost. A kernel
  // that does not use v emits no dfdv triplets at all (uses_velocity() is
  // fixed for a term, so the pattern never changes).
  void AddJacobian(double t, const MatrixN3& x, const MatrixN3& v, std::vector<Triplet>* dfdx,
                   std::vector<Triplet>* dfdv) const override {
    if (kernel_.uses_velocity())
      JacobianPass<true>(t, x, v, dfdx, dfdv);
    else
      JacobianPass<false>(t, x, v, dfdx, dfdv);
  }

 private:
  template <bool kVelocity>
  void JacobianPass(double t, const MatrixN3& x, const MatrixN3& v, std::vector<Triplet>* dfdx,
                    std::vector<Triplet>* dfdv) const {
    constexpr int D = kVelocity ? 6 * K : 3 * K;
    using Derivs = Eigen::Matrix<double, D, 1>;
    using AD = Eigen::AutoDiffScalar<Derivs>;
    // Every centre writes its fixed number of triplets at its own offset,
    // so the centres run on the OpenMP threads with a result independent of
    // the thread count (AutoDiff costs microseconds per centre: threads pay
    // off from a few hundred centres). resize() keeps the capacity: no
    // allocation after the first call.
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
      kernel_.template Evaluate<AD>(t, c.valid, c.weight, xs, vs, fs);
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

  void Evaluate(double t, const MatrixN3& x, const MatrixN3& v, const Centre& c,
                std::array<Vector3, Kernel::kOutputs>* out) const {
    std::array<Vector3, K> xs, vs, fs;
    for (int k = 0; k < K; ++k) {
      xs[k] = x.row(c.nodes[k]).transpose();
      vs[k] = v.row(c.nodes[k]).transpose();
      fs[k].setZero();
    }
    kernel_.template Evaluate<double>(t, c.valid, c.weight, xs, vs, fs);
    for (int k = 0; k < Kernel::kOutputs; ++k) (*out)[static_cast<std::size_t>(k)] = fs[static_cast<std::size_t>(k)];
  }

  std::string name_;
  Kernel kernel_;
  std::vector<Centre> centres_;
  mutable GatherLists gather_;  // kOutputs > 1 and many centres only
};

// Builds one centre per particle with the first K patch slots.
template <class Kernel>
std::vector<typename StencilTerm<Kernel>::Centre> GridCentres(const GridGeometry& geo) {
  constexpr int K = Kernel::kNodes;
  std::vector<typename StencilTerm<Kernel>::Centre> out;
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
      c.weight = geo.area(p);
      out.push_back(c);
    }
  return out;
}

// --- Shear, energy form (SPEC §2.2) -----------------------------------------
// γ = ⟨a, b⟩, a = (x_r − x_l)/Δu, b = (x_u − x_d)/Δv, one-sided on the border
// (missing neighbour := centre, spacing halves). E = ½ μ γ² lu lv and the
// Rayleigh dissipation ½ d_s γ̇² lu lv give F = −(μ γ + d_s γ̇) lu lv ∂γ/∂x.
struct ShearKernel {
  static constexpr int kNodes = 5;    // centre, r, l, u, d
  static constexpr int kOutputs = 5;
  bool uses_velocity() const { return damping != 0.0; }  ///< whether f depends on v
  double mu, damping, lu, lv;
  template <class S>
  void Evaluate(double, std::uint32_t valid, double, const std::array<V3<S>, 5>& x, const std::array<V3<S>, 5>& v,
                std::array<V3<S>, 5>& f) const {
    const double du = lu * (((valid >> 1) & 1u) + ((valid >> 2) & 1u));
    const double dv = lv * (((valid >> 3) & 1u) + ((valid >> 4) & 1u));
    const V3<S> a = (x[1] - x[2]) / du, b = (x[3] - x[4]) / dv;
    const V3<S> ad = (v[1] - v[2]) / du, bd = (v[3] - v[4]) / dv;
    S sigma = mu * a.dot(b);
    if (damping != 0.0) sigma += damping * (ad.dot(b) + a.dot(bd));
    const S s = sigma * (lu * lv);
    f[1] -= s * b / du;
    f[2] += s * b / du;
    f[3] -= s * a / dv;
    f[4] += s * a / dv;
  }
};

// --- Membrane bending (2.25), Alg. 3 ----------------------------------------
struct MembraneKernel {
  static constexpr int kNodes = 9;
  static constexpr int kOutputs = 1;
  bool uses_velocity() const { return damping != 0.0; }  ///< whether f depends on v
  double bu, bv, damping, lu, lv;
  template <class S>
  void Evaluate(double, std::uint32_t valid, double, const std::array<V3<S>, 9>& x, const std::array<V3<S>, 9>& v,
                std::array<V3<S>, 9>& f) const {
    const Patch<S, 9> px{x, valid}, pv{v, valid};
    V3<S> s = bu * px.Lu(0, 0, lu) + bv * px.Lv(0, 0, lv);
    if (damping != 0.0) s += damping * (pv.Lu(0, 0, lu) + pv.Lv(0, 0, lv));
    const V3<S> n = px.Normal();
    f[0] += (s.dot(n) * (lu * lv)) * n;
  }
};

// --- Thin-plate bending (2.26), Alg. 4 --------------------------------------
// S = B_u ∂uu R + B_v ∂vv R with R = (∂uu + ∂vv) x, which expands to
// B_u s_uuuu + (B_u+B_v) s_uuvv + B_v s_vvvv; viscosity d_b Δ²v.
struct ThinPlateKernel {
  static constexpr int kNodes = 13;
  static constexpr int kOutputs = 1;
  bool uses_velocity() const { return damping != 0.0; }  ///< whether f depends on v
  double bu, bv, damping, lu, lv;

  template <class S>
  static V3<S> BiLaplacian(const Patch<S, 13>& p, double wu, double wv, double lu, double lv) {
    // Second differences of R = Lu + Lv at the centre, zero normal to a border.
    auto R = [&](int di, int dj) { return V3<S>(p.Lu(di, dj, lu) + p.Lv(di, dj, lv)); };
    V3<S> out = V3<S>::Zero();
    if (wu != 0.0 && p.Has(1, 0) && p.Has(-1, 0)) out += wu * (R(1, 0) - 2.0 * R(0, 0) + R(-1, 0)) / (lu * lu);
    if (wv != 0.0 && p.Has(0, 1) && p.Has(0, -1)) out += wv * (R(0, 1) - 2.0 * R(0, 0) + R(0, -1)) / (lv * lv);
    return out;
  }

  template <class S>
  void Evaluate(double, std::uint32_t valid, double, const std::array<V3<S>, 13>& x, const std::array<V3<S>, 13>& v,
                std::array<V3<S>, 13>& f) const {
    const Patch<S, 13> px{x, valid};
    V3<S> s = BiLaplacian(px, bu, bv, lu, lv);
    if (damping != 0.0) s += BiLaplacian(Patch<S, 13>{v, valid}, damping, damping, lu, lv);
    const V3<S> n = px.Normal();
    f[0] -= (s.dot(n) * (lu * lv)) * n;
  }
};

// --- Transverse contraction (2.22), Alg. 5 ----------------------------------
// Slots: centre i, its u-neighbour j (left, right on the border), its
// v-neighbour k (lower j−1, upper on the border). τ1 = C ε_11 acts along the
// v-edge (i,k), τ2 = C ε_22 along the u-edge (i,j).
struct TransverseKernel {
  static constexpr int kNodes = 3;
  static constexpr int kOutputs = 3;
  bool uses_velocity() const { return false; }  ///< whether f depends on v
  double c1122, lu, lv;
  template <class S>
  void Evaluate(double, std::uint32_t, double, const std::array<V3<S>, 3>& x, const std::array<V3<S>, 3>&,
                std::array<V3<S>, 3>& f) const {
    const V3<S> du = x[1] - x[0], dv = x[2] - x[0];
    const S nu = Norm(du), nv = Norm(dv);
    const S tau1 = c1122 * (nu / lu - 1.0);  // C ε_11 → stress along v
    const S tau2 = c1122 * (nv / lv - 1.0);  // C ε_22 → stress along u
    const V3<S> fu = tau1 * dv / nv, fv = tau2 * du / nu;
    f[0] += fu + fv;
    f[2] -= fu;
    f[1] -= fv;
  }
};

// --- Wind (2.35, 2.36) ------------------------------------------------------
struct WindKernel {
  static constexpr int kNodes = 9;
  static constexpr int kOutputs = 1;
  bool uses_velocity() const { return false; }  ///< whether f depends on v
  WindSpec w;
  template <class S>
  void Evaluate(double t, std::uint32_t valid, double area, const std::array<V3<S>, 9>& x, const std::array<V3<S>, 9>&,
                std::array<V3<S>, 9>& f) const {
    const Vector3 fw = (w.constant + std::sin(w.angular_frequency * t)) * w.direction;
    const V3<S> n = Patch<S, 9>{x, valid}.Normal();
    const S fn = n.dot(fw.cast<S>());
    const V3<S> normal = fn * n;
    f[0] += area * (w.drag * normal + w.lift * (fw.cast<S>() - normal));
  }
};

// --- Air resistance (2.37): always opposes v (SPEC §2.5) --------------------
struct AirKernel {
  static constexpr int kNodes = 9;
  static constexpr int kOutputs = 1;
  bool uses_velocity() const { return true; }  ///< whether f depends on v
  double c_air;
  template <class S>
  void Evaluate(double, std::uint32_t valid, double area, const std::array<V3<S>, 9>& x, const std::array<V3<S>, 9>& v,
                std::array<V3<S>, 9>& f) const {
    using std::abs;
    const S speed = Norm(v[0]);
    if (!(speed > 1e-12)) return;  // v/|v| undefined at rest; the force is 0 there
    const V3<S> n = Patch<S, 9>{x, valid}.Normal();
    f[0] -= (c_air * area * abs(v[0].dot(n)) / speed) * v[0];
  }
};

// --- Springs: nonlinear part of the IMEX split (SPEC §2.1) -----------------
class TensionNonlinear final : public ForceTerm {
 public:
  // F_nl on a (SPEC §2.1): −s_e l_e d/|d|, d = x_b − x_a.
  static Vector3 Force(const MatrixN3& x, const Spring& s) {
    const Vector3 d = (x.row(s.b) - x.row(s.a)).transpose();
    return (-s.stiffness * s.rest_length / d.norm()) * d;
  }
  TensionNonlinear(std::vector<Spring> springs, int num_particles) : springs_(std::move(springs)) {
    if (static_cast<std::ptrdiff_t>(springs_.size()) >= kParallelMinimum)
      gather_ = GatherLists(num_particles, springs_.size(), 2, [this](std::size_t s, int k) {
        return k == 0 ? springs_[s].a : springs_[s].b;
      });
  }
  std::string_view name() const override { return "tension_nonlinear"; }
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
  // ∂F_nl,a/∂x_b = −s_e l_e (I − d̂d̂ᵀ)/|d|; ∂/∂x_a is its negative.
  void AddJacobian(double, const MatrixN3& x, const MatrixN3&, std::vector<Triplet>* dfdx,
                   std::vector<Triplet>*) const override {
    for (const Spring& s : springs_) {
      const Vector3 d = (x.row(s.b) - x.row(s.a)).transpose();
      const double len = d.norm();
      const Vector3 dh = d / len;
      const Eigen::Matrix3d kab = (-s.stiffness * s.rest_length / len) * (Eigen::Matrix3d::Identity() - dh * dh.transpose());
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) {
          dfdx->emplace_back(3 * s.a + r, 3 * s.b + c, kab(r, c));
          dfdx->emplace_back(3 * s.a + r, 3 * s.a + c, -kab(r, c));
          dfdx->emplace_back(3 * s.b + r, 3 * s.a + c, kab(r, c));
          dfdx->emplace_back(3 * s.b + r, 3 * s.b + c, -kab(r, c));
        }
    }
  }

 private:
  std::vector<Spring> springs_;
  mutable GatherLists gather_;  // many springs only
};

class Gravity final : public ForceTerm {
 public:
  Gravity(const Eigen::VectorXd& m, const Vector3& g) : force_(m * g.transpose()) {}
  std::string_view name() const override { return "gravity"; }
  void AddForce(double, const MatrixN3&, const MatrixN3&, MatrixN3* f) const override { *f += force_; }
  void AddJacobian(double, const MatrixN3&, const MatrixN3&, std::vector<Triplet>*, std::vector<Triplet>*) const override {}

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

std::unique_ptr<ForceTerm> MakeShear(const GridGeometry& geo, double mu, double damping) {
  return std::make_unique<StencilTerm<ShearKernel>>("shear", ShearKernel{mu, damping, geo.lu, geo.lv},
                                                    GridCentres<ShearKernel>(geo), geo.nu * geo.nv);
}

std::unique_ptr<ForceTerm> MakeMembraneBend(const GridGeometry& geo, double bu, double bv, double damping) {
  return std::make_unique<StencilTerm<MembraneKernel>>(
      "bend_membrane", MembraneKernel{bu, bv, damping, geo.lu, geo.lv}, GridCentres<MembraneKernel>(geo), geo.nu * geo.nv);
}

std::unique_ptr<ForceTerm> MakeThinPlateBend(const GridGeometry& geo, double bu, double bv, double damping) {
  return std::make_unique<StencilTerm<ThinPlateKernel>>(
      "bend_thin_plate", ThinPlateKernel{bu, bv, damping, geo.lu, geo.lv}, GridCentres<ThinPlateKernel>(geo), geo.nu * geo.nv);
}

std::unique_ptr<ForceTerm> MakeTransverse(const GridGeometry& geo, double c1122) {
  std::vector<StencilTerm<TransverseKernel>::Centre> centres;
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
  return std::make_unique<StencilTerm<WindKernel>>("wind", WindKernel{wind}, GridCentres<WindKernel>(geo), geo.nu * geo.nv);
}

std::unique_ptr<ForceTerm> MakeAirResistance(const GridGeometry& geo, double c_air) {
  return std::make_unique<StencilTerm<AirKernel>>("air", AirKernel{c_air}, GridCentres<AirKernel>(geo), geo.nu * geo.nv);
}

}  // namespace clothbench
