// lgvi._core: the compiled half of the Python package `lgvi` (pybind11 +
// numpy). It runs the CLI's own run loop, app::simulate() from lgvi_app, so
// that a scenario gives the same numbers to the last bit from Python and
// from `lgvi run`. The public API (argument checking with messages naming
// the argument, Result objects, plotting) is the pure-Python layer in
// python/lgvi; this module is private to it.
//
// Quaternions cross this boundary scalar-first, (w, x, y, z), as numpy
// arrays of shape (4,).
//
// The GIL: released while a run with a built-in potential integrates; held
// throughout when the potential is written in Python (every evaluation calls
// into the interpreter). Either way Ctrl-C (SIGINT) is noticed every 4096
// steps and stops the run at a step boundary with KeyboardInterrupt.

#include "io/memory_sink.hpp"
#include "app/ensemble.hpp"
#include "io/formats/registry.hpp"
#include "app/interactions/registry.hpp"
#include "app/method_registry.hpp"
#include "app/scenario.hpp"
#include "app/simulation.hpp"
#include "app/summary.hpp"
#include "io/toml_writer.hpp"

#include <lgvi/error.hpp>
#include <lgvi/forcing.hpp>
#include <lgvi/integrate.hpp>
#include <lgvi/lgvi.hpp>
#include <lgvi/potential.hpp>
#include <lgvi/rigid_body.hpp>
#include <lgvi/s3.hpp>
#include <lgvi/state.hpp>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <variant>
#include <vector>

namespace py = pybind11;

