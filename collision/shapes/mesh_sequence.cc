// A deforming mesh obstacle: a sequence of meshes with one topology (OFF,
// OBJ or PLY files, each at its time), placed as `mesh` places one file,
// x ↦ R(scale · x) + translate. Between frames t_k < t_{k+1} the vertices
// move linearly,
//   X(t) = (1 − λ) X_k + λ X_{k+1},  λ = (t − t_k)/(t_{k+1} − t_k),
// with the constant velocity (X_{k+1} − X_k)/(t_{k+1} − t_k); before the
// first and after the last frame the mesh is held (docs/model.md §7,
// "Deforming obstacles"). A surface point moves with the barycentric
// interpolation of its triangle's vertex velocities.
#include <algorithm>
#include <limits>
#include <filesystem>
#include <stdexcept>
#include <system_error>

#include <fmt/format.h>

#include "collision/shapes/obstacle_shape.h"
#include "collision/shapes/point_frames.h"
#include "collision/shapes/triangle_mesh.h"

namespace clothbench {
namespace {

struct SequencePlacement {
  std::vector<double> times;       ///< strictly increasing [s]
  std::vector<std::string> paths;  ///< the resolved files, one per time
  double scale = 1.0;
  Vector3 rotate = Vector3::Zero();     ///< degrees about x, then y, then z
  Vector3 translate = Vector3::Zero();  ///< [m]
};

// The loaded frames: placed vertices per frame, the one triangle list.
struct SequenceFrames {
  PointFrames vertices;
  std::vector<std::array<int, 3>> triangles;
};

// The sequence at one time: a rigid mesh whose surface moves.
class MeshAtTime final : public ObstacleShape {
 public:
  MeshAtTime(std::vector<Vector3> x, std::vector<Vector3> v, const std::vector<std::array<int, 3>>& triangles)
      : x_(std::move(x)), v_(std::move(v)), triangles_(triangles), mesh_(x_, triangles) {}
  std::string_view type() const override { return "mesh_sequence"; }
  double SignedDistance(const Vector3& p, Vector3* dir) const override { return mesh_.SignedDistance(p, dir); }
  std::optional<SegmentHit> FirstHit(const Vector3& a, const Vector3& b) const override { return mesh_.FirstHit(a, b); }
  Vector3 anchor() const override { return Vector3::Zero(); }
  void Surface(std::vector<Vector3>* vertices, std::vector<std::array<int, 3>>* triangles) const override {
    *vertices = x_;
    *triangles = triangles_;
  }
  const TriangleMesh* mesh() const override { return &mesh_; }
  Vector3 SurfaceVelocity(const Vector3& p) const override {
    Vector3 c;
    const std::array<int, 3>& t = triangles_[static_cast<std::size_t>(mesh_.ClosestFace(p, &c))];
    const Vector3 &a = x_[t[0]], &b = x_[t[1]], &d = x_[t[2]];
    // Barycentric coordinates of c in (a, b, d) (Ericson, Real-Time Collision Detection §3.4).
    const Vector3 e0 = b - a, e1 = d - a, e2 = c - a;
    const double d00 = e0.dot(e0), d01 = e0.dot(e1), d11 = e1.dot(e1), d20 = e2.dot(e0), d21 = e2.dot(e1);
    const double det = d00 * d11 - d01 * d01;
    if (!(det > 0.0)) return (v_[t[0]] + v_[t[1]] + v_[t[2]]) / 3.0;  // a degenerate face: its mean
    const double wb = (d11 * d20 - d01 * d21) / det, wd = (d00 * d21 - d01 * d20) / det;
    return (1.0 - wb - wd) * v_[t[0]] + wb * v_[t[1]] + wd * v_[t[2]];
  }
  double MaxVertexDistance(const ObstacleShape& other) const override {
    const auto* o = dynamic_cast<const MeshAtTime*>(&other);
    if (!o) throw std::logic_error("mesh_sequence: states of different shapes");
    return MaxPointDistance(x_, o->x_);
  }

 private:
  std::vector<Vector3> x_, v_;  // vertices [m] and their velocities [m/s]
  std::vector<std::array<int, 3>> triangles_;
  TriangleMesh mesh_;
};

class MeshSequence final : public ObstacleShape {
 public:
  explicit MeshSequence(SequencePlacement placement) : placement_(std::move(placement)) {}
  MeshSequence(SequencePlacement placement, std::shared_ptr<const SequenceFrames> frames)
      : placement_(std::move(placement)), frames_(std::move(frames)), rest_(Interpolate(placement_.times.front())) {}
  std::string_view type() const override { return "mesh_sequence"; }
  std::shared_ptr<const ObstacleShape> Load() const override {
    if (frames_) return shared_from_this();
    return std::make_shared<const MeshSequence>(placement_, ReadFrames());
  }
  bool loads_file() const override { return true; }
  std::string file() const override { return placement_.paths.front(); }
  std::string_view file_key() const override { return "frames"; }
  bool deforms() const override { return true; }
  // At rest: the first frame.
  double SignedDistance(const Vector3& p, Vector3* dir) const override { return Rest().SignedDistance(p, dir); }
  std::optional<SegmentHit> FirstHit(const Vector3& a, const Vector3& b) const override { return Rest().FirstHit(a, b); }
  Vector3 anchor() const override { return Vector3::Zero(); }
  void Surface(std::vector<Vector3>* vertices, std::vector<std::array<int, 3>>* triangles) const override {
    Rest().Surface(vertices, triangles);
  }
  const TriangleMesh* mesh() const override { return frames_ ? Rest().mesh() : nullptr; }
  double MaxVertexSpeedBetween(double t0, double t1) const override {
    return frames_ ? frames_->vertices.max_speed(t0, t1) : 0.0;
  }
  double NextFrameTime(double t) const override {
    return frames_ ? frames_->vertices.NextTime(t) : std::numeric_limits<double>::infinity();
  }
  std::shared_ptr<const ObstacleShape> At(double t) const override {
    if (!frames_) throw std::logic_error("mesh_sequence queried before Load()");
    return cache_.At(t, [this](double at) { return Interpolate(at); });
  }

