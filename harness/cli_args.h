// Command-line pieces the executables share: the usage error every
// refusal throws, comma-separated lists, and the --out check. Each refusal
// is one line naming the option and the rule (exit 2, docs/guide/scenes.md
// "Limits").
#ifndef CLOTHBENCH_HARNESS_CLI_ARGS_H_
#define CLOTHBENCH_HARNESS_CLI_ARGS_H_

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "model/output_file.h"
#include "model/scene.h"

namespace clothbench {

/// Bad command-line input: reported as one line, exit code 2.
struct UsageError : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

/// "ic0" | "cholesky" | "amg" | "auto" | "jacobi" | "none".
/// @throws UsageError naming `option` for any other name
inline PreconditionerType ParsePreconditioner(const std::string& name, const std::string& option) {
  for (PreconditionerType t : {PreconditionerType::kIc0, PreconditionerType::kCholesky, PreconditionerType::kAmg,
                               PreconditionerType::kAuto, PreconditionerType::kJacobi, PreconditionerType::kNone})
    if (name == ToString(t)) return t;
  throw UsageError(fmt::format("{}: \"{}\" must be ic0, cholesky, amg, auto, jacobi or none", option, name));
}

/// "adaptive" | "nearest_axis" | "spread" (SolverSpec::amg_frames).
/// @throws UsageError naming `option` for any other name
inline AmgFrames ParseAmgFrames(const std::string& name, const std::string& option) {
  for (AmgFrames f : {AmgFrames::kAdaptive, AmgFrames::kNearestAxis, AmgFrames::kSpread})
    if (name == ToString(f)) return f;
  throw UsageError(fmt::format("{}: \"{}\" must be adaptive, nearest_axis or spread", option, name));
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

/// A list of finite positive numbers, each once to 6 significant digits
/// (two entries printing alike would give two rows or cells with one name,
/// e.g. sbdf2_h0.01 for 0.01 and 0.0100000000001). @throws UsageError
/// naming `option`.
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
    // Rows and cells are named with 6 significant digits ({:g}).
    for (double w : out)
      if (fmt::format("{:g}", w) == fmt::format("{:g}", v))
        throw UsageError(w == v ? fmt::format("{}: {:g} is listed twice", option, v)
                                : fmt::format("{}: {} and {} are the same to 6 significant digits, which name the "
                                              "rows and cells; list values that differ there",
                                              option, EscapeControl(item), fmt::format("{:.17g}", w)));
    out.push_back(v);
  }
  return out;
}

/// Refuses, before any computing, an --out that cannot be written, with one
/// line naming --out and the path: a folder (created if missing) that cannot
/// be created or written; <out> and the XDMF file <stem>.xdmf, each with its
/// temporary, by the project's output rules (CheckOutputTarget: absent or
/// regular files, never links, devices or FIFOs, and not an input of the
/// command); <out>.journal a folder (bench_integrators) or a regular file
/// (`journal_folder` false: stress_stability) or absent, never a link.
/// Absent files are created and removed again (a probe: the name is
/// accepted by the file system).
/// @param option how the caller names the path in messages ("--out";
///   the Python module's "path")
/// @throws UsageError
inline void CheckOutputPaths(const std::string& out, bool journal_folder = true,
                             const std::string& option = "--out") {
  namespace fs = std::filesystem;
  const auto refuse = [&](const std::string& path, const std::string& why) {
    return UsageError(fmt::format("{}: \"{}\" {}", option, EscapeControl(path), why));
  };
  std::error_code ec;
  fs::path folder = fs::path(out).parent_path();
  if (folder.empty()) folder = ".";
  fs::create_directories(folder, ec);
  if (ec || !fs::is_directory(folder, ec) || ::access(folder.c_str(), W_OK) != 0)
    throw UsageError(fmt::format("{}: folder \"{}\" {}", option, EscapeControl(folder.string()),
                                 ec ? "cannot be created: " + ec.message() : std::string("is not writable")));
  fs::path xdmf = out;
  xdmf.replace_extension(".xdmf");
  try {
    CheckOutputTarget(out, option);
    CheckOutputTarget(xdmf.string(), option);
  } catch (const OutputRefused& e) {
    throw UsageError(e.what());
  }
  const std::string journal = out + ".journal";
  const fs::file_status st = fs::symlink_status(journal, ec);
  if (ec && ec != std::errc::no_such_file_or_directory) throw refuse(journal, "cannot be used: " + ec.message());
  if (fs::exists(st) && (journal_folder ? !fs::is_directory(st) : !fs::is_regular_file(st)))
    throw refuse(journal, journal_folder ? "is not a folder (a journal of this output is one; links are not followed)"
                                         : "is not a regular file (links are not followed)");
  for (const std::string& path : {out, TemporaryOf(out), xdmf.string(), TemporaryOf(xdmf.string()), journal}) {
    if (fs::exists(fs::symlink_status(path, ec))) continue;
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0644);
    if (fd < 0) throw refuse(path, fmt::format("cannot be created: {}", std::strerror(errno)));
    ::close(fd);
    ::unlink(path.c_str());
  }
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

/// Probes an output file before anything is computed: the project's output
/// rules (CheckOutputTarget: absent or a regular file, never a link, device,
/// FIFO or folder, not an input of the command nor one of `others`, the
/// command's other outputs), its folder created, and the name accepted by
/// the file system (an absent file is created exclusively and removed).
/// @throws UsageError naming `option`.
inline void CheckWritableFile(const std::string& path, const std::string& option,
                              const std::vector<std::string>& others = {}) {
  namespace fs = std::filesystem;
  std::error_code ec;
  try {
    CheckOutputTarget(path, option, others);
  } catch (const OutputRefused& e) {
    throw UsageError(e.what());
  }
  const fs::path folder = fs::path(path).parent_path();
  if (!folder.empty()) fs::create_directories(folder, ec);
  if (fs::exists(fs::symlink_status(path, ec))) {
    if (::access(path.c_str(), W_OK) != 0)
      throw UsageError(fmt::format("{}: cannot write \"{}\": {}", option, EscapeControl(path), std::strerror(errno)));
    return;
  }
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0644);
  if (fd < 0)
    throw UsageError(fmt::format("{}: cannot write \"{}\": {}", option, EscapeControl(path), std::strerror(errno)));
  ::close(fd);
  ::unlink(path.c_str());
}

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_CLI_ARGS_H_
