// Obstacles for collision response (docs/model.md §7, thesis ch. 4): a shape
// (collision/shapes/: plane, sphere, box, cylinder — a round table is a
// cylinder with a top — and CGAL triangle meshes) with its contact
// parameters, placed by a keyframed rigid motion (thesis §6.2, class
// Environment). Each gives the signed distance of a point, the collision
// direction D (outward normal of the closest surface point) and the first
// point where a segment enters it (the old→new ray cast of §5.1).
#ifndef CLOTHBENCH_MODEL_OBSTACLE_H_
#define CLOTHBENCH_MODEL_OBSTACLE_H_

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "collision/shapes/obstacle_shape.h"
#include "model/types.h"

namespace clothbench {

/// One keyframe of a moving obstacle: at time t [s] the obstacle, as placed
/// by its other keys, is rotated by `rotate` (degrees about x, then y, then
/// z) about its anchor (centre of an analytic obstacle, `translate` of a
/// mesh) and then moved by `translate` [m].
struct ObstacleKeyframe {
  double t = 0.0;
  Vector3 translate = Vector3::Zero();
  Vector3 rotate = Vector3::Zero();
};

/// The rigid placement of an obstacle at one time: a point x of the obstacle
/// as placed in the scene is at anchor + translation + R (x − anchor).
/// Velocities are exact for the piecewise-linear translation and the
/// constant-rate rotation between keyframes.
struct ObstaclePose {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Vector3 translation = Vector3::Zero();         ///< [m]
  Vector3 anchor = Vector3::Zero();              ///< [m], the rotation centre as placed
  Vector3 linear_velocity = Vector3::Zero();     ///< of the anchor [m/s]
  Vector3 angular_velocity = Vector3::Zero();    ///< world frame [rad/s]
  bool identity = true;                          ///< no motion applied (static obstacle)
  /// A deforming shape's state at this time, in world coordinates
  /// (ObstacleShape::At; the transform above is then the identity):
  /// distances, casts and edges are its, and so is the surface velocity.
  std::shared_ptr<const ObstacleShape> deformed;

  /// World point → the obstacle's placed (scene) frame.
  Vector3 ToPlaced(const Vector3& p) const {
    return identity ? p : Vector3(anchor + rotation.transpose() * (p - anchor - translation));
  }
  /// Placed-frame direction → world direction.
  Vector3 ToWorldDirection(const Vector3& d) const { return identity ? d : Vector3(rotation * d); }
  /// Placed-frame point → world point.
  Vector3 ToWorld(const Vector3& x) const { return identity ? x : Vector3(anchor + translation + rotation * (x - anchor)); }
  /// Velocity [m/s] of the obstacle's material point at world position p.
  Vector3 Velocity(const Vector3& p) const {
    if (deformed) return deformed->SurfaceVelocity(p);
    return linear_velocity + angular_velocity.cross(p - anchor - translation);
  }
};

/// A keyframed rigid motion (thesis §6.2, class Environment): of an
/// obstacle, or of fixed particles (`[[constraints.motion]]`). Between
/// keyframes the translation is linear and the rotation turns at a constant
/// rate along the shortest arc from one keyframe's rotation to the next's
/// (so keyframes less than 180° apart give any turn); before the first and
/// after the last keyframe the pose is held.
class KeyframedMotion {
 public:
  KeyframedMotion() = default;
  /// @param keys times strictly increasing (the scene parser checks)
  /// @param anchor [m] the rotation centre as placed
  KeyframedMotion(std::vector<ObstacleKeyframe> keys, const Vector3& anchor);
  /// The rigid placement at time t [s] (identity without keyframes).
  ObstaclePose PoseAt(double t) const;
  bool moving() const { return !keys_.empty(); }

