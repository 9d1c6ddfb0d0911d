// The cloth of patterns and seams (docs/model.md §2.8).
#include "model/cloth_layout.h"

#include <algorithm>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <utility>

#include <fmt/format.h>

namespace clothbench {
namespace {

// The samples along side s of an nu × nv pattern.
int SideLength(int nu, int nv, int s) { return s == PatternSpec::kV0 || s == PatternSpec::kV1 ? nu : nv; }
// The samples across side s (along the thread that crosses it).
int SideDepth(int nu, int nv, int s) { return s == PatternSpec::kV0 || s == PatternSpec::kV1 ? nv : nu; }

// The grid coordinates of the node at position t along side s (in the
// side's direction, PatternSpec) and depth d inward from it; d < 0 lies
// beyond the side.
std::array<int, 2> SideNode(int nu, int nv, int s, int t, int d) {
  switch (s) {
    case PatternSpec::kV0: return {t, d};
    case PatternSpec::kU1: return {nu - 1 - d, t};
    case PatternSpec::kV1: return {t, nv - 1 - d};
    default: return {d, t};  // kU0
  }
}

struct UnionFind {
  explicit UnionFind(int n) : parent(static_cast<std::size_t>(n)) { std::iota(parent.begin(), parent.end(), 0); }
  int Find(int a) {
    while (parent[static_cast<std::size_t>(a)] != a) a = parent[static_cast<std::size_t>(a)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(a)])];
    return a;
  }
  void Join(int a, int b) {  // the smaller index stays the representative
    a = Find(a);
    b = Find(b);
    if (a != b) parent[static_cast<std::size_t>(std::max(a, b))] = std::min(a, b);
  }
  std::vector<int> parent;
};

}  // namespace

std::vector<std::array<int, 2>> SeamPairs(const SeamSpec& seam, int la, int lb) {
  const int fa = seam.first_a, ea = seam.last_a < 0 ? la - 1 : seam.last_a;
  const int fb = seam.first_b, eb = seam.last_b < 0 ? lb - 1 : seam.last_b;
  std::vector<std::array<int, 2>> out;
  if (fa < 0 || ea >= la || fa >= ea || fb < 0 || eb >= lb || fb >= eb || ea - fa != eb - fb) return out;
  for (int k = 0; k <= ea - fa; ++k) out.push_back({fa + k, seam.reversed ? eb - k : fb + k});
  return out;
}

std::string SeamRule(const std::vector<PatternSpec>& patterns, const SeamSpec& seam) {
  const int n = static_cast<int>(patterns.size());
  if (seam.pattern_a < 0 || seam.pattern_a >= n) return "a: names no pattern";
  if (seam.pattern_b < 0 || seam.pattern_b >= n) return "b: names no pattern";
  if (seam.pattern_a == seam.pattern_b && seam.side_a == seam.side_b) return "b: is side a itself";
  const PatternSpec& a = patterns[static_cast<std::size_t>(seam.pattern_a)];
  const PatternSpec& b = patterns[static_cast<std::size_t>(seam.pattern_b)];
  const int la = SideLength(a.nu, a.nv, seam.side_a), lb = SideLength(b.nu, b.nv, seam.side_b);
  const int ea = seam.last_a < 0 ? la - 1 : seam.last_a, eb = seam.last_b < 0 ? lb - 1 : seam.last_b;
  if (seam.first_a < 0 || ea >= la || seam.first_a >= ea)
    return fmt::format("a_samples: [{}, {}] must be 2 samples first < last of \"{}\"'s 0 … {}", seam.first_a, ea, seam.a, la - 1);
  if (seam.first_b < 0 || eb >= lb || seam.first_b >= eb)
    return fmt::format("b_samples: [{}, {}] must be 2 samples first < last of \"{}\"'s 0 … {}", seam.first_b, eb, seam.b, lb - 1);
  if (ea - seam.first_a != eb - seam.first_b)
    return fmt::format("b: \"{}\" has {} samples and \"{}\" {}: a seam's sides must have the same number", seam.a,
                       ea - seam.first_a + 1, seam.b, eb - seam.first_b + 1);
  return "";
}

