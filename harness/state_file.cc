#include "harness/state_file.h"

#include <zlib.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>

#include "harness/sweep.h"
#include "model/output_file.h"

namespace clothbench {
namespace {

constexpr char kMagic[8] = {'C', 'B', 'S', 'T', 'A', 'T', 'E', '2'};

// The scene's hash as stored in a state file.
std::uint64_t SceneKey(const Scene& scene) { return std::stoull(Fnv1a64(scene.toml), nullptr, 16); }

constexpr std::size_t kHead = sizeof kMagic + sizeof(std::uint64_t) + sizeof(std::int64_t) + sizeof(double);

}  // namespace

std::size_t StateBytes(Eigen::Index n) {
  return kHead + 2 * static_cast<std::size_t>(3 * n) * sizeof(double) + sizeof(std::uint32_t);
}

// The bytes of a state file of `s` on `scene`.
std::string EncodeState(const Scene& scene, const State& s) {
  const auto n = static_cast<std::int64_t>(s.x.rows());
  const std::uint64_t key = SceneKey(scene);
  std::string bytes(kMagic, sizeof kMagic);
  bytes.append(reinterpret_cast<const char*>(&key), sizeof key);
  bytes.append(reinterpret_cast<const char*>(&n), sizeof n);
  bytes.append(reinterpret_cast<const char*>(&s.t), sizeof s.t);
  const auto block = static_cast<std::size_t>(3 * n) * sizeof(double);
  for (const MatrixN3* m : {&s.x, &s.v}) bytes.append(reinterpret_cast<const char*>(m->data()), block);
  const auto crc = static_cast<std::uint32_t>(
      crc32(0L, reinterpret_cast<const Bytef*>(bytes.data()), static_cast<uInt>(bytes.size())));
  bytes.append(reinterpret_cast<const char*>(&crc), sizeof crc);
  return bytes;
}

// Reads a state file saved from `scene` (n particles). Only a regular file
// of exactly StateBytes(n) bytes is opened and read (a FIFO, a folder or a
// device is refused before it is opened). @return the state, or nullopt
// with *why naming the broken rule.
std::optional<State> ReadState(const std::string& path, const Scene& scene, Eigen::Index n, std::string* why) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec) {
    *why = "cannot be used: " + ec.message();
    return std::nullopt;
  }
  if (!std::filesystem::is_regular_file(status)) {
    *why = "is not a regular file";
    return std::nullopt;
  }
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  const std::size_t expected = StateBytes(n);
  if (ec || size != expected) {
    *why = ec ? "cannot be used: " + ec.message()
              : fmt::format("has {} bytes, a state of this scene's {} particles has {} (another scene, truncated or "
                            "damaged)",
                            size, n, expected);
    return std::nullopt;
  }
  std::ifstream in(path, std::ios::binary);
  std::string bytes(expected, '\0');
  if (!in || !in.read(bytes.data(), static_cast<std::streamsize>(expected))) {
    *why = "cannot be read";
    return std::nullopt;
  }
  if (std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0) {
    *why = "is not a contact_replay state file of this version (no CBSTATE2 header; save it again)";
    return std::nullopt;
  }
  std::uint32_t stored = 0;
  std::memcpy(&stored, bytes.data() + bytes.size() - sizeof stored, sizeof stored);
  const auto crc = static_cast<std::uint32_t>(crc32(0L, reinterpret_cast<const Bytef*>(bytes.data()),
                                                    static_cast<uInt>(bytes.size() - sizeof stored)));
  if (crc != stored) {
    *why = "fails its CRC-32 check (damaged or truncated)";
    return std::nullopt;
  }
  std::uint64_t key = 0;
  std::int64_t count = 0;
  std::memcpy(&key, bytes.data() + sizeof kMagic, sizeof key);
  std::memcpy(&count, bytes.data() + sizeof kMagic + sizeof key, sizeof count);
  if (count != n) {
    *why = fmt::format("holds {} particles, the scene has {}", count, n);
    return std::nullopt;
  }
  if (key != SceneKey(scene)) {
    *why = fmt::format("was saved from another scene (scene hash {:016x}, --scene's {:016x})", key, SceneKey(scene));
    return std::nullopt;
  }
  State s;
  std::memcpy(&s.t, bytes.data() + kHead - sizeof s.t, sizeof s.t);
  s.x.resize(n, 3);
  s.v.resize(n, 3);
  const std::size_t block = static_cast<std::size_t>(3 * n) * sizeof(double);
  std::memcpy(s.x.data(), bytes.data() + kHead, block);
  std::memcpy(s.v.data(), bytes.data() + kHead + block, block);
  if (!std::isfinite(s.t) || !s.x.allFinite() || !s.v.allFinite()) {
    *why = "holds a value that is not finite";
    return std::nullopt;
  }
  NoteInputFile(path);  // an output of this command must not replace it
  if (!(s.t >= 0.0 && s.t <= scene.t_end)) {
    *why = fmt::format("is at t = {} s, outside the scene's [0, t_end = {}] s", s.t, scene.t_end);
    return std::nullopt;
  }
  return s;
}

}  // namespace clothbench
