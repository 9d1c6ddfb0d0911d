// XDMF 3 writer (an XML description; the data stay in the HDF5 file).
#include "results/xdmf.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <vector>

#include <fmt/format.h>

#include "results/result_reader.h"
#include "model/output_file.h"

namespace clothbench {
namespace {

// A DataItem referring to a whole dataset of the result file.
std::string DataItem(const std::string& file, const std::string& dataset, const std::vector<std::size_t>& shape,
                     bool integer) {
  std::string dims;
  for (std::size_t d : shape) {
    if (!dims.empty()) dims += ' ';
    dims += std::to_string(d);
  }
  return fmt::format(R"(<DataItem Dimensions="{}" NumberType="{}" Precision="{}" Format="HDF">{}:{}</DataItem>)", dims,
                     integer ? "Int" : "Float", integer ? 4 : 8, file, dataset);
}

// Frame times of the stored frames of `name` ("positions" or "velocities")
// under group g: every time of g/times for g/<name>, the first and last for
// g/<name>_ends; empty if neither is stored.
std::vector<double> StoredFrameTimes(const ResultReader& f, const std::string& g, const std::string& name) {
  const std::vector<double> times = f.Exists(g + "/times") ? f.Doubles(g + "/times") : std::vector<double>{};
  if (times.empty()) return {};
  if (f.Exists(g + "/" + name)) {
    const std::size_t n = std::min(times.size(), f.Shape(g + "/" + name)[0]);
    return {times.begin(), times.begin() + static_cast<std::ptrdiff_t>(n)};
  }
  if (f.Exists(g + "/" + name + "_ends")) return {times.front(), times.back()};
  return {};
}

// A deforming obstacle's surface as a temporal collection, one grid per
// stored time (the report's `/scene/obstacles/k/positions`).
std::string MovingObstacle(const ResultReader& f, const std::string& file, const std::string& k,
                           const std::vector<std::size_t>& tri) {
  const std::string o = "/scene/obstacles/" + k;
  const std::vector<double> times = f.Doubles(o + "/times");
  const std::vector<std::size_t> shape = f.Shape(o + "/positions");
  std::string body = fmt::format(R"(    <Grid Name="obstacle_{}" GridType="Collection" CollectionType="Temporal">)"
                                 "\n",
                                 k);
  for (std::size_t j = 0; j < times.size() && j < shape[0]; ++j)
    body += fmt::format(R"(      <Grid Name="obstacle_{}_{}" GridType="Uniform">)"
                        "\n"
                        R"(        <Time Value="{:.17g}"/>)"
                        "\n"
                        R"(        <Topology TopologyType="Triangle" NumberOfElements="{}">{}</Topology>)"
                        "\n"
                        R"(        <Geometry GeometryType="XYZ">{}</Geometry>)"
                        "\n      </Grid>\n",
                        k, j, times[j], tri[0], DataItem(file, o + "/triangles", tri, true),
                        DataItem(file, fmt::format("{}/frame_views/positions_{}", o, j), {shape[1], 3}, false));
  return body + "    </Grid>\n";
}

}  // namespace

std::string WriteXdmf(const std::string& h5_path) {
  const ResultReader f(h5_path);
  std::vector<std::string> groups;
  if (f.Exists("/reference")) groups.push_back("/reference");
  for (const std::string& id : f.Children("/runs")) groups.push_back("/runs/" + id);
  const bool has_faces = f.Exists("/scene/faces");
  const std::string file = std::filesystem::path(h5_path).filename().string();
  const std::vector<std::size_t> faces_shape = has_faces ? f.Shape("/scene/faces") : std::vector<std::size_t>{};
  const long n = f.Long("/scene", "n_particles").value_or(0);

  std::string body;
  int collections = 0;
  for (const std::string& g : groups) {
    const std::vector<double> times = StoredFrameTimes(f, g, "positions");
    if (times.empty() || !has_faces) continue;
    const std::vector<double> vtimes = StoredFrameTimes(f, g, "velocities");
    const std::string name = g == "/reference" ? "reference" : g.substr(std::string("/runs/").size());
    body += fmt::format(R"(    <Grid Name="{}" GridType="Collection" CollectionType="Temporal">)"
                        "\n",
                        name);
    for (std::size_t k = 0; k < times.size(); ++k) {
      body += fmt::format(R"(      <Grid Name="{}_{}" GridType="Uniform">)"
                          "\n",
                          name, k);
      body += fmt::format(R"(        <Time Value="{:.17g}"/>)"
                          "\n",
                          times[k]);
      body += fmt::format(R"(        <Topology TopologyType="Quadrilateral" NumberOfElements="{}">{}</Topology>)"
                          "\n",
                          faces_shape[0], DataItem(file, "/scene/faces", faces_shape, true));
      body += fmt::format(R"(        <Geometry GeometryType="XYZ">{}</Geometry>)"
                          "\n",
                          DataItem(file, fmt::format("{}/frame_views/positions_{}", g, k),
                                   {static_cast<std::size_t>(n), 3}, false));
      for (std::size_t j = 0; j < vtimes.size(); ++j)
        if (vtimes[j] == times[k])
          body += fmt::format(R"(        <Attribute Name="velocity" AttributeType="Vector" Center="Node">{}</Attribute>)"
                              "\n",
                              DataItem(file, fmt::format("{}/frame_views/velocities_{}", g, j),
                                       {static_cast<std::size_t>(n), 3}, false));
      body += "      </Grid>\n";
    }
    body += "    </Grid>\n";
    ++collections;
  }
  if (collections == 0) return "";
  // Triangle-mesh obstacles: static, or a deforming one's surface at its
  // stored times.
  for (const std::string& k : f.Children("/scene/obstacles")) {
    const std::string o = "/scene/obstacles/" + k;
    if (!f.Exists(o + "/vertices") || !f.Exists(o + "/triangles")) continue;
    const std::vector<std::size_t> tri = f.Shape(o + "/triangles");
    if (f.Exists(o + "/positions") && f.Exists(o + "/times")) {
      body += MovingObstacle(f, file, k, tri);
      continue;
    }
    body += fmt::format(R"(    <Grid Name="obstacle_{}" GridType="Uniform">)"
                        "\n"
                        R"(      <Topology TopologyType="Triangle" NumberOfElements="{}">{}</Topology>)"
                        "\n"
                        R"(      <Geometry GeometryType="XYZ">{}</Geometry>)"
                        "\n    </Grid>\n",
                        k, tri[0], DataItem(file, o + "/triangles", tri, true),
                        DataItem(file, o + "/vertices", f.Shape(o + "/vertices"), false));
  }
  std::filesystem::path xdmf = h5_path;
  xdmf.replace_extension(".xdmf");
  try {
    WriteFileAtomically(xdmf.string(),
                        "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n  <Domain>\n" + body + "  </Domain>\n</Xdmf>\n",
                        "XDMF");
  } catch (const std::runtime_error& e) {
    throw ResultError(e.what());
  }
  return xdmf.string();
}

}  // namespace clothbench
