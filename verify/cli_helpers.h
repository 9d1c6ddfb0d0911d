// What the end-to-end tests of the executables share: a tiny scene, a
// per-process temporary folder and running a command with its output
// captured.
#ifndef CLOTHBENCH_VERIFY_CLI_HELPERS_H_
#define CLOTHBENCH_VERIFY_CLI_HELPERS_H_

#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>

namespace clothbench::testing {

/// 4×3 particles, 0.04 s at h = 0.01 s, two fixed corners: a run of every
/// method takes milliseconds.
inline const char* const kTinyScene = R"(name = "tiny"
t_end = 0.04
frame_dt = 0.01
h = 0.01
[grid]
nu = 4
nv = 3
size = [0.3, 0.2]
[material]
tension = [100.0, 100.0]
tension_damping = 0.1
shear = 1.0
bend = [1e-5, 1e-5]
[constraints]
fixed = ["corner:u0v1", "corner:u1v1"]
[solver]
cg_tolerance = 1e-10
)";

/// <tmp>/<prefix><pid>, created; removed with its contents when the test
/// process exits.
inline std::filesystem::path TempDir(const std::string& prefix) {
  struct Removed {
    std::set<std::filesystem::path> dirs;
    ~Removed() {
      for (const auto& d : dirs) {
        std::error_code ignored;
        std::filesystem::remove_all(d, ignored);
      }
    }
  };
  static Removed made;
  std::filesystem::path d = std::filesystem::temp_directory_path() / (prefix + std::to_string(::getpid()));
  std::filesystem::create_directories(d);
  made.dirs.insert(d);
  return d;
}

inline std::string Slurp(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

struct Outcome {
  int exit_code;
  std::string out, err;
};

/// Runs `binary args` through the shell with stdout and stderr captured in
/// files under `dir`.
inline Outcome RunCommand(const std::string& binary, const std::string& args, const std::filesystem::path& dir) {
  const std::filesystem::path out = dir / "stdout.txt", err = dir / "stderr.txt";
  const std::string cmd = binary + " " + args + " > " + out.string() + " 2> " + err.string();
  const int rc = std::system(cmd.c_str());
  return {WIFEXITED(rc) ? WEXITSTATUS(rc) : -1, Slurp(out), Slurp(err)};
}

}  // namespace clothbench::testing

#endif  // CLOTHBENCH_VERIFY_CLI_HELPERS_H_
