// Not starting a run whose prediction exceeds what it may use
// (docs/notes/work-precision.md, "Predicting a first run").
#ifndef CLOTHBENCH_HARNESS_FIRST_RUN_H_
#define CLOTHBENCH_HARNESS_FIRST_RUN_H_

#include <string_view>

#include "model/particle_system.h"
#include "solver/record/run_record.h"
#include "solver/run.h"

namespace clothbench {

/// True (run's status kNotStarted, its message the prediction, the bound it
/// exceeds and the prediction's source) if `p` predicts more than
/// `time_limit_s` [s] (> 0; ≤ 0: no limit) or more than 80 % of the memory
/// available now (MemAvailable, harness/memory_check.h) — the share
/// CheckMemory allows a whole command.
bool RefusedByPrediction(const FirstRunPrediction& p, double time_limit_s, RunSummary* run);

/// predict(sys, variant), computed once per process for each function,
/// variant and scene text (Scene::toml: a refined scene has its own), so
/// that a row's every h or rtol, and a sweep's rerun of it, share one
/// analysis and one timing of the machine (reference/klu_prediction.h).
FirstRunPrediction PredictOnce(FirstRunPrediction (*predict)(const ParticleSystem&, std::string_view),
                               const ParticleSystem& sys, std::string_view variant);

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_FIRST_RUN_H_
