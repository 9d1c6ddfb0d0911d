// Projective dynamics' own contact (Ly, Jouve, Bertails-Descoubes 2020,
// "Projective dynamics with dry frictional contact", ACM TOG 39(4) 57;
// docs/model.md §10): contact impulses in the global step's right-hand
// side, each refined in the local step, so the prefactored matrix stays.
//
// The global step solves A v = b + R with A = M + h² L_K + h L_D and R =
// Σ_c J_cᵀ r_c the contact impulses [kg m/s]. Ly et al. split A into a
// diagonal and a positive semi-definite part and predict, from the current
// iterate v^k and the impulses r^k of the last global step, the velocity
// the next global step gives:
//   v̂ = v^k + D⁻¹ (b + R^k − A v^k),
// then refine every contact alone on u_c = J_c v̂ + W_c (r_c − r_c^k),
// W_c = J_c D⁻¹ J_cᵀ. Here D = M: A − M = h² L_K + h L_D is positive
// semi-definite, so W_c bounds the contact's true compliance J_c A⁻¹ J_cᵀ
// from above and the refinement r ← r + (target − u)/W_c never
// overshoots it. The fixed point of the iteration is implicit Euler
// with Signorini's condition and Coulomb friction at every listed contact.
//  - Obstacles (ObstacleDetection, collision/obstacle_contacts.h, from the
//    step's start): particle p against the nearest obstacle along its
//    collision direction D, d(x₁) ≥ δ linearised,
//      ⟨v₁ − v_obs, D⟩ ≥ (δ − d)/h,
//    with Coulomb friction μ = c_f against the velocity relative to the
//    obstacle. W = 1/m_p I: the local Signorini–Coulomb problem is solved
//    exactly (r_N = max(0, ·), then r_T projected onto the disc μ r_N).
//  - Self-contact (`[collision] self = true`): every point–triangle and
//    edge–edge pair the broad phase finds over the predicted path
//    x₀ → x₀ + h v⁰ (collision/self_contact.h) within δ plus a skin and
//    the predicted motion of its particles, as
//    the inequality ⟨n, Σ_k w_k x_k(t₁)⟩ ≥ δ on its closest points' weights
//    w and normal n at x₀, linearised like the obstacles', frictionless.
//    Pairs share particles, so W_c = Σ_k w_k² c_k/m_k with c_k the pairs
//    of particle k: the Jacobi sweep over all pairs is then a convergent
//    splitting (Cauchy–Schwarz: J M⁻¹ Jᵀ ≤ diag(W_c)).
// A particle the list missed (it left the predicted path) and a listed one
// whose impulse, short of converging in the step's iterations, let it end
// inside the obstacle (d < 0) are projected after the step
// (peers/position_contacts.h, ProjectOntoObstacles), and a
// pair by the run's self-contact response (collision/self_contact_response.h):
// the fail-safes, whose counts say how often they acted.
#ifndef CLOTHBENCH_PEERS_CONTACT_IMPULSES_H_
#define CLOTHBENCH_PEERS_CONTACT_IMPULSES_H_

#include <optional>
#include <vector>

#include "collision/obstacle_contacts.h"
#include "collision/self_contact.h"
#include "collision/self_contact_response.h"
#include "model/particle_system.h"
#include "solver/contact.h"

namespace clothbench {

class ContactImpulses {
 public:
  /// @param system the model (obstacles, `[collision]`; must outlive this)
  /// @param w inverse masses [1/kg], 0 for fixed particles (never in a contact)
  ContactImpulses(const ParticleSystem& system, const Eigen::VectorXd& w);

  /// Whether `system` has obstacles or self-contact (`[collision] self =
  /// true`): otherwise nothing here acts.
  static bool Acts(const ParticleSystem& system) {
    const auto& collision = system.scene().collision;
    return !system.obstacles().empty() || (collision && collision->self);
  }
  bool active() const { return obstacles_ || self_; }
  /// Whether the scene asks for self-contact (the pairs are listed).
  bool self_contact() const { return self_; }
  /// Forgets the last step (a new run); the work restarts.
  void Reset();

