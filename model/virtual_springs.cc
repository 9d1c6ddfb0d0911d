// The virtual springs' force (model/virtual_springs.h; thesis §5.4): the
// points on the cloth edges, the split rest lengths and the force
// correction.
#include "model/virtual_springs.h"

#include <algorithm>

#include "model/block_scatter.h"

namespace clothbench {
namespace {

// Two candidates that are one virtual particle: the same obstacle edge
// through the same cloth edge (found from both its faces), or the same
// point inside a face (an obstacle vertex that ends several edges; its
// coordinates from different edges differ by round-off).
bool SamePoint(const VirtualParticle& l, const VirtualParticle& r) {
  if (l.a != r.a || l.b != r.b) return false;
  if (l.a < 0) return l.face == r.face && (l.x - r.x).squaredNorm() <= 1e-24 * (1.0 + l.x.squaredNorm());
  return l.obstacle == r.obstacle && l.edge == r.edge;
}

}  // namespace

VirtualSprings::VirtualSprings(int grid_nu, int grid_nv, const std::vector<Spring>& springs, bool split_tension)
    : nu_(grid_nu), springs_(springs), split_(split_tension) {
  const auto n = static_cast<std::size_t>(grid_nu) * static_cast<std::size_t>(grid_nv);
  u_spring_.assign(n, -1);
  v_spring_.assign(n, -1);
  for (std::size_t k = 0; k < springs_.size(); ++k) {
    const Spring& s = springs_[k];
    const int lo = std::min(s.a, s.b), hi = std::max(s.a, s.b);
    (hi - lo == 1 ? u_spring_ : v_spring_)[static_cast<std::size_t>(lo)] = static_cast<int>(k);
    damped_ = damped_ || s.damping != 0.0;
  }
  spring_side_.assign(2 * springs_.size(), -1);
  first_side_.assign(n, -1);
}

VirtualSprings::~VirtualSprings() = default;

void VirtualSprings::ClearTopology() {
  for (const VirtualSpring& side : sides_) {
    const Spring& s = springs_[static_cast<std::size_t>(side.spring)];
    spring_side_[2 * static_cast<std::size_t>(side.spring) + (side.p == s.a ? 0 : 1)] = -1;
    first_side_[static_cast<std::size_t>(side.p)] = -1;
  }
  sides_.clear();
  couplings_.clear();
  next_side_.clear();
  particles_.clear();
}

// §5.4: one virtual particle per (cloth edge, obstacle edge), the points of
// each cloth edge ordered from a to b, and the split springs.
void VirtualSprings::SplitSprings(double t, const MatrixN3& x) {
  t_update_ = t;
  // §5.4: a point on a cloth edge is found from both faces of that edge:
  // keep one per (cloth edge, obstacle edge). Then order the points of each
  // cloth edge from a to b.
  std::sort(particles_.begin(), particles_.end(), [](const VirtualParticle& l, const VirtualParticle& r) {
    if (l.a != r.a) return l.a < r.a;
    if (l.b != r.b) return l.b < r.b;
    if (l.a < 0) {  // inside a face: one per point (an obstacle vertex ends several edges)
      if (l.face != r.face) return l.face < r.face;
      return std::lexicographical_compare(l.x.data(), l.x.data() + 3, r.x.data(), r.x.data() + 3);
    }
    if (l.obstacle != r.obstacle) return l.obstacle < r.obstacle;
    if (l.edge != r.edge) return l.edge < r.edge;
    return l.s < r.s;
  });
  particles_.erase(std::unique(particles_.begin(), particles_.end(), SamePoint), particles_.end());
  // Runs of one cloth edge, ordered by s.
  std::size_t k = 0;
  while (k < particles_.size() && particles_[k].a < 0) ++k;
  while (k < particles_.size()) {
    std::size_t end = k;
    while (end < particles_.size() && particles_[end].a == particles_[k].a && particles_[end].b == particles_[k].b)
      ++end;
    std::sort(particles_.begin() + static_cast<std::ptrdiff_t>(k), particles_.begin() + static_cast<std::ptrdiff_t>(end),
              [](const VirtualParticle& l, const VirtualParticle& r) { return l.s < r.s; });
    const int a = particles_[k].a, b = particles_[k].b;
    const int spring = b - a == 1 && a % nu_ != nu_ - 1 ? u_spring_[static_cast<std::size_t>(a)]
                       : b - a == nu_                     ? v_spring_[static_cast<std::size_t>(a)]
                                                          : -1;
    if (spring >= 0) {
      // Current segment lengths l_0 … l_m of P_a V_1 … V_m P_b.
      const Vector3 xa = x.row(a).transpose(), xb = x.row(b).transpose();
      double total = (particles_[k].x - xa).norm() + (xb - particles_[end - 1].x).norm();
      for (std::size_t j = k + 1; j < end; ++j) total += (particles_[j].x - particles_[j - 1].x).norm();
      const Spring& s = springs_[static_cast<std::size_t>(spring)];
      if (total > 0.0) {
        const auto add_side = [&](int p, int q, std::size_t neighbour, double segment) {
          VirtualSpring side;
          side.spring = spring;
          side.p = p;
          side.q = q;
          side.neighbour = static_cast<int>(neighbour);
          side.rest = s.rest_length * segment / total;  // r_j = r l_j / Σ l_i
          spring_side_[2 * static_cast<std::size_t>(spring) + (p == s.a ? 0 : 1)] = static_cast<int>(sides_.size());
          next_side_.push_back(first_side_[static_cast<std::size_t>(p)]);
          first_side_[static_cast<std::size_t>(p)] = static_cast<int>(sides_.size());
          sides_.push_back(side);
        };
        // Particles a and b of the sort are the spring's ends in either order.
        const std::size_t near_a = k, near_b = end - 1;
        add_side(a, b, near_a, (particles_[near_a].x - xa).norm());
        add_side(b, a, near_b, (xb - particles_[near_b].x).norm());
        couplings_.push_back({spring, a, b, s.stiffness, s.damping});
      }
    }
    k = end;
  }
}

int VirtualSprings::Find(const VirtualParticle& c) const {
  const auto run = std::equal_range(particles_.begin(), particles_.end(), c, [](const VirtualParticle& l, const VirtualParticle& r) {
    return l.a != r.a ? l.a < r.a : l.b < r.b;
  });
  for (auto it = run.first; it != run.second; ++it)
    if (SamePoint(*it, c)) return static_cast<int>(it - particles_.begin());
  return -1;
}

double VirtualSprings::TensionEnergyChange(const MatrixN3& x) const {
  const auto energy = [&](double stiffness, double length, double rest) {
    const double stretch = split_ ? length - rest : length;
    return 0.5 * stiffness * stretch * stretch;
  };
  double e = 0.0;
  for (const VirtualSpring& side : sides_) {
    const Spring& s = springs_[static_cast<std::size_t>(side.spring)];
    e += energy(s.stiffness, (particles_[static_cast<std::size_t>(side.neighbour)].x - x.row(side.p).transpose()).norm(),
                side.rest);
  }
  for (const RemovedCoupling& c : couplings_) {
    const Spring& s = springs_[static_cast<std::size_t>(c.spring)];
    e -= energy(s.stiffness, (x.row(c.b) - x.row(c.a)).norm(), s.rest_length);
  }
  return e;
}

void VirtualSprings::AddRemovedCouplings(const MatrixN3& x, const MatrixN3& v, MatrixN3* g) const {
  AddCouplingProduct(false, x, g);
  if (damped_) AddCouplingProduct(true, v, g);
}

void VirtualSprings::AddCouplingProduct(bool damping, const MatrixN3& x, MatrixN3* out) const {
  for (const RemovedCoupling& c : couplings_) {
    const double w = damping ? c.damping : c.stiffness;
    if (w == 0.0) continue;
    out->row(c.a) += w * x.row(c.b);
    out->row(c.b) += w * x.row(c.a);
  }
}

Vector3 VirtualSprings::PositionAt(int k, double t) const {
  const VirtualParticle& vp = particles_[static_cast<std::size_t>(k)];
  return vp.x + (t - t_update_) * vp.v;
}

// On particle p with replaced neighbour q and virtual neighbour V:
//   Δf = s (x_V − x_q) + c (v_V − v_q) − s (r_j d̂_V − l d̂),
// d_V = x_V − x_p, d = x_q − x_p (the rest-length part only with F_nl).
//   ∂Δf/∂x_p = s r_j (I − d̂_V d̂_Vᵀ)/|d_V| − s l (I − d̂ d̂ᵀ)/|d|,
//   ∂Δf/∂x_q = −s I + s l (I − d̂ d̂ᵀ)/|d|,  ∂Δf/∂v_q = −c I.
void VirtualSprings::SideTerms(const VirtualSpring& side, double t, const MatrixN3& x, const MatrixN3& v,
                                 Vector3* f, Matrix3* dp, Matrix3* dq) const {
  const Spring& s = springs_[static_cast<std::size_t>(side.spring)];
  const VirtualParticle& vp = particles_[static_cast<std::size_t>(side.neighbour)];
  const Vector3 xv = PositionAt(side.neighbour, t);
  const Vector3 xp = x.row(side.p).transpose(), xq = x.row(side.q).transpose();
  *f = s.stiffness * (xv - xq);
  if (s.damping != 0.0) *f += s.damping * (vp.v - v.row(side.q).transpose());
  *dp = Matrix3::Zero();
  *dq = -s.stiffness * Matrix3::Identity();
  if (!split_) return;
  const Vector3 dv = xv - xp, d = xq - xp;
  const double lv = dv.norm(), l = d.norm();
  if (lv > 0.0) {
    const Vector3 u = dv / lv;
    *f -= (s.stiffness * side.rest) * u;
    *dp += (s.stiffness * side.rest / lv) * (Matrix3::Identity() - u * u.transpose());
  }
  if (l > 0.0) {
    const Vector3 u = d / l;
    const Matrix3 k = (s.stiffness * s.rest_length / l) * (Matrix3::Identity() - u * u.transpose());
    *f += (s.stiffness * s.rest_length) * u;
    *dp -= k;
    *dq += k;
  }
}

void VirtualSprings::AddForce(double t, const MatrixN3& x, const MatrixN3& v, MatrixN3* f) const {
  Vector3 fp;
  Matrix3 dp, dq;
  for (const VirtualSpring& side : sides_) {
    SideTerms(side, t, x, v, &fp, &dp, &dq);
    f->row(side.p) += fp.transpose();
  }
}

void VirtualSprings::AddJacobian(double t, const MatrixN3& x, const MatrixN3& v, std::vector<Triplet>* dfdx,
                                   std::vector<Triplet>* dfdv) const {
  // The pattern of every spring's four blocks, whether split or not (it
  // may not depend on the state); zeros where no side is.
  Vector3 fp;
  for (std::size_t k = 0; k < springs_.size(); ++k) {
    const Spring& s = springs_[k];
    for (int end = 0; end < 2; ++end) {
      const int p = end == 0 ? s.a : s.b, q = end == 0 ? s.b : s.a;
      Matrix3 dp = Matrix3::Zero(), dq = Matrix3::Zero(), dvq = Matrix3::Zero();
      if (const int side = spring_side_[2 * k + static_cast<std::size_t>(end)]; side >= 0) {
        SideTerms(sides_[static_cast<std::size_t>(side)], t, x, v, &fp, &dp, &dq);
        dvq = -s.damping * Matrix3::Identity();
      }
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) {
          dfdx->emplace_back(3 * p + r, 3 * p + c, dp(r, c));
          dfdx->emplace_back(3 * p + r, 3 * q + c, dq(r, c));
          if (damped_) dfdv->emplace_back(3 * p + r, 3 * q + c, dvq(r, c));
        }
    }
  }
}

