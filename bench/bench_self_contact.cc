// Microbenchmarks of the self-contact detection and response
// (collision/self_contact.h, self_contact_response.h; docs/notes/collisions.md,
// "Self-contact"): the broad phase (CGAL's box_intersection_d) and one
// response to a step, on a 0.6 m sheet of side×side particles (spacing l)
// folded into a hairpin whose two layers are 0.3 l apart and each move
// 0.2 l toward the other over the step of 5 ms (so that they cross without
// a response), with a thickness of 0.1 l.
//
//   build/bench/bench_self_contact [--benchmark_filter=REGEX]
#include <cmath>
#include <numbers>

#include <benchmark/benchmark.h>

#include "collision/self_contact_response.h"
#include "collision/edge_projection.h"
#include "model/particle_system.h"

namespace clothbench {
namespace {

constexpr double kSheet = 0.6, kStep = 0.005;
double Spacing(int side) { return kSheet / (side - 1); }
double Thickness(int side) { return 0.1 * Spacing(side); }

Scene FoldScene(int side) {
  Scene s = DefaultScene();
  s.grid.nu = s.grid.nv = side;
  s.grid.size = {kSheet, kSheet};
  s.fixed.clear();
  s.fixed_specs.clear();
  s.collision = SelfCollisionSpec{true, Thickness(side)};
  return s;
}

// The sheet along v bent into a hairpin: down one layer, a half circle of
// diameter kGap, up the other; the layers close at kClosing over the step.
void Hairpin(const ParticleSystem& sys, MatrixN3* x0, MatrixN3* x1) {
  const Scene& s = sys.scene();
  const int side = s.grid.nu;
  const double radius = 0.15 * Spacing(side), move = 0.2 * Spacing(side), arc = std::numbers::pi * radius, leg = 0.5 * (kSheet - arc);
  x0->resize(sys.num_particles(), 3);
  x1->resize(sys.num_particles(), 3);
  for (int j = 0; j < s.grid.nv; ++j) {
    const double along = kSheet * j / (s.grid.nv - 1);
    double y = 0.0, z = 0.0, layer = 0.0;
    if (along < leg) {
      y = -radius, z = -(leg - along), layer = 1.0;
    } else if (along < leg + arc) {
      const double a = (along - leg) / radius;
      y = -radius * std::cos(a), z = radius * std::sin(a);
    } else {
      y = radius, z = -(along - leg - arc), layer = -1.0;
    }
    for (int i = 0; i < s.grid.nu; ++i) {
      const int p = s.Index(i, j);
      x0->row(p) << kSheet * i / (s.grid.nu - 1), y, z;
      x1->row(p) = x0->row(p);
      (*x1)(p, 1) += layer * move;
    }
  }
}

void BM_BroadPhase(benchmark::State& state) {
  const int side = static_cast<int>(state.range(0));
  const ParticleSystem sys(FoldScene(side));
  MatrixN3 x0, x1;
  Hairpin(sys, &x0, &x1);
  SelfContactDetector detector(GridTriangles(sys.scene().grid.nu, sys.scene().grid.nv).vertices, sys.num_particles());
  std::vector<SelfContactPair> pairs;
  for (auto _ : state) {
    detector.Candidates(x0, x1, 2.0 * Thickness(side), &pairs);
    benchmark::DoNotOptimize(pairs.data());
  }
  state.counters["particles"] = sys.num_particles();
  state.counters["candidates"] = static_cast<double>(pairs.size());
}
BENCHMARK(BM_BroadPhase)->ArgName("side")->Arg(32)->Arg(100)->Arg(316)->Unit(benchmark::kMillisecond);

void BM_Respond(benchmark::State& state) {
  const int side = static_cast<int>(state.range(0));
  const ParticleSystem sys(FoldScene(side));
  MatrixN3 x0, x1;
  Hairpin(sys, &x0, &x1);
  SelfContactResponse response(sys, Thickness(side));
  const MatrixN3 v1 = (x1 - x0) / kStep;
  MatrixN3 x, v;
  for (auto _ : state) {
    x = x1;
    v = v1;
    response.Respond(kStep, x0, &x, &v);
    benchmark::DoNotOptimize(x.data());
  }
  const SelfContactStats& st = response.stats();
  state.counters["particles"] = sys.num_particles();
  state.counters["detection_share"] = st.detection_seconds / (st.detection_seconds + st.response_seconds);
  const double steps = static_cast<double>(st.steps);
  state.counters["collisions_per_step"] = static_cast<double>(st.collisions) / steps;
  state.counters["broad_phases_per_step"] = static_cast<double>(st.broad_phases) / steps;
  state.counters["zone_passes_per_step"] = static_cast<double>(st.zone_passes) / steps;
}
BENCHMARK(BM_Respond)->ArgName("side")->Arg(32)->Arg(100)->Arg(316)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace clothbench

BENCHMARK_MAIN();
