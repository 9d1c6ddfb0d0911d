// Vertex Block Descent (peers/vbd, docs/model.md §10).
//
// 1. Convergence to implicit Euler: VBD's fixed point is implicit Euler's
//    solution at the same h (every term in the local Newton steps), so as
//    the sweeps per step grow the trajectory approaches
//    implicit_euler/newton's (solved with η = 1e-10). On the default scene
//    over 0.5 s at h = 0.01 s the rms difference of the final positions
//    falls monotonically over 1, 4, 16, 64 sweeps, for VBD and for VBD
//    with Chebyshev acceleration at the ρ it measures. Gauss–Seidel
//    contracts by about 0.984 per sweep here (numerical stiffness 62.5), so
//    64 plain sweeps leave 5.1e-2 m as measured (bound 0.1 m), and the
//    accelerated ones 6.4e-5 m (bound 1e-4 m, the accuracy PD reaches;
//    with ρ from 128 sweeps instead of 512 it was 2.6e-4 m, so the bound
//    also guards the measurement of ρ). Over 5 steps, 1024 sweeps reach
//    the Newton solution to round-off (measured 5.5e-12 m; bound 1e-9 m),
//    so the fixed point is implicit Euler's.
// 2. Rest: a flat sheet at its rest lengths without gravity, two corners
//    fixed, is an equilibrium of every force; 100 steps leave it there to
//    round-off (1e-12 m), without drift or spin.
// 3. Threads: a colour's particles do not read each other, so a step is
//    bit-identical with 1 and 2 OpenMP threads (a 150 × 150 sheet, whose
//    colours are large enough to run in parallel; ρ given, not measured,
//    to spare the 512 sweeps of its measurement).
#include <gtest/gtest.h>

#include <omp.h>

#include <cmath>
#include <cstdio>

#include "harness/methods.h"
#include "peers/vbd.h"
#include "solver/integrator.h"
#include "verify/stepping.h"

namespace clothbench {
namespace {

using testing::AdvanceFromRest;
using testing::RmsDifference;

TEST(VertexBlockDescent, ConvergesToImplicitEulerWithTheIterations) {
  const ParticleSystem sys(BuiltinScene("swinging_sheet"));
  const double h = 0.01;
  const int steps = 50;
  const MatrixN3 x_ref = testing::ImplicitEulerNewtonFromRest(sys, h, steps);
  for (const ChebyshevSettings& cheb : {ChebyshevSettings{}, kVbdChebyshev}) {
    double last = 1e300;
    for (int k : {1, 4, 16, 64}) {
      VertexBlockDescent vbd(sys, k, cheb);
      const double d = RmsDifference(AdvanceFromRest(sys, vbd, h, steps), x_ref);
      std::printf("[ vbd%s ] %2d iterations (%d colours, rho %.4f): rms difference to implicit_euler/newton %.3e m\n",
                  cheb.on ? "/chebyshev" : "", k, vbd.colours(), vbd.rho(), d);
      EXPECT_LT(d, last) << k << " iterations";
      last = d;
    }
    EXPECT_LE(last, cheb.on ? 1e-4 : 0.1);
  }
  const MatrixN3 x5 = testing::ImplicitEulerNewtonFromRest(sys, h, 5);
  VertexBlockDescent many(sys, 1024);
  const double d = RmsDifference(AdvanceFromRest(sys, many, h, 5), x5);
  std::printf("[ vbd ] 1024 iterations, 5 steps: rms difference to implicit_euler/newton %.3e m\n", d);
  EXPECT_LE(d, 1e-9);
}

TEST(VertexBlockDescent, PinnedSheetAtRestStaysAtRest) {
  Scene scene = BuiltinScene("swinging_sheet");
  scene.forces.gravity = Vector3::Zero();
  const ParticleSystem sys(scene);
  for (const ChebyshevSettings& cheb : {ChebyshevSettings{}, kVbdChebyshev}) {
    VertexBlockDescent vbd(sys, 4, cheb);
    const MatrixN3 x = AdvanceFromRest(sys, vbd, 0.01, 100);
    EXPECT_LT((x - sys.rest_positions()).cwiseAbs().maxCoeff(), 1e-12) << cheb.on << " rho " << vbd.rho();
    EXPECT_LT(vbd.v().cwiseAbs().maxCoeff(), 1e-10);
  }
}

TEST(VertexBlockDescent, BitIdenticalForAnyThreadCount) {
  Scene scene = BuiltinScene("swinging_sheet");
  scene.grid.nu = scene.grid.nv = 150;
  const ParticleSystem sys(scene);
  const int threads = omp_get_max_threads();
  MatrixN3 x[2];
  for (int t : {1, 2}) {
    omp_set_num_threads(t);
    ChebyshevSettings cheb = kVbdChebyshev;
    cheb.rho = 0.98;
    VertexBlockDescent vbd(sys, 2, cheb);
    x[t - 1] = AdvanceFromRest(sys, vbd, 0.01, 3);
  }
  omp_set_num_threads(threads);
  EXPECT_TRUE((x[0].array() == x[1].array()).all());
  EXPECT_GT((x[0] - sys.rest_positions()).norm(), 1e-3);  // it moved
}

}  // namespace
}  // namespace clothbench