namespace lgvi::app {
namespace {

// ---------------------------------------------------------------------------
// numpy conversions

py::array_t<double> array3(const Vector3<double>& v) {
  py::array_t<double> a(3);
  double* d = a.mutable_data();
  d[0] = v.x();
  d[1] = v.y();
  d[2] = v.z();
  return a;
}

/// Scalar-first (w, x, y, z).
py::array_t<double> quaternion_array(const S3d& q) {
  py::array_t<double> a(4);
  double* d = a.mutable_data();
  d[0] = q.w();
  d[1] = q.vec().x();
  d[2] = q.vec().y();
  d[3] = q.vec().z();
  return a;
}

py::array_t<double> matrix_array(const Matrix3<double>& m) {
  py::array_t<double> a({3, 3});
  auto r = a.mutable_unchecked<2>();
  for (py::ssize_t i = 0; i < 3; ++i)
    for (py::ssize_t j = 0; j < 3; ++j) r(i, j) = m(i, j);
  return a;
}

/// The arrays of(b) of shape `shape` of bodies b < n stacked on a leading body axis, (n, shape...); with
/// `single_face`, one body's array as it is (the single-body face: (3,), not (1, 3)).
template <class Of>
py::array_t<double> stacked(std::size_t n, std::vector<py::ssize_t> shape, bool single_face, Of&& of) {
  if (single_face && n == 1) return of(std::size_t{0});
  py::ssize_t per_body = 1;
  for (const py::ssize_t d : shape) per_body *= d;
  shape.insert(shape.begin(), static_cast<py::ssize_t>(n));
  py::array_t<double> a(shape);
  for (std::size_t b = 0; b < n; ++b) {
    const py::array_t<double> one = of(b);
    std::copy_n(one.data(), per_body, a.mutable_data() + per_body * static_cast<py::ssize_t>(b));
  }
  return a;
}

/// One vector per body: (3,) for one body (the single-body face), (N, 3) for N.
py::array_t<double> body_vectors(const std::vector<Vector3<double>>& v) {
  return stacked(v.size(), {3}, true, [&v](std::size_t b) { return array3(v[b]); });
}

void make_read_only(py::array& a) {
  py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
}

std::string shape_text(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

using Numbers = py::array_t<double, py::array::c_style | py::array::forcecast>;

/// `obj` as float64 numbers of shape (n,) (or (n, n) with `matrix`), all
/// finite unless `any_value`; ValueError naming `name` otherwise.
Numbers numbers(py::handle obj, const std::string& name, py::ssize_t n, bool matrix = false, bool any_value = false) {
  Numbers a = Numbers::ensure(obj);
  const std::string want = matrix ? "(" + std::to_string(n) + ", " + std::to_string(n) + ")"
                                  : "(" + std::to_string(n) + ",)";
  if (!a) throw py::value_error(name + ": must be numbers of shape " + want + ", got " +
                                std::string(py::str(py::type::handle_of(obj).attr("__name__"))) + " " +
                                std::string(py::repr(obj)));
  const bool ok = matrix ? (a.ndim() == 2 && a.shape(0) == n && a.shape(1) == n) : (a.ndim() == 1 && a.shape(0) == n);
  if (!ok) throw py::value_error(name + ": must have shape " + want + ", got shape " + shape_text(a));
  for (py::ssize_t i = 0; i < a.size() && !any_value; ++i)
    if (!std::isfinite(a.data()[i])) throw py::value_error(name + ": must be finite, got " + std::string(py::repr(obj)));
  return a;
}

/// A Python number, a numpy scalar or a 0-d array, as a double; ValueError
/// "NAME must be a number ..." otherwise. An array with dimensions is
/// refused, shape (1,) too: numpy (>= 1.25) deprecates float() of such
/// arrays, and one is usually a slip (x[:1] for x[0]).
double number(py::handle v, const std::string& name) {
  if (py::isinstance<py::array>(v) && py::reinterpret_borrow<py::array>(v).ndim() > 0)
    throw py::value_error(name + " must be a number (a float or a 0-d array), got an array of shape " +
                          std::string(py::str(v.attr("shape"))) + "; float(a[0]) if its element is meant");
  const double d = PyFloat_AsDouble(v.ptr());
  if (d == -1.0 && PyErr_Occurred()) {
    PyErr_Clear();
    throw py::value_error(name + " must be a number, got " + std::string(py::repr(v)));
  }
  return d;
}

/// `obj` as finite float64 numbers of shape (n, width); ValueError naming `name` otherwise.
Numbers body_rows(py::handle obj, const std::string& name, py::ssize_t n, py::ssize_t width) {
  Numbers a = Numbers::ensure(obj);
  const std::string want = "(" + std::to_string(n) + ", " + std::to_string(width) + "), one row per body";
  if (!a) throw py::value_error(name + ": must be numbers of shape " + want + ", got " + std::string(py::repr(obj)));
  if (!(a.ndim() == 2 && a.shape(0) == n && a.shape(1) == width))
    throw py::value_error(name + ": must have shape " + want + ", got shape " + shape_text(a));
  for (py::ssize_t i = 0; i < a.size(); ++i)
    if (!std::isfinite(a.data()[i]))
      throw py::value_error(name + "[" + std::to_string(i / width) + "]: must be finite, got " +
                            std::to_string(a.data()[i]));
  return a;
}

Vector3<double> vec3(py::handle obj, const std::string& name, bool any_value = false) {
  const Numbers a = numbers(obj, name, 3, false, any_value);
  return {a.data()[0], a.data()[1], a.data()[2]};
}

/// A unit quaternion, scalar-first; within 1e-6 of unit norm, then
/// normalized as the scenario reader does (or, with `normalize` false, taken
/// as given: a state from a trajectory, whose |q| - 1 is round-off).
S3d unit_quaternion(py::handle obj, const std::string& name, bool normalize = true) {
  const Numbers a = numbers(obj, name, 4);
  const double* d = a.data();
  try {
    const S3d checked = S3d::from_quaternion_checked(d[0], d[1], d[2], d[3]);
    return normalize ? checked : S3d(d[0], d[1], d[2], d[3]);
  } catch (const InvalidInput& e) {
    throw py::value_error(name + ": " + e.what());
  }
}

/// The trajectory rows as a (rows, columns) float64 array owning the vector
/// (21 columns for a single-body scenario, 26 in the long layout).
py::array_t<double> rows_array(std::vector<double>&& data, std::int64_t rows, int columns = trajectory_columns) {
  if (rows == 0) return py::array_t<double>(std::vector<py::ssize_t>{0, columns});
  auto* heap = new std::vector<double>(std::move(data));
  py::capsule owner(heap, [](void* p) { delete static_cast<std::vector<double>*>(p); });
  return py::array_t<double>({static_cast<py::ssize_t>(rows), py::ssize_t{columns}},
                             {py::ssize_t{columns} * py::ssize_t{sizeof(double)}, py::ssize_t{sizeof(double)}},
                             heap->data(), owner);
}

// ---------------------------------------------------------------------------
// A potential written in Python

/// Calls Python: either one callable (x, q) -> (energy, force, torque), or
/// three callables energy(x, q), force(x, q), torque(x, q). x is the centre
/// of mass (3,), q the attitude, scalar-first (w, x, y, z) (4,), both
/// read-only float64 arrays; force is -dV/dx (inertial frame) and torque the
/// body-frame torque M (F(q) dV/dq = -2 M). The GIL must be held.
class PythonPotential {
 public:
  explicit PythonPotential(py::object spec) {
    if (py::isinstance<py::tuple>(spec) && py::len(spec) == 3) {
      py::tuple t = spec.cast<py::tuple>();
      energy_ = t[0];
      force_ = t[1];
      torque_ = t[2];
      for (const auto& [f, name] : {std::pair{&energy_, "energy"}, {&force_, "force"}, {&torque_, "torque"}})
        if (!PyCallable_Check(f->ptr()))
          throw py::value_error(std::string("potential: ") + name + " must be callable as " + name + "(x, q)");
    } else if (PyCallable_Check(spec.ptr())) {
      combined_ = spec;
    } else {
      throw py::value_error(
          "potential: must be a PythonPotential, a callable (x, q) -> (energy, force, torque), or None for the "
          "scenario's own; got " +
          std::string(py::repr(spec)));
    }
  }

  /// Non-finite values are returned as they are: the integrator reports
  /// them as a failed step, naming the step.
  PotentialEvaluation operator()(const Vector3<double>& x, const S3d& q) const {
    py::array xa = array3(x), qa = quaternion_array(q);
    make_read_only(xa);
    make_read_only(qa);
    PotentialEvaluation e;
    if (combined_) {
      const py::object r = combined_(xa, qa);
      if (!(py::isinstance<py::tuple>(r) || py::isinstance<py::list>(r)) || py::len(r) != 3)
        throw py::value_error("potential: must return (energy, force, torque), got " + std::string(py::repr(r)));
      const py::sequence s = r.cast<py::sequence>();
      e.energy = number(s[0], "potential: the returned energy");
      e.force = vec3(s[1], "potential: the returned force", true);
      e.torque = vec3(s[2], "potential: the returned torque", true);
    } else {
      e.energy = number(energy_(xa, qa), "potential: the returned energy");
      e.force = vec3(force_(xa, qa), "potential: the returned force", true);
      e.torque = vec3(torque_(xa, qa), "potential: the returned torque", true);
    }
    return e;
  }

 private:
  py::object combined_, energy_, force_, torque_;
};

CallablePotential make_python_potential(py::object spec) { return CallablePotential(PythonPotential(std::move(spec))); }

/// The scenario with a Python forcing added: `forcing` is None (the scenario
/// as it is) or a tuple (f, body name or None, velocity_dependent) from
/// lgvi.PythonForcing, f(t, x, q, p, w) -> (force, torque), force inertial,
/// torque in the body frame, q scalar-first.
Scenario with_python_forcing(const Scenario& sc, py::object forcing) {
  if (forcing.is_none()) return sc;
  // A Python forcing may read any body's rate, which it is given as a rigid body's: refused with wheels
  // anywhere in the scenario (the reader refuses only the rate-reading kinds, and per body).
  if (sc.system.has_wheels())
    throw py::value_error("forcing: a scenario with reaction wheels takes no Python forcing (it would read the "
                          "body's rate as a rigid body's, not the gyrostat's)");
  const py::tuple spec = forcing.cast<py::tuple>();
  py::object f = spec[0];
  if (!PyCallable_Check(f.ptr())) throw py::value_error("forcing: must be callable as f(t, x, q, p, w)");
  std::size_t body = lgvi::ForcingSet::all_bodies;
  if (!spec[1].is_none()) {
    const std::string name = spec[1].cast<std::string>();
    body = sc.system.index_of(name);
    if (body == sc.system.size()) throw py::value_error("forcing: body: no body is named \"" + name + "\"");
  }
  Scenario out = sc;
  auto call = [f](double t, std::size_t, const RigidBodyState& s) {
    py::array xa = array3(s.x), qa = quaternion_array(s.q), pa = array3(s.p), wa = array3(s.w);
    for (py::array* a : {&xa, &qa, &pa, &wa}) make_read_only(*a);
    const py::object r = f(t, xa, qa, pa, wa);
    if (!(py::isinstance<py::tuple>(r) || py::isinstance<py::list>(r)) || py::len(r) != 2)
      throw py::value_error("forcing: must return (force, torque), got " + std::string(py::repr(r)));
    const py::sequence seq = r.cast<py::sequence>();
    return lgvi::Wrench{vec3(seq[0], "forcing: the returned force", true),
                        vec3(seq[1], "forcing: the returned torque", true)};
  };
  out.forcing.add(lgvi::CallableForcing{call, spec[2].cast<bool>()}, body);
  return out;
}

// ---------------------------------------------------------------------------
// TOML text of the package's documents (scenarios and sweeps built in Python),
// by the CLI's writer (io/toml_writer.hpp): one writer, whatever wrote the file.

toml::table toml_table(const py::dict& d, bool inline_subtables);

/// A TOML value as built from Python (toml_value).
using TomlValue = std::variant<bool, std::int64_t, double, std::string, toml::array, toml::table>;

/// A str as UTF-8; what Python raises (UnicodeEncodeError, a ValueError) for a lone surrogate.
std::string utf8(py::handle s) {
  Py_ssize_t size = 0;
  const char* data = PyUnicode_AsUTF8AndSize(s.ptr(), &size);
  if (!data) throw py::error_already_set();
  return {data, static_cast<std::size_t>(size)};
}

/// A Python value as TOML: bool, int (64 bits; ValueError beyond), float,
/// str, list or tuple (an array; of tables, [[key]], when every element is a
/// dict), dict (a table, inline when `inline_table`); TypeError otherwise, as
/// json.dumps refuses what it cannot write, and RecursionError for a list or
/// dict that holds itself.
TomlValue toml_value(py::handle v, bool inline_table) {
  struct Depth {
    Depth() {
      if (Py_EnterRecursiveCall(" while writing TOML") != 0) throw py::error_already_set();
    }
    ~Depth() { Py_LeaveRecursiveCall(); }
    Depth(const Depth&) = delete;
    Depth& operator=(const Depth&) = delete;
  } depth;
  if (PyBool_Check(v.ptr())) return v.ptr() == Py_True;
  if (PyLong_Check(v.ptr())) {
    int overflow = 0;
    const long long i = PyLong_AsLongLongAndOverflow(v.ptr(), &overflow);
    if (overflow != 0)
      throw py::value_error("cannot write " + std::string(py::repr(v)) + " as TOML: an integer beyond 64 bits");
    return static_cast<std::int64_t>(i);
  }
  if (PyFloat_Check(v.ptr())) return PyFloat_AsDouble(v.ptr());
  if (PyUnicode_Check(v.ptr())) return utf8(v);
  if (PyDict_Check(v.ptr())) {
    toml::table t = toml_table(v.cast<py::dict>(), true);
    t.is_inline(inline_table);
    return t;
  }
  if (PyList_Check(v.ptr()) || PyTuple_Check(v.ptr())) {
    const py::sequence seq = v.cast<py::sequence>();
    bool of_tables = seq.size() > 0;
    for (const py::handle e : seq) of_tables = of_tables && PyDict_Check(e.ptr());
    toml::array a;
    for (const py::handle e : seq) std::visit([&a](auto&& x) { a.push_back(std::move(x)); }, toml_value(e, !of_tables));
    return a;
  }
  throw py::type_error("cannot write " + std::string(py::repr(v)) + " as TOML");
}

/// The dict as a TOML table; its dict values inline tables when `inline_subtables` (every table but the
/// document: a scenario's [initial] orbit = { ... }).
toml::table toml_table(const py::dict& d, bool inline_subtables) {
  toml::table t;
  for (const auto item : d) {
    if (!PyUnicode_Check(item.first.ptr()))
      throw py::type_error("cannot write the key " + std::string(py::repr(item.first)) + " as TOML (keys are str)");
    const std::string key = utf8(item.first);
    std::visit([&](auto&& x) { t.insert_or_assign(key, std::move(x)); }, toml_value(item.second, inline_subtables));
  }
  return t;
}

// ---------------------------------------------------------------------------
// Type-erased steppers

/// The Python Stepper's view of a method: the system's state, advanced by the
/// same N-body stepper as simulate() builds.
class AnyStepper {
 public:
  virtual ~AnyStepper() = default;
  virtual void initialize(SystemState& s) = 0;
  /// Steps `s` from step k towards k_end (time k h) with the run loop's
  /// integrate_range, asking `stop` before each step; `k` counts the steps
  /// taken. On a failure (IntegrationFailure, or what a Python potential or
  /// forcing raised) `s` and `k` are the last good step's.
  virtual void advance(SystemState& s, std::int64_t& k, std::int64_t k_end, double h,
                       const std::function<bool()>& stop) = 0;
  virtual const SystemEvaluation& evaluation() const = 0;
  virtual SolveReport last_solve() const = 0;
  virtual std::vector<double> internal_state() const = 0;
  virtual void resume(SystemState& s, const std::vector<double>& internal) = 0;
  /// The forcing's work since initialize (0 without forcing).
  virtual double work() const = 0;
};

template <class S>
class StepperModel final : public AnyStepper {
 public:
  StepperModel(S&& s, std::shared_ptr<std::int64_t> evaluations)
      : s_(std::move(s)), evaluations_(std::move(evaluations)) {}
  void initialize(SystemState& s) override {
    s_.initialize(s, 0.0);
    eval_ = s_.evaluation();
  }
  void advance(SystemState& s, std::int64_t& k, std::int64_t k_end, double h,
               const std::function<bool()>& stop) override {
    // integrate_range leaves the last good state in `s` on a failure.
    integrate_range(s_, s, 0.0, h, k, k_end, [&k](const SystemStepInfo& i) { k = i.k; }, stop);
    eval_ = s_.evaluation();
  }
  const SystemEvaluation& evaluation() const override { return eval_; }
  SolveReport last_solve() const override { return s_.last_solve(); }
  std::vector<double> internal_state() const override { return s_.internal_state(); }
  double work() const override { return lgvi::detail::forcing_work(s_); }
  void resume(SystemState& s, const std::vector<double>& internal) override {
    s_.resume(s, 0.0, internal);
    eval_ = s_.evaluation();
  }

 private:
  S s_;
  std::shared_ptr<std::int64_t> evaluations_;  // the system potential counts into it
  SystemEvaluation eval_;
};

/// The stepper of the scenario's method for its system potential, as
/// simulate() builds it (scenario_system_potential), with `field` (a Python
/// potential) in place of its [potential] when given.
std::unique_ptr<AnyStepper> make_stepper(const Scenario& sc, const CallablePotential* field) {
  if (sc.integrator.adaptive())
    throw py::value_error("scenario: Stepper takes fixed steps (its t is k h); this scenario has [integrator] "
                          "time_transform = \"potential\" (use lgvi.simulate, which runs it)");
  if (sc.system.has_wheels())
    throw py::value_error("scenario: Stepper steps rigid bodies' states (x, q, p, w); this scenario has reaction "
                          "wheels ([[body.wheel]]), whose momenta it does not hold yet (use lgvi.simulate, which "
                          "runs it)");
  auto evaluations = std::make_shared<std::int64_t>(0);
  // The same method table as the CLI's run loop (app/method_registry.hpp).
  return lgvi::app::with_stepper(
      sc, lgvi::app::scenario_system_potential(sc, field, evaluations.get()), lgvi::app::scenario_parallelism(sc),
      [&](auto& stepper) -> std::unique_ptr<AnyStepper> {
        return std::make_unique<StepperModel<std::decay_t<decltype(stepper)>>>(std::move(stepper), evaluations);
      });
}

// ---------------------------------------------------------------------------
// simulate

/// Checks for Ctrl-C between legs of a run (simulate() calls `progress`
/// every `progress_every` steps); a pending KeyboardInterrupt (or whatever a
/// Python signal handler raised) stops the run and is re-raised afterwards.
struct InterruptWatch {
  volatile std::sig_atomic_t stop = 0;
  std::shared_ptr<py::error_already_set> pending;

  void install(SimulationOptions& o) {
    o.stop_flag = &stop;
    o.progress_every = 4096;
    o.progress = [this](std::int64_t, double) {
      py::gil_scoped_acquire gil;
      if (PyErr_CheckSignals() != 0) {
        pending = std::make_shared<py::error_already_set>();
        stop = 1;
      }
    };
  }
};

/// The scenario with a Python control law in place of its wheel controller's PD law (WheelAttitudeControl::
/// set_law): M = control(t, q, omega, wheel_speeds), q and omega what the law sees (the sensors' readings),
/// the wheels' speeds relative to the body; M body axes (3,).
Scenario with_python_control(const Scenario& sc, py::object control) {
  if (control.is_none()) return sc;
  if (!PyCallable_Check(control.ptr())) throw py::value_error("control: must be callable as f(t, q, omega, wheel_speeds)");
  if (!sc.wheel_control)
    throw py::value_error("control: a control law drives the reaction wheels of a scenario with [[forcing]] kind = "
                          "\"attitude-control\" and actuator = \"wheels\" (its period, max_torque and split apply)");
  Scenario out = sc;
  out.wheel_control->set_law([control](double t, const lgvi::AttitudeMeasurement& m, const std::vector<double>& speeds) {
    py::array qa = quaternion_array(m.q), wa = array3(m.omega);
    py::array sa = py::array_t<double>(static_cast<py::ssize_t>(speeds.size()), speeds.data());
    for (py::array* a : {&qa, &wa, &sa}) make_read_only(*a);
    return vec3(control(t, qa, wa, sa), "control: the returned torque", true);
  });
  return out;
}

py::tuple run_simulation(const Scenario& scenario_in, py::object potential, py::object forcing, py::object control) {
  const Scenario scenario = with_python_control(scenario_in, control);
  // The reader checked that the adaptive step's field is gravity; a Python potential replaces it unchecked.
  if (scenario.integrator.adaptive() && !potential.is_none())
    throw py::value_error("potential: a scenario with time_transform = \"potential\" adapts its step to U = -V of "
                          "its own field (gravity, checked by the reader); run it with that field, or use "
                          "time_transform = \"none\" with a Python potential");
  Scenario sc = with_python_forcing(scenario, std::move(forcing));
  const bool python_forcing = sc.forcing.size() != scenario.forcing.size();
  // A Python forcing or control law is called with the GIL held, from this thread only: the run's
  // per-body loops on one thread (the results are the same on any number). A Python potential is
  // called so by scenario_system_potential.
  if (python_forcing || !control.is_none()) sc.threads = 1;
  const std::int64_t every = sc.output_every;
  const TrajectoryLayout layout = lgvi::app::scenario_layout(sc);
  // An adaptive run's steps are not known before it ends (steps is its max_steps): room for duration / epsilon.
  const std::int64_t steps = sc.integrator.adaptive()
                                 ? static_cast<std::int64_t>(std::ceil(sc.integrator.duration / sc.integrator.step))
                                 : sc.integrator.steps;
  MemorySink sink((steps / every + 2) * layout.rows_per_step(), layout);
  SimulationResult r;
  InterruptWatch watch;
  SimulationOptions opt;
  watch.install(opt);
  if (potential.is_none() && !python_forcing && control.is_none()) {
    py::gil_scoped_release release;
    r = simulate(sc, sink, opt);
  } else if (potential.is_none()) {
    r = simulate(sc, sink, opt);
  } else {
    const CallablePotential p = make_python_potential(potential);
    r = simulate(sc, p, sink, opt);
  }
  if (watch.pending) throw *watch.pending;
  const std::string summary = summary_json(sc, r);
  sink.close(sc.source_text, summary);
  const std::int64_t rows = sink.rows();
  // The side tables (SimulationResult::sensors, wheels), each as {file: (columns, rows x columns array)}.
  py::dict tables;
  for (SideTable* table : {&r.sensors, &r.wheels}) {
    if (table->columns.empty()) continue;
    const auto table_rows = static_cast<std::int64_t>(table->rows());
    tables[py::str(table->file)] = py::make_tuple(
        table->columns, rows_array(std::move(table->values), table_rows, static_cast<int>(table->columns.size())));
  }
  return py::make_tuple(rows_array(sink.take(), rows, layout.columns), summary, r.completed, r.error, tables,
                        layout.column_names());
}

// ---------------------------------------------------------------------------
// The stepping object

class PyStepper {
 public:
  PyStepper(const Scenario& sc, py::object potential, py::object forcing)
      : sc_(with_python_forcing(sc, std::move(forcing))), python_forcing_(sc_.forcing.size() != sc.forcing.size()) {
    if (python_forcing_) sc_.threads = 1;  // called with the GIL held, from this thread only
    set_potential_impl(std::move(potential));
    state_ = sc_.initial_state;
    initialize_at(state_, "initial state");
    energy0_ = energy();
    momentum0_ = angular_momentum(state_);
    linear_momentum0_ = linear_momentum(state_);
    for (const Vector3<double>& p : state_.p) linear_momentum_scale_ += p.norm();
  }

  void step(std::int64_t n) {
    require_idle();
    if (n < 0) throw py::value_error("n: must be >= 0, got " + std::to_string(n));
    if (python_ || python_forcing_ || n < 64) {
      advance(n);
      return;
    }
    // A built-in potential: without the GIL, in legs of 4096 steps with a
    // check for Ctrl-C between them. Meanwhile another Python thread is
    // refused the state (require_idle), which changes under it.
    struct Busy {
      std::atomic<bool>& flag;
      explicit Busy(std::atomic<bool>& f) : flag(f) { flag = true; }
      ~Busy() { flag = false; }
      Busy(const Busy&) = delete;
      Busy& operator=(const Busy&) = delete;
    } busy(busy_);
    for (std::int64_t done = 0; done < n;) {
      const std::int64_t leg = std::min<std::int64_t>(n - done, 4096);
      {
        py::gil_scoped_release release;
        advance(leg);
      }
      done += leg;
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
    }
  }

  /// Re-evaluates the potential at the current state (after the parameters
  /// of a Python potential changed), keeping the solver's warm start.
  void refresh() {
    require_idle();
    resume_at(state_, impl_->internal_state());
  }

  void set_potential(py::object potential) {
    require_idle();
    const std::vector<double> internal = impl_->internal_state();
    py::object old_object = python_object_;
    std::unique_ptr<AnyStepper> old = std::move(impl_);
    const bool old_python = python_;
    try {
      set_potential_impl(std::move(potential));
      resume_at(state_, internal);
    } catch (...) {
      impl_ = std::move(old);
      python_ = old_python;
      python_object_ = old_object;
      throw;
    }
  }

  /// Each part None (kept) or, for one body, shape (3,) ((4,) for q); for N
  /// bodies shape (N, 3) ((N, 4)), row a body a's.
  void set_state(py::object x, py::object q, py::object p, py::object w) {
    require_idle();
    SystemState s = state_;
    const std::size_t n = s.size();
    auto vectors = [n](py::handle obj, const std::string& name, std::vector<Vector3<double>>& out) {
      if (n == 1) {
        out[0] = vec3(obj, name);
        return;
      }
      const Numbers a = body_rows(obj, name, static_cast<py::ssize_t>(n), 3);
      for (std::size_t b = 0; b < n; ++b) out[b] = Vector3<double>(a.data() + 3 * b);
    };
    if (!x.is_none()) vectors(x, "position", s.x);
    if (!q.is_none()) {
      if (n == 1) {
        s.q[0] = unit_quaternion(q, "quaternion");
      } else {
        const Numbers a = body_rows(q, "quaternion", static_cast<py::ssize_t>(n), 4);
        for (std::size_t b = 0; b < n; ++b) {
          const double* d = a.data() + 4 * b;
          try {
            s.q[b] = S3d::from_quaternion_checked(d[0], d[1], d[2], d[3]);
          } catch (const InvalidInput& e) {
            throw py::value_error("quaternion[" + std::to_string(b) + "]: " + e.what());
          }
        }
      }
    }
    if (!p.is_none()) vectors(p, "momentum", s.p);
    if (!w.is_none()) {
      vectors(w, "w", s.w);
      // As the scenario reader: a linear body has no momentum about its axis
      // (a point none), beyond round-off, which is removed.
      for (std::size_t b = 0; b < n; ++b) {
        const RigidBody& body = sc_.system.body(b);
        if (!body.admits_momentum(s.w[b]))
          throw py::value_error((n == 1 ? std::string("w") : "w[" + std::to_string(b) + "]") + ": the body is " +
                                (body.rotational_dof() == 2 ? "linear: it has no angular momentum about its axis"
                                                            : "a point mass: it has no angular momentum; give w = 0"));
        s.w[b] = body.admissible_momentum(s.w[b]);
      }
    }
    // Refused there: the integrator is put back as it was at the current state.
    const std::vector<double> internal = impl_->internal_state();
    try {
      initialize_at(s, "state");
    } catch (...) {
      try {
        impl_->resume(state_, internal);
      } catch (...) {  // the current state was stepped to, so it evaluates; nothing better to do otherwise
      }
      throw;
    }
    state_ = std::move(s);
  }

  std::int64_t k() const {
    require_idle();
    return k_;
  }
  double t() const { return static_cast<double>(k()) * sc_.integrator.step; }
  double h() const { return sc_.integrator.step; }
  const SystemState& state() const {
    require_idle();
    return state_;
  }
  /// One quantity of each body's state in rotation-matrix form (state.hpp's project: Omega, x-dot).
  std::vector<Vector3<double>> projected(Vector3<double> RotationMatrixState::*quantity) const {
    require_idle();
    std::vector<Vector3<double>> v;
    for (std::size_t b = 0; b < state_.size(); ++b) v.push_back(project(state_.body(b), sc_.system.body(b)).*quantity);
    return v;
  }
  const SystemEvaluation& evaluation() const {
    require_idle();
    return impl_->evaluation();
  }
  double energy() const { return total_energy(state_, sc_.system, impl_->evaluation()); }
  double energy0() const { return energy0_; }
  /// The forcing's work since k = 0 (0 without forcing).
  double work() const {
    require_idle();
    return impl_->work();
  }
  const Vector3<double>& momentum0() const { return momentum0_; }
  const Scenario& scenario() const { return sc_; }
  SolveReport last_solve() const {
    require_idle();
    return impl_->last_solve();
  }
  bool python_potential() const { return python_; }

  /// The trajectory row simulate() would write at this step: one body's
  /// (SingleBodyRow); for a system its rows of the long format (one per body,
  /// through "work" when forced; not the thermodynamic columns).
  py::array_t<double> row() const {
    require_idle();
    const double e = energy();
    const Vector3<double> L = angular_momentum(state_);
    const bool forced = !sc_.forcing.empty();
    // With a forcing: E - E0 - W and the column "work", as simulate() writes them.
    const double de = forced ? e - energy0_ - work() : e - energy0_;
    if (sc_.layout == RowLayout::single_body) {
      const SingleBodyRow row(t(), state_.body(0), e, de, state_.q[0].norm_error(), L, (L - momentum0_).norm(),
                              forced ? std::optional(work()) : std::nullopt);
      py::array_t<double> a(row.columns);
      std::copy_n(row.values, row.columns, a.mutable_data());
      return a;
    }
    const Vector3<double> P = linear_momentum(state_);
    const SystemRowTotals totals{e, de, P, linear_momentum_error(P, linear_momentum0_, linear_momentum_scale_), L,
                                 (L - momentum0_).norm()};
    const double tail[1] = {forced ? work() : 0.0};
    const int columns = bodies_trajectory_columns + (forced ? 1 : 0);
    py::array_t<double> a({static_cast<py::ssize_t>(state_.size()), static_cast<py::ssize_t>(columns)});
    double buffer[bodies_trajectory_columns + 3];
    for (std::size_t b = 0; b < state_.size(); ++b) {
      system_row(t(), state_, b, totals, tail, forced ? 1 : 0, buffer);
      std::copy_n(buffer, columns, a.mutable_data() + static_cast<std::ptrdiff_t>(b) * columns);
    }
    return a;
  }

 private:
  void set_potential_impl(py::object potential) {
    if (potential.is_none()) {
      impl_ = make_stepper(sc_, nullptr);
      python_ = false;
      python_object_ = py::none();
    } else {
      const CallablePotential p = make_python_potential(potential);
      impl_ = make_stepper(sc_, &p);
      python_ = true;
      python_object_ = potential;
    }
  }

  void initialize_at(SystemState& s, const char* what) {
    try {
      impl_->initialize(s);
    } catch (const StepFailure& f) {
      throw py::value_error(std::string(what) + ": " + f.what() + (f.hint().empty() ? "" : "; " + f.hint()));
    }
  }

  void resume_at(SystemState& s, const std::vector<double>& internal) {
    try {
      impl_->resume(s, internal);
    } catch (const StepFailure& f) {
      throw py::value_error(std::string("potential at the current state: ") + f.what());
    }
  }

  /// n steps with the run loop's integrate_range, which leaves the last good
  /// state on a failure; the integrator is then re-initialized there. With
  /// Python in the loop, Ctrl-C is checked before every step.
  void advance(std::int64_t n) {
    const bool python = python_ || python_forcing_;
    const std::function<bool()> stop = [python] { return python && PyErr_CheckSignals() != 0; };
    const std::int64_t end = k_ + n;
    try {
      impl_->advance(state_, k_, end, sc_.integrator.step, stop);
    } catch (...) {  // IntegrationFailure, or an exception raised by a Python potential or forcing
      recover();
      throw;
    }
    if (k_ < end) throw py::error_already_set();  // Ctrl-C: PyErr_CheckSignals set KeyboardInterrupt
  }

  void recover() noexcept {
    try {
      impl_->initialize(state_);
    } catch (...) {  // the potential fails at the last good state too: nothing better to do
    }
  }

  /// RuntimeError while step() runs without the GIL in another thread.
  void require_idle() const {
    if (busy_) throw std::runtime_error("Stepper: step() is running in another thread; wait for it to return");
  }

  Scenario sc_;
  std::atomic<bool> busy_{false};  // step() without the GIL (require_idle)
  bool python_forcing_ = false;  // a Python forcing: the GIL stays held
  std::unique_ptr<AnyStepper> impl_;
  py::object python_object_ = py::none();
  bool python_ = false;
  SystemState state_;
  std::int64_t k_ = 0;
  double energy0_ = 0.0;
  Vector3<double> momentum0_ = Vector3<double>::Zero();
  Vector3<double> linear_momentum0_ = Vector3<double>::Zero();
  double linear_momentum_scale_ = 0.0;  // sum |p_a| at k = 0, as the run's statistics
};

// ---------------------------------------------------------------------------
// Bodies

RigidBody make_body(py::object mass, py::object inertia) {
  const double m = number(mass, "mass");
  const Numbers j = numbers(inertia, "inertia", 3, true);
  Matrix3<double> J;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) J(r, c) = j.data()[3 * r + c];
  return RigidBody(m, J);
}

RigidBody body_from_balls(const py::sequence& balls) {
  std::vector<Ball> v;
  for (std::size_t i = 0; i < balls.size(); ++i) {
    const std::string name = "balls[" + std::to_string(i) + "]";
    py::object b = balls[i];
    if (!(py::isinstance<py::tuple>(b) || py::isinstance<py::list>(b)) || (py::len(b) != 3 && py::len(b) != 4))
      throw py::value_error(name + ": must be (position, mass, radius) or (position, mass, radius, type)");
    const py::sequence s = b.cast<py::sequence>();
    Ball ball;
    ball.position = vec3(s[0], name + ".position");
    ball.mass = number(s[1], name + ".mass");
    ball.radius = number(s[2], name + ".radius");
    if (py::len(s) == 4) ball.type = s[3].cast<int>();
    v.push_back(ball);
  }
  return RigidBody::from_balls(std::move(v));
}

py::list balls_list(const RigidBody& b) {
  py::list out;
  for (const Ball& ball : b.balls()) {
    py::dict d;
    d["position"] = array3(ball.position);
    d["mass"] = ball.mass;
    d["radius"] = ball.radius;
    d["type"] = ball.type;
    out.append(d);
  }
  return out;
}

py::tuple evaluation_tuple(const PotentialEvaluation& e) {
  return py::make_tuple(e.energy, array3(e.force), array3(e.torque));
}

}  // namespace
}  // namespace lgvi::app

