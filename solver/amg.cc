// hypre BoomerAMG as the preconditioner of the filtered PCG. hypre and MPI
// are confined to this file.
#include "solver/amg.h"

#include "solver/decoupled.h"

// The C API only (Open MPI would otherwise pull in its C++ bindings).
#define OMPI_SKIP_MPICXX 1
#include <mpi.h>
#include <HYPRE.h>
#include <HYPRE_IJ_mv.h>
#include <HYPRE_parcsr_ls.h>
#include <_hypre_parcsr_ls.h>
#include <_hypre_parcsr_mv.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>

namespace clothbench {
namespace {

// MPI and hypre are started once per process, on first use, and stopped at
// exit. A run never needs mpirun: Open MPI starts as a singleton. Every
// hypre object lives on MPI_COMM_SELF: each process (each rank of a sweep,
// harness/sweep.h) solves its own systems whole, and hypre's messages must
// never meet the sweep's on MPI_COMM_WORLD.
bool StartHypre() {
  static const bool started = [] {
    int initialized = 0;
    MPI_Initialized(&initialized);
    if (!initialized) {
      if (MPI_Init(nullptr, nullptr) != MPI_SUCCESS) return false;
      std::atexit([] {
        int finalized = 0;
        MPI_Finalized(&finalized);
        if (!finalized) MPI_Finalize();
      });
    }
    return HYPRE_Init() == 0;
  }();
  return started;
}

// BoomerAMG with the settings of the class comment.
HYPRE_Solver CreateAmg() {
  HYPRE_Solver amg = nullptr;
  HYPRE_BoomerAMGCreate(&amg);
  HYPRE_BoomerAMGSetPrintLevel(amg, 0);
  HYPRE_BoomerAMGSetMaxIter(amg, 1);  // one V-cycle per application
  HYPRE_BoomerAMGSetTol(amg, 0.0);
  HYPRE_BoomerAMGSetCoarsenType(amg, 10);     // HMIS
  HYPRE_BoomerAMGSetInterpType(amg, 6);       // extended+i
  HYPRE_BoomerAMGSetPMaxElmts(amg, 4);
  HYPRE_BoomerAMGSetStrongThreshold(amg, 0.25);
  HYPRE_BoomerAMGSetRelaxType(amg, 6);        // hybrid symmetric Gauss–Seidel
  HYPRE_BoomerAMGSetNumSweeps(amg, 1);
  HYPRE_BoomerAMGSetRelaxOrder(amg, 0);       // lexicographic: symmetric with the reverse up-sweep
  return amg;
}

// The n×n matrix of the CSR rows (row i: entries start[i] to start[i + 1]
// of cols and values) as a hypre ParCSR matrix, built in place: one process
// owns every row, so the matrix is its diag block with no off-process
// columns. Each row's diagonal entry goes first (hypre's smoothers read it
// there), the others keep their order. hypre's IJ interface, which this
// replaces, sorted and hashed every entry: 0.03 s of a 0.2 s setup at 10⁵
// particles. @return null if a row has no diagonal entry.
HYPRE_ParCSRMatrix MakeMatrix(int n, const int* start, const int* cols, const double* values) {
  HYPRE_BigInt starts[2] = {0, n};
  const int nnz = start[n];
  hypre_ParCSRMatrix* a = hypre_ParCSRMatrixCreate(MPI_COMM_SELF, n, n, starts, starts, 0, nnz, 0);
  hypre_ParCSRMatrixInitialize(a);
  hypre_CSRMatrix* diag = hypre_ParCSRMatrixDiag(a);
  HYPRE_Int* row = hypre_CSRMatrixI(diag);
  HYPRE_Int* col = hypre_CSRMatrixJ(diag);
  double* val = hypre_CSRMatrixData(diag);
  for (int i = 0; i < n; ++i) {
    const int diagonal = static_cast<int>(std::find(cols + start[i], cols + start[i + 1], i) - cols);
    if (diagonal == start[i + 1]) {
      hypre_ParCSRMatrixDestroy(a);
      return nullptr;
    }
    row[i] = start[i];
    col[start[i]] = i;
    val[start[i]] = values[diagonal];
    int at = start[i] + 1;
    for (int k = start[i]; k < start[i + 1]; ++k) {
      if (k == diagonal) continue;
      col[at] = cols[k];
      val[at++] = values[k];
    }
  }
  row[n] = nnz;
  hypre_ParCSRMatrixSetNumNonzeros(a);
  hypre_MatvecCommPkgCreate(a);
  return reinterpret_cast<HYPRE_ParCSRMatrix>(a);
}

// BoomerAMG's setup of `amg` for `a`; *levels gets the hierarchy's depth.
bool SetUp(HYPRE_Solver amg, HYPRE_ParCSRMatrix a, HYPRE_ParVector b, HYPRE_ParVector x, int* levels) {
  HYPRE_ParVectorSetConstantValues(b, 0.0);
  HYPRE_ParVectorSetConstantValues(x, 0.0);
  if (HYPRE_BoomerAMGSetup(amg, a, b, x) != 0) {
    HYPRE_ClearAllErrors();
    return false;
  }
  *levels = hypre_ParAMGDataNumLevels(reinterpret_cast<hypre_ParAMGData*>(amg));
  return true;
}

// Both hierarchies (A_F's and the prefiltered system's) are coarsened
// aggressively on their first level from this many particles on
// (CoarsenAggressively).
constexpr int kAggressiveCoarseningNodes = 20000;

// Aggressive coarsening on the first level, interpolated there with hypre's
// 2-stage extended+i interpolation in matrix-matrix form (AggInterpType 6:
// extended+i, the other levels' interpolation, applied across the two
// stages) instead of the default multipass. For the prefiltered hierarchy,
// on round_table_100k's 1 s drape: 664 CG iterations instead of 842 (9.4
// instead of 13.2 per impact step, 5.5 instead of 7.3 at rest) for setups
// as costly within the machine's spread, and in a replay of
// round_table_1m's impact 8 per step instead of 12. For A_F's hierarchy:
// more CG iterations per step (6.75 instead of 5.25 on bench_scaling's
// contact-free sheet at 10⁵ and 10⁶), but cheaper V-cycles and setups; the
// contact-free step of round_table_1m in bench_integrators took 1.72 s
// against 2.15–2.17 s (docs/notes/performance.md, "2-stage interpolation on the
// aggressive level").
void CoarsenAggressively(HYPRE_Solver amg) {
  HYPRE_BoomerAMGSetAggNumLevels(amg, 1);
  HYPRE_BoomerAMGSetAggInterpType(amg, 6);
}

}  // namespace

// One hierarchy: its matrix, vectors and BoomerAMG object.
struct Hierarchy {
  int n = 0;  // unknowns
  HYPRE_IJVector ij_b = nullptr, ij_x = nullptr;
  HYPRE_ParCSRMatrix par_a = nullptr;
  // The finest level's matrix when it differs from the one set up (kept
  // hierarchy, changed contacts); null: par_a.
  HYPRE_ParCSRMatrix par_fine = nullptr;
  HYPRE_ParVector par_b = nullptr, par_x = nullptr;
  HYPRE_Solver amg = nullptr;
  bool ready = false;
  int levels = 0;

