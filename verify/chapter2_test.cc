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

#include <array>
#include <cmath>
#include <string>
#include <utility>

#include "results/metrics.h"
#include "solver/static_solve.h"
#include "verify/elastica.h"
#include "verify/test_scenes.h"

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

// The scene on the graded samples of testing::GradedSamples(α) when α > 0
// (docs/model.md §2.7): the threads stay straight, so the continuum solutions
// hold unchanged; α = 0 keeps the uniform grid.
Scene Sampled(const Scene& s, double alpha, double alpha_v = -1.0) {
  if (alpha == 0.0) return s;
  return testing::WithSamples(s, testing::GradedSamples(s.grid.nu, s.grid.nv, s.grid.size, alpha, alpha_v));
}

// The rest distance of particle p from the grid's origin along `axis`.
double Along(const ParticleSystem& sys, int p, const Vector3& axis) {
  return (sys.rest_positions().row(p).transpose() - sys.scene().grid.origin).dot(axis);
}

Sweep Hanging(double alpha) {
  Sweep sw;
  const double f = 981.0, k = 1e4, len = 1.0;
  for (int n : kSides) {
    Scene s = BaseScene(n);
    s.grid.v_axis = Vector3(0.0, -1.0, 0.0);
    s.material.density = 100.0;
    s.material.tension = {k, k};
    s.forces.gravity = Vector3(0.0, -9.81, 0.0);
    s.fixed = ResolveFixed("edge:v0", n, n, "");
    const double l = s.lv();
    s = Sampled(s, alpha);
    const ParticleSystem sys(s);
    MatrixN3 x = sys.rest_positions();
    const StaticSummary st = SolveStatic(sys, {}, {}, &x);
    EXPECT_TRUE(st.converged) << st.message;
    MatrixN3 exact = sys.rest_positions();
    for (int p = 0; p < sys.num_particles(); ++p) {
      const double sj = Along(sys, p, s.grid.v_axis);
      exact.row(p) += (f / k) * (len * sj - 0.5 * sj * sj) * s.grid.v_axis.transpose();
    }
    sw.l.push_back(l);
    sw.e.push_back(ErrorRms(x, exact));
  }
  return sw;
}

TEST(Chapter2, HangingTextile) { CheckSweep("hanging", Hanging(0.0), 1.0); }

Sweep Sheared(double alpha) {
  Sweep sw;
  const double f = 10.0, mu = 100.0, len = 1.0, a = f / mu;
  auto g = [](double y) { return 0.5 * (y * std::sqrt(1 - y * y) + std::asin(y)); };
  for (int n : kSides) {
    Scene s = BaseScene(n);
    s.material.tension = {1e9, 1e9};
    s.material.shear = mu;
    s.forces.gravity = Vector3(f, 0.0, 0.0);  // ρ = 1: force density f along u, parallel to the fixed edge
    s.fixed = ResolveFixed("edge:v0", n, n, "");
    const double l = s.lv();
    s = Sampled(s, alpha);
    const ParticleSystem sys(s);
    MatrixN3 exact = sys.rest_positions();
    for (int p = 0; p < sys.num_particles(); ++p) {
      const double sj = Along(sys, p, s.grid.v_axis);
      const double w = (f / mu) * (len * sj - 0.5 * sj * sj);
      const double contraction = (g(a * len) - g(a * (len - sj))) / a - sj;  // ∫₀ˢ (cos θ − 1)
      exact(p, 0) += w;
      exact(p, 1) += contraction;
    }
    MatrixN3 x = exact;
    const StaticSummary st = SolveStiff(s, 1e5, 1e9, {}, &x);
    EXPECT_TRUE(st.converged) << "n=" << n << ": " << st.message;
    double sum = 0.0;
    for (int p = 0; p < sys.num_particles(); ++p) sum += std::pow(x(p, 0) - exact(p, 0), 2);
    sw.l.push_back(l);
    sw.e.push_back(std::sqrt(sum / sys.num_particles()));
    const int tip = s.Index(n / 2, n - 1);
    const double ratio = (x(tip, 1) - sys.rest_positions()(tip, 1)) / (exact(tip, 1) - sys.rest_positions()(tip, 1));
    std::printf("[ chapter 2 ] shear n=%d: free-edge contraction %.4e m, continuum %.4e m, ratio %.3f\n", n,
                x(tip, 1) - sys.rest_positions()(tip, 1), exact(tip, 1) - sys.rest_positions()(tip, 1), ratio);
    if (n >= 17 && alpha == 0.0) {
      EXPECT_GT(ratio, 1.15) << "the odd-even contraction defect changed; update docs/notes/verification.md and this test";
      EXPECT_LT(ratio, 1.35) << "the odd-even contraction defect changed; update docs/notes/verification.md and this test";
    }
  }
  return sw;
}

