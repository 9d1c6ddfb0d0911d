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

RunRecord ReadRunRecord(const ResultReader& f, const std::string& g, const std::string& id) {
  RunRecord r;
  r.id = id;
  for (const RecordField& field : RunRecordFields()) {
    const std::string name = field.name;
    std::visit(
        [&](auto member) {
          using T = std::remove_reference_t<decltype(r.*member)>;
          if constexpr (std::is_same_v<T, std::string>) {
            if (auto v = f.String(g, name)) r.*member = *v;
          } else if constexpr (std::is_same_v<T, long>) {
            if (auto v = f.Long(g, name)) r.*member = *v;
          } else if constexpr (std::is_same_v<T, double>) {
            if (auto v = f.Double(g, name)) r.*member = *v;
          } else {
            r.*member = f.Double(g, name);
          }
        },
        field.member);
  }
  // One timing stores no spread (files before solver_time_s_median: the same).
  if (!f.Double(g, "solver_time_s_median")) r.solver_time_s_median = r.solver_time_s;
  if (!f.Double(g, "solver_time_s_max")) r.solver_time_s_max = r.solver_time_s;
  if (!r.error_final_m) r.error_final_m = f.Double(g, "error_rms_m");  // files before error_final_m
  return r;
}

RunTable ReadRunTable(const ResultReader& f) {
  RunTable t;
  const auto str = [&](const std::string& o, const std::string& n) { return f.String(o, n).value_or(""); };
  t.schema = str("/", "schema");
  t.created = str("/", "created");
  t.git_commit = str("/", "git_commit");
  t.host = str("/", "host");
  t.compiler = str("/", "compiler");
  t.build_type = str("/", "build_type");
  t.hardware_threads = f.Long("/", "hardware_threads").value_or(0);
  t.error_metric = f.String("/", "error_metric").value_or("final");
  t.scene_name = str("/scene", "name");
  t.scene_source = str("/scene", "source");
  t.explicit_terms = str("/scene", "explicit_terms");
  t.frames = str("/scene", "frames");
  t.n_particles = f.Long("/scene", "n_particles").value_or(0);
  t.n_fixed = f.Long("/scene", "n_fixed").value_or(0);
  t.t_end = f.Double("/scene", "t_end").value_or(0.0);
  t.frame_dt = f.Double("/scene", "frame_dt").value_or(0.0);
  t.h = f.Double("/scene", "h").value_or(0.0);
  t.numerical_stiffness = f.Double("/scene", "numerical_stiffness").value_or(0.0);
  t.cg_tolerance = f.Double("/scene", "solver_cg_tolerance").value_or(0.0);
  t.cg_reference = str("/scene", "solver_cg_reference");
  t.preconditioner = str("/scene", "solver_preconditioner");
  t.predictor = str("/scene", "solver_predictor");
  t.amg_frames = str("/scene", "solver_amg_frames");
  t.max_updates = f.Long("/scene", "solver_max_updates").value_or(0);
  t.cholesky_ordering = str("/scene", "solver_cholesky_ordering");
  t.contact_factors = str("/scene", "solver_contact_factors");
  t.tangent_projection = str("/scene", "solver_tangent_projection");
  t.newton_jacobian = str("/scene", "solver_newton_jacobian");
  t.controller_updates = str("/scene", "solver_controller_updates");
  t.cg_max_iterations = f.Long("/scene", "solver_cg_max_iterations").value_or(0);
  t.max_rejections = f.Long("/scene", "solver_max_rejections").value_or(0);
  t.fixed_point_tolerance = f.Double("/scene", "solver_fixed_point_tolerance").value_or(0.0);
  t.step_factor = f.Double("/scene", "solver_step_factor").value_or(0.0);
  t.h_min = f.Double("/scene", "solver_h_min").value_or(0.0);
  t.h_max = f.Double("/scene", "solver_h_max").value_or(0.0);
  if (f.Exists("/reference")) t.reference = ReadRunRecord(f, "/reference", "reference");
  for (const std::string& id : f.Children("/runs")) t.runs.push_back(ReadRunRecord(f, "/runs/" + id, id));
  if (f.Exists("/work_precision/targets")) {
    EqualAccuracyTable w;
    w.targets = f.Doubles("/work_precision/targets");
    w.reference = f.String("/work_precision", "baseline").value_or(str("/work_precision", "reference_method"));
    w.metric = f.String("/work_precision", "error_metric").value_or("final");
    std::stringstream labels(str("/work_precision", "labels"));  // comma-separated
    for (std::string label; std::getline(labels, label, ',');) w.labels.push_back(label);
    const std::vector<double> cost = f.Doubles("/work_precision/solver_time");
    const std::vector<double> ratio =
        f.Doubles(f.Exists("/work_precision/ratio") ? "/work_precision/ratio" : "/work_precision/ratio_to_cvode");
    const std::vector<int32_t> bound =
        f.Exists("/work_precision/upper_bound") ? f.Ints("/work_precision/upper_bound") : std::vector<int32_t>{};
    const std::vector<double> min_error =
        f.Exists("/work_precision/min_error") ? f.Doubles("/work_precision/min_error") : std::vector<double>{};
    const std::size_t cols = w.targets.size();
    if (cost.size() != w.labels.size() * cols || ratio.size() != cost.size() ||
        (!bound.empty() && bound.size() != cost.size()) || (!min_error.empty() && min_error.size() != w.labels.size()))
      throw ResultError(fmt::format("{}: /work_precision: {} labels × {} targets but {} cells", f.path(),
                                    w.labels.size(), cols, cost.size()));
    for (std::size_t m = 0; m < w.labels.size(); ++m) {
      w.cost.emplace_back();
      w.ratio.emplace_back();
      w.upper_bound.emplace_back();
      for (std::size_t j = 0; j < cols; ++j) {
        const double c = cost[m * cols + j], q = ratio[m * cols + j];
        w.cost.back().push_back(c >= 0.0 ? std::optional(c) : std::nullopt);
        w.ratio.back().push_back(q >= 0.0 ? std::optional(q) : std::nullopt);
        w.upper_bound.back().push_back(!bound.empty() && bound[m * cols + j] != 0);
      }
      w.min_error.push_back(!min_error.empty() && min_error[m] > 0.0 ? std::optional(min_error[m]) : std::nullopt);
    }
    for (int32_t k : f.Ints("/work_precision/fastest")) {
      if (k < -1 || k >= static_cast<int32_t>(w.labels.size()))
        throw ResultError(fmt::format("{}: /work_precision/fastest: {} is not a label index (-1 … {})", f.path(), k,
                                      static_cast<long>(w.labels.size()) - 1));
      w.fastest.push_back(k);
    }
    if (w.fastest.size() != cols)
      throw ResultError(fmt::format("{}: /work_precision/fastest: {} entries, {} targets", f.path(), w.fastest.size(),
                                    cols));
    if (f.Exists("/work_precision/tied")) {
      const std::vector<int32_t> tied = f.Ints("/work_precision/tied");
      if (tied.size() != cost.size())
        throw ResultError(fmt::format("{}: /work_precision/tied: {} cells, {} expected", f.path(), tied.size(), cost.size()));
      for (std::size_t j = 0; j < cols; ++j) {
        w.tied.emplace_back();
        for (std::size_t m = 0; m < w.labels.size(); ++m)
          if (tied[j * w.labels.size() + m]) w.tied.back().push_back(static_cast<int>(m));
      }
    }
    t.work_precision = std::move(w);
  }
  return t;
}

