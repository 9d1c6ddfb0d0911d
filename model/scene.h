// Scene description: the cloth grid, its material, external forces, fixed
// particles and solver settings, read from TOML.
// docs/model.md §1 (discretisation), §2 (forces), §5–6 (solver settings).
#ifndef CLOTHBENCH_MODEL_SCENE_H_
#define CLOTHBENCH_MODEL_SCENE_H_

#include <array>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "collision/shapes/escape_control.h"
#include "model/obstacle.h"
#include "model/cloth_layout.h"
#include "model/pattern.h"
#include "model/solver_spec.h"
#include "model/types.h"

namespace clothbench {

struct Scene;

/// Thrown for a bad scene: the message is one line naming the source (file),
/// the key and the rule it broke, e.g.
/// `scenes/x.toml: material.tension: must be 2 numbers >= 0`.
class SceneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Limits of a run that every scene and command line is held to before
/// anything is computed (docs/guide/scenes.md, "Limits"): the steps t_end/h of a
/// fixed-step run, the frames t_end/frame_dt kept, and the particles nu·nv.
inline constexpr double kMaxStepsPerRun = 1e7;
inline constexpr double kMaxFramesPerRun = 1e6;
inline constexpr double kMaxParticles = 1e7;
/// The largest magnitude any scene number may have (a stated limit far
/// beyond every physical value, so that products of two never overflow).
inline constexpr double kMaxMagnitude = 1e12;
/// The longest scene `name` [bytes]: it is stored as an HDF5 attribute
/// (compact attributes hold at most 64 KiB together) and names output files.
inline constexpr std::size_t kMaxSceneNameBytes = 1024;

/// Checks t_end, frame_dt and h of `scene` against kMaxFramesPerRun and
/// kMaxStepsPerRun. @throws SceneError "<source>: <key>: <rule>".
void CheckRunLength(const Scene& scene, const std::string& source);

enum class BendModel { kNone, kMembrane, kThinPlate };
/// "split": springs with rest length l_e, IMEX split F_lin + F_nl (docs/model.md §2.1).
/// "linear": zero-rest-length springs, f = −L_K x − L_D v only (F_nl absent):
/// an exactly linear prestressed membrane, used by the modal order tests.
enum class TensionModel { kSplit, kLinear };
enum class MassLumping { kUniform, kArea };
std::string_view ToString(BendModel m);
std::string_view ToString(TensionModel m);
std::string_view ToString(MassLumping m);

struct GridSpec {
  int nu = 20;                                    ///< particles along u (>= 2)
  int nv = 20;                                    ///< particles along v (>= 2)
  std::array<double, 2> size = {0.76, 0.76};      ///< [m] along u and v
  Vector3 origin = Vector3(0.0, 0.0, 1.0);        ///< [m] rest position of particle (0,0)
  Vector3 u_axis = Vector3::UnitX();              ///< unit vector along u
  Vector3 v_axis = Vector3::UnitY();              ///< unit vector along v, orthogonal to u
};

/// Material constants per unit length of cloth (docs/model.md §1).
struct MaterialSpec {
  double density = 1.0;                           ///< ρ [kg/m²]
  std::array<double, 2> tension = {1000.0, 1000.0};  ///< k_u, k_v [N/m], (2.20)
  double tension_damping = 0.0;                   ///< d_t [N s/m], (3.18)
  TensionModel tension_model = TensionModel::kSplit;
  double shear = 0.0;                             ///< μ [N/m], (2.21)
  double shear_damping = 0.0;                     ///< d_s [N s/m]
  std::array<double, 2> bend = {0.0, 0.0};        ///< B_u, B_v ([N m] thin plate, [N/m] membrane)
  double bend_damping = 0.0;                      ///< d_b, (2.30)
  BendModel bend_model = BendModel::kThinPlate;   ///< (2.25) membrane | (2.26) thin plate
  double transverse = 0.0;                        ///< C_1122 [N/m], (2.22)
  MassLumping mass_lumping = MassLumping::kUniform;  ///< docs/model.md §1
};

/// Oscillating wind (2.35, 2.36): f_w(t) = (a + sin(ω t)) w.
struct WindSpec {
  Vector3 direction = Vector3::Zero();  ///< w [m/s·(force scale)], direction and strength
  double constant = 0.0;                ///< a, constant part
  double angular_frequency = 0.0;       ///< ω [rad/s]
  double drag = 1.0;                    ///< c_drag [kg/(m² s)·…] normal coefficient
  double lift = 0.0;                    ///< c_lift tangential coefficient
};

struct ForcesSpec {
  Vector3 gravity = Vector3(0.0, 0.0, -9.81);  ///< [m/s²]
  std::optional<WindSpec> wind;                ///< absent: no wind term
  double air = 0.0;                            ///< c_air [kg/(m² s)], (2.37); 0: no term
};

/// `[collision]`: the cloth against itself (docs/notes/collisions.md, "Self-contact").
/// Present, every run's stored frames are checked for crossing triangle
/// pairs; `self` turns the self-contact response on.
struct SelfCollisionSpec {
  bool self = false;       ///< respond to self-contact (Bridson et al. 2002)
  /// [m] the cloth's thickness: pairs closer than it repel. Below the
  /// flat grid's closest non-adjacent elements, lu·lv/√(lu² + lv²) (a
  /// vertex to the diagonal of the next quad), so that the rest state is
  /// free of contact.
  double thickness = 1e-3;
};

/// Why `thickness` [m] does not suit the grid of `scene` (SelfCollisionSpec:
/// below lu·lv/√(lu² + lv²)), or empty if it does.
std::string SelfContactThicknessRule(const Scene& scene, double thickness);

/// Fixed particles that follow a keyframed rigid motion
/// (`[[constraints.motion]]`; docs/guide/scenes.md): their rest positions moved
/// by KeyframedMotion (model/obstacle.h) about `anchor`. Every method that
/// integrates such a scene sets their positions and velocities to the
/// motion's at each step's end and holds them there through the step's
/// solve (ParticleSystem::ForEachPrescribed).
struct FixedMotionSpec {
  std::string particles_spec;                ///< as written ("edge:u1", "corner:u0v0", …)
  std::vector<int> particles;                ///< resolved, sorted, unique; all fixed
  std::optional<Vector3> anchor;             ///< rotation centre [m]; absent: the particles' rest centroid
  std::vector<ObstacleKeyframe> keyframes;   ///< non-empty, times strictly increasing
};

/// One scene: everything needed to build the particle system and run it.
struct Scene {
  std::string name = "unnamed";
  double t_end = 1.0;      ///< [s]
  double frame_dt = 0.01;  ///< [s] interval of stored frames
  double h = 0.01;         ///< [s] nominal step
  GridSpec grid;                         ///< the sheet; with `patterns`, the one pattern's grid
  std::vector<PatternSpec> patterns;     ///< `[[pattern]]`; empty: the cloth is `[grid]`
  std::vector<SeamSpec> seams;           ///< `[[seam]]`
  /// `[sewing] time` [s]: the sewing phase that brings the seams' sides
  /// together (solver/sewing.h); 0: none, the sides must start together.
  double sewing_time = 0.0;
  /// The cloth of the patterns and seams (docs/model.md §2.7–2.8), unless
  /// it is `grid`'s uniform sheet (no patterns, or one flat rectangle):
  /// then null. With it, `grid` holds the first pattern's nu, nv, placement
  /// and the bounding box of its samples.
  std::shared_ptr<const ClothLayout> cloth;
  MaterialSpec material;                 ///< the cloth's; with one pattern, that pattern's
  /// Per pattern, `[material]` with its `[pattern.material]` keys over it.
  std::vector<MaterialSpec> pattern_materials;
  ForcesSpec forces;
  std::vector<std::string> fixed_specs;  ///< as written in the scene
  std::vector<int> fixed;                ///< resolved flat particle indices, sorted, unique
  std::vector<FixedMotionSpec> motions;  ///< `[[constraints.motion]]`; empty: every fixed particle at rest
  SolverSpec solver;
  std::vector<ObstacleSpec> obstacles;   ///< `[[obstacle]]` (docs/model.md §7); empty: no detection, no filter
  std::optional<SelfCollisionSpec> collision;  ///< `[collision]`; absent: no self-contact, frames not checked
  std::string source = "<memory>";       ///< file path or "<embedded>"
  std::string toml;                      ///< the scene's TOML text

