// Vertex Block Descent (Chen et al. 2024; Chebyshev: §3.8, Wang 2015;
// docs/model.md §10).
#include "peers/vbd.h"

#include <chrono>
#include <vector>


namespace clothbench {

VertexBlockDescent::VertexBlockDescent(const ParticleSystem& system, int iterations, ChebyshevSettings chebyshev)
    : IteratedStepper(system, "vbd", iterations, chebyshev, kRhoIterations, InitialGuess::kSafeguardedExtrapolation,
                      ObstacleResponse::kVelocityFilter, RhoEstimate::kKrylov) {
  const auto start = std::chrono::steady_clock::now();
  const int n = system.num_particles();
  system.PrepareParticleForces();
  // Greedy colouring in particle order: each free particle takes the least
  // colour that none of its neighbours has (fixed particles never move, so
  // they constrain nobody).
  std::vector<int> offsets, neighbours;
  system.ParticleGraph(&offsets, &neighbours);
  std::vector<int> colour(static_cast<std::size_t>(n), -1);
  std::vector<int> taken;  // taken[c] == p: colour c is a neighbour's of p
  int colours = 0;
  for (int p = 0; p < n; ++p) {
    if (system.is_fixed(p)) continue;
    for (int q = offsets[static_cast<std::size_t>(p)]; q < offsets[static_cast<std::size_t>(p) + 1]; ++q) {
      const int c = colour[static_cast<std::size_t>(neighbours[static_cast<std::size_t>(q)])];
      if (c >= 0) taken[static_cast<std::size_t>(c)] = p;
    }
    int c = 0;
    while (c < colours && taken[static_cast<std::size_t>(c)] == p) ++c;
    if (c == colours) {
      ++colours;
      taken.push_back(-1);
    }
    colour[static_cast<std::size_t>(p)] = c;
  }
  colour_start_.assign(static_cast<std::size_t>(colours) + 1, 0);
  for (int p = 0; p < n; ++p)
    if (colour[static_cast<std::size_t>(p)] >= 0) ++colour_start_[static_cast<std::size_t>(colour[static_cast<std::size_t>(p)]) + 1];
  for (std::size_t c = 0; c < static_cast<std::size_t>(colours); ++c) colour_start_[c + 1] += colour_start_[c];
  order_.resize(static_cast<std::size_t>(colour_start_.back()));
  std::vector<int> fill(colour_start_.begin(), colour_start_.end() - 1);
  for (int p = 0; p < n; ++p)
    if (colour[static_cast<std::size_t>(p)] >= 0)
      order_[static_cast<std::size_t>(fill[static_cast<std::size_t>(colour[static_cast<std::size_t>(p)])]++)] = p;

  colouring_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (const auto& collision = system.scene().collision; collision && collision->self) {
    self_.emplace(system, collision->thickness);
    x_colour_.setZero(n, 3);
    truncated_.assign(static_cast<std::size_t>(n), 0);
    if (system.has_prescribed_motion())
      for (MatrixN3* m : {&x_split_, &v_split_}) m->setZero(n, 3);
  }
}

StepStats VertexBlockDescent::Step(double h) {
  if (self_) {
    ++self_->stats().steps;  // once, also where ρ's measurement iterates first
    // The step's largest predicted motion: inertia and gravity from its start.
    const double v_max = v0_.rows() ? v0_.rowwise().norm().maxCoeff() : 0.0;
    self_->SetStepMotion(h * v_max + h * h * sys_.scene().forces.gravity.norm());
  }
  const int pieces = self_ && sys_.has_prescribed_motion() ? KinematicSplit(h) : 1;
  if (pieces == 1) return IteratedStepper::Step(h);
  // A moving fixed particle cannot be truncated to its bound, as the free
  // ones are: the step is split until its motion per piece is within it
  // (the bounds' guarantee needs every vertex within its own, Chen et al.
  // 2025). A failed piece leaves the step's start state.
  const double t0 = t_;
  x_split_ = x0_;
  v_split_ = v0_;
  StepStats total;
  for (int k = 0; k < pieces; ++k) {
    const StepStats st = IteratedStepper::Step(h / pieces);
    total.updates += st.updates;
    total.solve_time += st.solve_time;
    total.setup_time += st.setup_time;
    total.colliding = std::max(total.colliding, st.colliding);
    if (st.status != StepStatus::kOk) {
      total.status = st.status;
      t_ = t0;
      x0_ = x_split_;
      v0_ = v_split_;
      break;
    }
  }
  total.t = t0 + h;
  total.h = h;
  if (total.status == StepStatus::kOk) t_ = t0 + h;
  return total;
}

int VertexBlockDescent::KinematicSplit(double h) {
  self_->Detect(x0_);
  start_detected_ = true;  // the first (or only) piece's iterations start from these pairs
  double ratio = 0.0;  // the largest motion over its bound
  sys_.ForEachPrescribed(t_ + h, [&](int p, const Vector3& x, const Vector3&) {
    ratio = std::max(ratio, (x - x0_.row(p).transpose()).norm() / self_->bound(p));
  });
  int pieces = 1;
  while (pieces < kMaxSplit && ratio > pieces) pieces *= 2;
  return pieces;
}

void VertexBlockDescent::Reset(double t, const MatrixN3& x, const MatrixN3& v) {
  IteratedStepper::Reset(t, x, v);
  if (self_) self_->Reset();
}

bool VertexBlockDescent::Bound(double h, int p, Vector3* vp) {
  Vector3 xp = x0_.row(p).transpose() + h * *vp;
  if (!self_->Truncate(p, &xp)) return false;
  *vp = (xp - x0_.row(p).transpose()) / h;
  truncated_[static_cast<std::size_t>(p)] = 1;
  return true;
}

void VertexBlockDescent::BeginIterations(double h) {
  if (!self_) return;
  if (!start_detected_) self_->Detect(x0_);  // KinematicSplit detected at x₀ already
  start_detected_ = false;
  AfterIteration(h);  // the first iterate within the bounds
}

void VertexBlockDescent::AfterIteration(double h) {
  if (!self_) return;
  long truncated = 0;
  for (int p : order_) {
    Vector3 vp = v_.row(p).transpose();
    if (Bound(h, p, &vp)) v_.row(p) = vp.transpose();
  }
  for (char& c : truncated_) {
    truncated += c;
    c = 0;
  }
  self_->stats().projections += truncated;
  // A moving fixed particle (`[[constraints.motion]]`) is not truncated: it
  // goes where its motion takes it. Past its bound, its pairs are detected
  // again from there, as after a truncation.
  bool moved_past = false;
  sys_.ForEachPrescribed(t_ + h, [&](int p, const Vector3& x, const Vector3&) {
    Vector3 xp = x;
    moved_past = moved_past || self_->Truncate(p, &xp);
  });
  if (truncated == 0 && !moved_past) return;
  // A particle at its bound: the detection again, from where the iterate is.
  x_colour_.noalias() = x0_ + h * v_;
  self_->Detect(x_colour_);
}

void VertexBlockDescent::Relax(double t1, double h, int p) {
  Vector3 f;
  Matrix3 dfdx, dfdv;
  sys_.ParticleForce(t1, x_, v_, p, &f, &dfdx, &dfdv);
  if (const MatrixN3* friction = contact_forces()) f += friction->row(p).transpose();
  if (self_) {  // the penalty at the colour's start positions (the same for any thread count)
    Matrix3 k = Matrix3::Zero();
    self_->AddForce(p, x_colour_, &f, &k);
    dfdx -= k;
  }
  const double m = sys_.masses()(p);
  Vector3 v1 = v_.row(p).transpose();
  const Vector3 r = m * (v1 - v0_.row(p).transpose()) - h * f;
  const Matrix3 j = m * Matrix3::Identity() - h * dfdv - (h * h) * dfdx;
  if (!LocalStep(p, j, r, &v1)) return;
  if (self_) Bound(h, p, &v1);
  v_.row(p) = v1.transpose();
  x_.row(p) = x0_.row(p) + h * v1.transpose();
}

// One sweep: the colours in sequence, each colour's particles in parallel.
void VertexBlockDescent::Iteration(double h) {
  const double t1 = t_ + h;
  x_.noalias() = x0_ + h * v_;
  for (std::size_t c = 0; c + 1 < colour_start_.size(); ++c) {
    const std::ptrdiff_t first = colour_start_[c], last = colour_start_[c + 1];
    if (self_) x_colour_ = x_;
#pragma omp parallel for schedule(static) if (last - first >= kParallelColour)
    for (std::ptrdiff_t i = first; i < last; ++i) Relax(t1, h, order_[static_cast<std::size_t>(i)]);
  }
}

}  // namespace clothbench