void WriteRunRecord(ResultFile& f, const std::string& g, const RunRecord& record) {
  RunRecord r = record;
  if (r.repeats <= 1) r.solver_time_s_median = r.solver_time_s_max = r.solver_time_s;
  for (const RecordField& field : RunRecordFields()) {
    std::visit(
        [&](auto member) {
          const auto& v = r.*member;
          using T = std::remove_cvref_t<decltype(v)>;
          bool store = true;
          switch (field.stored) {
            case Stored::kAlways: break;
            case Stored::kAdaptive: store = r.step_kind == "adaptive"; break;
            case Stored::kStepped: store = r.step_kind != "adaptive"; break;
            case Stored::kSubstepped: store = r.step_kind == "substepped"; break;
            default:
              if constexpr (std::is_same_v<T, std::string>) store = !v.empty();
              else if constexpr (std::is_same_v<T, std::optional<double>>) store = v.has_value();
              else store = field.stored == Stored::kPositive ? v > 0 : v >= 0;
          }
          if (!store) return;
          if constexpr (std::is_same_v<T, std::optional<double>>) f.SetAttribute(g, field.name, *v);
          else f.SetAttribute(g, field.name, v);
        },
        field.member);
  }
}

void WriteSceneRecord(ResultFile& f, const RunTable& t) {
  f.SetAttribute("/scene", "name", t.scene_name);
  f.SetAttribute("/scene", "source", t.scene_source);
  f.SetAttribute("/scene", "n_particles", t.n_particles);
  f.SetAttribute("/scene", "n_fixed", t.n_fixed);
  f.SetAttribute("/scene", "t_end", t.t_end);
  f.SetAttribute("/scene", "frame_dt", t.frame_dt);
  f.SetAttribute("/scene", "frames", t.frames);
  f.SetAttribute("/scene", "explicit_terms", t.explicit_terms);
  f.SetAttribute("/scene", "h", t.h);
  f.SetAttribute("/scene", "numerical_stiffness", t.numerical_stiffness);
  f.SetAttribute("/scene", "solver_cg_tolerance", t.cg_tolerance);
  f.SetAttribute("/scene", "solver_cg_reference", t.cg_reference);
  f.SetAttribute("/scene", "solver_preconditioner", t.preconditioner);
  f.SetAttribute("/scene", "solver_predictor", t.predictor);
  if (!t.amg_frames.empty()) f.SetAttribute("/scene", "solver_amg_frames", t.amg_frames);
  f.SetAttribute("/scene", "solver_max_updates", t.max_updates);
  if (!t.cholesky_ordering.empty()) {
    f.SetAttribute("/scene", "solver_cholesky_ordering", t.cholesky_ordering);
    f.SetAttribute("/scene", "solver_contact_factors", t.contact_factors);
    f.SetAttribute("/scene", "solver_tangent_projection", t.tangent_projection);
    f.SetAttribute("/scene", "solver_newton_jacobian", t.newton_jacobian);
    f.SetAttribute("/scene", "solver_controller_updates", t.controller_updates);
    f.SetAttribute("/scene", "solver_cg_max_iterations", t.cg_max_iterations);
    f.SetAttribute("/scene", "solver_max_rejections", t.max_rejections);
    f.SetAttribute("/scene", "solver_fixed_point_tolerance", t.fixed_point_tolerance);
    f.SetAttribute("/scene", "solver_step_factor", t.step_factor);
    f.SetAttribute("/scene", "solver_h_min", t.h_min);
    f.SetAttribute("/scene", "solver_h_max", t.h_max);
  }
}

