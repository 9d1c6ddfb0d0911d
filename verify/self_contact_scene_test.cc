// Self-contact on the premise scene scenes/fold_over_rod.toml (docs/
// collisions.md, "Self-contact"): without a response the sheet's halves pass
// through each other; with it no stored frame of a supporting method has a
// crossing triangle pair, at the scene's h and at h/4; runs repeat bit for
// bit on 1 and 2 threads; a method without a response is refused.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include <omp.h>

#include "model/particle_system.h"
#include "model/scene.h"
#include "peers/baraff_witkin.h"
#include "peers/xpbd.h"
#include "solver/run.h"

namespace clothbench {
namespace {

// The scene to t = 0.6 s: the halves first swing through each other at
// about t = 0.45 s (230 crossing pairs at 0.5 s without self-contact).
Scene Fold(bool self) {
  Scene s = LoadScene(std::string(CLOTHBENCH_SCENES_DIR) + "/fold_over_rod.toml");
  s.t_end = 0.6;
  s.collision->self = self;
  return s;
}

int MostCrossings(const RunSummary& r) {
  const auto& c = r.trajectory.crossing_pairs;
  EXPECT_EQ(c.size(), r.trajectory.times.size());  // every stored frame counted
  return c.empty() ? -1 : *std::max_element(c.begin(), c.end());
}

TEST(SelfContactScene, WithoutSelfContactTheHalvesPassThroughEachOther) {
  const Scene s = Fold(false);
  const ParticleSystem sys(s);
  const RunSummary r = RunIntegrator(sys, Method::kSbdf2, {s.h, s.t_end, s.frame_dt});
  ASSERT_EQ(r.status, RunStatus::kOk) << r.message;
  EXPECT_GT(MostCrossings(r), 50);
  EXPECT_FALSE(r.self_contact.has_value());
}

class SelfContactMethods : public ::testing::TestWithParam<std::pair<Method, double>> {};

TEST_P(SelfContactMethods, NoFrameCrossesAtHAndAtAQuarterOfH) {
  const Scene s = Fold(true);
  const ParticleSystem sys(s);
  const auto [method, fraction] = GetParam();
  const RunSummary r = RunIntegrator(sys, method, {fraction * s.h, s.t_end, s.frame_dt});
  ASSERT_EQ(r.status, RunStatus::kOk) << r.message;
  EXPECT_EQ(MostCrossings(r), 0);
  ASSERT_TRUE(r.self_contact.has_value());
  EXPECT_GT(r.self_contact->repulsions + r.self_contact->collisions, 0);
  // Each self-contact work series value is the response's count at its frame.
  EXPECT_EQ(r.trajectory.contact_work_self.size(), r.trajectory.times.size());
}

INSTANTIATE_TEST_SUITE_P(Fold, SelfContactMethods,
                         ::testing::Values(std::pair{Method::kSbdf2, 1.0}, std::pair{Method::kSbdf2, 0.25},
                                           std::pair{Method::kBdf2, 1.0}, std::pair{Method::kBdf2, 0.25},
                                           std::pair{Method::kImplicitEuler, 1.0},
                                           std::pair{Method::kImplicitMidpoint, 1.0}));

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
