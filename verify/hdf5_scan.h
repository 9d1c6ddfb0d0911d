// Test helpers: every floating-point value an HDF5 file stores, in datasets
// (compound members included) and attributes, checked for finiteness; and
// every value of a file, for comparing two.
#ifndef CLOTHBENCH_VERIFY_HDF5_SCAN_H_
#define CLOTHBENCH_VERIFY_HDF5_SCAN_H_

#include <hdf5.h>

#include <cmath>
#include <map>
#include <string>
#include <vector>

namespace clothbench::testing {

struct NonFiniteScan {
  long values = 0;                   ///< floating-point values read
  std::vector<std::string> offenders;  ///< "<object>" or "<object>@<attribute>" holding a non-finite value
};

namespace internal {

inline bool AllFinite(const std::vector<double>& v) {
  for (double x : v)
    if (!std::isfinite(x)) return false;
  return true;
}

// Reads the float members of a compound type (or the whole dataset for a
// float type) as doubles.
inline void ScanDataset(hid_t ds, const std::string& name, NonFiniteScan* scan) {
  const hid_t type = H5Dget_type(ds);
  const hid_t space = H5Dget_space(ds);
  const hssize_t n = H5Sget_simple_extent_npoints(space);
  if (H5Tget_class(type) == H5T_FLOAT && n > 0) {
    std::vector<double> buf(static_cast<std::size_t>(n));
    if (H5Dread(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data()) >= 0) {
      scan->values += n;
      if (!AllFinite(buf)) scan->offenders.push_back(name);
    }
  } else if (H5Tget_class(type) == H5T_COMPOUND && n > 0) {
    for (int m = 0; m < H5Tget_nmembers(type); ++m) {
      const hid_t mt = H5Tget_member_type(type, static_cast<unsigned>(m));
      if (H5Tget_class(mt) == H5T_FLOAT) {
        char* member = H5Tget_member_name(type, static_cast<unsigned>(m));
        const hid_t mem = H5Tcreate(H5T_COMPOUND, sizeof(double));
        H5Tinsert(mem, member, 0, H5T_NATIVE_DOUBLE);
        std::vector<double> buf(static_cast<std::size_t>(n));
        if (H5Dread(ds, mem, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data()) >= 0) {
          scan->values += n;
          if (!AllFinite(buf)) scan->offenders.push_back(name + "." + member);
        }
        H5Tclose(mem);
        H5free_memory(member);
      }
      H5Tclose(mt);
    }
  }
  H5Sclose(space);
  H5Tclose(type);
}

struct VisitData {
  hid_t file;
  NonFiniteScan* scan;
};

inline herr_t ScanAttribute(hid_t object, const char* attr_name, const H5A_info_t*, void* data) {
  auto* d = static_cast<std::pair<std::string, NonFiniteScan*>*>(data);
  const hid_t a = H5Aopen(object, attr_name, H5P_DEFAULT);
  const hid_t type = H5Aget_type(a);
  if (H5Tget_class(type) == H5T_FLOAT) {
    const hid_t space = H5Aget_space(a);
    const hssize_t n = H5Sget_simple_extent_npoints(space);
    std::vector<double> buf(static_cast<std::size_t>(n));
    if (n > 0 && H5Aread(a, H5T_NATIVE_DOUBLE, buf.data()) >= 0) {
      d->second->values += n;
      if (!AllFinite(buf)) d->second->offenders.push_back(d->first + "@" + attr_name);
    }
    H5Sclose(space);
  }
  H5Tclose(type);
  H5Aclose(a);
  return 0;
}

inline herr_t ScanObject(hid_t, const char* name, const H5O_info_t* info, void* data) {
  auto* d = static_cast<VisitData*>(data);
  const hid_t obj = H5Oopen(d->file, name, H5P_DEFAULT);
  if (obj < 0) return 0;
  std::pair<std::string, NonFiniteScan*> ad{name, d->scan};
  hsize_t idx = 0;
  H5Aiterate2(obj, H5_INDEX_NAME, H5_ITER_NATIVE, &idx, ScanAttribute, &ad);
  if (info->type == H5O_TYPE_DATASET) ScanDataset(obj, name, d->scan);
  H5Oclose(obj);
  return 0;
}

}  // namespace internal

/// Scans every dataset and attribute of the HDF5 file at `path`.
/// Returns values = -1 if the file cannot be opened.
inline NonFiniteScan ScanForNonFinite(const std::string& path) {
  NonFiniteScan scan;
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (file < 0) {
    scan.values = -1;
    return scan;
  }
  internal::VisitData data{file, &scan};
  H5Ovisit(file, H5_INDEX_NAME, H5_ITER_NATIVE, internal::ScanObject, &data);
  H5Fclose(file);
  return scan;
}

/// Every value of an HDF5 file as bytes in native types: "<object>" for a
/// dataset, "<object>.<member>" for a compound member, "<object>@<attr>"
/// for an attribute (strings as their bytes), for comparing two files.
using FileContents = std::map<std::string, std::string>;

namespace internal {

inline std::string ReadAll(hid_t obj, hid_t mem_type, hssize_t n, bool attribute) {
  const std::size_t size = H5Tget_size(mem_type);
  std::string buf(static_cast<std::size_t>(n) * size, '\0');
  if (n > 0) {
    if (attribute) H5Aread(obj, mem_type, buf.data());
    else H5Dread(obj, mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data());
  }
  return buf;
}

inline herr_t ContentAttribute(hid_t object, const char* attr_name, const H5A_info_t*, void* data) {
  auto* d = static_cast<std::pair<std::string, FileContents*>*>(data);
  const hid_t a = H5Aopen(object, attr_name, H5P_DEFAULT);
  const hid_t type = H5Aget_type(a), space = H5Aget_space(a);
  const hid_t native = H5Tget_native_type(type, H5T_DIR_ASCEND);
  (*d->second)[d->first + "@" + attr_name] = ReadAll(a, native, H5Sget_simple_extent_npoints(space), true);
  H5Tclose(native);
  H5Sclose(space);
  H5Tclose(type);
  H5Aclose(a);
  return 0;
}

inline herr_t ContentObject(hid_t, const char* name, const H5O_info_t* info, void* data) {
  auto* d = static_cast<std::pair<hid_t, FileContents*>*>(data);
  const hid_t obj = H5Oopen(d->first, name, H5P_DEFAULT);
  if (obj < 0) return 0;
  std::pair<std::string, FileContents*> ad{name, d->second};
  hsize_t idx = 0;
  H5Aiterate2(obj, H5_INDEX_NAME, H5_ITER_NATIVE, &idx, ContentAttribute, &ad);
  if (info->type == H5O_TYPE_DATASET) {
    const hid_t type = H5Dget_type(obj), space = H5Dget_space(obj);
    const hssize_t n = H5Sget_simple_extent_npoints(space);
    if (H5Tget_class(type) == H5T_COMPOUND) {
      for (int m = 0; m < H5Tget_nmembers(type); ++m) {
        char* member = H5Tget_member_name(type, static_cast<unsigned>(m));
        const hid_t mt = H5Tget_member_type(type, static_cast<unsigned>(m));
        const hid_t native = H5Tget_native_type(mt, H5T_DIR_ASCEND);
        const hid_t mem = H5Tcreate(H5T_COMPOUND, H5Tget_size(native));
        H5Tinsert(mem, member, 0, native);
        (*d->second)[std::string(name) + "." + member] = ReadAll(obj, mem, n, false);
        H5Tclose(mem);
        H5Tclose(native);
        H5Tclose(mt);
        H5free_memory(member);
      }
    } else {
      const hid_t native = H5Tget_native_type(type, H5T_DIR_ASCEND);
      (*d->second)[name] = ReadAll(obj, native, n, false);
      H5Tclose(native);
    }
    H5Sclose(space);
    H5Tclose(type);
  }
  H5Oclose(obj);
  return 0;
}

}  // namespace internal

inline FileContents ReadContents(const std::string& path) {
  FileContents c;
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (file < 0) return c;
  std::pair<hid_t, FileContents*> data{file, &c};
  H5Ovisit(file, H5_INDEX_NAME, H5_ITER_NATIVE, internal::ContentObject, &data);
  H5Fclose(file);
  return c;
}

}  // namespace clothbench::testing

#endif  // CLOTHBENCH_VERIFY_HDF5_SCAN_H_
