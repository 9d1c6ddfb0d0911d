// Small scenes for the unit tests.
#ifndef CLOTHBENCH_VERIFY_TEST_SCENES_H_
#define CLOTHBENCH_VERIFY_TEST_SCENES_H_

#include <algorithm>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <omp.h>

#include "collision/shapes/obstacle_shape.h"
#include "model/particle_system.h"

namespace clothbench::testing {

/// The n3×n3 sparse matrix of triplets `t` (duplicates summed).
inline SparseMatrix ToSparse(int n3, const std::vector<Triplet>& t) {
  SparseMatrix m(n3, n3);
  m.setFromTriplets(t.begin(), t.end());
  return m;
}

/// The largest magnitude of a stored entry of `m`.
inline double MaxAbs(const SparseMatrix& m) {
  double out = 0.0;
  for (Eigen::Index k = 0; k < m.nonZeros(); ++k) out = std::max(out, std::abs(m.valuePtr()[k]));
  return out;
}

/// The body of scenes/mocap_dress.toml (capsules on the CMU clip 01_01.bvh
/// that scripts/setup installs, from 0.5 s into it, at the scene's scale
/// and rotation) with the legs and feet at the default radius 0.045 m (the
/// scene gives them 0.07 and 0.055 m), placed by `translate` [m]:
/// (0.53, 0.93, 0) puts its root at (0, -0.1, 1) m at t = 0, as the scene does.
inline std::shared_ptr<const ObstacleShape> MocapBody(const Vector3& translate) {
  const std::vector<std::pair<std::string, double>> radii = {
      {"Spine", 0.12}, {"Spine1", 0.13}, {"LeftUpLeg", 0.09}, {"RightUpLeg", 0.09}, {"Neck1", 0.06}, {"Head", 0.06}};
  return ShapeFromValues("skeleton", {{"path", std::string("/usr/share/assimp/models/BVH/01_01.bvh")},
                                      {"scale", 0.056},
                                      {"start", 0.5},
                                      {"radius", 0.045},
                                      {"radii", radii},
                                      {"rotate", Vector3(90.0, 0.0, 180.0)},
                                      {"translate", translate}});
}

/// A nu×nv sheet in the xy-plane with every force term switched on.
inline Scene AllTermsScene(int nu = 5, int nv = 4, BendModel bend = BendModel::kThinPlate) {
  Scene s;
  s.name = "all_terms";
  s.grid.nu = nu;
  s.grid.nv = nv;
  s.grid.size = {0.3, 0.2};
  s.material.tension = {200.0, 150.0};
  s.material.tension_damping = 0.3;
  s.material.shear = 20.0;
  s.material.shear_damping = 0.2;
  s.material.bend = {2e-3, 1e-3};
  s.material.bend_damping = 1e-3;
  s.material.bend_model = bend;
  s.material.transverse = 15.0;
  s.forces.gravity = Vector3(0.0, 0.0, -9.81);
  WindSpec w;
  w.direction = Vector3(0.3, 1.0, 2.0);
  w.constant = 0.5;
  w.angular_frequency = 3.0;
  w.drag = 1.2;
  w.lift = 0.4;
  s.forces.wind = w;
  s.forces.air = 0.7;
  return s;
}

/// The samples (nu·nv)×2 [m] of a nu × nv rectangle of `size` under the
/// map (u, v) ↦ (size_u φ(u), size_v φ(v)) with φ(t) = t + α t (1 − t): graded
/// along both threads, which stay straight, spacings (1 + α) : (1 − α) from
/// one edge to the other (α = 0: the uniform grid); `alpha_v`, if given, is
/// v's α.
inline Eigen::MatrixX2d GradedSamples(int nu, int nv, std::array<double, 2> size, double alpha, double alpha_v = -1.0) {
  Eigen::MatrixX2d x(static_cast<Eigen::Index>(nu) * nv, 2);
  const double av = alpha_v < 0.0 ? alpha : alpha_v;
  const auto phi = [](double t, double a) { return t + a * t * (1.0 - t); };
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i < nu; ++i)
      x.row(i + nu * j) << size[0] * phi(static_cast<double>(i) / (nu - 1), alpha),
          size[1] * phi(static_cast<double>(j) / (nv - 1), av);
  return x;
}

/// A 7×6-sample trapezoid pattern, 0.3 m at its curved lower side (v0) and
/// 0.2 m at its top: no two of its stencils share their rest geometry.
inline PatternSpec CurvedPanel() {
  PatternSpec p;
  p.name = "panel";
  p.corners = {Vector2(0.0, 0.0), Vector2(0.3, 0.0), Vector2(0.25, 0.2), Vector2(0.05, 0.2)};
  p.sides = {std::vector<Vector2>{p.corners[0], Vector2(0.15, -0.03), p.corners[1]},
             std::vector<Vector2>{p.corners[1], p.corners[2]}, std::vector<Vector2>{p.corners[3], p.corners[2]},
             std::vector<Vector2>{p.corners[0], p.corners[3]}};
  p.nu = 7;
  p.nv = 6;
  return p;
}

/// `s` with its grid's cloth given as the rest samples `plane` of one
/// pattern placed at the grid's origin and axes (SetCurvilinearCloth): the
/// model's curvilinear branch (docs/model.md §2.7).
inline Scene WithSamples(Scene s, Eigen::MatrixX2d plane) {
  PatternSpec p;
  p.name = "cloth";
  p.nu = s.grid.nu;
  p.nv = s.grid.nv;
  p.origin = s.grid.origin;
  p.x_axis = s.grid.u_axis;
  p.y_axis = s.grid.v_axis;
  SetCurvilinearCloth(&s, p, std::move(plane));
  return s;
}