 private:
  std::vector<ObstacleKeyframe> keys_;
  Vector3 anchor_ = Vector3::Zero();
  std::vector<Eigen::Quaterniond> rotations_;  // one per keyframe
};

/// How N particles lie against an obstacle at one pose (Obstacle::Penetration).
struct Penetration {
  double max_depth = 0.0;  ///< largest depth inside, max(0, −d) [m]
  int deepest = -1;        ///< the particle at max_depth; −1 if none is inside
  double depth_sum = 0.0;  ///< sum of −d over the particles inside [m]
  int inside = 0;          ///< particles with d < 0
  int close = 0;           ///< particles with d < δ/2
};

/// The Penetration of n signed distances d [m] to an obstacle with
/// collision distance δ [m], summed in particle order (+∞: far, adds nothing).
Penetration SumPenetration(const double* d, int n, double delta);

/// An obstacle as written in a scene (`[[obstacle]]`): its shape and the
/// contact parameters every shape shares.
struct ObstacleSpec {
  /// The shape at rest (collision/shapes/registry.cc picks it by `type`);
  /// required.
  std::shared_ptr<const ObstacleShape> shape;
  double collision_distance = 0.01;          ///< δ, thickness of the collision area [m]
  double friction = 0.0;                     ///< Coulomb coefficient c_f (docs/model.md §2.5)
  double relaxation = 0.5;                   ///< ω_r in (4.4), 0 < ω_r ≤ 1
  /// Insert the thesis' virtual particles where this obstacle's edges pass
  /// through the cloth (§5.2–5.4; collision/virtual_particles.h). Only for a
  /// shape with edges (not a plane).
  bool virtual_particles = false;
  /// Continuous detection against the obstacle's motion: the old→new cast
  /// of a particle follows its path relative to a moving obstacle (false:
  /// the obstacle's place at the step's start, as for a static one; the
  /// blow-up guard follows the relative path either way).
  bool continuous = true;
  /// Held still in its pose at t = 0 (HeldAt): the same body without its
  /// motion, for measuring what the motion costs.
  bool held = false;
  /// Rigid motion (any shape); empty: static. Times strictly increasing;
  /// before the first and after the last keyframe the pose is held.
  std::vector<ObstacleKeyframe> keyframes;

