// The obstacle shapes (docs/notes/collisions.md "Obstacle shapes"; docs/model.md §7,
// thesis ch. 4–5): one interface, one file per shape (plane.cc, sphere.cc,
// box.cc, cylinder.cc, mesh.cc) and one registry (registry.cc) that picks a
// shape by the TOML `type` of an `[[obstacle]]` table. A shape answers in
// its placed frame, at rest; model/obstacle.h moves it by its keyframes.
//
// This is the lowest layer of clothbench: it needs Eigen, CGAL and the
// header-only numeric types of model/types.h, and nothing else of the
// project. The scene (model/scene.cc) reads a shape's keys through
// ShapeKeys, so the shape states its own keys, ranges and messages.
#ifndef CLOTHBENCH_COLLISION_SHAPES_OBSTACLE_SHAPE_H_
#define CLOTHBENCH_COLLISION_SHAPES_OBSTACLE_SHAPE_H_

#include <array>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

#include <Eigen/Geometry>

namespace clothbench {

/// A point or direction [m] (the shapes are the lowest layer, below model/,
/// and include nothing of ours: this is model/types.h's Vector3).
using Vector3 = Eigen::Vector3d;

class TriangleMesh;

/// Rotation R = R_z(c) R_y(b) R_x(a) from angles (a, b, c) in degrees: about x,
/// then y, then z (the convention of the scene keys `rotate`).
Eigen::Matrix3d RotationFromDegrees(const Vector3& degrees);

/// Where a segment a → b first enters an obstacle.
struct SegmentHit {
  double s = 0.0;                      ///< fraction along the segment, in [0, 1]
  Vector3 point = Vector3::Zero();     ///< a + s (b − a) [m]
  Vector3 normal = Vector3::Zero();    ///< unit surface normal at the hit, facing a's side
};

/// One frame of a sequence of files: its time [s] and path as written.
struct TimedPath {
  double t = 0.0;
  std::string path;
};

/// How a shape reads its keys from an `[[obstacle]]` table (the scene's TOML
/// reader, or ShapeFromValues for shapes built in code). Every read marks
/// the key as used; the caller rejects keys nobody read.
class ShapeKeys {
 public:
  virtual ~ShapeKeys() = default;
  /// @throws the entry point's validation error, one line naming the key
  ///         and `rule` (SceneError: "<source>: obstacle[k].<key>: <rule>")
  [[noreturn]] virtual void Fail(std::string_view key, std::string_view rule) const = 0;
  /// A number in [lo, hi]; `fallback` if the key is absent. `units` follows
  /// the range in the message (e.g. " m").
  virtual double Range(std::string_view key, double fallback, double lo, double hi, std::string_view units) = 0;
  /// Three finite numbers (non-negative if asked); `fallback` if absent.
  virtual std::array<double, 3> Numbers3(std::string_view key, std::array<double, 3> fallback, bool non_negative) = 0;
  /// A string; `fallback` if absent.
  virtual std::string String(std::string_view key, std::string fallback) = 0;
  /// A non-empty array of tables { t = s, path = "…" } (t finite and ≥ 0,
  /// path a non-empty string; no other keys), as written; empty if absent.
  virtual std::vector<TimedPath> TimedPaths(std::string_view key) = 0;
  /// A table { name = number, … } of finite numbers (checked by the
  /// caller), as written; empty if absent.
  virtual std::vector<std::pair<std::string, double>> NamedNumbers(std::string_view key) = 0;
  /// A path as written under `key`, resolved: a relative path is relative to
  /// the scene file (for a built-in scene, the source tree's scenes/).
  virtual std::string ResolvePath(const std::string& path) const = 0;
  /// Records `path` as an input of this command, which no output may replace.
  virtual void NoteInputFile(const std::string& path) const = 0;