/// AllTermsScene with only the momentum-conserving internal forces:
/// tension, shear and transverse contraction (no gravity, wind, air, and no
/// bending, whose projection onto vertex normals is not conservative).
inline Scene InternalForcesScene(int nu, int nv) {
  Scene s = AllTermsScene(nu, nv);
  s.forces.gravity.setZero();
  s.forces.wind.reset();
  s.forces.air = 0.0;
  s.material.bend = {0.0, 0.0};
  s.material.bend_damping = 0.0;
  return s;
}

/// Positions near rest with a smooth out-of-plane bump and random jitter
/// (so no term is degenerate), and random velocities.
inline void PerturbedState(const ParticleSystem& sys, unsigned seed, MatrixN3* x, MatrixN3* v, double jitter = 0.01) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  *x = sys.rest_positions();
  v->setZero(sys.num_particles(), 3);
  const Scene& s = sys.scene();
  for (int j = 0; j < s.grid.nv; ++j)
    for (int i = 0; i < s.grid.nu; ++i) {
      const int p = s.Index(i, j);
      (*x)(p, 2) += 0.05 * std::sin(0.9 * i + 0.3) * std::cos(0.7 * j + 0.1);
      for (int c = 0; c < 3; ++c) {
        (*x)(p, c) += jitter * u(rng);
        (*v)(p, c) = 0.5 * u(rng);
      }
    }
}

/// Linear membrane: zero-rest-length springs (tension_model = "linear"), all
/// four edges fixed, gravity, no shear or bending, 7×6 particles 0.1 m apart
/// (m = 0.01 kg): an exactly linear system (modal order and energy tests).
/// @param damping d_t [N s/m]; L_D = (d_t/k) L_K (proportional damping)
inline Scene LinearMembrane(double damping) {
  Scene s;
  s.grid.nu = 7;
  s.grid.nv = 6;
  s.grid.size = {0.6, 0.5};
  s.material.tension = {10.0, 10.0};
  s.material.tension_model = TensionModel::kLinear;
  s.material.tension_damping = damping;
  s.material.shear = 0.0;
  s.material.bend = {0.0, 0.0};
  s.forces.gravity = Vector3(0.0, 0.0, -9.81);
  for (const char* e : {"edge:u0", "edge:u1", "edge:v0", "edge:v1"})
    for (int p : ResolveFixed(e, s.grid.nu, s.grid.nv, "")) s.fixed.push_back(p);
  std::sort(s.fixed.begin(), s.fixed.end());
  s.fixed.erase(std::unique(s.fixed.begin(), s.fixed.end()), s.fixed.end());
  s.solver.cg_tolerance = 1e-13;
  s.solver.max_updates = 50;
  return s;
}

/// The tablecloth (scenes/tablecloth.toml) released flat 5 mm above an
/// infinite plane z = 0.7 m, i.e. inside the collision area (δ = 10 mm), for
/// t_end [s].
inline Scene TableclothOnPlane(double t_end) {
  Scene s = BuiltinScene("tablecloth");
  s.grid.origin.z() = 0.705;
  ObstacleSpec& plane = s.obstacles[0];
  plane.shape = ShapeFromValues("plane", {{"center", Vector3(0.0, 0.0, 0.7)}, {"normal", Vector3::UnitZ()}});
  s.t_end = t_end;
  return s;
}

/// Runs f() on `threads` OpenMP threads, then restores the thread count
/// (the bit-identical-across-thread-counts tests).
template <class F>
void WithThreads(int threads, F f) {
  const int before = omp_get_max_threads();
  omp_set_num_threads(threads);
  f();
  omp_set_num_threads(before);
}

// The same sheet as [grid] and as one [[pattern]] (same origin and axes):
// 7 × 5 samples over 0.6 × 0.4 m, u along +y, v down; SheetScene fixes
// the selection `fixed` (its v0 edge: "edge:v0" or "panel:edge:v0").
inline const char* const kGridSheet = R"([grid]
nu = 7
nv = 5
size = [0.6, 0.4]
origin = [0.1, -0.2, 1.0]
u_axis = [0.0, 1.0, 0.0]
v_axis = [0.0, 0.0, -1.0]
)";

inline const char* const kRectanglePattern = R"([[pattern]]
name = "panel"
corners = [[0.0, 0.0], [0.6, 0.0], [0.6, 0.4], [0.0, 0.4]]
samples = [7, 5]
origin = [0.1, -0.2, 1.0]
x_axis = [0.0, 1.0, 0.0]
y_axis = [0.0, 0.0, -1.0]
)";

inline std::string SheetScene(const std::string& cloth, const std::string& fixed, double h = 0.005,
                              double frame_dt = 0.05) {
  return "name = \"sheet\"\nt_end = 0.05\nh = " + std::to_string(h) + "\nframe_dt = " + std::to_string(frame_dt) +
         "\n" + cloth + "[material]\nshear = 10.0\nbend = [1e-3, 1e-3]\n[constraints]\nfixed = [\"" + fixed + "\"]\n";
}

}  // namespace clothbench::testing

#endif  // CLOTHBENCH_VERIFY_TEST_SCENES_H_
