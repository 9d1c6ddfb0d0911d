// HDF5 reader (C API) and the RunTable attribute layout shared with the
// writer.
#include "results/result_reader.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <memory>
#include <sstream>

#include <type_traits>
#include <variant>

#include <fmt/format.h>
#include <hdf5.h>

#include "model/output_file.h"
#include "results/hdf5_util.h"

namespace clothbench {
namespace {

using internal::Handle;

std::optional<AttributeValue> ReadAttribute(hid_t attr) {
  Handle type{H5Aget_type(attr), H5Tclose};
  Handle space{H5Aget_space(attr), H5Sclose};
  if (H5Sget_simple_extent_npoints(space.id) != 1) return std::nullopt;
  switch (H5Tget_class(type.id)) {
    case H5T_STRING: {
      if (H5Tis_variable_str(type.id) > 0) {
        Handle mem{H5Tcopy(H5T_C_S1), H5Tclose};
        H5Tset_size(mem.id, H5T_VARIABLE);
        H5Tset_cset(mem.id, H5Tget_cset(type.id));
        char* s = nullptr;
        if (H5Aread(attr, mem.id, &s) < 0 || s == nullptr) return std::nullopt;
        std::string out(s);
        H5free_memory(s);
        return out;
      }
      // An attribute is stored whole in its object header or dense storage:
      // a declared size beyond the stored one is a damaged file.
      if (H5Tget_size(type.id) > H5Aget_storage_size(attr) + 64) return std::nullopt;
      std::string buf(H5Tget_size(type.id), '\0');
      if (H5Aread(attr, type.id, buf.data()) < 0) return std::nullopt;
      buf.resize(std::min(buf.size(), buf.find('\0')));
      return buf;
    }
    case H5T_INTEGER: {
      int64_t v = 0;
      if (H5Aread(attr, H5T_NATIVE_INT64, &v) < 0) return std::nullopt;
      return static_cast<long>(v);
    }
    case H5T_FLOAT: {
      double v = 0.0;
      if (H5Aread(attr, H5T_NATIVE_DOUBLE, &v) < 0) return std::nullopt;
      return v;
    }
    default:
      return std::nullopt;
  }
}

herr_t CollectName(hid_t, const char* name, const H5L_info_t*, void* data) {
  static_cast<std::vector<std::string>*>(data)->emplace_back(name);
  return 0;
}

herr_t CollectAttribute(hid_t loc, const char* name, const H5A_info_t*, void* data) {
  auto* out = static_cast<std::vector<std::pair<std::string, AttributeValue>>*>(data);
  Handle attr{H5Aopen(loc, name, H5P_DEFAULT), H5Aclose};
  if (attr.id < 0) return 0;
  if (auto v = ReadAttribute(attr.id)) out->emplace_back(name, *v);
  return 0;
}

// Refuses what a result file never holds and a reader must not follow: a
// link that is not a hard link (an external link opens another file; a
// soft link may loop), and a dataset whose data live outside the file (a
// virtual dataset's sources, external storage): opening those would read,
// or block on, a file the user did not name (a FIFO). H5Lvisit follows
// hard links only; a dataset's layout is read from its creation property
// list without touching its sources.
struct ForeignReference {
  std::string what;  // "" while none is found
};

herr_t CheckLink(hid_t group, const char* name, const H5L_info_t* info, void* data) {
  auto* found = static_cast<ForeignReference*>(data);
  if (info->type != H5L_TYPE_HARD) {
    found->what = fmt::format("\"{}\" is a {} link (a result file holds hard links only; another file is not "
                              "followed)",
                              name, info->type == H5L_TYPE_SOFT ? "soft" : "external");
    return 1;
  }
  H5O_info_t object{};
  if (H5Oget_info_by_name2(group, name, &object, H5O_INFO_BASIC, H5P_DEFAULT) < 0 || object.type != H5O_TYPE_DATASET)
    return 0;
  Handle ds{H5Dopen2(group, name, H5P_DEFAULT), H5Dclose};
  if (ds.id < 0) return 0;
  Handle dcpl{H5Dget_create_plist(ds.id), H5Pclose};
  if (dcpl.id < 0) return 0;
  if (H5Pget_layout(dcpl.id) == H5D_VIRTUAL) {
    // The frame views (docs/guide/results-schema.md) map datasets of this file
    // (source file "."); a source in another file is refused.
    size_t mappings = 0;
    if (H5Pget_virtual_count(dcpl.id, &mappings) < 0)
      found->what = fmt::format("dataset \"{}\" is a virtual dataset whose sources cannot be listed", name);
    for (size_t k = 0; k < mappings && found->what.empty(); ++k) {
      char file[8] = {};
      const ssize_t len = H5Pget_virtual_filename(dcpl.id, k, file, sizeof file);
      if (len != 1 || std::string(file) != ".")
        found->what = fmt::format("dataset \"{}\" is a virtual dataset with a source in another file (which is not "
                                  "read)", name);
    }
  } else if (H5Pget_external_count(dcpl.id) > 0)
    found->what = fmt::format("dataset \"{}\" keeps its data in external files, which are not read", name);
  return found->what.empty() ? 0 : 1;
}

}  // namespace

ResultReader::ResultReader(const std::string& path) : path_(path) {
  internal::NoAtExit();
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  // The integrity block first: HDF5 parses no byte that was not written by
  // a ResultFile. Non-blocking, so that a FIFO or device is refused, not
  // waited on.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) throw ResultError(fmt::format("{}: cannot open: {}", path, std::strerror(errno)));
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    throw ResultError(fmt::format("{}: not a regular file", path));
  }
  const std::unique_ptr<std::FILE, int (*)(std::FILE*)> in(::fdopen(fd, "rb"), std::fclose);
  if (!in) {
    ::close(fd);
    throw ResultError(fmt::format("{}: cannot open: {}", path, std::strerror(errno)));
  }
  CheckResultSignature(path, in.get());
  if (H5Fis_hdf5(path.c_str()) <= 0)
    throw ResultError(fmt::format("{}: cannot open: not an HDF5 file or not readable", path));
  file_ = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (file_ < 0) throw ResultError(fmt::format("{}: cannot open the HDF5 file", path));
  NoteInputFile(path);  // an output of this command must not replace it
  CheckSchema();
}

