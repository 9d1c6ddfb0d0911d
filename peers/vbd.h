// Vertex Block Descent (Chen, Liu, Yang, Yuksel 2024, "Vertex Block
// Descent", ACM TOG 43(4)) on the thesis' particle model, with optional
// Chebyshev acceleration (its §3.8; Wang 2015), docs/model.md §10.
//
// VBD minimises the incremental potential of implicit Euler one particle
// at a time: with the other particles held, particle p takes one 3×3
// Newton step on its local potential, the particles of one graph colour in
// parallel (they do not read each other), Gauss–Seidel across colours. For
// a force that is the gradient of an energy that is the paper's step
// x_p += H_p⁻¹ f_p. This model also has forces that are not gradients
// (the projected bending of (2.25)/(2.26), air, wind) and its own damping
// (the springs' L_D, shear viscosity, bending damping), so the local step
// here is Newton's on particle p's row of the implicit Euler equations in
// velocities, x = x₀ + h v:
//   r_p(v) = m_p (v_p − v₀_p) − h f_p(t₁, x₀ + h v, v) = 0,
//   J_p = m_p I − h ∂f_p/∂v_p − h² ∂f_p/∂x_p,  v_p ← v_p − J_p⁻¹ r_p,
// with every term of the model in f_p (ParticleSystem::ParticleForce).
// Scaled by h this is the paper's step in positions; its Rayleigh damping
// H_d = (k_d/h) H is one particular ∂f/∂v, and the model's own damping
// terms enter the same way, implicitly. The fixed point is implicit
// Euler's for the whole model, so as the iterations grow VBD converges to
// implicit_euler/newton at the same h (test VertexBlockDescent.*). The
// first iterate is the better, by the implicit Euler residual, of the
// paper's adaptive initialisation (§3.7: the last step's acceleration
// along gravity, clamped to [0, |g|]) and the constant-acceleration
// extrapolation (InitialGuess::kSafeguardedExtrapolation). Against the
// inertial guess v₀ + h M⁻¹ f_ext the paper's took the default scene's
// difference to implicit_euler/newton after 64 sweeps from 7.8e-2 to
// 5.1e-2 m and turned six of the 400-particle scenes' energy_growth and
// speed rows ok (docs/notes/work-precision.md, "vbd"); the better of the two
// takes it to 7.9e-4 m (docs/model.md §10). A J_p whose determinant is
// negligible leaves p unchanged in that sweep, as Warp's VBD does
// (warp/sim/integrator_vbd.py, `if abs(wp.determinant(h)) > 1e-5`).
//
// Contacts: the implicit methods' velocity filter (solver/contact.h,
// ObstacleResponse::kVelocityFilter): each contact's normal velocity is
// held at its (4.4) target in every iterate, its particle's local step
// solves only the tangential directions, friction is explicit, and the
// constraint impulses after the sweeps decide release. The fixed point is
// implicit Euler's with the same contacts (the paper's own contacts are
// penalty energies inside the iterations; this model's contact is the
// thesis' non-penetration constraint, docs/model.md §10). Fixed particles
// have v = 0.
//
// Self-contact (`[collision] self = true`): the paper's penalty energy on
// point–triangle and edge–edge pairs inside the local steps, each
// particle's iterate truncated to the conservative bound around where the
// pairs were last detected, and a new detection after a sweep that
// truncated one (peers/position_contacts.h, VbdSelfContact). The penalty
// reads the positions at its colour's start, so a sweep is the same for
// any thread count.
#ifndef CLOTHBENCH_PEERS_VBD_H_
#define CLOTHBENCH_PEERS_VBD_H_

#include <optional>
#include <string_view>
#include <vector>

#include "model/particle_system.h"
#include "peers/iterated.h"
#include "peers/position_contacts.h"
#include "solver/integrator.h"

namespace clothbench {

/// The integrator name used by the executables and result files.
inline constexpr std::string_view kVbdName = "vbd";

/// Vertex Block Descent with a fixed number of iterations (sweeps over all
/// colours) per step (peers/iterated.h: the step, Chebyshev and the
/// obstacles). The particles of a colour run on the OpenMP threads; each
/// writes only its own row, so a step is bit-identical for any thread
/// count. No allocation in a step.
class VertexBlockDescent : public IteratedStepper {
 public:
  /// Colours the particle graph (ParticleSystem::ParticleGraph) greedily in
  /// particle order, once.
  /// @param system the model (must outlive the stepper)
  /// @param iterations k ≥ 1 sweeps per step
  /// @param chebyshev acceleration (off: plain VBD)
  /// @throws std::invalid_argument if iterations < 1 or the Chebyshev
  ///   settings are outside their ranges
  VertexBlockDescent(const ParticleSystem& system, int iterations, ChebyshevSettings chebyshev = {});

