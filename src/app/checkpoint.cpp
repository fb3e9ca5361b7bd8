#include "app/checkpoint.hpp"

#include "io/output.hpp"

#include <lgvi/error.hpp>

#include <fmt/format.h>

#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace lgvi::app {

namespace {

/// The two groups of a checkpoint's fields besides the run's own: the stepper's and the observer's.
constexpr std::string_view stepper_group = "stepper.", recorder_group = "recorder.";

/// Whether a field is in a group (its name starts with the group's prefix).
bool under(const std::string& name, std::string_view group) { return name.starts_with(group); }

// A checkpoint file (native byte order, little-endian on every platform lgvi
// builds on) is
//   magic "LGVICKPT", int64 version, then
//   version >= 5: int64 field count, and per field: int64 name length, the
//     name, int64 type (CheckpointFields::Type), int64 element count, int64
//     byte size (= count x the element's size), the bytes;
//   versions 2 to 4: fixed fields and length-prefixed arrays (read_legacy).
// 3: N bodies, linear momentum statistics; 4: the same layout, written by an lgvi whose
// central field gives a body of mass + inertia its gravity-gradient term (resume_run
// refuses to continue an older one with the new model unless the scenario says model = "point");
// 5: named fields, the same model as 4.
constexpr char checkpoint_magic[8] = {'L', 'G', 'V', 'I', 'C', 'K', 'P', 'T'};
constexpr std::int64_t checkpoint_version = 5;

/// The statistics kept as numbers: (field name, first number, how many).
template <class Stats, class F>
void for_each_statistic(Stats& s, F f) {
  f("statistics.energy0", &s.energy0, 1);
  f("statistics.momentum0", s.momentum0.data(), 3);
  f("statistics.max_energy_error", &s.max_energy_error, 1);
  f("statistics.max_quat_error", &s.max_quat_error, 1);
  f("statistics.max_momentum_error", &s.max_momentum_error, 1);
  f("statistics.last_t", &s.last_t, 1);
  f("statistics.wall_seconds_before", &s.wall_seconds_before, 1);
  f("statistics.linear_momentum0", s.linear_momentum0.data(), 3);
  f("statistics.linear_momentum_scale", &s.linear_momentum_scale, 1);
  f("statistics.max_linear_momentum_error", &s.max_linear_momentum_error, 1);
  f("statistics.rot_energy0", &s.rot_energy0, 1);
  f("statistics.min_rot_energy", &s.min_rot_energy, 1);
  f("statistics.max_rot_energy", &s.max_rot_energy, 1);
  f("statistics.spin0", s.spin0.data(), 3);
  f("statistics.min_spin", &s.min_spin, 1);
  f("statistics.max_spin", &s.max_spin, 1);
  f("statistics.max_spin_change", &s.max_spin_change, 1);
}

/// The counters: (field name, the counter).
template <class Stats, class F>
void for_each_counter(Stats& s, F f) {
  f("statistics.iterations_total", s.iterations_total);
  f("statistics.potential_evaluations", s.potential_evaluations);
  f("statistics.steps_solved", s.steps_solved);
  f("statistics.iterations_max", s.iterations_max);
  f("statistics.last_k", s.last_k);
  f("statistics.contact_episodes", s.contact_episodes);
}

/// The run's own fields (everything but the stepper's).
CheckpointFields run_fields(const Checkpoint& c) {
  CheckpointFields f;
  f.put_i64("run.step", {c.k});
  std::vector<double> state;  // 13 numbers per body: x, q (scalar first), p, w
  state.reserve(13 * c.state.size());
  for (std::size_t a = 0; a < c.state.size(); ++a) {
    const Vector4<double> q = c.state.q[a].scalar_first();
    const Vector3<double>&x = c.state.x[a], &p = c.state.p[a], &w = c.state.w[a];
    state.insert(state.end(), {x.x(), x.y(), x.z(), q(0), q(1), q(2), q(3), p.x(), p.y(), p.z(), w.x(), w.y(), w.z()});
  }
  f.put_f64("run.state", std::move(state));
  if (!c.state.eta.empty()) {  // bodies with reaction wheels: per body its wheel count, then the momenta eta
    std::vector<std::int64_t> counts;
    std::vector<double> eta;
    for (const std::vector<double>& e : c.state.eta) {
      counts.push_back(static_cast<std::int64_t>(e.size()));
      eta.insert(eta.end(), e.begin(), e.end());
    }
    f.put_i64("run.wheel_counts", std::move(counts));
    f.put_f64("run.wheel_momenta", std::move(eta));
  }
  f.put_i64("run.checkpoint_every", {c.checkpoint_every});
  f.put_text("run.scenario_name", c.scenario_name);
  const RunStatistics& s = c.stats;
  for_each_statistic(s, [&](const char* name, const double* v, std::size_t n) { f.put_f64(name, {v, v + n}); });
  for_each_counter(s, [&](const char* name, std::int64_t v) { f.put_i64(name, {v}); });
  f.put_i64("statistics.observed", {s.observed ? 1 : 0});
  // Contact episodes: per episode a, b, first_k, last_k and first_t, last_t, max_depth, distance.
  std::vector<std::int64_t> steps;
  std::vector<double> values;
  for (const ContactEpisode& e : s.contacts) {
    steps.insert(steps.end(), {e.a, e.b, e.first_k, e.last_k});
    values.insert(values.end(), {e.first_t, e.last_t, e.max_depth, e.distance});
  }
  f.put_i64("statistics.contacts.steps", std::move(steps));
  f.put_f64("statistics.contacts.values", std::move(values));
  if (const ThermoStatistics& t = s.thermo; t.frames > 0) {  // a molecular run's (thermo_columns)
    f.put_f64("statistics.thermo", {t.temperature0, t.pressure0, t.temperature, t.pressure, t.temperature_sum,
                                    t.pressure_sum});
    f.put_i64("statistics.thermo_frames", {t.frames});
  }
  if (s.max_time_step > 0.0) f.put_f64("statistics.time_steps", {s.min_time_step, s.max_time_step});  // adaptive runs
  if (!s.wheels.empty()) {  // per wheel its largest speed and torque, and its time at a limit; then the totals
    std::vector<double> w;
    for (const RunStatistics::WheelStatistics& x : s.wheels) w.insert(w.end(), {x.max_speed, x.max_torque, x.time_limited});
    f.put_f64("statistics.wheels", std::move(w));
    f.put_f64("statistics.wheel_totals", {s.wheel_effort, s.wheels_saturated_time});
  }
  f.put_i64("sink.position", {c.sink.rows, c.sink.bytes, static_cast<std::int64_t>(c.sink.crc32)});
  return f;
}

SystemState state_from(const std::vector<double>& st) {
  SystemState state(st.size() / 13);
  for (std::size_t a = 0; a < state.size(); ++a) {
    const double* v = st.data() + 13 * a;
    state.x[a] = {v[0], v[1], v[2]};
    state.q[a] = S3d(v[3], v[4], v[5], v[6]);
    state.p[a] = {v[7], v[8], v[9]};
    state.w[a] = {v[10], v[11], v[12]};
  }
  return state;
}

/// Takes the run's fields from `f` into c; the stepper's ("stepper.*") stay
/// for the stepper, everything else must have been read.
void take_run_fields(CheckpointFields& f, Checkpoint& c) {
  c.k = f.i64_value("run.step");
  const std::vector<double>& st = f.f64("run.state");
  if (st.empty() || st.size() % 13 != 0)
    throw InvalidInput("checkpoint field 'run.state' holds " + std::to_string(st.size()) +
                       " values, expected 13 per body");
  c.state = state_from(st);
  if (f.has("run.wheel_counts")) {
    const std::vector<std::int64_t>& counts = f.i64("run.wheel_counts", c.state.size());
    const std::vector<double>& eta = f.f64("run.wheel_momenta");
    std::size_t total = 0;
    for (const std::int64_t n : counts) {
      if (n < 0 || static_cast<std::uint64_t>(n) > eta.size())
        throw InvalidInput("checkpoint field 'run.wheel_counts' holds a count of " + std::to_string(n) + " wheels");
      total += static_cast<std::size_t>(n);
    }
    if (total != eta.size())
      throw InvalidInput("checkpoint field 'run.wheel_momenta' holds " + std::to_string(eta.size()) +
                         " values, 'run.wheel_counts' " + std::to_string(total) + " wheels");
    c.state.eta.resize(c.state.size());
    std::size_t at = 0;
    for (std::size_t a = 0; a < c.state.size(); ++a) {
      const auto n = static_cast<std::size_t>(counts[a]);
      c.state.eta[a].assign(eta.begin() + static_cast<std::ptrdiff_t>(at), eta.begin() + static_cast<std::ptrdiff_t>(at + n));
      at += n;
    }
  }
  c.checkpoint_every = f.i64_value("run.checkpoint_every");
  c.scenario_name = f.text("run.scenario_name");
  RunStatistics& s = c.stats;
  for_each_statistic(s, [&](const char* name, double* v, std::size_t n) {
    const std::vector<double>& x = f.f64(name, n);
    std::copy(x.begin(), x.end(), v);
  });
  for_each_counter(s, [&](const char* name, std::int64_t& v) { v = f.i64_value(name); });
  s.observed = f.i64_value("statistics.observed") != 0;
  const std::vector<std::int64_t>& steps = f.i64("statistics.contacts.steps");
  const std::vector<double>& values = f.f64("statistics.contacts.values");
  if (steps.size() % 4 != 0 || values.size() != steps.size() ||
      steps.size() / 4 > RunStatistics::max_listed_contacts)
    throw InvalidInput("checkpoint fields 'statistics.contacts.steps' and 'statistics.contacts.values' hold " +
                       std::to_string(steps.size()) + " and " + std::to_string(values.size()) +
                       " values, expected 4 each per contact episode (at most " +
                       std::to_string(RunStatistics::max_listed_contacts) + " episodes)");
  s.contacts.resize(steps.size() / 4);
  for (std::size_t i = 0; i < s.contacts.size(); ++i) {
    ContactEpisode& e = s.contacts[i];
    e.a = steps[4 * i];
    e.b = steps[4 * i + 1];
    e.first_k = steps[4 * i + 2];
    e.last_k = steps[4 * i + 3];
    e.first_t = values[4 * i];
    e.last_t = values[4 * i + 1];
    e.max_depth = values[4 * i + 2];
    e.distance = values[4 * i + 3];
  }
  if (f.has("statistics.thermo")) {
    const std::vector<double>& t = f.f64("statistics.thermo", 6);
    s.thermo = {t[0], t[1], t[2], t[3], t[4], t[5], f.i64_value("statistics.thermo_frames")};
  }
  if (f.has("statistics.time_steps")) {
    const std::vector<double>& t = f.f64("statistics.time_steps", 2);
    s.min_time_step = t[0];
    s.max_time_step = t[1];
  }
  if (f.has("statistics.wheels")) {
    const std::vector<double>& w = f.f64("statistics.wheels");
    if (w.size() % 3 != 0)
      throw InvalidInput("checkpoint field 'statistics.wheels' holds " + std::to_string(w.size()) +
                         " values, expected 3 per wheel");
    s.wheels.resize(w.size() / 3);
    for (std::size_t i = 0; i < s.wheels.size(); ++i) s.wheels[i] = {w[3 * i], w[3 * i + 1], w[3 * i + 2]};
    const std::vector<double>& totals = f.f64("statistics.wheel_totals", 2);
    s.wheel_effort = totals[0];
    s.wheels_saturated_time = totals[1];
  }
  const std::vector<std::int64_t>& sink = f.i64("sink.position", 3);
  c.sink.rows = sink[0];
  c.sink.bytes = sink[1];
  c.sink.crc32 = static_cast<std::uint32_t>(sink[2]);
  std::vector<std::string> unknown;
  for (const CheckpointFields::Field& field : f.fields())
    if (!field.read && !under(field.name, stepper_group) && !under(field.name, recorder_group))
      unknown.push_back(field.name);
  if (!unknown.empty()) throw InvalidInput(CheckpointFields::unknown_fields_message(unknown));
}

/// Reads the bytes after the version of a file of versions 2 to 4 into c,
/// the stepper's numbers as the field "stepper.internal" (each stepper
/// knows that layout: see its load()).
void read_legacy(const std::string& path, const std::string& bytes, std::size_t pos, Checkpoint& c) {
  const std::int64_t version = c.version;
  auto fail = [&] { throw InvalidInput(path + ": not an lgvi checkpoint, or truncated"); };
  auto get = [&](auto& v) {
    if (pos + sizeof v > bytes.size()) fail();
    std::memcpy(&v, bytes.data() + pos, sizeof v);
    pos += sizeof v;
  };
  auto get_vec = [&](std::vector<double>& v) {
    std::int64_t n = 0;
    get(n);
    if (n < 0 || n > static_cast<std::int64_t>(bytes.size() / 8)) fail();
    v.resize(static_cast<std::size_t>(n));
    for (double& d : v) get(d);
  };
  get(c.k);
  std::vector<double> st;
  get_vec(st);
  if (st.empty() || st.size() % 13 != 0 || (version == 2 && st.size() != 13)) fail();
  c.state = state_from(st);
  std::vector<double> internal;
  get_vec(internal);
  c.stepper.put_f64("stepper.internal", std::move(internal));
  std::vector<double> s;
  get_vec(s);
  // 14 numbers: a checkpoint from before the rotation statistics (they
  // then cover the resumed leg only).
  if (version == 2 ? s.size() != 9u : (s.size() != 14u && s.size() != 23u)) fail();
  RunStatistics& r = c.stats;
  r.energy0 = s[0];
  r.momentum0 = {s[1], s[2], s[3]};
  r.max_energy_error = s[4];
  r.max_quat_error = s[5];
  r.max_momentum_error = s[6];
  r.last_t = s[7];
  r.wall_seconds_before = s[8];
  if (version > 2) {
    r.linear_momentum0 = {s[9], s[10], s[11]};
    r.linear_momentum_scale = s[12];
    r.max_linear_momentum_error = s[13];
  }
  if (s.size() != 23u) {
    // Unknown before this checkpoint: the summary says null rather than a
    // range of the resumed leg only (std::min/max keep the NaN).
    const double unknown = std::numeric_limits<double>::quiet_NaN();
    r.rot_energy0 = r.min_rot_energy = r.max_rot_energy = unknown;
    r.spin0 = Vector3<double>::Constant(unknown);
    r.min_spin = r.max_spin = r.max_spin_change = unknown;
  } else {
    r.rot_energy0 = s[14];
    r.min_rot_energy = s[15];
    r.max_rot_energy = s[16];
    r.spin0 = {s[17], s[18], s[19]};
    r.min_spin = s[20];
    r.max_spin = s[21];
    r.max_spin_change = s[22];
  }
  std::int64_t observed = 0, crc = 0;
  get(r.iterations_total);
  get(r.potential_evaluations);
  get(r.steps_solved);
  get(r.iterations_max);
  get(r.last_k);
  get(observed);
  r.observed = observed != 0;
  get(c.sink.rows);
  get(c.sink.bytes);
  get(crc);
  c.sink.crc32 = static_cast<std::uint32_t>(crc);
  get(c.checkpoint_every);
  std::int64_t name_size = 0;
  get(name_size);
  if (name_size < 0 || pos + static_cast<std::size_t>(name_size) > bytes.size()) fail();
  c.scenario_name = bytes.substr(pos, static_cast<std::size_t>(name_size));
  pos += static_cast<std::size_t>(name_size);
  if (pos == bytes.size()) return;  // written before contact episodes were recorded
  std::int64_t listed = 0;
  get(r.contact_episodes);
  get(listed);
  if (listed < 0 || static_cast<std::size_t>(listed) > RunStatistics::max_listed_contacts) fail();
  r.contacts.resize(static_cast<std::size_t>(listed));
  for (ContactEpisode& e : r.contacts) {
    get(e.a);
    get(e.b);
    get(e.first_k);
    get(e.last_k);
    get(e.first_t);
    get(e.last_t);
    get(e.max_depth);
    get(e.distance);
  }
  if (pos != bytes.size()) fail();
}

/// Reads the fields of a file of version 5 from `pos` on.
CheckpointFields read_fields(const std::string& path, const std::string& bytes, std::size_t pos) {
  std::string after = "the header";
  auto get = [&](std::int64_t& v, const char* what) {
    if (pos + sizeof v > bytes.size())
      throw InvalidInput(path + ": truncated checkpoint: it ends inside the " + what + " of the field after " + after);
    std::memcpy(&v, bytes.data() + pos, sizeof v);
    pos += sizeof v;
  };
  std::int64_t count = 0;
  get(count, "count");
  if (count < 0 || static_cast<std::uint64_t>(count) > bytes.size())
    throw InvalidInput(path + ": damaged checkpoint: " + std::to_string(count) + " fields");
  CheckpointFields f;
  for (std::int64_t i = 0; i < count; ++i) {
    std::int64_t name_size = 0, type = 0, n = 0, size = 0;
    get(name_size, "name");
    if (name_size <= 0 || static_cast<std::uint64_t>(name_size) > bytes.size() - pos)
      throw InvalidInput(fmt::format("{}: truncated or damaged checkpoint: the name of the field after {} is cut off "
                                     "or has a length of {}",
                                     path, after, name_size));
    const std::string name = bytes.substr(pos, static_cast<std::size_t>(name_size));
    pos += static_cast<std::size_t>(name_size);
    after = "'" + name + "'";
    const std::string field = fmt::format("{}: checkpoint field '{}'", path, name);
    if (pos + 3 * sizeof(std::int64_t) > bytes.size()) throw InvalidInput(field + " is truncated (its header is cut off)");
    get(type, "type");
    get(n, "count");
    get(size, "size");
    std::size_t element = 0;
    if (type == static_cast<std::int64_t>(CheckpointFields::Type::F64) ||
        type == static_cast<std::int64_t>(CheckpointFields::Type::I64))
      element = 8;
    else if (type == static_cast<std::int64_t>(CheckpointFields::Type::Text))
      element = 1;
    else
      throw InvalidInput(field + " has an unknown type (" + std::to_string(type) +
                         "): written by a newer lgvi? resume with the lgvi that wrote it");
    // n is checked against size / element first, so that n * element cannot wrap around.
    if (n < 0 || size < 0 || static_cast<std::uint64_t>(n) > static_cast<std::uint64_t>(size) / element ||
        static_cast<std::uint64_t>(size) != static_cast<std::uint64_t>(n) * element)
      throw InvalidInput(field + " is damaged: " + std::to_string(size) + " bytes for " + std::to_string(n) + " " +
                         CheckpointFields::type_name(static_cast<CheckpointFields::Type>(type)) + " values");
    if (static_cast<std::uint64_t>(size) > bytes.size() - pos)
      throw InvalidInput(field + " is truncated: it holds " + std::to_string(size) + " bytes, the file ends after " +
                         std::to_string(bytes.size() - pos));
    const char* data = bytes.data() + pos;
    const auto un = static_cast<std::size_t>(n);
    try {
      switch (static_cast<CheckpointFields::Type>(type)) {
        case CheckpointFields::Type::F64: {
          std::vector<double> v(un);
          if (un > 0) std::memcpy(v.data(), data, 8 * un);  // an empty vector's data() may be null
          f.put_f64(name, std::move(v));
          break;
        }
        case CheckpointFields::Type::I64: {
          std::vector<std::int64_t> v(un);
          if (un > 0) std::memcpy(v.data(), data, 8 * un);
          f.put_i64(name, std::move(v));
          break;
        }
        case CheckpointFields::Type::Text: f.put_text(name, std::string(data, un)); break;
      }
    } catch (const InvalidInput& e) {
      throw InvalidInput(path + ": " + e.what());
    }
    pos += static_cast<std::size_t>(size);
  }
  if (pos != bytes.size())
    throw InvalidInput(path + ": damaged checkpoint: " + std::to_string(bytes.size() - pos) +
                       " bytes after its last field (" + after + ")");
  return f;
}

}  // namespace

