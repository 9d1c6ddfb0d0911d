// The thesis' collision-adaptive virtual particles (thesis §5.2–5.4;
// docs/model.md, "Virtual particles"): where an obstacle's edges pass
// through the cloth, points on those edges are inserted into the cloth's
// triangles for one step. This is their detection: the projection of the
// obstacles' edges onto the cloth (§5.3, collision/edge_projection.h), the
// faces' orientation, and the refined mesh for display. The springs they
// split and their force are the model's term (model/virtual_springs.h),
// which this sets each update.
#ifndef CLOTHBENCH_COLLISION_VIRTUAL_PARTICLES_H_
#define CLOTHBENCH_COLLISION_VIRTUAL_PARTICLES_H_

#include <array>
#include <memory>
#include <vector>

#include "collision/edge_projection.h"
#include "model/obstacle.h"
#include "model/particle_system.h"
#include "model/trajectory.h"
#include "model/types.h"
#include "model/virtual_springs.h"

namespace clothbench {

class TriangleMesh;

/// The virtual particles of a cloth grid against the obstacles that ask
/// for them (ObstacleSpec::virtual_particles). The topology is per-step
/// state: Update sets it from the step's initial positions into the model's
/// VirtualSprings term, and every force evaluation until the next Update
/// uses it (the run driver updates before each step).
class VirtualParticles : public VirtualSprings::Detection {
 public:
  /// The virtual particles of `system`, or nullptr if no obstacle asks for
  /// them: made at the first call and owned by the system's VirtualSprings
  /// term (ParticleSystem::virtual_springs), so that every entry point
  /// reaches the same one. Not thread safe at the first call.
  static VirtualParticles* Of(const ParticleSystem& system);

  /// @param grid_nu, grid_nv the cloth grid
  /// @param springs the model's term, whose topology Update sets (must outlive this)
  /// @param obstacles the model's obstacles (must outlive this); those with
  ///        spec().virtual_particles are projected
  /// @param cell the edge grid's cell [m]: twice the longest rest length
  VirtualParticles(int grid_nu, int grid_nv, VirtualSprings* springs, const std::vector<Obstacle>& obstacles,
                   double cell);
  ~VirtualParticles() override;

  /// Computes the virtual particles and springs at time t [s] from the N×3
  /// positions x [m] (§5.3, §5.4); nothing if t and x are those of the last
  /// update. Reuses its buffers: no allocation once they have grown to the
  /// scene's need.
  void Update(double t, const MatrixN3& x);
  /// Forgets the topology (no virtual particles, no force) and the faces'
  /// orientations: the start of a run.
  void Clear();
  /// The model's term and its topology (VirtualSprings).
  const VirtualSprings& springs() const { return *springs_; }
  const std::vector<VirtualParticle>& particles() const { return springs_->particles(); }
  const std::vector<VirtualSpring>& virtual_springs() const { return springs_->virtual_springs(); }
  const std::vector<RemovedCoupling>& removed_couplings() const { return springs_->removed_couplings(); }
  double TensionEnergyChange(const MatrixN3& x) const { return springs_->TensionEnergyChange(x); }
  /// The cloth's sub-mesh at positions x [m] (the update's, for display,
  /// §5.3): every cloth triangle with virtual particles re-triangulated
  /// with them by a constrained Delaunay triangulation in its plane, the
  /// projected obstacle edges as constraints, lifted back to the virtual
  /// particles on the obstacle; the others as they are. Its time counts as
  /// topology. @param triangles overwritten: indices < N are base particles,
  /// N + k virtual particle k (a crossing of two projected edges inside a
  /// face, where the triangulation adds a point, is appended to
  /// particles() with no force)
  void RefinedMesh(const MatrixN3& x, std::vector<std::array<int, 3>>* triangles);
  /// Appends the current virtual particles and the refined mesh at
  /// positions x [m] as one more frame of `frames` (model/trajectory.h).
  void RecordFrame(const MatrixN3& x, VirtualFrames* frames);
  /// The cloth's triangles (GridTriangles) the projection works on.
  const ClothTriangles& triangles() const { return cloth_; }
  /// Wall time [s] since Clear (the start of a run) in the projection
  /// (§5.3; Table 5.1's "projection"), in the springs' topology (ordering
  /// the points on the cloth edges, splitting the rest lengths) and in
  /// RefinedMesh's triangulations (with the springs, Table 5.1's
  /// "topology"); the number of updates that computed and of triangulations.
  double projection_seconds() const { return projection_seconds_; }
  double springs_seconds() const { return springs_seconds_; }
  double triangulation_seconds() const { return triangulation_seconds_; }
  long updates() const { return updates_; }
  long triangulations() const { return triangulations_; }

 private:
  struct Source;  // one obstacle that is projected
  void ClearTopology();
  // The parts of Update: one obstacle's projection (with its edge index and
  // its virtual particles).
  void ProjectSource(Source* src, double t, const MatrixN3& x);
  void IndexEdges(Source* src, const ObstaclePose& pose);
  void AddVirtualParticles(const Source* src, const ObstaclePose& pose, const MatrixN3& x);

  int nu_ = 0, nv_ = 0;
  double cell_ = 0.0;  // the edge grid's cell [m]: twice the longest rest length
  VirtualSprings* springs_;
  ClothTriangles cloth_;
  std::vector<std::unique_ptr<Source>> sources_;
  double t_update_ = 0.0;
  MatrixN3 x_update_;      // the positions of the last update
  bool current_ = false;   // an update since Clear
  struct Segment {  // a standing projection: its face and its two end points (as found)
    int face = 0;
    std::array<VirtualParticle, 2> ends;
  };
  std::vector<Segment> segments_;
  std::vector<std::vector<int>> face_points_;      // RefinedMesh: the virtual particles of each face
  std::vector<std::pair<double, int>> on_edge_;    // RefinedMesh: the points on one face edge, in order
  std::vector<std::array<int, 3>> record_faces_;   // RecordFrame: the refined mesh
  // Scratch of Update.
  std::vector<Vector3> normal_;
  std::vector<FaceEdgeHit> hits_;
  double projection_seconds_ = 0.0, springs_seconds_ = 0.0, triangulation_seconds_ = 0.0;
  long updates_ = 0, triangulations_ = 0;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_COLLISION_VIRTUAL_PARTICLES_H_
