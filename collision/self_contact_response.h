// The cloth's response to contact with itself (docs/notes/collisions.md,
// "Self-contact"), after Bridson, Fedkiw & Anderson 2002, "Robust
// treatment of collisions, contact and friction for cloth animation", §7:
// a step's end state is corrected through its mean velocity ν = (x₁ − x₀)/h
//   1. repulsion (§7.2): every pair closer than the thickness at x₀ has its
//      relative normal velocity raised to at least 0.1 (thickness − d)/h,
//      which also stops an approaching pair (the inelastic impulse);
//   2. collision impulses (§7.3): every pair that the CCD finds touching
//      along x₀ → x₀ + hν has its relative normal velocity set to zero, by
//      Gauss–Seidel passes in the pairs' sorted order, until none is found
//      or kImpulsePasses are spent;
//   3. rigid impact zones (§7.4, Provot 1997): the particles of the pairs
//      still colliding are merged into zones that move rigidly (their
//      linear and angular momentum kept; a zone holding a fixed particle
//      stops), until no pair collides or kZonePasses are spent.
// Impulses are weighted by inverse mass (fixed particles: none) and so keep
// the linear momentum. The state becomes x₁ + hΔν, v₁ + Δν.
#ifndef CLOTHBENCH_COLLISION_SELF_CONTACT_RESPONSE_H_
#define CLOTHBENCH_COLLISION_SELF_CONTACT_RESPONSE_H_

#include <algorithm>
#include <array>
#include <utility>
#include <vector>

#include "collision/self_contact.h"
#include "collision/self_contact_list.h"
#include "model/particle_system.h"

namespace clothbench {

/// What the response did since Reset.
struct SelfContactStats {
  long steps = 0;                ///< steps responded to
  long candidates = 0;           ///< pairs each broad phase listed, summed over them
  long broad_phases = 0;         ///< broad phases (CGAL box_intersection_d; builds of a list kept over steps)
  long repulsions = 0;           ///< repulsion impulses (stage 1)
  long collisions = 0;           ///< collision impulses (stage 2)
  long zone_passes = 0;          ///< impact-zone passes (stage 3)
  long unresolved_steps = 0;     ///< steps that ended with a collision left
  long projections = 0;          ///< position projections (a position-based peer's own constraints)
  long pair_impulses = 0;        ///< pairs holding an impulse at a step's end (projective dynamics' own constraints)
  double detection_seconds = 0;  ///< broad phase, closest points and CCD [s]
  double response_seconds = 0;   ///< impulses, zones and the work's energies [s]
  double work = 0.0;             ///< W_self: the energy the corrections added (< 0: removed) [J]
  /// The counts by the names a result file and the Python door give them
  /// (docs/guide/results-schema.md, /runs/<id>/self_contact).
  std::array<std::pair<const char*, long>, 9> Counts() const {
    return {{{"steps", steps}, {"candidates", candidates}, {"broad_phases", broad_phases}, {"repulsions", repulsions},
             {"collisions", collisions}, {"zone_passes", zone_passes}, {"unresolved_steps", unresolved_steps},
             {"projections", projections}, {"pair_impulses", pair_impulses}}};
  }
  /// The sum of two stages' counters and times (a stepper's own constraints
  /// and the run's response after them); steps the larger.
  SelfContactStats& operator+=(const SelfContactStats& o) {
    steps = std::max(steps, o.steps);
    candidates += o.candidates;
    broad_phases += o.broad_phases;
    repulsions += o.repulsions;
    collisions += o.collisions;
    zone_passes += o.zone_passes;
    unresolved_steps += o.unresolved_steps;
    projections += o.projections;
    pair_impulses += o.pair_impulses;
    detection_seconds += o.detection_seconds;
    response_seconds += o.response_seconds;
    work += o.work;
    return *this;
  }
};

/// The candidate list kept over steps of the cloth's grid triangles:
/// patches of SelfContactResponse::kPatchCells × kPatchCells grid quads, a skin of
/// SelfContactResponse::kSkinFraction grid spacings.
/// @param system the cloth (its scene's grid)
SelfContactList GridSelfContactList(const ParticleSystem& system);

class SelfContactResponse {
 public:
  static constexpr double kRepulsion = 0.1;  ///< Bridson et al. 2002, §7.2: 0.1 d/Δt
  static constexpr int kImpulsePasses = 8;
  static constexpr int kZonePasses = 100;
  /// A coplanar instant is a collision when the pair is within this
  /// fraction of the thickness: the bisection finds it to round-off, so
  /// this only widens a crossing through an element's border.
  static constexpr double kCcdToleranceFraction = 1e-3;
  /// The skin R of the candidate lists kept over steps (SelfContactList,
  /// GridSelfContactList) as a fraction of the grid spacing: a list holds
  /// the pairs within reach + 2R and is rebuilt when a patch's motion could
  /// bring a pair it left out within the reach. Each step tests only the
  /// listed pairs whose distance bound falls within the thickness. Measured
  /// on fold_over_rod and sphere_fold (docs/notes/collisions.md, "The list kept
  /// over steps").
  static constexpr double kSkinFraction = 0.25;
  /// The broad phase boxes patches of kPatchCells × kPatchCells grid quads
  /// (GridPatches), not single triangles.
  static constexpr int kPatchCells = 2;

