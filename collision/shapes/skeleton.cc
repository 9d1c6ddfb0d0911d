// A body driven by motion capture: a skeleton and its animation read from a
// BVH file by Assimp (aiScene::mAnimations, one aiNodeAnim per joint), a
// capsule per bone between a joint and its child, each with its radius.
// Forward kinematics at each of the clip's frames gives the joints' world
// positions, placed as a mesh is, x ↦ R(scale · x) + translate; between
// frames they move linearly with the chord's velocity (as a mesh
// sequence's vertices do: at the CMU clips' 120 frames/s a bone turning at
// 10 rad/s is then shorter by at most 1 − cos(ωΔτ/2) = 2e-4 of its length
// mid-frame). Scene time t is clip time start + time_scale · t, held at the
// clip's first and last frame outside it (docs/model.md §7).
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <stdexcept>
#include <system_error>

#include <assimp/Importer.hpp>
#include <assimp/scene.h>
#include <fmt/format.h>

#include "collision/shapes/obstacle_shape.h"
#include "collision/shapes/point_frames.h"

namespace clothbench {
namespace {

struct SkeletonPlacement {
  std::string path;  ///< the resolved BVH file
  double scale = 1.0, time_scale = 1.0, start = 0.0;
  double radius = 0.05;                         ///< default per bone [m]
  std::map<std::string, double, std::less<>> radii;  ///< per bone (by its child joint's name) [m]
  Vector3 rotate = Vector3::Zero(), translate = Vector3::Zero();
};

// The clip: per frame the joints' placed positions, and the bones.
struct Clip {
  PointFrames joints;                      ///< the joints [m] at the frames' scene times [s]
  std::vector<std::array<int, 2>> bones;   ///< (parent joint, child joint)
  std::vector<double> radii;               ///< per bone [m]
  std::vector<std::string> names;          ///< per joint
};

// The skeleton at one time: capsules with their ends' velocities.
class Pose final : public ObstacleShape {
 public:
  Pose(std::vector<Vector3> x, std::vector<Vector3> v, std::shared_ptr<const Clip> clip)
      : x_(std::move(x)), v_(std::move(v)), clip_(std::move(clip)) {
    for (std::size_t b = 0; b < clip_->bones.size(); ++b) {
      const auto [i, j] = clip_->bones[b];
      capsules_.push_back(ShapeFromValues("capsule", {{"a", x_[i]}, {"b", x_[j]}, {"radius", clip_->radii[b]}}));
    }
  }
  std::string_view type() const override { return "skeleton"; }
  double SignedDistance(const Vector3& p, Vector3* dir) const override {
    double best = std::numeric_limits<double>::infinity();
    for (const auto& c : capsules_) {
      Vector3 d;
      const double s = c->SignedDistance(p, &d);
      if (s < best) best = s, *dir = d;
    }
    return best;
  }
  std::optional<SegmentHit> FirstHit(const Vector3& a, const Vector3& b) const override {
    std::optional<SegmentHit> first;
    for (const auto& c : capsules_)
      if (auto hit = c->FirstHit(a, b); hit && (!first || hit->s < first->s)) first = hit;
    return first;
  }
  Vector3 anchor() const override { return Vector3::Zero(); }
  bool has_edges() const override { return false; }
  void Surface(std::vector<Vector3>* vertices, std::vector<std::array<int, 3>>* triangles) const override {
    vertices->clear();
    triangles->clear();
    for (const auto& c : capsules_) {
      std::vector<Vector3> v;
      std::vector<std::array<int, 3>> t;
      c->Surface(&v, &t);
      const int offset = static_cast<int>(vertices->size());
      vertices->insert(vertices->end(), v.begin(), v.end());
      for (const auto& [a, b, d] : t) triangles->push_back({a + offset, b + offset, d + offset});
    }
  }
  // The closest bone's point moves with its ends' interpolated velocity.
  Vector3 SurfaceVelocity(const Vector3& p) const override {
    std::size_t best = 0;
    double distance = std::numeric_limits<double>::infinity();
    for (std::size_t b = 0; b < capsules_.size(); ++b) {
      Vector3 d;
      if (const double s = capsules_[b]->SignedDistance(p, &d); s < distance) distance = s, best = b;
    }
    if (capsules_.empty()) return Vector3::Zero();
    const auto [i, j] = clip_->bones[best];
    const Vector3 ab = x_[j] - x_[i];
    const double s = std::clamp((p - x_[i]).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    return (1.0 - s) * v_[i] + s * v_[j];
  }
  // The distance to a union of capsules moves by at most the largest joint displacement.
  double MaxVertexDistance(const ObstacleShape& other) const override {
    const auto* o = dynamic_cast<const Pose*>(&other);
    if (!o) throw std::logic_error("skeleton: poses of different shapes");
    return MaxPointDistance(x_, o->x_);
  }

 private:
  std::vector<Vector3> x_, v_;  // joints [m] and their velocities [m/s]
  std::shared_ptr<const Clip> clip_;
  std::vector<std::shared_ptr<const ObstacleShape>> capsules_;
};

class Skeleton final : public ObstacleShape {
 public:
  explicit Skeleton(SkeletonPlacement placement) : placement_(std::move(placement)) {}
  Skeleton(SkeletonPlacement placement, std::shared_ptr<const Clip> clip)
      : placement_(std::move(placement)), clip_(std::move(clip)), rest_(Interpolate(clip_->joints.times().front())) {}
  std::string_view type() const override { return "skeleton"; }
  std::shared_ptr<const ObstacleShape> Load() const override {
    if (clip_) return shared_from_this();
    return std::make_shared<const Skeleton>(placement_, ReadClip());
  }
  bool loads_file() const override { return true; }
  std::string file() const override { return placement_.path; }
  bool deforms() const override { return true; }
  bool has_edges() const override { return false; }
  double SignedDistance(const Vector3& p, Vector3* dir) const override { return Rest().SignedDistance(p, dir); }
  std::optional<SegmentHit> FirstHit(const Vector3& a, const Vector3& b) const override { return Rest().FirstHit(a, b); }
  Vector3 anchor() const override { return Vector3::Zero(); }
  void Surface(std::vector<Vector3>* vertices, std::vector<std::array<int, 3>>* triangles) const override {
    Rest().Surface(vertices, triangles);
  }
  double MaxVertexSpeedBetween(double t0, double t1) const override {
    return clip_ ? clip_->joints.max_speed(t0, t1) : 0.0;
  }
  double NextFrameTime(double t) const override {
    return clip_ ? clip_->joints.NextTime(t) : std::numeric_limits<double>::infinity();
  }
  std::shared_ptr<const ObstacleShape> At(double t) const override {
    if (!clip_) throw std::logic_error("skeleton queried before Load()");
    return cache_.At(t, [this](double at) { return Interpolate(at); });
  }

