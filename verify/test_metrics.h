// Measures the tests share that no entry point reports: a run's one-line
// summary for assertion messages, a method's classical order, the
// least-squares order of a convergence series, and the deepest penetration
// after a time.
#ifndef CLOTHBENCH_VERIFY_TEST_METRICS_H_
#define CLOTHBENCH_VERIFY_TEST_METRICS_H_

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "harness/methods.h"
#include "results/metrics.h"
#include "solver/integrator.h"
#include "solver/run.h"

namespace clothbench::testing {

/// One line of a run's outcome and counts, for assertion messages.
inline std::string Brief(const RunSummary& r) {
  return fmt::format(
      "{}: {} steps ({} rejected), {} updates, {} CG iterations, solver {:.3f} s (setup {:.3f} s), wall {:.3f} s{}{}",
      r.status, r.steps, r.rejected, r.updates, r.cg_iterations, r.solver_time_s, r.setup_time_s, r.wall_time_s,
      r.message.empty() ? "" : ": ", r.message);
}

/// Classical order of convergence of a thesis method (1, 2 or 3; docs/model.md §4).
inline int MethodOrder(Method m) {
  if (m == Method::kSbdf3) return 3;
  return (m == Method::kImexEuler || m == Method::kImplicitEuler || m == Method::kSymplecticEuler) ? 1 : 2;
}

/// The step engine's methods that the property, energy, no-allocation and
/// collision tests cover: every thesis method in the registry (solver/
/// layer) that solves with the PCG, in registry order, so a new one is
/// covered by its registry line. Symplectic Euler, the explicit baseline,
/// is left out: it is stable only below its step limit.
inline const std::vector<Method>& EngineMethods() {
  static const std::vector<Method> kMethods = [] {
    std::vector<Method> m;
    for (const MethodEntry& e : Registry())
      if (e.layer == "solver" && e.pcg) m.push_back(*MethodFromString(e.name));
    return m;
  }();
  return kMethods;
}

/// Least-squares slope of log e against log h (the observed order over a series).
inline double LeastSquaresOrder(const std::vector<double>& h, const std::vector<double>& e) {
  const double n = static_cast<double>(h.size());
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t k = 0; k < h.size(); ++k) {
    const double x = std::log(h[k]), y = std::log(e[k]);
    sx += x;
    sy += y;
    sxx += x * x;
    sxy += x * y;
  }
  return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

/// Max of p.max_depth over the frames at or after t_from [s], over all obstacles [m].
inline double MaxDepthAfter(const PenetrationSeries& p, const std::vector<double>& times, double t_from) {
  double m = 0.0;
  for (std::size_t f = 0; f < times.size(); ++f)
    if (times[f] >= t_from - 1e-12)
      for (int o = 0; o < p.obstacles; ++o) m = std::max(m, p.max_depth[f * static_cast<std::size_t>(p.obstacles) + o]);
  return m;
}

}  // namespace clothbench::testing

#endif  // CLOTHBENCH_VERIFY_TEST_METRICS_H_
