// Chapter 2: spatial convergence to analytic equilibria
// (docs/model.md §9 experiments 1–3; thesis §2.8, Fig. 2.11). Each experiment solves
// the static equilibrium f(x, 0) = 0 of the discrete model (solver/
// static_solve.h) on n×n grids, n = 5, 9, 17, 33, and compares with the
// continuum solution at the nodes: e = rms over nodes of |x − x_continuum|.
// The test asserts that e falls with every refinement and that the observed
// rate between the two finest grids is at least the derived rate minus 0.1
// (the 0.1 covers the pre-asymptotic O(l²) terms at l = L/32).
//
// 1. Hanging textile: one edge fixed, in-plane body force f = ρg = 981 N/m²
//    along the sheet, k = 1e4 N/m, tension only. Continuum (linear spring law
//    along the fibre): u(s) = (f/k)(L s − s²/2). The uniform mass lumping
//    (thesis, docs/model.md §1) gives the free-edge row a full cell's mass, i.e. an
//    extra load f l/2 per width at s = L, whose displacement (f l/2k) s is the
//    whole discretisation error (second differences are exact on quadratics):
//    derived rate 1.
// Experiments 2 and 3 have nearly inextensible fibres. A Newton step in the
// soft (shear, bending) directions stretches them at second order, and the
// line search then stalls. They are therefore solved by a homotopy in the
// tension modulus, k = k0, 10 k0, … up to the experiment's value (k0 = 1e5
// for experiment 2, 1e3 for experiment 3), each solve
// warm-started from the previous one and the first from the sampled
// continuum solution. Only the final solve, at the experiment's k, is
// compared; the discrete equilibrium is unique, so the path does not change
// it.
//
// 2. Sheared textile: one edge fixed, f = 10 N/m² parallel to it, tension
//    1e9 N/m (rows and fibres inextensible, so rows translate rigidly and the
//    problem is 1-D), μ = 100 N/m. Continuum: μ sin θ = f (L − s),
//    w(s) = (f/μ)(L s − s²/2) along the edge and ∫₀ˢ (cos θ − 1) normal to it.
//    The error measured is that of w (the displacement along the edge). The
//    one-sided shear strain of the free row and the uniform lumping are O(l):
//    derived rate 1. The rate is reached slowly: the equivalent 1-D problem
//    (rows rigid) gives 0.77, 0.92, 0.97, 0.98, … 1.00 up to n = 1025.
//    FINDING: the contraction normal to the edge does not converge. The
//    central-difference shear strain γ_j = (w_{j+1} − w_{j−1})/2l (Alg. 2's
//    stencil, in the energy form of docs/model.md §2.2) has an odd–even null mode. The
//    discrete w carries a checkerboard of amplitude O(l) whose slope is O(1),
//    and the inextensible fibres turn Σ Δw²/2l into an O(1) extra
//    contraction: the free edge contracts ≈1.24× the continuum value at every
//    resolution. The test pins that ratio, so a change to the shear stencil
//    shows up here.
// 3. Bending: left edge clamped (two fixed columns), right edge on a roller
//    (z held), f = 1 N/m² downwards, thin plate B = 5 N m, E = 1e6 N/m, span
//    3 m. Reference: the continuum limit of the thesis' thin-plate operator,
//    solved by shooting with CVODE (derivation and rate in elastica.md):
//    derived rate 1.
#include <gtest/gtest.h>

#include <cmath>

#include "results/metrics.h"
#include "solver/static_solve.h"
#include "verify/elastica.h"

