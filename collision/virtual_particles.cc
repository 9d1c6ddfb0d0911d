// Virtual particles (thesis §5.2–5.4; collision/virtual_particles.h): the
// projection of the obstacles' edges onto the cloth and the refined mesh.
#include "collision/virtual_particles.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <optional>
#include <unordered_map>

#include "collision/face_triangulation.h"
#include "collision/shapes/triangle_mesh.h"

namespace clothbench {

// An obstacle whose edges are projected: its edges in the placed frame and
// the closed surface on the same vertices, for the ray check (Fig. 5.9).
struct VirtualParticles::Source {
  int index = 0;
  const Obstacle* obstacle = nullptr;
  std::vector<Vector3> placed;            // vertices, placed frame [m]
  std::vector<Vector3> world;             // at the last update's pose
  std::vector<std::array<int, 2>> edges;
  std::unique_ptr<TriangleMesh> surface;  // analytic obstacles; a mesh obstacle casts against its own
  // A uniform grid of the edges' boxes at the last pose (rebuilt when the
  // pose moves): cell key → edges, and a per-edge stamp that visits each
  // edge once per query.
  std::unordered_map<std::uint64_t, std::vector<int>> cells;
  std::vector<int> wide;                   // edges over too many cells: in every query
  std::vector<std::uint64_t> stamp;
  std::uint64_t query = 0;
  ObstaclePose built_pose;
  bool built = false;
  int side = 0;                           // σ: the cloth's side away from the obstacle (0: not yet voted)
};

VirtualParticles* VirtualParticles::Of(const ParticleSystem& system) {
  VirtualSprings* springs = system.virtual_springs();
  if (!springs) return nullptr;
  if (!springs->detection()) {
    double cell = 0.0;
    for (const Spring& s : system.springs()) cell = std::max(cell, 2.0 * s.rest_length);  // about a face's query box
    springs->Attach(std::make_unique<VirtualParticles>(system.scene().grid.nu, system.scene().grid.nv, springs,
                                                       system.obstacles(), cell));
  }
  return static_cast<VirtualParticles*>(springs->detection());
}

VirtualParticles::VirtualParticles(int grid_nu, int grid_nv, VirtualSprings* springs,
                                   const std::vector<Obstacle>& obstacles, double cell)
    : nu_(grid_nu), nv_(grid_nv), cell_(cell), springs_(springs), cloth_(GridTriangles(grid_nu, grid_nv)) {
  for (std::size_t k = 0; k < obstacles.size(); ++k) {
    const Obstacle& o = obstacles[k];
    if (!o.spec().virtual_particles) continue;
    auto src = std::make_unique<Source>();
    src->index = static_cast<int>(k);
    src->obstacle = &o;
    o.Edges(ObstaclePose{}, &src->placed, &src->edges);
    if (!o.mesh()) {
      std::vector<Vector3> vertices;
      std::vector<std::array<int, 3>> triangles;
      o.Surface(&vertices, &triangles);
      src->surface = std::make_unique<TriangleMesh>(vertices, triangles);
    }
    sources_.push_back(std::move(src));
  }
}

VirtualParticles::~VirtualParticles() = default;

void VirtualParticles::Clear() {
  for (const auto& src : sources_) src->side = 0;
  current_ = false;
  projection_seconds_ = springs_seconds_ = triangulation_seconds_ = 0.0;
  updates_ = triangulations_ = 0;
  ClearTopology();
}

void VirtualParticles::ClearTopology() {
  springs_->ClearTopology();
  segments_.clear();
}

namespace {

// An edge over more cells than this is kept out of the grid and offered
// to every query (a long edge against a fine cloth).
constexpr double kMaxEdgeCells = 4096;

std::uint64_t CellKey(long i, long j, long k) {
  const auto part = [](long v) { return static_cast<std::uint64_t>(v + (1L << 20)) & ((1ULL << 21) - 1); };
  return part(i) | (part(j) << 21) | (part(k) << 42);
}

// Calls f(key) for every grid cell (side `cell` [m]) that `box` meets;
// false, without a call, if they are more than kMaxEdgeCells or the box is
// not finite (a long edge against a fine cloth, a blown-up face).
template <class F>
bool ForEachCell(const Eigen::AlignedBox3d& box, double cell, F f) {
  const Eigen::Array3d lo = (box.min().array() / cell).floor(), hi = (box.max().array() / cell).floor();
  if (!lo.allFinite() || !hi.allFinite() || (hi - lo + 1.0).prod() > kMaxEdgeCells) return false;
  for (long i = static_cast<long>(lo.x()); i <= static_cast<long>(hi.x()); ++i)
    for (long j = static_cast<long>(lo.y()); j <= static_cast<long>(hi.y()); ++j)
      for (long k = static_cast<long>(lo.z()); k <= static_cast<long>(hi.z()); ++k) f(CellKey(i, j, k));
  return true;
}

}  // namespace

// §5.3: every standing projection of one obstacle's edges at time t onto
// the cloth at positions x.
void VirtualParticles::ProjectSource(Source* src, double t, const MatrixN3& x) {
  const Obstacle& o = *src->obstacle;
  const ObstaclePose pose = o.PoseAt(t);
  src->world.resize(src->placed.size());
  for (std::size_t k = 0; k < src->placed.size(); ++k) src->world[k] = pose.ToWorld(src->placed[k]);
  IndexEdges(src, pose);
  // Whether any edge lies in the cells a box meets (a face without one
  // neither votes nor projects).
  const auto near_edges = [&](const Eigen::AlignedBox3d& box) {
    bool near = !src->wide.empty();
    if (!ForEachCell(box, cell_, [&](std::uint64_t key) { near = near || src->cells.count(key) > 0; })) near = true;
    return near;
  };
  // The faces' orientation, away from the obstacle: one side of the
  // sheet for all its faces, n = σ (P2 − P1) × (P3 − P1) in the grid's
  // order (counter-clockwise about u × v). σ is voted by the faces whose
  // centroid is outside and whose normal is within 60° of the direction
  // D from the obstacle, weighted by |⟨n, D⟩|, among the faces with
  // obstacle edges in reach; it changes only on a clear majority. A
  // single face's D is no guide: beside a box's side, below its top edge, D is horizontal and ⟨n, D⟩ only round-off, and
  // neighbours oriented apart make the bisecting plane S_i the face's
  // own plane.
  double vote = 0.0, weight = 0.0;
  Eigen::AlignedBox3d reach;
  for (const Vector3& w : src->world) reach.extend(w);
  for (const auto& tri : cloth_.vertices) {
    const Vector3 a = x.row(tri[0]).transpose(), b = x.row(tri[1]).transpose(), c = x.row(tri[2]).transpose();
    Eigen::AlignedBox3d box(a);
    box.extend(b).extend(c);
    const double grow = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
    box.min().array() -= grow;
    box.max().array() += grow;
    if (!box.intersects(reach) || !near_edges(box)) continue;
    Vector3 d;
    if (o.SignedDistance(pose, (a + b + c) / 3.0, &d) <= 0.0) continue;
    const double cosine = (b - a).cross(c - a).normalized().dot(d);
    if (std::abs(cosine) < 0.5) continue;
    vote += cosine;
    weight += std::abs(cosine);
  }
  if (src->side == 0 || vote * src->side < -0.5 * weight) src->side = vote < 0.0 ? -1 : 1;
  const double side = src->side;
  const auto outward = [&](std::size_t f, const Vector3&) {
    const auto& tri = cloth_.vertices[f];
    return Vector3(side * (x.row(tri[1]) - x.row(tri[0])).cross(x.row(tri[2]) - x.row(tri[0])).transpose());
  };
  // Fig. 5.9: a ray crosses another face of the obstacle if it runs
  // through the solid after its first hit. A ray that only grazes a face
  // (a vertical ray from below a box's top edge runs along its side)
  // touches the surface without entering: points after the hit are
  // tested against the polyhedron's signed distance (7 of them, so that
  // a ray through a thin part of a mesh is seen too).
  const TriangleMesh& surface = src->surface ? *src->surface : *o.mesh();
  const auto first_hit = [&](const Vector3& a, const Vector3& b) -> std::optional<double> {
    const Vector3 pa = pose.ToPlaced(a), pb = pose.ToPlaced(b);
    const std::optional<SegmentHit> hit = surface.FirstHit(pa, pb);
    if (!hit || hit->s >= 1.0 - 1e-9) return std::nullopt;  // none, or the edge itself
    const double tol = 1e-9 + 1e-6 * (pb - pa).norm();
    Vector3 dir;
    for (int k = 1; k < 8; ++k) {
      const double s = hit->s + (1.0 - hit->s) * k / 8.0;
      if (surface.SignedDistance(pa + s * (pb - pa), &dir) < -tol) return hit->s;
    }
    return std::nullopt;
  };
  const auto candidates = [&](const Eigen::AlignedBox3d& box, const auto& visit) {
    const std::uint64_t q = ++src->query;
    const auto offer = [&](int e) {
      std::uint64_t& mark = src->stamp[static_cast<std::size_t>(e)];
      if (mark == q) return;
      mark = q;
      visit(static_cast<std::size_t>(e));
    };
    for (int e : src->wide) offer(e);
    const bool listed = ForEachCell(box, cell_, [&](std::uint64_t key) {
      if (const auto it = src->cells.find(key); it != src->cells.end())
        for (int e : it->second) offer(e);
    });
    if (!listed)  // a blown-up face
      for (std::size_t e = 0; e < src->edges.size(); ++e) offer(static_cast<int>(e));
  };
  ProjectObstacleEdges(x, cloth_, src->world, src->edges, outward, first_hit, candidates, &normal_, &hits_);
  AddVirtualParticles(src, pose, x);
}

// The edges of `src` by grid cell at `pose`, for the faces' queries
// (§5.3's acceleration): rebuilt only when the obstacle moved.
void VirtualParticles::IndexEdges(Source* src, const ObstaclePose& pose) {
  const bool moved = !src->built || pose.rotation != src->built_pose.rotation ||
                     pose.translation != src->built_pose.translation;
  if (moved) {
    src->cells.clear();
    src->wide.clear();
    src->stamp.assign(src->edges.size(), 0);
    for (std::size_t e = 0; e < src->edges.size(); ++e) {
      Eigen::AlignedBox3d b(src->world[static_cast<std::size_t>(src->edges[e][0])]);
      b.extend(src->world[static_cast<std::size_t>(src->edges[e][1])]);
      if (!ForEachCell(b, cell_, [&](std::uint64_t key) { src->cells[key].push_back(static_cast<int>(e)); }))
        src->wide.push_back(static_cast<int>(e));
    }
    src->built = true;
    src->built_pose = pose;
  }
}

// The virtual particles of the faces' hits of one obstacle's edges
// (hits_, §5.3), each end with its cloth edge or face, and the segments.
void VirtualParticles::AddVirtualParticles(const Source* src, const ObstaclePose& pose, const MatrixN3& x) {
  for (const FaceEdgeHit& h : hits_) {
    const EdgeProjection& pr = h.projection;
    segments_.push_back({h.face, {}});
    for (int end = 0; end < 2; ++end) {
      const int on = end == 0 ? pr.v_edge : pr.w_edge;
      VirtualParticle vp;
      vp.x = end == 0 ? pr.v : pr.w;
      vp.v = pose.Velocity(vp.x);
      vp.obstacle = src->index;
      vp.edge = h.edge;
      vp.face = h.face;
      if (on >= 0) {
        int a = h.vertices[static_cast<std::size_t>(on)], b = h.vertices[static_cast<std::size_t>((on + 1) % 3)];
        if (a > b) std::swap(a, b);
        vp.a = a;
        vp.b = b;
        const Vector3 xa = x.row(a).transpose(), ab = x.row(b).transpose() - xa;
        const Vector3 bar = end == 0 ? pr.v_bar : pr.w_bar;
        vp.s = std::clamp((bar - xa).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
        vp.bar = xa + vp.s * ab;
      } else {
        vp.bar = end == 0 ? pr.v_bar : pr.w_bar;
      }
      springs_->points().push_back(vp);
      segments_.back().ends[static_cast<std::size_t>(end)] = vp;
    }
  }
}

void VirtualParticles::Update(double t, const MatrixN3& x) {
  // The same state again (a frame at a step's end, then the next step; a
  // step retried after a rejection): the topology stands.
  if (current_ && t == t_update_ && x == x_update_) return;
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  ClearTopology();
  t_update_ = t;
  x_update_ = x;
  current_ = true;
  // §5.3: every standing projection of every obstacle's edges.
  for (const auto& src : sources_) ProjectSource(src.get(), t, x);
  const auto projected = Clock::now();
  springs_->SplitSprings(t, x);
  const auto done = Clock::now();
  projection_seconds_ += std::chrono::duration<double>(projected - start).count();
  springs_seconds_ += std::chrono::duration<double>(done - projected).count();
  ++updates_;
}

void VirtualParticles::RefinedMesh(const MatrixN3& x, std::vector<std::array<int, 3>>* triangles) {
  std::vector<VirtualParticle>& particles = springs_->points();  // crossings are appended (no force)
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  const int n = nu_ * nv_;
  const std::size_t nf = cloth_.vertices.size();
  face_points_.resize(nf);
  for (std::vector<int>& points : face_points_) points.clear();
  for (std::size_t k = 0; k < particles.size(); ++k) {
    const VirtualParticle& p = particles[k];
    face_points_[static_cast<std::size_t>(p.face)].push_back(static_cast<int>(k));
    if (p.a < 0) continue;
    // A point on a cloth edge belongs to the triangle across it too.
    const auto& t = cloth_.vertices[static_cast<std::size_t>(p.face)];
    for (std::size_t e = 0; e < 3; ++e)
      if (std::min(t[e], t[(e + 1) % 3]) == p.a && std::max(t[e], t[(e + 1) % 3]) == p.b) {
        if (const int across = cloth_.across[static_cast<std::size_t>(p.face)][e]; across >= 0)
          face_points_[static_cast<std::size_t>(across)].push_back(static_cast<int>(k));
      }
  }
  triangles->clear();
  std::vector<Eigen::Vector2d> points;
  std::vector<std::array<int, 2>> constraints;
  std::vector<std::array<int, 3>> local;
  for (std::size_t f = 0; f < nf; ++f) {
    const auto& t = cloth_.vertices[f];
    const std::vector<int>& extra = face_points_[f];
    if (extra.empty()) {
      triangles->push_back(t);
      continue;
    }
    // The face's plane: origin P1, axes e1 along P1P2 and e2 = n × e1.
    const Vector3 o = x.row(t[0]).transpose();
    const Vector3 e1 = (x.row(t[1]).transpose() - o).normalized();
    const Vector3 nrm = e1.cross(x.row(t[2]).transpose() - o).normalized();
    const Vector3 e2 = nrm.cross(e1);
    const auto flat = [&](const Vector3& p) { return Eigen::Vector2d((p - o).dot(e1), (p - o).dot(e2)); };
    points.clear();
    for (int k = 0; k < 3; ++k) points.push_back(flat(x.row(t[static_cast<std::size_t>(k)]).transpose()));
    for (int k : extra) points.push_back(flat(particles[static_cast<std::size_t>(k)].bar));
    // The boundary, corner to corner through the points on each edge.
    constraints.clear();
    for (std::size_t e = 0; e < 3; ++e) {
      const int from = t[e], to = t[(e + 1) % 3];
      on_edge_.clear();
      for (std::size_t k = 0; k < extra.size(); ++k) {
        const VirtualParticle& p = particles[static_cast<std::size_t>(extra[k])];
        if (p.a == std::min(from, to) && p.b == std::max(from, to))
          on_edge_.emplace_back(p.a == from ? p.s : 1.0 - p.s, static_cast<int>(k) + 3);
      }
      std::sort(on_edge_.begin(), on_edge_.end());
      int last = static_cast<int>(e);
      for (const auto& [u, i] : on_edge_) {
        constraints.push_back({last, i});
        last = i;
      }
      constraints.push_back({last, static_cast<int>((e + 1) % 3)});
    }
    for (const Segment& seg : segments_) {
      if (seg.face != static_cast<int>(f)) continue;
      std::array<int, 2> ends{};
      bool found = true;
      for (std::size_t e = 0; e < 2; ++e) {
        const int k = springs_->Find(seg.ends[e]);
        const auto at = std::find(extra.begin(), extra.end(), k);
        found = found && k >= 0 && at != extra.end();
        ends[e] = found ? 3 + static_cast<int>(at - extra.begin()) : 0;
      }
      if (found) constraints.push_back(ends);
    }
    const std::size_t before = points.size();
    TriangulateFace(&points, constraints, &local);
    for (std::size_t k = before; k < points.size(); ++k) {  // crossings of two projected edges
      VirtualParticle c;
      c.face = static_cast<int>(f);
      c.obstacle = c.edge = -1;
      c.x = c.bar = o + points[k].x() * e1 + points[k].y() * e2;
      face_points_[f].push_back(static_cast<int>(particles.size()));
      particles.push_back(c);
    }
    const auto global = [&](int i) {
      return i < 3 ? t[static_cast<std::size_t>(i)] : n + face_points_[f][static_cast<std::size_t>(i - 3)];
    };
    for (const auto& tri : local) triangles->push_back({global(tri[0]), global(tri[1]), global(tri[2])});
  }
  triangulation_seconds_ += std::chrono::duration<double>(Clock::now() - start).count();
  ++triangulations_;
}

void VirtualParticles::RecordFrame(const MatrixN3& x, VirtualFrames* frames) {
  RefinedMesh(x, &record_faces_);
  if (frames->offsets.empty()) frames->offsets.push_back(0);
  if (frames->face_offsets.empty()) frames->face_offsets.push_back(0);
  const std::vector<VirtualParticle>& particles = springs_->particles();
  for (const VirtualParticle& p : particles) {
    frames->x.insert(frames->x.end(), {p.x.x(), p.x.y(), p.x.z()});
    frames->cloth_edge.insert(frames->cloth_edge.end(), {p.a, p.b});
    frames->obstacle_edge.insert(frames->obstacle_edge.end(), {p.obstacle, p.edge});  // −1, −1 for a crossing
  }
  for (const auto& f : record_faces_) frames->faces.insert(frames->faces.end(), f.begin(), f.end());
  frames->tension_energy.push_back(springs_->TensionEnergyChange(x));
  frames->offsets.push_back(frames->offsets.back() + static_cast<int32_t>(particles.size()));
  frames->face_offsets.push_back(frames->face_offsets.back() + static_cast<int32_t>(record_faces_.size()));
}

}  // namespace clothbench