void WriteWorkPrecision(ResultFile& f, const EqualAccuracyTable& t) {
  f.CreateGroup("/work_precision");
  f.SetAttribute("/work_precision", "baseline", t.reference);
  f.SetAttribute("/work_precision", "error_metric", t.metric);
  f.SetAttribute("/work_precision", "measure",
                 std::string("solver_time_s at e_rms(t_end) = target on each method's lower envelope of (error, "
                             "solver_time_s) runs, log-log interpolation between adjacent envelope runs; upper_bound 1: "
                             "the cheapest run already meets the target (cost <= that run's); -1 where no run reaches "
                             "the target (min_error: the smallest error reached, -1 if every run failed)"));
  f.WriteVector("/work_precision/targets", t.targets, "m");
  std::string labels;
  for (const std::string& l : t.labels) labels += (labels.empty() ? "" : ",") + l;
  f.SetAttribute("/work_precision", "labels", labels);
  const int rows = static_cast<int>(t.labels.size()), cols = static_cast<int>(t.targets.size());
  std::vector<double> cost, ratio, min_error;
  std::vector<int32_t> bound;
  for (std::size_t m = 0; m < static_cast<std::size_t>(rows); ++m) {
    for (std::size_t j = 0; j < static_cast<std::size_t>(cols); ++j) {
      cost.push_back(t.cost[m][j].value_or(-1.0));
      ratio.push_back(t.ratio[m][j].value_or(-1.0));
      bound.push_back(m < t.upper_bound.size() && t.upper_bound[m][j] ? 1 : 0);
    }
    min_error.push_back(m < t.min_error.size() && t.min_error[m] ? *t.min_error[m] : -1.0);
  }
  f.WriteTable("/work_precision/solver_time", rows, cols, cost, "s");
  f.WriteTable("/work_precision/ratio", rows, cols, ratio, "");
  f.WriteTable("/work_precision/upper_bound", rows, cols, bound);
  f.WriteVector("/work_precision/min_error", min_error, "m");
  // tied [T, M]: 1 where the method is tied with the fastest at the target.
  std::vector<int32_t> tied(static_cast<std::size_t>(cols) * static_cast<std::size_t>(rows), 0);
  for (std::size_t j = 0; j < t.tied.size(); ++j)
    for (int m : t.tied[j]) tied[j * static_cast<std::size_t>(rows) + static_cast<std::size_t>(m)] = 1;
  f.WriteTable("/work_precision/tied", cols, rows, tied);
  std::vector<int32_t> fastest(t.fastest.begin(), t.fastest.end());
  f.WriteTable("/work_precision/fastest", 1, cols, fastest);
}

}  // namespace clothbench
