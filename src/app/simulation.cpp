#include "app/simulation.hpp"

#include "app/interactions/registry.hpp"

#include "io/formats/particles.hpp"
#include "io/formats/registry.hpp"
#include "io/memory_sink.hpp"
#include "app/method_registry.hpp"
#include "io/output.hpp"

#include <lgvi/error.hpp>
#include <lgvi/integrate.hpp>
#include <lgvi/lgvi.hpp>
#include <lgvi/potential.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <functional>
#include <iterator>
#include <limits>
#include <memory>
#include <optional>
#include <utility>
#include <variant>

namespace lgvi::app {

namespace {
/// The [potential] for body a.
ScenarioPotential body_potential(const Scenario& s, std::size_t a) {
  const RigidBody& body = s.system.body(a);
  switch (s.potential.kind) {
    case PotentialKind::Central:
      return CentralGravity(body, s.potential.mu, s.potential.stop_at_contact, s.potential.j2,
                            s.potential.reference_radius, s.potential.pole,
                            s.potential.point_masses ? CentralGravity::Model::PointMass
                                                     : CentralGravity::Model::Extended);
    case PotentialKind::Uniform: return UniformGravity(body, s.potential.g);
    case PotentialKind::HeavyTop: return HeavyTop(body, s.potential.g, s.potential.pivot_to_com);
    case PotentialKind::None: break;
  }
  return NoPotential{};
}

/// The external field of every body, as one ExternalField of the right type.
template <class P>
ExternalField<P> field_of(const Scenario& s, const Parallelism& par) {
  std::vector<P> per_body;
  per_body.reserve(s.bodies());
  for (std::size_t a = 0; a < s.bodies(); ++a) per_body.push_back(std::get<P>(body_potential(s, a)));
  return ExternalField<P>(std::move(per_body), par);
}
}  // namespace

ScenarioPotential scenario_potential(const Scenario& s) { return body_potential(s, 0); }

Parallelism scenario_parallelism(const Scenario& s) {
  return s.threads > 0 ? Parallelism{s.threads} : Parallelism::all_cores();
}

ScenarioSystemPotential scenario_system_potential(const Scenario& s, const CallablePotential* field,
                                                  std::int64_t* evaluations) {
  const Parallelism par = scenario_parallelism(s);
  ScenarioSystemPotential::External external = ExternalField<NoPotential>::uniform(NoPotential{}, s.bodies(), par);
  if (field) {
    // A user's function (Python's, which needs its interpreter lock) is called from the calling thread
    // only; the results are the same on any number of threads.
    external = ExternalField<CallablePotential>::uniform(*field, s.bodies(), Parallelism{1});
  } else {
    switch (s.potential.kind) {
      case PotentialKind::Central: external = field_of<CentralGravity>(s, par); break;
      case PotentialKind::Uniform: external = field_of<UniformGravity>(s, par); break;
      case PotentialKind::HeavyTop: external = field_of<HeavyTop>(s, par); break;
      case PotentialKind::None: break;
    }
  }
  ScenarioSystemPotential::Mutual mutual;
  if (s.interaction.descriptor) mutual = s.interaction.descriptor->build(s.system, s.interaction, par);
  return {std::move(external), std::move(mutual), evaluations};
}

namespace {

/// sensors.csv's columns after t, in one place: each one's name, its sensor, and its value in a reading.
struct SensorColumn {
  const char* name;
  bool gyro;  ///< the gyro's (else the star tracker's)
  double (*value)(const AttitudeMeasurement&);
};
constexpr SensorColumn sensor_columns[] = {
    {"gyro.wx", true, [](const AttitudeMeasurement& m) { return m.omega.x(); }},
    {"gyro.wy", true, [](const AttitudeMeasurement& m) { return m.omega.y(); }},
    {"gyro.wz", true, [](const AttitudeMeasurement& m) { return m.omega.z(); }},
    {"gyro.bias_x", true, [](const AttitudeMeasurement& m) { return m.gyro_bias.x(); }},
    {"gyro.bias_y", true, [](const AttitudeMeasurement& m) { return m.gyro_bias.y(); }},
    {"gyro.bias_z", true, [](const AttitudeMeasurement& m) { return m.gyro_bias.z(); }},
    {"star_tracker.qw", false, [](const AttitudeMeasurement& m) { return m.q.w(); }},
    {"star_tracker.qx", false, [](const AttitudeMeasurement& m) { return m.q.vec().x(); }},
    {"star_tracker.qy", false, [](const AttitudeMeasurement& m) { return m.q.vec().y(); }},
    {"star_tracker.qz", false, [](const AttitudeMeasurement& m) { return m.q.vec().z(); }},
};

bool has_column(const AttitudeSensors& sensors, const SensorColumn& c) {
  return c.gyro ? sensors.has_gyro() : sensors.has_star_tracker();
}

}  // namespace

std::vector<std::string> sensor_header(const Scenario& s) {
  if (!s.wheel_control || !s.wheel_control->sensors()) return {};
  std::vector<std::string> h{"t"};
  for (const SensorColumn& c : sensor_columns)
    if (has_column(*s.wheel_control->sensors(), c)) h.emplace_back(c.name);
  return h;
}

std::vector<std::string> wheel_row_header(const Scenario& s) {
  if (s.layout != RowLayout::long_format || !s.system.has_wheels()) return {};
  return {"t", "body", "wheel", "speed", "momentum", "torque"};
}

namespace {

/// The side tables: each one's file, its place in the result, its columns, and the checkpoint field of its
/// position. A checkpoint of an lgvi that held the rows themselves (the field `rows_field`) still resumes:
/// its rows are written into a new file.
struct SideTableKind {
  const char* file;
  SideTable SimulationResult::* in_result;
  std::vector<std::string> (*header)(const Scenario&);
  const char* position_field;
  const char* rows_field;
};
const SideTableKind side_table_kinds[] = {
    {"sensors.csv", &SimulationResult::sensors, sensor_header, "recorder.sensors.position", "recorder.sensor_readings"},
    {"wheels.csv", &SimulationResult::wheels, wheel_row_header, "recorder.wheels.position", "recorder.wheel_rows"},
};

/// A run's side tables: a sink per table the scenario writes (SimulationOptions::open_side_table's, or a
/// MemorySink), their positions in a checkpoint, and the tables in the result.
class SideTables {
 public:
  SideTables(const Scenario& sc, SideTableOpener opener) : opener_(std::move(opener)) {
    for (const SideTableKind& kind : side_table_kinds) tables_.push_back(Table{&kind, kind.header(sc)});
  }