void write_checkpoint(const std::string& path, const Checkpoint& c) {
  CheckpointFields fields = run_fields(c);
  for (const CheckpointFields::Field& field : c.stepper.fields()) {
    if (!under(field.name, stepper_group))
      throw std::logic_error("checkpoint field '" + field.name + "' of the stepper is not under 'stepper.'");
    fields.put(field);
  }
  for (const CheckpointFields::Field& field : c.recorder.fields()) {
    if (!under(field.name, recorder_group))
      throw std::logic_error("checkpoint field '" + field.name + "' of the recorder is not under 'recorder.'");
    fields.put(field);
  }
  std::string bytes(checkpoint_magic, sizeof checkpoint_magic);
  auto put = [&](std::int64_t v) { bytes.append(reinterpret_cast<const char*>(&v), sizeof v); };
  put(checkpoint_version);
  put(static_cast<std::int64_t>(fields.fields().size()));
  for (const CheckpointFields::Field& field : fields.fields()) {
    put(static_cast<std::int64_t>(field.name.size()));
    bytes += field.name;
    put(static_cast<std::int64_t>(field.type));
    put(static_cast<std::int64_t>(field.count()));
    switch (field.type) {
      case CheckpointFields::Type::F64:
        put(static_cast<std::int64_t>(8 * field.f64.size()));
        bytes.append(reinterpret_cast<const char*>(field.f64.data()), 8 * field.f64.size());
        break;
      case CheckpointFields::Type::I64:
        put(static_cast<std::int64_t>(8 * field.i64.size()));
        bytes.append(reinterpret_cast<const char*>(field.i64.data()), 8 * field.i64.size());
        break;
      case CheckpointFields::Type::Text:
        put(static_cast<std::int64_t>(field.text.size()));
        bytes += field.text;
        break;
    }
  }
  write_file_atomically(path, bytes);
}

