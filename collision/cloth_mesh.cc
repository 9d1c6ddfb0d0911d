// The cloth's triangles and patches of a scene (collision/cloth_mesh.h).
#include "collision/cloth_mesh.h"

#include <algorithm>
#include <array>
#include <map>
#include <utility>

#include "collision/self_contact.h"

namespace clothbench {

ClothTriangles SceneTriangles(const Scene& scene) {
  if (!scene.cloth) return GridTriangles(scene.grid.nu, scene.grid.nv);
  ClothTriangles out;
  for (const std::array<int, 4>& q : scene.cloth->quads) {
    out.vertices.push_back({q[0], q[1], q[2]});
    out.vertices.push_back({q[0], q[2], q[3]});
  }
  // Each undirected edge's triangles; an edge with exactly two is inner.
  std::map<std::pair<int, int>, std::vector<int>> edge;
  for (std::size_t t = 0; t < out.vertices.size(); ++t)
    for (int k = 0; k < 3; ++k) {
      const int a = out.vertices[t][static_cast<std::size_t>(k)], b = out.vertices[t][static_cast<std::size_t>((k + 1) % 3)];
      edge[{std::min(a, b), std::max(a, b)}].push_back(static_cast<int>(t));
    }
  out.across.assign(out.vertices.size(), {-1, -1, -1});
  for (std::size_t t = 0; t < out.vertices.size(); ++t)
    for (int k = 0; k < 3; ++k) {
      const int a = out.vertices[t][static_cast<std::size_t>(k)], b = out.vertices[t][static_cast<std::size_t>((k + 1) % 3)];
      const std::vector<int>& ts = edge[{std::min(a, b), std::max(a, b)}];
      if (ts.size() == 2) out.across[t][static_cast<std::size_t>(k)] = ts[0] == static_cast<int>(t) ? ts[1] : ts[0];
    }
  return out;
}

std::vector<int> ScenePatches(const Scene& scene, int cells) {
  if (!scene.cloth) return GridPatches(scene.grid.nu, scene.grid.nv, cells);
  std::vector<int> out;
  int first = 0;
  for (const ClothBlock& b : scene.cloth->blocks) {
    const std::vector<int> block = GridPatches(b.nu, b.nv, cells);
    int count = 0;
    for (int p : block) {
      out.push_back(first + p);
      count = std::max(count, p + 1);
    }
    first += count;
  }
  return out;
}

}  // namespace clothbench