namespace clothbench {
namespace {

const std::vector<int> kSides = {5, 9, 17, 33};

struct Sweep {
  std::vector<double> l, e;
};

void CheckSweep(const char* name, const Sweep& s, double derived_rate) {
  std::printf("[ chapter 2 ] %-8s", name);
  for (std::size_t k = 0; k < s.e.size(); ++k) std::printf(" n=%d e=%.3e", kSides[k], s.e[k]);
  const double last = ObservedOrder(s.l[s.l.size() - 2], s.e[s.e.size() - 2], s.l.back(), s.e.back());
  std::printf("  rates");
  for (std::size_t k = 1; k < s.e.size(); ++k) std::printf(" %.2f", ObservedOrder(s.l[k - 1], s.e[k - 1], s.l[k], s.e[k]));
  std::printf(" (derived %.0f)\n", derived_rate);
  for (std::size_t k = 1; k < s.e.size(); ++k) EXPECT_LT(s.e[k], s.e[k - 1]) << name << " n=" << kSides[k];
  EXPECT_GE(last, derived_rate - 0.1) << name;
}

// Solves with k = k0, 10 k0, …, k_final (tension homotopy), warm-started.
StaticSummary SolveStiff(Scene s, double k0, double k_final, const std::vector<int>& constrained, MatrixN3* x) {
  StaticSummary st;
  for (double k = k0; k <= k_final * 1.0001; k *= 10.0) {
    s.material.tension = {k, k};
    st = SolveStatic(ParticleSystem(s), constrained, {}, x);
    if (!st.converged) {
      st.message = "k = " + std::to_string(k) + ": " + st.message;
      return st;
    }
  }
  return st;
}

Scene BaseScene(int n) {
  Scene s;
  s.grid.nu = s.grid.nv = n;
  s.grid.size = {1.0, 1.0};
  s.grid.origin = Vector3::Zero();
  s.material.tension_damping = 0.0;
  s.material.shear = 0.0;
  s.material.bend = {0.0, 0.0};
  s.material.bend_model = BendModel::kNone;
  return s;
}

TEST(Chapter2, HangingTextile) {
  Sweep sw;
  const double f = 981.0, k = 1e4, len = 1.0;
  for (int n : kSides) {
    Scene s = BaseScene(n);
    s.grid.v_axis = Vector3(0.0, -1.0, 0.0);
    s.material.density = 100.0;
    s.material.tension = {k, k};
    s.forces.gravity = Vector3(0.0, -9.81, 0.0);
    s.fixed = ResolveFixed("edge:v0", n, n, "");
    const ParticleSystem sys(s);
    MatrixN3 x = sys.rest_positions();
    const StaticSummary st = SolveStatic(sys, {}, {}, &x);
    ASSERT_TRUE(st.converged) << st.message;
    MatrixN3 exact = sys.rest_positions();
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const double sj = j * s.lv();
        exact.row(s.Index(i, j)) += (f / k) * (len * sj - 0.5 * sj * sj) * s.grid.v_axis.transpose();
      }
    sw.l.push_back(s.lv());
    sw.e.push_back(ErrorRms(x, exact));
  }
  CheckSweep("hanging", sw, 1.0);
}

TEST(Chapter2, ShearedTextile) {
  Sweep sw;
  const double f = 10.0, mu = 100.0, len = 1.0, a = f / mu;
  auto g = [](double y) { return 0.5 * (y * std::sqrt(1 - y * y) + std::asin(y)); };
  for (int n : kSides) {
    Scene s = BaseScene(n);
    s.material.tension = {1e9, 1e9};
    s.material.shear = mu;
    s.forces.gravity = Vector3(f, 0.0, 0.0);  // ρ = 1: force density f along u, parallel to the fixed edge
    s.fixed = ResolveFixed("edge:v0", n, n, "");
    const ParticleSystem sys(s);
    MatrixN3 exact = sys.rest_positions();
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const double sj = j * s.lv();
        const double w = (f / mu) * (len * sj - 0.5 * sj * sj);
        const double contraction = (g(a * len) - g(a * (len - sj))) / a - sj;  // ∫₀ˢ (cos θ − 1)
        exact(s.Index(i, j), 0) += w;
        exact(s.Index(i, j), 1) += contraction;
      }
    MatrixN3 x = exact;
    const StaticSummary st = SolveStiff(s, 1e5, 1e9, {}, &x);
    ASSERT_TRUE(st.converged) << "n=" << n << ": " << st.message;
    double sum = 0.0;
    for (int p = 0; p < sys.num_particles(); ++p) sum += std::pow(x(p, 0) - exact(p, 0), 2);
    sw.l.push_back(s.lv());
    sw.e.push_back(std::sqrt(sum / sys.num_particles()));
    const int tip = s.Index(n / 2, n - 1);
    const double ratio = (x(tip, 1) - sys.rest_positions()(tip, 1)) / (exact(tip, 1) - sys.rest_positions()(tip, 1));
    std::printf("[ chapter 2 ] shear n=%d: free-edge contraction %.4e m, continuum %.4e m, ratio %.3f\n", n,
                x(tip, 1) - sys.rest_positions()(tip, 1), exact(tip, 1) - sys.rest_positions()(tip, 1), ratio);
    if (n >= 17) {
      EXPECT_GT(ratio, 1.15) << "the odd-even contraction defect changed; update the README and this test";
      EXPECT_LT(ratio, 1.35) << "the odd-even contraction defect changed; update the README and this test";
    }
  }
  CheckSweep("shear w", sw, 1.0);
}

