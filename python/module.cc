// The Python module `clothbench` (pybind11): load a scene, run any registry
// row by its command-line name, get the run as numpy arrays. The runs go
// through the same harness as bench_integrators (harness/methods.h), so a
// row's positions are bit-identical to the command line's.
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>
#include <csignal>
#include <chrono>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <type_traits>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <toml++/toml.h>

#include "harness/bench_sweep.h"
#include "harness/cli_args.h"
#include "harness/methods.h"
#include "harness/reference.h"
#include "harness/output_lock.h"
#include "harness/result_writer.h"
#include "harness/run_request.h"
#include "model/output_file.h"
#include "model/interrupt.h"
#include "model/obstacle.h"
#include "model/particle_system.h"
#include "model/scene.h"
#include "results/contained_read.h"
#include "results/metrics.h"
#include "results/result_reader.h"
#include "results/run_records.h"
#include "results/scale_verdict.h"
#include "results/work_precision.h"
#include "solver/progress.h"

namespace py = pybind11;

namespace clothbench {
namespace {

// SIGINT/SIGTERM while clothbench computes in Python: Python's own handler
// only trips a flag that the interpreter checks between bytecodes, which a
// long step or setup (with the GIL released, or on a worker thread) never
// reaches. For the call's lifetime this handler records the signal for the
// C++ loops (model/interrupt.h: the PCG's, VBD's, PD's and XPBD's
// iterations and the step loops end at it) and then calls Python's, so that
// the call ends with KeyboardInterrupt. Nested and concurrent calls share one
// installation (counted); the last one out restores Python's handler and
// clears the recorded signal.
class InterruptScope {
 public:
  InterruptScope() {
    const std::lock_guard<std::mutex> guard(Mutex());
    if (Count()++ > 0) return;
    for (int k = 0; k < 2; ++k) {
      const int sig = k == 0 ? SIGINT : SIGTERM;
      struct sigaction mine {};
      mine.sa_sigaction = &InterruptScope::Handler;
      mine.sa_flags = SA_SIGINFO | SA_ONSTACK;
      sigemptyset(&mine.sa_mask);
      installed()[k] = ::sigaction(sig, &mine, &previous()[k]) == 0;
    }
  }
  ~InterruptScope() {
    const std::lock_guard<std::mutex> guard(Mutex());
    if (--Count() > 0) return;
    for (int k = 0; k < 2; ++k)
      if (installed()[k]) ::sigaction(k == 0 ? SIGINT : SIGTERM, &previous()[k], nullptr);
    internal::g_interrupt_signal.store(0, std::memory_order_relaxed);
  }
  InterruptScope(const InterruptScope&) = delete;
  InterruptScope& operator=(const InterruptScope&) = delete;

