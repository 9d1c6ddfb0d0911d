// The registry of obstacle shapes: the TOML `type` of an `[[obstacle]]`
// table → the factory that its file in collision/shapes/ defines. A new
// shape is one file that defines `std::shared_ptr<const ObstacleShape>
// Parse<Name>(ShapeKeys&)` and one line here (docs/notes/collisions.md "Obstacle
// shapes").
#include <fmt/format.h>

#include "collision/shapes/obstacle_shape.h"

// X(type, factory): one line per shape.
#define CLOTHBENCH_OBSTACLE_SHAPES(X) \
  X("plane", ParsePlane)              \
  X("sphere", ParseSphere)            \
  X("box", ParseBox)                  \
  X("cylinder", ParseCylinder)        \
  X("capsule", ParseCapsule)          \
  X("mesh", ParseMesh)                \
  X("mesh_sequence", ParseMeshSequence) \
  X("skeleton", ParseSkeleton)

namespace clothbench {

#define CLOTHBENCH_DECLARE_SHAPE(type, factory) std::shared_ptr<const ObstacleShape> factory(ShapeKeys& keys);
CLOTHBENCH_OBSTACLE_SHAPES(CLOTHBENCH_DECLARE_SHAPE)
#undef CLOTHBENCH_DECLARE_SHAPE

namespace {

struct ShapeEntry {
  std::string_view type;
  std::shared_ptr<const ObstacleShape> (*parse)(ShapeKeys&);
};

#define CLOTHBENCH_SHAPE_ENTRY(type, factory) ShapeEntry{type, &factory},
constexpr ShapeEntry kShapes[] = {CLOTHBENCH_OBSTACLE_SHAPES(CLOTHBENCH_SHAPE_ENTRY)};
#undef CLOTHBENCH_SHAPE_ENTRY

}  // namespace

std::vector<std::string_view> ObstacleShapeTypes() {
  std::vector<std::string_view> types;
  for (const ShapeEntry& e : kShapes) types.push_back(e.type);
  return types;
}

std::shared_ptr<const ObstacleShape> ParseObstacleShape(std::string_view type, ShapeKeys& keys) {
  for (const ShapeEntry& e : kShapes)
    if (e.type == type) return e.parse(keys);
  std::string names;
  const std::size_t n = std::size(kShapes);
  for (std::size_t k = 0; k < n; ++k)
    names += fmt::format("{}\"{}\"", k == 0 ? "" : (k + 1 == n ? " or " : ", "), kShapes[k].type);
  keys.Fail("type", fmt::format("must be {} (got \"{}\")", names, type));
  return nullptr;  // not reached: Fail throws
}

}  // namespace clothbench
