// Microbenchmarks of the kernels of a step (Google Benchmark): explicit
// forces g(t,x,v), one filtered-PCG solve per preconditioner, one step per
// integrator, the sparse force Jacobian used by CVODE (closed form and the
// AutoDiff oracle), and one refresh of the tangent matrix J_α (Newton,
// Baraff–Witkin). Sheets of side×side particles 0.04 m apart with the
// default scene's material.
//
//   build/bench/bench_kernels [--benchmark_filter=REGEX]
#include <chrono>
#include <cmath>
#include <string>

#include <benchmark/benchmark.h>
#include <Eigen/CholmodSupport>

#include "bench/kernel_scenes.h"
#include "model/particle_system.h"
#include "harness/methods.h"
#include "solver/integrator.h"
#include "solver/tangent.h"

namespace clothbench {
namespace {

Scene SheetOf(const benchmark::State& state) {
  const int side = static_cast<int>(state.range(0));
  return state.range(1) ? SquarePatternScene(side) : SquareScene(side);
}

// g(t, x, v) of `scene`'s sheet at its swung state, timed.
void TimeExplicitForces(benchmark::State& state, const Scene& scene) {
  const ParticleSystem sys(scene);
  MatrixN3 x, v, g(sys.num_particles(), 3);
  SwungState(sys, &x, &v);
  for (auto _ : state) {
    sys.ExplicitForces(0.2, x, v, &g);
    benchmark::DoNotOptimize(g.data());
  }
  state.SetComplexityN(sys.num_particles());
}

void BM_ExplicitForces(benchmark::State& state) {
  TimeExplicitForces(state, SquareScene(static_cast<int>(state.range(0))));
}
BENCHMARK(BM_ExplicitForces)->ArgNames({"side"})->Arg(10)->Arg(20)->Arg(40)->Arg(316)->Complexity(benchmark::oN);

// Explicit forces and a J_α refresh on the grid's path (pattern:0) and on
// the curvilinear path (pattern:1), the same sheet, 10⁴ to 10⁶ particles.
void BM_ExplicitForcesPath(benchmark::State& state) { TimeExplicitForces(state, SheetOf(state)); }
BENCHMARK(BM_ExplicitForcesPath)->ArgNames({"side", "pattern"})->ArgsProduct({{100, 316, 1000}, {0, 1}});

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
    plane.shape = ShapeFromValues("plane", {{"center", Vector3(0.0, 0.0, -100.0)}});
    scene.obstacles.push_back(plane);
  }
  const ParticleSystem sys(scene);
  StepEngine e(sys, *MethodFromString(KernelBenchmarkMethod().name), scene.solver);
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
BENCHMARK(BM_ForceJacobian)->ArgName("side")->Arg(20)->Arg(316);

// Every particle's force and diagonal Jacobian blocks through the
// per-particle access of Vertex Block Descent (ParticleSystem::
// ParticleForce), serially: one VBD sweep's force work. Per term with
// range(1) = the term's index in ParticleSystem::terms(), −1: the whole
// force (the linear part's row included).
void BM_ParticleForces(benchmark::State& state) {
  const ParticleSystem sys(SquareScene(static_cast<int>(state.range(0))));
  MatrixN3 x, v;
  SwungState(sys, &x, &v);
  sys.PrepareParticleForces();
  const int term = static_cast<int>(state.range(1));
  if (term >= static_cast<int>(sys.terms().size())) {
    state.SkipWithError("no such term");
    return;
  }
  if (term >= 0) state.SetLabel(std::string(sys.terms()[static_cast<std::size_t>(term)]->name()));
  for (auto _ : state) {
    Vector3 f;
    Matrix3 dx, dv;
    for (int p = 0; p < sys.num_particles(); ++p) {
      if (term < 0) {
        sys.ParticleForce(0.2, x, v, p, &f, &dx, &dv);
      } else {
        f.setZero();
        dx.setZero();
        dv.setZero();
        sys.terms()[static_cast<std::size_t>(term)]->AddParticleForce(0.2, x, v, p, &f, &dx, &dv);
      }
      benchmark::DoNotOptimize(f.data());
      benchmark::DoNotOptimize(dx.data());
    }
  }
  state.counters["ns/particle"] = benchmark::Counter(static_cast<double>(sys.num_particles()),
                                                     benchmark::Counter::kIsIterationInvariantRate |
                                                         benchmark::Counter::kInvert);
}
BENCHMARK(BM_ParticleForces)->ArgNames({"side", "term"})->ArgsProduct({{20, 100}, {-1, 0, 1, 2, 3}});

// The same triplets by forward-mode AutoDiff of the force kernels (the test
// oracle of the closed forms; what every Jacobian cost before them).
void BM_ForceJacobianAutoDiff(benchmark::State& state) {
  const ParticleSystem sys(SquareScene(static_cast<int>(state.range(0))));
  MatrixN3 x, v;
  SwungState(sys, &x, &v);
  std::vector<Triplet> dx, dv;
  for (auto _ : state) {
    dx.clear();
    dv.clear();
    for (const auto& term : sys.terms()) term->AddJacobianAutoDiff(0.2, x, v, &dx, &dv);
    benchmark::DoNotOptimize(dx.data());
  }
}
BENCHMARK(BM_ForceJacobianAutoDiff)->ArgName("side")->Arg(20);

// One refresh of J_α = M − αh ∂f/∂v − α²h² ∂f/∂x with every term (clamped
// springs, symmetrised as Baraff–Witkin uses it): closed-form blocks
// accumulated into the fixed pattern. Compare with BM_ExplicitForces at the
// same side.
void TimeTangentUpdate(benchmark::State& state, const Scene& scene) {
  const ParticleSystem sys(scene);
  MatrixN3 x, v;
  SwungState(sys, &x, &v);
  TangentSystem ts(sys, {TangentProjection::kClamp, true, true});
  for (auto _ : state) {
    ts.Update(0.2, x, v, 0.01);
    benchmark::DoNotOptimize(ts.matrix().valuePtr());
  }
  state.counters["nnz"] = static_cast<double>(ts.matrix().nonZeros());
}

void BM_TangentUpdate(benchmark::State& state) {
  TimeTangentUpdate(state, SquareScene(static_cast<int>(state.range(0))));
}
BENCHMARK(BM_TangentUpdate)->ArgName("side")->Arg(20)->Arg(316);

void BM_TangentUpdatePath(benchmark::State& state) { TimeTangentUpdate(state, SheetOf(state)); }
BENCHMARK(BM_TangentUpdatePath)->ArgNames({"side", "pattern"})->ArgsProduct({{100, 316}, {0, 1}});

// J_α's values for a new αh from the stored force Jacobians (the pass that
// follows every Update, and CVODE's γ change without a Jacobian evaluation).
void BM_TangentSetAlphaH(benchmark::State& state) {
  const ParticleSystem sys(SquareScene(static_cast<int>(state.range(0))));
  MatrixN3 x, v;
  SwungState(sys, &x, &v);
  TangentSystem ts(sys, {TangentProjection::kClamp, true, true});
  ts.Update(0.2, x, v, 0.01);
  for (auto _ : state) {
    ts.SetAlphaH(0.01);
    benchmark::DoNotOptimize(ts.matrix().valuePtr());
  }
  const double bytes = 8.0 * 3.0 * static_cast<double>(ts.matrix().nonZeros());  // read ∂f/∂x, write J_α (+ its RFO)
  state.counters["floor_GBps"] = benchmark::Counter(bytes, benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_TangentSetAlphaH)->ArgName("side")->Arg(20)->Arg(316);

// y = J_α x for the 3N×3N J_α (the PCG's product in Newton, Baraff–Witkin
// and the SUNDIALS reduced solves). Floor: J's values and row indices, 12
// bytes per entry.
void BM_TangentProduct(benchmark::State& state) {
  const ParticleSystem sys(SquareScene(static_cast<int>(state.range(0))));
  MatrixN3 x, v;
  SwungState(sys, &x, &v);
  TangentSystem ts(sys, {TangentProjection::kClamp, true, true});
  ts.Update(0.2, x, v, 0.01);
  MatrixN3R u = MatrixN3R::Random(sys.num_particles(), 3), y(sys.num_particles(), 3);
  for (auto _ : state) {
    TangentProduct(ts.matrix(), u, &y);
    benchmark::DoNotOptimize(y.data());
  }
  const double bytes = 12.0 * static_cast<double>(ts.matrix().nonZeros());
  state.counters["nnz"] = static_cast<double>(ts.matrix().nonZeros());
  state.counters["floor_GBps"] = benchmark::Counter(bytes, benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_TangentProduct)->ArgName("side")->Arg(20)->Arg(316);

// A supernodal CHOLMOD factor (METIS) of the whole 3N×3N J_α, the
// preconditioner Baraff–Witkin would need to converge in one CG iteration
// (docs/notes/newton.md): the symbolic analysis and one numeric factorisation,
// with the factor's entries. Once per size: at side 316 it takes seconds.
void BM_TangentCholmodFactor(benchmark::State& state) {
  const ParticleSystem sys(SquareScene(static_cast<int>(state.range(0))));
  MatrixN3 x, v;
  SwungState(sys, &x, &v);
  TangentSystem ts(sys, {TangentProjection::kClamp, true, true});
  ts.Update(0.2, x, v, 0.01);
  double lnz = 0.0, analysis = 0.0;
  for (auto _ : state) {
    Eigen::CholmodSupernodalLLT<SparseMatrix, Eigen::Lower> llt;
    llt.cholmod().nmethods = 1;
    llt.cholmod().method[0].ordering = CHOLMOD_METIS;
    const auto start = std::chrono::steady_clock::now();
    llt.analyzePattern(ts.matrix());
    analysis = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    llt.factorize(ts.matrix());
    if (llt.info() != Eigen::Success) state.SkipWithError("J_alpha not positive definite");
    lnz = llt.cholmod().lnz;
  }
  state.counters["factor_nnz"] = lnz;
  state.counters["analysis_s"] = analysis;
}
BENCHMARK(BM_TangentCholmodFactor)->ArgName("side")->Arg(100)->Arg(316)->Iterations(1)->Unit(benchmark::kSecond);
}  // namespace
}  // namespace clothbench
BENCHMARK_MAIN();
