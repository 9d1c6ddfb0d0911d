// HDF5 writer (C API).
#include "results/result_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <memory>
#include <thread>

#include <fmt/format.h>
#include <hdf5.h>

#include "git_commit.h"  // generated at build time
#include "model/interrupt.h"
#include "model/output_file.h"
#include "results/hdf5_util.h"
#include "results/run_table.h"

namespace clothbench {

const std::vector<StepRecordField>& StepRecordFields() {
  static const std::vector<StepRecordField> fields = {
      {"t", offsetof(StepRecord, t), true},
      {"h", offsetof(StepRecord, h), true},
      {"updates", offsetof(StepRecord, updates), false},
      {"cg_iterations", offsetof(StepRecord, cg_iterations), false},
      {"status", offsetof(StepRecord, status), false},
      {"colliding", offsetof(StepRecord, colliding), false},
      {"solve_time_s", offsetof(StepRecord, solve_time_s), true},
      {"setup_time_s", offsetof(StepRecord, setup_time_s), true},
      {"preconditioner", offsetof(StepRecord, preconditioner), false},
  };
  return fields;
}
namespace {

using internal::Handle;

// zlib level of the frame datasets: 4 compresses these doubles within a few
// per cent of level 9 at a fraction of its time.
constexpr unsigned kDeflateLevel = 4;

// The system's reason where a write failed for lack of room or rights
// (HDF5's error stack says only "write failed").
std::string SystemReason() {
  const int e = errno;
  return e == ENOSPC || e == EFBIG || e == EDQUOT || e == EIO || e == EACCES || e == EROFS
             ? fmt::format(": {}", std::strerror(e))
             : "";
}

hid_t Check(hid_t id, const std::string& what, const std::string& file) {
  if (id < 0) throw ResultError(fmt::format("{}: HDF5 error: {}{}", file, what, SystemReason()));
  return id;
}

// The last line of the rule "never store a non-finite number": the runs end
// at a blow-up (solver/run.h, BlowUpGuard) and derived attributes that would
// be non-finite are left out, so a non-finite dataset value is a bug; the
// file is not written (the .tmp is removed by unwinding).
void RequireFinite(const double* values, std::size_t n, const std::string& dataset, const std::string& file) {
  for (std::size_t k = 0; k < n; ++k)
    if (!std::isfinite(values[k]))
      throw ResultError(fmt::format("{}: {}[{}] = {} is not finite; no file is written", file, dataset, k, values[k]));
}

}  // namespace

ResultFile::ResultFile(const std::string& path) : path_(path), tmp_path_(path + ".tmp") {
  internal::NoAtExit();
  errno = 0;
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);  // errors become ResultError, not stderr dumps
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  std::error_code ec;
  if (!parent.empty()) std::filesystem::create_directories(parent, ec);
  Handle fcpl{H5Pcreate(H5P_FILE_CREATE), H5Pclose};
  H5Pset_userblock(fcpl.id, kSignatureBytes);  // the integrity block, written by Commit
  try {
    // The project's output rules (model/output_file.h): a regular leftover
    // temporary is removed, anything else there refused, and the file is
    // created exclusively (O_CREAT|O_EXCL: a link planted at the name makes
    // it fail, never followed).
    FreeTemporaryName(path_, "result file");
    file_ = Check(H5Fcreate(tmp_path_.c_str(), H5F_ACC_EXCL, fcpl.id, H5P_DEFAULT), "cannot create file", tmp_path_);
  } catch (const OutputRefused& e) {
    throw ResultError(e.what());
  } catch (...) {
    // No destructor runs for a constructor that throws: the temporary HDF5
    // may have created (empty, on a full disk) is removed here.
    std::remove(tmp_path_.c_str());
    throw;
  }
}

ResultFile::~ResultFile() {
  if (file_ >= 0) H5Fclose(file_);
  if (!committed_) std::remove(tmp_path_.c_str());
}

void ResultFile::CreateGroup(const std::string& path) {
  Handle lcpl{H5Pcreate(H5P_LINK_CREATE), H5Pclose};
  H5Pset_create_intermediate_group(lcpl.id, 1);
  // Links keep their creation order, so readers list runs in run order.
  Handle gcpl{H5Pcreate(H5P_GROUP_CREATE), H5Pclose};
  H5Pset_link_creation_order(gcpl.id, H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED);
  Handle g{Check(H5Gcreate2(file_, path.c_str(), lcpl.id, gcpl.id, H5P_DEFAULT), "cannot create group " + path, path_),
           H5Gclose};
}

