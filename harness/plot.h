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

#include <fmt/format.h>

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

/// Runs scripts/plot on `file` into `dir` and prints where the plots are.
/// Without Debian's python3 (/usr/bin/python3, which carries h5py and
/// matplotlib) it says so on stderr and writes nothing; the result file is
/// unaffected. @returns true if the plots were written.
inline bool Plot(const std::string& program, const std::string& file, const std::string& dir) {
  const char* python = "/usr/bin/python3";
  const auto quote = [](const std::string& s) {
    std::string q = "'";
    for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return q + "'";
  };
  if (::access(python, X_OK) != 0 ||
      std::system(fmt::format("{} -c 'import h5py, matplotlib' 2> /dev/null", python).c_str()) != 0) {
    fmt::print(stderr, "{}: --plot: {} with h5py and matplotlib not found (scripts/setup installs them); no plots\n",
               program, python);
    return false;
  }
  std::fflush(stdout);
  const std::string cmd = fmt::format("{} {} {} --out {} > /dev/null", python, quote(CLOTHBENCH_PLOT_SCRIPT),
                                      quote(file), quote(dir));
  if (std::system(cmd.c_str()) != 0) {
    fmt::print(stderr, "{}: --plot: {} failed; the result file is complete\n", program, CLOTHBENCH_PLOT_SCRIPT);
    return false;
  }
  fmt::print("plots: {}/{}_*.png and .svg\n", dir, std::filesystem::path(file).stem().string());
  return true;
}

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_PLOT_H_