// The row of VBD, as the registry lists it (harness/registry.cc).
#include "solver/method_row.h"

namespace clothbench {
namespace {

// Why VBD ends `penetration` at a large h with few sweeps
// (docs/notes/collisions.md, "VBD at the obstacles").
constexpr std::string_view kVbdPenetration =
    "vbd rows, penetration: the entry test predicts a particle's path from its velocity at the step's start, and a "
    "VBD iterate that is still far from implicit Euler's solution after its few sweeps can move a particle much "
    "faster than that (on the swinging box at h = 0.01 s and 4 sweeps: 7 cm in one step from 1.9 m/s), past the "
    "test; more sweeps or a smaller h end ok. A property of the method's unconverged iterate "
    "(docs/notes/collisions.md, \"VBD at the obstacles\").";

}  // namespace

/// vbd: Vertex Block Descent, one local Newton step per particle and
/// sweep, colours in sequence; vbd/chebyshev with the paper's acceleration
/// at the measured ρ (kVbdChebyshev). Every term is implicit in the local
/// steps. Default parameters: a sweep costs 0.22 ms at 400 particles (6× a
/// pd iteration) and the default run's budget holds 1 and 4 sweeps at h,
/// h/4, h/16 (10,500 sweeps per row, 2.3 s), their own counts: at h = 0.01 s
/// 1 and 4 sweeps gain energy (energy_growth) and 16, 64 give 0.23, 0.11 m;
/// at h/4 9.8e-2 … 5.9e-3 m (1 … 64); at h/16 4.8e-2, 2.5e-3, 1.5e-3 m
/// with 1, 4, 16 (the floor); with Chebyshev the same within 20 %
/// (`bench_integrators --integrators vbd,vbd/chebyshev --h
/// 0.01,0.0025,0.000625`, docs/notes/work-precision.md, "vbd").
MethodEntry VbdRow() {
  return {.name = kVbdName, .kind = StepKind::kIterated, .layer = "peers", .collisions = true,
          .make = [](const ParticleSystem& sys, const SolverSpec&, int iterations,
                     std::string_view variant) -> std::unique_ptr<Stepper> {
            return std::make_unique<VertexBlockDescent>(sys, iterations,
                                                        variant == "chebyshev" ? kVbdChebyshev : ChebyshevSettings{});
          },
          .variants = {"chebyshev"},
          .describe = [](const Stepper& stepper, const ParticleSystem&, RunRecord* row) {
            // chebyshev_rho: the ρ measured at the first step and used (none
            // without Chebyshev); chebyshev_rho_sweeps: the plain sweeps behind
            // it, over every h; colours: the particle graph's colours (a
            // sweep's sequential stages).
            const auto& vbd = static_cast<const VertexBlockDescent&>(stepper);  // this entry builds one
            if (vbd.rho() > 0.0) row->SetMethodAttribute("chebyshev_rho", vbd.rho());
            if (vbd.rho_sweeps() > 0) row->SetMethodAttribute("chebyshev_rho_sweeps", long{vbd.rho_sweeps()});
            row->SetMethodAttribute("colours", long{vbd.colours()});
          },
          .defaults = {{.modifiers = "", .h_factors = {1.0, 1.0 / 4, 1.0 / 16}, .iterations = {1, 4}},
                       {.modifiers = "chebyshev", .h_factors = {1.0, 1.0 / 4, 1.0 / 16}, .iterations = {1, 4}}},
          .table_note = "vbd rows: updates = iterations (each a sweep of one local Newton step per particle, every "
                        "term implicit, the colours of the particle graph in sequence)",
          .status_notes = {{"vbd", "penetration", kVbdPenetration}, {"vbd/chebyshev", "penetration", kVbdPenetration}}};
}

}  // namespace clothbench
