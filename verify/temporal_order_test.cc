// Temporal order (docs/model.md §9 chapter 3), measured two ways.
//
// 1. Against the exact modal solution of a linear scene (zero-rest-length
//    springs, border fixed, proportional damping L_D = (d/k) L_K, gravity):
//      u(t) = u_p + M^{-1/2} Q q(t),  u_p = L_ff⁻¹ M g,
//      q_k'' + (d/k) λ_k q_k' + λ_k q_k = 0,  q(0) = −Qᵀ M^{1/2} u_p, q'(0) = 0,
//    with M^{-1/2} L_ff M^{-1/2} = Q Λ Qᵀ (modal decomposition of M⁻¹L_K, L_D).
//    Every mode is underdamped, q_k = e^{−σt}(q0 cos ω_d t + σ q0/ω_d sin ω_d t).
//    Steps h = 4e-3 … 5e-4 s (h ω_max ≤ 0.36); CG tolerance 1e-13 keeps the
//    inexact solve far below the smallest error (≈1e-7 m).
//
// 2. Against a tight CVODE reference on the nonlinear swinging sheet: the
//    default swinging sheet's material (k = 1000 N/m, d_t = 0.5, μ = 10,
//    thin plate B = 1e-5, gravity) on an 8×8 grid 0.04 m apart, fixed at two
//    adjacent corners, t_end = 0.05 s; CVODE BDF at rtol = atol = 1e-12.
//    Steps h = 4e-4 … 5e-5 s (numerical stiffness 0.1 … 0.0016): there
//    (a) the fixed-point loop of the implicit methods converges (contraction
//    ≈ α²h²sλ/(m + α²h²sλ) ≤ 0.45) and (b) IMEX Euler is past its
//    pre-asymptotic range (docs/notes/verification.md, "Observed order"). CG tolerance 1e-13 and a
//    fixed-point tolerance of 1e-14 m/s keep solver errors below 1e-11 m,
//    under the smallest measured error.
//
// In both, the least-squares slope of log e_rms against log h over four
// halving steps must be within 0.3 of the classical order (1 for the Euler
// methods, 2 for the other thesis methods, 3 for SBDF(3)); the slopes are
// printed.
#include <gtest/gtest.h>

#include "verify/test_metrics.h"
#include "reference/cvode_reference.h"
#include "results/metrics.h"
#include "solver/run.h"
#include "verify/modal_solution.h"
#include "verify/test_scenes.h"

#include <Eigen/Dense>

namespace clothbench {
namespace {

Scene LinearScene() {
  Scene s = testing::LinearMembrane(0.01);  // proportional: L_D = 1e-3 L_K
  s.name = "linear_membrane";
  s.t_end = 0.4;
  s.frame_dt = 0.4;
  return s;
}

// Exact positions at time t from rest (see the file header).
MatrixN3 ExactLinear(const ParticleSystem& sys, double t) {
  MatrixN3 x, v;
  testing::LinearModalFlow(sys).Flow(sys.rest_positions(), MatrixN3::Zero(sys.num_particles(), 3), t, &x, &v);
  return x;
}

class ModalOrderTest : public ::testing::TestWithParam<Method> {};

TEST_P(ModalOrderTest, ObservedOrderMatchesClassicalOrder) {
  const Scene s = LinearScene();
  const ParticleSystem sys(s);
  const MatrixN3 exact = ExactLinear(sys, s.t_end);
  std::vector<double> hs = {0.004, 0.002, 0.001, 0.0005}, es;
  for (double h : hs) {
    const RunSummary r = RunIntegrator(sys, GetParam(), {h, s.t_end, s.frame_dt});
    ASSERT_TRUE(r.ok()) << r.message;
    es.push_back(ErrorRms(r.trajectory.positions.back(), exact));
  }
  const double slope = testing::LeastSquaresOrder(hs, es);
  std::printf("[ modal order ] %-18s e_rms = %.3e %.3e %.3e %.3e  slope %.3f\n", std::string(ToString(GetParam())).c_str(),
              es[0], es[1], es[2], es[3], slope);
  EXPECT_NEAR(slope, testing::MethodOrder(GetParam()), 0.3);
}

INSTANTIATE_TEST_SUITE_P(Integrators, ModalOrderTest, ::testing::ValuesIn(testing::EngineMethods()),
                         [](const auto& param_info) { return std::string(ToString(param_info.param)); });


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
    const RunSummary r = RunCvode(sys, ReferenceOptions{1e-12, 1e-12, 5, 0.05, 0.05});
    EXPECT_TRUE(r.ok()) << r.message;
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
    ASSERT_TRUE(r.ok()) << testing::Brief(r);
    ASSERT_EQ(r.rejected, 0) << "fixed-point loop did not converge: " << testing::Brief(r);
    es.push_back(ErrorRms(r.trajectory.positions.back(), Reference()));
  }
  const double slope = testing::LeastSquaresOrder(hs, es);
  std::printf("[ cvode order ] %-18s e_rms = %.3e %.3e %.3e %.3e  slope %.3f\n",
              std::string(ToString(GetParam())).c_str(), es[0], es[1], es[2], es[3], slope);
  EXPECT_NEAR(slope, testing::MethodOrder(GetParam()), 0.3);
}

INSTANTIATE_TEST_SUITE_P(Integrators, CvodeOrderTest, ::testing::ValuesIn(testing::EngineMethods()),
                         [](const auto& param_info) { return std::string(ToString(param_info.param)); });

}  // namespace
}  // namespace clothbench
