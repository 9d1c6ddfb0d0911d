// IDA (residual form, fixed particles algebraic), ARKODE and CVODE with the
// reduced solve agree with CVODE (ODE on the free DOFs, KLU) on every thesis
// scene.
//
// Both run at rtol = atol = 1e-8 over the first 0.2 s of each scene. Each
// controls its local error per step to ≈ rtol·|y| + atol with |y| ≲ 2 (m,
// m/s); global errors can grow beyond that over a few hundred steps, so we
// allow 100·rtol = 1e-6 m in e_rms at every frame (measured: 3.5e-10 to
// 3.5e-9 m, printed). A wrong residual, mass, sign or Jacobian block gives
// differences of order 1e-3 m or a failed run.
#include <gtest/gtest.h>

#include "reference/cvode_reference.h"
#include "peers/arkode.h"
#include "reference/ida_reference.h"
#include "results/metrics.h"

namespace clothbench {
namespace {

class ReferenceAgreementTest : public ::testing::TestWithParam<const char*> {
 protected:
  // The scene over its first 0.2 s and the options of both runs.
  static Scene FirstPart(const char* name) {
    Scene s = LoadScene(std::string(CLOTHBENCH_SCENES_DIR) + "/" + name + ".toml");
    s.t_end = 0.2;
    return s;
  }
  static ReferenceOptions Options(const Scene& s) { return {1e-8, 1e-8, 5, s.t_end, s.frame_dt}; }
  // max over frames of e_rms between two successful runs.
  static std::optional<TrajectoryErrors> Compare(const RunSummary& a, const RunSummary& c) {
    EXPECT_TRUE(a.ok()) << a.message;
    EXPECT_TRUE(c.ok()) << c.message;
    if (!a.ok() || !c.ok()) return std::nullopt;
    return CompareTrajectories(a.trajectory.positions, c.trajectory.positions);
  }
};

TEST_P(ReferenceAgreementTest, IdaMatchesCvode) {
  const Scene s = FirstPart(GetParam());
  const ParticleSystem sys(s);
  const RunSummary c = RunCvode(sys, Options(s)), i = RunIda(sys, Options(s));
  const auto e = Compare(i, c);
  ASSERT_TRUE(e.has_value());
  std::printf("[ ida vs cvode ] %-14s rtol 1e-8: max_t e_rms = %.2e m (cvode %ld steps, ida %ld steps)\n", GetParam(),
              e->rms_max, c.sundials->nst, i.sundials->nst);
  EXPECT_LT(e->rms_max, 1e-6);
  // Fixed particles stay exactly at rest in IDA's algebraic equations too.
  for (int p : sys.fixed())
    EXPECT_LT((i.trajectory.positions.back().row(p) - sys.rest_positions().row(p)).norm(), 1e-12);
}

// ARKODE's IMEX ARK324L2SA with the reduced PCG solve (peers/arkode.h)
// against CVODE, both at rtol = atol = 1e-8, same bound and reasoning as
// above; the PCG stops at ARKLS's own linear tolerance.
TEST_P(ReferenceAgreementTest, ArkodeMatchesCvode) {
  const Scene s = FirstPart(GetParam());
  const ParticleSystem sys(s);
  const RunSummary c = RunCvode(sys, Options(s)), a = RunArkode(sys, Options(s));
  const auto e = Compare(a, c);
  ASSERT_TRUE(e.has_value());
  std::printf("[ arkode vs cvode ] %-18s rtol 1e-8: max_t e_rms = %.2e m (cvode %ld steps, arkode %ld steps, "
              "%ld PCG iterations)\n",
              GetParam(), e->rms_max, c.sundials->nst, a.sundials->nst, a.sundials->nli);
  EXPECT_LT(e->rms_max, 1e-6);
}

// CVODE with the reduced velocity solve (row `cvode`: the closed-form,
// clamped and symmetrised tangent, the scene's preconditioner, CVODE's own
// linear tolerance) against CVODE with KLU on the exact first-order
// Jacobian, both at rtol = atol = 1e-8: the same bound and reasoning as
// above. Its Newton systems are solved inexactly with an approximate
// Jacobian, which CVODE's Newton test absorbs; a wrong elimination (a sign
// of γ, M or ∂f/∂x r_x) gives O(1e-3 m) or a failed run.
TEST_P(ReferenceAgreementTest, ReducedCvodeMatchesKluCvode) {
  const Scene s = FirstPart(GetParam());
  const ParticleSystem sys(s);
  const RunSummary c = RunCvode(sys, Options(s)), r = RunCvodeReduced(sys, Options(s), s.solver);
  const auto e = Compare(r, c);
  ASSERT_TRUE(e.has_value());
  std::printf("[ cvode reduced vs klu ] %-14s rtol 1e-8: max_t e_rms = %.2e m (klu %ld steps, reduced %ld steps, "
              "%ld Jacobians, %ld PCG iterations)\n",
              GetParam(), e->rms_max, c.sundials->nst, r.sundials->nst, r.sundials->nje, r.sundials->nli);
  EXPECT_LT(e->rms_max, 1e-6);
  EXPECT_GT(r.sundials->nli, 0);
  EXPECT_GE(r.sundials->nje, 1);
}

// IDA with the reduced velocity solve (row `ida`) against CVODE with KLU,
// the same bound and reasoning as above.
TEST_P(ReferenceAgreementTest, ReducedIdaMatchesKluCvode) {
  const Scene s = FirstPart(GetParam());
  const ParticleSystem sys(s);
  const RunSummary c = RunCvode(sys, Options(s)), i = RunIdaReduced(sys, Options(s), s.solver);
  const auto e = Compare(i, c);
  ASSERT_TRUE(e.has_value());
  std::printf("[ ida reduced vs cvode klu ] %-14s rtol 1e-8: max_t e_rms = %.2e m (cvode %ld steps, ida %ld steps, "
              "%ld Jacobians, %ld PCG iterations)\n",
              GetParam(), e->rms_max, c.sundials->nst, i.sundials->nst, i.sundials->nje, i.sundials->nli);
  EXPECT_LT(e->rms_max, 1e-6);
  EXPECT_GT(i.sundials->nli, 0);
  for (int p : sys.fixed())
    EXPECT_LT((i.trajectory.positions.back().row(p) - sys.rest_positions().row(p)).norm(), 1e-12);
}

INSTANTIATE_TEST_SUITE_P(ThesisScenes, ReferenceAgreementTest,
                         ::testing::Values("swinging_sheet", "hanging_sheet", "wind_sheet", "hanging_tablecloth"),
                         [](const auto& param_info) { return std::string(param_info.param); });

}  // namespace
}  // namespace clothbench