 private:
  static void Handler(int sig, siginfo_t* info, void* context) {
    RequestInterrupt(sig);
    const struct sigaction& prev = previous()[sig == SIGINT ? 0 : 1];
    if (prev.sa_flags & SA_SIGINFO) {
      if (prev.sa_sigaction) prev.sa_sigaction(sig, info, context);
    } else if (prev.sa_handler != SIG_DFL && prev.sa_handler != SIG_IGN && prev.sa_handler) {
      prev.sa_handler(sig);
    }
  }
  static std::mutex& Mutex() {
    static std::mutex m;
    return m;
  }
  static int& Count() {
    static int n = 0;
    return n;
  }
  static struct sigaction* previous() {
    static struct sigaction p[2];
    return p;
  }
  static bool* installed() {
    static bool b[2] = {false, false};
    return b;
  }
};


// Sets the dotted key `path` ("material.density"; "obstacle.0.held": the first
// table of an array of tables) in `table` to a Python
// scalar or list of numbers, creating tables on the way.
void SetKey(toml::table& table, const std::string& path, const py::handle& value) {
  toml::node* node = &table;
  std::string rest = path;
  for (std::size_t dot; (dot = rest.find('.')) != std::string::npos; rest = rest.substr(dot + 1)) {
    const std::string key = rest.substr(0, dot);
    if (toml::array* a = node->as_array()) {  // an array of tables: "obstacle.0.held"
      const bool digits = !key.empty() && key.size() < 10 && key.find_first_not_of("0123456789") == std::string::npos;
      if (!digits || std::stoul(key) >= a->size())
        throw py::value_error(fmt::format("override \"{}\": \"{}\" is not an index of its {} tables", path, key, a->size()));
      node = a->get(std::stoul(key));
    } else {
      toml::table* t = node->as_table();
      if (!t->contains(key)) t->insert(key, toml::table{});
      node = t->get(key);
    }
    if (!node->is_table() && !node->is_array_of_tables())
      throw py::value_error("override \"" + path + "\": \"" + key + "\" is not a table");
  }
  toml::table* t = node->as_table();
  if (!t) throw py::value_error("override \"" + path + "\": an index of an array of tables must be followed by a key");
  // A Python int beyond 64 bits: ValueError naming the key, not pybind11's cast error.
  const auto integer = [&path](const py::handle& x) {
    int overflow = 0;
    const long long v = PyLong_AsLongLongAndOverflow(x.ptr(), &overflow);
    if (overflow != 0) throw py::value_error("override \"" + path + "\": an integer beyond 64 bits");
    return static_cast<int64_t>(v);
  };
  if (py::isinstance<py::bool_>(value)) t->insert_or_assign(rest, value.cast<bool>());
  else if (py::isinstance<py::int_>(value)) t->insert_or_assign(rest, integer(value));
  else if (py::isinstance<py::float_>(value)) t->insert_or_assign(rest, value.cast<double>());
  else if (py::isinstance<py::str>(value)) t->insert_or_assign(rest, value.cast<std::string>());
  else if (py::isinstance<py::list>(value) || py::isinstance<py::tuple>(value)) {
    toml::array a;
    for (const py::handle& x : value) {
      if (py::isinstance<py::str>(x)) a.push_back(x.cast<std::string>());
      else if (py::isinstance<py::bool_>(x)) a.push_back(x.cast<bool>());
      else if (py::isinstance<py::int_>(x)) a.push_back(integer(x));
      else if (py::isinstance<py::float_>(x)) a.push_back(x.cast<double>());
      else throw py::type_error("override \"" + path + "\": a list of numbers or strings is expected");
    }
    t->insert_or_assign(rest, std::move(a));
  } else {
    throw py::type_error("override \"" + path + "\": a bool, number, string or list is expected");
  }
}

// A built-in name, a file path, or TOML text (if it contains a newline or
// '='), with dotted-key overrides.
Scene MakeScene(const std::string& what, const py::dict& overrides, const py::object& particles) {
  const InterruptScope interrupts;  // Ctrl-C reaches a large grid's setup
  const bool text = what.find('\n') != std::string::npos || what.find('=') != std::string::npos;
  Scene s = text ? ParseScene(what, "<python>") : LoadSceneOrBuiltin(what);
  if (!particles.is_none()) {
    if (!py::isinstance<py::int_>(particles) || py::isinstance<py::bool_>(particles))
      throw py::type_error("particles: an int expected");
    int overflow = 0;
    const long long n = PyLong_AsLongLongAndOverflow(particles.ptr(), &overflow);
    if (overflow != 0 || n < 4 || static_cast<double>(n) > kMaxParticles)
      throw py::value_error(fmt::format("particles: {} must be a whole number of particles from 4 to {:g}",
                                        py::str(particles).cast<std::string>().substr(0, 40), kMaxParticles));
    s = RefineGrid(s, static_cast<long>(n));
  }
  if (overrides.empty()) return s;
  toml::table t = toml::parse(s.toml);
  for (const auto& [k, v] : overrides) {
    if (!py::isinstance<py::str>(k))
      throw py::type_error(fmt::format("overrides: key {} must be a dotted key string ('material.density')",
                                       py::repr(k).cast<std::string>().substr(0, 40)));
    SetKey(t, k.cast<std::string>(), v);
  }
  std::ostringstream os;
  os << t;
  return ParseScene(os.str(), s.source + " (with overrides)");
}

py::array_t<double> Frames(const std::vector<MatrixN3>& frames, int n) {
  py::array_t<double> a({static_cast<py::ssize_t>(frames.size()), static_cast<py::ssize_t>(n), py::ssize_t{3}});
  auto m = a.mutable_unchecked<3>();
  for (std::size_t f = 0; f < frames.size(); ++f)
    for (int p = 0; p < n; ++p)
      for (int c = 0; c < 3; ++c) m(static_cast<py::ssize_t>(f), p, c) = frames[f](p, c);
  return a;
}

py::array StepStatsArray(const std::vector<StepRecord>& steps) {
  py::list names, formats, offsets;
  for (const StepRecordField& c : StepRecordFields()) {
    names.append(c.name);
    formats.append(c.is_double ? "f8" : "i4");
    offsets.append(c.offset);
  }
  py::dict spec;
  spec["names"] = names;
  spec["formats"] = formats;
  spec["offsets"] = offsets;
  spec["itemsize"] = sizeof(StepRecord);
  const py::module_ np = py::module_::import("numpy");
  py::array a = np.attr("zeros")(steps.size(), np.attr("dtype")(spec));
  if (a.itemsize() != static_cast<py::ssize_t>(sizeof(StepRecord))) throw std::logic_error("step_stats dtype");
  if (!steps.empty()) std::memcpy(a.mutable_data(), steps.data(), steps.size() * sizeof(StepRecord));
  return a;
}

// Installed for every run: between steps, at most every 50 ms of wall time
// (and at t_end), takes the GIL, lets Python run its signal handlers
// (PyErr_CheckSignals: Ctrl-C raises KeyboardInterrupt) and calls a Python
// `progress(t, t_end)` if one was given, at most every 0.2 s. An exception
// either raises stops the run after the current step and is raised again
// by run().
class PythonProgress : public ProgressSink {
 public:
  PythonProgress(py::object callback, double t_end) : callback_(std::move(callback)), t_end_(t_end) {}
  PythonProgress(const PythonProgress&) = delete;
  PythonProgress& operator=(const PythonProgress&) = delete;
  void Update(double t) override {
    const auto now = std::chrono::steady_clock::now();
    if (t < t_end_ && now - last_check_ < std::chrono::milliseconds(50)) return;
    last_check_ = now;
    py::gil_scoped_acquire gil;
    if (PyErr_CheckSignals() != 0) {
      error_ = std::make_unique<py::error_already_set>();
      throw Stopped();
    }
    if (callback_.is_none() || (t < t_end_ && now - last_call_ < std::chrono::milliseconds(200))) return;
    last_call_ = now;
    try {
      callback_(t, t_end_);
    } catch (py::error_already_set& e) {
      error_ = std::make_unique<py::error_already_set>(std::move(e));
      throw Stopped();
    }
  }
  struct Stopped : std::runtime_error {
    Stopped() : std::runtime_error("the run was stopped from Python") {}
  };
  // The process' sink while it lives (taken under g_run_mutex).
  struct Installed {
    explicit Installed(PythonProgress* sink) { SetProgressSink(sink); }
    ~Installed() { SetProgressSink(nullptr); }
    Installed(const Installed&) = delete;
    Installed& operator=(const Installed&) = delete;
  };
  // Re-raises the exception that stopped the run (KeyboardInterrupt or the callback's).
  void RethrowError() {
    if (error_) throw std::move(*error_);
  }