  /// A resume: where the checkpoint left each table. Throws InvalidInput naming a missing or malformed field.
  void load(const CheckpointFields& in) {
    for (Table& t : tables_) {
      if (t.columns.empty()) continue;
      if (in.has(t.kind->rows_field)) {
        t.rows_to_write = in.f64(t.kind->rows_field);
        if (t.rows_to_write.size() % t.columns.size() != 0)
          throw InvalidInput("checkpoint field '" + std::string(t.kind->rows_field) + "' holds " +
                             std::to_string(t.rows_to_write.size()) + " values, not rows of " +
                             std::to_string(t.columns.size()));
        continue;
      }
      const std::vector<std::int64_t>& p = in.i64(t.kind->position_field, 3);
      t.resume = SinkPosition{p[0], p[1], static_cast<std::uint32_t>(p[2])};
    }
  }

  /// Opens the sinks: after the trajectory's (the folder is there, the checkpoint has loaded).
  void open() {
    for (Table& t : tables_) {
      if (t.columns.empty()) continue;
      std::string header;
      for (const std::string& c : t.columns) header += (header.empty() ? "" : ",") + c;
      const TrajectoryLayout layout{header, static_cast<int>(t.columns.size()), 0};
      if (!opener_) {
        t.sink = std::make_unique<MemorySink>(0, layout);
        continue;
      }
      t.sink = opener_(t.kind->file, layout, t.resume ? &*t.resume : nullptr);
      for (std::size_t at = 0; at < t.rows_to_write.size(); at += t.columns.size()) t.sink->row(&t.rows_to_write[at]);
      t.rows_to_write = {};
    }
  }

  /// The sink of a table (null: the scenario writes no such table, or not opened yet).
  TrajectorySink* sink(SideTable SimulationResult::* which) const {
    for (const Table& t : tables_)
      if (t.kind->in_result == which) return t.sink.get();
    return nullptr;
  }

  /// Each table's rows made durable, and its position into a checkpoint's recorder fields.
  void save(CheckpointFields& out) const {
    for (const Table& t : tables_) {
      if (!t.sink) continue;
      const SinkPosition p = t.sink->sync();
      out.put_i64(t.kind->position_field, {p.rows, p.bytes, static_cast<std::int64_t>(p.crc32)});
    }
  }

  /// Closes the sinks; the tables' names and columns into the result, and their rows if kept in memory.
  /// Throws std::runtime_error on a write error.
  void close(SimulationResult& result) {
    for (Table& t : tables_) {
      SideTable& table = result.*(t.kind->in_result);
      table.file = t.kind->file;
      table.columns = t.columns;
      if (!t.sink) continue;
      t.sink->close("", "");
      if (auto* memory = dynamic_cast<MemorySink*>(t.sink.get())) table.values = memory->take();
    }
  }

 private:
  struct Table {
    const SideTableKind* kind;
    std::vector<std::string> columns;
    std::unique_ptr<TrajectorySink> sink = nullptr;
    std::optional<SinkPosition> resume = std::nullopt;
    std::vector<double> rows_to_write = {};
  };
  SideTableOpener opener_;
  std::vector<Table> tables_;
};

}  // namespace

SideTableOpener side_tables_in(const std::string& dir) {
  return [dir](const std::string& file, const TrajectoryLayout& layout, const SinkPosition* resume) {
    return open_trajectory(TrajectoryFormat(), (std::filesystem::path(dir) / file).string(), layout, resume);
  };
}

std::vector<std::string> side_table_files() {
  std::vector<std::string> files;
  for (const SideTableKind& kind : side_table_kinds) files.emplace_back(kind.file);
  return files;
}

ThermoColumns thermo_columns(const Scenario& s) {
  if (s.layout != RowLayout::long_format || !s.interaction.descriptor || !s.interaction.descriptor->reach) return ThermoColumns::none;
  const Box& box = s.system.box();
  const bool closed = !box.free_space() && box.periodic(0) && box.periodic(1) && box.periodic(2);
  return closed ? ThermoColumns::temperature_and_pressure : ThermoColumns::temperature;
}

std::int64_t degrees_of_freedom(const Scenario& s) {
  std::int64_t n = -3;  // less the total momentum's 3
  // A reaction wheel's spin is one more: the kinetic energy holds it (Wheels::kinetic_energy).
  for (std::size_t a = 0; a < s.bodies(); ++a)
    n += 3 + s.system.body(a).rotational_dof() + static_cast<std::int64_t>(s.system.body(a).wheels().size());
  return n;
}

TrajectoryLayout scenario_layout(const Scenario& s) {
  const bool forced = conservation_laws(s).forced;  // a forcing or motor torques: the work column
  TrajectoryLayout layout =
      s.layout == RowLayout::long_format ? TrajectoryLayout::long_format(static_cast<std::int64_t>(s.bodies()), forced, thermo_columns(s))
                      : TrajectoryLayout::single_body(forced);
  // A body with reaction wheels: per wheel its speed relative to the body, its axial momentum and the torque
  // applied over the step from the row's time, after the forced columns.
  if (s.layout == RowLayout::single_body)
    for (const Wheel& w : s.body().wheels().list()) {
      layout.header += "," + w.name + ".speed," + w.name + ".momentum," + w.name + ".torque";
      layout.columns += 3;
    }
  if (!holds_columns(s.output_format)) layout.shapes = body_shapes(s.system);
  if (writes_file_ids(s.output_format)) layout.ids = s.file_ids;
  // An adaptive run's rows are not at multiples of a step: 0 (the dump numbers its frames).
  layout.step = s.integrator.adaptive() ? 0.0 : s.integrator.step;
  layout.box = s.system.box();
  return layout;
}

namespace {

/// Contact between bodies after every step, under [run] on_contact "stop" or
/// "warn" (contact.hpp): it only reads the state. Episodes go to the
/// statistics; under "stop" the first contact ends the run.
class ContactWatch {
 public:
  ContactWatch(const Scenario& sc, RunStatistics& stats)
      : sc_(sc), stats_(stats), active_(sc.on_contact != OnContact::Ignore && sc.bodies() > 1) {
    if (active_) detector_ = ContactDetector(sc.system);
  }

