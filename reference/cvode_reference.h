// SUNDIALS CVODE reference (SPEC §8): variable-order BDF with Newton
// iteration and KLU on the analytic sparse Jacobian, integrating
//   ẋ = v,  v̇ = M⁻¹ f(t, x, v)                                        (3.13)
// on the free degrees of freedom (fixed particles stay at rest). At
// rtol ≤ 1e-10 it produces the reference trajectory; at looser rtol it is a
// competitor row of the bench table.
#ifndef CLOTHBENCH_REFERENCE_CVODE_REFERENCE_H_
#define CLOTHBENCH_REFERENCE_CVODE_REFERENCE_H_

#include <string>
#include <vector>

#include "model/particle_system.h"
#include "solver/run.h"

namespace clothbench {

struct CvodeOptions {
  double rtol = 1e-10;     ///< relative tolerance
  double atol = -1.0;      ///< absolute tolerance [m, m/s]; < 0: atol = rtol
  int max_order = 5;       ///< BDF order limit (1..5)
  double t_end = 1.0;      ///< [s]
  double frame_dt = 0.01;  ///< [s]
};

/// CVODE counters (CVodePrintAllStats names).
struct CvodeStats {
  long nst = -1;    ///< steps
  long nfe = -1;    ///< right-hand side evaluations
  long nni = -1;    ///< nonlinear (Newton) iterations
  long nli = -1;    ///< linear iterations (0 for the direct KLU solver)
  long netf = -1;   ///< error test failures
  long ncfn = -1;   ///< nonlinear convergence failures
  long nje = -1;    ///< Jacobian evaluations
  long nsetups = -1;  ///< linear solver setups (KLU factorisations)
};

struct CvodeResult {
  bool ok = false;
  std::string status = "not_run";  ///< "ok" or the CVODE failure flag name
  std::string message;
  CvodeStats stats;
  double solver_time_in_seconds = -1.0;
  double wall_time_in_seconds = -1.0;
  Trajectory trajectory;
  std::vector<double> step_t, step_h;  ///< step history from CV_ONE_STEP mode
  std::vector<int> step_order;
};

/// Integrates `system` from rest to options.t_end; frames by CVODE's dense
/// output (CVodeGetDky). Never throws for solver failure: see status.
CvodeResult RunCvode(const ParticleSystem& system, const CvodeOptions& options);

}  // namespace clothbench

#endif  // CLOTHBENCH_REFERENCE_CVODE_REFERENCE_H_
