// --plot DIR of bench_integrators and stress_stability: runs scripts/plot
// (Python, h5py + matplotlib) on the result file once it is written.
#ifndef CLOTHBENCH_HARNESS_PLOT_H_
#define CLOTHBENCH_HARNESS_PLOT_H_

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>

#include <fmt/format.h>

#include "harness/cli_args.h"
#include "model/output_file.h"
#include "model/scene.h"

namespace clothbench {

/// Refuses, before any computing, a --plot folder that cannot be created or
/// written. @throws std::invalid_argument naming the option and the folder.
inline bool PlotDirWritable(const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  return !ec && std::filesystem::is_directory(dir) && ::access(dir.c_str(), W_OK) == 0;
}
inline void CheckPlotDir(const std::string& dir) {
  if (!PlotDirWritable(dir))
    throw std::invalid_argument(fmt::format("--plot: \"{}\" is not a writable folder", EscapeControl(dir)));
}

/// Runs Debian's python3 (/usr/bin/python3, which carries h5py and
/// matplotlib) on `script` with `file` and `--out out`, each single-quoted
/// (no stored string reaches the shell unquoted), its stdout discarded.
/// Without that python3 it says so on stderr, naming `option`, and runs
/// nothing; if the script fails it says so. The result file is unaffected.
/// @returns true if the script ran and exited 0
inline bool RunPythonScript(const std::string& program, const std::string& option, const char* script,
                            const std::string& file, const std::string& out, const char* nothing) {
  const char* python = "/usr/bin/python3";
  const auto quote = [](const std::string& s) {
    std::string q = "'";
    for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return q + "'";
  };
  if (::access(python, X_OK) != 0 ||
      std::system(fmt::format("{} -c 'import h5py, matplotlib' 2> /dev/null", python).c_str()) != 0) {
    fmt::print(stderr, "{}: {}: {} with h5py and matplotlib not found (scripts/setup installs them); {}\n", program,
               option, python, nothing);
    return false;
  }
  std::fflush(stdout);
  // "--out=<out> -- <file>": a path starting with "-" is a value, never an option.
  // The report validates the file with the Python module of this build
  // (CLOTHBENCH_PYTHON_DIR).
  const std::string cmd = fmt::format("CLOTHBENCH_PYTHON_DIR={} {} {} {} -- {} > /dev/null", quote(CLOTHBENCH_PYTHON_DIR),
                                      python, quote(script), quote("--out=" + out), quote(file));
  if (std::system(cmd.c_str()) != 0) {
    fmt::print(stderr, "{}: {}: {} failed; the result file is complete\n", program, option, script);
    return false;
  }
  return true;
}

/// Runs scripts/plot on `file` into `dir` and prints where the plots are
/// (RunPythonScript). @returns true if the plots were written.
inline bool Plot(const std::string& program, const std::string& file, const std::string& dir) {
  if (!RunPythonScript(program, "--plot", CLOTHBENCH_PLOT_SCRIPT, file, dir, "no plots")) return false;
  fmt::print("plots: {}/{}_*.png and .svg\n", dir, std::filesystem::path(file).stem().string());
  return true;
}

/// The page scripts/report writes for `result_file`: its stem + ".html" beside it.
inline std::string ReportPageOf(const std::string& result_file) {
  return std::filesystem::path(result_file).replace_extension(".html").string();
}

/// The first line of every page scripts/report writes: the mark of a page it may replace.
inline constexpr std::string_view kReportMark = "<!-- clothbench report -->";

/// Refuses, before any computing, a --report page that scripts/report would
/// refuse after it: what CheckOutputTarget refuses at the page's path (a
/// link, folder or device; an input of the command or `result_file`
/// itself), or a file there that is not a page of scripts/report (it is
/// never replaced).
/// @throws UsageError "--report: \"<page>\" <rule>"
inline void CheckReportTarget(const std::string& result_file) {
  const std::string page = ReportPageOf(result_file);
  try {
    CheckOutputTarget(page, "--report", {result_file});
  } catch (const OutputRefused& e) {
    throw UsageError(e.what());
  }
  if (!std::filesystem::exists(std::filesystem::symlink_status(page))) return;
  std::FILE* f = std::fopen(page.c_str(), "rb");
  std::string head(kReportMark.size(), '\0');
  const bool mark = f && std::fread(head.data(), 1, head.size(), f) == head.size() && head == kReportMark;
  if (f) std::fclose(f);
  if (!mark)
    throw UsageError(fmt::format("--report: \"{}\" exists and is not a clothbench report (not replaced)",
                                 EscapeControl(page)));
}

/// The exit code of a command whose result file is complete but whose
/// --report page was not written (the reason is on stderr).
inline constexpr int kExitNoPage = 4;

/// Runs scripts/report on `file` (the page beside it, ReportPageOf) and
/// prints the page's path (RunPythonScript).
/// @returns 0 if the page was written, else kExitNoPage (said on stderr)
inline int Report(const std::string& program, const std::string& file) {
  const std::string page = ReportPageOf(file);
  if (!RunPythonScript(program, "--report", CLOTHBENCH_REPORT_SCRIPT, file, page, "no page")) {
    fmt::print(stderr, "{}: --report: no page written (exit {})\n", program, kExitNoPage);
    return kExitNoPage;
  }
  fmt::print("report: {}\n", page);
  return 0;
}

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_PLOT_H_
