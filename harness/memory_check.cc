// The memory estimate a run is checked against before any computing.
#include "harness/memory_check.h"

#include <sys/statvfs.h>

#include <filesystem>
#include <fstream>
#include <string>

#include <fmt/format.h>

#include "harness/cli_args.h"

namespace clothbench {

// Bytes of memory available to this process (MemAvailable of
// /proc/meminfo; 0 if unknown).
double AvailableBytes() {
  std::ifstream in("/proc/meminfo");
  std::string key;
  double kb = 0.0;
  while (in >> key) {
    if (key == "MemAvailable:" && (in >> kb)) return kb * 1024.0;
    in.ignore(1 << 12, '\n');
  }
  return 0.0;
}

double FreeDiskBytes(const std::string& path) {
  std::filesystem::path folder = std::filesystem::path(path).parent_path();
  if (folder.empty()) folder = ".";
  struct statvfs st {};
  if (::statvfs(folder.c_str(), &st) != 0) return 0.0;
  return static_cast<double>(st.f_bavail) * static_cast<double>(st.f_frsize);
}

// Refuses, before any computing, a run whose frames and solver state would
// not fit in memory. Estimate per particle [bytes]: 24 per N×3 matrix, of
// which the step engine holds ~25 and every kept frame 2 (positions and
// velocities, held for all rows until the file is written); A_α and the
// Laplacians ~200; the CHOLMOD factor and what its analysis and
// factorisation hold at their peak (METIS' ordering, the symbolic factor,
// CHOLMOD's workspace) 2.2 kB: sbdf2 with the cholesky preconditioner
// peaks at 3.00 GB at 10⁶ particles and 0.297 GB at 316² (`/usr/bin/time
// -v build/bench/bench_integrators --scene large_sheet --integrators
// sbdf2 --h 0.01 --reference none --frames none`), 3.0 kB per particle
// (the earlier 45 entries × 12 bytes counted the factor alone and let a
// 9·10⁶-particle run start and be killed at 23.7 GB); the SUNDIALS references a 3N×3N Jacobian
// (~117 entries per particle row triple) and its KLU factor with fill,
// taken as 4 kB per particle (an upper estimate, not a measurement).
// Every attempted step keeps a StepStats in the run and a StepRecord in its
// row until the file is written (`step_records` of all rows, ~100 bytes each).
void CheckMemory(const Scene& scene, const std::vector<RowMethod>& methods, const std::vector<std::size_t>& n_params,
                 std::size_t n_eta, const std::optional<RowMethod>& reference, double step_records,
                 const std::string& out) {
  const double n = scene.num_particles();
  const double frames = static_cast<double>(FrameTimes(scene.t_end, scene.frame_dt).size());
  double rows = 0.0;
  // The reduced references (cvode, ida) hold J_α like a tangent row; the
  // /klu ones the 6N×6N Jacobian and its factor.
  const bool sundials_reference = reference && scene.obstacles.empty();
  bool sundials = sundials_reference && !reference->uses_pcg();
  bool tangent = sundials_reference && reference->uses_pcg();
  for (std::size_t k = 0; k < methods.size(); ++k) {
    const RowMethod& m = methods[k];
    const double per = static_cast<double>(n_params[k]);
    rows += per * static_cast<double>(m.uses_pcg() ? n_eta : 1);
    if (m.entry->sparse_jacobian) sundials = true;
    if (m.solver == NonlinearSolver::kNewton || m.entry->tangent) tangent = true;
  }
  if (reference) rows += 1.0;
  // (rows + 1): the frames of every row, and one more copy of a row's as the
  // bytes that go to the journal and to rank 0 (harness/run_codec.h).
  double bytes = n * (25.0 * 24.0 + 200.0) + (rows + 1.0) * frames * 2.0 * 24.0 * n + step_records * 100.0;
  if (scene.solver.preconditioner == PreconditionerType::kCholesky ||
      scene.solver.preconditioner == PreconditionerType::kAuto)
    bytes += n * 2.2e3;
  if (sundials) bytes += n * 4096.0;
  // Newton and Baraff–Witkin rows hold the 3N×3N tangent system J_α with
  // ∂f/∂x, ∂f/∂v, its constant part and transpose positions on its pattern,
  // and its preconditioner: 6.5 kB per particle (measured peak RSS 7.76 GB
  // for baraff_witkin on the 10⁶-particle large_sheet, `/usr/bin/time -v
  // build/bench/bench_integrators --scene large_sheet --integrators
  // baraff_witkin --h 0.01 --reference none --frames none`).
  if (tangent) bytes += n * 6.5e3;
  const double available = AvailableBytes();
  if (available > 0.0 && bytes > 0.8 * available)
    throw UsageError(fmt::format(
        "{}: grid.nu × grid.nv = {} × {} = {:.0f} particles: this run needs about {:.1f} GB ({:.0f} frames × {:.0f} "
        "runs kept, {:.3g} step records), more than 80 % of the {:.1f} GB available; use --frames ends|none, fewer --h/--integrators, "
        "--reference none, or smaller nu/nv",
        scene.source, scene.grid.nu, scene.grid.nv, n, bytes / 1e9, frames, rows, step_records, available / 1e9));
  if (out.empty()) return;
  // On disk: every run's frames (positions and velocities, 8 bytes each)
  // and step records twice, in the journal and in the result file.
  const double disk = 2.0 * (rows * frames * 2.0 * 24.0 * n + step_records * 64.0) + 1e5;  // + HDF5 metadata
  const double free = FreeDiskBytes(out);
  if (free > 0.0 && disk > free)
    throw UsageError(fmt::format("--out: \"{}\": the journal and the result file need about {:.3g} MB ({:.0f} frames × "
                                 "{:.0f} runs of {:.0f} particles), more than the {:.3g} MB free there; use --frames "
                                 "ends|none or another --out",
                                 EscapeControl(out), disk / 1e6, frames, rows, n, free / 1e6));
}


}  // namespace clothbench
