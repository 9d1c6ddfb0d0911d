// Microbenchmarks of the kernels of a step (Google Benchmark): explicit
// forces g(t,x,v), one filtered-PCG solve per preconditioner, one step per
// integrator, and the sparse force Jacobian used by CVODE. Sheets of
// side×side particles 0.04 m apart with the default scene's material.
//
//   build/bench/bench_kernels [--benchmark_filter=REGEX]
#include <benchmark/benchmark.h>

#include "model/particle_system.h"
#include "solver/integrator.h"

namespace clothbench {
namespace {

Scene SquareScene(int side) {
  Scene s = DefaultScene();
  s.grid.nu = s.grid.nv = side;
  s.grid.size = {0.04 * (side - 1), 0.04 * (side - 1)};
  s.fixed = {s.Index(0, side - 1), s.Index(side - 1, side - 1)};
  return s;
}

// A deformed, moving state: the sheet after 0.2 s of swinging (BDF(2)).
void SwungState(const ParticleSystem& sys, MatrixN3* x, MatrixN3* v) {
  StepEngine e(sys, Method::kBdf2, sys.scene().solver);
  e.Reset(0.0, sys.rest_positions(), MatrixN3::Zero(sys.num_particles(), 3));
  for (int k = 0; k < 80; ++k) e.Step(0.0025);
  *x = e.x();
  *v = e.v();
}

void BM_ExplicitForces(benchmark::State& state) {
  const ParticleSystem sys(SquareScene(static_cast<int>(state.range(0))));
  MatrixN3 x, v, g(sys.num_particles(), 3);
  SwungState(sys, &x, &v);
  for (auto _ : state) {
    sys.ExplicitForces(0.2, x, v, &g);
    benchmark::DoNotOptimize(g.data());
  }
  state.SetComplexityN(sys.num_particles());
}
BENCHMARK(BM_ExplicitForces)->ArgNames({"side"})->Arg(10)->Arg(20)->Arg(40)->Complexity(benchmark::oN);

void BM_FilteredPcg(benchmark::State& state) {
  const ParticleSystem sys(SquareScene(static_cast<int>(state.range(0))));
  const auto type = static_cast<PreconditionerType>(state.range(1));
  SystemMatrix sm(sys, type);
  sm.Update(0.01);
  MatrixN3 x, v, g(sys.num_particles(), 3), b(sys.num_particles(), 3);
  SwungState(sys, &x, &v);
  sys.ExplicitForces(0.2, x, v, &g);
  b = sys.masses().asDiagonal() * v;
  b += 0.01 * g;
  VelocityFilter filter;
  for (int p : sys.fixed()) filter.Fix(p);
  PcgWorkspace work(sys.num_particles());
  long iterations = 0;
  MatrixN3 sol(sys.num_particles(), 3);
  for (auto _ : state) {
    sol.setZero();
    const PcgSummary s = FilteredPcg(sm.matrix(), b, filter, sm.preconditioner(), {1e-6, 1000}, &sol, &work);
    if (s.status != PcgStatus::kConverged) state.SkipWithError("PCG did not converge");
    iterations += s.iterations;
  }
  state.counters["cg_iters"] = benchmark::Counter(static_cast<double>(iterations), benchmark::Counter::kAvgIterations);
  state.SetLabel(std::string(ToString(type)));
}
BENCHMARK(BM_FilteredPcg)
    ->ArgNames({"side", "precond"})
    ->ArgsProduct({{20, 40}, {static_cast<long>(PreconditionerType::kNone), static_cast<long>(PreconditionerType::kJacobi),
                              static_cast<long>(PreconditionerType::kIc0)}});

void BM_Step(benchmark::State& state) {
  const Scene scene = SquareScene(20);
  const ParticleSystem sys(scene);
  const auto method = static_cast<Method>(state.range(0));
  StepEngine e(sys, method, scene.solver);
  MatrixN3 x, v;
  SwungState(sys, &x, &v);
  e.Reset(0.2, x, v);
  long updates = 0, cg = 0;
  for (auto _ : state) {
    const StepStats st = e.Step(0.0025);
    if (st.status != StepStatus::kOk) state.SkipWithError("step failed");
    updates += st.updates;
    cg += st.cg_iterations;
    if (e.t() > 0.6) {
      state.PauseTiming();
      e.Reset(0.2, x, v);
      state.ResumeTiming();
    }
  }
  state.counters["updates"] = benchmark::Counter(static_cast<double>(updates), benchmark::Counter::kAvgIterations);
  state.counters["cg_iters"] = benchmark::Counter(static_cast<double>(cg), benchmark::Counter::kAvgIterations);
  state.SetLabel(std::string(ToString(method)));
}
BENCHMARK(BM_Step)->ArgName("method")->DenseRange(0, 4);

// Collision detection cost: 0 = no obstacles (an empty list
// allocates no contact state, so detection and the filter rebuild never run:
// the collision-free path), 1 = a plane far below the sheet (detection runs
// every step but never constrains).
void BM_StepObstacles(benchmark::State& state) {
  Scene scene = SquareScene(20);
  if (state.range(0) == 1) {
    ObstacleSpec plane;
    plane.center = Vector3(0.0, 0.0, -100.0);
    scene.obstacles.push_back(plane);
  }
  const ParticleSystem sys(scene);
  StepEngine e(sys, Method::kSbdf2, scene.solver);
  MatrixN3 x, v;
  SwungState(sys, &x, &v);
  e.Reset(0.2, x, v);
  for (auto _ : state) {
    if (e.Step(0.0025).status != StepStatus::kOk) state.SkipWithError("step failed");
    if (e.t() > 0.6) {
      state.PauseTiming();
      e.Reset(0.2, x, v);
      state.ResumeTiming();
    }
  }
  state.SetLabel(state.range(0) == 1 ? "far plane" : "no obstacles");
}
BENCHMARK(BM_StepObstacles)->ArgName("obstacles")->Arg(0)->Arg(1);

void BM_ForceJacobian(benchmark::State& state) {
  const ParticleSystem sys(SquareScene(static_cast<int>(state.range(0))));
  MatrixN3 x, v;
  SwungState(sys, &x, &v);
  std::vector<Triplet> dx, dv;
  for (auto _ : state) {
    dx.clear();
    dv.clear();
    sys.ForceJacobian(0.2, x, v, &dx, &dv);
    benchmark::DoNotOptimize(dx.data());
  }
  state.counters["triplets"] = static_cast<double>(dx.size() + dv.size());
}
BENCHMARK(BM_ForceJacobian)->ArgName("side")->Arg(20);

}  // namespace
}  // namespace clothbench

BENCHMARK_MAIN();
