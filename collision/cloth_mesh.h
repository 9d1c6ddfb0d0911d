// The cloth's triangles and their patches for a scene: the uniform grid's
// (GridTriangles, GridPatches), or on a cloth of patterns (Scene::cloth;
// docs/model.md §2.8) every pattern's quads in the cloth's numbering, a
// seam's two sides one edge.
#ifndef CLOTHBENCH_COLLISION_CLOTH_MESH_H_
#define CLOTHBENCH_COLLISION_CLOTH_MESH_H_

#include <vector>

#include "collision/edge_projection.h"
#include "model/scene.h"

namespace clothbench {

/// The cloth's triangles: GridTriangles(nu, nv) on a uniform grid; on a
/// cloth of patterns each quad of ClothLayout::quads, in its order, split as
/// GridTriangles splits a quad (lower then upper triangle), with the
/// triangle across each edge (−1 on the cloth's border; a seam's edge joins
/// its two patterns' triangles).
ClothTriangles SceneTriangles(const Scene& scene);

/// Per triangle of SceneTriangles its patch of up to cells × cells quads
/// of one pattern (GridPatches on a uniform grid): patches number pattern
/// after pattern.
/// @param cells quads along each side of a patch, >= 1
std::vector<int> ScenePatches(const Scene& scene, int cells);

}  // namespace clothbench

#endif  // CLOTHBENCH_COLLISION_CLOTH_MESH_H_
