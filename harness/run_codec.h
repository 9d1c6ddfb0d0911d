// A run's results as bytes, bit for bit: what bench_integrators sends from
// one MPI rank to rank 0 and keeps in its journal (harness/sweep.h). Only
// what a rank computes travels; energies, errors and observed orders are
// derived on rank 0 exactly as in a serial run.
#ifndef CLOTHBENCH_HARNESS_RUN_CODEC_H_
#define CLOTHBENCH_HARNESS_RUN_CODEC_H_

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
#include <variant>
#include <vector>

#include <fmt/format.h>

#include "harness/methods.h"

namespace clothbench {

class ByteWriter {
 public:
  template <class T>
  void Pod(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    buf_.append(reinterpret_cast<const char*>(&v), sizeof(T));
  }
  void Str(const std::string& s) {
    Pod<uint64_t>(s.size());
    buf_ += s;
  }
  template <class T>
  void Vec(const std::vector<T>& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    Pod<uint64_t>(v.size());
    buf_.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
  }
  void Frames(const std::vector<MatrixN3>& frames) {
    Pod<uint64_t>(frames.size());
    for (const MatrixN3& f : frames) {
      Pod<int64_t>(f.rows());
      buf_.append(reinterpret_cast<const char*>(f.data()), static_cast<std::size_t>(f.size()) * sizeof(double));
    }
  }
  std::string Take() { return std::move(buf_); }

 private:
  std::string buf_;
};

/// Reads what ByteWriter wrote. @throws std::runtime_error on truncated or
/// malformed bytes (a damaged journal entry).
class ByteReader {
 public:
  explicit ByteReader(std::string_view bytes) : b_(bytes) {}
  template <class T>
  T Pod() {
    T v;
    Need(sizeof(T));
    std::memcpy(&v, b_.data() + at_, sizeof(T));
    at_ += sizeof(T);
    return v;
  }
  std::string Str() {
    const auto n = Pod<uint64_t>();
    Need(n);
    std::string s(b_.substr(at_, n));
    at_ += n;
    return s;
  }
  template <class T>
  std::vector<T> Vec() {
    const auto n = Pod<uint64_t>();
    if (n > b_.size() / sizeof(T) + 1) throw std::runtime_error("malformed run record");
    Need(n * sizeof(T));
    std::vector<T> v(n);
    std::memcpy(v.data(), b_.data() + at_, n * sizeof(T));
    at_ += n * sizeof(T);
    return v;
  }
  std::vector<MatrixN3> Frames() {
    const auto n = Pod<uint64_t>();
    if (n > b_.size()) throw std::runtime_error("malformed run record");
    std::vector<MatrixN3> frames(n);
    for (MatrixN3& f : frames) {
      const auto rows = Pod<int64_t>();
      if (rows < 0 || static_cast<uint64_t>(rows) > b_.size()) throw std::runtime_error("malformed run record");
      const std::size_t bytes = static_cast<std::size_t>(rows) * 3 * sizeof(double);
      Need(bytes);
      f.resize(rows, 3);
      std::memcpy(f.data(), b_.data() + at_, bytes);
      at_ += bytes;
    }
    return frames;
  }
  bool done() const { return at_ == b_.size(); }

