// Test helpers: every value of an HDF5 file (datasets, compound members and
// attributes), for comparing two files, and every floating-point one
// checked for finiteness.
#ifndef CLOTHBENCH_VERIFY_HDF5_SCAN_H_
#define CLOTHBENCH_VERIFY_HDF5_SCAN_H_

#include <hdf5.h>

#include <cmath>
#include <cstring>
#include <map>
#include <set>
#include <string>
#include <vector>

namespace clothbench::testing {

/// Every value of a file as bytes in native types (floating point as
/// double): "<object>" for a dataset, "<object>.<member>" for a compound
/// member, "<object>@<attr>" for an attribute (strings as their bytes).
struct FileContents {
  std::map<std::string, std::string> values;
  std::set<std::string> doubles;  ///< the keys whose bytes are doubles
};

namespace internal {

// Reads n elements of `file_type` from a dataset or attribute `obj` under
// `key`, through a compound memory type holding only `member` if given.
inline void ReadValue(hid_t obj, bool attribute, hid_t file_type, hssize_t n, const std::string& key,
                      const char* member, FileContents* c) {
  const bool is_double = H5Tget_class(file_type) == H5T_FLOAT;
  const hid_t native = is_double ? H5Tcopy(H5T_NATIVE_DOUBLE) : H5Tget_native_type(file_type, H5T_DIR_ASCEND);
  hid_t mem = native;
  if (member) {
    mem = H5Tcreate(H5T_COMPOUND, H5Tget_size(native));
    H5Tinsert(mem, member, 0, native);
  }
  std::string buf(static_cast<std::size_t>(n) * H5Tget_size(mem), '\0');
  if (n > 0) {
    if (attribute) H5Aread(obj, mem, buf.data());
    else H5Dread(obj, mem, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data());
  }
  c->values[key] = std::move(buf);
  if (is_double) c->doubles.insert(key);
  if (member) H5Tclose(mem);
  H5Tclose(native);
}

inline herr_t ReadAttribute(hid_t object, const char* attr_name, const H5A_info_t*, void* data) {
  auto* d = static_cast<std::pair<std::string, FileContents*>*>(data);
  const hid_t a = H5Aopen(object, attr_name, H5P_DEFAULT);
  const hid_t type = H5Aget_type(a), space = H5Aget_space(a);
  ReadValue(a, true, type, H5Sget_simple_extent_npoints(space), d->first + "@" + attr_name, nullptr, d->second);
  H5Sclose(space);
  H5Tclose(type);
  H5Aclose(a);
  return 0;
}

inline herr_t ReadObject(hid_t, const char* name, const H5O_info_t* info, void* data) {
  auto* d = static_cast<std::pair<hid_t, FileContents*>*>(data);
  const hid_t obj = H5Oopen(d->first, name, H5P_DEFAULT);
  if (obj < 0) return 0;
  std::pair<std::string, FileContents*> ad{name, d->second};
  hsize_t idx = 0;
  H5Aiterate2(obj, H5_INDEX_NAME, H5_ITER_NATIVE, &idx, ReadAttribute, &ad);
  if (info->type == H5O_TYPE_DATASET) {
    const hid_t type = H5Dget_type(obj), space = H5Dget_space(obj);
    const hssize_t n = H5Sget_simple_extent_npoints(space);
    if (H5Tget_class(type) == H5T_COMPOUND) {
      for (int m = 0; m < H5Tget_nmembers(type); ++m) {
        char* member = H5Tget_member_name(type, static_cast<unsigned>(m));
        const hid_t mt = H5Tget_member_type(type, static_cast<unsigned>(m));
        ReadValue(obj, false, mt, n, std::string(name) + "." + member, member, d->second);
        H5Tclose(mt);
        H5free_memory(member);
      }
    } else {
      ReadValue(obj, false, type, n, name, nullptr, d->second);
    }
    H5Sclose(space);
    H5Tclose(type);
  }
  H5Oclose(obj);
  return 0;
}

}  // namespace internal

/// Reads every value of the file at `path` (empty if it cannot be opened).
inline FileContents ReadContents(const std::string& path) {
  FileContents c;
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (file < 0) return c;
  std::pair<hid_t, FileContents*> data{file, &c};
  H5Ovisit(file, H5_INDEX_NAME, H5_ITER_NATIVE, internal::ReadObject, &data);
  H5Fclose(file);
  return c;
}

struct NonFiniteScan {
  long values = 0;                     ///< floating-point values read
  std::vector<std::string> offenders;  ///< keys (as in FileContents) holding a non-finite value
};

/// Checks every floating-point value of the file at `path`; values = -1 if
/// the file cannot be opened.
inline NonFiniteScan ScanForNonFinite(const std::string& path) {
  NonFiniteScan scan;
  if (H5Fis_hdf5(path.c_str()) <= 0) {
    scan.values = -1;
    return scan;
  }
  const FileContents c = ReadContents(path);
  for (const std::string& key : c.doubles) {
    const std::string& bytes = c.values.at(key);
    std::vector<double> v(bytes.size() / sizeof(double));
    std::memcpy(v.data(), bytes.data(), v.size() * sizeof(double));
    scan.values += static_cast<long>(v.size());
    for (double x : v)
      if (!std::isfinite(x)) {
        scan.offenders.push_back(key);
        break;
      }
  }
  return scan;
}

}  // namespace clothbench::testing

#endif  // CLOTHBENCH_VERIFY_HDF5_SCAN_H_
