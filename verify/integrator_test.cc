// Step engine (SPEC §3–4, §6).
//
// Order test: a linear scene (zero-rest-length springs, border fixed,
// proportional damping L_D = (d/k) L_K, gravity) has the exact solution
//   u(t) = u_p + M^{-1/2} Q q(t),  u_p = L_ff⁻¹ M g,
//   q_k'' + (d/k) λ_k q_k' + λ_k q_k = 0,  q(0) = −Qᵀ M^{1/2} u_p, q'(0) = 0,
// with M^{-1/2} L_ff M^{-1/2} = Q Λ Qᵀ (modal decomposition of M⁻¹L_K, L_D).
// Every mode is underdamped here, so q_k = e^{−σt}(q0 cos ω_d t + σ q0/ω_d sin ω_d t).
// Error e_rms(t_end) against it over four halving steps in the asymptotic
// range (h ω_max ≤ 0.36); the least-squares slope must be within 0.3 of the
// classical order (1 for the Euler methods, 2 for the others). CG tolerance
// 1e-13 keeps the inexact solve far below the smallest error (≈1e-7 m).
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include "results/metrics.h"
#include "solver/run.h"
#include "verify/test_scenes.h"

namespace clothbench {
namespace {

TEST(Bdf2Coefficients, ConstantStepValues) {
  const Bdf2Coefficients c(1.0);
  EXPECT_DOUBLE_EQ(c.c1, 4.0 / 3.0);
  EXPECT_DOUBLE_EQ(c.c2, 1.0 / 3.0);
  EXPECT_DOUBLE_EQ(c.c3, 2.0 / 3.0);
}

// Variable-step BDF(2) is exact for polynomials of degree ≤ 2: constants
// (c1 − c2 = 1), t (c2/ω + c3 = 1) and t² (2 c3 − c2/ω² = 1).
TEST(Bdf2Coefficients, ExactForQuadraticsAtAnyRatio) {
  for (double w : {0.25, 0.5, 1.0, 2.0, 3.0}) {
    const Bdf2Coefficients c(w);
    EXPECT_NEAR(c.c1 - c.c2, 1.0, 1e-15);
    EXPECT_NEAR(c.c2 / w + c.c3, 1.0, 1e-15);
    EXPECT_NEAR(2 * c.c3 - c.c2 / (w * w), 1.0, 1e-15);
  }
}

Scene LinearScene() {
  Scene s = testing::LinearMembrane(0.01);  // proportional: L_D = 1e-3 L_K
  s.name = "linear_membrane";
  s.t_end = 0.4;
  s.frame_dt = 0.4;
  return s;
}

// Exact positions at time t (see the file header).
MatrixN3 ExactLinear(const ParticleSystem& sys, double t) {
  const Scene& s = sys.scene();
  std::vector<int> free;
  for (int p = 0; p < sys.num_particles(); ++p)
    if (!sys.is_fixed(p)) free.push_back(p);
  const int nf = static_cast<int>(free.size());
  const Eigen::MatrixXd lk(sys.stiffness_laplacian());
  Eigen::MatrixXd lff(nf, nf);
  Eigen::VectorXd sqm(nf);
  for (int a = 0; a < nf; ++a) {
    sqm(a) = std::sqrt(sys.masses()(free[a]));
    for (int b = 0; b < nf; ++b) lff(a, b) = lk(free[a], free[b]);
  }
  const double c = s.material.tension_damping / s.material.tension[0];
  const Eigen::MatrixXd w = sqm.cwiseInverse().asDiagonal() * lff * sqm.cwiseInverse().asDiagonal();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(w);
  MatrixN3 x = sys.rest_positions();
  for (int col = 0; col < 3; ++col) {
    const double g = s.forces.gravity(col);
    if (g == 0.0) continue;
    const Eigen::VectorXd mg = sqm.cwiseProduct(sqm) * g;
    const Eigen::VectorXd up = lff.ldlt().solve(mg);
    const Eigen::VectorXd q0 = -eig.eigenvectors().transpose() * sqm.cwiseProduct(up);
    Eigen::VectorXd q(nf);
    for (int k = 0; k < nf; ++k) {
      const double lam = eig.eigenvalues()(k), sigma = 0.5 * c * lam, wd = std::sqrt(lam - sigma * sigma);
      q(k) = std::exp(-sigma * t) * (q0(k) * std::cos(wd * t) + sigma * q0(k) / wd * std::sin(wd * t));
    }
    const Eigen::VectorXd u = up + sqm.cwiseInverse().cwiseProduct(eig.eigenvectors() * q);
    for (int a = 0; a < nf; ++a) x(free[a], col) += u(a);
  }
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
    ASSERT_TRUE(r.ok) << r.message;
    es.push_back(ErrorRms(r.trajectory.positions.back(), exact));
  }
  const double slope = LeastSquaresOrder(hs, es);
  std::printf("[ modal order ] %-18s e_rms = %.3e %.3e %.3e %.3e  slope %.3f\n", std::string(ToString(GetParam())).c_str(),
              es[0], es[1], es[2], es[3], slope);
  EXPECT_NEAR(slope, MethodOrder(GetParam()), 0.3);
}

INSTANTIATE_TEST_SUITE_P(Integrators, ModalOrderTest, ::testing::ValuesIn(AllMethods()),
                         [](const auto& param_info) { return std::string(ToString(param_info.param)); });

// Fixed particles never move; runs are reproducible bit for bit.
TEST(StepEngine, FixedParticlesStayAndRunsAreReproducible) {
  Scene s = DefaultScene();
  s.t_end = 0.1;
  s.solver.cg_tolerance = 1e-6;
  const ParticleSystem sys(s);
  for (Method m : AllMethods()) {
    const RunSummary a = RunIntegrator(sys, m, {0.01, s.t_end, s.frame_dt});
    const RunSummary b = RunIntegrator(sys, m, {0.01, s.t_end, s.frame_dt});
    ASSERT_TRUE(a.ok) << ToString(m) << ": " << a.message;
    EXPECT_EQ(a.trajectory.positions.size(), 11u);
    EXPECT_TRUE((a.trajectory.positions.back().array() == b.trajectory.positions.back().array()).all()) << ToString(m);
    EXPECT_EQ(a.cg_iterations, b.cg_iterations);
    for (int p : sys.fixed())
      EXPECT_EQ((a.trajectory.positions.back().row(p) - sys.rest_positions().row(p)).norm(), 0.0) << ToString(m);
    if (IsImex(m)) {
      EXPECT_EQ(a.fixed_point_updates, a.steps) << "IMEX methods do one update per step";
    }
  }
}

// A step that cannot converge is rejected, retried with smaller h, and
// finally reported as a status: no exception, no NaN in the trajectory.
TEST(StepEngine, FailureIsReportedAsStatus) {
  Scene s = DefaultScene();
  s.solver.cg_max_iterations = 1;  // PCG cannot converge in one iteration here
  s.solver.max_rejections = 3;
  const ParticleSystem sys(s);
  const RunSummary r = RunIntegrator(sys, Method::kBdf2, {0.01, 0.1, 0.01});
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.status, "cg_failed");
  EXPECT_EQ(r.rejected_steps, 4);
  for (const MatrixN3& x : r.trajectory.positions) EXPECT_TRUE(x.allFinite());
  EXPECT_FALSE(r.message.empty());
}