void ResultFile::SetAttribute(const std::string& object, const std::string& name, const std::string& value) {
  Handle type{H5Tcopy(H5T_C_S1), H5Tclose};
  H5Tset_size(type.id, value.empty() ? 1 : value.size());
  H5Tset_strpad(type.id, H5T_STR_NULLPAD);
  H5Tset_cset(type.id, H5T_CSET_UTF8);
  Handle space{H5Screate(H5S_SCALAR), H5Sclose};
  Handle attr{Check(H5Acreate_by_name(file_, object.c_str(), name.c_str(), type.id, space.id, H5P_DEFAULT, H5P_DEFAULT,
                                      H5P_DEFAULT),
                    "cannot create attribute " + object + "@" + name, path_),
              H5Aclose};
  const std::string buf = value.empty() ? std::string(1, '\0') : value;
  Check(H5Awrite(attr.id, type.id, buf.data()), "cannot write attribute " + name, path_);
}

namespace {

// Writes one scalar attribute of file type `ftype` from memory type `mtype`.
void WriteScalarAttribute(hid_t file, const std::string& path, const std::string& object, const std::string& name,
                          hid_t ftype, hid_t mtype, const void* value) {
  Handle space{H5Screate(H5S_SCALAR), H5Sclose};
  Handle attr{Check(H5Acreate_by_name(file, object.c_str(), name.c_str(), ftype, space.id, H5P_DEFAULT, H5P_DEFAULT,
                                      H5P_DEFAULT),
                    "cannot create attribute " + object + "@" + name, path),
              H5Aclose};
  Check(H5Awrite(attr.id, mtype, value), "cannot write attribute " + name, path);
}

}  // namespace

void ResultFile::SetAttribute(const std::string& object, const std::string& name, double value) {
  if (!std::isfinite(value)) return;  // a non-finite attribute is left out (docs/guide/results-schema.md)
  WriteScalarAttribute(file_, path_, object, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &value);
}

void ResultFile::SetAttribute(const std::string& object, const std::string& name, long value) {
  const int64_t v = value;
  WriteScalarAttribute(file_, path_, object, name, H5T_STD_I64LE, H5T_NATIVE_INT64, &v);
}

