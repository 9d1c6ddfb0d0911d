// The integrators the executables run by name: the thesis' methods (each
// fully implicit one with the fixed point of Alg. 6 or with Newton) and the
// peers. Row labels name the nonlinear solver when it is Newton, e.g.
// "bdf2/newton". The SUNDIALS references (cvode, ida) are handled by the
// executables themselves.
#ifndef CLOTHBENCH_BENCH_METHODS_H_
#define CLOTHBENCH_BENCH_METHODS_H_

#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "model/particle_system.h"
#include "peers/baraff_witkin.h"
#include "solver/integrator.h"

namespace clothbench {

/// One row's integrator: a thesis method with its nonlinear solver, or a peer.
struct RowMethod {
  std::string name;                 ///< "bdf2", "baraff_witkin", …
  std::optional<Method> method;     ///< empty for a peer
  NonlinearSolver solver = NonlinearSolver::kFixedPoint;
  /// "bdf2" (fixed point, IMEX and explicit methods), "bdf2/newton", "baraff_witkin".
  std::string label() const {
    return solver == NonlinearSolver::kNewton ? name + "/" + std::string(ToString(solver)) : name;
  }
  /// The label as an HDF5 group-name part ("bdf2_newton").
  std::string id() const {
    std::string s = label();
    for (char& c : s)
      if (c == '/') c = '_';
    return s;
  }
  bool fully_implicit() const { return method && IsFullyImplicit(*method); }
  /// The stepper on `sys` with the scene's solver settings, the nonlinear
  /// solver replaced by this row's.
  std::unique_ptr<Stepper> Make(const ParticleSystem& sys, SolverSpec spec) const {
    spec.nonlinear_solver = solver;
    if (!method) return std::make_unique<BaraffWitkin>(sys, spec);
    return std::make_unique<StepEngine>(sys, *method, spec);
  }
};

/// The known names, for messages.
inline std::string KnownMethodNames() {
  std::string s;
  for (Method m : AllMethods()) s += std::string(ToString(m)) + ", ";
  return s + std::string(ToString(Method::kSymplecticEuler)) + ", " + std::string(kBaraffWitkinName);
}

/// Parses "fixed_point" | "newton". @throws std::invalid_argument naming `option`.
inline NonlinearSolver ParseNonlinearSolver(const std::string& s, const std::string& option) {
  for (NonlinearSolver n : {NonlinearSolver::kFixedPoint, NonlinearSolver::kNewton})
    if (s == ToString(n)) return n;
  throw std::invalid_argument(fmt::format("{}: \"{}\" must be fixed_point or newton", option, s));
}

/// One RowMethod per name; a fully implicit method gives one per solver in
/// `solvers` (in that order), any other method one row. A name may carry its
/// solver itself: "bdf2/newton".
/// @param also further names the caller accepts, for the message ("cvode, ida")
/// @throws std::invalid_argument for an unknown name or solver, naming `option`.
inline std::vector<RowMethod> ExpandMethods(const std::vector<std::string>& names,
                                            const std::vector<NonlinearSolver>& solvers, const std::string& option,
                                            const std::string& also = "") {
  std::vector<RowMethod> out;
  for (const std::string& full : names) {
    const auto slash = full.find('/');
    const std::string name = full.substr(0, slash);
    RowMethod r;
    r.name = name;
    r.method = MethodFromString(name);
    if (!r.method && name != kBaraffWitkinName)
      throw std::invalid_argument(fmt::format("{}: unknown integrator \"{}\" (expected {}{})", option, full,
                                              KnownMethodNames(), also.empty() ? "" : ", " + also));
    if (slash != std::string::npos) {
      if (!r.fully_implicit())
        throw std::invalid_argument(fmt::format("{}: \"{}\": only implicit_euler, bdf2 and implicit_midpoint take a "
                                                "nonlinear solver",
                                                option, full));
      r.solver = ParseNonlinearSolver(full.substr(slash + 1), option);
      out.push_back(r);
    } else if (r.fully_implicit()) {
      for (NonlinearSolver s : solvers) {
        r.solver = s;
        out.push_back(r);
      }
    } else {
      out.push_back(r);
    }
  }
  return out;
}

}  // namespace clothbench

#endif  // CLOTHBENCH_BENCH_METHODS_H_