 private:
  const ObstacleShape& Rest() const {
    if (!rest_) throw std::logic_error("skeleton queried before Load(): " + placement_.path);
    return *rest_;
  }
  std::shared_ptr<const Clip> ReadClip() const;
  std::shared_ptr<const Pose> Interpolate(double t) const {
    std::vector<Vector3> x, v;
    clip_->joints.At(t, &x, &v);
    return std::make_shared<const Pose>(std::move(x), std::move(v), clip_);
  }

  SkeletonPlacement placement_;
  std::shared_ptr<const Clip> clip_;  // after Load
  std::shared_ptr<const Pose> rest_;  // at the first frame
  StateCache cache_;
};

// The node's transform relative to its parent at key `k` of its channel
// (its rest transform without one).
aiMatrix4x4 LocalAt(const aiNode* node, const aiNodeAnim* channel, unsigned k) {
  if (!channel) return node->mTransformation;
  const aiVector3D position = channel->mPositionKeys[std::min(k, channel->mNumPositionKeys - 1)].mValue;
  const aiQuaternion rotation = channel->mRotationKeys[std::min(k, channel->mNumRotationKeys - 1)].mValue;
  return aiMatrix4x4(aiVector3D(1.0f, 1.0f, 1.0f), rotation, position);
}

// Reads the BVH: its joints (every node under the root), bones, and the
// joints' placed positions at every frame. @throws std::runtime_error
// naming the file and the rule
std::shared_ptr<const Clip> Skeleton::ReadClip() const {
  const SkeletonPlacement& p = placement_;
  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFile(p.path, 0);
  if (!scene || !scene->mRootNode)
    throw std::runtime_error(fmt::format("\"{}\": {}", p.path, importer.GetErrorString()));
  if (scene->mNumAnimations == 0 || scene->mAnimations[0]->mNumChannels == 0)
    throw std::runtime_error(fmt::format("\"{}\" has no motion frames", p.path));
  const aiAnimation& anim = *scene->mAnimations[0];
  std::map<std::string, const aiNodeAnim*> channels;
  const aiNodeAnim* clock = nullptr;  // the channel with the most keys gives the frames' times
  for (unsigned c = 0; c < anim.mNumChannels; ++c) {
    channels[anim.mChannels[c]->mNodeName.C_Str()] = anim.mChannels[c];
    if (!clock || anim.mChannels[c]->mNumRotationKeys > clock->mNumRotationKeys) clock = anim.mChannels[c];
  }
  const unsigned frames = clock->mNumRotationKeys;
  if (frames == 0) throw std::runtime_error(fmt::format("\"{}\" has no motion frames", p.path));
  auto clip = std::make_shared<Clip>();
  std::vector<const aiNode*> nodes;
  std::vector<int> parent;
  const auto collect = [&](const auto& self, const aiNode* n, int up) -> void {
    nodes.push_back(n);
    parent.push_back(up);
    clip->names.emplace_back(n->mName.C_Str());
    const int me = static_cast<int>(nodes.size()) - 1;
    for (unsigned c = 0; c < n->mNumChildren; ++c) self(self, n->mChildren[c], me);
  };
  collect(collect, scene->mRootNode, -1);
  for (const auto& [name, r] : p.radii)
    if (std::find(clip->names.begin(), clip->names.end(), name) == clip->names.end())
      throw std::runtime_error(fmt::format("\"{}\" has no joint \"{}\" (radii names a bone by its child joint)", p.path, name));
  const double tps = anim.mTicksPerSecond > 0.0 ? anim.mTicksPerSecond : 25.0;
  const Eigen::Matrix3d R = RotationFromDegrees(p.rotate);
  for (unsigned k = 0; k < frames; ++k) {
    // The frame's clip time, in scene time: (τ − start)/time_scale.
    const double tick = clock->mRotationKeys[k].mTime;
    const double t = (tick / tps - p.start) / p.time_scale;
    std::vector<aiMatrix4x4> world(nodes.size());
    std::vector<Vector3> x(nodes.size());
    for (std::size_t j = 0; j < nodes.size(); ++j) {
      const auto it = channels.find(nodes[j]->mName.C_Str());
      const aiMatrix4x4 local = LocalAt(nodes[j], it == channels.end() ? nullptr : it->second, k);
      world[j] = parent[j] < 0 ? local : world[static_cast<std::size_t>(parent[j])] * local;
      x[j] = R * (p.scale * Vector3(world[j].a4, world[j].b4, world[j].c4)) + p.translate;
    }
    if (!clip->joints.empty() && !(t > clip->joints.last_time())) continue;  // frames at one tick
    clip->joints.Add(t, std::move(x));
  }
  // A bone per joint with a parent, unless the two coincide (a zero offset).
  for (std::size_t j = 0; j < nodes.size(); ++j) {
    if (parent[j] < 0) continue;
    const std::vector<Vector3>& first = clip->joints.frame(0);
    if (!((first[j] - first[static_cast<std::size_t>(parent[j])]).norm() > 1e-6)) continue;
    clip->bones.push_back({parent[j], static_cast<int>(j)});
    const auto r = p.radii.find(clip->names[j]);
    clip->radii.push_back(r == p.radii.end() ? p.radius : r->second);
  }
  if (clip->bones.empty()) throw std::runtime_error(fmt::format("\"{}\" has no bones of positive length", p.path));
  return clip;
}

// The BVH's MOTION header before Assimp reads it: Assimp gives a clip of
// "Frames: 0" one key of zeros. @return "" or the rule the file breaks
std::string CheckBvhFrames(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  bool motion = false;
  while (std::getline(in, line)) {
    if (line.rfind("MOTION", 0) == 0) motion = true;
    if (motion && line.rfind("Frames:", 0) == 0) {
      const long frames = std::strtol(line.c_str() + 7, nullptr, 10);
      return frames > 0 ? "" : "has no motion frames (Frames: " + std::to_string(frames) + ")";
    }
  }
  return "has no motion frames (no MOTION section with a Frames: line)";
}

}  // namespace

/// Keys: `path` (a BVH file, relative to the scene file), `scale` (file
/// units to m, in [1e-6, 1e6]), `time_scale` (clip seconds per scene
/// second, in [1e-3, 1e3]), `start` (the clip's time at t = 0 [s], ≥ 0),
/// `radius` (each bone's default [m], in [1e-4, 1]), `radii` (a table
/// { JointName = r }: the bone ending at that joint), `rotate` (degrees
/// about x, then y, then z) and `translate` [m] as for `mesh`.
std::shared_ptr<const ObstacleShape> ParseSkeleton(ShapeKeys& keys) {
  SkeletonPlacement m;
  const std::string rel = keys.String("path", "");
  if (rel.empty()) keys.Fail("path", "must name a BVH file (motion capture)");
  const std::filesystem::path p(keys.ResolvePath(rel));
  std::error_code ec;
  if (!std::filesystem::is_regular_file(p, ec))
    keys.Fail("path", fmt::format("BVH file \"{}\" not found or not a regular file", p.string()));
  m.path = p.string();
  if (const std::string why = CheckBvhFrames(m.path); !why.empty())
    keys.Fail("path", fmt::format("BVH file \"{}\" {}", m.path, why));
  keys.NoteInputFile(m.path);  // an output of this command must not replace it
  keys.Placement(&m.scale, &m.rotate, &m.translate);
  m.time_scale = keys.Range("time_scale", 1.0, 1e-3, 1e3, "");
  m.start = keys.Range("start", 0.0, 0.0, 1e6, " s");
  m.radius = keys.Range("radius", m.radius, 1e-4, 1.0, " m");
  for (const auto& [name, r] : keys.NamedNumbers("radii")) {
    if (!(r >= 1e-4 && r <= 1.0)) keys.Fail("radii", fmt::format("{} = {:g} must be in [1e-4, 1] m", name, r));
    m.radii[name] = r;
  }
  return std::make_shared<const Skeleton>(std::move(m));
}

}  // namespace clothbench
