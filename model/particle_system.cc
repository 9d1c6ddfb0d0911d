// Assembly of the particle model (docs/model.md §1, §2, §2.6).
#include "model/particle_system.h"

#include <algorithm>
#include <array>
#include <set>
#include <utility>

#include <Eigen/Geometry>
#include <fmt/format.h>

namespace clothbench {

ParticleSystem::ParticleSystem(const Scene& scene) : scene_(scene) {
  const int nu = scene.grid.nu, nv = scene.grid.nv;
  n_ = scene.num_particles();
  const double lu = scene.lu(), lv = scene.lv();
  const MaterialSpec& mat = scene.material;

  if (scene.cloth && !scene.cloth->sewn)
    throw SceneError(fmt::format("{}: sewing: the cloth is not sewn yet (solver/sewing.h, Sew)", scene.source));
  if (scene.cloth) {
    CurvilinearCloth(scene);
  } else {
    // Rest positions and lumped masses (docs/model.md §1). "area" halves border masses.
    rest_.resize(n_, 3);
    mass_.resize(n_);
    for (int j = 0; j < nv; ++j)
      for (int i = 0; i < nu; ++i) {
        const int p = scene.Index(i, j);
        rest_.row(p) = (scene.grid.origin + i * lu * scene.grid.u_axis + j * lv * scene.grid.v_axis).transpose();
        double w = 1.0;
        if (mat.mass_lumping == MassLumping::kArea) {
          if (i == 0 || i == nu - 1) w *= 0.5;
          if (j == 0 || j == nv - 1) w *= 0.5;
        }
        mass_(p) = mat.density * lu * lv * w;
      }

    // Springs on u- and v-edges (docs/model.md §2.1, (2.20)).
    for (int j = 0; j < nv; ++j)
      for (int i = 0; i < nu; ++i) {
        const int p = scene.Index(i, j);
        if (i + 1 < nu)
          springs_.push_back({p, scene.Index(i + 1, j), mat.tension[0] * lv / lu, lu, mat.tension_damping * lv / lu});
        if (j + 1 < nv)
          springs_.push_back({p, scene.Index(i, j + 1), mat.tension[1] * lu / lv, lv, mat.tension_damping * lu / lv});
      }
  }

  // L_K, L_D (3.19): weighted graph Laplacians, one N×N matrix each.
  auto laplacian = [&](auto weight) {
    std::vector<Triplet> t;
    t.reserve(springs_.size() * 4);
    for (const Spring& s : springs_) {
      const double w = weight(s);
      if (w == 0.0) continue;
      t.emplace_back(s.a, s.a, w);
      t.emplace_back(s.b, s.b, w);
      t.emplace_back(s.a, s.b, -w);
      t.emplace_back(s.b, s.a, -w);
    }
    SparseMatrix l(n_, n_);
    l.setFromTriplets(t.begin(), t.end());
    l.makeCompressed();
    return l;
  };
  lk_ = laplacian([](const Spring& s) { return s.stiffness; });
  ld_ = laplacian([](const Spring& s) { return s.damping; });

  for (std::size_t k = 0; k < scene.obstacles.size(); ++k) {
    try {
      obstacles_.emplace_back(scene.obstacles[k]);
    } catch (const std::runtime_error& e) {  // an unreadable, empty or misplaced mesh
      throw SceneError(fmt::format("{}: obstacle[{}].{}: {}", scene.source, k, scene.obstacles[k].shape->file_key(),
                                   e.what()));
    }
    // A cloth that starts inside a solid obstacle is refused before
    // computing: meshes here, when they load; analytic obstacles again (a
    // scene built in code has not been through ParseScene).
    if (const std::string why = StartsInside(obstacles_.back(), rest_); !why.empty())
      throw SceneError(fmt::format("{}: obstacle[{}] {}", scene.source, k, why));
  }
  for (const FixedMotionSpec& m : scene.motions) {
    Vector3 anchor = Vector3::Zero();
    if (m.anchor) {
      anchor = *m.anchor;
    } else {
      for (int p : m.particles) anchor += rest_.row(p).transpose();
      anchor /= static_cast<double>(std::max<std::size_t>(1, m.particles.size()));
    }
    prescribed_.push_back({m.particles, KeyframedMotion(m.keyframes, anchor)});
  }
  fixed_ = scene.fixed;
  fixed_mask_.assign(static_cast<std::size_t>(n_), 0);
  for (int p : fixed_) fixed_mask_[static_cast<std::size_t>(p)] = 1;

  // Explicit terms: only those with non-zero coefficients (docs/model.md §2.6).
  geo_ = GridGeometry{nu, nv, lu, lv, mass_ / mat.density, scene.cloth};
  const GridGeometry& geo = geo_;
  if ((mat.tension[0] != 0.0 || mat.tension[1] != 0.0) && mat.tension_model == TensionModel::kSplit) {
    std::vector<Spring> stiff;
    for (const Spring& s : springs_)
      if (s.stiffness != 0.0) stiff.push_back(s);
    terms_.push_back(MakeTensionNonlinear(std::move(stiff), n_));
  }
  if (mat.shear != 0.0 || mat.shear_damping != 0.0) terms_.push_back(MakeShear(geo, mat.shear, mat.shear_damping));
  const bool bend = mat.bend[0] != 0.0 || mat.bend[1] != 0.0 || mat.bend_damping != 0.0;
  if (bend && mat.bend_model == BendModel::kMembrane)
    terms_.push_back(MakeMembraneBend(geo, mat.bend[0], mat.bend[1], mat.bend_damping));
  if (bend && mat.bend_model == BendModel::kThinPlate)
    terms_.push_back(MakeThinPlateBend(geo, mat.bend[0], mat.bend[1], mat.bend_damping));
  if (mat.transverse != 0.0) terms_.push_back(MakeTransverse(geo, mat.transverse));
  if (scene.forces.gravity.squaredNorm() > 0.0) terms_.push_back(MakeGravity(mass_, scene.forces.gravity));
  if (scene.forces.wind && scene.forces.wind->direction.squaredNorm() > 0.0 &&
      (scene.forces.wind->drag != 0.0 || scene.forces.wind->lift != 0.0)) {
    terms_.push_back(MakeWind(geo, *scene.forces.wind));
    external_terms_.push_back(terms_.back().get());
  }
  if (scene.forces.air != 0.0) {
    terms_.push_back(MakeAirResistance(geo, scene.forces.air));
    external_terms_.push_back(terms_.back().get());
  }
  // Virtual particles (thesis §5.2–5.4), last: a scene without them keeps
  // its terms and their order.
  if (std::any_of(scene.obstacles.begin(), scene.obstacles.end(),
                  [](const ObstacleSpec& o) { return o.virtual_particles; })) {
    auto term = std::make_unique<VirtualSprings>(nu, nv, springs_, mat.tension_model == TensionModel::kSplit);
    virtual_ = term.get();
    terms_.push_back(std::move(term));
  }
}

// A cloth of patterns (docs/model.md §2.7–2.8): the start is the placed,
// sewn patterns (ClothLayout::start); each particle has the cell area A of
// its stencil centre (CentreRestAt); a spring's rest length is its edge's in
// its pattern's plane, l_e, and its stiffness s_e = k A_e / l_e² with
// A_e = ½ (A_a + A_b): the tension energy ½ k ε² per area. A seam's edges are
// in both its patterns; each is one spring, its first pattern's. "uniform"
// lumping gives m_p = ρ A_p; "area" ρ times a quarter of each adjacent
// quad's rest area, in every pattern the particle is in.
void ParticleSystem::CurvilinearCloth(const Scene& scene) {
  const ClothLayout& cloth = *scene.cloth;
  const MaterialSpec& mat = scene.material;
  rest_ = cloth.start;
  Eigen::VectorXd cell = Eigen::VectorXd::Zero(n_);
  ForEachCentre(cloth, [&](const ClothBlock& b, int i, int j, int p) { cell(p) = CentreRestAt(b, i, j).area; });
  if (mat.mass_lumping == MassLumping::kArea) {
    mass_.setZero(n_);
    for (const ClothBlock& b : cloth.blocks)
      for (int j = 0; j + 1 < b.nv; ++j)
        for (int i = 0; i + 1 < b.nu; ++i) {
          const std::array<int, 4> q = {i + b.nu * j, i + 1 + b.nu * j, i + 1 + b.nu * (j + 1), i + b.nu * (j + 1)};
          const Eigen::Vector2d d1 = b.plane.row(q[2]) - b.plane.row(q[0]), d2 = b.plane.row(q[3]) - b.plane.row(q[1]);
          const double quarter = 0.125 * std::abs(d1.x() * d2.y() - d1.y() * d2.x());  // ¼ of ½ |d1 × d2|
          for (int k : q) mass_(b.At(k % b.nu, k / b.nu)) += quarter;
        }
    mass_ *= mat.density;
  } else {
    mass_ = mat.density * cell;
  }
  std::set<std::pair<int, int>> edges;
  for (const ClothBlock& b : cloth.blocks)
    for (int j = 0; j < b.nv; ++j)
      for (int i = 0; i < b.nu; ++i)
        for (int dir = 0; dir < 2; ++dir) {
          if (dir == 0 ? i + 1 >= b.nu : j + 1 >= b.nv) continue;
          const int ei = i + (dir == 0), ej = j + (dir == 1);
          const int p = b.At(i, j), q = b.At(ei, ej);
          if (p == q || !edges.insert({std::min(p, q), std::max(p, q)}).second) continue;  // a seam's edge: once
          const double l = (b.plane.row(ei + b.nu * ej) - b.plane.row(i + b.nu * j)).norm(), a = 0.5 * (cell(p) + cell(q));
          springs_.push_back({p, q, mat.tension[static_cast<std::size_t>(dir)] * a / (l * l), l,
                              mat.tension_damping * a / (l * l)});
        }
}

void ParticleSystem::AddExternalForces(double t, const MatrixN3& x, const MatrixN3& v, MatrixN3* f) const {
  for (const ForceTerm* term : external_terms_) term->AddForce(t, x, v, f);
}

EnergyBreakdown ParticleSystem::Energies(const MatrixN3& x, const MatrixN3& v) const {
  EnergyBreakdown e;
  const MaterialSpec& mat = scene_.material;
  // Lazy expressions only: no temporaries (the blow-up guard evaluates
  // this inside the step loop).
  const Vector3& g = scene_.forces.gravity;
  e.kinetic = 0.5 * v.rowwise().squaredNorm().cwiseProduct(mass_).sum();
  e.momentum = v.transpose() * mass_;
  e.gravity = -(x.col(0) * g.x() + x.col(1) * g.y() + x.col(2) * g.z()).cwiseProduct(mass_).sum();
  // Each spring's and each particle's term is computed in parallel into a
  // buffer of this thread (sized at the first call, before any step loop),
  // then summed in the serial order: the sums are those of one thread,
  // bit for bit, for any thread count.
  thread_local std::vector<double> spring_terms, shear_terms, bend_terms;
  const bool linear = mat.tension_model == TensionModel::kLinear;
  const auto n_springs = static_cast<std::ptrdiff_t>(springs_.size());
  spring_terms.resize(springs_.size());
  double* st = spring_terms.data();
#pragma omp parallel for schedule(static) if (n_springs >= kParallelMinimum)
  for (std::ptrdiff_t k = 0; k < n_springs; ++k) {
    const Spring& s = springs_[static_cast<std::size_t>(k)];
    const double len = (x.row(s.b) - x.row(s.a)).norm();
    const double stretch = linear ? len : len - s.rest_length;
    st[k] = 0.5 * s.stiffness * stretch * stretch;
  }
  for (std::ptrdiff_t k = 0; k < n_springs; ++k) e.tension += st[k];
  const int nu = scene_.grid.nu, nv = scene_.grid.nv;
  const double lu = scene_.lu(), lv = scene_.lv();
  const bool shear = mat.shear != 0.0;
  const bool bend = mat.bend_model != BendModel::kNone && (mat.bend[0] != 0.0 || mat.bend[1] != 0.0);
  if (!shear && !bend) return e;
  if (scene_.cloth) {
    CurvilinearEnergies(geo_, shear ? mat.shear : 0.0, bend ? mat.bend[0] : 0.0, bend ? mat.bend[1] : 0.0, x, &e.shear,
                        &e.bending);
    return e;
  }
  const std::ptrdiff_t n_grid = static_cast<std::ptrdiff_t>(nu) * nv;
  shear_terms.resize(static_cast<std::size_t>(n_grid));
  bend_terms.resize(static_cast<std::size_t>(n_grid));
  double* sh = shear_terms.data();
  double* be = bend_terms.data();
#pragma omp parallel for schedule(static) if (n_grid >= kParallelMinimum / 2)
  for (std::ptrdiff_t k = 0; k < n_grid; ++k) {
    const int j = static_cast<int>(k / nu), i = static_cast<int>(k % nu);
    auto at = [&](int a, int b) { return Vector3(x.row(scene_.Index(a, b)).transpose()); };
    if (shear) {
      // Shear strain γ with one-sided differences on the border (docs/model.md §2.2).
      const int r = std::min(i + 1, nu - 1), l = std::max(i - 1, 0), u = std::min(j + 1, nv - 1), d = std::max(j - 1, 0);
      const Vector3 a = (at(r, j) - at(l, j)) / ((r - l) * lu), b = (at(i, u) - at(i, d)) / ((u - d) * lv);
      const double gamma = a.dot(b);
      sh[k] = 0.5 * mat.shear * gamma * gamma * lu * lv;
    }
    if (bend) {
      // Vertex normal: mean of the unit normals of the adjacent quads.
      Vector3 n = Vector3::Zero();
      for (int s : {1, -1})
        for (int t : {1, -1}) {
          if (i + s < 0 || i + s >= nu || j + t < 0 || j + t >= nv) continue;
          const Vector3 nf = (at(i + s, j + t) - at(i, j)).cross(at(i, j + t) - at(i + s, j)) * (s * t);
          n += nf.normalized();
        }
      n.normalize();
      const double kuu = (i > 0 && i < nu - 1) ? (at(i + 1, j) - 2 * at(i, j) + at(i - 1, j)).dot(n) / (lu * lu) : 0.0;
      const double kvv = (j > 0 && j < nv - 1) ? (at(i, j + 1) - 2 * at(i, j) + at(i, j - 1)).dot(n) / (lv * lv) : 0.0;
      be[k] = 0.5 * lu * lv * (mat.bend[0] * kuu * kuu + mat.bend[1] * kvv * kvv);
    }
  }
  for (std::ptrdiff_t k = 0; k < n_grid; ++k) {
    if (shear) e.shear += sh[k];
    if (bend) e.bending += be[k];
  }
  return e;
}

std::vector<std::string> ParticleSystem::TermNames() const {
  std::vector<std::string> names;
  for (const auto& t : terms_) names.emplace_back(t->name());
  return names;
}

void ParticleSystem::ExplicitForces(double t, const MatrixN3& x, const MatrixN3& v, MatrixN3* g) const {
  // The sum starts from a constant term (gravity) if there is one, one pass
  // instead of a zeroing and an addition; the other terms follow in order.
  const ForceTerm* start = nullptr;
  for (const auto& term : terms_)
    if (term->constant_force()) {
      start = term.get();
      break;
    }
  if (start) *g = *start->constant_force();
  else g->setZero();
  for (const auto& term : terms_)
    if (term.get() != start) term->AddForce(t, x, v, g);
}

void ParticleSystem::Forces(double t, const MatrixN3& x, const MatrixN3& v, MatrixN3* f) const {
  ExplicitForces(t, x, v, f);
  f->noalias() -= lk_ * x;
  if (has_tension_damping()) f->noalias() -= ld_ * v;
}

void ParticleSystem::ForceJacobian(double t, const MatrixN3& x, const MatrixN3& v, std::vector<Triplet>* dfdx,
                                   std::vector<Triplet>* dfdv) const {
  // Linear part: −L_K ⊗ I₃ and −L_D ⊗ I₃ (3.19).
  auto add_kron = [](const SparseMatrix& l, std::vector<Triplet>* out) {
    for (int col = 0; col < l.outerSize(); ++col)
      for (SparseMatrix::InnerIterator it(l, col); it; ++it)
        for (int c = 0; c < 3; ++c) out->emplace_back(3 * it.row() + c, 3 * it.col() + c, -it.value());
  };
  add_kron(lk_, dfdx);
  add_kron(ld_, dfdv);
  for (const auto& term : terms_) term->AddJacobian(t, x, v, dfdx, dfdv);
}

void ParticleSystem::PrepareParticleForces() const {
  for (const auto& term : terms_) term->PrepareParticleForces(n_);
}

void ParticleSystem::ParticleForce(double t, const MatrixN3& x, const MatrixN3& v, int p, Vector3* f, Matrix3* dfdx,
                                   Matrix3* dfdv) const {
  // Row p of −L_K x − L_D v: L_K and L_D are symmetric, so column p.
  f->setZero();
  double kpp = 0.0, dpp = 0.0;
  for (SparseMatrix::InnerIterator it(lk_, p); it; ++it) {
    *f -= it.value() * x.row(it.row()).transpose();
    if (it.row() == p) kpp = it.value();
  }
  if (ld_.nonZeros() > 0)
    for (SparseMatrix::InnerIterator it(ld_, p); it; ++it) {
      *f -= it.value() * v.row(it.row()).transpose();
      if (it.row() == p) dpp = it.value();
    }
  *dfdx = -kpp * Matrix3::Identity();
  *dfdv = -dpp * Matrix3::Identity();
  for (const auto& term : terms_) term->AddParticleForce(t, x, v, p, f, dfdx, dfdv);
}

void ParticleSystem::ParticleGraph(std::vector<int>* offsets, std::vector<int>* neighbours) const {
  // Both directions of every off-diagonal block, one term at a time (a
  // term's block list is the largest transient: 16 pairs per particle for
  // shear), then sorted and made unique per particle.
  std::vector<std::array<int, 2>> pairs;
  for (int col = 0; col < lk_.outerSize(); ++col)
    for (SparseMatrix::InnerIterator it(lk_, col); it; ++it)
      if (it.row() != col) pairs.push_back({static_cast<int>(it.row()), col});
  std::vector<BlockPair> blocks;
  for (const auto& term : terms_) {
    blocks.clear();
    term->JacobianBlocks(&blocks);
    for (const BlockPair& b : blocks)
      if (b[0] != b[1]) {
        pairs.push_back({b[0], b[1]});
        pairs.push_back({b[1], b[0]});
      }
    std::sort(pairs.begin(), pairs.end());
    pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  }
  offsets->assign(static_cast<std::size_t>(n_) + 1, 0);
  for (const auto& pq : pairs) ++(*offsets)[static_cast<std::size_t>(pq[0]) + 1];
  for (std::size_t p = 0; p < static_cast<std::size_t>(n_); ++p) (*offsets)[p + 1] += (*offsets)[p];
  neighbours->resize(pairs.size());
  for (std::size_t k = 0; k < pairs.size(); ++k) (*neighbours)[k] = pairs[k][1];  // sorted by (p, q)
}

}  // namespace clothbench
