// A triangle-mesh obstacle read through CGAL (OFF, OBJ or PLY;
// triangle_mesh.h), placed as x ↦ R(scale · x) + translate. The scene
// parser checks the file and its header; the model reads it (Load).
#include <filesystem>
#include <system_error>

#include <fmt/format.h>

#include "collision/shapes/obstacle_shape.h"
#include "collision/shapes/triangle_mesh.h"

namespace clothbench {
namespace {

struct MeshPlacement {
  std::string path;  ///< the resolved mesh file
  double scale = 1.0;
  Vector3 rotate = Vector3::Zero();     ///< degrees about x, then y, then z
  Vector3 translate = Vector3::Zero();  ///< [m]
};

class Mesh final : public ObstacleShape {
 public:
  explicit Mesh(MeshPlacement placement) : placement_(std::move(placement)) {}
  Mesh(MeshPlacement placement, std::shared_ptr<const TriangleMesh> mesh)
      : placement_(std::move(placement)), mesh_(std::move(mesh)) {}
  std::string_view type() const override { return "mesh"; }
  std::shared_ptr<const ObstacleShape> Load() const override {
    if (mesh_) return shared_from_this();
    return std::make_shared<const Mesh>(
        placement_, std::make_shared<const TriangleMesh>(placement_.path, placement_.scale, placement_.rotate,
                                                         placement_.translate));
  }
  bool loads_file() const override { return true; }
  double SignedDistance(const Vector3& p, Vector3* dir) const override { return Loaded().SignedDistance(p, dir); }
  std::optional<SegmentHit> FirstHit(const Vector3& a, const Vector3& b) const override {
    return Loaded().FirstHit(a, b);
  }
  Vector3 anchor() const override { return placement_.translate; }
  void Surface(std::vector<Vector3>* vertices, std::vector<std::array<int, 3>>* triangles) const override {
    vertices->clear();
    triangles->clear();
    std::vector<double> xyz;
    std::vector<int32_t> t;
    Loaded().Export(&xyz, &t);
    for (std::size_t k = 0; k + 2 < xyz.size(); k += 3) vertices->emplace_back(xyz[k], xyz[k + 1], xyz[k + 2]);
    for (std::size_t k = 0; k + 2 < t.size(); k += 3) triangles->push_back({t[k], t[k + 1], t[k + 2]});
  }
  const TriangleMesh* mesh() const override { return mesh_.get(); }
  std::string file() const override { return placement_.path; }

 private:
  const TriangleMesh& Loaded() const {
    if (!mesh_) throw std::logic_error("mesh obstacle queried before Load(): " + placement_.path);
    return *mesh_;
  }

  MeshPlacement placement_;
  std::shared_ptr<const TriangleMesh> mesh_;  // after Load (shared by copies)
};

}  // namespace

/// Keys: `path` (an OFF, OBJ or PLY file, relative to the scene file),
/// `scale` in [1e-6, 1e6], `rotate` (degrees about x, then y, then z, at
/// most 3600 in magnitude), `translate` [m] (within 1e6 m).
std::shared_ptr<const ObstacleShape> ParseMesh(ShapeKeys& keys) {
  MeshPlacement m;
  const std::string rel = keys.String("path", "");
  if (rel.empty()) keys.Fail("path", "must name a mesh file (OFF, OBJ or PLY)");
  const std::filesystem::path p(keys.ResolvePath(rel));
  std::error_code ec;
  const auto status = std::filesystem::status(p, ec);
  if (ec && ec != std::errc::no_such_file_or_directory)
    keys.Fail("path", fmt::format("mesh file \"{}\" cannot be used: {}", p.string(), ec.message()));
  if (!std::filesystem::exists(status))
    keys.Fail("path", fmt::format("mesh file \"{}\" not found (scripts/setup extracts CGAL's data into data/)",
                                  p.string()));
  if (!std::filesystem::is_regular_file(status))
    keys.Fail("path", fmt::format("mesh file \"{}\" is not a regular file", p.string()));
  if (const std::string why = CheckMeshHeader(p.string()); !why.empty())
    keys.Fail("path", fmt::format("mesh file \"{}\": {}", p.string(), why));
  m.path = p.string();
  keys.NoteInputFile(m.path);  // an output of this command must not replace it
  keys.Placement(&m.scale, &m.rotate, &m.translate);
  return std::make_shared<const Mesh>(std::move(m));
}

}  // namespace clothbench
