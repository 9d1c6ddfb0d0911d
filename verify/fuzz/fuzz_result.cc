// libFuzzer target of the result-file reader (results/result_reader.h) and
// of what clothbench_inspect reads after ValidateResultFile accepted a file
// (docs/verification.md, "Fuzzing").
//
// For any byte string, opened as an in-memory HDF5 image, the reader must
// either refuse it with a ResultError whose message is one line naming the
// file, or accept it; after ValidateResultFile accepted it, the run table,
// every attribute, every stored frame of every run, the faces, the step
// tables and the printed table must be readable without another exception,
// every frame value finite and every face index a particle of the scene.
// Anything else (another exception, a sanitizer report, a violated
// invariant) aborts and is a finding. Seeds: small result files of
// bench_integrators and stress_stability (verify/fuzz/results/).
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "results/result_reader.h"
#include "results/run_table.h"

namespace {

[[noreturn]] void Finding(const char* what, const std::string& detail) {
  std::fprintf(stderr, "fuzz_result finding: %s: %s\n", what, detail.c_str());
  std::abort();
}

void ReadEverything(const clothbench::ResultReader& f) {
  using namespace clothbench;
  const RunTable t = ReadRunTable(f);
  std::FILE* null = std::fopen("/dev/null", "w");
  if (null) {
    PrintRunTable(null, t);
    if (t.work_precision) PrintWorkPrecision(null, *t.work_precision);
    std::fclose(null);
  }
  std::vector<std::string> groups;
  if (f.Exists("/reference")) groups.push_back("/reference");
  for (const std::string& id : f.Children("/runs")) groups.push_back("/runs/" + id);
  const long n = f.Long("/scene", "n_particles").value_or(0);
  if (f.Exists("/scene/faces"))
    for (int32_t q : f.Ints("/scene/faces"))
      if (q < 0 || q >= n) Finding("face index outside the particles", std::to_string(q));
  if (f.Exists("/scene/toml")) f.Text("/scene/toml");
  for (const std::string& g : groups) {
    f.Attributes(g);
    for (const char* name : {"positions", "velocities", "positions_ends", "velocities_ends"}) {
      const std::string d = g + "/" + name;
      if (!f.Exists(d)) continue;
      const std::vector<std::size_t> shape = f.Shape(d);
      for (std::size_t k = 0; k < shape[0]; ++k) {
        const MatrixN3 x = f.Frame(d, k);
        if (x.rows() != n || !x.allFinite()) Finding("frame not N×3 finite", d);
      }
    }
    if (f.Exists(g + "/step_stats")) f.StepStats(g + "/step_stats");
    if (f.Exists(g + "/times"))
      for (double v : f.Doubles(g + "/times"))
        if (!std::isfinite(v)) Finding("non-finite time", g);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace clothbench;
  try {
    const ResultReader f("fuzz.h5", data, size);
    ValidateResultFile(f);
    try {
      ReadEverything(f);
    } catch (const ResultError& e) {
      // A frame value that is not finite is found when the frame is read
      // (ValidateResultFile checks extents, not every frame's values).
      if (std::string(e.what()).find("non-finite value") == std::string::npos &&
          std::string(e.what()).find("cannot read") == std::string::npos)
        Finding("ResultError after ValidateResultFile accepted the file", e.what());
    }
  } catch (const ResultError& e) {
    const std::string m = e.what();
    if (m.empty() || m.find('\n') != std::string::npos || m.rfind("fuzz.h5", 0) != 0)
      Finding("refusal not one line naming the file", m);
  }
  return 0;
}
