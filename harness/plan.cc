// Planning a run from its options (harness/plan.h).
#include "harness/plan.h"

#include <algorithm>
#include <cmath>
#include <functional>

#include <fmt/format.h>

#include "harness/cli_args.h"

namespace clothbench {

std::vector<std::string> DefaultRowNames(NonlinearSolver scene_solver, bool solver_from_cli) {
  std::vector<std::string> names;
  for (const DefaultRow& d : DefaultRows())
    if (!d.newton_variant || (!solver_from_cli && scene_solver != NonlinearSolver::kNewton))
      names.emplace_back(d.label);
  return names;
}

RowPlan PlanRows(const Scene& scene, const std::vector<RowMethod>& methods, const std::vector<double>& hs,
                 const std::vector<double>& rtols, const std::vector<int>& substeps, const std::vector<int>& iterations,
                 std::size_t n_eta) {
  RowPlan plan;
  plan.params.resize(methods.size());
  for (std::size_t k = 0; k < methods.size(); ++k) {
    const RowMethod& m = methods[k];
    const DefaultParams d = DefaultRowParams(m);
    std::vector<double> mh = hs;
    if (mh.empty())
      for (double f : d.h_factors)
        if (f * scene.h <= scene.t_end) mh.push_back(f * scene.h);
    if (mh.empty()) mh = {scene.h};
    std::sort(mh.begin(), mh.end(), std::greater<>());
    auto& ps = plan.params[k];
    const StepKindSpec& kind = SpecOf(m.kind());
    if (kind.count_divides_h) {  // substeps: the runs in order of decreasing substep h/n
      for (double h : mh)
        for (int n : substeps) ps.emplace_back(h, n);
      std::stable_sort(ps.begin(), ps.end(),
                       [](const auto& a, const auto& b) { return a.first / a.second > b.first / b.second; });
    } else if (kind.counted()) {  // iterations: the command's, the method's or the default list
      const std::vector<int>& counts = !iterations.empty()    ? iterations
                                       : !d.iterations.empty() ? d.iterations
                                                               : kDefaultIterations;
      for (double h : mh)  // h decreasing, each with its iteration counts increasing
        for (int count : counts) ps.emplace_back(h, count);
    } else if (!kind.adaptive()) {
      for (double h : mh) ps.emplace_back(h, 1);
    } else {
      // A scene under error control sets its own rtol as the default.
      const bool scene_rtol = m.error_control && scene.solver.step_control == StepControl::kError;
      for (double r : !rtols.empty() ? rtols : scene_rtol ? std::vector<double>{scene.solver.rtol} : d.rtols)
        ps.emplace_back(r, 1);
    }
    plan.n_params.push_back(ps.size());
    // The longest fixed-step or substepped run must stay within the step limit.
    if (!kind.adaptive())
      for (const auto& [h, count] : ps) {
        const int n = kind.count_divides_h ? count : 1;  // steps per h
        plan.step_records += std::ceil(scene.t_end / h * n) * static_cast<double>(m.uses_pcg() ? n_eta : 1);
        if (scene.t_end / h * n > kMaxStepsPerRun)
          throw UsageError(fmt::format("{}: {} at h = {:g} s{} needs t_end/h = {:.3g} steps, more than the limit of "
                                       "{:g} (solver/run.h, RunLimits)",
                                       hs.empty() ? "scene h" : (n > 1 ? "--h/--substeps" : "--h"), m.label(), h,
                                       n > 1 ? fmt::format(" with {} substeps", n) : "", scene.t_end / h * n,
                                       kMaxStepsPerRun));
      }
  }
  return plan;
}

}  // namespace clothbench
