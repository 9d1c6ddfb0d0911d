// bench_scaling: one SBDF(2) step of the large sheet (scenes/large_sheet.toml)
// at N = 10³, 10⁴, 10⁵ and 10⁶ particles (√N × √N, same 1 m square and
// material), for each preconditioner of the filtered PCG, without contacts
// and with a contact patch: a round table (cylinder) under the centre whose
// top is δ/2 below the sheet, so that 10 % or 30 % of the sheet starts in
// contact (docs/model.md §7).
//
// Setup (outside the timing): the model, A_α's pattern, the preconditioner's
// symbolic phase and step 1 (IMEX Euler, SBDF(2)'s start). Timed: steps 2–5,
// one per benchmark iteration, each minus the time spent refactorising (step
// 2 refactorises because α changes from 1 to 2/3); that factorisation is in
// the setup_s counter instead. Counters: cg_per_step, setup_s (assembly,
// analysis, both factorisations) split into analysis_s and factorization_s
// (one factorisation), colliding (particles in contact),
// factor_nnz (Cholesky) or amg_levels and amg_fallbacks.
//
//   build/bench/bench_scaling [--benchmark_filter=REGEX]
//                             [--benchmark_out=out/scaling.json --benchmark_out_format=json]
// SbdfStep/cholesky_amd: the factor with AMD ordering instead of METIS.
// SbdfStep/cholesky_plain, amg_plain: the factor without contact factors
// and the hierarchy without prefiltering (both of A_F alone; solver key
// contact_factors = false).
// StepPart/*: one Cholesky solve, one A·x, one evaluation of the explicit
// forces, one preconditioner application in contact frames and one
// refactorisation at 10⁵ and 10⁶ particles (the parts of a step).
// By default the preconditioners whose step at 10⁶ takes minutes (ic0,
// jacobi, none) stop at 10⁵; CLOTHBENCH_SCALING_ALL=1 adds them at 10⁶.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include "model/particle_system.h"
#include "harness/methods.h"
#include "solver/integrator.h"

