// Self-contact on the premise scenes scenes/fold_over_rod.toml and
// scenes/pile_on_floor.toml (docs/notes/collisions.md, "Self-contact"): without a
// response the cloth passes through itself; with it no stored frame of a
// supporting method has a crossing triangle pair, at the scene's h and at
// h/4 (XPBD and VBD with their own, peers/position_contacts.h); runs
// repeat bit for bit on 1 and 2 threads; a method without self-contact is
// refused.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <memory>
#include <string>

#include <omp.h>

#include "model/particle_system.h"
#include "model/scene.h"
#include "peers/baraff_witkin.h"
#include "peers/projective_dynamics.h"
#include "peers/vbd.h"
#include "peers/xpbd.h"
#include "reference/cvode_reference.h"
#include "reference/ida_reference.h"
#include "solver/integrator.h"
#include "solver/run.h"

namespace clothbench {
namespace {

// A premise scene, with or without its self-contact response, to t_end [s].
Scene Premise(const std::string& name, double t_end, bool self) {
  Scene s = LoadScene(std::string(CLOTHBENCH_SCENES_DIR) + "/" + name + ".toml");
  s.t_end = t_end;
  s.collision->self = self;
  return s;
}
// fold_over_rod to t = 0.6 s: the halves first swing through each other at
// about t = 0.45 s (230 crossing pairs at 0.5 s without self-contact).
Scene Fold(bool self) { return Premise("fold_over_rod", 0.6, self); }
// pile_on_floor to t = 1 s: folds first cross at about t = 0.5 s (115
// crossing pairs at 0.5 s, 689 at 1 s without self-contact).
Scene Pile(bool self) { return Premise("pile_on_floor", 1.0, self); }

int MostCrossings(const RunSummary& r) {
  const auto& c = r.trajectory.crossing_pairs;
  EXPECT_EQ(c.size(), r.trajectory.times.size());  // every stored frame counted
  return c.empty() ? -1 : *std::max_element(c.begin(), c.end());
}

// Every stored frame of b equals a's, bit for bit.
void ExpectSameFrames(const RunSummary& a, const RunSummary& b) {
  ASSERT_EQ(b.trajectory.positions.size(), a.trajectory.positions.size());
  for (std::size_t k = 0; k < a.trajectory.positions.size(); ++k)
    EXPECT_TRUE(b.trajectory.positions[k] == a.trajectory.positions[k]) << "frame " << k;
}

TEST(SelfContactScene, WithoutSelfContactTheClothPassesThroughItself) {
  for (const Scene& s : {Fold(false), Pile(false)}) {
    const ParticleSystem sys(s);
    const RunSummary r = RunIntegrator(sys, Method::kSbdf2, {s.h, s.t_end, s.frame_dt});
    ASSERT_EQ(r.status, RunStatus::kOk) << s.name << ": " << r.message;
    EXPECT_GT(MostCrossings(r), 50) << s.name;
    EXPECT_FALSE(r.self_contact.has_value());
  }
}

struct MethodCase {
  bool pile;  // pile_on_floor, else fold_over_rod
  Method method;
  double fraction;  // of the scene's h
};

class SelfContactMethods : public ::testing::TestWithParam<MethodCase> {};

TEST_P(SelfContactMethods, NoFrameCrossesAtHAndAtAQuarterOfH) {
  const auto [pile, method, fraction] = GetParam();
  const Scene s = pile ? Pile(true) : Fold(true);
  const ParticleSystem sys(s);
  const RunSummary r = RunIntegrator(sys, method, {fraction * s.h, s.t_end, s.frame_dt});
  ASSERT_EQ(r.status, RunStatus::kOk) << r.message;
  EXPECT_EQ(MostCrossings(r), 0);
  ASSERT_TRUE(r.self_contact.has_value());
  EXPECT_GT(r.self_contact->repulsions + r.self_contact->collisions, 0);
  // Each self-contact work series value is the response's count at its frame.
  EXPECT_EQ(r.trajectory.contact_work_self.size(), r.trajectory.times.size());
}

INSTANTIATE_TEST_SUITE_P(Premises, SelfContactMethods,
                         ::testing::Values(MethodCase{false, Method::kSbdf2, 1.0}, MethodCase{false, Method::kSbdf2, 0.25},
                                           MethodCase{false, Method::kBdf2, 1.0}, MethodCase{false, Method::kBdf2, 0.25},
                                           MethodCase{false, Method::kImplicitEuler, 1.0},
                                           MethodCase{false, Method::kImplicitMidpoint, 1.0},
                                           MethodCase{true, Method::kSbdf2, 1.0}, MethodCase{true, Method::kSbdf2, 0.25},
                                           MethodCase{true, Method::kBdf2, 1.0}),
                         [](const ::testing::TestParamInfo<MethodCase>& param_info) {
                           return std::string(param_info.param.pile ? "pile_" : "fold_") +
                                  std::string(ToString(param_info.param.method)) +
                                  (param_info.param.fraction == 1.0 ? "_h" : "_quarter_h");
                         });

TEST(SelfContactScene, BaraffWitkinHasNoCrossingEither) {
  const Scene s = Fold(true);
  const ParticleSystem sys(s);
  BaraffWitkin bw(sys, s.solver);
  const RunSummary r = RunStepper(sys, bw, {s.h, s.t_end, s.frame_dt});
  ASSERT_EQ(r.status, RunStatus::kOk) << r.message;
  EXPECT_EQ(MostCrossings(r), 0);
}

TEST(SelfContactScene, RepeatsBitForBitOnOneAndTwoThreads) {
  const Scene s = Fold(true);
  const ParticleSystem sys(s);
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const RunSummary a = RunIntegrator(sys, Method::kSbdf2, {s.h, s.t_end, s.frame_dt});
  const RunSummary b = RunIntegrator(sys, Method::kSbdf2, {s.h, s.t_end, s.frame_dt});
  omp_set_num_threads(2);
  const RunSummary c = RunIntegrator(sys, Method::kSbdf2, {s.h, s.t_end, s.frame_dt});
  omp_set_num_threads(threads);
  ASSERT_EQ(a.status, RunStatus::kOk) << a.message;
  for (const RunSummary* other : {&b, &c}) {
    ExpectSameFrames(a, *other);
    EXPECT_EQ(other->self_contact->collisions, a.self_contact->collisions);
    EXPECT_EQ(other->self_contact->repulsions, a.self_contact->repulsions);
  }
}

// A stepper that says it takes corrections and drops them: its steps
// cross as without a response, and the first crossing frame ends the run.
class DropsCorrections : public StepEngine {
 public:
  using StepEngine::StepEngine;
  void CorrectState(const MatrixN3& x, const MatrixN3& v) override {
    (void)x;
    (void)v;
  }
};

TEST(SelfContactScene, ACrossingFrameEndsTheRunWithSelfIntersection) {
  const Scene s = Fold(true);
  const ParticleSystem sys(s);
  DropsCorrections engine(sys, Method::kSbdf2, s.solver);
  const RunSummary r = RunStepper(sys, engine, {s.h, s.t_end, s.frame_dt});
  EXPECT_EQ(r.status, RunStatus::kSelfIntersection);
  EXPECT_NE(r.message.find("crosses itself at t = "), std::string::npos) << r.message;
  const auto& c = r.trajectory.crossing_pairs;
  ASSERT_EQ(c.size(), r.trajectory.times.size());
  // The crossing frame is kept, and it is the only one that crosses.
  EXPECT_GT(c.back(), 0);
  EXPECT_EQ(std::count_if(c.begin(), c.end(), [](int32_t n) { return n > 0; }), 1);
  EXPECT_LT(r.trajectory.times.back(), s.t_end);
}

// The peers' own self-contact. XPBD: constraints in every substep; at 16
// substeps (Δt = 0.31 ms) the fold has no crossing at h and h/4, and on
// the pile, where layers land on each other at up to 3 m/s, 4 substeps
// (Δt = 1.25 ms) suffice at h; one substep of 5 ms is not asserted: the
// pile crosses there (docs/notes/collisions.md, "Self-contact"). VBD: the
// penalty in its local steps within the conservative bounds, at one and
// four sweeps per step, h and h/4. PD: the run's response after its step.
struct PeerCase {
  enum Peer { kXpbd, kVbd, kPd } peer;
  bool pile;        // else the fold
  int updates;      // XPBD's substeps, VBD's sweeps per step
  double fraction;  // of the scene's h
};

class SelfContactPeers : public ::testing::TestWithParam<PeerCase> {};

TEST_P(SelfContactPeers, NoFrameCrosses) {
  const auto [peer, pile, updates, fraction] = GetParam();
  const Scene s = pile ? Pile(true) : Fold(true);
  const ParticleSystem sys(s);
  std::unique_ptr<Stepper> stepper;
  if (peer == PeerCase::kVbd)
    stepper = std::make_unique<VertexBlockDescent>(sys, updates);
  else if (peer == PeerCase::kPd)
    stepper = std::make_unique<ProjectiveDynamics>(sys, s.solver, updates);
  else
    stepper = std::make_unique<Xpbd>(sys, updates);
  const RunSummary r = RunStepper(sys, *stepper, {fraction * s.h, s.t_end, s.frame_dt});
  ASSERT_EQ(r.status, RunStatus::kOk) << r.message;
  EXPECT_EQ(MostCrossings(r), 0);
  ASSERT_TRUE(r.self_contact.has_value());
  // Detected: the list kept over steps (collision/self_contact_list.h) is
  // built at least once, and then again only as the cloth moves.
  EXPECT_GE(r.self_contact->broad_phases, 1);
  if (peer == PeerCase::kPd) {  // its own impulses acted; the fail-safe response's work is counted
    // On the fold at the scene's h, 4 iterations leave the halves apart to
    // t = 0.6 s (measured: no pair within δ at a step's end, and the
    // response acts neither); at h/4 and on the pile the cloth touches itself.
    if (pile || fraction < 1.0) {
      EXPECT_GT(r.self_contact->pair_impulses, 0);
    }
    EXPECT_EQ(r.trajectory.contact_work_self.size(), r.trajectory.times.size());
    return;
  }
  if (peer == PeerCase::kXpbd) {
    EXPECT_GT(r.self_contact->projections, 0);  // the constraints acted
  }
  EXPECT_EQ(r.self_contact->repulsions + r.self_contact->collisions, 0);   // not the response's impulses
  EXPECT_TRUE(r.trajectory.contact_work_self.empty());                     // its work is not counted
}

INSTANTIATE_TEST_SUITE_P(
    Premises, SelfContactPeers,
    ::testing::Values(PeerCase{PeerCase::kXpbd, false, 16, 1.0}, PeerCase{PeerCase::kXpbd, false, 16, 0.25},
                      PeerCase{PeerCase::kXpbd, true, 4, 1.0}, PeerCase{PeerCase::kVbd, false, 1, 1.0},
                      PeerCase{PeerCase::kVbd, false, 4, 0.25}, PeerCase{PeerCase::kVbd, true, 1, 1.0},
                      PeerCase{PeerCase::kVbd, true, 4, 1.0}, PeerCase{PeerCase::kVbd, true, 1, 0.25},
                      PeerCase{PeerCase::kPd, false, 4, 1.0}, PeerCase{PeerCase::kPd, false, 4, 0.25},
                      PeerCase{PeerCase::kPd, true, 16, 1.0}, PeerCase{PeerCase::kPd, true, 4, 0.25}),
    [](const ::testing::TestParamInfo<PeerCase>& c) {
      const char* name = c.param.peer == PeerCase::kXpbd ? "xpbd_" : c.param.peer == PeerCase::kVbd ? "vbd_" : "pd_";
      return std::string(name) + (c.param.pile ? "pile_" : "fold_") +
             std::to_string(c.param.updates) + (c.param.fraction == 1.0 ? "_h" : "_quarter_h");
    });

// The runs of the stepper `make(sys)` builds over `options`, on 1 and on 2
// threads; both have the same frames.
template <class Make>
std::array<RunSummary, 2> OnOneAndTwoThreads(const ParticleSystem& sys, const RunOptions& options, Make make) {
  const int threads = omp_get_max_threads();
  std::array<RunSummary, 2> r;
  for (int k = 0; k < 2; ++k) {
    omp_set_num_threads(k + 1);
    auto stepper = make(sys);
    r[static_cast<std::size_t>(k)] = RunStepper(sys, *stepper, options);
  }
  omp_set_num_threads(threads);
  ExpectSameFrames(r[0], r[1]);
  return r;
}

TEST(SelfContactScene, XpbdRepeatsBitForBitOnOneAndTwoThreads) {
  const Scene s = Fold(true);
  const ParticleSystem sys(s);
  const auto r = OnOneAndTwoThreads(sys, {s.h, s.t_end, s.frame_dt},
                                    [](const ParticleSystem& p) { return std::make_unique<Xpbd>(p, 4); });
  ASSERT_EQ(r[0].status, RunStatus::kOk) << r[0].message;
  ASSERT_TRUE(r[0].self_contact && r[1].self_contact);
  EXPECT_EQ(r[1].self_contact->projections, r[0].self_contact->projections);
}

// Projective dynamics' impulses (a Jacobi sweep over sorted lists, serial)
// and its CHOLMOD solves: the same frames on 1 and 2 threads, on the fold
// at h/4 to t = 0.5 s, after its halves met (pairs hold impulses).
TEST(SelfContactScene, PdRepeatsBitForBitOnOneAndTwoThreads) {
  const Scene s = Fold(true);
  const ParticleSystem sys(s);
  const auto r = OnOneAndTwoThreads(sys, {0.25 * s.h, 0.5, s.frame_dt}, [&](const ParticleSystem& p) {
    return std::make_unique<ProjectiveDynamics>(p, s.solver, 4);
  });
  ASSERT_EQ(r[0].status, RunStatus::kOk) << r[0].message;
  ASSERT_TRUE(r[0].self_contact && r[1].self_contact);
  EXPECT_GT(r[0].self_contact->pair_impulses, 0);
  EXPECT_EQ(r[1].self_contact->pair_impulses, r[0].self_contact->pair_impulses);
  EXPECT_EQ(r[1].self_contact->repulsions, r[0].self_contact->repulsions);
}

// The SUNDIALS rows take the response at the end of every internal step
// and restart from a corrected state (sundials/sundials_common.h,
// RunFrames): the fold's halves meet (t ≈ 0.45 s) and no stored frame
// crosses, where SBDF(2) without self-contact has up to 230 crossing pairs.
TEST(SelfContactScene, TheSundialsRowsCorrectTheirStepsAndDoNotCross) {
  const Scene s = Fold(true);
  const ParticleSystem sys(s);
  // CVODE with the reduced solve (5.5 s on a busy 2-core machine; RunIda,
  // with KLU, took ~90 s here: the ida rows are measured in
  // docs/notes/collisions.md, "Self-contact under SUNDIALS", instead).
  const ReferenceOptions o{1e-3, 1e-3, 5, s.t_end, s.frame_dt};
  const RunSummary r = RunCvodeReduced(sys, o, s.solver);
  std::printf("[ self contact ] cvode on fold_over_rod: %ld steps, %.2f s\n", r.steps, r.solver_time_s);
  ASSERT_EQ(r.status, RunStatus::kOk) << r.message;
  EXPECT_EQ(MostCrossings(r), 0);
  ASSERT_TRUE(r.self_contact.has_value());
  EXPECT_GT(r.self_contact->repulsions + r.self_contact->collisions, 0);
  EXPECT_EQ(r.self_contact->steps, r.steps);  // every internal step corrected
}

// IDA restarts after every correction from its own first-step estimate,
// at most 0.001 |tout − t|: with tout = t_end its steps crept to t_end,
// each 0.001 of the time left (fold_over_rod to t_end = 0.5 s: 13,809 of
// 24,915 steps in the last 1e-6 s, the last ones 1e-15 s;
// docs/notes/collisions.md, "Self-contact under SUNDIALS"). Its smallest
// step is now 1.8e-5 s at rtol 1e-3: a floor of 1e-9 s leaves four orders
// of margin and fails at any return of the creep.
TEST(SelfContactScene, IdaDoesNotCreepToTheEnd) {
  Scene s = Fold(true);
  s.t_end = 0.5;
  const ParticleSystem sys(s);
  const ReferenceOptions o{1e-3, 1e-3, 5, s.t_end, s.frame_dt};
  const RunSummary r = RunIdaReduced(sys, o, s.solver);
  std::printf("[ self contact ] ida on fold_over_rod to 0.5 s: %ld steps, %.2f s\n", r.steps, r.solver_time_s);
  ASSERT_EQ(r.status, RunStatus::kOk) << r.message;
  EXPECT_EQ(MostCrossings(r), 0);
  double smallest = s.t_end;
  for (const StepStats& st : r.step_stats) smallest = std::min(smallest, st.h);
  EXPECT_GT(smallest, 1e-9);
}

// A stepper that neither corrects its state nor has self-contact of its own.
class NoSelfContact : public StepEngine {
 public:
  using StepEngine::StepEngine;
  bool corrects_state() const override { return false; }
};

TEST(SelfContactScene, AMethodWithoutSelfContactIsRefused) {
  const Scene s = Fold(true);
  const ParticleSystem sys(s);
  NoSelfContact engine(sys, Method::kSbdf2, s.solver);
  const RunSummary r = RunStepper(sys, engine, {s.h, s.t_end, s.frame_dt});
  EXPECT_EQ(r.status, RunStatus::kUnsupportedScene);
  EXPECT_NE(r.message.find("collision.self"), std::string::npos) << r.message;
  EXPECT_EQ(r.steps, 0);
}

}  // namespace
}  // namespace clothbench