  /// Checks the state of step k (time t); true if the run must stop here.
  bool observe(std::int64_t k, double t, const SystemState& s) {
    if (!active_) return false;
    const std::vector<Contact>& found = detector_.find(s);
    if (found.empty()) {
      open_.clear();
      return false;
    }
    // Both lists are in the order of (a, b): a merge continues the episodes
    // of the previous step and begins the others.
    next_open_.clear();
    std::size_t o = 0;
    for (const Contact& c : found) {
      const auto key = std::pair(static_cast<std::int64_t>(c.a), static_cast<std::int64_t>(c.b));
      while (o < open_.size() && open_[o].key < key) ++o;
      std::size_t index = none;
      if (o < open_.size() && open_[o].key == key) {
        index = open_[o].index;
      } else {
        ++stats_.contact_episodes;
        if (stats_.contacts.size() < RunStatistics::max_listed_contacts) {
          index = stats_.contacts.size();
          stats_.contacts.push_back({key.first, key.second, k, k, t, t, c.depth(), c.distance});
        }
      }
      if (index != none) {
        ContactEpisode& e = stats_.contacts[index];
        e.last_k = k;
        e.last_t = t;
        if (c.depth() > e.max_depth) {
          e.max_depth = c.depth();
          e.distance = c.distance;
        }
      }
      next_open_.push_back({key, index});
    }
    std::swap(open_, next_open_);
    if (sc_.on_contact != OnContact::Stop) return false;
    stop_message_ = stop_message(found.front(), k, t);
    return true;
  }

  /// On resume from step k: the listed episodes that were going on at k.
  void resume_at(std::int64_t k) {
    open_.clear();
    for (std::size_t i = 0; i < stats_.contacts.size(); ++i)
      if (stats_.contacts[i].last_k == k) open_.push_back({{stats_.contacts[i].a, stats_.contacts[i].b}, i});
    std::sort(open_.begin(), open_.end(), [](const Open& u, const Open& v) { return u.key < v.key; });
  }

  /// Why the run stopped (empty if it did not stop at a contact).
  const std::string& stopped() const { return stop_message_; }

 private:
  static constexpr std::size_t none = static_cast<std::size_t>(-1);
  struct Open {
    std::pair<std::int64_t, std::int64_t> key;
    std::size_t index;  ///< in stats.contacts, or none (beyond the listed ones)
  };

  std::string stop_message(const Contact& c, std::int64_t k, double t) const {
    auto body = [&](std::size_t a, std::ptrdiff_t ball) {
      return (ball >= 0 ? "ball " + std::to_string(ball) + " of " : std::string()) + "bodies[" + std::to_string(a) +
             "] (\"" + sc_.system.name(a) + "\")";
    };
    return fmt::format("contact: {} and {} overlap at t = {} (step {}): centre distance {}, contact depth {} ({}); the "
                       "model (no contact forces) does not hold from here; [run] on_contact = \"warn\" records "
                       "contacts and goes on",
                       body(c.a, c.ball_a), body(c.b, c.ball_b), t, k, c.distance, c.depth(),
                       describe_reach(sc_.system, c));
  }

