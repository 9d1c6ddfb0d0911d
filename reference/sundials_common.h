// Shared parts of the SUNDIALS references (SPEC §8): options, counters,
// results, the one-step frame loop and the sparse-matrix copy.
#ifndef CLOTHBENCH_REFERENCE_SUNDIALS_COMMON_H_
#define CLOTHBENCH_REFERENCE_SUNDIALS_COMMON_H_

#include <functional>
#include <string>
#include <vector>

#include "model/particle_system.h"
#include "solver/run.h"

namespace clothbench {

struct ReferenceOptions {
  double rtol = 1e-10;     ///< relative tolerance
  double atol = -1.0;      ///< absolute tolerance [m, m/s]; < 0: atol = rtol
  int max_order = 5;       ///< BDF order limit (1..5)
  double t_end = 1.0;      ///< [s]
  double frame_dt = 0.01;  ///< [s]
  double AbsoluteTolerance() const { return atol > 0.0 ? atol : rtol; }
};

/// SUNDIALS counters (CVodePrintAllStats / IDAPrintAllStats names).
struct ReferenceStats {
  long nst = -1;      ///< steps
  long nfe = -1;      ///< right-hand side (CVODE), residual (IDA) or explicit f_E (ARKODE) evaluations
  long nfe_i = -1;    ///< implicit f_I evaluations (ARKODE only)
  long nni = -1;      ///< nonlinear (Newton) iterations
  long nli = -1;      ///< linear iterations (0 for the direct KLU solver)
  long netf = -1;     ///< error test failures
  long ncfn = -1;     ///< nonlinear convergence failures
  long nje = -1;      ///< Jacobian evaluations
  long nsetups = -1;  ///< linear solver setups (KLU factorisations)
};

struct ReferenceResult {
  bool ok = false;
  std::string integrator;          ///< "cvode", "ida" or "bdf2_self_convergence"
  double h = 0.0;                  ///< fixed step [s] of a self-convergence reference; 0 for SUNDIALS
  std::string status = "not_run";  ///< "ok" or the SUNDIALS flag name
  std::string message;
  ReferenceStats stats;
  double solver_time_in_seconds = -1.0;
  double setup_time_in_seconds = -1.0;  ///< matrix and preconditioner setup (ARKODE's reduced solve) [s]
  double wall_time_in_seconds = -1.0;
  Trajectory trajectory;
  std::vector<double> step_t, step_h;  ///< step history from one-step mode
  std::vector<int> step_order;
  std::vector<double> step_time;  ///< wall time of each one-step call [s]
};

namespace internal {

/// Calls of one SUNDIALS integrator used by the shared frame loop.
struct OneStepDriver {
  /// Takes one internal step towards t_end; returns the flag, sets t.
  std::function<int(double* t)> step;
  /// Positions and velocities at time tf inside the last step (dense output).
  std::function<int(double tf, MatrixN3* x, MatrixN3* v)> state_at;
  /// Positions and velocities at the current time.
  std::function<void(MatrixN3* x, MatrixN3* v)> current_state;
  std::function<void(double* h, int* order)> last_step;
  std::function<std::string(int flag)> flag_name;
};

/// Runs the one-step loop (the Debian build has no monitoring) storing the
/// step history and the frames 0, frame_dt, …, t_end. `error` holds the
/// message of the SUNDIALS error handler, if any.
void RunFrames(const OneStepDriver& d, const ParticleSystem& system, const ReferenceOptions& options,
               const std::string& error, ReferenceResult* res);

/// The free degrees of freedom of a particle system as a SUNDIALS state
/// y = [x_free; v_free] (6·N_free entries; fixed particles are not
/// unknowns and stay at rest), used by the CVODE reference and ARKODE.
class FreeDofMap {
 public:
  explicit FreeDofMap(const ParticleSystem& system);
  int num_free() const { return static_cast<int>(free_.size()); }
  int size() const { return 6 * num_free(); }
  /// Flat particle index of free particle k.
  int particle(int k) const { return free_[static_cast<std::size_t>(k)]; }
  /// Free index of particle p, −1 if p is fixed.
  int free_index(int p) const { return free_index_[static_cast<std::size_t>(p)]; }
  /// y from N×3 positions [m] and velocities [m/s].
  void ToY(const MatrixN3& x, const MatrixN3& v, double* y) const;
  /// N×3 positions from y, fixed particles at rest.
  void PositionsFromY(const double* y, MatrixN3* x) const;
  /// N×3 velocities from y, fixed particles 0.
  void VelocitiesFromY(const double* y, MatrixN3* v) const;

 private:
  const ParticleSystem& sys_;
  std::vector<int> free_, free_index_;
};

/// A SUNDIALS error handler (CVErrHandlerFn, IDAErrHandlerFn,
/// ARKErrHandlerFn) that stores "<module> <function> (flag <code>): <msg>"
/// in the std::string passed as its user data.
void StoreErrorMessage(int code, const char* module, const char* function, char* msg, void* error_string);

/// Records the first failing setup call in `res`: status = the flag's name
/// (`flag_name`: CVodeGetReturnFlagName, …), message = the error handler's
/// text `error` or "<call> failed with <flag>". Returns flag >= 0.
bool CheckFlag(int flag, const char* call, char* (*flag_name)(long int), const std::string& error,
               ReferenceResult* res);

/// Copies a compressed-column Eigen matrix into a SUNDIALS CSC matrix
/// (reallocating if needed). Returns 0 or −1.
int CopyToSunSparse(const SparseMatrix& j, void* sun_matrix);

}  // namespace internal
}  // namespace clothbench

#endif  // CLOTHBENCH_REFERENCE_SUNDIALS_COMMON_H_