Checkpoint read_checkpoint(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InvalidInput(path + ": no checkpoint here (was the run started with --checkpoint-every N?)");
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  constexpr std::size_t header = sizeof checkpoint_magic + sizeof(std::int64_t);
  if (bytes.size() < header || std::memcmp(bytes.data(), checkpoint_magic, sizeof checkpoint_magic) != 0)
    throw InvalidInput(path + ": not an lgvi checkpoint, or truncated");
  Checkpoint c;
  c.path = path;
  std::memcpy(&c.version, bytes.data() + sizeof checkpoint_magic, sizeof c.version);
  if (c.version > checkpoint_version)
    throw InvalidInput(path + ": checkpoint version " + std::to_string(c.version) +
                       " was written by a newer lgvi (this one reads versions 2 to " +
                       std::to_string(checkpoint_version) + "); resume with the lgvi that wrote it");
  if (c.version < 2)
    throw InvalidInput(path + ": checkpoint version " + std::to_string(c.version) + " is not supported by this lgvi");
  // Versions 2 (one body, no linear momentum statistics) to 4 still resume.
  if (c.version < 5) {
    read_legacy(path, bytes, header, c);
    return c;
  }
  CheckpointFields fields = read_fields(path, bytes, header);
  try {
    take_run_fields(fields, c);
  } catch (const InvalidInput& e) {
    throw InvalidInput(path + ": " + e.what());
  }
  for (const CheckpointFields::Field& field : fields.fields())
    if (!field.read) (under(field.name, recorder_group) ? c.recorder : c.stepper).put(field);
  return c;
}

}  // namespace lgvi::app