 private:
  py::object callback_;
  double t_end_;
  std::chrono::steady_clock::time_point last_check_{}, last_call_{};
  std::unique_ptr<py::error_already_set> error_;
};

// run() and reference() compute one at a time: the progress sink and the
// OpenMP thread count are the process'. A second thread's call waits here
// with the GIL released.
std::mutex g_run_mutex;

// The Python value of keyword `name` as T, or nullopt for None.
// @throws py::type_error naming the keyword and the type expected
template <class T>
std::optional<T> Arg(const py::object& value, const char* name) {
  if (value.is_none()) return std::nullopt;
  const auto refuse = [&](const char* what) {
    return py::type_error(fmt::format("{}: {} expected, got {}", name, what,
                                      py::str(py::type::of(value).attr("__name__")).cast<std::string>()));
  };
  if constexpr (std::is_same_v<T, std::string>) {
    if (!py::isinstance<py::str>(value)) throw refuse("a str");
    return value.cast<std::string>();
  } else if constexpr (std::is_same_v<T, long>) {
    if (py::isinstance<py::bool_>(value) || !py::isinstance<py::int_>(value)) throw refuse("an int");
    try {
      return value.cast<long>();
    } catch (const py::cast_error&) {
      throw py::value_error(fmt::format("{}: {} is out of range", name, py::str(value).cast<std::string>()));
    }
  } else {
    if (py::isinstance<py::bool_>(value) || !(py::isinstance<py::float_>(value) || py::isinstance<py::int_>(value)))
      throw refuse("a number");
    return value.cast<double>();
  }
}

// A scene argument: a name, a path or TOML text (str) with overrides, or a
// Scene from load_scene(). @throws py::type_error naming `name`
Scene SceneArg(const py::object& scene, const py::object& overrides, const char* name = "scene") {
  if (!overrides.is_none() && !py::isinstance<py::dict>(overrides))
    throw py::type_error("overrides: a dict of dotted keys expected");
  const py::dict o = overrides.is_none() ? py::dict() : overrides.cast<py::dict>();
  if (py::isinstance<py::str>(scene)) return MakeScene(scene.cast<std::string>(), o, py::none());
  if (py::isinstance<Scene>(scene)) {
    if (!o.empty()) throw py::value_error("overrides: give them to load_scene() for a Scene object");
    return scene.cast<Scene>();
  }
  throw py::type_error(fmt::format("{}: a scene name, path, TOML text or Scene expected", name));
}

// The record behind a dict from run() or reference(). @throws ValueError naming `name`
template <class Record>
std::shared_ptr<Record> RecordOf(const py::object& d, const char* name, const char* from) {
  if (!py::isinstance<py::dict>(d))
    throw py::type_error(fmt::format("{}: a dict returned by clothbench.{}() expected", name, from));
  if (!d.cast<py::dict>().contains("record"))
    throw py::value_error(fmt::format("{}: a dict returned by clothbench.{}() expected (this one has no record)", name,
                                      from));
  try {
    return d.cast<py::dict>()["record"].cast<std::shared_ptr<Record>>();
  } catch (const py::cast_error&) {
    throw py::type_error(fmt::format("{}: a dict returned by clothbench.{}() expected", name, from));
  }
}

// A RunRecord (a row of a result file, or its reference) as a dict: its
// id, every field of RunRecordFields() under its attribute name (optional
// values are None) and the run's method attributes under theirs.
py::dict RecordDict(const RunRecord& r) {
  py::dict d;
  d["id"] = r.id;
  for (const RecordField& field : RunRecordFields())
    std::visit(
        [&](auto member) {
          const auto& v = r.*member;
          using T = std::remove_cvref_t<decltype(v)>;
          if constexpr (std::is_same_v<T, std::optional<double>>)
            d[field.name] = v ? py::cast(*v) : py::none();
          else if constexpr (std::is_same_v<T, StepKind> || std::is_same_v<T, RunStatus>)
            d[field.name] = std::string(ToString(v));
          else
            d[field.name] = v;
        },
        field.member);
  for (const auto& attribute : r.method_attributes)
    std::visit([&](const auto& v) { d[py::str(attribute.first)] = v; }, attribute.second);
  return d;
}

// Argument `name` as a real array of `ndim` dimensions, the last of size 3
// (N×3 positions, or F×N×3 frames), every value finite, as doubles.
// @throws TypeError for a non-array or a non-real dtype, ValueError naming
//   `name` for another shape or a NaN/Inf value
py::array_t<double, py::array::c_style> RealArrayArg(const py::object& value, const char* name, int ndim) {
  const py::module_ np = py::module_::import("numpy");
  const py::array a = np.attr("asarray")(value);
  const char kind = a.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u')
    throw py::type_error(fmt::format("{}: an array of real numbers expected (dtype {})", name,
                                     py::str(a.dtype()).cast<std::string>()));
  if (a.ndim() != ndim || a.shape(ndim - 1) != 3)
    throw py::value_error(fmt::format("{}: an {} array expected (shape {})", name, ndim == 2 ? "N×3" : "F×N×3",
                                      py::str(py::tuple(a.attr("shape"))).cast<std::string>()));
  const auto d = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
  if (!d) throw py::type_error(fmt::format("{}: cannot be read as doubles", name));
  const double* v = d.data();
  for (py::ssize_t k = 0; k < d.size(); ++k)
    if (!std::isfinite(v[k]))
      throw py::value_error(fmt::format("{}: element {} is {} (every value must be finite)", name, k, v[k]));
  return d;
}

// Argument `name`, an N×3 array (RealArrayArg), as MatrixN3 (copied).
MatrixN3 MatrixArg(const py::object& value, const char* name) {
  const auto a = RealArrayArg(value, name, 2);
  MatrixN3 m(a.shape(0), 3);
  auto r = a.unchecked<2>();
  for (py::ssize_t p = 0; p < a.shape(0); ++p)
    for (int c = 0; c < 3; ++c) m(p, c) = r(p, c);
  return m;
}

// obstacle_distances(scene, times, positions): per frame and particle the
// signed distance [m] to the nearest obstacle of the scene at that time
// (Obstacle::SignedDistance, negative inside), its unit direction and the
// obstacle's index. @throws TypeError/ValueError naming times or positions
py::dict ObstacleDistances(const Scene& scene, const py::object& times_arg, const py::object& positions_arg) {
  const auto x = RealArrayArg(positions_arg, "positions", 3);
  const py::module_ np = py::module_::import("numpy");
  const auto times = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(np.attr("asarray")(times_arg));
  if (!times || times.ndim() != 1 || times.shape(0) != x.shape(0))
    throw py::value_error(fmt::format("times: a 1-D array of one time per frame expected ({} frames)", x.shape(0)));
  for (py::ssize_t k = 0; k < times.shape(0); ++k)
    if (!std::isfinite(times.at(k))) throw py::value_error(fmt::format("times: element {} is not finite", k));
  if (scene.obstacles.empty()) throw py::value_error("scene: it has no obstacle");
  std::vector<Obstacle> obstacles;
  for (const ObstacleSpec& spec : scene.obstacles) obstacles.emplace_back(spec);
  const py::ssize_t frames = x.shape(0), n = x.shape(1);
  py::array_t<double> distance({frames, n}), direction({frames, n, py::ssize_t{3}});
  py::array_t<int> nearest({frames, n});
  auto xr = x.unchecked<3>();
  auto dr = distance.mutable_unchecked<2>();
  auto nr = direction.mutable_unchecked<3>();
  auto kr = nearest.mutable_unchecked<2>();
  for (py::ssize_t f = 0; f < frames; ++f)
    for (py::ssize_t p = 0; p < n; ++p) {
      const Vector3 point(xr(f, p, 0), xr(f, p, 1), xr(f, p, 2));
      dr(f, p) = std::numeric_limits<double>::infinity();
      kr(f, p) = -1;
      for (std::size_t k = 0; k < obstacles.size(); ++k) {
        Vector3 d = Vector3::Zero();
        const double value = obstacles[k].SignedDistance(times.at(f), point, &d);
        if (value >= dr(f, p)) continue;
        dr(f, p) = value;
        kr(f, p) = static_cast<int>(k);
        for (int c = 0; c < 3; ++c) nr(f, p, c) = d(c);
      }
    }
  py::dict out;
  out["distance"] = distance;
  out["direction"] = direction;
  out["obstacle"] = nearest;
  return out;
}

// run(reference=d): the arrays d holds must be the record's, which run()
// compares against: finite, of its shape and unchanged since reference()
// returned them. @throws ValueError naming reference["<key>"]
void CheckReferenceArrays(const py::dict& d, const RunSummary& ref) {
  for (const char* key : {"positions", "velocities"}) {
    if (!d.contains(key)) continue;
    const std::string name = fmt::format("reference[\"{}\"]", key);
    const auto a = RealArrayArg(d[key], name.c_str(), 3);
    const std::vector<MatrixN3>& frames =
        std::string(key) == "positions" ? ref.trajectory.positions : ref.trajectory.velocities;
    const py::ssize_t n = frames.empty() ? 0 : static_cast<py::ssize_t>(frames.front().rows());
    if (a.shape(0) != static_cast<py::ssize_t>(frames.size()) || a.shape(1) != n)
      throw py::value_error(fmt::format("{}: shape ({}, {}, 3) is not the reference run's ({}, {}, 3)", name,
                                        a.shape(0), a.shape(1), frames.size(), n));
    auto r = a.unchecked<3>();
    for (py::ssize_t f = 0; f < a.shape(0); ++f)
      for (py::ssize_t p = 0; p < n; ++p)
        for (int c = 0; c < 3; ++c)
          if (r(f, p, c) != frames[static_cast<std::size_t>(f)](p, c))
            throw py::value_error(fmt::format("{}: frame {} differs from the reference run's (run() compares "
                                              "against the run reference() computed; pass its dict unchanged)",
                                              name, f));
  }
}

// Runs one row. `method` is a command-line row name ("sbdf2",
// "bdf2/newton", "sbdf2/error", "arkode/ark4", "cvode/klu", "xpbd");
// `h` [s] for fixed-step and substepped rows, `rtol` for adaptive ones.
// Every argument is validated as a RunRequest (harness/run_request.h), the
// same rules and text as the command line's, before anything is computed.
py::dict Run(const py::object& scene_arg, const py::object& method, const py::object& h, const py::object& rtol,
             const py::object& substeps, const py::object& iterations, const py::object& cg_tolerance, const py::object& preconditioner,
             const py::object& tangent_terms, const py::object& t_end, const py::object& overrides,
             const py::object& progress, const py::object& reference, const py::object& repeat,
             const py::object& time_budget, const py::object& time_limit, const py::object& self_contact,
             const py::kwargs& settings) {
  const InterruptScope interrupts;  // Ctrl-C reaches the loops inside a step and the setup
  RunRequest q;
  q.scene = SceneArg(scene_arg, overrides);
  const std::optional<std::string> name = Arg<std::string>(method, "method");
  if (!name) throw py::type_error("method: a str expected, got NoneType");
  q.method = *name;
  q.h = Arg<double>(h, "h");
  q.rtol = Arg<double>(rtol, "rtol");
  q.substeps = Arg<long>(substeps, "substeps");
  q.iterations = Arg<long>(iterations, "iterations");
  q.cg_tolerance = Arg<double>(cg_tolerance, "cg_tolerance");
  q.preconditioner = Arg<std::string>(preconditioner, "preconditioner");
  q.tangent_terms = Arg<std::string>(tangent_terms, "tangent_terms");
  // The methods' own settings (MethodSetting: arkode_table, cvode_setting), by keyword.
  for (const auto& [key, value] : settings) {
    const std::string field = py::str(key);
    if (!FindSetting(field)) throw py::type_error(fmt::format("run() got an unexpected keyword argument '{}'", field));
    if (std::optional<std::string> v = Arg<std::string>(py::reinterpret_borrow<py::object>(value), field.c_str()))
      q.settings.emplace_back(field, std::move(*v));
  }
  q.self_contact = Arg<std::string>(self_contact, "self_contact");
  q.t_end = Arg<double>(t_end, "t_end");
  q.repeat = Arg<long>(repeat, "repeat");
  q.time_budget = Arg<double>(time_budget, "time_budget").value_or(30.0);
  q.time_limit = Arg<double>(time_limit, "time_limit").value_or(RunLimits().time_limit_s);
  if (!progress.is_none() && !PyCallable_Check(progress.ptr()))
    throw py::type_error("progress: a callable progress(t, t_end) expected");
  std::shared_ptr<RunSummary> ref;
  if (!reference.is_none()) {
    ref = RecordOf<RunSummary>(reference, "reference", "reference");
    const py::dict d = reference.cast<py::dict>();
    if (!d.contains("scene_hash")) throw py::type_error("reference: a dict returned by clothbench.reference() expected");
    q.reference_scene = d["scene_hash"].cast<std::string>();
    CheckReferenceArrays(d, *ref);
  }
  const ResolvedRun run = q.Resolve();  // UsageError: ValueError naming the keyword
  const ParticleSystem sys(run.scene);
  auto record = std::make_shared<MethodRun>();
  MethodRun& r = *record;
  {
    PythonProgress sink(progress, run.scene.t_end);
    try {
      py::gil_scoped_release release;
      const std::lock_guard<std::mutex> one_at_a_time(g_run_mutex);
      const PythonProgress::Installed installed(&sink);
      const auto once = [&] { return run.row.Run(sys, run.scene, run.spec, run.param, run.ctx, run.count); };
      r = once();
      // Repetitions as bench_integrators' (--repeat, --time-budget); the
      // progress callback follows each timing.
      double budget = q.time_budget;
      RepeatTimings(&r, static_cast<int>(q.repeat.value_or(0)), &budget, once);
    } catch (const PythonProgress::Stopped&) {
      sink.RethrowError();
      throw;
    }
  }
  std::vector<MethodRun> one;  // errors and energies as the result file has them
  one.push_back(std::move(r));
  CompareToReference(sys, ref.get(), run.scene.t_end, ErrorMetric::kFinal, &one);
  r = std::move(one.front());
  if (ref && r.ok() && !r.err)
    throw py::value_error("reference: its frames do not match the run's (the same scene and t_end?)");
  const int n = sys.num_particles();
  py::dict out = RecordDict(r);  // the attributes a result file stores for the run (error_* None without reference)
  out["times"] = py::array_t<double>(static_cast<py::ssize_t>(r.trajectory.times.size()), r.trajectory.times.data());
  out["positions"] = Frames(r.trajectory.positions, n);
  out["velocities"] = Frames(r.trajectory.velocities, n);
  out["step_stats"] = StepStatsArray(StepRecords(r));
  py::dict energy;  // the series a result file stores under /runs/<id>/energy
  for (const EnergyField& field : EnergySeriesFields())
    if (field.Stored(r.energy)) energy[field.name] = r.energy.*field.member;
  out["energy"] = energy;
  // Scenes with [collision]: each frame's crossing triangle pairs and, with
  // the response on, its counters (as /runs/<id>/crossing_pairs and self_contact).
  if (!r.trajectory.crossing_pairs.empty())
    out["crossing_pairs"] = py::array_t<int32_t>(static_cast<py::ssize_t>(r.trajectory.crossing_pairs.size()),
                                                 r.trajectory.crossing_pairs.data());
  if (r.self_contact) {
    const SelfContactStats& st = *r.self_contact;
    py::dict sc;
    for (const auto& [name, v] : st.Counts()) sc[name] = v;
    sc["detection_s"] = st.detection_seconds;
    sc["response_s"] = st.response_seconds;
    sc["work_J"] = st.work;
    out["self_contact"] = sc;
  }
  out["scene_hash"] = SceneHash(run.scene);
  out["record"] = record;  // for write_results
  return out;
}


// The reference run of `method` ("cvode", "cvode/klu", "ida", "ida/klu") at
// `rtol` [-], as --reference does (RunReference, with its error estimate at
// rtol/10): validated as the request of that row at that rtol, t_end and
// scene.
py::dict Reference(const py::object& scene_arg, const py::object& method, const py::object& rtol,
                   const py::object& t_end, const py::object& overrides) {
  const InterruptScope interrupts;  // Ctrl-C reaches the loops inside a step and the setup
  RunRequest q;
  q.scene = SceneArg(scene_arg, overrides);
  const std::string name = Arg<std::string>(method, "method").value_or(std::string(DefaultReference()));
  try {
    ParseReference(name, "method");
  } catch (const std::invalid_argument& e) {
    throw py::value_error(EscapeControl(e.what()));
  }
  q.method = name;
  q.rtol = Arg<double>(rtol, "rtol").value_or(1e-10);
  q.t_end = Arg<double>(t_end, "t_end");
  const ResolvedRun run = q.Resolve();
  const ParticleSystem sys(run.scene);
  auto record = std::make_shared<RunSummary>();
  RunSummary& r = *record;
  {
    PythonProgress sink(py::none(), run.scene.t_end);
    try {
      py::gil_scoped_release release;
      const std::lock_guard<std::mutex> one_at_a_time(g_run_mutex);
      const PythonProgress::Installed installed(&sink);
      r = RunReference(sys, run.scene, run.row, run.param, run.ctx, DefaultErrorMetric(run.scene));
    } catch (const PythonProgress::Stopped&) {
      sink.RethrowError();
      throw;
    }
  }
  NameReference(run.scene, &r);
  py::dict out = RecordDict(r);  // the attributes a result file stores for /runs/reference
  out["method"] = name;
  out["scene_hash"] = SceneHash(run.scene);
  out["record"] = record;  // for run(reference=...) and write_results
  out["step_stats"] = StepStatsArray(StepRecords(r));
  out["times"] = py::array_t<double>(static_cast<py::ssize_t>(r.trajectory.times.size()), r.trajectory.times.data());
  out["positions"] = Frames(r.trajectory.positions, sys.num_particles());
  out["velocities"] = Frames(r.trajectory.velocities, sys.num_particles());
  return out;
}

// Writes the result file `path` (docs/guide/results-schema.md) of `runs` (dicts
// from run(), in table order, all on `scene`) and `reference` (a dict from
// reference(), or None), as bench_integrators writes it: errors, observed
// orders and the equal-accuracy table at `targets` [m] against the
// reference. Under `<path>.lock`, through a temporary renamed at the end;
// a path that exists as anything but a regular file is refused.
void WriteResultFile(const py::object& path_arg, const py::object& scene_arg, const py::object& runs_arg,
                     const py::object& reference, const py::object& frames_arg, const py::object& targets_arg,
                     const py::object& baseline_arg, const py::object& error_metric_arg) {
  const std::optional<std::string> path = Arg<std::string>(path_arg, "path");
  if (!path || path->empty()) throw py::type_error("path: a non-empty str expected");
  const std::optional<std::string> error_metric = Arg<std::string>(error_metric_arg, "error_metric");
  std::optional<ErrorMetric> metric;
  if (error_metric && !(metric = ParseErrorMetric(*error_metric)))
    throw py::value_error(fmt::format("error_metric: \"{}\" must be final, l2 or max", EscapeControl(*error_metric)));
  const Scene scene = SceneArg(scene_arg, py::none());
  if (!metric) metric = DefaultErrorMetric(scene);  // as bench_integrators without --error-metric
  const std::string frames = Arg<std::string>(frames_arg, "frames").value_or("default");
  {
    // The frames mode by the rule every entry point shares (harness/run_request.h).
    RunRequest frames_only;
    frames_only.scene = scene;
    frames_only.frames = frames;
    (void)frames_only.SweepScene();
  }
  const std::string baseline = Arg<std::string>(baseline_arg, "baseline").value_or(std::string(DefaultReference()));
  std::vector<double> targets = {1e-2, 1e-3, 1e-4};
  if (!targets_arg.is_none()) {
    if (!py::isinstance<py::sequence>(targets_arg) || py::isinstance<py::str>(targets_arg))
      throw py::type_error("targets: a list of numbers expected");
    targets.clear();
    for (const py::handle& t : targets_arg.cast<py::sequence>()) {
      const double v = *Arg<double>(py::reinterpret_borrow<py::object>(t), "targets");
      if (!std::isfinite(v) || !(v > 0.0)) throw py::value_error(fmt::format("targets: {:g} m is not positive", v));
      targets.push_back(v);
    }
  }
  if (!py::isinstance<py::list>(runs_arg) && !py::isinstance<py::tuple>(runs_arg))
    throw py::type_error("runs: a list of dicts returned by clothbench.run() expected");
  const std::string hash = SceneHash(scene);
  std::vector<MethodRun> rows;
  for (const py::handle& d : runs_arg.cast<py::sequence>()) {
    const py::object run = py::reinterpret_borrow<py::object>(d);
    rows.push_back(*RecordOf<MethodRun>(run, "runs", "run"));
    const MethodRun& q = rows.back();
    const py::dict dict = run.cast<py::dict>();
    if (!q.trajectory.positions.empty() && q.trajectory.positions.front().rows() != scene.num_particles())
      throw py::value_error(fmt::format("runs: {} has {} particles, the scene {}", q.id,
                                        q.trajectory.positions.front().rows(), scene.num_particles()));
    if (!dict.contains("scene_hash") || dict["scene_hash"].cast<std::string>() != hash)
      throw py::value_error(fmt::format("runs: {} was computed on another scene, t_end or frame spacing than `scene`",
                                        q.id));
  }
  std::optional<RunSummary> ref;
  if (!reference.is_none()) {
    ref = *RecordOf<RunSummary>(reference, "reference", "reference");
    const py::dict d = reference.cast<py::dict>();
    if (!d.contains("scene_hash") || d["scene_hash"].cast<std::string>() != hash)
      throw py::value_error("reference: was computed on another scene, t_end or frame spacing than `scene`");
  }
  const ParticleSystem sys(scene);
  OutputLock lock(*path, /*journal_folder=*/true, "path");  // UsageError: ValueError naming path
  py::gil_scoped_release release;
  CompareToReference(sys, ref ? &*ref : nullptr, scene.t_end, *metric, &rows);
  // reference() estimates its error in the scene's default metric: known for that one only.
  const double reference_error = ref && *metric == DefaultErrorMetric(scene) ? ref->error_estimate_m : -1.0;
  const EqualAccuracyTable wp = WorkPrecision(rows, targets, baseline, *metric, reference_error);
  const RunTable table = MakeRunTable(scene, sys, ref, rows, frames, ref ? &wp : nullptr, *metric);
  WriteResults(*path, scene, sys, ref, rows, table, 1);
}

// An equal-accuracy table as a dict: targets, labels, cost, ratio,
// upper_bound, tied, min_error (per method; None where every run failed),
// fastest (labels; None where no method reaches a target) and baseline.
py::dict EqualAccuracyDict(const EqualAccuracyTable& t) {
  py::dict out;
  out["targets"] = t.targets;
  out["labels"] = t.labels;
  out["cost"] = t.cost;
  out["ratio"] = t.ratio;
  out["upper_bound"] = t.upper_bound;
  out["tied"] = t.tied;
  out["min_error"] = t.min_error;
  std::vector<std::optional<std::string>> fastest;
  for (int k : t.fastest) fastest.push_back(k >= 0 ? std::optional(t.labels[static_cast<std::size_t>(k)]) : std::nullopt);
  out["fastest"] = fastest;
  out["baseline"] = t.reference;
  out["unresolved"] = t.unresolved;
  out["stop_reasons"] = t.stop_reasons;
  out["reference_error_m"] = t.reference_error_m >= 0.0 ? py::object(py::float_(t.reference_error_m)) : py::none();
  return out;
}

// A --sizes file's verdict as a dict: sizes, targets, labels, error_metric,
// result_files, and per size and target fastest, runner_up (labels or
// None), margin (or None) and cost_s ({label: solver time [s]}).
py::dict ScaleVerdictDict(const ScaleVerdict& v) {
  const auto label = [&](int m) { return m >= 0 ? py::object(py::str(v.labels[static_cast<std::size_t>(m)])) : py::none(); };
  py::dict d;
  d["sizes"] = v.sizes;
  d["targets"] = v.targets;
  d["labels"] = v.labels;
  d["error_metric"] = v.metric;
  d["result_files"] = v.result_files;
  py::list fastest, runner, margin, cost;
  for (std::size_t i = 0; i < v.sizes.size(); ++i) {
    py::list f, r, g, c;
    for (std::size_t j = 0; j < v.targets.size(); ++j) {
      f.append(label(v.fastest[i][j]));
      r.append(label(v.runner_up[i][j]));
      g.append(v.margin[i][j] ? py::object(py::float_(*v.margin[i][j])) : py::none());
      py::dict per;
      for (std::size_t m = 0; m < v.labels.size(); ++m)
        if (v.cost[i][j][m]) per[py::str(v.labels[m])] = *v.cost[i][j][m];
      c.append(per);
    }
    fastest.append(f);
    runner.append(r);
    margin.append(g);
    cost.append(c);
  }
  d["fastest"] = fastest;      // [size][target] label or None
  d["runner_up"] = runner;
  d["margin"] = margin;        // [size][target] runner-up cost / fastest cost, or None
  d["cost_s"] = cost;          // [size][target] {label: solver time [s]} of the methods with a number
  return d;
}

// A result file's records (ReadRunTable): provenance, scene, the reference
// and every run as dicts of their attributes, and the equal-accuracy table.
py::dict ReadResultFile(const std::string& path) {
  CheckReadableInChild(path);  // a file that crashes the HDF5 library: ValueError, not a dead interpreter
  const ResultReader reader(path);
  const RunTable t = ValidateResultFile(reader);
  py::dict out;
  out["schema"] = t.schema;
  out["git_commit"] = t.git_commit;
  out["created"] = t.created;
  py::dict scene;  // every /scene attribute (SceneRecordFields), solver_* without the prefix
  for (const SceneField& field : SceneRecordFields())
    std::visit([&](auto member) { scene[py::str(std::string(field.key()))] = t.*member; }, field.member);
  out["scene"] = scene;
  out["reference"] = t.reference ? py::object(RecordDict(*t.reference)) : py::none();
  py::list runs;
  for (const RunRecord& r : t.runs) runs.append(RecordDict(r));
  out["runs"] = runs;
  out["work_precision"] = t.work_precision ? py::object(EqualAccuracyDict(*t.work_precision)) : py::none();
  if (reader.Exists("/scale_verdict")) out["scale_verdict"] = ScaleVerdictDict(ReadScaleVerdict(reader));
  return out;
}

// The default run's parameters of a row: h [s] or rtol values.
std::vector<double> DefaultParamsOf(const py::object& scene_arg, const std::string& method) {
  const Scene scene = py::isinstance<py::str>(scene_arg) ? MakeScene(scene_arg.cast<std::string>(), py::dict(), py::none())
                                                         : scene_arg.cast<Scene>();
  const std::vector<RowMethod> rows = ExpandMethods({method}, {scene.solver.nonlinear_solver}, "method");
  const DefaultParams d = DefaultRowParams(rows.front());
  if (SpecOf(rows.front().kind()).adaptive()) return d.rtols;
  std::vector<double> h;
  for (double f : d.h_factors) h.push_back(f * scene.h);
  return h;
}

// The equal-accuracy table (docs/notes/work-precision.md) of {label: [(cost, e_rms), ...]}.
py::dict EqualAccuracy(const std::vector<std::pair<std::string, std::vector<std::pair<double, double>>>>& runs,
                       const std::vector<double>& targets, const std::string& baseline) {
  std::vector<std::string> labels;
  std::vector<std::vector<WorkPoint>> points;
  for (const auto& [label, pts] : runs) {
    labels.push_back(label);
    points.emplace_back();
    for (const auto& [cost, err] : pts) points.back().push_back({cost, err});
  }
  return EqualAccuracyDict(BuildEqualAccuracyTable(labels, points, targets, baseline));
}

}  // namespace
}  // namespace clothbench

