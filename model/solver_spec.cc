// Names and validation of the solver settings (model/solver_spec.h).
#include "model/solver_spec.h"

#include <fmt/format.h>

namespace clothbench {

std::string_view ToString(PreconditionerType p) {
  switch (p) {
    case PreconditionerType::kNone: return "none";
    case PreconditionerType::kJacobi: return "jacobi";
    case PreconditionerType::kIc0: return "ic0";
    case PreconditionerType::kCholesky: return "cholesky";
    case PreconditionerType::kAmg: return "amg";
    case PreconditionerType::kAuto: return "auto";
  }
  return "?";
}
std::string_view ToString(CholeskyOrdering o) { return o == CholeskyOrdering::kMetis ? "metis" : "amd"; }
std::string_view ToString(AmgFrames f) {
  return f == AmgFrames::kAdaptive ? "adaptive" : f == AmgFrames::kNearestAxis ? "nearest_axis" : "spread";
}
std::string_view ToString(Predictor p) {
  return p == Predictor::kConstantVelocity ? "constant" : "extrapolate";
}
std::string_view ToString(CgReference r) {
  return r == CgReference::kFixedOnly ? "fixed_only" : "filtered";
}
std::string_view ToString(NonlinearSolver s) {
  return s == NonlinearSolver::kFixedPoint ? "fixed_point" : "newton";
}
std::string_view ToString(ContactHistory c) {
  switch (c) {
    case ContactHistory::kKeep: return "keep";
    case ContactHistory::kRestart: return "restart";
    case ContactHistory::kProject: return "project";
    case ContactHistory::kLand: return "land";
  }
  return "keep";
}

std::string_view ToString(FrictionLaw f) {
  switch (f) {
    case FrictionLaw::kExplicit: return "explicit";
    case FrictionLaw::kRegularised: return "regularised";
    case FrictionLaw::kImplicit: return "implicit";
    case FrictionLaw::kImplicitIterated: return "implicit_iterated";
  }
  return "?";
}

std::string_view ToString(FrictionCap f) {
  switch (f) {
    case FrictionCap::kMass: return "mass";
    case FrictionCap::kSystem: return "system";
    case FrictionCap::kStiction: return "stiction";
  }
  return "?";
}

std::string_view ToString(NewtonJacobian j) {
  return j == NewtonJacobian::kRefresh ? "refresh" : "frozen";
}
std::string_view ToString(TangentProjection p) {
  return p == TangentProjection::kClamp ? "clamp" : "none";
}
std::string_view ToString(StepControl s) {
  return s == StepControl::kFixed ? "fixed" : s == StepControl::kIterations ? "iterations" : "error";
}

bool SolverSpec::IsValid(std::string* error) const {
  auto fail = [error](std::string msg) {
    if (error) *error = std::move(msg);
    return false;
  };
  if (!(cg_tolerance > 0.0 && cg_tolerance < 1.0)) return fail(fmt::format("cg_tolerance = {} must be in (0, 1)", cg_tolerance));
  if (cg_max_iterations < 1) return fail(fmt::format("cg_max_iterations = {} must be >= 1", cg_max_iterations));
  if (max_updates < 1) return fail(fmt::format("max_updates = {} must be >= 1", max_updates));
  if (controller_updates[0] < 1 || controller_updates[0] > controller_updates[1])
    return fail(fmt::format("controller_updates = [{}, {}] must satisfy 1 <= lo <= hi", controller_updates[0],
                            controller_updates[1]));
  if (!(fixed_point_tolerance >= 0.0)) return fail(fmt::format("fixed_point_tolerance = {} must be >= 0", fixed_point_tolerance));
  if (!(step_factor > 1.0)) return fail(fmt::format("step_factor = {} must be > 1", step_factor));
  if (!(h_min > 0.0)) return fail(fmt::format("h_min = {} must be > 0", h_min));
  if (!(h_max >= 0.0)) return fail(fmt::format("h_max = {} must be >= 0", h_max));
  if (!(rtol > 0.0 && rtol < 1.0)) return fail(fmt::format("rtol = {} must be in (0, 1)", rtol));
  if (!(atol >= 0.0)) return fail(fmt::format("atol = {} must be >= 0", atol));
  if (max_rejections < 0) return fail(fmt::format("max_rejections = {} must be >= 0", max_rejections));
  if (IsImplicit(friction_law) && friction_cap != FrictionCap::kMass)
    return fail(fmt::format("friction_cap = \"{}\" caps an explicit friction impulse and friction_law = \"{}\" "
                            "has none to cap: leave friction_cap at \"mass\"",
                            ToString(friction_cap), ToString(friction_law)));
  if (friction_cap == FrictionCap::kStiction && friction_law == FrictionLaw::kRegularised)
    return fail("friction_cap = \"stiction\" holds particles in place and friction_law = \"regularised\" has no "
                "sticking: choose one");
  return true;
}

}  // namespace clothbench
