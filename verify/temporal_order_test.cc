// Temporal order against a tight CVODE reference on the nonlinear swinging
// sheet (issue 3 item 3; SPEC §9 chapter 3).
//
// Scene: the default swinging sheet's material (k = 1000 N/m, d_t = 0.5,
// μ = 10, thin plate B = 1e-5, gravity) on an 8×8 grid 0.04 m apart, fixed
// at two adjacent corners, t_end = 0.05 s. Reference: CVODE BDF, rtol = atol
// = 1e-12. Steps h = 4e-4 … 5e-5 s (numerical stiffness 0.1 … 0.0016): in
// this range (a) the fixed-point loop of the implicit methods converges (its
// contraction ≈ α²h²sλ/(m + α²h²sλ) ≤ 0.45) and (b) IMEX Euler is past its
// pre-asymptotic range (README "Observed order"). CG tolerance 1e-13 and a
// fixed-point tolerance of 1e-14 m/s keep solver errors below 1e-11 m, under
// the smallest measured error. The least-squares slope of log e_rms against
// log h must be within 0.3 of the classical order.
#include <gtest/gtest.h>

#include "reference/cvode_reference.h"
#include "results/metrics.h"
#include "solver/run.h"

namespace clothbench {
namespace {

Scene SmallSwingingSheet() {
  Scene s = DefaultScene();
  s.grid.nu = s.grid.nv = 8;
  s.grid.size = {0.28, 0.28};
  s.fixed = {s.Index(0, 7), s.Index(7, 7)};
  s.t_end = 0.05;
  s.frame_dt = 0.05;
  s.solver.cg_tolerance = 1e-13;
  s.solver.fixed_point_tolerance = 1e-14;
  s.solver.max_updates = 200;
  return s;
}

const MatrixN3& Reference() {
  static const MatrixN3 ref = [] {
    const ParticleSystem sys(SmallSwingingSheet());
    const ReferenceResult r = RunCvode(sys, ReferenceOptions{1e-12, 1e-12, 5, 0.05, 0.05});
    EXPECT_TRUE(r.ok) << r.message;
    return r.trajectory.positions.back();
  }();
  return ref;
}

class CvodeOrderTest : public ::testing::TestWithParam<Method> {};

TEST_P(CvodeOrderTest, LeastSquaresSlopeMatchesClassicalOrder) {
  const Scene s = SmallSwingingSheet();
  const ParticleSystem sys(s);
  const std::vector<double> hs = {4e-4, 2e-4, 1e-4, 5e-5};
  std::vector<double> es;
  for (double h : hs) {
    const RunSummary r = RunIntegrator(sys, GetParam(), {h, s.t_end, s.frame_dt});
    ASSERT_TRUE(r.ok) << r.BriefReport();
    ASSERT_EQ(r.rejected_steps, 0) << "fixed-point loop did not converge: " << r.BriefReport();
    es.push_back(ErrorRms(r.trajectory.positions.back(), Reference()));
  }
  const double slope = LeastSquaresOrder(hs, es);
  std::printf("[ cvode order ] %-18s e_rms = %.3e %.3e %.3e %.3e  slope %.3f\n",
              std::string(ToString(GetParam())).c_str(), es[0], es[1], es[2], es[3], slope);
  EXPECT_NEAR(slope, MethodOrder(GetParam()), 0.3);
}

INSTANTIATE_TEST_SUITE_P(Integrators, CvodeOrderTest, ::testing::ValuesIn(AllMethods()),
                         [](const auto& param_info) { return std::string(ToString(param_info.param)); });

}  // namespace
}  // namespace clothbench
