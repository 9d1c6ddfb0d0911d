// Shooting solution of the strip's continuum limit (elastica.md) with CVODE.
#include "verify/elastica.h"

#include <array>
#include <cmath>

#include <Eigen/Dense>
#include <cvode/cvode.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunnonlinsol/sunnonlinsol_fixedpoint.h>

namespace clothbench::testing {
namespace {

struct Params {
  double f, b;
};

// y = (θ, κ, κ', T, x, z).
int Rhs(realtype, N_Vector yv, N_Vector ydv, void* user) {
  const Params& p = *static_cast<Params*>(user);
  const double* y = N_VGetArrayPointer(yv);
  double* yd = N_VGetArrayPointer(ydv);
  const double th = y[0], k = y[1], dk = y[2], t = y[3];
  yd[0] = k;
  yd[1] = dk;
  yd[2] = k * k * k + (t * k - p.f * std::cos(th)) / p.b;
  yd[3] = p.f * std::sin(th);
  yd[4] = std::cos(th);
  yd[5] = std::sin(th);
  return 0;
}

// Integrates from s = 0 with the given unknowns; returns y at each of `outs`
// (sorted, the last one is L).
bool Shoot(const Params& p, const std::array<double, 3>& u, const std::vector<double>& outs,
           std::vector<std::array<double, 6>>* ys) {
  SUNContext ctx = nullptr;
  SUNContext_Create(nullptr, &ctx);
  N_Vector y = N_VNew_Serial(6, ctx);
  double* yy = N_VGetArrayPointer(y);
  yy[0] = 0.0;
  yy[1] = u[0];
  yy[2] = u[1];
  yy[3] = u[2];
  yy[4] = 0.0;
  yy[5] = 0.0;
  void* mem = CVodeCreate(CV_ADAMS, ctx);
  SUNNonlinearSolver nls = SUNNonlinSol_FixedPoint(y, 0, ctx);
  Params pp = p;
  bool ok = CVodeInit(mem, Rhs, 0.0, y) >= 0 && CVodeSStolerances(mem, 1e-12, 1e-14) >= 0 &&
            CVodeSetUserData(mem, &pp) >= 0 && CVodeSetNonlinearSolver(mem, nls) >= 0 &&
            CVodeSetMaxNumSteps(mem, 1000000) >= 0;
  ys->clear();
  double t = 0.0;
  for (double s : outs) {
    if (!ok) break;
    if (s > t) ok = CVode(mem, s, y, &t, CV_NORMAL) >= 0;
    std::array<double, 6> row{};
    for (int k = 0; k < 6; ++k) row[static_cast<std::size_t>(k)] = yy[k];
    ys->push_back(row);
  }
  CVodeFree(&mem);
  SUNNonlinSolFree(nls);
  N_VDestroy(y);
  SUNContext_Free(&ctx);
  return ok;
}

}  // namespace

ElasticaSolution SolveStripElastica(double length, double load, double bend, const std::vector<double>& s) {
  ElasticaSolution sol;
  std::array<double, 3> u = {-load * length * length / (8 * bend), 5 * load * length / (8 * bend), 0.0};
  std::vector<std::array<double, 6>> ys;
  auto residual = [&](const Params& p, const std::array<double, 3>& uu, Eigen::Vector3d* r) {
    if (!Shoot(p, uu, {length}, &ys)) return false;
    *r = Eigen::Vector3d(ys.back()[1], ys.back()[5], ys.back()[3]);  // κ(L), z(L), T(L)
    return r->allFinite();
  };
  const int kSteps = 10;
  for (int step = 1; step <= kSteps; ++step) {  // continuation in the load
    const Params p{load * step / kSteps, bend};
    Eigen::Vector3d r;
    bool converged = false;
    for (int it = 0; it < 50 && !converged; ++it) {
      if (!residual(p, u, &r)) {
        sol.message = "shooting integration failed";
        return sol;
      }
      if (r.cwiseAbs().maxCoeff() < 1e-12) {
        converged = true;
        break;
      }
      Eigen::Matrix3d j;
      for (int c = 0; c < 3; ++c) {
        const double d = 1e-6 * std::max(1.0, std::abs(u[static_cast<std::size_t>(c)]));
        std::array<double, 3> up = u, um = u;
        up[static_cast<std::size_t>(c)] += d;
        um[static_cast<std::size_t>(c)] -= d;
        Eigen::Vector3d rp, rm;
        if (!residual(p, up, &rp) || !residual(p, um, &rm)) {
          sol.message = "shooting integration failed";
          return sol;
        }
        j.col(c) = (rp - rm) / (2 * d);
      }
      const Eigen::Vector3d du = j.fullPivLu().solve(-r);
      for (int c = 0; c < 3; ++c) u[static_cast<std::size_t>(c)] += du(c);
    }
    if (!converged) {
      sol.message = "Newton on the shooting unknowns did not converge";
      return sol;
    }
    sol.shooting_residual = r.cwiseAbs().maxCoeff();
  }
  std::vector<double> outs = s;
  outs.push_back(length);
  if (!Shoot({load, bend}, u, outs, &ys)) {
    sol.message = "final integration failed";
    return sol;
  }
  for (std::size_t k = 0; k < s.size(); ++k) {
    sol.x.push_back(ys[k][4]);
    sol.z.push_back(ys[k][5]);
  }
  sol.kappa0 = u[0];
  sol.dkappa0 = u[1];
  sol.tension0 = u[2];
  sol.ok = true;
  return sol;
}

}  // namespace clothbench::testing