  const Scenario& sc_;
  RunStatistics& stats_;
  bool active_;
  ContactDetector detector_;
  std::vector<Open> open_, next_open_;
  std::string stop_message_;
};

/// The observer: diagnostics at every step, rows every `output_every` steps
/// (one row per body in the long layout), and the last row of a run stopped
/// at a contact.
struct Recorder {
  const Scenario& scenario;
  TrajectorySink& sink;
  RunStatistics& stats;
  ContactWatch& contact;
  /// The molecular virial at a state (the stepper's potential's), for the
  /// pressure column; empty when the layout has none.
  std::function<double(const SystemState&)> virial = {};
  ThermoColumns thermo = ThermoColumns::none;
  /// The temperature's degrees of freedom (counted once: O(N)).
  std::int64_t dof = degrees_of_freedom(scenario);
  /// The energy error is E - E0 - W (a forcing, or motor torques on reaction wheels).
  bool forced = conservation_laws(scenario).forced;
  /// The diagnostics' threads (those of the scenario's run: the values do not depend on them).
  Parallelism par = scenario_parallelism(scenario);
  /// One body's terms of the diagnostics at a step: its kinetic energy and
  /// its rotational part, its angular momentum x x p + R pi and the spin R
  /// pi in it, and |q| - 1.
  struct BodyTerms {
    double ke = 0.0, rot = 0.0, dq = 0.0;
    Vector3<double> l = Vector3<double>::Zero(), spin = Vector3<double>::Zero();
  };
  /// The bodies' terms are computed in blocks of this many (72 B each: a
  /// block's stay in a core's L2), each block's on the threads.
  static constexpr std::size_t diagnostics_block = 8192;
  std::vector<BodyTerms> body_terms = {};
  std::vector<double> row_buffer = {};  ///< a single-body row with its wheels' columns
  /// A copy of the scenario's wheel controller, sampled on the same states as the stepper's: its commands.
  std::optional<WheelAttitudeControl> wheel_control = scenario.wheel_control;
  std::vector<double> wheel_commands = {};  ///< per wheel, its command at the observed state
  std::vector<double> wheel_speeds = {};    ///< per wheel, its speed relative to the body there
  std::vector<double> wheel_columns = {};   ///< per wheel, its speed, momentum and applied torque there
  TrajectorySink* sensor_table = nullptr;  ///< SimulationResult::sensors' sink (SideTables)
  std::vector<double> sensor_row = {};
  bool wheels = scenario.system.has_wheels();
  /// A system's wheels at the written frames: SimulationResult::wheels' sink (SideTables).
  TrajectorySink* wheel_table = nullptr;

  /// A row of sensors.csv (sensor_header's columns).
  void record_sensors(double t, const AttitudeSensors& sensors, const AttitudeMeasurement& m) {
    sensor_row.assign(1, t);
    for (const SensorColumn& c : sensor_columns)
      if (has_column(sensors, c)) sensor_row.push_back(c.value(m));
    if (sensor_table) sensor_table->row(sensor_row.data());
  }
  /// SimulationOptions::observe_step (may be empty).
  std::function<void(std::int64_t, double, const SystemState&)> observe_step = {};

  /// The wheels of every body that has them, at this state and every step: into the statistics (per wheel,
  /// body by body), body 0's columns (speed, momentum, torque per wheel) into wheel_columns for a single
  /// body's rows, and at a written frame of a system one row per wheel into wheel_table. The
  /// torque is the command at t after the limits (Wheel::applied_torque), as the step from t applies it
  /// (lgvi.hpp's kick_wheels).
  void observe_wheels(const SystemStepInfo& i, bool written) {
    const System& sys = scenario.system;
    const SystemState& s = i.state;
    const bool end = scenario.integrator.ends(i.k, i.t);
    // The step from t applies these torques over h: the statistics of torque and time count it, except at
    // the end (no step follows).
    const double h = end ? 0.0 : scenario.integrator.step;
    const bool rows = written && scenario.layout == RowLayout::long_format;
    wheel_columns.clear();
    bool any_limited = false;
    std::size_t first = 0;  // body a's first wheel in stats.wheels
    for (std::size_t a = 0; a < sys.size(); ++a) {
      const Wheels& wheels = sys.body(a).wheels();
      if (wheels.empty()) continue;
      if (stats.wheels.size() < first + wheels.size()) stats.wheels.resize(first + wheels.size());
      wheel_commands.assign(wheels.size(), 0.0);
      const Vector3<double> omega = wheels.body_rate(s.w[a], s.eta[a].data());
      wheel_speeds.resize(wheels.size());
      for (std::size_t w = 0; w < wheels.size(); ++w) wheel_speeds[w] = wheels.relative_speed(w, s.eta[a].data(), omega);
      for (const WheelTorque& u : scenario.wheel_torques)
        if (u.body == a) wheel_commands[u.wheel] += u.torque.at(i.t);
      if (wheel_control && a == 0) {
        if (i.k == 0) wheel_control->reset();
        // The controller's samples, as the stepper takes them (not at the last state: no step follows, and a
        // law of one's own is called once per sample): what its sensors read. The last row holds the last
        // command.
        if (!end && wheel_control->sample(i.t, s.q[0], omega, wheel_speeds) && wheel_control->sensors())
          record_sensors(i.t, *wheel_control->sensors(), wheel_control->measured());
        for (std::size_t w = 0; w < wheels.size(); ++w) wheel_commands[w] += wheel_control->command()[w];
      }
      for (std::size_t w = 0; w < wheels.size(); ++w) {
        const double speed = wheel_speeds[w];
        const double u = wheels[w].applied_torque(wheel_commands[w], speed);
        const bool limited = u != wheel_commands[w];
        any_limited = any_limited || limited;
        RunStatistics::WheelStatistics& st = stats.wheels[first + w];
        st.max_speed = std::max(st.max_speed, std::abs(speed));
        if (!end) st.max_torque = std::max(st.max_torque, std::abs(u));
        if (limited) st.time_limited += h;
        if (!end && wheel_control && a == 0) stats.wheel_effort += std::abs(u) * h;  // held over the step
        if (a == 0 && scenario.layout == RowLayout::single_body) wheel_columns.insert(wheel_columns.end(), {speed, s.eta[a][w], u});
        if (rows && wheel_table) {
          const double row[] = {i.t, static_cast<double>(a), static_cast<double>(w), speed, s.eta[a][w], u};
          wheel_table->row(row);
        }
      }
      // A wheel-torque table may switch inside a step: its effort is the impulse the step gives (kick_wheels,
      // the same formula). Computed here, at t, rather than read from the stepper after the step: the
      // statistics at step k hold the step from t_k, as the rows' torque columns do and as every checkpoint
      // holds them, and a step that fails counted its command.
      if (!end)
        for (const WheelTorque& u : scenario.wheel_torques) {
          if (u.body != a) continue;
          const Wheel& wheel = wheels[u.wheel];
          stats.wheel_effort += std::abs(wheel.speed_limited(u.torque.impulse(i.t, i.t + h, wheel.max_torque),
                                                             wheel_speeds[u.wheel]));
        }
      first += wheels.size();
    }
    if (any_limited) stats.wheels_saturated_time += h;
  }