  int num_particles() const { return cloth ? cloth->num_particles : grid.nu * grid.nv; }
  /// Whether the cloth is one uniform grid, `grid` (else Scene::cloth).
  bool uniform_grid() const { return cloth == nullptr; }
  /// The rest spacing along u [m]: the grid's, or a curvilinear pattern's smallest.
  double lu() const { return cloth ? cloth->least_spacing[0] : grid.size[0] / (grid.nu - 1); }
  /// The rest spacing along v [m]: the grid's, or a curvilinear pattern's smallest.
  double lv() const { return cloth ? cloth->least_spacing[1] : grid.size[1] / (grid.nv - 1); }
  /// Flat index p = i + nu·j (docs/model.md §1).
  int Index(int i, int j) const { return i + grid.nu * j; }
  /// Numerical stiffness h²k/(ρl²) (§3.4.4) with the largest k_e/l_e² of u and v.
  double NumericalStiffness(double step) const;
};

/// Parses and validates a scene from TOML text.
/// @param text   TOML document (format: docs/guide/scenes.md)
/// @param source name used in error messages (a path or "<embedded>")
/// @throws SceneError with a one-line message on any syntax error, unknown
///         key, wrong type or value out of range.
Scene ParseScene(std::string_view text, const std::string& source);

/// Reads and parses a scene file. @throws SceneError (also if unreadable).
Scene LoadScene(const std::string& path);

/// The embedded default scene (scenes/swinging_sheet.toml, compiled in).
Scene DefaultScene();
/// A compiled-in scene by name. @throws SceneError for an unknown name.
Scene BuiltinScene(std::string_view name);
/// A built-in scene if `arg` names one, else the scene file at path `arg`.
Scene LoadSceneOrBuiltin(const std::string& arg);

/// The scene on a finer or coarser grid of about `n` particles: nu and nv
/// chosen so that nu·nv ≈ n with the rest spacings' ratio lu/lv of `scene`
/// kept (nu − 1 : nv − 1 as in the scene, each at least 2), and the sheet's
/// size, material (per unit length and area, docs/model.md §1, "Resolution"),
/// forces, constraints, obstacles, h and t_end unchanged. The TOML text is
/// rewritten (toml++; the comments are dropped) with the new [grid] nu, nv
/// and the name "<name>_<nu>x<nv>", and parsed again by ParseScene, so the
/// stored text reproduces the refined scene.
/// @param n the particle count wanted, 4 … kMaxParticles
/// @throws SceneError "<source>: constraints.fixed: …" if a fixed spec names
///   particles by index ("particle:I,J" does not follow a refinement), or a
///   ParseScene error of the rewritten text
Scene RefineGrid(const Scene& scene, long n);

/// The largest distance [m] a seam's two samples may start apart (they are
/// merged into one particle at their midpoint).
inline constexpr double kSeamGap = 1e-6;

/// Makes `cloth` the scene's Scene::cloth, and `grid` its first pattern's
/// nu, nv, placement and sample box (`patterns` must be the cloth's).
void SetCloth(Scene* scene, ClothLayout cloth);

/// Makes the rest samples `plane` ((nu·nv)×2 [m], row i + nu·j, nu × nv =
/// pattern.nu × pattern.nv) the cloth of `scene`, placed by `pattern`
/// (PlacePattern): Scene::cloth of the one pattern, `patterns` = {pattern},
/// no seams. The model then takes its rest geometry from the samples
/// (docs/model.md §2.7). Tests give their own samplings with it.
/// @throws std::invalid_argument if plane's rows are not nu·nv
void SetCurvilinearCloth(Scene* scene, const PatternSpec& pattern, Eigen::MatrixX2d plane);

/// Resolves a constraint spec ("edge:u0", "corner:u1v0", "particle:I,J") to
/// flat indices. @throws SceneError naming `what` on a malformed spec.
std::vector<int> ResolveFixed(const std::string& spec, int nu, int nv, const std::string& what);

}  // namespace clothbench

#endif  // CLOTHBENCH_MODEL_SCENE_H_