ResultReader::ResultReader(const std::string& name, const void* image, std::size_t size) : path_(name) {
  internal::NoAtExit();
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  CheckResultSignature(name, static_cast<const unsigned char*>(image), size);
  Handle fapl{H5Pcreate(H5P_FILE_ACCESS), H5Pclose};
  // The core (in-memory) driver on a copy of the image; nothing is written back.
  if (size == 0 || H5Pset_fapl_core(fapl.id, 1 << 16, 0) < 0 || H5Pset_file_image(fapl.id, const_cast<void*>(image), size) < 0)
    throw ResultError(fmt::format("{}: cannot open: not an HDF5 file image", name));
  file_ = H5Fopen(name.c_str(), H5F_ACC_RDONLY, fapl.id);
  if (file_ < 0) throw ResultError(fmt::format("{}: cannot open the HDF5 file image", name));
  CheckSchema();
}

void ResultReader::CheckSchema() {
  ForeignReference found;
  if (H5Lvisit(file_, H5_INDEX_NAME, H5_ITER_INC, CheckLink, &found) < 0 && found.what.empty())
    found.what = "its links cannot be listed (a damaged file)";
  if (!found.what.empty()) {
    H5Fclose(file_);
    file_ = -1;
    throw ResultError(fmt::format("{}: {}", path_, found.what));
  }
  const std::optional<std::string> schema = String("/", "schema");
  if (!schema) {
    H5Fclose(file_);
    file_ = -1;
    throw ResultError(fmt::format("{}: not a clothbench result file (no root attribute \"schema\")", path_));
  }
  if (*schema != kResultSchema) {
    H5Fclose(file_);
    file_ = -1;
    throw ResultError(fmt::format("{}: schema {} is not {}, the schema this build reads; rerun the command that "
                                  "wrote it (root attribute \"created\" and \"git_commit\" name when and how)",
                                  path_, *schema, kResultSchema));
  }
}