ClothLayout BuildClothLayout(const std::vector<PatternSpec>& patterns, const std::vector<SeamSpec>& seams,
                             const std::vector<Eigen::MatrixX2d>* samples) {
  ClothLayout out;
  std::vector<Eigen::MatrixX2d> plane;
  std::vector<MatrixN3> placed;
  int total = 0;
  if (samples && samples->size() != patterns.size())
    throw std::invalid_argument(fmt::format("BuildClothLayout: {} samplings for {} patterns", samples->size(), patterns.size()));
  for (const PatternSpec& p : patterns) {
    plane.push_back(samples ? (*samples)[plane.size()] : SamplePattern(p));
    if (plane.back().rows() != static_cast<Eigen::Index>(p.nu) * p.nv)
      throw std::invalid_argument(fmt::format("BuildClothLayout: {} samples for {} × {}", plane.back().rows(), p.nu, p.nv));
    placed.push_back(PlacePattern(p, plane.back()));
    out.first.push_back(total);
    total += p.nu * p.nv;
  }
  const auto unsewn = [&](int k, int i, int j) {
    return out.first[static_cast<std::size_t>(k)] + i + patterns[static_cast<std::size_t>(k)].nu * j;
  };
  // Merge each seam's pairs; a side's sample sews once.
  UnionFind classes(total);
  std::vector<std::array<int, 3>> sewn;  // (pattern, side, sample)
  for (const SeamSpec& s : seams) {
    if (const std::string rule = SeamRule(patterns, s); !rule.empty()) throw std::invalid_argument(rule);
    const PatternSpec& a = patterns[static_cast<std::size_t>(s.pattern_a)];
    const PatternSpec& b = patterns[static_cast<std::size_t>(s.pattern_b)];
    const auto pairs = SeamPairs(s, SideLength(a.nu, a.nv, s.side_a), SideLength(b.nu, b.nv, s.side_b));
    for (const auto& [ta, tb] : pairs)
      for (const std::array<int, 3>& at : {std::array<int, 3>{s.pattern_a, s.side_a, ta}, std::array<int, 3>{s.pattern_b, s.side_b, tb}}) {
        if (std::find(sewn.begin(), sewn.end(), at) != sewn.end())
          throw std::invalid_argument(fmt::format("b: sample {} of side {} of pattern \"{}\" is in an earlier seam already",
                                                  at[2], PatternSpec::kSideNames[static_cast<std::size_t>(at[1])],
                                                  patterns[static_cast<std::size_t>(at[0])].name));
        sewn.push_back(at);
      }
    for (const auto& [ta, tb] : pairs) {
      const auto na = SideNode(a.nu, a.nv, s.side_a, ta, 0);
      const auto nb = SideNode(b.nu, b.nv, s.side_b, tb, 0);
      const int pa = na[0] + a.nu * na[1], pb = nb[0] + b.nu * nb[1];
      out.largest_gap = std::max(out.largest_gap, (placed[static_cast<std::size_t>(s.pattern_a)].row(pa) -
                                                   placed[static_cast<std::size_t>(s.pattern_b)].row(pb)).norm());
      classes.Join(unsewn(s.pattern_a, na[0], na[1]), unsewn(s.pattern_b, nb[0], nb[1]));
    }
  }
  // Cloth particles in the order of their first unsewn particle; each at
  // the mean of its unsewn particles' placed positions.
  out.merged.assign(static_cast<std::size_t>(total), -1);
  for (int u = 0; u < total; ++u) {
    const int r = classes.Find(u);
    out.merged[static_cast<std::size_t>(u)] = r == u ? out.num_particles++ : out.merged[static_cast<std::size_t>(r)];
  }
  out.start = MatrixN3::Zero(out.num_particles, 3);
  Eigen::VectorXd count = Eigen::VectorXd::Zero(out.num_particles);
  for (std::size_t k = 0; k < patterns.size(); ++k)
    for (int q = 0; q < patterns[k].nu * patterns[k].nv; ++q) {
      const int c = out.merged[static_cast<std::size_t>(out.first[k] + q)];
      out.start.row(c) += placed[k].row(q);
      count(c) += 1.0;
    }
  out.start.array().colwise() /= count.array();
  // Blocks: nodes, then the cells beyond each seamed side.
  out.least_spacing = {std::numeric_limits<double>::max(), std::numeric_limits<double>::max()};
  for (std::size_t k = 0; k < patterns.size(); ++k) {
    const PatternSpec& p = patterns[k];
    ClothBlock b;
    b.nu = p.nu;
    b.nv = p.nv;
    b.plane = plane[k];
    const std::size_t cells = static_cast<std::size_t>(p.nu + 4) * static_cast<std::size_t>(p.nv + 4);
    b.particle.assign(cells, -1);
    b.rest.assign(cells, Eigen::Vector2d::Zero());
    b.owner.assign(static_cast<std::size_t>(p.nu * p.nv), 0);
    for (int j = 0; j < p.nv; ++j)
      for (int i = 0; i < p.nu; ++i) {
        const int u = unsewn(static_cast<int>(k), i, j);
        b.particle[static_cast<std::size_t>(b.Cell(i, j))] = out.merged[static_cast<std::size_t>(u)];
        b.rest[static_cast<std::size_t>(b.Cell(i, j))] = plane[k].row(i + p.nu * j).transpose();
        b.owner[static_cast<std::size_t>(i + p.nu * j)] = classes.Find(u) == u;
        if (i + 1 < p.nu) out.least_spacing[0] = std::min(out.least_spacing[0], (plane[k].row(i + 1 + p.nu * j) - plane[k].row(i + p.nu * j)).norm());
        if (j + 1 < p.nv) out.least_spacing[1] = std::min(out.least_spacing[1], (plane[k].row(i + p.nu * (j + 1)) - plane[k].row(i + p.nu * j)).norm());
        if (i + 1 < p.nu && j + 1 < p.nv)
          out.quads.push_back({out.merged[static_cast<std::size_t>(u)], out.merged[static_cast<std::size_t>(u + 1)],
                               out.merged[static_cast<std::size_t>(u + 1 + p.nu)], out.merged[static_cast<std::size_t>(u + p.nu)]});
      }
    out.blocks.push_back(std::move(b));
  }
  // Beyond each seamed side, both ways: the other side's nodes at depths 1
  // and 2, at rest on this pattern's crossing thread continued straight.
  for (const SeamSpec& s : seams)
    for (int dir = 0; dir < 2; ++dir) {
      const int ka = dir == 0 ? s.pattern_a : s.pattern_b, sa = dir == 0 ? s.side_a : s.side_b;
      const int kb = dir == 0 ? s.pattern_b : s.pattern_a, sb = dir == 0 ? s.side_b : s.side_a;
      ClothBlock& a = out.blocks[static_cast<std::size_t>(ka)];
      const ClothBlock& bb = out.blocks[static_cast<std::size_t>(kb)];
      const int depth = SideDepth(bb.nu, bb.nv, sb);
      const ClothBlock& pa = out.blocks[static_cast<std::size_t>(s.pattern_a)];
      const ClothBlock& pb = out.blocks[static_cast<std::size_t>(s.pattern_b)];
      for (auto [t, tb] : SeamPairs(s, SideLength(pa.nu, pa.nv, s.side_a), SideLength(pb.nu, pb.nv, s.side_b))) {
        if (dir == 1) std::swap(t, tb);
        const auto a0 = SideNode(a.nu, a.nv, sa, t, 0), a1 = SideNode(a.nu, a.nv, sa, t, 1);
        const auto b0 = SideNode(bb.nu, bb.nv, sb, tb, 0);
        const Eigen::Vector2d xa0 = a.plane.row(a0[0] + a.nu * a0[1]).transpose();
        const Eigen::Vector2d out_dir = (xa0 - a.plane.row(a1[0] + a.nu * a1[1]).transpose()).normalized();
        for (int d = 1; d <= 2 && d < depth; ++d) {
          const auto bd = SideNode(bb.nu, bb.nv, sb, tb, d), ad = SideNode(a.nu, a.nv, sa, t, -d);
          const std::size_t cell = static_cast<std::size_t>(a.Cell(ad[0], ad[1]));
          a.particle[cell] = bb.particle[static_cast<std::size_t>(bb.Cell(bd[0], bd[1]))];
          a.rest[cell] = xa0 + out_dir * (bb.plane.row(bd[0] + bb.nu * bd[1]) - bb.plane.row(b0[0] + bb.nu * b0[1])).norm();
        }
      }
    }
  return out;
}

}  // namespace clothbench