PYBIND11_MODULE(_core, m) {
  using namespace lgvi;
  using namespace lgvi::app;
  m.doc() =
      "lgvi._core: the compiled part of the Python package lgvi (private; use `import lgvi`).\n\n"
      "Runs the same compiled run loop as the `lgvi` command line, so results are bit-identical.\n"
      "Quaternions are scalar-first (w, x, y, z) numpy arrays of shape (4,).";
  m.attr("__version__") = LGVI_VERSION;
  m.attr("TRAJECTORY_HEADER") = trajectory_header;
  m.attr("BODIES_TRAJECTORY_HEADER") = lgvi::app::bodies_trajectory_header;
  m.attr("FORCED_TRAJECTORY_HEADER") = forced_trajectory_header;
  m.attr("FORCED_BODIES_TRAJECTORY_HEADER") = forced_bodies_trajectory_header;
  m.attr("THERMO_COLUMNS") = py::make_tuple(lgvi::app::temperature_column, lgvi::app::pressure_column);
  // The names the scenario reader accepts, from the tables it uses.
  py::list methods, solvers, formats, interactions;
  for (const lgvi::MethodTraits& t : Method::all()) methods.append(t.name);
  for (SolverKind k : {SolverKind::Newton, SolverKind::NewtonExp, SolverKind::Broyden}) solvers.append(to_string(k));
  // [output] format: every registered format (io/formats/registry.cpp), with its file in a run folder and
  // whether that file holds the trajectory's columns (lgvi.load reads it) or is an export for viewers.
  py::dict format_files;
  for (const lgvi::app::FormatDescriptor* d : lgvi::app::trajectory_formats()) {
    formats.append(std::string(d->name));
    format_files[py::str(std::string(d->name))] = py::make_tuple(std::string(d->file_name), d->holds_columns);
  }
  // [interaction] kind: "none" and every registered kind (app/interactions/registry.cpp), with the keys each takes.
  py::dict interaction_keys;
  interactions.append("none");
  interaction_keys["none"] = py::tuple();
  for (const lgvi::app::InteractionDescriptor* d : lgvi::app::interaction_kinds()) {
    py::list keys;
    for (std::string_view key : d->keys) keys.append(std::string(key));
    interactions.append(std::string(d->kind));
    interaction_keys[py::str(std::string(d->kind))] = py::tuple(keys);
  }
  m.attr("METHODS") = py::tuple(methods);
  m.attr("SOLVERS") = py::tuple(solvers);
  m.attr("FORMATS") = py::tuple(formats);
  m.attr("FORMAT_FILES") = format_files;
  m.attr("INTERACTIONS") = py::tuple(interactions);
  m.attr("INTERACTION_KEYS") = interaction_keys;

  // lgvi::IntegrationFailure -> IntegrationError(RuntimeError) with .step, .time and .result (None here).
  static py::exception<IntegrationFailure> integration_error(m, "IntegrationError", PyExc_RuntimeError);
  integration_error.doc() =
      "A step of the integration failed (the rotation equation has no root for this step, the solver did not "
      "converge, or a value became non-finite).\n\n"
      "Attributes: step (the index k of the failed step, from t_k to t_k+1), time (t_k), and result: for "
      "lgvi.simulate, the Result up to the last good step; None from Stepper.step().";
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const IntegrationFailure& e) {
      py::object type = integration_error;
      py::object inst = type(e.what());
      inst.attr("step") = e.step();
      inst.attr("time") = e.time();
      inst.attr("result") = py::none();
      PyErr_SetObject(type.ptr(), inst.ptr());
    }
  });

  py::class_<RigidBody>(m, "Body",
                        "A rigid body (C++ lgvi::RigidBody): mass, standard inertia J about the centre of mass in body "
                        "axes, and the uniform balls it is made of (if any). Validated on construction.")
      .def(py::init(&make_body), py::arg("mass"), py::arg("inertia"),
           "Body from mass m > 0 and the 3x3 inertia J (symmetric positive semi-definite, principal moments with "
           "J1 + J2 >= J3; a zero moment makes a linear body, J = 0 a point). ValueError naming `mass` or "
           "`inertia` otherwise.")
      .def_static("from_balls", &body_from_balls, py::arg("balls"),
                  "Body from a sequence of (position (3,), mass > 0, radius >= 0) uniform balls; positions are "
                  "shifted so that the centre of mass is the body origin.")
      .def_property_readonly("mass", &RigidBody::mass, "Total mass m.")
      .def_property_readonly("inertia", [](const RigidBody& b) { return matrix_array(b.inertia()); },
                             "Standard inertia J (3x3, body axes, about the centre of mass).")
      .def_property_readonly("inertia_inverse", [](const RigidBody& b) { return matrix_array(b.inertia_inverse()); },
                             "J^-1 (3x3); the pseudo-inverse for a linear body, 0 for a point.")
      .def_property_readonly("rotational_dof", &RigidBody::rotational_dof,
                             "Rotational degrees of freedom: 3, 2 for a linear body (point masses on one line: no "
                             "moment about it, no rotation about it), 0 for a point mass.")
      .def_property_readonly("linear_axis", [](const RigidBody& b) { return array3(b.linear_axis()); },
                             "A linear body's axis n (body frame, unit), J = I (1 - n n^T); zeros otherwise.")
      .def_property_readonly("balls", &balls_list,
                             "The balls as dicts {position (3,) relative to the centre of mass, mass, radius}; "
                             "empty for a body given by mass and inertia.")
      .def_static(
          "sphere", [](py::object mass, py::object radius) {
            return RigidBody::sphere(number(mass, "mass"), number(radius, "radius"));
          },
          py::arg("mass"), py::arg("radius"), "A uniform solid sphere: J = 2/5 m r^2 I.")
      .def_static(
          "ellipsoid", [](py::object mass, py::object semi_axes) {
            return RigidBody::ellipsoid(number(mass, "mass"), vec3(semi_axes, "semi_axes"));
          },
          py::arg("mass"), py::arg("semi_axes"),
          "A uniform solid ellipsoid, semi-axes (a, b, c) along the body axes: J = m/5 diag(b^2 + c^2, a^2 + c^2, "
          "a^2 + b^2).")
      .def("bounded_by", &RigidBody::bounded_by, py::arg("radius"),
           "This body (mass + inertia) within a bounding sphere of the radius, for contact detection.")
      .def_property_readonly(
          "extent",
          [](const RigidBody& b) {
            switch (b.extent()) {
              case Extent::Sphere: return "sphere";
              case Extent::Ellipsoid: return "ellipsoid";
              case Extent::Balls: return "balls";
              case Extent::Point: break;
            }
            return "point";
          },
          "What is known of its extent: \"balls\", \"sphere\", \"ellipsoid\", or \"point\" (mass + inertia only).")
      .def_property_readonly("semi_axes", [](const RigidBody& b) { return array3(b.semi_axes()); },
                             "The semi-axes (a, b, c) of an ellipsoid, (r, r, r) of a sphere; zeros otherwise.");
  m.def(
      "ellipsoid_volume", [](py::object semi_axes) { return ellipsoid_volume(vec3(semi_axes, "semi_axes")); },
      py::arg("semi_axes"), "4/3 pi a b c.");

  py::class_<Scenario>(m, "Scenario",
                       "A parsed and validated scenario (C++ lgvi::app::Scenario), as the CLI reads it. Created by "
                       "parse_scenario() or read_scenario().")
      .def_readonly("name", &Scenario::name, "The scenario's name (the file's stem).")
      .def_readonly("toml", &Scenario::source_text, "The TOML text it was read from.")
      .def_property_readonly("body", [](const Scenario& s) { return s.body(); }, "The body (a copy; the first body of a [[bodies]] scenario).")
      .def_property_readonly(
          "body_names",
          [](const Scenario& s) {
            std::vector<std::string> names(s.bodies());
            for (std::size_t a = 0; a < names.size(); ++a) names[a] = s.system.name(a);
            return names;
          },
          "The bodies' names, in scenario order.")
      .def_property_readonly("potential_kind", [](const Scenario& s) { return std::string(to_string(s.potential.kind)); },
                             "\"none\", \"central\" or \"uniform\".")
      .def_property_readonly("mu", [](const Scenario& s) { return s.potential.mu; }, "mu of a central potential.")
      .def_property_readonly("g", [](const Scenario& s) { return array3(s.potential.g); },
                             "g of a uniform potential (3,).")
      .def_property_readonly("position", [](const Scenario& s) { return array3(s.initial().x); },
                             "Initial centre of mass x0 (3,).")
      .def_property_readonly("quaternion", [](const Scenario& s) { return quaternion_array(s.initial().q); },
                             "Initial attitude q0 (4,), scalar-first (w, x, y, z), normalized.")
      .def_property_readonly("momentum", [](const Scenario& s) { return array3(s.initial().p); },
                             "Initial linear momentum p0 = m v0 (3,).")
      .def_property_readonly("w", [](const Scenario& s) { return array3(s.initial().w); },
                             "Initial w0 = 2 J Omega0 (3,), the paper's angular momentum variable.")
      .def_property_readonly("step", [](const Scenario& s) { return s.integrator.step; }, "Step size h.")
      .def_property_readonly("duration", [](const Scenario& s) { return s.integrator.duration; }, "Duration.")
      .def_property_readonly("steps", [](const Scenario& s) { return s.integrator.steps; },
                             "Number of steps, ceil(duration / step).")
      .def_property_readonly("on_contact", [](const Scenario& s) { return std::string(to_string(s.on_contact)); },
                             "[run] on_contact as it applies: \"stop\", \"warn\" or \"ignore\".")
      .def_property_readonly("method", [](const Scenario& s) { return std::string(to_string(s.integrator.method)); },
                             "The method's name (one of lgvi.METHODS).")
      .def_property_readonly("solver",
                             [](const Scenario& s) { return std::string(to_string(s.integrator.solver.kind)); },
                             "\"newton\", \"newton-exp\" or \"broyden\".")
      .def_property_readonly("tolerance", [](const Scenario& s) { return s.integrator.solver.tolerance; },
                             "Solver's relative tolerance.")
      .def_property_readonly("max_iterations", [](const Scenario& s) { return s.integrator.solver.max_iterations; },
                             "Solver's iteration limit.")
      .def_property_readonly("predictor_order", [](const Scenario& s) { return s.integrator.solver.predictor_order; },
                             "Degree of the initial-guess extrapolation (0..3).")
      .def_property_readonly("order", [](const Scenario& s) { return s.integrator.composition.order(); },
                             "Order of the composed method (2: the method's own step).")
      .def_property_readonly("composition", [](const Scenario& s) { return s.integrator.composition.gamma(); },
                             "Sub-step fractions gamma_1..gamma_s of a composed step.")
      .def_readonly("every", &Scenario::output_every, "A row every this many steps (plus the first and last).")
      .def_property_readonly("output_format",
                             [](const Scenario& s) { return std::string(to_string(s.output_format)); },
                             "The CLI's trajectory format: \"csv\", \"npz\", \"hdf5\", or the exports for viewers "
                             "\"xyz\" (OVITO) and \"vtk\" (ParaView).")
      .def_property_readonly("layout", [](const Scenario& s) { return std::string(to_string(s.layout)); },
                             "The trajectory's row layout ([output] layout): \"single-body\" or \"long\".")
      .def(
          "evaluate_potential",
          [](const Scenario& s, py::object x, py::object q) {
            const Vector3<double> xv = vec3(x, "position");
            const S3d qv = unit_quaternion(q, "quaternion", false);
            try {
              return std::visit([&](const auto& p) { return evaluation_tuple(p.evaluate(xv, qv)); },
                                lgvi::app::scenario_potential(s));
            } catch (const StepFailure& f) {  // e.g. a ball at the centre of central gravity
              throw py::value_error("position: the potential is not defined here: " + std::string(f.what()));
            }
          },
          py::arg("position"), py::arg("quaternion"),
          "The scenario's potential at (x, q), q scalar-first (w, x, y, z) within 1e-6 of unit norm, used as given: "
          "(energy, force (3,), body torque (3,)).");

  m.def(
      "check_quaternion", [](py::handle q, const std::string& name) { unit_quaternion(q, name, false); },
      py::arg("q"), py::arg("name"),
      "Raises ValueError (naming `name`) unless q is a scalar-first (w, x, y, z) quaternion within 1e-6 of unit "
      "norm: the library's S3::from_quaternion_checked, the check of scenario files.");
  m.def(
      "toml_text", [](const py::dict& document) { return write_toml(toml_table(document, false)); },
      py::arg("document"),
      "A document (a dict of tables: dicts of bool, int, float, str, lists and dicts) as TOML text, by the "
      "CLI's writer (src/io/toml_writer.hpp); TypeError for a value TOML cannot hold, ValueError for an int beyond "
      "64 bits.");
  m.def("parse_scenario", &parse_scenario, py::arg("text"), py::arg("name"),
        "Parses and validates scenario TOML text exactly as the CLI does; ValueError with the CLI's message "
        "(\"NAME: key 'K': ...\") otherwise.");
  m.def("read_scenario", &read_scenario, py::arg("path"),
        "Reads a scenario file exactly as the CLI does; ValueError with the CLI's message otherwise.");

  m.def("simulate", &run_simulation, py::arg("scenario"), py::arg("potential") = py::none(),
        py::arg("forcing") = py::none(), py::arg("control") = py::none(),
        "Runs the scenario with the CLI's run loop: returns (rows (rows, columns) float64: the trajectory's, "
        "one row a written step (and body, in the long layout), summary JSON text, completed, error, the side "
        "tables {file: (columns, rows)}, the trajectory's column names). `potential`: None (the scenario's own; the GIL is released), one callable (x, q) -> (energy, "
        "force, torque) or a tuple of three callables (x, q) -> energy / force / torque, q scalar-first "
        "(w, x, y, z). `forcing`: None or (f, body name or None, velocity_dependent) with f(t, x, q, p, w) -> (force, "
        "torque), added to the scenario's [[forcing]]. `control`: None or f(t, q, omega, wheel_speeds) -> body "
        "torque, in place of the wheel controller's PD law. Ctrl-C stops the run with KeyboardInterrupt.");

  m.def(
      "check_potential",
      [](py::object potential, py::object x, py::object q) {
        const Vector3<double> xv = vec3(x, "position");
        const S3d qv = unit_quaternion(q, "quaternion", false);
        const CallablePotential p = make_python_potential(std::move(potential));
        const DerivativeCheck c = check_potential_derivatives(p, xv, qv);
        return py::make_tuple(c.force_error, c.torque_error);
      },
      py::arg("potential"), py::arg("position"), py::arg("quaternion"),
      "Relative errors (force, torque) of a Python potential's force and torque against 4th-order finite "
      "differences of its energy at (x, q), q scalar-first (w, x, y, z) (C++ check_potential_derivatives).");

  py::class_<PyStepper>(m, "Stepper",
                        "One step at a time (C++ integrator of the scenario's method and solver). Quaternions "
                        "scalar-first (w, x, y, z).")
      .def(py::init<const Scenario&, py::object, py::object>(), py::arg("scenario"), py::arg("potential") = py::none(),
           py::arg("forcing") = py::none(),
           "Initializes the integrator at the scenario's initial state (k = 0).")
      .def("step", &PyStepper::step, py::arg("n") = 1,
           "Takes n steps (IntegrationError on failure; the state stays at the last good step).")
      .def("refresh", &PyStepper::refresh,
           "Re-evaluates the potential at the current state (after changing what a Python potential depends "
           "on), keeping the solver's warm start.")
      .def("set_potential", &PyStepper::set_potential, py::arg("potential"),
           "Replaces the potential (None: the scenario's own) from the current step on.")
      .def("set_state", &PyStepper::set_state, py::arg("position") = py::none(), py::arg("quaternion") = py::none(),
           py::arg("momentum") = py::none(), py::arg("w") = py::none(),
           "Replaces parts of the state (quaternion scalar-first (w, x, y, z)) and re-initializes the integrator.")
      .def_property_readonly("k", &PyStepper::k, "Steps taken.")
      .def_property_readonly("t", &PyStepper::t, "Time k h (never accumulated).")
      .def_property_readonly("h", &PyStepper::h, "Step size.")
      .def_property_readonly("bodies", [](const PyStepper& s) { return s.state().size(); }, "N, the bodies stepped.")
      .def_property_readonly(
          "masses",
          [](const PyStepper& s) {
            const System& sys = s.scenario().system;
            py::array_t<double> a(static_cast<py::ssize_t>(sys.size()));
            for (std::size_t b = 0; b < sys.size(); ++b) a.mutable_data()[b] = sys.body(b).mass();
            return a;
          },
          "The bodies' masses m_a (N,).")
      .def_property_readonly(
          "inertias",
          [](const PyStepper& s) {
            const System& sys = s.scenario().system;
            return stacked(sys.size(), {3, 3}, false, [&sys](std::size_t b) { return matrix_array(sys.body(b).inertia()); });
          },
          "The bodies' inertia tensors J_a in body axes (N, 3, 3).")
      .def_property_readonly("position", [](const PyStepper& s) { return body_vectors(s.state().x); },
                             "x (3,), or (N, 3).")
      .def_property_readonly(
          "quaternion",
          [](const PyStepper& s) {
            const SystemState& st = s.state();
            return stacked(st.size(), {4}, true, [&st](std::size_t b) { return quaternion_array(st.q[b]); });
          },
          "q (4,), or (N, 4), scalar-first (w, x, y, z).")
      .def_property_readonly("momentum", [](const PyStepper& s) { return body_vectors(s.state().p); },
                             "p (3,), or (N, 3).")
      .def_property_readonly("w", [](const PyStepper& s) { return body_vectors(s.state().w); },
                             "w = 2 J Omega (3,), or (N, 3).")
      .def_property_readonly(
          "omega", [](const PyStepper& s) { return body_vectors(s.projected(&RotationMatrixState::omega)); },
          "Body angular velocity Omega = J^-1 w / 2 (3,), or (N, 3).")
      .def_property_readonly(
          "velocity", [](const PyStepper& s) { return body_vectors(s.projected(&RotationMatrixState::xdot)); },
          "Velocity p / m (3,), or (N, 3).")
      .def_property_readonly(
          "rotation_matrix",
          [](const PyStepper& s) {
            const SystemState& st = s.state();
            return stacked(st.size(), {3, 3}, true, [&st](std::size_t b) { return matrix_array(st.q[b].matrix()); });
          },
          "R = pi(q) (3x3), or (N, 3, 3), body to inertial.")
      .def_property_readonly("energy", &PyStepper::energy, "Total energy (kinetic + potential).")
      .def_property_readonly("initial_energy", &PyStepper::energy0, "Energy at k = 0.")
      .def_property_readonly("initial_angular_momentum", [](const PyStepper& s) { return array3(s.momentum0()); },
                             "L at k = 0.")
      .def_property_readonly("potential_energy", [](const PyStepper& s) { return s.evaluation().energy; },
                             "V at the current state.")
      .def_property_readonly("force", [](const PyStepper& s) { return body_vectors(s.evaluation().force); },
                             "Force -dV/dx_a at the current state (3,), or (N, 3), inertial frame.")
      .def_property_readonly("torque", [](const PyStepper& s) { return body_vectors(s.evaluation().torque); },
                             "Body-frame torque M_a at the current state (3,), or (N, 3).")
      .def_property_readonly("angular_momentum", [](const PyStepper& s) { return array3(angular_momentum(s.state())); },
                             "Total angular momentum about the origin L = sum_a x_a cross p_a + R_a w_a / 2 (3,).")
      .def_property_readonly("linear_momentum", [](const PyStepper& s) { return array3(linear_momentum(s.state())); },
                             "Total linear momentum P = sum_a p_a (3,).")
      .def_property_readonly("solver_iterations", [](const PyStepper& s) { return s.last_solve().iterations; },
                             "Iterations of the last step's rotation solve.")
      .def_property_readonly("python_potential", &PyStepper::python_potential,
                             "Whether the potential is written in Python.")
      .def_property_readonly("work", &PyStepper::work, "The forcing's work since k = 0 (0 without forcing).")
      .def("row", &PyStepper::row,
           "The 21 trajectory columns at the current step (22 with the forcing's work), as simulate() writes them; "
           "for N bodies the long format's rows (N, 26), 27 columns with the work.");

  // Ensembles (lgvi.ensemble): the plan of `lgvi ensemble` and one member's row.
  py::class_<lgvi::app::EnsemblePlan>(m, "EnsemblePlan", "A sweep, read and checked: members and their varied values.")
      .def_property_readonly("header", [](const lgvi::app::EnsemblePlan& p) { return p.header; },
                             "members.csv's header line.")
      .def_property_readonly("members", &lgvi::app::EnsemblePlan::members, "Number of members.")
      .def_property_readonly("scenario_name", [](const lgvi::app::EnsemblePlan& p) { return p.scenario_name; },
                             "The base scenario's name.")
      .def("varied", [](const lgvi::app::EnsemblePlan& p, std::int64_t i) { return p.varied.at(static_cast<std::size_t>(i)); },
           py::arg("i"), "Member i's varied values, in the header's order.")
      .def("member_toml", &lgvi::app::EnsemblePlan::member_toml, py::arg("i"), "Member i's scenario (TOML text).")
      .def_property_readonly(
          "changes_not_errors", [](const lgvi::app::EnsemblePlan& p) { return p.changes_not_errors; },
          "The '..._error' columns that measure a change of a quantity the members do not conserve.")
      .def_property_readonly("metrics", [](const lgvi::app::EnsemblePlan& p) { return p.metrics.names; },
                             "[ensemble] metrics: the names of the GNC columns of each row.")
      .def_property_readonly("settle_band_deg", [](const lgvi::app::EnsemblePlan& p) { return p.metrics.settle_band_deg; },
                             "[ensemble] settle_band_deg (NaN if not given).")
      .def_property_readonly("series_times", [](const lgvi::app::EnsemblePlan& p) { return p.series_times; },
                             "With pointing metrics: the times of the pointing-error curve each row carries.")
      .def("split_row", &lgvi::app::EnsemblePlan::split_row, py::arg("row"),
           "A member's row as (its members.csv row, the pointing errors after it as CSV text).");
  m.def(
      "ensemble_plan",
      [](const std::string& sweep_text, const std::string& name, const std::string& scenario_text) {
        try {
          return lgvi::app::parse_ensemble_text(sweep_text, name, scenario_text);
        } catch (const lgvi::InvalidInput& e) {
          throw py::value_error(e.what());
        }
      },
      py::arg("sweep_text"), py::arg("name"), py::arg("scenario_text"),
      "Read a sweep (TOML text) over the given base scenario text; check every member. ValueError naming the key.");
  m.def(
      "run_member",
      [](std::int64_t index, const std::vector<double>& varied, const std::string& scenario_toml,
         const std::string& scenario_name, const std::vector<std::string>& metrics, double settle_band_deg) {
        py::gil_scoped_release release;
        return lgvi::app::run_member_scenario(index, varied, scenario_toml, scenario_name, 1, {},
                                              lgvi::app::MemberMetrics{metrics, settle_band_deg});
      },
      py::arg("index"), py::arg("varied"), py::arg("scenario_toml"), py::arg("scenario_name"),
      py::arg("metrics") = std::vector<std::string>{}, py::arg("settle_band_deg") = std::nan(""),
      "Run one member; its row (the CLI's bytes: EnsemblePlan.split_row separates its pointing errors).");
}
