// Command-line pieces the executables share: the usage error every
// refusal throws, comma-separated lists, and the --out check. Each refusal
// is one line naming the option and the rule (exit 2, docs/scenes.md
// "Limits").
#ifndef CLOTHBENCH_HARNESS_CLI_ARGS_H_
#define CLOTHBENCH_HARNESS_CLI_ARGS_H_

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "model/scene.h"
#include "peers/arkode.h"

namespace clothbench {

/// Bad command-line input: reported as one line, exit code 2.
struct UsageError : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

/// "ic0" | "cholesky" | "amg" | "jacobi" | "none".
/// @throws UsageError naming `option` for any other name
inline PreconditionerType ParsePreconditioner(const std::string& name, const std::string& option) {
  for (PreconditionerType t : {PreconditionerType::kIc0, PreconditionerType::kCholesky, PreconditionerType::kAmg,
                               PreconditionerType::kJacobi, PreconditionerType::kNone})
    if (name == ToString(t)) return t;
  throw UsageError(fmt::format("{}: \"{}\" must be ic0, cholesky, amg, jacobi or none", option, name));
}

/// The items of a comma-separated list, trimmed. @throws UsageError naming
/// `option` for an empty list or an empty item (leading, inner or trailing).
inline std::vector<std::string> SplitList(const std::string& s, const std::string& option) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  const auto empty_item = [&] {
    return UsageError(fmt::format("{}: empty item in the list \"{}\"", option, EscapeControl(s)));
  };
  while (std::getline(ss, item, ',')) {
    const auto b = item.find_first_not_of(" \t"), e = item.find_last_not_of(" \t");
    if (b == std::string::npos) throw empty_item();
    out.push_back(item.substr(b, e - b + 1));
  }
  if (out.empty()) throw UsageError(fmt::format("{}: empty list \"{}\"", option, EscapeControl(s)));
  const auto last = s.find_last_not_of(" \t");
  if (last != std::string::npos && s[last] == ',') throw empty_item();  // a trailing comma
  return out;
}

/// A list of finite positive numbers, each once (two equal entries would
/// give two rows or cells with one name). @throws UsageError naming `option`.
inline std::vector<double> ParsePositiveList(const std::string& s, const std::string& option) {
  std::vector<double> out;
  for (const std::string& item : SplitList(s, option)) {
    std::size_t pos = 0;
    double v = 0.0;
    try {
      v = std::stod(item, &pos);
    } catch (...) {
      pos = 0;
    }
    if (pos != item.size() || !std::isfinite(v) || !(v > 0.0))
      throw UsageError(fmt::format("{}: \"{}\" is not a positive number", option, item));
    if (std::find(out.begin(), out.end(), v) != out.end())
      throw UsageError(fmt::format("{}: {:g} is listed twice", option, v));
    out.push_back(v);
  }
  return out;
}

/// @throws UsageError if `name` is not one of ArkodeTableNames() (--arkode-table).
inline void CheckArkodeTable(const std::string& name) {
  if (std::find(ArkodeTableNames().begin(), ArkodeTableNames().end(), name) != ArkodeTableNames().end()) return;
  std::string known;
  for (const std::string& t : ArkodeTableNames()) known += (known.empty() ? "" : ", ") + t;
  throw UsageError(fmt::format("--arkode-table: \"{}\" must be one of {}", name, known));
}

/// Refuses, before any computing, an --out that is a directory or whose
/// folder cannot be created or written (the folder is created).
inline void CheckOutputFolder(const std::string& out) {
  if (std::filesystem::is_directory(out)) throw UsageError(fmt::format("--out: \"{}\" is a directory", out));
  std::filesystem::path folder = std::filesystem::path(out).parent_path();
  if (folder.empty()) folder = ".";
  std::error_code ec;
  std::filesystem::create_directories(folder, ec);
  if (ec || !std::filesystem::is_directory(folder) || ::access(folder.c_str(), W_OK) != 0)
    throw UsageError(fmt::format("--out: folder \"{}\" {}", folder.string(),
                                 ec ? "cannot be created: " + ec.message() : std::string("is not writable")));
}

/// The smallest relative tolerance a run in double precision can meet: a
/// hundred units of round-off (ε ≈ 2.2e-16). Below it CVODE, IDA, ARKODE
/// and the error-controlled rows cut the step until the step limit.
inline constexpr double kMinRelativeTolerance = 1e-14;

/// A relative tolerance in [kMinRelativeTolerance, 1). @throws UsageError
/// naming `option` and the rule.
inline void CheckTolerance(double rtol, const std::string& option) {
  if (!std::isfinite(rtol) || !(rtol > 0.0) || rtol >= 1.0)
    throw UsageError(fmt::format("{}: {:g} must be a positive number below 1", option, rtol));
  if (rtol < kMinRelativeTolerance)
    throw UsageError(fmt::format("{}: {:g} is below {:g}, which double precision cannot meet (100 units of round-off)",
                                 option, rtol, kMinRelativeTolerance));
}

/// A list of relative tolerances, each checked by CheckTolerance.
inline std::vector<double> ParseTolerances(const std::string& s, const std::string& option) {
  std::vector<double> out = ParsePositiveList(s, option);
  for (double r : out) CheckTolerance(r, option);
  return out;
}

/// Probes an output file before anything is computed: its folder is
/// created, the file opened for appending (nothing it holds is changed) and
/// removed again if it did not exist. @throws UsageError naming `option`.
inline void CheckWritableFile(const std::string& path, const std::string& option) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw UsageError(fmt::format("{}: \"{}\" is a folder", option, EscapeControl(path)));
  const fs::path folder = fs::path(path).parent_path();
  if (!folder.empty()) fs::create_directories(folder, ec);
  const bool existed = fs::exists(fs::symlink_status(path, ec));
  if (existed && !fs::is_regular_file(path, ec))
    throw UsageError(fmt::format("{}: \"{}\" is not a regular file", option, EscapeControl(path)));
  const bool ok = static_cast<bool>(std::ofstream(path, std::ios::app));
  if (!existed) fs::remove(path, ec);
  if (!ok) throw UsageError(fmt::format("{}: cannot write \"{}\"", option, EscapeControl(path)));
}

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_CLI_ARGS_H_