// Invalid options are a status with a message naming the field, not a crash.
TEST(StepEngine, InvalidOptionsAreReported) {
  Scene s = DefaultScene();
  s.solver.cg_tolerance = 2.0;
  const RunSummary r = RunIntegrator(ParticleSystem(s), Method::kSbdf2, {0.01, 0.1, 0.01});
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.status, "invalid_options");
  EXPECT_NE(r.message.find("cg_tolerance"), std::string::npos) << r.message;
  const RunSummary r2 = RunIntegrator(ParticleSystem(DefaultScene()), Method::kSbdf2, {-0.01, 0.1, 0.01});
  EXPECT_EQ(r2.status, "invalid_options");
  EXPECT_NE(r2.BriefReport().find("h = -0.01"), std::string::npos) << r2.BriefReport();
}

// The iteration controller (SPEC §6) changes h and still reaches t_end and
// every frame.
TEST(StepEngine, IterationControllerReachesEnd) {
  Scene s = DefaultScene();
  s.t_end = 0.2;
  s.solver.cg_tolerance = 1e-6;
  s.solver.step_control = StepControl::kIterations;
  s.solver.h_max = 0.02;
  const ParticleSystem sys(s);
  const RunSummary r = RunIntegrator(sys, Method::kBdf2, {0.005, s.t_end, s.frame_dt});
  ASSERT_TRUE(r.ok) << r.message;
  EXPECT_EQ(r.trajectory.times.size(), 21u);
  double hmin = 1, hmax = 0;
  for (const StepStats& st : r.step_stats) {
    hmin = std::min(hmin, st.h);
    hmax = std::max(hmax, st.h);
  }
  EXPECT_GT(hmax, hmin);  // the controller did change h
  EXPECT_NEAR(r.step_stats.back().t, s.t_end, 1e-12);
}

}  // namespace
}  // namespace clothbench