ResultReader::~ResultReader() {
  if (file_ >= 0) H5Fclose(file_);
}

bool ResultReader::Exists(const std::string& object) const {
  if (object == "/") return true;
  std::string prefix;
  std::size_t pos = 0;
  while (pos != std::string::npos) {
    pos = object.find('/', pos + 1);
    prefix = object.substr(0, pos);
    if (H5Lexists(file_, prefix.c_str(), H5P_DEFAULT) <= 0) return false;
  }
  return true;
}

std::vector<std::string> ResultReader::Children(const std::string& group) const {
  std::vector<std::string> names;
  if (!Exists(group)) return names;
  Handle g{H5Gopen2(file_, group.c_str(), H5P_DEFAULT), H5Gclose};
  if (g.id < 0) return names;
  hsize_t idx = 0;
  // Creation order where tracked, else by name.
  if (H5Literate(g.id, H5_INDEX_CRT_ORDER, H5_ITER_INC, &idx, CollectName, &names) < 0) {
    names.clear();
    idx = 0;
    H5Literate(g.id, H5_INDEX_NAME, H5_ITER_INC, &idx, CollectName, &names);
  }
  return names;
}

std::vector<std::pair<std::string, AttributeValue>> ResultReader::Attributes(const std::string& object) const {
  std::vector<std::pair<std::string, AttributeValue>> out;
  if (!Exists(object)) return out;
  Handle obj{H5Oopen(file_, object.c_str(), H5P_DEFAULT), H5Oclose};
  if (obj.id < 0) return out;
  hsize_t idx = 0;
  if (H5Aiterate2(obj.id, H5_INDEX_CRT_ORDER, H5_ITER_INC, &idx, CollectAttribute, &out) < 0) {
    out.clear();
    idx = 0;
    H5Aiterate2(obj.id, H5_INDEX_NAME, H5_ITER_INC, &idx, CollectAttribute, &out);
  }
  return out;
}

