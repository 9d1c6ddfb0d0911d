// A registry row run as bench_integrators runs it, for the tests.
#ifndef CLOTHBENCH_VERIFY_TEST_ROWS_H_
#define CLOTHBENCH_VERIFY_TEST_ROWS_H_

#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "harness/methods.h"
#include "model/particle_system.h"
#include "model/scene.h"

namespace clothbench::testing {

/// Row `label` (e.g. "sbdf2", "baraff_witkin") on `scene` at `param` (its
/// h [s], or its rtol) through RowMethod::Run (harness/methods.h).
inline MethodRun RunRow(const Scene& scene, const std::string& label, double param) {
  const std::vector<RowMethod> rows = ExpandMethods({label}, {scene.solver.nonlinear_solver}, "test");
  EXPECT_EQ(rows.size(), 1u) << label;
  const ParticleSystem sys(scene);
  return rows.front().Run(sys, scene, scene.solver, param, RunContext{});
}

}  // namespace clothbench::testing

#endif  // CLOTHBENCH_VERIFY_TEST_ROWS_H_