 private:
  const ObstacleShape& Rest() const {
    if (!rest_) throw std::logic_error("mesh_sequence queried before Load(): " + placement_.paths.front());
    return *rest_;
  }
  std::shared_ptr<const SequenceFrames> ReadFrames() const;
  std::shared_ptr<const MeshAtTime> Interpolate(double t) const;

  SequencePlacement placement_;
  std::shared_ptr<const SequenceFrames> frames_;  // after Load (shared by copies)
  std::shared_ptr<const MeshAtTime> rest_;        // the first frame
  StateCache cache_;
};

// Reads every frame and checks that they share the first one's topology.
// @throws std::runtime_error naming the file and the rule
std::shared_ptr<const SequenceFrames> MeshSequence::ReadFrames() const {
  auto frames = std::make_shared<SequenceFrames>();
  const SequencePlacement& p = placement_;
  for (std::size_t k = 0; k < p.paths.size(); ++k) {
    const TriangleMesh m(p.paths[k], p.scale, p.rotate, p.translate);
    std::vector<double> xyz;
    std::vector<int32_t> tri;
    m.Export(&xyz, &tri);
    std::vector<std::array<int, 3>> triangles;
    for (std::size_t j = 0; j + 2 < tri.size(); j += 3) triangles.push_back({tri[j], tri[j + 1], tri[j + 2]});
    std::vector<Vector3> x;
    for (std::size_t j = 0; j + 2 < xyz.size(); j += 3) x.emplace_back(xyz[j], xyz[j + 1], xyz[j + 2]);
    if (k == 0) {
      frames->triangles = std::move(triangles);
    } else if (x.size() != frames->vertices.frame(0).size() || triangles != frames->triangles) {
      throw std::runtime_error(fmt::format(
          "frame {} (\"{}\", {} vertices, {} triangles) does not have the topology of frame 0 (\"{}\", {} vertices, "
          "{} triangles): a sequence keeps one vertex count and the same triangles",
          k, p.paths[k], x.size(), triangles.size(), p.paths[0], frames->vertices.frame(0).size(), frames->triangles.size()));
    }
    frames->vertices.Add(p.times[k], std::move(x));
  }
  return frames;
}

std::shared_ptr<const MeshAtTime> MeshSequence::Interpolate(double t) const {
  std::vector<Vector3> x, v;
  frames_->vertices.At(t, &x, &v);
  return std::make_shared<const MeshAtTime>(std::move(x), std::move(v), frames_->triangles);
}

// A frame's file: it exists, is a regular file and has a plausible header.
void CheckFrameFile(ShapeKeys& keys, std::size_t k, const std::filesystem::path& p) {
  std::error_code ec;
  const auto status = std::filesystem::status(p, ec);
  const auto fail = [&](const std::string& rule) {
    keys.Fail("frames", fmt::format("frame {}: mesh file \"{}\" {}", k, p.string(), rule));
  };
  if (ec && ec != std::errc::no_such_file_or_directory) fail("cannot be used: " + ec.message());
  if (!std::filesystem::exists(status)) fail("not found");
  if (!std::filesystem::is_regular_file(status)) fail("is not a regular file");
  if (const std::string why = CheckMeshHeader(p.string()); !why.empty()) fail(why);
}

}  // namespace

/// Keys: `frames` (an array of { t = s, path = "file" }, times strictly
/// increasing, paths relative to the scene file, OFF, OBJ or PLY with one
/// topology), `scale` in [1e-6, 1e6], `rotate` (degrees about x, then y,
/// then z, at most 3600 in magnitude), `translate` [m] (within 1e6 m).
std::shared_ptr<const ObstacleShape> ParseMeshSequence(ShapeKeys& keys) {
  SequencePlacement m;
  const std::vector<TimedPath> frames = keys.TimedPaths("frames");
  if (frames.empty()) keys.Fail("frames", "is required: [{ t = s, path = \"file\" }, ...], one mesh per time");
  for (std::size_t k = 0; k < frames.size(); ++k) {
    if (k > 0 && !(frames[k].t > frames[k - 1].t))
      keys.Fail("frames", fmt::format("frame {} (\"{}\"): t = {:g} s must be greater than frame {}'s t = {:g} s", k,
                                      frames[k].path, frames[k].t, k - 1, frames[k - 1].t));
    const std::filesystem::path p(keys.ResolvePath(frames[k].path));
    CheckFrameFile(keys, k, p);
    m.times.push_back(frames[k].t);
    m.paths.push_back(p.string());
    keys.NoteInputFile(m.paths.back());  // an output of this command must not replace it
  }
  keys.Placement(&m.scale, &m.rotate, &m.translate);
  return std::make_shared<const MeshSequence>(std::move(m));
}

}  // namespace clothbench