  /// The kinetic temperature and the pressure of a written frame (thermo_columns),
  /// into the statistics: T = 2 K / (k_B n_f), n_f = 6 N - 3 (LAMMPS's count for
  /// rigid bodies: 3 translational and 3 rotational per body, 2 for a linear
  /// body and none for a point, one per reaction wheel, less the 3 of the total momentum), k_B = 1 (T in energy units); P = (2 K_trans + W) / (3 V),
  /// W the pair forces' molecular virial (PairInteraction::virial), V the box's volume.
  std::pair<double, double> thermodynamics(const SystemState& s, double kinetic) {
    const System& sys = scenario.system;
    // No degrees of freedom left (one point body): 0, as LAMMPS's compute temp.
    const double temperature = dof > 0 ? 2.0 * kinetic / static_cast<double>(dof) : 0.0;
    double pressure = std::numeric_limits<double>::quiet_NaN();
    if (thermo == ThermoColumns::temperature_and_pressure) {
      double translational = 0.0;
      for (std::size_t a = 0; a < s.size(); ++a) translational += s.p[a].squaredNorm() / (2.0 * sys.body(a).mass());
      pressure = (2.0 * translational + virial(s)) / (3.0 * sys.box().volume());
    }
    ThermoStatistics& th = stats.thermo;
    if (th.frames == 0) {
      th.temperature0 = temperature;
      th.pressure0 = pressure;
    }
    th.temperature = temperature;
    th.pressure = pressure;
    th.temperature_sum += temperature;
    th.pressure_sum += pressure;
    ++th.frames;
    return {temperature, pressure};
  }

  /// The state is finite (the stepper checks it), but what is derived from
  /// it can still overflow: |p|^2 / 2m or x x p beyond the largest double.
  /// A row or summary with inf or NaN in it would read as a result; the run
  /// fails at this step instead, naming what overflowed.
  void require_finite_diagnostics(const SystemStepInfo& i, double energy, double de, const Vector3<double>& L,
                                  const Vector3<double>& P, double rot_energy) const {
    if (std::isfinite(energy + de + L.sum() + P.sum() + rot_energy + i.work)) return;
    const char* what = !std::isfinite(energy) || !std::isfinite(rot_energy) ? "the energy"
                       : !std::isfinite(de)                                  ? "the energy error"
                       : !L.allFinite()                                      ? "the angular momentum"
                       : !P.allFinite()                                      ? "the linear momentum"
                                                                             : "the forcing's work";
    const StepFailure cause(std::string(what) + " is not finite although the state is: it overflows double precision",
                            "rescale the scenario's units (lengths, masses, times) so that positions, momenta and "
                            "energies stay well below 1e150");
    const std::int64_t step = std::max<std::int64_t>(0, i.k - 1);
    // The failing step began at the last observed t (an adaptive run's own clock) or at step h.
    const double t = scenario.integrator.adaptive() ? stats.last_t : static_cast<double>(step) * scenario.integrator.step;
    throw IntegrationFailure(step, t, cause);
  }