  /// The contact list of a step of h [s] from t0 [s] at x0 (N×3 [m]) with
  /// the first iterate v_guess (N×3 [m/s]): the obstacle contacts (test 3
  /// along v_guess; x_prev: positions one step earlier, for the tunnelling
  /// test, or nullptr), and the self-contact pairs over x₀ → x₀ + h v_guess,
  /// sorted. No allocation once the lists reached their size.
  /// @return the listed obstacle contacts
  int BeginStep(double t0, double h, const MatrixN3& x0, const MatrixN3& v_guess, const MatrixN3* x_prev);
  /// Starts a step's iterations: every impulse 0.
  void BeginIterations();
  /// One local step of the contacts: from the iterate v (N×3 [m/s], the
  /// last global step's, which the impulses in effect produced), refines
  /// every impulse and adds R = Σ J_cᵀ r_c to the contact-free right-hand
  /// side *b (N×3 [kg m/s]).
  void Refine(const MatrixN3& v, MatrixN3* b);
  /// After the step (v0, v1 N×3 [m/s] at its ends): adds the impulses'
  /// work ⟨J_cᵀ r_c, (v₀ + v₁)/2⟩ to work() (normal part: holding, tangential:
  /// friction) and keeps the holding contacts for the next detection.
  /// @return the contacts whose impulse is not 0 (obstacles and pairs)
  int EndStep(const MatrixN3& v0, const MatrixN3& v1);
  /// Per particle, whether it is in the step's obstacle list (the fail-safe
  /// projection leaves these to the impulses unless they end inside).
  const std::vector<char>& listed() const { return listed_; }

  /// Work of the impulses since Reset [J], and of the fail-safe projection
  /// (AddFailSafeWork), for the energy balance.
  const ContactResponse::Work& work() const { return work_; }
  /// Adds the fail-safe projection's work [J] (½ m (|v₁|² − |v|²) of each
  /// particle it moved: its impulse m (v₁ − v) over the mean velocity).
  void AddFailSafeWork(double work) { work_.holding += work; }
  /// The self-contact counters since Reset: steps, broad_phases, candidates
  /// (the pairs listed, of those the broad phase reported), pair_impulses (the pairs holding an impulse at a
  /// step's end), detection_seconds (the list) and response_seconds (the
  /// local steps of the pairs).
  const SelfContactStats& self_stats() const { return self_stats_; }

  /// The skin of the self-contact list beyond δ and the predicted motion,
  /// as a fraction of the grid spacing (a quarter of the spacing listed as
  /// many pairs on the premise scenes and changed no crossing count).
  static constexpr double kSkinFraction = 0.05;

 private:
  struct NodeContact {
    int particle;
    int obstacle;
    Vector3 normal;
    double target_n;    // ⟨v_obs, D⟩ + (δ − d)/h [m/s]
    Vector3 v_obstacle;  // [m/s]
    double mu;
    Vector3 r;  // impulse [kg m/s]
  };
  struct PairContact {
    SelfContactPair pair;
    std::array<double, 4> w;
    Vector3 n;
    double target;  // (δ − gap)/h [m/s]
    double compliance;  // W_c [1/kg]
    double r;  // normal impulse [kg m/s]
  };

  const ParticleSystem& sys_;
  Eigen::VectorXd w_;
  bool obstacles_ = false, self_ = false;
  std::optional<ObstacleDetection> detection_;
  std::vector<NodeContact> nodes_;
  std::vector<ObstacleDetection::Prior> prior_;  // per particle: the last step's holding contact
  std::vector<char> listed_;
  double thickness_ = 0.0, skin_ = 0.0;
  std::optional<SelfContactDetector> detector_;
  std::vector<SelfContactPair> candidates_;
  std::vector<PairContact> pairs_;
  std::vector<int> pair_count_;  // per particle: the pairs it belongs to
  std::vector<double> motion_;   // per particle: |x_end − x₀| [m]
  std::vector<PairGeometry> geometry_;  // per candidate: its closest points at x₀
  std::vector<char> listed_pair_;       // per candidate: listed
  std::vector<int> touched_;     // particles of the listed pairs and contacts (each once)
  std::vector<char> marked_;     // per particle: in touched_
  MatrixN3 impulse_, x_end_;     // R = Σ J_cᵀ r_c; the predicted end positions
  ContactResponse::Work work_;
  SelfContactStats self_stats_;
};

}  // namespace clothbench

#endif  // CLOTHBENCH_PEERS_CONTACT_IMPULSES_H_