namespace {

std::optional<AttributeValue> Attribute(hid_t file, const std::string& object, const std::string& name) {
  if (H5Aexists_by_name(file, object.c_str(), name.c_str(), H5P_DEFAULT) <= 0) return std::nullopt;
  Handle attr{H5Aopen_by_name(file, object.c_str(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose};
  if (attr.id < 0) return std::nullopt;
  return ReadAttribute(attr.id);
}

}  // namespace

std::optional<std::string> ResultReader::String(const std::string& object, const std::string& name) const {
  if (!Exists(object)) return std::nullopt;
  const auto v = Attribute(file_, object, name);
  if (!v || !std::holds_alternative<std::string>(*v)) return std::nullopt;
  return std::get<std::string>(*v);
}

std::optional<double> ResultReader::Double(const std::string& object, const std::string& name) const {
  if (!Exists(object)) return std::nullopt;
  const auto v = Attribute(file_, object, name);
  if (!v) return std::nullopt;
  if (const double* d = std::get_if<double>(&*v)) return *d;
  if (const long* l = std::get_if<long>(&*v)) return static_cast<double>(*l);
  return std::nullopt;
}

std::optional<long> ResultReader::Long(const std::string& object, const std::string& name) const {
  if (!Exists(object)) return std::nullopt;
  const auto v = Attribute(file_, object, name);
  if (!v) return std::nullopt;
  if (const long* l = std::get_if<long>(&*v)) return *l;
  return std::nullopt;
}

std::vector<std::size_t> ResultReader::Shape(const std::string& dataset) const {
  if (!Exists(dataset)) throw ResultError(fmt::format("{}: no dataset {}", path_, dataset));
  Handle ds{H5Dopen2(file_, dataset.c_str(), H5P_DEFAULT), H5Dclose};
  if (ds.id < 0) throw ResultError(fmt::format("{}: {} is not a dataset", path_, dataset));
  Handle space{H5Dget_space(ds.id), H5Sclose};
  const int rank = H5Sget_simple_extent_ndims(space.id);
  std::vector<hsize_t> dims(static_cast<std::size_t>(std::max(rank, 0)));
  H5Sget_simple_extent_dims(space.id, dims.data(), nullptr);
  return {dims.begin(), dims.end()};
}

namespace {

// The number of values of `shape`, refused (ResultError naming the dataset)
// if it overflows or exceeds what the dataset stores: deflate expands at most
// ~1032× (zlib's limit), so a dataset declaring more than 1100× its stored
// bytes (plus 1 MiB for small or fill-valued ones) is damaged, and reading it
// would only allocate memory the file cannot fill.
std::size_t CheckedCount(hid_t ds, const std::string& path, const std::string& dataset,
                         const std::vector<std::size_t>& shape, std::size_t value_size) {
  constexpr std::size_t kMaxBytes = std::size_t{1} << 40;
  std::size_t n = 1;
  for (std::size_t d : shape) {
    if (d != 0 && n > kMaxBytes / value_size / d)
      throw ResultError(fmt::format("{}: {}: extent beyond {} bytes (damaged file)", path, dataset, kMaxBytes));
    n *= d;
  }
  const hsize_t stored = H5Dget_storage_size(ds);
  if (n > 0 && n * value_size > 1100 * static_cast<std::size_t>(stored) + (std::size_t{1} << 20))
    throw ResultError(fmt::format("{}: {}: declares {} values but stores {} bytes (damaged file)", path, dataset, n,
                                  stored));
  return n;
}

template <typename T>
std::vector<T> ReadAll(hid_t file, const std::string& path, const std::string& dataset, hid_t mem_type,
                       const std::vector<std::size_t>& shape) {
  Handle ds{H5Dopen2(file, dataset.c_str(), H5P_DEFAULT), H5Dclose};
  if (ds.id < 0) throw ResultError(fmt::format("{}: {} is not a dataset", path, dataset));
  std::vector<T> out(CheckedCount(ds.id, path, dataset, shape, sizeof(T)));
  const std::size_t n = out.size();
  if (n > 0 && H5Dread(ds.id, mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()) < 0)
    throw ResultError(fmt::format("{}: cannot read {}", path, dataset));
  return out;
}

}  // namespace

std::vector<double> ResultReader::Doubles(const std::string& dataset) const {
  return ReadAll<double>(file_, path_, dataset, H5T_NATIVE_DOUBLE, Shape(dataset));
}

std::vector<int32_t> ResultReader::Ints(const std::string& dataset) const {
  return ReadAll<int32_t>(file_, path_, dataset, H5T_NATIVE_INT32, Shape(dataset));
}

std::string ResultReader::Text(const std::string& dataset) const {
  if (!Exists(dataset)) throw ResultError(fmt::format("{}: no dataset {}", path_, dataset));
  Handle ds{H5Dopen2(file_, dataset.c_str(), H5P_DEFAULT), H5Dclose};
  Handle type{H5Dget_type(ds.id), H5Tclose};
  Handle space{H5Dget_space(ds.id), H5Sclose};
  if (ds.id < 0 || H5Tget_class(type.id) != H5T_STRING || H5Tis_variable_str(type.id) > 0 ||
      H5Sget_simple_extent_type(space.id) != H5S_SCALAR)
    throw ResultError(fmt::format("{}: {} is not a fixed-length string", path_, dataset));
  std::string text(CheckedCount(ds.id, path_, dataset, {H5Tget_size(type.id)}, 1), '\0');
  if (H5Dread(ds.id, type.id, H5S_ALL, H5S_ALL, H5P_DEFAULT, text.data()) < 0)
    throw ResultError(fmt::format("{}: cannot read {}", path_, dataset));
  text.erase(std::find_if(text.rbegin(), text.rend(), [](char c) { return c != '\0'; }).base(), text.end());
  return text;
}

std::vector<std::string> ResultReader::Strings(const std::string& dataset) const {
  if (!Exists(dataset)) throw ResultError(fmt::format("{}: no dataset {}", path_, dataset));
  const std::vector<std::size_t> shape = Shape(dataset);
  Handle ds{H5Dopen2(file_, dataset.c_str(), H5P_DEFAULT), H5Dclose};
  Handle type{H5Dget_type(ds.id), H5Tclose};
  if (ds.id < 0 || H5Tget_class(type.id) != H5T_STRING || H5Tis_variable_str(type.id) > 0)
    throw ResultError(fmt::format("{}: {} is not a table of fixed-length strings", path_, dataset));
  const std::size_t width = H5Tget_size(type.id);
  if (width == 0) throw ResultError(fmt::format("{}: {} has strings of width 0", path_, dataset));
  std::vector<std::size_t> bytes = shape;
  bytes.push_back(width);
  std::string buf(CheckedCount(ds.id, path_, dataset, bytes, 1), '\0');
  if (!buf.empty() && H5Dread(ds.id, type.id, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data()) < 0)
    throw ResultError(fmt::format("{}: cannot read {}", path_, dataset));
  std::vector<std::string> out;
  for (std::size_t k = 0; k + width <= buf.size(); k += width) {
    std::string v = buf.substr(k, width);
    v.erase(std::find(v.begin(), v.end(), '\0'), v.end());
    out.push_back(std::move(v));
  }
  return out;
}

MatrixN3 ResultReader::Frame(const std::string& dataset, std::size_t k) const {
  const std::vector<std::size_t> shape = Shape(dataset);
  if (shape.size() != 3 || shape[2] != 3) throw ResultError(fmt::format("{}: {} is not [F, N, 3]", path_, dataset));
  if (k >= shape[0])
    throw ResultError(fmt::format("{}: {} has {} frames (0 … {}); no frame {}", path_, dataset, shape[0],
                                  shape[0] - 1, k));
  Handle ds{H5Dopen2(file_, dataset.c_str(), H5P_DEFAULT), H5Dclose};
  CheckedCount(ds.id, path_, dataset, shape, sizeof(double));
  Handle space{H5Dget_space(ds.id), H5Sclose};
  const hsize_t start[3] = {k, 0, 0}, count[3] = {1, shape[1], 3};
  H5Sselect_hyperslab(space.id, H5S_SELECT_SET, start, nullptr, count, nullptr);
  Handle mem{H5Screate_simple(3, count, nullptr), H5Sclose};
  std::vector<double> buf(shape[1] * 3);
  if (H5Dread(ds.id, H5T_NATIVE_DOUBLE, mem.id, space.id, H5P_DEFAULT, buf.data()) < 0)
    throw ResultError(fmt::format("{}: cannot read frame {} of {}", path_, k, dataset));
  MatrixN3 x(static_cast<Eigen::Index>(shape[1]), 3);
  for (std::size_t p = 0; p < shape[1]; ++p)
    for (std::size_t c = 0; c < 3; ++c) {
      const double v = buf[p * 3 + c];
      if (!std::isfinite(v))
        throw ResultError(fmt::format("{}: {}: frame {} holds a non-finite value at [{}, {}] (damaged file)", path_,
                                      dataset, k, p, c));
      x(static_cast<Eigen::Index>(p), static_cast<Eigen::Index>(c)) = v;
    }
  return x;
}

std::vector<StepRecord> ResultReader::StepStats(const std::string& dataset) const {
  const std::vector<std::size_t> shape = Shape(dataset);
  Handle mem{internal::StepRecordType(), H5Tclose};
  return ReadAll<StepRecord>(file_, path_, dataset, mem.id, shape);
}

}  // namespace clothbench