namespace clothbench {
namespace {

/// The large sheet with side×side particles; contact_fraction > 0 adds a
/// cylinder under the centre covering that fraction of the sheet's area.
Scene ScalingScene(int side, double contact_fraction, PreconditionerType preconditioner) {
  Scene s = BuiltinScene("large_sheet");
  s.grid.nu = s.grid.nv = side;
  s.fixed = {s.Index(0, side - 1), s.Index(side - 1, side - 1)};
  s.solver.preconditioner = preconditioner;
  s.solver.cg_max_iterations = 100000;  // report the iterations needed, not a failure
  if (contact_fraction > 0.0) {
    ObstacleSpec table;
    table.collision_distance = 0.005;
    table.shape = ShapeFromValues(
        "cylinder", {{"radius", std::sqrt(contact_fraction * s.grid.size[0] * s.grid.size[1] / M_PI)},
                     {"center", Vector3(0.5 * s.grid.size[0], 0.5 * s.grid.size[1],
                                        s.grid.origin.z() - 0.5 * table.collision_distance)},
                     {"height", 0.5}});
    table.friction = 0.3;
    s.obstacles.push_back(table);
  }
  return s;
}

void BM_SbdfStep(benchmark::State& state) {
  const int side = static_cast<int>(state.range(0));
  const auto type = static_cast<PreconditionerType>(state.range(1));
  const double contact = static_cast<double>(state.range(2)) / 100.0;
  Scene scene = ScalingScene(side, contact, type);
  if (state.range(3) == 1) scene.solver.cholesky_ordering = CholeskyOrdering::kAmd;
  if (state.range(3) == 2) scene.solver.contact_factors = false;  // the factor of A_F alone
  const ParticleSystem sys(scene);
  StepEngine engine(sys, *MethodFromString(KernelBenchmarkMethod().name), scene.solver);
  engine.Reset(0.0, sys.rest_positions(), MatrixN3::Zero(sys.num_particles(), 3));
  const double h = scene.h;
  StepStats first = engine.Step(h);  // IMEX Euler start
  if (first.status != StepStatus::kOk) {
    state.SkipWithError(std::string(ToString(first.status)).c_str());
    return;
  }
  long cg = 0;
  int colliding = 0;
  std::vector<double> times;
  for (auto _ : state) {
    const StepStats st = engine.Step(h);
    if (st.status != StepStatus::kOk) {
      state.SkipWithError(std::string(ToString(st.status)).c_str());
      return;
    }
    const double seconds = st.solve_time - st.setup_time;  // factorisation excluded
    state.SetIterationTime(seconds);
    times.push_back(seconds);
    cg += st.cg_iterations;
    colliding = std::max(colliding, st.colliding);
  }
  std::sort(times.begin(), times.end());
  const std::size_t k = times.size();
  state.counters["median_step_s"] = k ? 0.5 * (times[(k - 1) / 2] + times[k / 2]) : 0.0;
  state.counters["cg_per_step"] = static_cast<double>(cg) / static_cast<double>(std::max<std::size_t>(k, 1));
  state.counters["setup_s"] = engine.system_matrix().setup_seconds();
  // Setup = analysis (once) + two numeric factorisations (α = 1 for the IMEX
  // Euler start, α = 2/3 for SBDF(2)).
  state.counters["analysis_s"] = engine.system_matrix().analysis_seconds();
  state.counters["factorization_s"] =
      0.5 * (engine.system_matrix().setup_seconds() - engine.system_matrix().analysis_seconds());
  state.counters["colliding"] = colliding;
  state.counters["N"] = sys.num_particles();
  if (type == PreconditionerType::kCholesky)
    state.counters["factor_nnz"] = static_cast<double>(engine.system_matrix().preconditioner().factor_nonzeros());
  if (type == PreconditionerType::kAmg) {
    state.counters["amg_levels"] = engine.system_matrix().preconditioner().amg_levels();
    // Setups of the prefiltered hierarchy whose V-cycle was not finite (A_F's served instead).
    state.counters["amg_fallbacks"] = static_cast<double>(engine.system_matrix().preconditioner().contact_stats().fallbacks);
  }
  state.SetComplexityN(sys.num_particles());
}

// The parts of a step at N particles, for the distance to the bandwidth
// floor: 0 one preconditioner application without contacts (A_F's factor,
// three columns), 1 one A·x, 2 the explicit forces g(t, x, v), 3 one
// application in contact frames (a sphere's cap of contacts, every normal
// tilted: columns x, y with A_F's factor, z with the contact factor, as a
// CG iteration on a curved obstacle reads them), 4 one numeric
// refactorisation of A_F (what a contact factor's refactorisation costs).
void BM_StepParts(benchmark::State& state) {
  const int side = static_cast<int>(state.range(0));
  const int part = static_cast<int>(state.range(1));
  const Scene scene = ScalingScene(side, 0.0, PreconditionerType::kCholesky);
  const ParticleSystem sys(scene);
  SystemMatrix sm(sys, PreconditionerType::kCholesky, CholeskyOrdering::kMetis, /*contact_factors=*/part == 3);
  const double alpha_h = scene.h * 2.0 / 3.0;
  if (!sm.Update(alpha_h)) {
    state.SkipWithError("factorisation failed");
    return;
  }
  const int n = sys.num_particles();
  if (part == 3) {
    // The particles within 0.3 m of the sheet's centre, each constrained
    // along the normal of a sphere of radius 0.5 m below that centre (28 %
    // of the sheet, normals up to 37° from the vertical).
    VelocityFilter filter;
    filter.Reserve(n);
    for (int p : sys.fixed()) filter.Fix(p);
    const MatrixN3& x0 = sys.rest_positions();
    const Vector3 c = 0.5 * (x0.colwise().minCoeff() + x0.colwise().maxCoeff()).transpose() - Vector3(0, 0, 0.5);
    for (int p = 0; p < n; ++p) {
      const Vector3 d = x0.row(p).transpose() - c;
      if (std::hypot(d.x(), d.y()) < 0.3) filter.Constrain(p, d.normalized(), 0.0);
    }
    if (!sm.AdaptTo(filter) || sm.preconditioner().ServedBy() != 3) {
      state.SkipWithError("contact frames not set up");
      return;
    }
  }
  MatrixN3 r = MatrixN3::Random(n, 3), z(n, 3), g(n, 3);
  const MatrixN3 x = sys.rest_positions();
  const MatrixN3 v = MatrixN3::Random(n, 3);
  const long reads_before = sm.preconditioner().factor_reads();
  long k = 0;
  for (auto _ : state) {
    if (part == 0 || part == 3) sm.preconditioner().Apply(r, &z);
    if (part == 1) SymmetricProduct(sm.matrix(), r, &z);
    if (part == 2) sys.ExplicitForces(0.0, x, v, &g);
    if (part == 4 && !sm.Update(alpha_h * (++k % 2 ? 1.0 + 1e-9 : 1.0))) {
      state.SkipWithError("factorisation failed");
      break;  // the loop does not end by itself after SkipWithError
    }
    benchmark::DoNotOptimize(z.data());
    benchmark::DoNotOptimize(g.data());
  }
  state.counters["N"] = n;
  if (part == 0 || part == 3) {
    state.counters["factor_nnz"] = static_cast<double>(sm.preconditioner().factor_nonzeros());
    state.counters["factor_reads"] = static_cast<double>(sm.preconditioner().factor_reads() - reads_before) /
                                     static_cast<double>(std::max<benchmark::IterationCount>(state.iterations(), 1));
  }
}

}  // namespace
}  // namespace clothbench