 private:
  void Need(std::size_t n) const {
    if (n > b_.size() - at_) throw std::runtime_error("truncated run record");
  }
  std::string_view b_;
  std::size_t at_ = 0;
};

namespace internal {

inline void PutTrajectory(ByteWriter& w, const Trajectory& t) {
  w.Vec(t.times);
  w.Frames(t.positions);
  w.Frames(t.velocities);
  w.Vec(t.external_work);
  w.Vec(t.contact_work_holding);
  w.Vec(t.contact_work_pulling);
  w.Vec(t.contact_work_friction);
  w.Vec(t.crossing_pairs);
  w.Vec(t.contact_work_self);
  const VirtualFrames& v = t.virtual_particles;
  for (const auto* ints : {&v.offsets, &v.face_offsets, &v.cloth_edge, &v.obstacle_edge, &v.faces}) w.Vec(*ints);
  w.Vec(v.x);
  w.Vec(v.tension_energy);
}
inline Trajectory GetTrajectory(ByteReader& r) {
  Trajectory t;
  t.times = r.Vec<double>();
  t.positions = r.Frames();
  t.velocities = r.Frames();
  t.external_work = r.Vec<double>();
  t.contact_work_holding = r.Vec<double>();
  t.contact_work_pulling = r.Vec<double>();
  t.contact_work_friction = r.Vec<double>();
  t.crossing_pairs = r.Vec<int32_t>();
  t.contact_work_self = r.Vec<double>();
  VirtualFrames& v = t.virtual_particles;
  for (auto* ints : {&v.offsets, &v.face_offsets, &v.cloth_edge, &v.obstacle_edge, &v.faces}) *ints = r.Vec<int32_t>();
  v.x = r.Vec<double>();
  v.tension_energy = r.Vec<double>();
  return t;
}
inline void PutSundials(ByteWriter& w, const std::optional<SundialsStats>& s) {
  w.Pod<uint8_t>(s.has_value());
  if (s) w.Pod(*s);
}
inline std::optional<SundialsStats> GetSundials(ByteReader& r) {
  if (!r.Pod<uint8_t>()) return std::nullopt;
  return r.Pod<SundialsStats>();
}

// Range checks of a decoded record (a journal entry passed its checksum, a
// message came from another rank): counts non-negative, numbers finite,
// status codes known, every frame N×3 and each per-frame series as long as
// the frame times. @throws std::runtime_error naming the field.
[[noreturn]] inline void OutOfRange(const std::string& what) {
  throw std::runtime_error("decoded value out of range: " + what);
}
inline void CheckFinite(double v, const char* what) {
  if (!std::isfinite(v)) OutOfRange(fmt::format("{} = {}", what, v));
}
inline void CheckCount(long v, long min, const char* what) {
  if (v < min) OutOfRange(fmt::format("{} = {} (at least {})", what, v, min));
}
inline void CheckTrajectory(const Trajectory& t, long n_particles) {
  for (std::size_t k = 0; k < t.times.size(); ++k) {
    CheckFinite(t.times[k], "frame time");
    if (k > 0 && t.times[k] < t.times[k - 1]) OutOfRange("frame times decrease");
  }
  for (const auto* frames : {&t.positions, &t.velocities}) {
    if (frames->size() > t.times.size()) OutOfRange("more frames than frame times");
    for (const MatrixN3& f : *frames)
      if (f.rows() != n_particles || !f.allFinite()) OutOfRange("a frame that is not a finite N×3 matrix");
  }
  if (!t.crossing_pairs.empty() && t.crossing_pairs.size() != t.times.size())
    OutOfRange("a crossing count series not as long as the frame times");
  for (int32_t c : t.crossing_pairs)
    if (c < 0) OutOfRange("a negative crossing count");
  for (const auto* w : {&t.external_work, &t.contact_work_holding, &t.contact_work_pulling, &t.contact_work_friction,
                        &t.contact_work_self}) {
    if (!w->empty() && w->size() != t.times.size()) OutOfRange("a work series not as long as the frame times");
    for (double v : *w) CheckFinite(v, "work");
  }
  const VirtualFrames& v = t.virtual_particles;
  if (v.empty()) return;
  const auto offsets_ok = [&](const std::vector<int32_t>& o, std::size_t rows) {
    if (o.size() != t.times.size() + 1 || o.front() != 0 || static_cast<std::size_t>(o.back()) != rows) return false;
    return std::is_sorted(o.begin(), o.end());
  };
  const std::size_t k = v.x.size() / 3;
  if (v.x.size() % 3 != 0 || v.cloth_edge.size() != 2 * k || v.obstacle_edge.size() != 2 * k || v.faces.size() % 3 != 0 ||
      !offsets_ok(v.offsets, k) || !offsets_ok(v.face_offsets, v.faces.size() / 3))
    OutOfRange("virtual particle frames of inconsistent sizes");
  for (double c : v.x) CheckFinite(c, "virtual particle position");
  if (v.tension_energy.size() != t.times.size()) OutOfRange("virtual particle frames of inconsistent sizes");
  for (double e : v.tension_energy) CheckFinite(e, "virtual springs' energy");
  for (std::size_t f = 0; f + 1 < v.face_offsets.size(); ++f)
    for (std::size_t i = 3 * static_cast<std::size_t>(v.face_offsets[f]); i < 3 * static_cast<std::size_t>(v.face_offsets[f + 1]); ++i)
      if (v.faces[i] < 0 || v.faces[i] >= n_particles + (v.offsets[f + 1] - v.offsets[f]))
        OutOfRange("a refined face's vertex index");
}
inline void CheckStepStatus(int status) {
  if (status < 0 || status > static_cast<int>(StepStatus::kTimeLimit)) OutOfRange(fmt::format("step status {}", status));
}

/// A run's method attributes (RunRecord::method_attributes): their count,
/// then each one's name, type index and value.
inline void PutMethodAttributes(ByteWriter& w, const std::vector<std::pair<std::string, MethodValue>>& attributes) {
  w.Pod(static_cast<long>(attributes.size()));
  for (const auto& [name, value] : attributes) {
    w.Str(name);
    w.Pod(static_cast<int>(value.index()));
    std::visit(
        [&](const auto& v) {
          if constexpr (std::is_same_v<std::remove_cvref_t<decltype(v)>, std::string>) w.Str(v);
          else w.Pod(v);
        },
        value);
  }
}

/// Reads what PutMethodAttributes wrote. @throws std::runtime_error on a
/// count or type out of range.
inline std::vector<std::pair<std::string, MethodValue>> GetMethodAttributes(ByteReader& r) {
  const long n = r.Pod<long>();
  if (n < 0 || n > 1024) OutOfRange(fmt::format("method attribute count {}", n));
  std::vector<std::pair<std::string, MethodValue>> attributes;
  for (long k = 0; k < n; ++k) {
    std::string name = r.Str();
    const int type = r.Pod<int>();
    if (type == 0) attributes.emplace_back(std::move(name), r.Str());
    else if (type == 1) attributes.emplace_back(std::move(name), r.Pod<long>());
    else if (type == 2) {
      const double v = r.Pod<double>();
      CheckFinite(v, "a method attribute");
      attributes.emplace_back(std::move(name), v);
    }
    else OutOfRange(fmt::format("method attribute type {}", type));
  }
  return attributes;
}

}  // namespace internal

/// One run as the step loop returned it (a row's MethodRun, the reference,
/// a thesis table row): its id, the fields of RunRecordFields() that a run computes
/// (errors, order and energies excluded: rank 0 derives them), its step
/// history, trajectory and SUNDIALS counters.
inline std::string EncodeRun(const RunSummary& m) {
  ByteWriter w;
  w.Str(m.id);
  for (const RecordField& field : RunRecordFields())
    if (!field.derived)
      std::visit(
          [&](auto member) {
            const auto& v = m.*member;
            using T = std::remove_cvref_t<decltype(v)>;
            if constexpr (std::is_same_v<T, std::string>) w.Str(v);
            else if constexpr (!std::is_same_v<T, std::optional<double>>) w.Pod(v);
          },
          field.member);
  internal::PutMethodAttributes(w, m.method_attributes);
  w.Pod(m.matrix_rebuilds);
  w.Vec(m.step_stats);
  internal::PutTrajectory(w, m.trajectory);
  internal::PutSundials(w, m.sundials);
  return w.Take();
}

/// Bumped by hand when EncodeRun's own layout (the method attributes, step
/// history, trajectory or SUNDIALS counters) changes in a way that
/// RunRecordFormat does not see.
inline constexpr int kRunRecordLayout = 1;

/// What fixes EncodeRun's byte layout: the layout number, the stored fields
/// of RunRecordFields() by name and size in order, and the sizes of a step's
/// stats and of the SUNDIALS counters. A journal's key carries it
/// (JournalKey), so that a build whose records differ refuses an older
/// build's journal instead of discarding its runs as malformed.
inline std::string RunRecordFormat() {
  std::string text = fmt::format("layout {}", kRunRecordLayout);
  for (const RecordField& field : RunRecordFields())
    if (!field.derived)
      std::visit(
          [&](auto member) {
            using T = std::remove_cvref_t<decltype(RunSummary{}.*member)>;
            text += fmt::format(" {}:{}", field.name, std::is_same_v<T, std::string> ? 0 : sizeof(T));
          },
          field.member);
  text += fmt::format(" steps:{} sundials:{}", sizeof(StepStats), sizeof(SundialsStats));
  return text;
}

/// Decodes what EncodeRun wrote into `m`'s record, step history,
/// trajectory and SUNDIALS counters (a MethodRun's derived fields are left
/// alone). @param n_particles the scene's N (every frame is N×3)
/// @throws std::runtime_error on a truncated or malformed record, or a
/// value out of range (internal::CheckTrajectory and the counts).
inline void DecodeRun(std::string_view bytes, long n_particles, RunSummary* m) {
  ByteReader r(bytes);
  m->id = r.Str();
  for (const RecordField& field : RunRecordFields())
    if (!field.derived)
      std::visit(
          [&](auto member) {
            auto& v = m->*member;
            using T = std::remove_cvref_t<decltype(v)>;
            if constexpr (std::is_same_v<T, std::string>) v = r.Str();
            else if constexpr (!std::is_same_v<T, std::optional<double>>) v = r.Pod<T>();
          },
          field.member);
  m->method_attributes = internal::GetMethodAttributes(r);
  m->matrix_rebuilds = r.Pod<int>();
  m->step_stats = r.Vec<StepStats>();
  m->trajectory = internal::GetTrajectory(r);
  m->sundials = internal::GetSundials(r);
  if (!r.done()) throw std::runtime_error("malformed run record");
  using namespace internal;
  for (double v : {m->h, m->rtol, m->cg_tolerance, m->atol, m->solver_time_s, m->solver_time_s_median,
                   m->solver_time_s_max, m->wall_time_s, m->setup_time_s, m->contact_detection_time_s,
                   m->numerical_stiffness})
    CheckFinite(v, "a parameter or time");
  if (m->h < 0.0 || m->rtol < 0.0 || m->solver_time_s < 0.0) OutOfRange("a negative step, tolerance or time");
  CheckCount(m->repeats, 1, "repeats");
  for (long v : {m->threads, m->substeps, m->iterations, m->steps, m->updates, m->cg_iterations, m->rejected, m->cg_unconverged})
    CheckCount(v, 0, "a count");
  if (ToString(m->status) == "?" || ToString(m->step_kind) == "?") OutOfRange("a run status or step kind");
  CheckCount(m->error_test_failures, -1, "error_test_failures");
  CheckCount(m->events, -1, "events");
  CheckCount(m->matrix_rebuilds, -1, "matrix_rebuilds");
  CheckTrajectory(m->trajectory, n_particles);
  for (const StepStats& st : m->step_stats) {
    for (double v : {st.t, st.h, st.solve_time, st.setup_time, st.error_norm}) CheckFinite(v, "a step record");
    if (st.h < 0.0 || st.updates < -1 || st.cg_iterations < -1 || st.colliding < -1 || st.preconditioner < 0 ||
        st.preconditioner > 3)
      OutOfRange("a step record");
    CheckStepStatus(static_cast<int>(st.status));
    if (static_cast<int>(st.pcg_status) < 0 || static_cast<int>(st.pcg_status) > static_cast<int>(PcgStatus::kTimeLimit))
      OutOfRange("a PCG status");
  }
}

/// A row's run: DecodeRun into a MethodRun.
inline MethodRun DecodeRun(std::string_view bytes, long n_particles) {
  MethodRun m;
  DecodeRun(bytes, n_particles, &m);
  return m;
}

}  // namespace clothbench

#endif  // CLOTHBENCH_HARNESS_RUN_CODEC_H_