PYBIND11_MODULE(clothbench, m) {
  using namespace clothbench;
  m.doc() = "clothbench: the integrators of implicit cloth simulation (Hauth 2004) and their peers, from Python";
  // Opaque handles kept in run() and reference() dicts for write_results.
  py::class_<MethodRun, std::shared_ptr<MethodRun>>(m, "RunRecord");
  py::class_<RunSummary, std::shared_ptr<RunSummary>>(m, "ReferenceRun");
  py::class_<Scene>(m, "Scene")
      .def_readonly("name", &Scene::name)
      .def_readonly("t_end", &Scene::t_end)
      .def_readonly("h", &Scene::h)
      .def_readonly("toml", &Scene::toml)
      .def_property_readonly("num_particles", &Scene::num_particles);
  m.def("load_scene", &MakeScene, py::arg("scene"), py::arg("overrides") = py::dict(),
        py::arg("particles") = py::none(),
        "A built-in scene by name, a TOML file, or TOML text; `particles` refines its grid to about that many "
        "particles, as bench_integrators --sizes does (sheet, material per unit length and area, constraints and "
        "t_end kept; docs/model.md, Resolution); `overrides` then sets dotted keys ({'material.density': 0.2}). "
        "Raises ValueError (SceneError) on bad input.");
  m.def("methods", [] {
    std::vector<std::string> names;
    for (const MethodEntry& e : Registry()) names.emplace_back(e.name);
    return names;
  });
  m.def("run", &Run, py::arg("scene"), py::arg("method"), py::arg("h") = py::none(), py::arg("rtol") = py::none(),
        py::arg("substeps") = py::none(), py::arg("iterations") = py::none(), py::arg("cg_tolerance") = py::none(), py::arg("preconditioner") = py::none(),
        py::arg("tangent_terms") = py::none(), py::arg("t_end") = py::none(), py::arg("overrides") = py::none(),
        py::arg("progress") = py::none(), py::arg("reference") = py::none(), py::arg("repeat") = py::none(),
        py::arg("time_budget") = py::none(), py::arg("time_limit") = py::none(), py::arg("self_contact") = py::none(),
        "Runs one row as bench_integrators does (the GIL released). Every argument is checked first, by the rules "
        "of the command line (harness/run_request.h): ValueError or TypeError naming the keyword. An option the row "
        "does not read (rtol of a fixed-step row, substeps of a row that takes none, ...) is refused. Returns a dict: "
        "times [F], positions and velocities [F, N, 3], step_stats (structured array), counts, times, status, "
        "energies, and with reference= (a dict from reference() on the same scene and t_end) error_final_m, "
        "error_l2_m, error_max_m (and _mps for the velocities). progress(t, t_end) is called at most every 0.2 s; "
        "an exception it raises, or Ctrl-C (KeyboardInterrupt: within 0.2 s inside the iterations, as a library call "
        "returns in a setup), stops the run and is raised "
        "again. The run is timed `repeat` times (None: 3 if the first takes under 2 s, else 1, within "
        "time_budget seconds, default 30), each later timing reproducing the end state bit for bit: solver_time_s "
        "is the least, with solver_time_s_median, solver_time_s_max and repeats. time_limit [s] (default 3600) "
        "ends a run with status time_limit. run() and reference() may be called from several threads; they "
        "compute one at a time (a process-wide lock, waited on with the GIL released). A method's own settings are "
        "keywords too (setting_names()), refused for a row that does not read them."),
  m.def("setting_names", [] {
    std::vector<std::string> names;
    for (const RowOption& o : RowOptions())
      if (FindSetting(o.field)) names.push_back(o.field);
    return names;
  }, "The keywords of the methods' own settings that run() takes (each method's MethodEntry::settings).");
  m.def("write_results", &WriteResultFile, py::arg("path"), py::arg("scene"), py::arg("runs"),
        py::arg("reference") = py::none(), py::arg("frames") = py::none(), py::arg("targets") = py::none(),
        py::arg("baseline") = py::none(), py::arg("error_metric") = py::none(),
        "Writes runs (dicts from run(), in table order, on scene) and the reference (a dict from reference()) "
        "as the HDF5 result file bench_integrators writes (docs/guide/results-schema.md), under <path>.lock and "
        "through a temporary file renamed at the end. error_metric: final | l2 | max (default: l2 on scenes with "
        "obstacles, final otherwise, as bench_integrators). ValueError for a path that is not a regular file (a "
        "link, device, FIFO or folder, or its temporary <path>.tmp is one), is an input read in this process, or "
        "is being written by another process, and for runs or a reference of another scene; ResultError (a "
        "ValueError) naming the system's reason, such as 'No space left on device', if the file cannot be "
        "written."),
  m.def("read_results", &ReadResultFile, py::arg("path"),
        "A result file's records: schema, scene, reference and runs (dicts of their attributes) and the "
        "equal-accuracy table (work_precision); for a bench_integrators --sizes file also scale_verdict (sizes, "
        "targets, labels, fastest, runner_up, margin and cost_s per size and target). Arrays: read the file with "
        "h5py.");
  m.def("check_output", [](const std::string& path, const std::string& option, const std::vector<std::string>& others) {
    CheckOutputTarget(path, option, others);
  }, py::arg("path"), py::arg("option"), py::arg("others") = std::vector<std::string>{},
        "Refuses an output path as every writer of the project does (model/output_file.h, CheckOutputTarget): "
        "ValueError '<option>: \"<path>\" <rule>' for a link, device, FIFO or folder at the path or at its "
        "temporary, an input of this process, one of `others`, or a lock, journal or temporary of clothbench. "
        "scripts/report checks its page with it.");
  m.def("reference", &Reference, py::arg("scene"), py::arg("method") = std::string(DefaultReference()),
        py::arg("rtol") = 1e-10, py::arg("t_end") = py::none(), py::arg("overrides") = py::none(),
        fmt::format("The reference run (method: {}; without /klu the reduced velocity solve, with /klu KLU; "
        "as --reference, with its error estimate error_estimate_m against the same at rtol/10): the attributes a "
        "result file stores for /reference (the same record keys as run()'s dict: status, steps, rtol, atol, ...), "
        "times, positions, "
        "velocities, step_stats, and the scene_hash that run() and write_results() compare with their scene's.",
        ReferenceNames()).c_str());  // pybind11 copies the text
  m.def("obstacle_distances", &ObstacleDistances, py::arg("scene"), py::arg("times"), py::arg("positions"),
        "Per frame and particle the signed distance [m] to the scene's nearest obstacle at that frame's time "
        "(negative inside; the model's own query, meshes included), its unit direction and the obstacle's index: "
        "a dict of distance [F, N], direction [F, N, 3] and obstacle [F, N]. times [F] and positions [F, N, 3] as "
        "run() returns them. TypeError/ValueError naming the argument; ValueError for a scene without obstacles.");
  m.def("row_param", [](const std::string& method) {
    const std::vector<RowMethod> rows = ExpandMethods({method}, {NonlinearSolver::kFixedPoint}, "method");
    return std::string(SpecOf(rows.front().kind()).param);
  }, py::arg("method"),
        "The keyword of run() that a row's default_params are for: \"h\" (fixed-step, substepped and iterated rows) "
        "or \"rtol\" (adaptive rows, */error). ValueError for an unknown row.");
  m.def("default_params", &DefaultParamsOf, py::arg("scene"), py::arg("method"),
        "The default run's h list [s] (fixed-step and substepped rows) or rtol list (adaptive rows) of a row.");
  m.def("error_rms", [](const py::object& x, const py::object& ref) {
    const MatrixN3 a = MatrixArg(x, "x"), b = MatrixArg(ref, "ref");
    if (a.rows() != b.rows())
      throw py::value_error(fmt::format("ref: {} rows, x has {} (the same particles expected)", b.rows(), a.rows()));
    if (a.rows() == 0) throw py::value_error("x: no particles (an N×3 array with N ≥ 1 expected)");
    return ErrorRms(a, b);
  }, py::arg("x"), py::arg("ref"),
        "e_rms = sqrt((1/N) sum_p |x_p - ref_p|^2) [m] of two N×3 arrays of the same N. TypeError for a "
        "non-real array, ValueError (naming x or ref) for another shape, N = 0 or a NaN/Inf value.");
  m.def("equal_accuracy", &EqualAccuracy, py::arg("runs"), py::arg("targets") = std::vector<double>{1e-2, 1e-3, 1e-4},
        py::arg("baseline") = std::string(DefaultReference()),
        "The equal-accuracy table of runs = [(label, [(solver_time_s, e_rms_m), ...]), ...] (runs in the order "
        "of decreasing h or rtol): cost and ratio per label and target (None where the runs do not bracket it), "
        "and the fastest label per target.");
  // Ctrl-C noticed inside the C++ (InterruptScope): KeyboardInterrupt, as
  // Python's own handler would raise it.
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const Interrupted&) {
      if (PyErr_CheckSignals() == 0 && !PyErr_Occurred()) PyErr_SetNone(PyExc_KeyboardInterrupt);
    }
  });
  py::register_exception<SceneError>(m, "SceneError", PyExc_ValueError);
  py::register_exception<ResultError>(m, "ResultError", PyExc_ValueError);
}