  void operator()(const SystemStepInfo& i) {
    const SystemState& s = i.state;
    const bool contact_stop = i.k > 0 && contact.observe(i.k, i.t, s);
    const std::size_t n = s.size();
    // Every diagnostic in one pass over the bodies (not one pass each), each
    // sum in body order from body 0's term as total_energy, angular_momentum
    // and linear_momentum (system.hpp) take them: the same values, bit for bit.
    const System& sys = scenario.system;
    // The bodies' terms in blocks, each block's on the threads (BodyTerms:
    // each term the same operations as alone), then summed here in body
    // order: the serial part is the sums only.
    auto terms_of = [&](std::size_t a, BodyTerms& t) {
      const RigidBody& body = sys.body(a);
      // kinetic_energy(s, sys, a) as its two terms, p^2 / 2m and the rotational
      // energy (state.hpp: the same operations, so the same bits); with wheels,
      // the gyrostat's (Wheels::kinetic_energy), less p^2 / 2m.
      const double translational = s.p[a].squaredNorm() / (2.0 * body.mass());
      if (!body.has_wheels()) {
        t.rot = rotational_kinetic_energy(s.w[a], body);
        t.ke = translational + t.rot;
      } else {
        t.ke = kinetic_energy(s, sys, a);
        t.rot = t.ke - translational;
      }
      // The spin R_a pi_a, pi_a = w_a / 2: the rotational part of
      // angular_momentum(body), x_a x p_a + R_a (w_a / 2), and the spin's sum.
      const Vector3<double> pi = 0.5 * s.w[a];
      t.spin = s.q[a].act(pi);
      t.l = s.x[a].cross(s.p[a]) + t.spin;
      t.dq = s.q[a].norm_error();
    };
    double kinetic = 0.0, rot_energy = 0.0, dq = 0.0;
    Vector3<double> L = Vector3<double>::Zero(), P = Vector3<double>::Zero(), spin = Vector3<double>::Zero();
    body_terms.resize(std::min(n, diagnostics_block));
    for (std::size_t first = 0; first < n; first += diagnostics_block) {
      const std::size_t count = std::min(diagnostics_block, n - first);
      parallel_for(count, par, [&](std::size_t l) { terms_of(first + l, body_terms[l]); });
      for (std::size_t l = 0; l < count; ++l) {
        const std::size_t a = first + l;
        const BodyTerms& t = body_terms[l];
        if (a == 0) {
          kinetic = t.ke;
          L = t.l;
          P = s.p[0];
          dq = t.dq;
        } else {
          kinetic += t.ke;
          L += t.l;
          P += s.p[a];
          if (std::abs(t.dq) > std::abs(dq)) dq = t.dq;
        }
        rot_energy += t.rot;
        spin += t.spin;
      }
    }
    const double energy = kinetic + i.evaluation.energy;  // total_energy(s, sys, i.evaluation)
    if (i.k == 0) {
      stats.rot_energy0 = stats.min_rot_energy = stats.max_rot_energy = rot_energy;
      stats.spin0 = spin;
      stats.min_spin = stats.max_spin = spin.norm();
      stats.energy0 = energy;
      stats.momentum0 = L;
      stats.linear_momentum0 = P;
      stats.linear_momentum_scale = 0.0;
      for (const Vector3<double>& p : s.p) stats.linear_momentum_scale += p.norm();
    } else {
      stats.iterations_total += i.solve.iterations;
      stats.iterations_max = std::max<std::int64_t>(stats.iterations_max, i.solve.worst_iterations);
      ++stats.steps_solved;
    }
    // With a forcing, the energy error is E - E0 - W: the integrator's own
    // error, with the work W done by the forcing taken out (forcing.hpp).
    const double de = forced ? energy - stats.energy0 - i.work : energy - stats.energy0;
    const double dl = (L - stats.momentum0).norm();
    stats.work = i.work;
    require_finite_diagnostics(i, energy, de, L, P, rot_energy);
    // |P - P0| relative to sum |p_a0|; absolute when every body starts at rest.
    const double dp = linear_momentum_error(P, stats.linear_momentum0, stats.linear_momentum_scale);
    stats.max_energy_error = std::max(stats.max_energy_error, std::abs(de));
    stats.max_quat_error = std::max(stats.max_quat_error, std::abs(dq));
    stats.max_momentum_error = std::max(stats.max_momentum_error, dl);
    stats.max_linear_momentum_error = std::max(stats.max_linear_momentum_error, dp);
    stats.min_rot_energy = std::min(stats.min_rot_energy, rot_energy);
    stats.max_rot_energy = std::max(stats.max_rot_energy, rot_energy);
    stats.min_spin = std::min(stats.min_spin, spin.norm());
    stats.max_spin = std::max(stats.max_spin, spin.norm());
    stats.max_spin_change = std::max(stats.max_spin_change, (spin - stats.spin0).norm());
    // (Not the last step of an exact finish: shortened to end at the duration, it says nothing of the dynamics.)
    if (scenario.integrator.adaptive() && i.k > 0 &&
        !(scenario.integrator.exact_finish && i.t >= scenario.integrator.duration)) {
      const double dt = i.t - stats.last_t;
      stats.min_time_step = stats.max_time_step > 0.0 ? std::min(stats.min_time_step, dt) : dt;
      stats.max_time_step = std::max(stats.max_time_step, dt);
    }
    stats.last_t = i.t;
    stats.last_k = i.k;
    stats.observed = true;
    if (observe_step) observe_step(i.k, i.t, s);
    const bool written = i.k % scenario.output_every == 0 || scenario.integrator.ends(i.k, i.t) || contact_stop;
    if (wheels) observe_wheels(i, written);  // every step: the statistics
    if (!written) return;
    if (scenario.layout == RowLayout::single_body) {
      const SingleBodyRow row(i.t, s.body(0), energy, de, dq, L, dl, forced ? std::optional(i.work) : std::nullopt);
      if (wheels) {
        row_buffer.assign(row.values, row.values + row.columns);
        row_buffer.insert(row_buffer.end(), wheel_columns.begin(), wheel_columns.end());
        sink.row(row_buffer.data());
        return;
      }
      sink.row(row.values);  // the layout's columns: the work only when forced
      return;
    }
    // The optional columns after the system's: the work when forced, then the thermodynamic ones.
    double tail[3] = {};
    int tail_size = 0;
    if (forced) tail[tail_size++] = i.work;
    if (thermo != ThermoColumns::none) {
      const auto [temperature, pressure] = thermodynamics(s, kinetic);
      tail[tail_size++] = temperature;
      if (thermo == ThermoColumns::temperature_and_pressure) tail[tail_size++] = pressure;
    }
    const SystemRowTotals totals{energy, de, P, dp, L, dl};
    double row[bodies_trajectory_columns + 3];
    for (std::size_t a = 0; a < n; ++a) {
      system_row(i.t, s, a, totals, tail, tail_size, row);
      sink.row(row);  // the layout's columns
    }
  }
};

/// Loads the checkpoint's state and the stepper's fields (resuming at its
/// step): CheckpointError for a body count that differs or a stepper field
/// that is unknown, missing or malformed; StepFailure (the step's) as thrown.
template <class Stepper>
void load_checkpoint(Stepper& stepper, const Scenario& sc, const Checkpoint& c, SystemState& state) {
  if (c.state.size() != sc.bodies())
    throw CheckpointError(c.path + ": checkpoint field 'run.state' holds " + std::to_string(c.state.size()) +
                          " bodies, the scenario has " + std::to_string(sc.bodies()));
  std::size_t wheels_total = 0;
  for (std::size_t a = 0; a < sc.bodies(); ++a) {
    const std::size_t wheels = sc.system.body(a).wheels().size();
    const std::size_t held = c.state.eta.empty() ? 0 : c.state.eta[a].size();
    if (held != wheels)
      throw CheckpointError(c.path + ": checkpoint field 'run.wheel_counts' holds " + std::to_string(held) +
                            " reaction wheels for body " + std::to_string(a) + ", the scenario has " +
                            std::to_string(wheels));
    wheels_total += wheels;
  }
  if (!c.stats.wheels.empty() && c.stats.wheels.size() != wheels_total)
    throw CheckpointError(c.path + ": checkpoint field 'statistics.wheels' holds " +
                          std::to_string(c.stats.wheels.size()) + " wheels, the scenario has " +
                          std::to_string(wheels_total));
  state = c.state;
  try {
    stepper.load(state, static_cast<double>(c.k) * sc.integrator.step, c.stepper);
    c.stepper.require_all_read();  // what this stepper does not know
  } catch (const InvalidInput& e) {
    throw CheckpointError(c.path + ": " + e.what());
  }
}

/// `evaluations`: the potential's count in this leg of the run (added to the
/// statistics' by the caller at the end, and to a checkpoint's here).
template <class Stepper>
SimulationResult run_with(Stepper& stepper, const Scenario& sc, const SinkOpener& open_sink,
                          const SimulationOptions& opt, const std::int64_t& evaluations) {
  SimulationResult result;
  RunStatistics& stats = result.stats;
  SystemState state;
  if (opt.start) state = std::move(*opt.start);
  else state = sc.initial_state;
  std::int64_t k0 = 0;
  const auto start = std::chrono::steady_clock::now();
  // A resume loads the checkpoint before the sink is opened: a checkpoint
  // this lgvi cannot read (CheckpointError, thrown from here) leaves the run
  // folder as it was. A step that fails at the loaded state (or, for a new
  // run, at the initial state) is the run's failure at that step, reported
  // with the sink open as for any other.
  std::optional<StepFailure> start_failure;
  // The recorder's copy of the wheel controller (Recorder), and the side tables.
  std::optional<WheelAttitudeControl> recorder_control = sc.wheel_control;
  SideTables side_tables(sc, opt.open_side_table);
  if (opt.resume) {
    stats = opt.resume->stats;
    k0 = opt.resume->k;
    try {
      load_checkpoint(stepper, sc, *opt.resume, state);
    } catch (const StepFailure& f) {
      start_failure = f;
    }
    try {
      const CheckpointFields& in = opt.resume->recorder;
      if (recorder_control)
        recorder_control->load(in, "recorder.wheel_control", static_cast<double>(k0) * sc.integrator.step, true);
      side_tables.load(in);
      in.require_all_read();
    } catch (const InvalidInput& e) {
      throw CheckpointError(opt.resume->path + ": " + e.what());
    }
  }
  // A resume opens the side tables first (the folder is there): one that is missing or shorter than the
  // checkpoint recorded is refused before the trajectory is truncated.
  if (opt.resume) {
    try {
      side_tables.open();
    } catch (const std::exception& e) {
      throw CheckpointError(opt.resume->path + ": " + e.what());
    }
  }
  // What the stepper or the recorder refuses at the initial state (InvalidInput:
  // an adaptive step with V = 0 and no monitor_scale, a pressure without a
  // potential) is refused before the sink is opened, so nothing is written.
  if (!opt.resume) {
    try {
      stepper.initialize(state, 0.0);
    } catch (const StepFailure& f) {
      start_failure = f;
    } catch (const InvalidInput& e) {
      // As the reader's refusals: the scenario's file first.
      if (sc.source.empty()) throw;
      throw InvalidInput(sc.source + ": " + e.what());
    }
  }
  const ThermoColumns thermo = thermo_columns(sc);
  std::function<double(const SystemState&)> virial;
  if (thermo == ThermoColumns::temperature_and_pressure) {
    if constexpr (requires { stepper.potential().virial(state); }) {
      virial = [&stepper](const SystemState& s) { return stepper.potential().virial(s).value(); };
    } else {
      throw InvalidInput("the pressure needs the stepper's potential; this method has none");
    }
  }
  TrajectorySink& sink = open_sink();
  if (!opt.resume) side_tables.open();
  ContactWatch contact(sc, stats);
  if (opt.resume) contact.resume_at(k0);
  Recorder recorder{sc, sink, stats, contact};
  recorder.wheel_control = std::move(recorder_control);
  recorder.sensor_table = side_tables.sink(&SimulationResult::sensors);
  recorder.wheel_table = side_tables.sink(&SimulationResult::wheels);
  recorder.observe_step = opt.observe_step;
  recorder.thermo = thermo;
  recorder.virial = std::move(virial);
  if (opt.resume && recorder.thermo != ThermoColumns::none && stats.thermo.frames == 0) {
    // A checkpoint from before the thermodynamic columns: the first frame and the
    // sums over the earlier leg are unknown (the summary says null), not the resumed leg's.
    const double unknown = std::numeric_limits<double>::quiet_NaN();
    stats.thermo = {unknown, unknown, unknown, unknown, unknown, unknown, 1};
  }
  const double h = sc.integrator.step;
  auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };
  auto checkpoint = [&](std::int64_t k) {
    Checkpoint c;
    c.k = k;
    c.state = state;
    stepper.save(c.stepper);
    if (recorder.wheel_control) recorder.wheel_control->save(c.recorder, "recorder.wheel_control");
    side_tables.save(c.recorder);
    c.stats = stats;
    c.stats.wall_seconds_before += elapsed();
    c.stats.potential_evaluations += evaluations;  // this leg's so far: a resumed run's total counts them
    c.sink = sink.sync();
    c.checkpoint_every = opt.checkpoint_every;
    c.scenario_name = sc.name;
    write_checkpoint(opt.checkpoint_path, c);
  };
  std::int64_t reached = k0;
  try {
    if (start_failure) {  // at step k0 (0 for a new run, whose statistics start at last_t = 0)
      throw IntegrationFailure(k0, sc.integrator.adaptive() ? stats.last_t : static_cast<double>(k0) * h, *start_failure);
    } else if (!opt.resume) {
      recorder(SystemStepInfo{0, 0.0, state, stepper.evaluation(), SolveReport{}});
    }
    // Steps are taken in legs that end at checkpoints and progress reports,
    // so the per-step loop stays free of those checks.
    const std::int64_t n = sc.integrator.steps;
    auto next_stop = [&](std::int64_t k) {
      std::int64_t e = n;
      if (opt.checkpoint_every > 0) e = std::min(e, (k / opt.checkpoint_every + 1) * opt.checkpoint_every);
      if (opt.progress) e = std::min(e, (k / opt.progress_every + 1) * opt.progress_every);
      return e;
    };
    auto stop_requested = [&] { return (opt.stop_flag && *opt.stop_flag != 0) || !contact.stopped().empty(); };
    // An adaptive run (time_transform) ends with the first step that reaches
    // the duration, at most n = max_steps steps; a fixed step after n steps.
    // Within a leg integrate_range asks stop_here before each step: the
    // stepper's clock is live there, `reached` is not (a fixed run's legs end
    // at n by themselves).
    auto time_now = [&] { return lgvi::detail::physical_time(stepper, static_cast<double>(reached) * h); };
    auto arrived = [&] { return sc.integrator.ends(reached, time_now()); };
    auto stop_here = [&] { return stop_requested() || arrived(); };
    while (reached < n && !arrived()) {
      const std::int64_t end = next_stop(reached);
      reached = integrate_range(stepper, state, 0.0, h, reached, end, recorder, stop_here);
      if (stop_requested()) break;
      if (opt.checkpoint_every > 0 && reached % opt.checkpoint_every == 0 && reached < n && !arrived())
        checkpoint(reached);
      if (opt.progress) opt.progress(reached, time_now());
    }
    if (!contact.stopped().empty()) {
      // Stopped at the step of a contact (the last row written): as a failed
      // run, with a checkpoint there when checkpointing.
      result.error = contact.stopped();
      if (opt.checkpoint_every > 0) checkpoint(reached);
    } else if (arrived()) {
      result.completed = true;
    } else if (reached < n) {
      result.interrupted = true;
      if (opt.checkpoint_every > 0) checkpoint(reached);
    } else {
      // An adaptive run that took max_steps steps short of the duration.
      result.error = fmt::format("integrator.max_steps: {} steps reached t = {:.9g} of duration {:.9g} (the smallest "
                                 "step was {:.3g}); a close encounter or a collision holds the step down: raise "
                                 "max_steps, or look at the trajectory's last rows",
                                 n, time_now(), sc.integrator.duration, stats.min_time_step);
      if (opt.checkpoint_every > 0) checkpoint(reached);
    }
  } catch (const IntegrationFailure& e) {
    result.error = e.what();
  }
  result.wall_seconds = stats.wall_seconds_before + elapsed();
  result.final_state = std::move(state);
  try {
    side_tables.close(result);
  } catch (const std::exception& e) {
    if (result.error.empty()) result.error = e.what();
    result.completed = false;
  }
  return result;
}

}  // namespace

