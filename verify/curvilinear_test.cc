// The model on a curvilinear pattern (docs/model.md §2.7): the stencils'
// rest geometry taken from the pattern's samples. On uniform samples the
// curvilinear branch must give the grid's model; on a curved pattern its
// closed-form Jacobians are checked against AutoDiff in jacobian_test.cc and
// its convergence in chapter2_test.cc.
#include <gtest/gtest.h>

#include <fmt/format.h>

#include "verify/test_scenes.h"

namespace clothbench {
namespace {

using testing::MaxAbs;
using testing::ToSparse;

// Uniform samples through the curvilinear branch: every spacing is computed
// from sampled positions (size·i/(n − 1)) instead of the grid's l, so the two
// models agree up to the round-off of those differences, ~1e-16 of the
// sheet's size over a spacing of 1/20 of it, amplified by the l⁻⁴ of the
// thin plate's weights: ≤ 1e-13 relative; 1e-10 leaves room and still
// catches any wrong weight, area or rest value (an O(1) relative change).
TEST(Curvilinear, UniformSamplesGiveTheGridsModel) {
  for (BendModel bend : {BendModel::kThinPlate, BendModel::kMembrane})
    for (MassLumping lumping : {MassLumping::kUniform, MassLumping::kArea}) {
      Scene grid = testing::AllTermsScene(7, 6, bend);
      grid.material.mass_lumping = lumping;
      const Scene curved = testing::WithSamples(grid, testing::GradedSamples(7, 6, grid.grid.size, 0.0));
      ASSERT_FALSE(curved.uniform_grid());
      const ParticleSystem a(grid), b(curved);
      const std::string what = fmt::format("{} {}", ToString(bend), ToString(lumping));
      ASSERT_EQ(a.TermNames(), b.TermNames()) << what;
      EXPECT_LT((a.masses() - b.masses()).cwiseAbs().maxCoeff() / a.masses().maxCoeff(), 1e-10) << what;
      EXPECT_LT((a.rest_positions() - b.rest_positions()).cwiseAbs().maxCoeff(), 1e-14) << what;
      ASSERT_EQ(a.springs().size(), b.springs().size());
      for (std::size_t k = 0; k < a.springs().size(); ++k) {
        EXPECT_NEAR(a.springs()[k].stiffness, b.springs()[k].stiffness, 1e-10 * a.springs()[k].stiffness) << what << k;
        EXPECT_NEAR(a.springs()[k].rest_length, b.springs()[k].rest_length, 1e-14) << what << k;
        EXPECT_NEAR(a.springs()[k].damping, b.springs()[k].damping, 1e-10 * a.springs()[k].damping) << what << k;
      }
      MatrixN3 x, v;
      testing::PerturbedState(a, 7, &x, &v, 0.02);
      const int n3 = 3 * a.num_particles();
      for (std::size_t t = 0; t < a.terms().size(); ++t) {
        MatrixN3 fa = MatrixN3::Zero(a.num_particles(), 3), fb = fa;
        a.terms()[t]->AddForce(0.3, x, v, &fa);
        b.terms()[t]->AddForce(0.3, x, v, &fb);
        const std::string name(a.terms()[t]->name());
        ASSERT_GT(fa.cwiseAbs().maxCoeff(), 0.0) << what << ' ' << name;
        EXPECT_LT((fa - fb).cwiseAbs().maxCoeff() / fa.cwiseAbs().maxCoeff(), 1e-10) << what << ' ' << name;
        std::vector<Triplet> ax, av, bx, bv;
        a.terms()[t]->AddJacobian(0.3, x, v, &ax, &av);
        b.terms()[t]->AddJacobian(0.3, x, v, &bx, &bv);
        const double scale = MaxAbs(ToSparse(n3, ax)) + MaxAbs(ToSparse(n3, av));
        if (scale == 0.0) continue;  // gravity
        EXPECT_LT(MaxAbs(ToSparse(n3, ax) - ToSparse(n3, bx)) / scale, 1e-10) << what << ' ' << name << " d/dx";
        EXPECT_LT(MaxAbs(ToSparse(n3, av) - ToSparse(n3, bv)) / scale, 1e-10) << what << ' ' << name << " d/dv";
      }
      const EnergyBreakdown ea = a.Energies(x, v), eb = b.Energies(x, v);
      EXPECT_NEAR(ea.shear, eb.shear, 1e-10 * ea.shear) << what;
      EXPECT_NEAR(ea.bending, eb.bending, 1e-10 * ea.bending) << what;
      EXPECT_NEAR(ea.tension, eb.tension, 1e-10 * ea.tension) << what;
    }
}

// On a graded pattern every node's rest geometry is its own: the rest state
// is free of force (springs at their rest lengths, no shear, flat), and the
// cell areas add up to the pattern's area.
TEST(Curvilinear, GradedRestStateIsForceFreeAndAreasAddUp) {
  Scene s = testing::AllTermsScene(9, 7);
  s.forces = ForcesSpec{};
  s.forces.gravity = Vector3::Zero();
  s.material.mass_lumping = MassLumping::kArea;
  s = testing::WithSamples(s, testing::GradedSamples(9, 7, s.grid.size, 0.5));
  const ParticleSystem sys(s);
  MatrixN3 f(sys.num_particles(), 3);
  sys.Forces(0.0, sys.rest_positions(), MatrixN3::Zero(sys.num_particles(), 3), &f);
  // Round-off of forces ~k ε over spacings of 1e-2 m: 1e-12 N.
  EXPECT_LT(f.cwiseAbs().maxCoeff(), 1e-10);
  // "area" lumping: each quad's area shared by its four corners, exactly the sheet's area.
  EXPECT_NEAR(sys.masses().sum() / s.material.density, s.grid.size[0] * s.grid.size[1], 1e-14);
  // The spacings really vary: φ(1/8)/(1 − φ(7/8)) = 2.56 from edge to edge.
  const auto phi = [](double t) { return t + 0.5 * t * (1.0 - t); };
  EXPECT_NEAR(sys.springs().front().rest_length / s.lu(), phi(0.125) / (1.0 - phi(0.875)), 1e-12);
}

// On a trapezoid with a curved side, tension, shear and gravity are the
// gradient of Energies' tension, shear and gravity: the central difference
// of the energy along a random direction d equals −f·d. Step 1e-6 m: the
// O(ε²) truncation (~1e-12 relative) and the energies' round-off over 2ε
// (~1e-16 E/1e-6 ≈ 1e-10 of f·d) are both below the 1e-6 tolerance, which
// any O(1) mismatch (a missing area, γ₀ or rest length) exceeds.
TEST(Curvilinear, TensionAndShearAreTheGradientsOfTheirEnergies) {
  const PatternSpec p = testing::CurvedPanel();
  Scene s = testing::InternalForcesScene(7, 6);
  s.material.transverse = 0.0;
  s.material.tension_damping = 0.0;
  s.material.shear_damping = 0.0;
  s.forces.gravity = Vector3(0.0, 0.0, -9.81);
  SetCurvilinearCloth(&s, p, SamplePattern(p));
  const ParticleSystem sys(s);
  MatrixN3 x, v;
  testing::PerturbedState(sys, 5, &x, &v, 0.02);
  v.setZero();
  MatrixN3 f(sys.num_particles(), 3);
  sys.Forces(0.0, x, v, &f);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  MatrixN3 d(sys.num_particles(), 3);
  for (Eigen::Index k = 0; k < d.size(); ++k) d.data()[k] = u(rng);
  const double eps = 1e-6;
  const auto energy = [&](const MatrixN3& y) {
    const EnergyBreakdown e = sys.Energies(y, v);
    return e.tension + e.shear + e.gravity;
  };
  const double slope = (energy(x + eps * d) - energy(x - eps * d)) / (2.0 * eps);
  const double work = (f.array() * d.array()).sum();
  EXPECT_NEAR(slope, -work, 1e-6 * std::abs(work)) << "dE/dε " << slope << ", −f·d " << -work;
}

}  // namespace
}  // namespace clothbench