  std::string_view type() const { return shape ? shape->type() : std::string_view("none"); }
};

/// The obstacle held still in its pose at time t [s]: a keyframed motion
/// becomes one keyframe with the pose at t (the rotation as degrees about x,
/// then y, then z), a deforming shape its state at t (ObstacleShape::At).
/// The sewing pre-phase dresses a moving body in its pose at t = 0
/// (docs/model.md §2.9). A spec already `held` is returned as it is.
/// @throws std::runtime_error as Obstacle's constructor (a shape's file)
ObstacleSpec HeldAt(const ObstacleSpec& spec, double t);

/// Positions beyond this [m] are a blown-up state (scenes place everything
/// within 1e6 m, docs/guide/scenes.md "Limits"): obstacle queries skip them.
inline constexpr double kMaxQueryMagnitude = 1e9;

class Obstacle {
 public:
  /// Loads the shape (ObstacleShape::Load: a mesh reads its file).
  /// @throws std::runtime_error for an unreadable mesh file;
  ///         std::invalid_argument if the spec has no shape
  explicit Obstacle(const ObstacleSpec& spec);
  /// Signed distance [m] of the world point p to the surface at `pose`
  /// (negative inside a solid; unsigned for an open mesh) and the unit
  /// outward direction D [world] at the closest surface point. A point that
  /// is not finite or beyond kMaxQueryMagnitude is not queried: +∞ (and
  /// FirstHit: no hit).
  double SignedDistance(const ObstaclePose& pose, const Vector3& p, Vector3* direction) const;
  /// The same at time t [s] (PoseAt(t)).
  double SignedDistance(double t, const Vector3& p, Vector3* direction) const {
    return SignedDistance(PoseAt(t), p, direction);
  }
  /// The first point where the segment a → b [m, world] enters the obstacle
  /// at `pose` (docs/model.md §7, thesis §5.1's ray cast), or nothing if it does not
  /// or a is already inside (the shape's ObstacleShape::FirstHit in the
  /// placed frame).
  std::optional<SegmentHit> FirstHit(const ObstaclePose& pose, const Vector3& a, const Vector3& b) const;
  /// The signed distances d of the N×3 positions x [m] at `pose`, summed up:
  /// the deepest particle inside, the depths and the particles within δ/2.
  Penetration PenetrationOf(const ObstaclePose& pose, const MatrixN3& x) const;
  /// The rigid placement at time t [s] from the keyframes (identity if none).
  /// A deforming shape's pose also holds its state at t (ObstaclePose::deformed).
  ObstaclePose PoseAt(double t) const {
    ObstaclePose pose = motion_.PoseAt(t);
    if (shape_->deforms()) pose.deformed = shape_->At(t);
    return pose;
  }
  /// PoseAt(t) with the velocities of the motion's piece after t: the same
  /// but at a keyframed motion's first keyframe, where PoseAt holds the
  /// pose at rest (velocity 0) and this gives the first piece's velocities
  /// (the contact in continuous time restarts there, HybridContact).
  ObstaclePose PoseAfter(double t) const {
    ObstaclePose pose = PoseAt(t);
    if (spec_.keyframes.size() > 1 && t == spec_.keyframes.front().t) {
      const ObstaclePose next = motion_.PoseAt(std::nextafter(t, std::numeric_limits<double>::infinity()));
      pose.linear_velocity = next.linear_velocity;
      pose.angular_velocity = next.angular_velocity;
    }
    return pose;
  }
  /// An upper bound [m] on how far any point of a mesh obstacle's solid
  /// moves from pose a to pose b: the largest displacement of its vertices
  /// (the displacement of a rigid motion is affine in the point, so its norm
  /// is largest at a vertex of the convex hull). The signed distance of
  /// every world point changes by at most this much (ContactResponse's
  /// distance cull). 0 for a static obstacle; +∞ for analytic obstacles
  /// (not needed: their distances cost less than the bound). A deforming
  /// mesh: the largest displacement of its vertices (the surface's points
  /// are their convex combinations).
  double MotionBound(const ObstaclePose& a, const ObstaclePose& b) const;
  /// Keyframed, or a shape that deforms (a mesh sequence).
  bool moving() const { return !spec_.keyframes.empty() || shape_->deforms(); }
  /// Where the obstacle's motion from pose `a` to pose `b`, `dt` [s] later,
  /// carries the world point p [m]: the rigid motion's image of p; for a
  /// deforming shape p moved with its closest surface point's velocity at
  /// `a` (exact within one frame interval). p itself for a static obstacle.
  /// The particle's path relative to the obstacle over a step is the
  /// segment from Carried(x₀) to x₁ at pose b (continuous detection).
  Vector3 Carried(const ObstaclePose& a, const ObstaclePose& b, const Vector3& p, double dt) const {
    if (!moving()) return p;
    if (a.deformed) return p + dt * a.Velocity(p);
    return b.ToWorld(a.ToPlaced(p));
  }
  /// The largest speed [m/s] of a deforming shape's vertices over its whole motion (0 otherwise).
  double MaxVertexSpeed() const {
    constexpr double kAll = std::numeric_limits<double>::infinity();
    return shape_->MaxVertexSpeedBetween(-kAll, kAll);
  }
  /// The largest speed [m/s] of a deforming shape's vertices at any time in
  /// [t0, t1] [s] (0 otherwise): what the distance culls' bounds move by
  /// (a motion-capture clip's first frame, often a T-pose the scene never
  /// reaches, does not count where the scene starts past it).
  double MaxVertexSpeedBetween(double t0, double t1) const { return shape_->MaxVertexSpeedBetween(t0, t1); }
  /// The first time after t [s] where the obstacle's velocity jumps: a
  /// keyframe time, or a frame time of a deforming shape (the
  /// piecewise-linear motion changes its velocity at once there); +∞ if
  /// none follows. At such a time PoseAt gives the piece after it, but for
  /// a keyframed motion's first keyframe (PoseAfter).
  double NextBreak(double t) const {
    double next = shape_->NextFrameTime(t);
    for (const ObstacleKeyframe& k : spec_.keyframes)
      if (k.t > t) return std::min(next, k.t);  // keyframe times increase
    return next;
  }
  /// Whether the obstacle's velocity field is smooth over (t0, t1]: no
  /// break (NextBreak) in it.
  bool SmoothBetween(double t0, double t1) const { return NextBreak(t0) > t1; }
  /// The obstacle's edges at `pose` (world coordinates), for the projection
  /// onto the cloth of the thesis' virtual particles (§5.3;
  /// collision/edge_projection.h): ObstacleShape::Edges moved to `pose`.
  /// @param vertices [m], overwritten; @param edges index pairs into them, overwritten
  void Edges(const ObstaclePose& pose, std::vector<Vector3>* vertices, std::vector<std::array<int, 2>>* edges) const;
  /// The closed triangle surface at rest whose edges include
  /// Edges(identity pose), on the same vertices (ObstacleShape::Surface).
  /// @param vertices [m], overwritten; @param triangles index triples, overwritten
  void Surface(std::vector<Vector3>* vertices, std::vector<std::array<int, 3>>* triangles) const {
    shape_->Surface(vertices, triangles);
  }
  const ObstacleSpec& spec() const { return spec_; }
  /// The loaded shape.
  const ObstacleShape& shape() const { return *shape_; }
  /// The placed triangle mesh of a mesh obstacle (at rest, before any
  /// keyframed motion); nullptr for analytic obstacles.
  const TriangleMesh* mesh() const { return shape_->mesh(); }

 private:
  ObstacleSpec spec_;
  std::shared_ptr<const ObstacleShape> shape_;  // loaded (shared by copies)
  KeyframedMotion motion_;
  std::shared_ptr<const std::vector<Vector3>> vertices_;  // keyframed mesh: placed vertices (MotionBound)
};

/// Whether the cloth at positions x [m, N×3; row q is particle first + q]
/// starts inside `o` at t = 0:
/// deeper than its collision distance δ (the run guard's penetration rule),
/// where every method would end `speed` or `penetration` pushing it out.
/// @return "" if not, else "(<type>): particle <p> starts <depth> m inside
///   it at (x, y, z) m, deeper than its collision distance <δ> m (<n>
///   particles start inside); move the grid or the obstacle"
std::string StartsInside(const Obstacle& o, const MatrixN3& x, long first = 0);

}  // namespace clothbench

#endif  // CLOTHBENCH_MODEL_OBSTACLE_H_
