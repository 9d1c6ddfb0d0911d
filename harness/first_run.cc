// Not starting a run whose prediction exceeds what it may use.
#include "harness/first_run.h"

#include <cstdint>
#include <map>
#include <mutex>
#include <string>

#include <fmt/format.h>

#include "harness/memory_check.h"
#include "harness/sweep.h"

namespace clothbench {

bool RefusedByPrediction(const FirstRunPrediction& p, double time_limit_s, RunSummary* run) {
  if (time_limit_s > 0.0 && p.seconds > time_limit_s) {
    run->status = RunStatus::kNotStarted;
    run->message = fmt::format("not started: predicted at {:.3g} s, past --time-limit {:g} s ({})",
                               p.seconds, time_limit_s, p.source);
    return true;
  }
  const double available = p.bytes > 0.0 ? AvailableBytes() : 0.0;
  if (available > 0.0 && p.bytes > 0.8 * available) {
    run->status = RunStatus::kNotStarted;
    run->message = fmt::format("not started: predicted to hold {:.3g} GB, more than 80 % of the {:.3g} GB "
                               "available ({})",
                               p.bytes / 1e9, available / 1e9, p.source);
    return true;
  }
  return false;
}

FirstRunPrediction PredictOnce(FirstRunPrediction (*predict)(const ParticleSystem&, std::string_view),
                               const ParticleSystem& sys, std::string_view variant) {
  static std::mutex mutex;
  static std::map<std::string, FirstRunPrediction> known;
  const std::string key = fmt::format("{}|{}|{}", reinterpret_cast<std::uintptr_t>(predict), variant,
                                      Fnv1a64(sys.scene().toml));
  {
    const std::lock_guard<std::mutex> lock(mutex);
    if (const auto it = known.find(key); it != known.end()) return it->second;
  }
  FirstRunPrediction p = predict(sys, variant);
  const std::lock_guard<std::mutex> lock(mutex);
  return known.emplace(key, std::move(p)).first->second;
}

}  // namespace clothbench