TEST(Chapter2, BendingStrip) {
  Sweep sw;
  const double f = 1.0, bend = 5.0, span = 3.0;
  for (int n : kSides) {
    const double l = span / (n - 2);
    std::vector<double> s_nodes;
    for (int i = 1; i < n; ++i) s_nodes.push_back((i - 1) * l);
    const testing::ElasticaSolution ref = testing::SolveStripElastica(span, f, bend, s_nodes);
    ASSERT_TRUE(ref.ok) << ref.message;
    Scene s = BaseScene(n);
    s.grid.size = {l * (n - 1), 0.5};
    s.material.tension = {1e6, 1e6};
    s.material.bend = {bend, bend};
    s.material.bend_model = BendModel::kThinPlate;
    std::vector<int> fixed, roller;
    for (int j = 0; j < n; ++j) {
      fixed.push_back(s.Index(0, j));
      fixed.push_back(s.Index(1, j));
      roller.push_back(3 * s.Index(n - 1, j) + 2);  // z of the right column
    }
    std::sort(fixed.begin(), fixed.end());
    s.fixed = fixed;
    s.forces.gravity = Vector3(0.0, 0.0, -f);
    const ParticleSystem sys(s);
    MatrixN3 x = sys.rest_positions();
    for (int j = 0; j < n; ++j)
      for (int i = 1; i < n; ++i) {
        x(s.Index(i, j), 0) = l + ref.x[static_cast<std::size_t>(i - 1)];
        x(s.Index(i, j), 2) = ref.z[static_cast<std::size_t>(i - 1)];
      }
    const StaticSummary st = SolveStiff(s, 1e3, 1e6, roller, &x);
    ASSERT_TRUE(st.converged) << "n=" << n << ": " << st.message;
    double sum = 0.0;
    int count = 0;
    for (int j = 0; j < n; ++j)
      for (int i = 1; i < n; ++i) {
        const double dx = (x(s.Index(i, j), 0) - l) - ref.x[static_cast<std::size_t>(i - 1)];
        const double dz = x(s.Index(i, j), 2) - ref.z[static_cast<std::size_t>(i - 1)];
        sum += dx * dx + dz * dz;
        ++count;
      }
    sw.l.push_back(l);
    sw.e.push_back(std::sqrt(sum / count));
    if (n == kSides.back())
      std::printf("[ chapter 2 ] elastica: kappa(0) = %.5f 1/m, T(0) = %.5f N/m, roller moved in by %.4f m, max sag %.4f m\n",
                  ref.kappa0, ref.tension0, span - ref.x.back(),
                  -*std::min_element(ref.z.begin(), ref.z.end()));
  }
  CheckSweep("bending", sw, 1.0);
}

}  // namespace
}  // namespace clothbench