void VirtualSprings::JacobianBlocks(std::vector<BlockPair>* blocks) const {
  for (const Spring& s : springs_) {
    blocks->push_back({s.a, s.b});
    blocks->push_back({s.a, s.a});
    blocks->push_back({s.b, s.a});
    blocks->push_back({s.b, s.b});
  }
}

void VirtualSprings::AccumulateJacobian(double t, const MatrixN3& x, const MatrixN3& v, const int* pos,
                                          double* dfdx, double* dfdv, std::size_t first, std::size_t last) const {
  if (sides_.empty()) return;
  Vector3 fp;
  Matrix3 dp, dq;
  for (std::size_t k = first; k < last; ++k)
    for (int end = 0; end < 2; ++end) {
      const int side = spring_side_[2 * k + static_cast<std::size_t>(end)];
      if (side < 0) continue;
      SideTerms(sides_[static_cast<std::size_t>(side)], t, x, v, &fp, &dp, &dq);
      // Blocks (a, b), (a, a), (b, a), (b, b): row p's off-diagonal and diagonal.
      const int* p = pos + 12 * k + (end == 0 ? 0 : 6);
      AddBlock(dq, p, dfdx);
      AddBlock(dp, p + 3, dfdx);
      if (damped_) AddBlock(Matrix3(-springs_[k].damping * Matrix3::Identity()), p, dfdv);
    }
}

void VirtualSprings::AddParticleForce(double t, const MatrixN3& x, const MatrixN3& v, int p, Vector3* f,
                                        Matrix3* dfdx, Matrix3*) const {
  Vector3 fp;
  Matrix3 dp, dq;
  for (int side = first_side_[static_cast<std::size_t>(p)]; side >= 0; side = next_side_[static_cast<std::size_t>(side)]) {
    SideTerms(sides_[static_cast<std::size_t>(side)], t, x, v, &fp, &dp, &dq);
    *f += fp;
    *dfdx += dp;
  }
}

}  // namespace clothbench