TEST(Chapter2, ShearedTextile) { CheckSweep("shear w", Sheared(0.0), 1.0); }

Sweep Bending(double alpha) {
  Sweep sw;
  const double f = 1.0, bend = 5.0;
  for (int n : kSides) {
    const double l = 3.0 / (n - 2);
    // Node i's rest coordinate along the strip; the clamp is columns 0 and 1.
    const Eigen::MatrixX2d plane = testing::GradedSamples(n, n, {l * (n - 1), 0.5}, alpha, 0.0);
    const double clamp = plane(1, 0), span = plane(n - 1, 0) - clamp;
    std::vector<double> s_nodes;
    for (int i = 1; i < n; ++i) s_nodes.push_back(plane(i, 0) - clamp);
    const testing::ElasticaSolution ref = testing::SolveStripElastica(span, f, bend, s_nodes);
    EXPECT_TRUE(ref.ok) << ref.message;
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
    s = Sampled(s, alpha, 0.0);
    const ParticleSystem sys(s);
    MatrixN3 x = sys.rest_positions();
    for (int j = 0; j < n; ++j)
      for (int i = 1; i < n; ++i) {
        x(s.Index(i, j), 0) = clamp + ref.x[static_cast<std::size_t>(i - 1)];
        x(s.Index(i, j), 2) = ref.z[static_cast<std::size_t>(i - 1)];
      }
    const StaticSummary st = SolveStiff(s, 1e3, 1e6, roller, &x);
    EXPECT_TRUE(st.converged) << "n=" << n << ": " << st.message;
    double sum = 0.0;
    int count = 0;
    for (int j = 0; j < n; ++j)
      for (int i = 1; i < n; ++i) {
        const double dx = (x(s.Index(i, j), 0) - clamp) - ref.x[static_cast<std::size_t>(i - 1)];
        const double dz = x(s.Index(i, j), 2) - ref.z[static_cast<std::size_t>(i - 1)];
        sum += dx * dx + dz * dz;
        ++count;
      }
    sw.l.push_back(l);
    sw.e.push_back(std::sqrt(sum / count));
    if (n == kSides.back() && alpha == 0.0)
      std::printf("[ chapter 2 ] elastica: kappa(0) = %.5f 1/m, T(0) = %.5f N/m, roller moved in by %.4f m, max sag %.4f m\n",
                  ref.kappa0, ref.tension0, span - ref.x.back(),
                  -*std::min_element(ref.z.begin(), ref.z.end()));
  }
  return sw;
}

TEST(Chapter2, BendingStrip) { CheckSweep("bending", Bending(0.0), 1.0); }