namespace {

SimulationResult simulate_with(const Scenario& sc, const CallablePotential* field, const SinkOpener& open_sink,
                               const SimulationOptions& opt) {
  if (opt.checkpoint_every > 0 && opt.checkpoint_path.empty())
    throw InvalidInput("checkpoint_every is set but no checkpoint path is given");
  // A control law of one's own (Python) keeps a state of its own, which a checkpoint cannot hold.
  if ((opt.checkpoint_every > 0 || opt.resume) && sc.wheel_control && sc.wheel_control->has_custom_law())
    throw InvalidInput("checkpoint_every: a run with a control law of one's own cannot be checkpointed or resumed "
                       "(the law's state is its own)");
  std::int64_t count = 0;
  SimulationResult r = with_stepper(sc, scenario_system_potential(sc, field, &count), scenario_parallelism(sc),
                                    [&](auto& stepper) { return run_with(stepper, sc, open_sink, opt, count); });
  r.stats.potential_evaluations += count;
  return r;
}
}  // namespace

SimulationResult simulate(const Scenario& sc, TrajectorySink& sink, const SimulationOptions& opt) {
  return simulate_with(sc, nullptr, [&]() -> TrajectorySink& { return sink; }, opt);
}

SimulationResult simulate(const Scenario& sc, const SinkOpener& open_sink, const SimulationOptions& opt) {
  return simulate_with(sc, nullptr, open_sink, opt);
}

SimulationResult simulate(const Scenario& sc, const CallablePotential& potential, TrajectorySink& sink,
                          const SimulationOptions& opt) {
  return simulate_with(sc, &potential, [&]() -> TrajectorySink& { return sink; }, opt);
}

}  // namespace lgvi::app
