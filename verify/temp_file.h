// A file the tests write for a reader that takes a path (mesh obstacles).
#ifndef CLOTHBENCH_VERIFY_TEMP_FILE_H_
#define CLOTHBENCH_VERIFY_TEMP_FILE_H_

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>

namespace clothbench::testing {

/// <tmp>/<pid>_<name> holding `text`, removed when the object goes out of
/// scope. Named after the process: ctest runs the tests of one file as
/// parallel processes, which must not write one file.
class TempFile {
 public:
  TempFile(const std::string& name, const std::string& text)
      : path_((std::filesystem::temp_directory_path() / (std::to_string(::getpid()) + "_" + name)).string()) {
    std::ofstream(path_) << text;
  }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  ~TempFile() {
    std::error_code ignored;
    std::filesystem::remove(path_, ignored);
  }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

}  // namespace clothbench::testing

#endif  // CLOTHBENCH_VERIFY_TEMP_FILE_H_
