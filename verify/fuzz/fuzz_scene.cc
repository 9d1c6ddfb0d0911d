// libFuzzer target of the scene parser and validator (model/scene.cc) and of
// the model built from what it accepts (docs/notes/verification.md, "Fuzzing").
//
// For any byte string, ParseScene must either refuse it with a SceneError
// whose message is one line naming the source, or return a scene whose
// every derived quantity is finite and within the stated limits
// (docs/guide/scenes.md, "Limits"); for accepted scenes of at most 400 particles
// without mesh obstacles the particle system is built and its forces and
// energies at rest, and at a perturbed state, must be finite (a garment
// whose sewing phase has not run has no model yet). Anything else
// (another exception, a sanitizer report, a violated invariant) aborts and
// is a finding. Built with clang only (-fsanitize=fuzzer,address,undefined),
// from the main build through verify/CMakeLists.txt.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "model/particle_system.h"
#include "model/scene.h"

namespace {

[[noreturn]] void Finding(const char* what, const std::string& detail) {
  std::fprintf(stderr, "fuzz_scene finding: %s: %s\n", what, detail.c_str());
  std::abort();
}

void CheckScene(const clothbench::Scene& s) {
  using namespace clothbench;
  if (!(s.t_end > 0 && s.t_end <= 1e6)) Finding("t_end out of range", std::to_string(s.t_end));
  if (!(s.t_end / s.frame_dt <= kMaxFramesPerRun)) Finding("frame count above the limit", std::to_string(s.frame_dt));
  if (!(s.t_end / s.h <= kMaxStepsPerRun)) Finding("step count above the limit", std::to_string(s.h));
  if (!(static_cast<double>(s.num_particles()) <= kMaxParticles)) Finding("too many particles", "");
  if (!std::isfinite(s.NumericalStiffness(s.h))) Finding("non-finite numerical stiffness", "");
  if (!(s.lu() >= 1e-6 && s.lv() >= 1e-6)) Finding("spacing below 1e-6 m", "");
}

bool HasMesh(const clothbench::Scene& s) {
  for (const auto& o : s.obstacles)
    if (o.shape->loads_file()) return true;
  return false;
}

void CheckModel(const clothbench::Scene& s) {
  using namespace clothbench;
  const ParticleSystem sys(s);
  if (!sys.masses().allFinite() || !(sys.masses().minCoeff() > 0.0)) Finding("non-positive or non-finite mass", "");
  if (!sys.rest_positions().allFinite()) Finding("non-finite rest positions", "");
  for (double t : {0.0, 0.5 * s.t_end, s.t_end})  // moving fixed particles: a finite prescribed state
    sys.ForEachPrescribed(t, [&](int p, const Vector3& x, const Vector3& v) {
      if (!x.allFinite() || !v.allFinite()) Finding("non-finite prescribed state", std::to_string(p));
    });
  const int n = sys.num_particles();
  MatrixN3 v = MatrixN3::Zero(n, 3), f(n, 3);
  // At rest, and displaced by 1 % of the spacing with 1 m/s velocities:
  // forces and energies of an admissible state must be finite.
  MatrixN3 x = sys.rest_positions();
  for (int pass = 0; pass < 2; ++pass) {
    sys.Forces(0.0, x, v, &f);
    if (!f.allFinite()) Finding("non-finite force", std::to_string(pass));
    const EnergyBreakdown e = sys.Energies(x, v);
    if (!std::isfinite(e.total())) Finding("non-finite energy", std::to_string(pass));
    for (int p = 0; p < n; ++p) {
      x(p, 2) += 0.01 * std::min(s.lu(), s.lv()) * ((p % 3) - 1);
      v(p, p % 3) = 1.0;
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  clothbench::Scene scene;
  try {
    scene = clothbench::ParseScene(text, "<fuzz>");
  } catch (const clothbench::SceneError& e) {
    const std::string m = e.what();
    if (m.rfind("<fuzz>", 0) != 0) Finding("refusal does not name the source", m);
    return 0;  // refused: the expected outcome for most inputs
  }
  CheckScene(scene);
  // Mesh paths name files of the machine, not of the input: not loaded here.
  // A garment with a sewing phase still to run has no model yet: it is
  // built from the sewn cloth (solver/sewing.h, a simulation the fuzzer
  // does not run); its patterns and seams were checked by ParseScene.
  const bool sewing_pending = scene.cloth && !scene.cloth->sewn;
  if (scene.num_particles() <= 400 && !HasMesh(scene) && !sewing_pending) {
    try {
      CheckModel(scene);
    } catch (const clothbench::SceneError& e) {
      Finding("an accepted scene is refused when the model is built", e.what());
    }
  }
  return 0;
}
