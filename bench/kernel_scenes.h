// The sheets the kernel microbenchmarks time (bench_kernels.cc): side×side
// particles 0.04 m apart with the default scene's material, on the grid's
// path or as one pattern on its own rest geometry, and a deformed, moving
// state of them.
#ifndef CLOTHBENCH_BENCH_KERNEL_SCENES_H_
#define CLOTHBENCH_BENCH_KERNEL_SCENES_H_

#include <cmath>
#include <utility>

#include "model/particle_system.h"
#include "model/pattern.h"
#include "harness/methods.h"
#include "solver/integrator.h"

namespace clothbench {

inline Scene SquareScene(int side) {
  Scene s = DefaultScene();
  s.grid.nu = s.grid.nv = side;
  s.grid.size = {0.04 * (side - 1), 0.04 * (side - 1)};
  s.fixed = {s.Index(0, side - 1), s.Index(side - 1, side - 1)};
  return s;
}

// The same sheet as one pattern on its own rest geometry (the curvilinear
// path of docs/model.md §2.7: per-centre rest chords, angle and area),
// its samples the grid's: the cost of that path against the grid's.
inline Scene SquarePatternScene(int side) {
  Scene s = SquareScene(side);
  PatternSpec p;
  p.name = "cloth";
  p.nu = p.nv = side;
  p.origin = s.grid.origin;
  p.x_axis = s.grid.u_axis;
  p.y_axis = s.grid.v_axis;
  Eigen::MatrixX2d plane(side * side, 2);
  for (int j = 0; j < side; ++j)
    for (int i = 0; i < side; ++i) plane.row(i + side * j) << 0.04 * i, 0.04 * j;
  SetCurvilinearCloth(&s, p, std::move(plane));
  return s;
}

// A deformed, moving state: the sheet after 0.2 s of swinging (the
// self-convergence method, BDF(2));
// above 40×40 a smooth fold with a velocity field of the same shape (the
// swing would dominate the benchmark's setup).
inline void SwungState(const ParticleSystem& sys, MatrixN3* x, MatrixN3* v) {
  if (sys.num_particles() > 1600) {
    *x = sys.rest_positions();
    v->setZero(sys.num_particles(), 3);
    for (int p = 0; p < sys.num_particles(); ++p) {
      const double u = (*x)(p, 0), w = (*x)(p, 1);
      (*x)(p, 2) += 0.05 * std::sin(4.0 * u) * std::cos(3.0 * w);
      (*x)(p, 0) *= 1.0 + 0.01 * std::cos(5.0 * w);
      (*v)(p, 2) = 0.3 * std::cos(2.0 * u + w);
      (*v)(p, 0) = 0.1 * std::sin(3.0 * w);
    }
    return;
  }
  StepEngine e(sys, *MethodFromString(SelfConvergenceMethod().name), sys.scene().solver);
  e.Reset(0.0, sys.rest_positions(), MatrixN3::Zero(sys.num_particles(), 3));
  for (int k = 0; k < 80; ++k) e.Step(0.0025);
  *x = e.x();
  *v = e.v();
}

}  // namespace clothbench

#endif  // CLOTHBENCH_BENCH_KERNEL_SCENES_H_