  /// @param system the cloth (masses, fixed particles, grid; must outlive this)
  /// @param thickness [m], > 0
  SelfContactResponse(const ParticleSystem& system, double thickness);

  void Reset() { stats_ = SelfContactStats{}; }
  /// Corrects the step of size h [s] from x0 to (x1, v1) (N×3 [m], [m/s],
  /// changed in place) as above.
  /// @return the pairs still colliding along x₀ → x₁ after it (0 unless
  ///         the impact zones ran out of passes)
  int Respond(double h, const MatrixN3& x0, MatrixN3* x1, MatrixN3* v1);
  const SelfContactStats& stats() const { return stats_; }
  double thickness() const { return thickness_; }

 private:
  // Sets the pair's relative velocity along g.n to at least `target` [m/s]
  // by an impulse weighted by inverse mass; updates x_end's rows. true if applied.
  bool Push(const SelfContactPair& pair, const PairGeometry& g, double target, double h, const MatrixN3& x0);
  // Makes the list cover x₀ → x_end_ and collects near_, the listed pairs
  // whose distance bound is within the thickness, with their distances at
  // x₀ (each computed once a step).
  void Refresh(const MatrixN3& x0);
  // The pairs colliding along x₀ → x_end_ (stage 2 applies impulses as it goes).
  int CollisionPass(double h, const MatrixN3& x0, bool apply, std::vector<int>* colliding);
  void RigidZones(double h, const MatrixN3& x0, const std::vector<int>& colliding);
  int Find(int p);

  const ParticleSystem& sys_;
  double thickness_;
  SelfContactList list_;
  Eigen::VectorXd inverse_mass_;
  SelfContactStats stats_;
  // Scratch of one step.
  MatrixN3 nu_, nu_start_, x_end_;
  std::vector<std::size_t> near_, fresh_;  // list indices: near the thickness; their distances not yet known
  std::vector<double> distance0_;  // each listed pair's distance at x₀ [m], where stamp_ is this step's
  std::vector<long> stamp_;
  long step_ = 0;
  std::vector<char> touching_;     // a pass's test of each pair of near_
  // The candidates a stage acts on, in the pairs' order (SortActing): the
  // impulses do not depend on the order of CGAL's report.
  std::vector<std::size_t> acting_;
  void SortActing();
  std::vector<int> parent_;   // impact zones (union–find over particles)
  std::vector<int> colliding_;  // a zone pass's colliding pairs, four particles each
  // Particles whose x_end changed since the last pass tested them; whether
  // the next pass tests every candidate (after a broad phase).
  std::vector<char> moved_, moved_before_;
  bool test_all_ = true;
  bool end_moved_ = true;  // x_end_ changed since the last Refresh
  std::vector<char> in_zone_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_COLLISION_SELF_CONTACT_RESPONSE_H_