int main(int argc, char** argv) {
  using namespace clothbench;
  const bool all = std::getenv("CLOTHBENCH_SCALING_ALL") != nullptr;
  // √N for N ≈ 10³, 10⁴, 10⁵, 10⁶.
  const std::vector<int> sides = {32, 100, 316, 1000};
  for (const int contact : {0, 10, 30}) {
    for (PreconditionerType type : {PreconditionerType::kCholesky, PreconditionerType::kAmg, PreconditionerType::kIc0,
                                    PreconditionerType::kJacobi, PreconditionerType::kNone}) {
      const bool fast = type == PreconditionerType::kCholesky || type == PreconditionerType::kAmg;
      const std::string name = "SbdfStep/" + std::string(ToString(type)) + "/contact" + std::to_string(contact);
      auto* b = benchmark::RegisterBenchmark(name.c_str(), BM_SbdfStep);
      b->ArgNames({"side", "", "", ""})->Iterations(4)->UseManualTime()->Unit(benchmark::kMillisecond);
      for (int side : sides)
        if (fast || all || side < 1000) b->Args({side, static_cast<long>(type), contact, 0});
      b->Complexity(benchmark::oN);
    }
  }
  // The Cholesky factor with AMD instead of METIS ordering (the choice of
  // the default cholesky_ordering), no contacts.
  auto* amd = benchmark::RegisterBenchmark("SbdfStep/cholesky_amd/contact0", BM_SbdfStep);
  amd->ArgNames({"side", "", "", ""})->Iterations(4)->UseManualTime()->Unit(benchmark::kMillisecond);
  for (int side : sides) amd->Args({side, static_cast<long>(PreconditionerType::kCholesky), 0, 1});
  amd->Complexity(benchmark::oN);
  // The Cholesky factor and the AMG hierarchy of A_F alone (without contact
  // factors, without prefiltering), with contacts: what the contact-aware
  // versions gain.
  for (PreconditionerType type : {PreconditionerType::kCholesky, PreconditionerType::kAmg})
    for (const int contact : {10, 30}) {
      const std::string name = "SbdfStep/" + std::string(ToString(type)) + "_plain/contact" + std::to_string(contact);
      auto* plain = benchmark::RegisterBenchmark(name.c_str(), BM_SbdfStep);
      plain->ArgNames({"side", "", "", ""})->Iterations(4)->UseManualTime()->Unit(benchmark::kMillisecond);
      for (int side : sides) plain->Args({side, static_cast<long>(type), contact, 2});
      plain->Complexity(benchmark::oN);
    }
  // Parts of a step (BM_StepParts).
  const std::vector<std::string> parts = {"CholeskySolve", "Product", "ExplicitForces", "ContactFramesApply",
                                          "Refactorisation"};
  for (std::size_t index = 0; index < parts.size(); ++index) {
    auto* b = benchmark::RegisterBenchmark(("StepPart/" + parts[index]).c_str(), BM_StepParts);
    b->ArgNames({"side", ""})->UseRealTime()->Unit(benchmark::kMillisecond);
    for (int side : {316, 1000}) b->Args({side, static_cast<long>(index)});
  }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 2;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
