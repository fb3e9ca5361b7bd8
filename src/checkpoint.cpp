#include "checkpoint.hpp"

#include "output.hpp"

#include <lgvi/error.hpp>

#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>

namespace lgvi::app {

namespace {

// Checkpoint file: magic, version, then fixed fields and length-prefixed arrays.
constexpr char checkpoint_magic[8] = {'L', 'G', 'V', 'I', 'C', 'K', 'P', 'T'};
// 3: N bodies, linear momentum statistics; 4: the same layout, written by an lgvi whose
// central field gives a body of mass + inertia its gravity-gradient term (resume_run
// refuses to continue an older one with the new model unless the scenario says model = "point").
constexpr std::int64_t checkpoint_version = 4;

}  // namespace

void write_checkpoint(const std::string& path, const Checkpoint& c) {
  std::string bytes(checkpoint_magic, sizeof checkpoint_magic);
  auto put = [&](const auto& v) { bytes.append(reinterpret_cast<const char*>(&v), sizeof v); };
  auto put_vec = [&](const std::vector<double>& v) {
    put(static_cast<std::int64_t>(v.size()));
    for (double d : v) put(d);
  };
  put(checkpoint_version);
  put(c.k);
  std::vector<double> state;  // 13 numbers per body: x, q (scalar first), p, w
  state.reserve(13 * c.state.size());
  for (std::size_t a = 0; a < c.state.size(); ++a) {
    const Vector4<double> q = c.state.q[a].scalar_first();
    const Vector3<double>&x = c.state.x[a], &p = c.state.p[a], &w = c.state.w[a];
    state.insert(state.end(), {x.x(), x.y(), x.z(), q(0), q(1), q(2), q(3), p.x(), p.y(), p.z(), w.x(), w.y(), w.z()});
  }
  put_vec(state);
  put_vec(c.stepper_internal);
  const RunStatistics& s = c.stats;
  put_vec({s.energy0, s.momentum0.x(), s.momentum0.y(), s.momentum0.z(), s.max_energy_error, s.max_quat_error,
           s.max_momentum_error, s.last_t, s.wall_seconds_before, s.linear_momentum0.x(), s.linear_momentum0.y(),
           s.linear_momentum0.z(), s.linear_momentum_scale, s.max_linear_momentum_error, s.rot_energy0,
           s.min_rot_energy, s.max_rot_energy, s.spin0.x(), s.spin0.y(), s.spin0.z(), s.min_spin, s.max_spin,
           s.max_spin_change});
  put(s.iterations_total);
  put(s.potential_evaluations);
  put(s.steps_solved);
  put(s.iterations_max);
  put(s.last_k);
  put(static_cast<std::int64_t>(s.observed));
  put(c.sink.rows);
  put(c.sink.bytes);
  put(static_cast<std::int64_t>(c.sink.crc32));
  put(c.checkpoint_every);
  put(static_cast<std::int64_t>(c.scenario_name.size()));
  bytes += c.scenario_name;
  // Contact episodes: a trailer that checkpoints written before it lack (they
  // resume with none).
  put(s.contact_episodes);
  put(static_cast<std::int64_t>(s.contacts.size()));
  for (const ContactEpisode& e : s.contacts) {
    put(e.a);
    put(e.b);
    put(e.first_k);
    put(e.last_k);
    put(e.first_t);
    put(e.last_t);
    put(e.max_depth);
    put(e.distance);
  }
  write_file_atomically(path, bytes);
}

Checkpoint read_checkpoint(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InvalidInput(path + ": no checkpoint here (was the run started with --checkpoint-every N?)");
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::size_t pos = 0;
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
  if (bytes.size() < sizeof checkpoint_magic || std::memcmp(bytes.data(), checkpoint_magic, sizeof checkpoint_magic) != 0)
    fail();
  pos = sizeof checkpoint_magic;
  std::int64_t version = 0;
  get(version);
  // Versions 2 (one body, no linear momentum statistics) and 3 still resume.
  if (version != checkpoint_version && version != 2 && version != 3)
    throw InvalidInput(path + ": checkpoint version " + std::to_string(version) + " is not supported by this lgvi");
  Checkpoint c;
  c.version = version;
  get(c.k);
  std::vector<double> st;
  get_vec(st);
  if (st.empty() || st.size() % 13 != 0 || (version == 2 && st.size() != 13)) fail();
  c.state = SystemState(st.size() / 13);
  for (std::size_t a = 0; a < c.state.size(); ++a) {
    const double* v = st.data() + 13 * a;
    c.state.x[a] = {v[0], v[1], v[2]};
    c.state.q[a] = S3d(v[3], v[4], v[5], v[6]);
    c.state.p[a] = {v[7], v[8], v[9]};
    c.state.w[a] = {v[10], v[11], v[12]};
  }
  get_vec(c.stepper_internal);
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
  if (pos == bytes.size()) return c;  // written before contact episodes were recorded
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
  return c;
}

}  // namespace lgvi::app