  Hierarchy() = default;
  Hierarchy(const Hierarchy&) = delete;
  Hierarchy& operator=(const Hierarchy&) = delete;
  ~Hierarchy() {
    Free();
    for (HYPRE_IJVector v : {ij_b, ij_x})
      if (v) HYPRE_IJVectorDestroy(v);
  }
  // Frees the matrix and the setup (the vectors stay).
  void Free() {
    if (amg) HYPRE_BoomerAMGDestroy(amg);
    if (par_a) HYPRE_ParCSRMatrixDestroy(par_a);
    FreeFine();
    amg = nullptr;
    par_a = nullptr;
    ready = false;
  }
  void FreeFine() {
    if (par_fine) HYPRE_ParCSRMatrixDestroy(par_fine);
    par_fine = nullptr;
  }
  HYPRE_ParCSRMatrix fine() const { return par_fine ? par_fine : par_a; }
  // Vectors of `size` unknowns (kept while the size is).
  void Resize(int size) {
    if (size == n && ij_b) return;
    for (HYPRE_IJVector* v : {&ij_b, &ij_x}) {
      if (*v) HYPRE_IJVectorDestroy(*v);
      HYPRE_IJVectorCreate(MPI_COMM_SELF, 0, size - 1, v);
      HYPRE_IJVectorSetObjectType(*v, HYPRE_PARCSR);
      HYPRE_IJVectorInitialize(*v);
      HYPRE_IJVectorAssemble(*v);
    }
    HYPRE_IJVectorGetObject(ij_b, reinterpret_cast<void**>(&par_b));
    HYPRE_IJVectorGetObject(ij_x, reinterpret_cast<void**>(&par_x));
    n = size;
  }
  double* b() const { return hypre_VectorData(hypre_ParVectorLocalVector(par_b)); }
  double* x() const { return hypre_VectorData(hypre_ParVectorLocalVector(par_x)); }
};

struct AmgPreconditioner::Impl {
  // A_F's hierarchy, applied to each column.
  Hierarchy scalar;
  std::vector<int> source;      // per entry of the CSR rows: position in A's values
  std::vector<int> start, cols;  // the CSR rows of A_F
  std::vector<double> values;
  // The prefiltered 3N×3N system (FactorizeSystem).
  Hierarchy system;
};

AmgPreconditioner::AmgPreconditioner() : impl_(std::make_unique<Impl>()) { StartHypre(); }
AmgPreconditioner::~AmgPreconditioner() = default;

bool AmgPreconditioner::Analyze(const SparseMatrix& a, const std::vector<int>& fixed) {
  if (!StartHypre()) return false;
  Impl& m = *impl_;
  m.scalar.Free();
  const int n = static_cast<int>(a.rows());
  // A_F is symmetric: column j of its CSC storage is row j of hypre's CSR rows.
  internal::DecoupledPattern pattern = internal::DecoupleFixed(a, fixed, /*upper_only=*/false);
  m.source = std::move(pattern.source);
  m.cols = std::move(pattern.inner);
  m.start = std::move(pattern.outer);
  m.values.assign(m.cols.size(), 0.0);
  m.scalar.Resize(n);
  return true;
}

bool AmgPreconditioner::Factorize(const SparseMatrix& a) {
  Impl& m = *impl_;
  Hierarchy& h = m.scalar;
  h.Free();
  if (h.n == 0) return false;
  for (std::size_t k = 0; k < m.source.size(); ++k) m.values[k] = a.valuePtr()[m.source[k]];
  h.par_a = MakeMatrix(h.n, m.start.data(), m.cols.data(), m.values.data());
  if (!h.par_a) return false;
  h.amg = CreateAmg();
  if (h.n >= kAggressiveCoarseningNodes) CoarsenAggressively(h.amg);
  h.ready = SetUp(h.amg, h.par_a, h.par_b, h.par_x, &h.levels);
  return h.ready;
}

void AmgPreconditioner::Solve(const MatrixN3& r, MatrixN3* z) const {
  const Hierarchy& h = impl_->scalar;
  if (!h.ready) {
    z->setConstant(std::numeric_limits<double>::quiet_NaN());
    return;
  }
  double* b = h.b();
  double* x = h.x();
  const auto bytes = static_cast<std::size_t>(h.n) * sizeof(double);
  for (int c = 0; c < 3; ++c) {
    std::memcpy(b, r.col(c).data(), bytes);
    std::memset(x, 0, bytes);  // a preconditioner application starts from zero
    HYPRE_BoomerAMGSolve(h.amg, h.par_a, h.par_b, h.par_x);
    std::memcpy(z->col(c).data(), x, bytes);
  }
}

int AmgPreconditioner::levels() const { return impl_->scalar.levels; }

bool AmgPreconditioner::FactorizeSystem(int n_nodes, const std::vector<int>& row_start, const std::vector<int>& cols,
                                        const std::vector<double>& values) {
  if (!StartHypre()) return false;
  Impl& m = *impl_;
  Hierarchy& h = m.system;
  h.Free();
  const int n = 3 * n_nodes;
  h.Resize(n);
  h.par_a = MakeMatrix(n, row_start.data(), cols.data(), values.data());
  if (!h.par_a) return false;
  h.amg = CreateAmg();
  HYPRE_BoomerAMGSetNumFunctions(h.amg, 3);  // interleaved: function of unknown i is i mod 3
  HYPRE_BoomerAMGSetNodal(h.amg, 1);         // nodal coarsening on the Frobenius norm of each block
  // Aggressive coarsening (CoarsenAggressively) from
  // kAggressiveCoarseningNodes particles on: a setup runs every step of an
  // impact, and at 10⁵ particles it cost 0.16 s instead of 0.22 s for about
  // 15 % more CG iterations (with multipass interpolation); the 1 s drape
  // of round_table_100k took 26 s instead of 30–32 s. Below, setups are
  // cheap and the iterations count: at 10⁴ the drape takes the same time
  // either way, with twice the CG iterations of a resting step
  // aggressively coarsened (docs/notes/performance.md, "Prefiltered AMG").
  if (n_nodes >= kAggressiveCoarseningNodes) CoarsenAggressively(h.amg);
  if (!SetUp(h.amg, h.par_a, h.par_b, h.par_x, &h.levels)) return false;
  // A setup can succeed and still give a V-cycle that is not finite (a
  // singular coarse level; seen at 10⁶ particles with the hierarchy built in
  // world frames): one V-cycle on a vector of ones checks it.
  HYPRE_ParVectorSetConstantValues(h.par_b, 1.0);
  HYPRE_ParVectorSetConstantValues(h.par_x, 0.0);
  HYPRE_BoomerAMGSolve(h.amg, h.par_a, h.par_b, h.par_x);
  const double* x = h.x();
  for (int i = 0; i < n; ++i)
    if (!std::isfinite(x[i])) {
      h.Free();
      return false;
    }
  h.ready = true;
  return true;
}

bool AmgPreconditioner::UpdateSystemFineLevel(int n_nodes, const std::vector<int>& row_start,
                                              const std::vector<int>& cols, const std::vector<double>& values) {
  Impl& m = *impl_;
  Hierarchy& h = m.system;
  const int n = 3 * n_nodes;
  if (!h.ready || h.n != n) return false;
  h.FreeFine();
  h.par_fine = MakeMatrix(n, row_start.data(), cols.data(), values.data());
  return h.par_fine != nullptr;
}

double AmgPreconditioner::SystemCycleFactor(int cycles) const {
  const Hierarchy& h = impl_->system;
  if (!h.ready) return std::numeric_limits<double>::quiet_NaN();
  double* x = h.x();
  std::uint32_t state = 12345u;  // a linear congruential sequence: the same start every call
  for (int i = 0; i < h.n; ++i) {
    state = state * 1664525u + 1013904223u;
    x[i] = static_cast<double>(state >> 8) / static_cast<double>(1u << 24) - 0.5;
  }
  HYPRE_ParVectorSetConstantValues(h.par_b, 0.0);
  const auto norm = [&] {
    double sum = 0.0;
    for (int i = 0; i < h.n; ++i) sum += x[i] * x[i];
    return std::sqrt(sum);
  };
  double before = norm(), factor = 0.0;
  for (int k = 0; k < cycles && before > 0.0; ++k) {
    for (int i = 0; i < h.n; ++i) x[i] /= before;  // unit norm: no underflow over many cycles
    HYPRE_BoomerAMGSolve(h.amg, h.fine(), h.par_b, h.par_x);
    factor = norm();
    before = factor;
  }
  return factor;
}

void AmgPreconditioner::SolveSystem(const MatrixN3& r, MatrixN3* z) const {
  const Hierarchy& h = impl_->system;
  if (!h.ready || 3 * r.rows() != h.n) {
    z->setConstant(std::numeric_limits<double>::quiet_NaN());
    return;
  }
  double* b = h.b();
  double* x = h.x();
  const Eigen::Index n = r.rows();
  for (Eigen::Index p = 0; p < n; ++p)
    for (int c = 0; c < 3; ++c) b[3 * p + c] = r(p, c);
  std::memset(x, 0, static_cast<std::size_t>(h.n) * sizeof(double));
  HYPRE_BoomerAMGSolve(h.amg, h.fine(), h.par_b, h.par_x);
  for (Eigen::Index p = 0; p < n; ++p)
    for (int c = 0; c < 3; ++c) (*z)(p, c) = x[3 * p + c];
}

}  // namespace clothbench