// The three experiments on graded samples (α = 0.4: spacings 1.4 : 0.6 from
// edge to edge, so the largest is 1.4 times the uniform grid's l): the same
// derived rates; and since every error is O(l_max), at most 1.4² ≈ 2 times the
// uniform grid's at the same n (the square: the constant of the leading term
// also moves with the grading). The bending strip is graded along its span
// only: graded across it as well, the static solve's residual line search
// stalls at max|f| ≈ 2e-6 N at n = 9 and 33 (k = 1e3, the homotopy's first
// stage), a stationary point of ‖f‖₂ of the non-conservative projected
// bending force, not of f.
TEST(Chapter2, GradedSamplingConvergesAtTheUniformRate) {
  const std::array<std::pair<const char*, Sweep (*)(double)>, 3> experiments = {
      {{"hanging", &Hanging}, {"shear w", &Sheared}, {"bending", &Bending}}};
  for (const auto& [name, run] : experiments) {
    const Sweep uniform = run(0.0), graded = run(0.4);
    CheckSweep((std::string(name) + " α=0.4").c_str(), graded, 1.0);
    for (std::size_t k = 0; k < graded.e.size(); ++k)
      EXPECT_LT(graded.e[k], 2.0 * uniform.e[k]) << name << " n=" << kSides[k] << ": graded " << graded.e[k]
                                                 << ", uniform " << uniform.e[k];
  }
}

// A trapezoid pattern (Coons-sampled, docs/model.md §2.7: neither uniform
// nor orthogonal) hangs from its narrow top edge under in-plane gravity,
// tension and shear, on n×n samples, n = 5 … 65. Without a continuum
// solution it is checked against itself: e_n = rms over the n×n nodes of
// |x_n − x_{2n−1}| (every coarse node is a fine one), and the observed order
// between successive e_n. The uniform mass lumping's free-edge load is
// O(l), as in the hanging textile, so the derived order is 1; the test asserts
// that e falls at every refinement and the last order is at least 0.9 (the
// 0.1 covers the pre-asymptotic terms, as for the uniform grids above).
TEST(Chapter2, TrapezoidSelfConverges) {
  const std::vector<int> sides = {5, 9, 17, 33, 65};
  std::vector<MatrixN3> solutions;
  for (int n : sides) {
    PatternSpec p;
    p.name = "skirt";
    p.corners = {Vector2(0.0, 0.0), Vector2(1.0, 0.0), Vector2(0.8, 1.0), Vector2(0.2, 1.0)};
    const auto& ends = PatternSpec::kSideCorners;
    for (std::size_t k = 0; k < 4; ++k) p.sides[k] = {p.corners[ends[k][0]], p.corners[ends[k][1]]};
    p.nu = p.nv = n;
    Scene s = BaseScene(n);
    s.material.tension = {1e3, 1e3};
    s.material.shear = 50.0;
    s.forces.gravity = Vector3(0.0, -9.81, 0.0);
    SetCurvilinearCloth(&s, p, SamplePattern(p));
    s.fixed = ResolveFixed("edge:v1", n, n, "");
    const ParticleSystem sys(s);
    MatrixN3 x = sys.rest_positions();
    const StaticSummary st = SolveStatic(sys, {}, {}, &x);
    ASSERT_TRUE(st.converged) << "n=" << n << ": " << st.message;
    solutions.push_back(x);
  }
  std::vector<double> e, orders;
  std::printf("[ chapter 2 ] trapezoid");
  for (std::size_t k = 0; k + 1 < sides.size(); ++k) {
    const int n = sides[k], fine = sides[k + 1];
    double sum = 0.0;
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i)
        sum += (solutions[k].row(i + n * j) - solutions[k + 1].row(2 * i + fine * 2 * j)).squaredNorm();
    e.push_back(std::sqrt(sum / (n * n)));
    std::printf(" n=%d e=%.3e", n, e.back());
    if (k > 0) orders.push_back(std::log2(e[k - 1] / e[k]));
  }
  std::printf("  orders");
  for (double o : orders) std::printf(" %.2f", o);
  std::printf(" (derived 1)\n");
  for (std::size_t k = 1; k < e.size(); ++k) EXPECT_LT(e[k], e[k - 1]) << "n=" << sides[k];
  EXPECT_GE(orders.back(), 0.9);
}

}  // namespace
}  // namespace clothbench
