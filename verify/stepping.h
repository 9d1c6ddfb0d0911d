// Helpers of the tests that run a stepper from rest and compare positions.
#ifndef CLOTHBENCH_VERIFY_STEPPING_H_
#define CLOTHBENCH_VERIFY_STEPPING_H_

#include <cmath>

#include <gtest/gtest.h>

#include "model/particle_system.h"
#include "solver/integrator.h"

namespace clothbench::testing {

/// The positions after `steps` steps of h from rest (every step must be ok).
inline MatrixN3 AdvanceFromRest(const ParticleSystem& sys, Stepper& stepper, double h, int steps) {
  stepper.Reset(0.0, sys.rest_positions(), MatrixN3::Zero(sys.num_particles(), 3));
  for (int k = 0; k < steps; ++k) {
    const StepStats st = stepper.Step(h);
    EXPECT_EQ(st.status, StepStatus::kOk) << "step " << k;
  }
  return stepper.x();
}

/// implicit_euler/newton's positions after `steps` steps of h from rest,
/// solved tightly (the CHOLMOD-preconditioned PCG at η = 1e-10): the
/// fixed point the iterated peers converge to.
inline MatrixN3 ImplicitEulerNewtonFromRest(const ParticleSystem& sys, double h, int steps) {
  SolverSpec newton = sys.scene().solver;
  newton.nonlinear_solver = NonlinearSolver::kNewton;
  newton.preconditioner = PreconditionerType::kCholesky;
  newton.cg_tolerance = 1e-10;
  StepEngine reference(sys, Method::kImplicitEuler, newton);
  return AdvanceFromRest(sys, reference, h, steps);
}

/// The rms over particles of the distance between two N×3 position sets [m].
inline double RmsDifference(const MatrixN3& a, const MatrixN3& b) {
  return (a - b).norm() / std::sqrt(static_cast<double>(a.rows()));
}

}  // namespace clothbench::testing

#endif  // CLOTHBENCH_VERIFY_STEPPING_H_
