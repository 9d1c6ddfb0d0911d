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

#include <cstdlib>
#include <cstring>
#include <limits>

namespace clothbench {
namespace {

// MPI and hypre are started once per process, on first use, and stopped at
// exit. A run never needs mpirun: Open MPI starts as a singleton.
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

}  // namespace

struct AmgPreconditioner::Impl {
  int n = 0;
  std::vector<int> source;      // per entry of the CSR rows: position in A's values
  std::vector<HYPRE_Int> ncols, rows, cols;
  std::vector<double> values;
  HYPRE_IJMatrix ij_a = nullptr;
  HYPRE_IJVector ij_b = nullptr, ij_x = nullptr;
  HYPRE_ParCSRMatrix par_a = nullptr;
  HYPRE_ParVector par_b = nullptr, par_x = nullptr;
  HYPRE_Solver amg = nullptr;
  bool ready = false;
  int levels = 0;

  void FreeMatrix() {
    if (amg) HYPRE_BoomerAMGDestroy(amg);
    if (ij_a) HYPRE_IJMatrixDestroy(ij_a);
    amg = nullptr;
    ij_a = nullptr;
    par_a = nullptr;
    ready = false;
  }
  ~Impl() {
    FreeMatrix();
    if (ij_b) HYPRE_IJVectorDestroy(ij_b);
    if (ij_x) HYPRE_IJVectorDestroy(ij_x);
  }
  HYPRE_IJVector MakeVector() {
    HYPRE_IJVector v = nullptr;
    HYPRE_IJVectorCreate(MPI_COMM_WORLD, 0, n - 1, &v);
    HYPRE_IJVectorSetObjectType(v, HYPRE_PARCSR);
    HYPRE_IJVectorInitialize(v);
    HYPRE_IJVectorAssemble(v);
    return v;
  }
};

AmgPreconditioner::AmgPreconditioner() : impl_(std::make_unique<Impl>()) { StartHypre(); }
AmgPreconditioner::~AmgPreconditioner() = default;

bool AmgPreconditioner::Analyze(const SparseMatrix& a, const std::vector<int>& fixed) {
  if (!StartHypre()) return false;
  Impl& m = *impl_;
  m.FreeMatrix();
  m.n = static_cast<int>(a.rows());
  // A_F is symmetric: column j of its CSC storage is row j of hypre's CSR rows.
  internal::DecoupledPattern pattern = internal::DecoupleFixed(a, fixed, /*upper_only=*/false);
  m.source = std::move(pattern.source);
  m.cols.assign(pattern.inner.begin(), pattern.inner.end());
  m.ncols.resize(static_cast<std::size_t>(m.n));
  m.rows.resize(static_cast<std::size_t>(m.n));
  for (int j = 0; j < m.n; ++j) {
    m.rows[static_cast<std::size_t>(j)] = j;
    m.ncols[static_cast<std::size_t>(j)] = pattern.outer[static_cast<std::size_t>(j) + 1] - pattern.outer[static_cast<std::size_t>(j)];
  }
  m.values.assign(m.cols.size(), 0.0);
  if (!m.ij_b) m.ij_b = m.MakeVector();
  if (!m.ij_x) m.ij_x = m.MakeVector();
  HYPRE_IJVectorGetObject(m.ij_b, reinterpret_cast<void**>(&m.par_b));
  HYPRE_IJVectorGetObject(m.ij_x, reinterpret_cast<void**>(&m.par_x));
  return true;
}

bool AmgPreconditioner::Factorize(const SparseMatrix& a) {
  Impl& m = *impl_;
  m.FreeMatrix();
  if (m.n == 0) return false;
  for (std::size_t k = 0; k < m.source.size(); ++k) m.values[k] = a.valuePtr()[m.source[k]];
  HYPRE_IJMatrixCreate(MPI_COMM_WORLD, 0, m.n - 1, 0, m.n - 1, &m.ij_a);
  HYPRE_IJMatrixSetObjectType(m.ij_a, HYPRE_PARCSR);
  HYPRE_IJMatrixSetRowSizes(m.ij_a, m.ncols.data());
  HYPRE_IJMatrixInitialize(m.ij_a);
  HYPRE_IJMatrixSetValues(m.ij_a, m.n, m.ncols.data(), m.rows.data(), m.cols.data(), m.values.data());
  if (HYPRE_IJMatrixAssemble(m.ij_a) != 0) return false;
  HYPRE_IJMatrixGetObject(m.ij_a, reinterpret_cast<void**>(&m.par_a));

  HYPRE_BoomerAMGCreate(&m.amg);
  HYPRE_BoomerAMGSetPrintLevel(m.amg, 0);
  HYPRE_BoomerAMGSetMaxIter(m.amg, 1);  // one V-cycle per application
  HYPRE_BoomerAMGSetTol(m.amg, 0.0);
  HYPRE_BoomerAMGSetCoarsenType(m.amg, 10);     // HMIS
  HYPRE_BoomerAMGSetInterpType(m.amg, 6);       // extended+i
  HYPRE_BoomerAMGSetPMaxElmts(m.amg, 4);
  HYPRE_BoomerAMGSetStrongThreshold(m.amg, 0.25);
  HYPRE_BoomerAMGSetRelaxType(m.amg, 6);        // hybrid symmetric Gauss–Seidel
  HYPRE_BoomerAMGSetNumSweeps(m.amg, 1);
  HYPRE_BoomerAMGSetRelaxOrder(m.amg, 0);       // lexicographic: symmetric with the reverse up-sweep
  HYPRE_ParVectorSetConstantValues(m.par_b, 0.0);
  HYPRE_ParVectorSetConstantValues(m.par_x, 0.0);
  if (HYPRE_BoomerAMGSetup(m.amg, m.par_a, m.par_b, m.par_x) != 0) {
    HYPRE_ClearAllErrors();
    return false;
  }
  m.levels = hypre_ParAMGDataNumLevels(reinterpret_cast<hypre_ParAMGData*>(m.amg));
  m.ready = true;
  return true;
}

void AmgPreconditioner::Solve(const MatrixN3& r, MatrixN3* z) const {
  Impl& m = *impl_;
  if (!m.ready) {
    z->setConstant(std::numeric_limits<double>::quiet_NaN());
    return;
  }
  double* b = hypre_VectorData(hypre_ParVectorLocalVector(m.par_b));
  double* x = hypre_VectorData(hypre_ParVectorLocalVector(m.par_x));
  const auto bytes = static_cast<std::size_t>(m.n) * sizeof(double);
  for (int c = 0; c < 3; ++c) {
    std::memcpy(b, r.col(c).data(), bytes);
    std::memset(x, 0, bytes);  // a preconditioner application starts from zero
    HYPRE_BoomerAMGSolve(m.amg, m.par_a, m.par_b, m.par_x);
    std::memcpy(z->col(c).data(), x, bytes);
  }
}

int AmgPreconditioner::levels() const { return impl_->levels; }

}  // namespace clothbench