  Vector3 Vec3(std::string_view key, const Vector3& fallback) {
    const auto a = Numbers3(key, {fallback.x(), fallback.y(), fallback.z()}, false);
    return Vector3(a[0], a[1], a[2]);
  }
  /// A file shape's placement x ↦ R(scale · x) + translate: `scale` in
  /// [1e-6, 1e6], `rotate` (degrees about x, then y, then z, at most 3600 in
  /// magnitude), `translate` [m] (within 1e6 m); absent keys keep the values given.
  void Placement(double* scale, Vector3* rotate, Vector3* translate) {
    *scale = Range("scale", *scale, 1e-6, 1e6, "");
    *rotate = Vec3("rotate", *rotate);
    if (rotate->cwiseAbs().maxCoeff() > 3600) Fail("rotate", "must be angles of magnitude at most 3600 degrees");
    *translate = Vec3("translate", *translate);
    if (translate->cwiseAbs().maxCoeff() > 1e6) Fail("translate", "must have coordinates of magnitude at most 1e6 m");
  }
  /// The centre (or a point) of an analytic shape: coordinates within 1e6 m.
  Vector3 Centre(std::string_view key) {
    const Vector3 c = Vec3(key, Vector3::Zero());
    if (c.cwiseAbs().maxCoeff() > 1e6) Fail(key, "must have coordinates of magnitude at most 1e6 m");
    return c;
  }
};

/// An obstacle's shape at rest, in its placed (scene) frame. Shared by the
/// copies of an obstacle and read from any thread: every query is const.
class ObstacleShape : public std::enable_shared_from_this<ObstacleShape> {
 public:
  virtual ~ObstacleShape() = default;
  /// The TOML `type` that names the shape ("plane", "sphere", …).
  virtual std::string_view type() const = 0;
  /// The shape ready for queries: a mesh reads its file here, not when the
  /// scene is parsed; the analytic shapes are ready as parsed (this).
  /// @throws std::runtime_error for an unreadable mesh file
  virtual std::shared_ptr<const ObstacleShape> Load() const { return shared_from_this(); }
  /// Whether Load reads a file (then the model checks where the cloth
  /// starts, not the scene parser: the check needs the loaded shape).
  virtual bool loads_file() const { return false; }
  /// Signed distance [m] of the placed point p (negative inside a solid;
  /// unsigned for an open mesh) and the unit outward direction D at the
  /// closest surface point (docs/model.md §7).
  virtual double SignedDistance(const Vector3& p, Vector3* direction) const = 0;
  /// The first point where the placed segment a → b enters the shape, or
  /// nothing if it does not or a is inside (thesis §5.1's ray cast). By
  /// default for a convex shape: the signed distance along the segment is
  /// convex, its minimum is bracketed by golden-section search and the entry
  /// by bisection (to 1e-12 of the segment).
  virtual std::optional<SegmentHit> FirstHit(const Vector3& a, const Vector3& b) const;
  /// The point [m] keyframed rotations turn about (a centre, a mesh's
  /// `translate`).
  virtual Vector3 anchor() const = 0;
  /// Whether the shape has edges for the thesis' virtual particles (§5.3).
  virtual bool has_edges() const { return true; }
  /// The shape's edges at rest for the virtual particles' projection (§5.3;
  /// collision/edge_projection.h). By default the edges of Surface's triangles,
  /// each once, as sorted index pairs.
  /// @param vertices [m], overwritten; @param edges index pairs into them, overwritten
  virtual void Edges(std::vector<Vector3>* vertices, std::vector<std::array<int, 2>>* edges) const;
  /// The closed triangle surface whose edges include Edges(), on the same
  /// vertices (extra vertices after them), counter-clockwise seen from
  /// outside; empty for a shape without edges. The virtual particles' ray
  /// check (Fig. 5.9) casts against it.
  /// @param vertices [m], overwritten; @param triangles index triples, overwritten
  virtual void Surface(std::vector<Vector3>* vertices, std::vector<std::array<int, 3>>* triangles) const = 0;
  /// The loaded triangle mesh of a mesh shape; nullptr for analytic shapes.
  virtual const TriangleMesh* mesh() const { return nullptr; }
  /// The file the shape was read from; empty for analytic shapes.
  virtual std::string file() const { return ""; }
  /// The scene key that names the shape's files ("path"; "frames").
  virtual std::string_view file_key() const { return "path"; }

  /// Shapes that deform in time (a mesh sequence); the others are rigid
  /// and move only by an obstacle's keyframes.
  virtual bool deforms() const { return false; }
  /// A deforming shape at time t [s], in world coordinates (it takes no
  /// keyframes): a rigid shape whose SurfaceVelocity gives its motion;
  /// nullptr for a rigid shape. Loaded shapes only.
  virtual std::shared_ptr<const ObstacleShape> At(double /*t*/) const { return nullptr; }
  /// The velocity [m/s] of the surface point closest to p [m]: 0 for a
  /// rigid shape at rest; for a deforming shape's At(t), the barycentric
  /// interpolation of its closest triangle's vertex velocities.
  virtual Vector3 SurfaceVelocity(const Vector3& /*p*/) const { return Vector3::Zero(); }
  /// The largest distance [m] any vertex moves between this state and
  /// `other` of the same deforming shape (At(t_a), At(t_b)); 0 for a rigid shape.
  virtual double MaxVertexDistance(const ObstacleShape& /*other*/) const { return 0.0; }
  /// The largest vertex speed [m/s] of a deforming shape at any time in
  /// [t0, t1] [s] (±∞ allowed: its whole motion); 0 for a rigid shape.
  virtual double MaxVertexSpeedBetween(double /*t0*/, double /*t1*/) const { return 0.0; }
  /// A deforming shape's first frame time after t [s]: where its vertex
  /// velocities jump (+∞ for a rigid shape and after the last frame).
  virtual double NextFrameTime(double /*t*/) const { return std::numeric_limits<double>::infinity(); }
};

/// Appends the triangle (a, b, c) of `vertices`, turned to face away from
/// `interior` (for the convex analytic shapes' Surface).
void AddOutwardTriangle(const std::vector<Vector3>& vertices, const Vector3& interior, int a, int b, int c,
                        std::vector<std::array<int, 3>>* triangles);

/// The shape named by `type`, its keys read through `keys` (registry.cc).
/// @throws through keys.Fail("type", …) for an unknown type, and for a key
///         that breaks its shape's rule
std::shared_ptr<const ObstacleShape> ParseObstacleShape(std::string_view type, ShapeKeys& keys);

/// The registered types, in the order of the registry ("plane", "sphere", …).
std::vector<std::string_view> ObstacleShapeTypes();

/// A key's value for a shape built in code: a number, three numbers or a string.
using ShapeValue = std::variant<double, Vector3, std::string, std::vector<TimedPath>,
                                std::vector<std::pair<std::string, double>>>;

/// A shape built in code (tests, benchmarks) from the keys its TOML table
/// would hold, by the same rules as the scene's; paths are used as given.
/// @throws std::invalid_argument "<type>.<key>: <rule>" for a broken rule or
///         a key the shape does not read
std::shared_ptr<const ObstacleShape> ShapeFromValues(std::string_view type,
                                                     const std::map<std::string, ShapeValue, std::less<>>& values);

}  // namespace clothbench

#endif  // CLOTHBENCH_COLLISION_SHAPES_OBSTACLE_SHAPE_H_
