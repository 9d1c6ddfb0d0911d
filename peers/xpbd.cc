// XPBD with substeps (Macklin, Müller, Chentanez 2016; Macklin et al. 2019,
// Algorithm 1; docs/model.md §10).
#include "peers/xpbd.h"

#include <chrono>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

#include "model/interrupt.h"
#include "peers/position_contacts.h"

namespace clothbench {

Vector3 Xpbd::ProjectDamper(Vector3* pa, Vector3* pb, const Vector3& xa, const Vector3& xb, double wa, double wb,
                            double damping, double dt) {
  const double bdt = damping * dt;
  const Vector3 dlambda = (-bdt / (1.0 + bdt * (wa + wb))) * ((*pb - xb) - (*pa - xa));
  *pa -= wa * dlambda;
  *pb += wb * dlambda;
  return dlambda;
}

double Xpbd::ProjectDistance(Vector3* pa, Vector3* pb, const Vector3& xa, const Vector3& xb, double wa, double wb,
                             double rest_length, double compliance, double damping, double dt) {
  const double w = wa + wb;
  const Vector3 d = *pb - *pa;
  const double len = d.norm();
  if (w == 0.0 || len == 0.0) return 0.0;
  const Vector3 n = d / len;  // ∇_b C = n, ∇_a C = −n
  const double c = len - rest_length;
  const double alpha = compliance / (dt * dt);  // α̃ = α/Δt² (Eq. 18 ff.)
  const double gamma = alpha * damping * dt;    // γ = α̃ β̃/Δt with β̃ = Δt² β (Eq. 26)
  // ∇C·(p − x) = n·((p_b − x_b) − (p_a − x_a)); λ = 0 in the one iteration.
  const double rate = gamma != 0.0 ? n.dot((*pb - xb) - (*pa - xa)) : 0.0;
  const double dlambda = (-c - gamma * rate) / ((1.0 + gamma) * w + alpha);
  *pa -= (wa * dlambda) * n;  // Δx = M⁻¹ ∇Cᵀ Δλ (Eq. 18)
  *pb += (wb * dlambda) * n;
  return dlambda;
}

Xpbd::Xpbd(const ParticleSystem& system, int substeps) : sys_(system), substeps_(substeps), proximity_(system) {
  if (substeps < 1) throw std::invalid_argument(fmt::format("xpbd: substeps = {} must be at least 1", substeps));
  const Scene& scene = system.scene();
  const MaterialSpec& mat = scene.material;
  const int n = system.num_particles();
  w_ = system.masses().cwiseInverse();
  for (int p : system.fixed()) w_(p) = 0.0;
  // Tension: the linear model's zero-rest-length springs have l = 0.
  const bool linear = mat.tension_model == TensionModel::kLinear;
  for (const Spring& s : system.springs())
    if (s.stiffness > 0.0 || s.damping > 0.0)
      distance_.push_back({s.a, s.b, linear ? 0.0 : s.rest_length,
                           s.stiffness > 0.0 ? 1.0 / s.stiffness : 0.0, s.damping});
  for (const Distance& d : distance_) has_dampers_ = has_dampers_ || d.damping > 0.0;
  const int nu = scene.grid.nu, nv = scene.grid.nv;
  const double lu = scene.grid.size[0] / (nu - 1), lv = scene.grid.size[1] / (nv - 1);
  const bool curvilinear = system.geometry().curvilinear();
  if (mat.shear > 0.0) {
    shear_compliance_ = curvilinear ? 1.0 / mat.shear : 1.0 / (mat.shear * lu * lv);
    shear_damping_ = curvilinear ? mat.shear_damping : mat.shear_damping * lu * lv;
    shear_.reserve(static_cast<std::size_t>(n));
    if (curvilinear) {  // each centre's rest geometry (docs/model.md §2.7–2.8)
      ForEachCentre(*system.geometry().cloth, [&](const ClothBlock& b, int i, int j, int c) {
        const auto at = [&](int a, int bb) { return b.At(a, bb) >= 0 ? b.At(a, bb) : c; };
        const CentreRest r = CentreRestAt(b, i, j);
        shear_.push_back({{c, at(i + 1, j), at(i - 1, j), at(i, j + 1), at(i, j - 1)}, r.du, r.dv, r.gamma0, 1.0 / r.area, r.area});
      });
    }
    for (int j = 0; j < nv && !curvilinear; ++j)
      for (int i = 0; i < nu; ++i) {
        const int c = scene.Index(i, j);
        ShearCross s;
        s.nodes = {c, i + 1 < nu ? scene.Index(i + 1, j) : c, i > 0 ? scene.Index(i - 1, j) : c,
                   j + 1 < nv ? scene.Index(i, j + 1) : c, j > 0 ? scene.Index(i, j - 1) : c};
        s.du = lu * ((i + 1 < nu) + (i > 0));
        s.dv = lv * ((j + 1 < nv) + (j > 0));
        shear_.push_back(s);
      }
  }
  for (const auto& term : system.terms()) {
    const std::string_view name = term->name();
    // The virtual springs correct the model's spring forces, which XPBD
    // replaces by its distance constraints: they do not act here.
    if (name == "tension_nonlinear" || name == "virtual_springs" || (name == "shear" && shear_constraint())) continue;
    explicit_.push_back(term.get());
    explicit_names_.emplace_back(name);
  }
  for (MatrixN3* m : {&x0_, &v0_, &x_, &v_, &p_, &f_}) m->setZero(n, 3);
  if (const auto& collision = scene.collision; collision && collision->self)
    self_.emplace(system, collision->thickness, w_);
}

void Xpbd::Reset(double t, const MatrixN3& x, const MatrixN3& v) {
  t_ = t;
  x0_ = x;
  v0_ = v;
  for (int p : sys_.fixed()) v0_.row(p).setZero();
  sys_.Prescribe(t, &x0_, &v0_);  // moving fixed particles (`[[constraints.motion]]`)
  if (self_) self_->Reset();
  proximity_.Reset();
}

void Xpbd::PredictionForces(double t, const MatrixN3& x, const MatrixN3& v, MatrixN3* f) const {
  f->setZero();
  for (const ForceTerm* term : explicit_) term->AddForce(t, x, v, f);
}

// C = γ = ⟨a, b⟩, a = (p_r − p_l)/du, b = (p_u − p_d)/dv (docs/model.md §2.2), with
// ∇_r C = b/du, ∇_l C = −b/du, ∇_u C = a/dv, ∇_d C = −a/dv; gradients of
// slots that hold the same particle (the border) are summed first.
void Xpbd::ProjectShear(double dt) {
  const double alpha0 = shear_compliance_ / (dt * dt);
  for (const ShearCross& s : shear_) {
    const double alpha = alpha0 * s.compliance_scale;
    const double gamma = alpha * shear_damping_ * s.area_scale * dt;
    const auto& k = s.nodes;
    const Vector3 a = (p_.row(k[1]) - p_.row(k[2])).transpose() / s.du;
    const Vector3 b = (p_.row(k[3]) - p_.row(k[4])).transpose() / s.dv;
    const std::array<Vector3, 5> slot = {Vector3::Zero(), b / s.du, -b / s.du, a / s.dv, -a / s.dv};
    std::array<int, 5> node{};
    std::array<Vector3, 5> grad;
    int m = 0;
    for (int q = 1; q < 5; ++q) {
      int u = 0;
      while (u < m && node[u] != k[q]) ++u;
      if (u == m) {
        node[m] = k[q];
        grad[m++] = slot[q];
      } else {
        grad[u] += slot[q];
      }
    }
    double denom = 0.0, rate = 0.0;
    for (int u = 0; u < m; ++u) {
      denom += w_(node[u]) * grad[u].squaredNorm();
      if (gamma != 0.0) rate += grad[u].dot((p_.row(node[u]) - x_.row(node[u])).transpose());
    }
    if (denom == 0.0) continue;
    const double dlambda = (-(a.dot(b) - s.gamma0) - gamma * rate) / ((1.0 + gamma) * denom + alpha);  // Eq. 26, λ = 0
    for (int u = 0; u < m; ++u) p_.row(node[u]) += (w_(node[u]) * dlambda) * grad[u].transpose();
  }
}

StepStats Xpbd::Step(double h) {
  const auto start = std::chrono::steady_clock::now();
  StepStats st;
  st.t = t_ + h;
  st.h = h;
  st.updates = substeps_;
  const double dt = h / substeps_;
  x_ = x0_;
  v_ = v0_;
  bool blown_up = false;
  if (self_) self_->BeginStep(h, x0_, v0_);
  for (int k = 0; k < substeps_; ++k) {
    if (DeadlinePassed()) {  // the run's --time-limit (model/interrupt.h); the state stays x₀, v₀
      st.status = StepStatus::kTimeLimit;
      st.solve_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      return st;
    }
    const double t = t_ + k * dt;
    // 1. v ← v + Δt M⁻¹ f_ext(x, v); 2. p ← x + Δt v (Algorithm 1).
    PredictionForces(t, x_, v_, &f_);
    v_ += dt * (w_.asDiagonal() * f_);
    p_ = x_ + dt * v_;
    // A moving fixed particle (w = 0) is kinematic: at its prescribed
    // position at the substep's end.
    sys_.ForEachPrescribed(t + dt, [&](int p, const Vector3& x, const Vector3&) { p_.row(p) = x.transpose(); });
    // 3.–4. One sweep: λ = 0, Δλ by Eq. 26, in a fixed order (deterministic).
    //    The dampers go first: after a distance projection they would see its
    //    correction as relative motion and undo most of it (β Δt w ≈ 6 on
    //    the swinging sheet at Δt = 0.01 s).
    if (has_dampers_)
      for (const Distance& c : distance_) {
        if (c.damping == 0.0) continue;
        Vector3 pa = p_.row(c.a).transpose(), pb = p_.row(c.b).transpose();
        ProjectDamper(&pa, &pb, x_.row(c.a).transpose(), x_.row(c.b).transpose(), w_(c.a), w_(c.b), c.damping, dt);
        p_.row(c.a) = pa.transpose();
        p_.row(c.b) = pb.transpose();
      }
    for (const Distance& c : distance_) {
      if (c.compliance == 0.0) continue;
      Vector3 pa = p_.row(c.a).transpose(), pb = p_.row(c.b).transpose();
      ProjectDistance(&pa, &pb, x_.row(c.a).transpose(), x_.row(c.b).transpose(), w_(c.a), w_(c.b), c.rest_length,
                      c.compliance, 0.0, dt);
      p_.row(c.a) = pa.transpose();
      p_.row(c.b) = pb.transpose();
    }
    if (!shear_.empty()) ProjectShear(dt);
    if (self_ || !sys_.obstacles().empty()) {
      // A non-finite prediction ends the step here, before the contact
      // queries (CGAL) see it; the state stays x₀, v₀.
      if (!p_.allFinite()) {
        blown_up = true;
        break;
      }
      // The obstacles first: a layer that they lift must not be lifted
      // through the one above it.
      if (!sys_.obstacles().empty()) st.colliding = ProjectOntoObstacles(sys_, &proximity_, w_, t + dt, dt, x_, &p_);
      if (self_) self_->Project(x_, static_cast<double>(k) / substeps_, static_cast<double>(k + 1) / substeps_, &p_);
    }
    // 5. v ← (p − x)/Δt, x ← p.
    v_ = (p_ - x_) / dt;
    x_.swap(p_);
  }
  if (!blown_up) sys_.Prescribe(t_ + h, &x_, &v_);
  if (blown_up || !x_.allFinite() || !v_.allFinite()) {
    st.status = StepStatus::kNonFinite;
  } else {
    x0_.swap(x_);
    v0_.swap(v_);
    t_ += h;
  }
  st.solve_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return st;
}

}  // namespace clothbench

