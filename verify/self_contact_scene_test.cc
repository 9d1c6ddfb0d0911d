// Self-contact on the premise scenes scenes/fold_over_rod.toml and
// scenes/pile_on_floor.toml (docs/collisions.md, "Self-contact"): without a
// response the cloth passes through itself; with it no stored frame of a
// supporting method has a crossing triangle pair, at the scene's h and at
// h/4; runs repeat bit for bit on 1 and 2 threads; a method without a
// response is refused.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include <omp.h>

#include "model/particle_system.h"
#include "model/scene.h"
#include "peers/baraff_witkin.h"
#include "peers/xpbd.h"
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
                         [](const ::testing::TestParamInfo<MethodCase>& info) {
                           return std::string(info.param.pile ? "pile_" : "fold_") +
                                  std::string(ToString(info.param.method)) +
                                  (info.param.fraction == 1.0 ? "_h" : "_quarter_h");
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
    ASSERT_EQ(other->trajectory.positions.size(), a.trajectory.positions.size());
    for (std::size_t k = 0; k < a.trajectory.positions.size(); ++k)
      EXPECT_TRUE(other->trajectory.positions[k] == a.trajectory.positions[k]) << "frame " << k;
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

TEST(SelfContactScene, AMethodWithoutAResponseIsRefused) {
  const Scene s = Fold(true);
  const ParticleSystem sys(s);
  Xpbd xpbd(sys, 4);
  const RunSummary r = RunStepper(sys, xpbd, {s.h, s.t_end, s.frame_dt});
  EXPECT_EQ(r.status, RunStatus::kUnsupportedScene);
  EXPECT_NE(r.message.find("collision.self"), std::string::npos) << r.message;
  EXPECT_EQ(r.steps, 0);
}

}  // namespace
}  // namespace clothbench
