#include "results/mesh_export.h"

#include <fmt/format.h>

#include "model/output_file.h"
#include "results/result_file.h"

namespace clothbench {

StoredFrames StoredFramesOf(const ResultReader& f, const std::string& run, const std::string& command) {
  const std::string g = run == "reference" ? "/reference" : "/runs/" + run;
  if (!f.Exists(g)) {
    std::string runs;
    for (const std::string& id : f.Children("/runs")) runs += (runs.empty() ? "" : ", ") + id;
    throw ResultError(fmt::format("{}: no run \"{}\" in {} (runs: reference, {})", command, run, f.path(), runs));
  }
  StoredFrames s;
  s.dataset = f.Exists(g + "/positions") ? g + "/positions" : g + "/positions_ends";
  if (!f.Exists(s.dataset))
    throw ResultError(fmt::format("{}: run \"{}\" in {} has no stored frames (written with --frames none)", command,
                                  run, f.path()));
  s.count = f.Shape(s.dataset)[0];
  if (s.count == 0) throw ResultError(fmt::format("{}: {} in {} holds no frames", command, s.dataset, f.path()));
  s.times = f.Doubles(g + "/times");
  return s;
}

ExportedFrame ExportFrame(const ResultReader& f, const std::string& run, long frame, MeshFormat format,
                          const std::string& path, const std::string& option) {
  CheckOutputTarget(path, option);
  const StoredFrames stored = StoredFramesOf(f, run, "export");
  const std::string& dataset = stored.dataset;
  const std::size_t frames = stored.count;
  if (frame < 0 || static_cast<std::size_t>(frame) >= frames)
    throw ResultError(fmt::format("--frame: {} is not a stored frame of {} ({} frames, 0 … {}{})", frame, dataset,
                                  frames, frames - 1, dataset.ends_with("_ends") ? ": t = 0 and t_end" : ""));
  const MatrixN3 x = f.Frame(dataset, static_cast<std::size_t>(frame));
  const std::vector<int32_t> faces = f.Ints("/scene/faces");
  const double t = stored.TimeOf(static_cast<std::size_t>(frame));
  std::string text;
  if (format == MeshFormat::kObj) {
    text += fmt::format("# {} run {} frame {} (t = {:g} s), positions [m]\n", f.path(), run, frame, t);
    for (Eigen::Index p = 0; p < x.rows(); ++p) text += fmt::format("v {:.17g} {:.17g} {:.17g}\n", x(p, 0), x(p, 1), x(p, 2));
    for (std::size_t q = 0; q + 3 < faces.size(); q += 4)
      text += fmt::format("f {} {} {} {}\n", faces[q] + 1, faces[q + 1] + 1, faces[q + 2] + 1, faces[q + 3] + 1);
  } else {
    text += fmt::format("ply\nformat ascii 1.0\ncomment {} run {} frame {} (t = {:g} s), positions [m]\n"
                        "element vertex {}\nproperty double x\nproperty double y\nproperty double z\n"
                        "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
                        f.path(), run, frame, t, x.rows(), faces.size() / 4);
    for (Eigen::Index p = 0; p < x.rows(); ++p) text += fmt::format("{:.17g} {:.17g} {:.17g}\n", x(p, 0), x(p, 1), x(p, 2));
    for (std::size_t q = 0; q + 3 < faces.size(); q += 4)
      text += fmt::format("4 {} {} {} {}\n", faces[q], faces[q + 1], faces[q + 2], faces[q + 3]);
  }
  WriteFileAtomically(path, text, option);
  return {t, static_cast<long>(x.rows()), static_cast<long>(faces.size() / 4)};
}

}  // namespace clothbench
