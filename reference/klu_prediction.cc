// KLU's analysis as the prediction of a cvode/klu or ida/klu run
// (docs/notes/work-precision.md, "Predicting a first run").
#include "reference/klu_prediction.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <vector>

#include <fmt/format.h>
#include <klu.h>

#include "model/scene.h"
#include "reference/cvode_reference.h"

namespace clothbench {
namespace {

// KLU's state for one matrix in 64-bit indices (klu_l, as SUNDIALS' KLU
// solver with sunindextype int64), freed on every return.
struct KluMatrix {
  explicit KluMatrix(const SparseMatrix& a) : n(a.rows()) {
    ap.assign(a.outerIndexPtr(), a.outerIndexPtr() + a.outerSize() + 1);
    ai.assign(a.innerIndexPtr(), a.innerIndexPtr() + a.nonZeros());
    ax.assign(a.valuePtr(), a.valuePtr() + a.nonZeros());
    klu_l_defaults(&common);
    common.ordering = 0;  // AMD, as SUNLinSol_KLUSetOrdering(klu, 0) in the runs
    common.halt_if_singular = 0;  // a timing: a zero pivot in a leading block does not end it
  }
  ~KluMatrix() {
    if (numeric) klu_l_free_numeric(&numeric, &common);
    if (symbolic) klu_l_free_symbolic(&symbolic, &common);
  }
  KluMatrix(const KluMatrix&) = delete;
  KluMatrix& operator=(const KluMatrix&) = delete;
  SuiteSparse_long n;
  std::vector<SuiteSparse_long> ap, ai;
  std::vector<double> ax;
  klu_l_common common{};
  klu_l_symbolic* symbolic = nullptr;
  klu_l_numeric* numeric = nullptr;
};

KluAnalysis Analyze(KluMatrix* m) {
  m->symbolic = klu_l_analyze(m->n, m->ap.data(), m->ai.data(), &m->common);
  if (!m->symbolic) throw std::runtime_error(fmt::format("klu_l_analyze failed (status {})", m->common.status));
  return {static_cast<long>(m->n), static_cast<double>(m->ai.size()), m->symbolic->lnz, m->symbolic->unz,
          m->symbolic->est_flops};
}

// The Newton matrix I − γJ of a step of γ = 10⁻³ s: the pattern is J's
// (whose diagonal is stored), the values those KLU pivots on in a run.
SparseMatrix NewtonMatrix(const SparseMatrix& j) {
  constexpr double kGamma = 1e-3;
  SparseMatrix a = -kGamma * j;
  for (int i = 0; i < a.rows(); ++i) a.coeffRef(i, i) += 1.0;
  return a;
}

// The rows and columns of the first `nc` of `nf` free particles of a
// matrix on y = [x_free; v_free] (6 nf rows).
SparseMatrix LeadingBlock(const SparseMatrix& a, int nf, int nc) {
  const auto map = [&](int i) {
    const int block = i / (3 * nf), k = (i % (3 * nf)) / 3;
    return k < nc ? block * 3 * nc + 3 * k + i % 3 : -1;
  };
  std::vector<Triplet> t;
  for (int c = 0; c < a.outerSize(); ++c) {
    const int mc = map(c);
    if (mc < 0) continue;
    for (SparseMatrix::InnerIterator it(a, c); it; ++it)
      if (const int mr = map(static_cast<int>(it.row())); mr >= 0) t.emplace_back(mr, mc, it.value());
  }
  SparseMatrix b(6 * nc, 6 * nc);
  b.setFromTriplets(t.begin(), t.end());
  b.makeCompressed();
  return b;
}

// The Newton matrix of the calibration at about `nc` particles: the same
// scene's grid refined to nc (RefineGrid: the same shape, so the same kind
// of fill), or, where the scene cannot be refined, the leading block of
// `a` on its first nc free particles (`nf` of them).
SparseMatrix CalibrationMatrix(const ParticleSystem& system, const SparseMatrix& a, int nf, int nc, bool refine) {
  if (!refine) return LeadingBlock(a, nf, nc);
  const ParticleSystem coarse(RefineGrid(system.scene(), nc));
  return NewtonMatrix(FirstOrderJacobianAtRest(coarse));
}

// Analysis and factorisation of `a`, the factorisation timed [s].
KluAnalysis TimedFactorisation(const SparseMatrix& a, double* seconds) {
  KluMatrix m(a);
  const KluAnalysis k = Analyze(&m);
  const auto start = std::chrono::steady_clock::now();
  m.numeric = klu_l_factor(m.ap.data(), m.ai.data(), m.ax.data(), m.symbolic, &m.common);
  *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!m.numeric) throw std::runtime_error(fmt::format("klu_l_factor failed (status {})", m.common.status));
  return k;
}

}  // namespace

KluAnalysis AnalyzeKlu(const SparseMatrix& a) {
  KluMatrix m(a);
  return Analyze(&m);
}

FirstRunPrediction PredictKluRun(const ParticleSystem& system) {
  constexpr double kMinFlops = 1e9, kCalibrationSeconds = 0.2, kCalibrationShare = 1.0 / 64.0;
  const SparseMatrix a = NewtonMatrix(FirstOrderJacobianAtRest(system));
  const KluAnalysis full = AnalyzeKlu(a);
  if (full.flops < kMinFlops) return {};
  const int nf = static_cast<int>(a.rows() / 6);
  bool refine = true;
  try {
    (void)RefineGrid(system.scene(), 4);
  } catch (const std::exception&) {
    refine = false;  // particles named by index, or no grid
  }
  // KLU's flop rate on calibrations doubled in size until a factorisation
  // is long enough to time; the last two give the rate's trend.
  KluAnalysis part, before;
  double seconds = 0.0, seconds_before = 0.0;
  int nc = std::max(64, nf / 256);
  for (;; nc *= 2) {
    before = part;
    seconds_before = seconds;
    part = TimedFactorisation(CalibrationMatrix(system, a, nf, nc, refine), &seconds);
    if ((seconds >= kCalibrationSeconds && part.flops >= kCalibrationShare * full.flops) || 2 * nc > nf / 4) break;
  }
  const double rate = part.flops / std::max(seconds, 1e-9);
  // r ∝ flops^(−q), q from the last two calibrations, never negative (a
  // rising rate is not extrapolated).
  double q = 0.0;
  if (seconds_before > 0.0 && part.flops > before.flops)
    q = std::max(0.0, std::log(rate / (before.flops / seconds_before)) / std::log(before.flops / part.flops));
  const double rate_full = rate * std::pow(full.flops / part.flops, -q);
  FirstRunPrediction p;
  p.seconds = full.flops / rate_full;
  p.bytes = 16.0 * (full.lnz + full.unz + full.nnz);
  p.source = fmt::format(
      "klu_analyze: one factorisation of I - gamma J ({} rows, {:.3g} entries) is {:.3g} flops and L + U hold "
      "{:.3g} entries; KLU here factorised {} {} ({} rows, {:.3g} flops) in {:.3f} s, {:.3g} GFlop/s, falling "
      "as flops^-{:.2f} from half that size: {:.3g} GFlop/s at the full size",
      full.rows, full.nnz, full.flops, full.lnz + full.unz, refine ? "the scene refined to" : "the leading block of",
      fmt::format("{} particles", nc), part.rows, part.flops, seconds, rate / 1e9, q, rate_full / 1e9);
  return p;
}

}  // namespace clothbench