// The row of XPBD, as the registry lists it (harness/registry.cc).
#include "solver/method_row.h"

namespace clothbench {

/// xpbd: substepped; default frame steps h and h/16, with --substeps
/// 1,4,16,64 substeps h/1 … h/1024: 0.19 … 2.7e-3 m at h/256 and ≈ 6.7e-4 m
/// at h/1024 on the default scene (docs/notes/work-precision.md).
MethodEntry XpbdRow() {
  return {.name = kXpbdName, .kind = StepKind::kSubstepped, .layer = "peers", .collisions = true,
          .make = [](const ParticleSystem& sys, const SolverSpec&, int substeps,
                     std::string_view) -> std::unique_ptr<Stepper> { return std::make_unique<Xpbd>(sys, substeps); },
          .describe = [](const Stepper& stepper, const ParticleSystem& sys, RunRecord* row) {
            // constraints: the terms solved as constraints ("tension,shear,
            // obstacles"); explicit_terms: those applied in the prediction.
            const auto& x = static_cast<const Xpbd&>(stepper);  // this entry's make builds an Xpbd
            std::string terms;
            for (const std::string& t : x.explicit_terms()) terms += (terms.empty() ? "" : ",") + t;
            if (!terms.empty()) row->SetMethodAttribute("explicit_terms", terms);
            row->SetMethodAttribute("constraints", std::string("tension") + (x.shear_constraint() ? ",shear" : "") +
                                                       (sys.obstacles().empty() ? "" : ",obstacles"));
          },
          .defaults = {{.modifiers = "", .h_factors = {1.0, 1.0 / 16}}},
          .table_note = "xpbd rows: updates = substeps (one constraint sweep each); constraints: ",
          .table_note_terms = "explicit forces in the prediction: "};
}

}  // namespace clothbench