namespace {

void WriteRaw(hid_t file, const std::string& file_path, const std::string& path, int rank, const hsize_t* dims,
              hid_t ftype, hid_t mtype, const void* data, bool empty) {
  Handle space{H5Screate_simple(rank, dims, nullptr), H5Sclose};
  Handle ds{Check(H5Dcreate2(file, path.c_str(), ftype, space.id, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                  "cannot create dataset " + path, file_path),
            H5Dclose};
  if (!empty) Check(H5Dwrite(ds.id, mtype, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), "cannot write " + path, file_path);
}

}  // namespace

void ResultFile::WriteString(const std::string& path, const std::string& value) {
  Handle type{H5Tcopy(H5T_C_S1), H5Tclose};
  H5Tset_size(type.id, value.empty() ? 1 : value.size());
  H5Tset_strpad(type.id, H5T_STR_NULLPAD);
  H5Tset_cset(type.id, H5T_CSET_UTF8);
  Handle space{H5Screate(H5S_SCALAR), H5Sclose};
  Handle ds{Check(H5Dcreate2(file_, path.c_str(), type.id, space.id, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                  "cannot create dataset " + path, path_),
            H5Dclose};
  const std::string buf = value.empty() ? std::string(1, '\0') : value;
  Check(H5Dwrite(ds.id, type.id, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data()), "cannot write " + path, path_);
}

void ResultFile::WriteVector(const std::string& path, const std::vector<double>& values, const std::string& units) {
  RequireFinite(values.data(), values.size(), path, path_);
  const hsize_t dims[1] = {values.size()};
  WriteRaw(file_, path_, path, 1, dims, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, values.data(), values.empty());
  if (!units.empty()) SetAttribute(path, "units", units);
}

void ResultFile::WriteTable(const std::string& path, int rows, int cols, const std::vector<double>& values,
                            const std::string& units) {
  RequireFinite(values.data(), values.size(), path, path_);
  const hsize_t dims[2] = {static_cast<hsize_t>(rows), static_cast<hsize_t>(cols)};
  WriteRaw(file_, path_, path, 2, dims, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, values.data(), values.empty());
  if (!units.empty()) SetAttribute(path, "units", units);
}

void ResultFile::WriteTable(const std::string& path, int rows, int cols, const std::vector<int32_t>& values) {
  const hsize_t dims[2] = {static_cast<hsize_t>(rows), static_cast<hsize_t>(cols)};
  WriteRaw(file_, path_, path, 2, dims, H5T_STD_I32LE, H5T_NATIVE_INT32, values.data(), values.empty());
}

void ResultFile::WriteArray3(const std::string& path, const std::array<std::size_t, 3>& dims,
                             const std::vector<double>& values, const std::string& units) {
  RequireFinite(values.data(), values.size(), path, path_);
  const hsize_t d[3] = {dims[0], dims[1], dims[2]};
  WriteRaw(file_, path_, path, 3, d, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, values.data(), values.empty());
  if (!units.empty()) SetAttribute(path, "units", units);
}

void ResultFile::WriteArray3(const std::string& path, const std::array<std::size_t, 3>& dims,
                             const std::vector<int32_t>& values) {
  const hsize_t d[3] = {dims[0], dims[1], dims[2]};
  WriteRaw(file_, path_, path, 3, d, H5T_STD_I32LE, H5T_NATIVE_INT32, values.data(), values.empty());
}

void ResultFile::WriteStrings(const std::string& path, int rows, int cols, const std::vector<std::string>& values) {
  std::size_t width = 1;
  for (const std::string& v : values) width = std::max(width, v.size());
  Handle type{H5Tcopy(H5T_C_S1), H5Tclose};
  H5Tset_size(type.id, width);
  H5Tset_strpad(type.id, H5T_STR_NULLPAD);
  H5Tset_cset(type.id, H5T_CSET_UTF8);
  std::string buf(values.size() * width, '\0');
  for (std::size_t k = 0; k < values.size(); ++k) values[k].copy(buf.data() + k * width, values[k].size());
  const hsize_t dims[2] = {static_cast<hsize_t>(rows), static_cast<hsize_t>(cols)};
  WriteRaw(file_, path_, path, 2, dims, type.id, type.id, buf.data(), values.empty());
}

void ResultFile::WriteVectors3(const std::string& path, const std::vector<Vector3>& rows, const std::string& units) {
  std::vector<double> buf;
  buf.reserve(rows.size() * 3);
  for (const Vector3& r : rows) buf.insert(buf.end(), {r.x(), r.y(), r.z()});
  RequireFinite(buf.data(), buf.size(), path, path_);
  const hsize_t dims[2] = {rows.size(), 3};
  WriteRaw(file_, path_, path, 2, dims, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, buf.data(), buf.empty());
  SetAttribute(path, "units", units);
}

void ResultFile::WriteFrames(const std::string& path, const std::vector<MatrixN3>& frames, const std::string& units) {
  const hsize_t f = frames.size(), n = frames.empty() ? 0 : static_cast<hsize_t>(frames[0].rows());
  const hsize_t dims[3] = {f, n, 3};
  Handle space{H5Screate_simple(3, dims, nullptr), H5Sclose};
  // One frame per chunk, byte shuffle + deflate (filters every HDF5 build
  // has; skipped if this one lacks them): a reader gets any frame without
  // decompressing the others.
  Handle dcpl{H5Pcreate(H5P_DATASET_CREATE), H5Pclose};
  if (f > 0 && n > 0) {
    const hsize_t chunk[3] = {1, n, 3};
    H5Pset_chunk(dcpl.id, 3, chunk);
    if (H5Zfilter_avail(H5Z_FILTER_SHUFFLE) > 0) H5Pset_shuffle(dcpl.id);
    if (H5Zfilter_avail(H5Z_FILTER_DEFLATE) > 0) H5Pset_deflate(dcpl.id, kDeflateLevel);
  }
  Handle ds{Check(H5Dcreate2(file_, path.c_str(), H5T_IEEE_F64LE, space.id, H5P_DEFAULT, dcpl.id, H5P_DEFAULT),
                  "cannot create dataset " + path, path_),
            H5Dclose};
  // Frame by frame from the N×3 column-major matrices into [N, 3] row order.
  std::vector<double> buf(n * 3);
  const hsize_t count[3] = {1, n, 3};
  Handle mem{H5Screate_simple(3, count, nullptr), H5Sclose};
  for (hsize_t k = 0; k < f && n > 0; ++k) {
    ThrowIfInterrupted();  // unwinding removes the .tmp
    for (hsize_t p = 0; p < n; ++p)
      for (hsize_t c = 0; c < 3; ++c)
        buf[p * 3 + c] = frames[k](static_cast<Eigen::Index>(p), static_cast<Eigen::Index>(c));
    RequireFinite(buf.data(), buf.size(), fmt::format("{}[{}]", path, k), path_);
    const hsize_t start[3] = {k, 0, 0};
    H5Sselect_hyperslab(space.id, H5S_SELECT_SET, start, nullptr, count, nullptr);
    Check(H5Dwrite(ds.id, H5T_NATIVE_DOUBLE, mem.id, space.id, H5P_DEFAULT, buf.data()), "cannot write " + path, path_);
  }
  SetAttribute(path, "units", units);
}

void ResultFile::WriteFrameViews(const std::string& frames_path, const std::string& view_prefix) {
  Handle src{Check(H5Dopen2(file_, frames_path.c_str(), H5P_DEFAULT), "cannot open " + frames_path, path_), H5Dclose};
  Handle src_space{H5Dget_space(src.id), H5Sclose};
  hsize_t dims[3] = {0, 0, 0};
  if (H5Sget_simple_extent_ndims(src_space.id) != 3) throw ResultError(fmt::format("{}: {} is not [F, N, 3]", path_, frames_path));
  H5Sget_simple_extent_dims(src_space.id, dims, nullptr);
  const hsize_t view_dims[2] = {dims[1], dims[2]};
  Handle view_space{H5Screate_simple(2, view_dims, nullptr), H5Sclose};
  const hsize_t count[3] = {1, dims[1], dims[2]};
  for (hsize_t k = 0; k < dims[0]; ++k) {
    const hsize_t start[3] = {k, 0, 0};
    H5Sselect_hyperslab(src_space.id, H5S_SELECT_SET, start, nullptr, count, nullptr);
    Handle dcpl{H5Pcreate(H5P_DATASET_CREATE), H5Pclose};
    // "." : the source dataset is in this file (under its final name too).
    Check(H5Pset_virtual(dcpl.id, view_space.id, ".", frames_path.c_str(), src_space.id),
          "cannot map a view of " + frames_path, path_);
    const std::string view = view_prefix + std::to_string(k);
    Handle lcpl{H5Pcreate(H5P_LINK_CREATE), H5Pclose};
    H5Pset_create_intermediate_group(lcpl.id, 1);
    Handle ds{Check(H5Dcreate2(file_, view.c_str(), H5T_IEEE_F64LE, view_space.id, lcpl.id, dcpl.id, H5P_DEFAULT),
                    "cannot create dataset " + view, path_),
              H5Dclose};
  }
}

void ResultFile::WriteStepStats(const std::string& path, const std::vector<StepRecord>& rows) {
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const double v[4] = {rows[k].t, rows[k].h, rows[k].solve_time_s, rows[k].setup_time_s};
    RequireFinite(v, 4, fmt::format("{}[{}]", path, k), path_);
  }
  Handle mem{internal::StepRecordType(), H5Tclose};
  const hsize_t dims[1] = {rows.size()};
  Handle space{H5Screate_simple(1, dims, nullptr), H5Sclose};
  Handle ds{Check(H5Dcreate2(file_, path.c_str(), mem.id, space.id, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                  "cannot create dataset " + path, path_),
            H5Dclose};
  if (!rows.empty()) Check(H5Dwrite(ds.id, mem.id, H5S_ALL, H5S_ALL, H5P_DEFAULT, rows.data()), "cannot write " + path, path_);
}

void ResultFile::Commit() {
  if (file_ >= 0) {
    const herr_t err = H5Fclose(file_);
    file_ = -1;
    if (err < 0) throw ResultError(fmt::format("{}: HDF5 error: cannot close file{}", tmp_path_, SystemReason()));
  }
  SignResultFile(tmp_path_);
  try {
    CommitTemporary(path_, "result file");  // refuses a target that became a link or a device meanwhile
  } catch (const std::exception& e) {
    throw ResultError(e.what());
  }
  committed_ = true;
}

namespace {

constexpr const char* kSignatureFormat = "clothbench result crc32 {:08x} bytes {}\n";

// The CRC-32 of what is left to read in `f` from its position, and how many
// bytes that was (added to *size).
uLong CrcOfRest(std::FILE* f, std::size_t* size) {
  std::vector<unsigned char> buf(std::size_t{1} << 20);
  uLong crc = crc32_z(0L, Z_NULL, 0);
  for (std::size_t got; (got = std::fread(buf.data(), 1, buf.size(), f)) > 0;) {
    crc = crc32_z(crc, buf.data(), got);
    *size += got;
  }
  return crc;
}

using File = std::unique_ptr<std::FILE, int (*)(std::FILE*)>;

}  // namespace

void SignResultFile(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDWR | O_NOFOLLOW | O_CLOEXEC);
  std::FILE* f = fd >= 0 ? ::fdopen(fd, "r+b") : nullptr;
  if (fd >= 0 && !f) ::close(fd);
  if (!f) throw ResultError(fmt::format("{}: cannot open to write its integrity block", path));
  std::size_t size = kSignatureBytes;
  bool ok = std::fseek(f, static_cast<long>(kSignatureBytes), SEEK_SET) == 0;
  const uLong crc = ok ? CrcOfRest(f, &size) : 0;
  ok = ok && !std::ferror(f);
  std::string block = fmt::format(kSignatureFormat, crc, size);
  block.resize(kSignatureBytes, '\0');
  ok = ok && std::fseek(f, 0, SEEK_SET) == 0 && std::fwrite(block.data(), 1, block.size(), f) == block.size();
  ok = (std::fflush(f) == 0) && ok;
  ok = (std::fclose(f) == 0) && ok;
  if (!ok) throw ResultError(fmt::format("{}: cannot write its integrity block: {}", path, std::strerror(errno)));
}

void CheckResultSignature(const std::string& name, const unsigned char* data, std::size_t size) {
  if (size < kSignatureBytes)
    throw ResultError(fmt::format("{}: {} bytes, shorter than a result file's integrity block (truncated, or not a "
                                  "clothbench result file)", name, size));
  const File image(fmemopen(const_cast<unsigned char*>(data), size, "rb"), std::fclose);
  if (!image) throw ResultError(fmt::format("{}: cannot read the image", name));
  CheckResultSignature(name, image.get());
}

void CheckResultSignature(const std::string& name, std::FILE* f) {
  char head[kSignatureBytes + 1] = {0};
  const std::size_t got_head = std::fread(head, 1, kSignatureBytes, f);
  if (got_head < kSignatureBytes)
    throw ResultError(fmt::format("{}: {} bytes, shorter than a result file's integrity block (truncated, or not a "
                                  "clothbench result file)", name, got_head));
  unsigned long long want_size = 0;
  unsigned want_crc = 0;
  if (std::sscanf(head, "clothbench result crc32 %8x bytes %llu", &want_crc, &want_size) != 2)
    throw ResultError(fmt::format("{}: no integrity block (not a clothbench result file, or written before result "
                                  "files carried one: rerun the command that wrote it)", name));
  std::size_t size = kSignatureBytes;
  const uLong crc = CrcOfRest(f, &size);
  if (std::ferror(f)) throw ResultError(fmt::format("{}: read error: {}", name, std::strerror(errno)));
  if (want_size != size)
    throw ResultError(fmt::format("{}: {} bytes, its integrity block says {} (truncated or appended to)", name, size,
                                  want_size));
  if (crc != want_crc)
    throw ResultError(fmt::format("{}: CRC-32 {:08x} of its content, its integrity block says {:08x} (damaged, or "
                                  "changed after it was written)", name, crc, want_crc));
}

void WriteProvenance(ResultFile& f) {
  f.SetAttribute("/", "schema", std::string(kResultSchema));
  f.SetAttribute("/", "created", NowIso8601Utc());
  f.SetAttribute("/", "git_commit", GitCommit());
  f.SetAttribute("/", "host", HostName());
  f.SetAttribute("/", "compiler", CompilerId());
  f.SetAttribute("/", "build_type", BuildType());
  f.SetAttribute("/", "hardware_threads", static_cast<long>(std::thread::hardware_concurrency()));
}

std::string HostName() {
  char buf[256] = {0};
  if (gethostname(buf, sizeof(buf) - 1) != 0) return "unknown";
  return buf;
}

std::string CompilerId() {
#if defined(__clang__)
  return fmt::format("clang {}", __clang_version__);
#elif defined(__GNUC__)
  return fmt::format("gcc {}", __VERSION__);
#else
  return "unknown";
#endif
}

std::string BuildType() { return CLOTHBENCH_BUILD_TYPE; }
std::string GitCommit() { return CLOTHBENCH_GIT_COMMIT; }

std::string NowIso8601Utc() {
  std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

}  // namespace clothbench