  int matrix_rebuilds() const override { return 0; }
  void Reset(double t, const MatrixN3& x, const MatrixN3& v) override;
  /// IteratedStepper::Step, counting the step for its self-contact.
  StepStats Step(double h) override;
  const SelfContactStats* own_self_contact() const override { return self_ ? &self_->stats() : nullptr; }
  /// The colouring and the ρ measurements [s].
  double setup_seconds() const override { return colouring_seconds_ + rho_seconds(); }
  /// The number of colours of the particle graph (free particles only).
  int colours() const { return static_cast<int>(colour_start_.size()) - 1; }
  /// The most plain sweeps from which ρ is measured (KrylovRho over
  /// RhoSweeps sweeps, a tenth of the run's, at the first step of each h
  /// when ChebyshevSettings::rho is 0 and a step extrapolates at all).
  /// Gauss–Seidel's slowest mode dominates the increments' ratio only
  /// after many sweeps (on the default scene at h = 0.01 s, 32 / 128 / 512
  /// / 1024 sweeps from rest give 0.838 / 0.9784 / 0.9840 / 0.9842); the
  /// Krylov estimate gives 0.9762 / 0.9842 / 0.9841 at 32 / 128 / 512. At
  /// 10⁴ particles the slowest modes lie within 1e-4 of 1 and neither
  /// settles in an affordable count (increment ratio at 512: 0.9983;
  /// Krylov at 96 / 256 / 512: 0.9981 / 0.9994 / 0.9997). The accelerated
  /// iteration is sensitive to ρ (default scene, 64 sweeps per step, ρ =
  /// 0.9802: 2.6e-4 m from implicit_euler/newton after 0.5 s; 0.9828:
  /// 1.1e-4 m; 0.9840: 6.4e-5 m), so a run with more sweeps gets a longer
  /// measurement (docs/notes/work-precision.md, "vbd").
  static constexpr int kRhoIterations = 128;
  /// A colour runs on the OpenMP threads from this many particles up: a
  /// particle's local step costs about 0.55 µs (bench_kernels,
  /// BM_ParticleForces), so 256 of them are ~0.14 ms, far above the few µs
  /// of a parallel region.
  static constexpr int kParallelColour = 256;

 private:
  void Iteration(double h) override;
  /// Self-contact: the detection at the step's start and the first iterate's bound.
  void BeginIterations(double h) override;
  /// Self-contact: every particle within its bound; a new detection if one was not.
  void AfterIteration(double h) override;
  // One local Newton step of particle p at t₁ (reads x_, v_; writes row p).
  void Relax(double t1, double h, int p);
  double colouring_seconds_ = 0.0;
  // Free particles by colour: colour c is order_[colour_start_[c] … colour_start_[c + 1]).
  std::vector<int> order_, colour_start_;
  std::optional<VbdSelfContact> self_;  // `[collision] self = true`
  MatrixN3 x_colour_;                   // self-contact: the positions at a colour's start (its contacts read them)
  std::vector<char> truncated_;         // self-contact: per particle, truncated in this iteration
  MatrixN3 x_split_, v_split_;          // self-contact with moving fixed particles: the state before a split step
  /// The pieces a step of h [s] takes so that no moving fixed particle
  /// (`[[constraints.motion]]`) moves beyond its bound in one piece: 1, 2,
  /// 4, … up to kMaxSplit (detects the pairs at x₀).
  int KinematicSplit(double h);
  bool start_detected_ = false;  // KinematicSplit's detection at x₀ serves the next BeginIterations
  static constexpr int kMaxSplit = 64;
  // Moves particle p's iterate v_p back within its bound; true if it did.
  bool Bound(double h, int p, Vector3* vp);
};

/// vbd/chebyshev's acceleration, with ρ measured in each run at the first
/// step of each h (KrylovRho over a tenth of the run's sweeps, at most
/// VertexBlockDescent::kRhoIterations = 128; 0.9788 from 40 on the default
/// scene at h = 0.01 s with 4 sweeps per step; the settings below were
/// chosen with the ratio of 512 plain increments, 0.9840 there). The paper's schedule (Chen
/// et al. 2024, §3.8: γ = 1, ω leaves 1 at the second sweep) diverges there
/// with 4 sweeps per step (rms difference to implicit_euler/newton after
/// 0.5 s: 1.3e21 m; 4.2e-2 and 3.0e-4 m with 16 and 64 sweeps; ρ from 128
/// sweeps and the inertial first iterate), and so does ρ = 0.99 with it at
/// 16 and 64; pd/chebyshev's γ = 0.9 and delay 2 give 2.5e-1, 1.7e-2,
/// 6.4e-5 m at 4, 16, 64 sweeps with the adaptive first iterate and ρ from
/// 512 sweeps, falling at every count (plain VBD: 3.0e-1, 1.9e-1, 5.1e-2 m;
/// test VertexBlockDescent.ConvergesToImplicitEulerWithTheIterations).
/// γ = 1 with delay 2 reached 3.5e-5 m at 64 there; not adopted, as it was
/// measured on this one scene only. Without a restart the schedule lets
/// Gauss–Seidel's complex modes grow: a tilted 15×12 sheet (verify/vbd_test.cc)
/// blows up at 4–6 sweeps per step, and the hanging sheet goes from 1.1e-3
/// m at 128 sweeps to 5.1e-3 m at 256; with the adaptive restart
/// (ChebyshevSettings::restart) no count from 1 to 256 fails on the tilted,
/// swinging and hanging sheets, the distance falls from 16 sweeps on, and
/// the default scene's 64-sweep distance is unchanged (6.4e-5 m;
/// docs/model.md §10).
inline constexpr ChebyshevSettings kVbdChebyshev{
    .on = true, .rho = 0.0, .gamma = 0.9, .delay = 2, .restart = true};

}  // namespace clothbench

#endif  // CLOTHBENCH_PEERS_VBD_H_
