// The one output primitive of the project: every file clothbench writes
// (result files, XDMF, OBJ/PLY, CSV, states, journals' entries, locks'
// probes) goes through OutputFile or is checked by CheckOutputTarget, and
// every file it reads is noted by NoteInputFile, so that an output that is
// also an input of the same command is refused before anything is computed.
// Lives in model/, the lowest layer that reads files (scenes and meshes);
// results/, harness/ and bench/ use it.
#ifndef CLOTHBENCH_MODEL_OUTPUT_FILE_H_
#define CLOTHBENCH_MODEL_OUTPUT_FILE_H_

#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace clothbench {

/// An output that cannot be written safely (exit 2 at the command line,
/// ValueError in Python): one line naming the option, the path and the rule.
struct OutputRefused : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

/// Records `path` as an input of this command (scene, mesh, result file,
/// state): its device and inode, and its absolute path. Files that do not
/// exist are ignored. Thread-safe.
void NoteInputFile(const std::string& path);
/// Forgets every input (the Python module: each call is one command).
void ClearInputFiles();

/// The temporary an output is written under: "<target>.tmp".
std::string TemporaryOf(const std::string& target);

/// Checks, before anything is computed, that `target` may be written by a
/// rename from its temporary, without following a link or replacing what
/// the project does not own:
///  - `target` is absent or a regular file (lstat: a symbolic link, a
///    device, a FIFO, a socket or a folder is refused);
///  - its temporary "<target>.tmp" is absent or a regular file (a leftover
///    of a killed writer, removed when the write starts);
///  - `target` is not the same file (device and inode, or the same absolute
///    path) as an input noted by NoteInputFile, nor as any of `others`
///    (the command's other outputs).
/// @param option how the command names the path ("--out", "--obj", "path")
/// @throws OutputRefused "<option>: \"<path>\" <rule>"
void CheckOutputTarget(const std::string& target, const std::string& option,
                       const std::vector<std::string>& others = {});

/// Frees the name of `target`'s temporary for an exclusive create: a
/// leftover regular file of that name (a killed writer's) is unlinked.
/// For writers that create the file themselves (HDF5's H5Fcreate with
/// H5F_ACC_EXCL, i.e. O_CREAT|O_EXCL, which fails on a planted link).
/// @throws OutputRefused if something other than a regular file stands there
void FreeTemporaryName(const std::string& target, const std::string& option);

/// Creates `target`'s temporary for writing: a leftover regular file of
/// that name is unlinked, then the temporary is opened with
/// O_CREAT|O_EXCL|O_NOFOLLOW, so a symbolic link or anything else planted
/// there in between is never followed (the open fails).
/// @return the open descriptor (O_WRONLY, O_CLOEXEC)
/// @throws OutputRefused if something other than a regular file stands at
///   the temporary's name; std::runtime_error "<option>: \"<path>\":
///   <errno text>" if it cannot be created
int CreateTemporary(const std::string& target, const std::string& option);

/// Renames `target`'s temporary over `target` after checking once more
/// that `target` is absent or a regular file (CheckOutputTarget's first
/// rule; a link planted meanwhile is not replaced). The temporary is
/// removed if the rename fails or is refused.
/// @throws OutputRefused or std::runtime_error naming `option`
void CommitTemporary(const std::string& target, const std::string& option);

/// Writes `bytes` to `target` through its temporary (CreateTemporary,
/// written, fsync'ed, closed, CommitTemporary); the temporary is removed on
/// every failure path.
/// @throws OutputRefused; std::runtime_error "<option>: \"<path>\": <what>
///   failed: <errno text>" (a full disk: "No space left on device")
void WriteFileAtomically(const std::string& target, std::string_view bytes, const std::string& option);

}  // namespace clothbench

#endif  // CLOTHBENCH_MODEL_OUTPUT_FILE_H_
