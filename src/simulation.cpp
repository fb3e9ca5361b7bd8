#include "simulation.hpp"

#include "method_dispatch.hpp"
#include "output.hpp"

#include <lgvi/error.hpp>
#include <lgvi/integrate.hpp>
#include <lgvi/lgvi.hpp>
#include <lgvi/potential.hpp>

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <variant>

namespace lgvi::app {

namespace {

}  // namespace

namespace {
/// The [potential] for body a.
ScenarioPotential body_potential(const Scenario& s, std::size_t a) {
  const RigidBody& body = s.system.body(a);
  switch (s.potential.kind) {
    case PotentialKind::Central: return CentralGravity(body, s.potential.mu, s.potential.stop_at_contact);
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
    external = ExternalField<CallablePotential>::uniform(*field, s.bodies(), par);
  } else {
    switch (s.potential.kind) {
      case PotentialKind::Central: external = field_of<CentralGravity>(s, par); break;
      case PotentialKind::Uniform: external = field_of<UniformGravity>(s, par); break;
      case PotentialKind::HeavyTop: external = field_of<HeavyTop>(s, par); break;
      case PotentialKind::None: break;
    }
  }
  ScenarioSystemPotential::Mutual mutual = NoMutualInteraction{};
  const InteractionSpec& i = s.interaction;
  switch (i.kind) {
    case InteractionKind::GravityBalls: mutual = MutualGravityBalls(s.system, i.G, par); break;
    case InteractionKind::GravityInertia: mutual = MutualGravityInertia(s.system, i.G, par); break;
    case InteractionKind::LennardJones: mutual = LennardJones(s.system, i.epsilon, i.sigma, i.cutoff, par, i.skin); break;
    case InteractionKind::None: break;
  }
  return {std::move(external), std::move(mutual), evaluations};
}

TrajectoryLayout scenario_layout(const Scenario& s) {
  return s.bodies_format ? TrajectoryLayout::long_format(static_cast<std::int64_t>(s.bodies()))
                         : TrajectoryLayout::single_body();
}

namespace {

/// The observer: diagnostics at every step, rows every `output_every` steps
/// (one row per body in the long layout).
struct Recorder {
  const Scenario& scenario;
  TrajectorySink& sink;
  RunStatistics& stats;
  std::vector<double> row_ = std::vector<double>(bodies_trajectory_columns);

  void operator()(const SystemStepInfo& i) {
    const SystemState& s = i.state;
    const std::size_t n = s.size();
    const double energy = total_energy(s, scenario.system, i.evaluation);
    const Vector3<double> L = angular_momentum(s);
    const Vector3<double> P = linear_momentum(s);
    if (i.k == 0) {
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
    const double de = energy - stats.energy0, dl = (L - stats.momentum0).norm();
    // |P - P0| relative to sum |p_a0|; absolute when every body starts at rest.
    const double dp_abs = (P - stats.linear_momentum0).norm();
    const double dp = stats.linear_momentum_scale > 0.0 ? dp_abs / stats.linear_momentum_scale : dp_abs;
    double dq = s.q[0].norm_error();
    for (std::size_t a = 1; a < n; ++a)
      if (std::abs(s.q[a].norm_error()) > std::abs(dq)) dq = s.q[a].norm_error();
    stats.max_energy_error = std::max(stats.max_energy_error, std::abs(de));
    stats.max_quat_error = std::max(stats.max_quat_error, std::abs(dq));
    stats.max_momentum_error = std::max(stats.max_momentum_error, dl);
    stats.max_linear_momentum_error = std::max(stats.max_linear_momentum_error, dp);
    stats.last_t = i.t;
    stats.last_k = i.k;
    stats.observed = true;
    if (i.k % scenario.output_every != 0 && i.k != scenario.integrator.steps) return;
    if (!scenario.bodies_format) {
      const auto& q = s.q[0].quaternion();
      const Vector3<double>&x = s.x[0], &p = s.p[0], &w = s.w[0];
      const double row[trajectory_columns] = {i.t,    x.x(), x.y(), x.z(), q.w(),   q.x(),   q.y(),
                                              q.z(),  p.x(), p.y(), p.z(), w.x(),   w.y(),   w.z(),
                                              energy, de,    dq,    L.x(), L.y(),   L.z(),   dl};
      sink.row(row);
      return;
    }
    for (std::size_t a = 0; a < n; ++a) {
      const auto& q = s.q[a].quaternion();
      const Vector3<double>&x = s.x[a], &p = s.p[a], &w = s.w[a];
      const double row[bodies_trajectory_columns] = {
          i.t,   static_cast<double>(a), x.x(), x.y(), x.z(), q.w(), q.x(),  q.y(),  q.z(),
          p.x(), p.y(), p.z(), w.x(), w.y(), w.z(), s.q[a].norm_error(), energy, de, P.x(), P.y(), P.z(), dp,
          L.x(), L.y(), L.z(), dl};
      sink.row(row);
    }
  }
};

template <class Stepper>
SimulationResult run_with(Stepper& stepper, const Scenario& sc, TrajectorySink& sink, const SimulationOptions& opt) {
  SimulationResult result;
  RunStatistics& stats = result.stats;
  SystemState state = sc.initial_state;
  std::int64_t k0 = 0;
  if (opt.resume) {
    stats = opt.resume->stats;
    state = opt.resume->state;
    k0 = opt.resume->k;
    if (state.size() != sc.bodies())
      throw InvalidInput("checkpoint: " + std::to_string(state.size()) + " bodies, the scenario has " +
                         std::to_string(sc.bodies()));
  }
  Recorder recorder{sc, sink, stats};
  const double h = sc.integrator.step;
  const auto start = std::chrono::steady_clock::now();
  auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };
  auto checkpoint = [&](std::int64_t k) {
    Checkpoint c;
    c.k = k;
    c.state = state;
    c.stepper_internal = stepper.internal_state();
    c.stats = stats;
    c.stats.wall_seconds_before += elapsed();
    c.sink = sink.sync();
    c.checkpoint_every = opt.checkpoint_every;
    c.scenario_name = sc.name;
    write_checkpoint(opt.checkpoint_path, c);
  };
  std::int64_t reached = k0;
  try {
    if (opt.resume) {
      try {
        stepper.resume(state, static_cast<double>(k0) * h, opt.resume->stepper_internal);
      } catch (const StepFailure& f) {
        throw IntegrationFailure(k0, static_cast<double>(k0) * h, f);
      }
    } else {
      try {
        stepper.initialize(state, 0.0);
      } catch (const StepFailure& f) {
        throw IntegrationFailure(0, 0.0, f);
      }
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
    auto stop_requested = [&] { return opt.stop_flag && *opt.stop_flag != 0; };
    while (reached < n) {
      const std::int64_t end = next_stop(reached);
      reached = integrate_range(stepper, state, 0.0, h, reached, end, recorder, stop_requested);
      if (stop_requested()) break;
      if (opt.checkpoint_every > 0 && reached % opt.checkpoint_every == 0 && reached < n) checkpoint(reached);
      if (opt.progress) opt.progress(reached, static_cast<double>(reached) * h);
    }
    if (reached < n) {
      result.interrupted = true;
      if (opt.checkpoint_every > 0) checkpoint(reached);
    } else {
      result.completed = true;
    }
  } catch (const IntegrationFailure& e) {
    result.error = e.what();
  }
  result.wall_seconds = stats.wall_seconds_before + elapsed();
  result.final_state = state;
  return result;
}

std::vector<double> to_vector(const Eigen::Ref<const Eigen::VectorXd>& v) { return {v.data(), v.data() + v.size()}; }

/// A body's inertia and balls as JSON arrays (one line each).
std::string inertia_json(const RigidBody& b) {
  std::string inertia = "[";
  for (int i = 0; i < 3; ++i)
    inertia += (i ? ", [" : "[") + json_number(b.inertia()(i, 0)) + ", " + json_number(b.inertia()(i, 1)) + ", " +
               json_number(b.inertia()(i, 2)) + "]";
  return inertia + "]";
}
std::string balls_json(const RigidBody& b) {
  std::string balls = "[";
  for (std::size_t i = 0; i < b.balls().size(); ++i) {
    const Ball& ball = b.balls()[i];
    balls += fmt::format("{}{{\"position\": [{}, {}, {}], \"mass\": {}, \"radius\": {}}}", i ? ", " : "",
                         json_number(ball.position.x()), json_number(ball.position.y()),
                         json_number(ball.position.z()), json_number(ball.mass), json_number(ball.radius));
  }
  return balls + "]";
}

/// One element per line (lists of bodies); JsonObject::str indents the lines.
std::string json_lines(const std::vector<std::string>& elements) {
  std::string s = "[";
  for (std::size_t i = 0; i < elements.size(); ++i) s += (i ? ",\n  " : "\n  ") + elements[i];
  return s + (elements.empty() ? "]" : "\n]");
}

JsonObject setup_json(const Scenario& s) {
  JsonObject pot;
  pot.string("kind", to_string(s.potential.kind));
  if (s.potential.kind == PotentialKind::Central)
    pot.number("mu", s.potential.mu).boolean("stop_at_contact", s.potential.stop_at_contact);
  if (s.potential.kind == PotentialKind::Uniform || s.potential.kind == PotentialKind::HeavyTop)
    pot.array("g", to_vector(s.potential.g));
  if (s.potential.kind == PotentialKind::HeavyTop) pot.array("pivot_to_com", to_vector(s.potential.pivot_to_com));
  JsonObject integ;
  integ.string("method", to_string(s.integrator.method))
      .string("solver", to_string(s.integrator.solver.kind))
      .number("step", s.integrator.step)
      .number("tolerance", s.integrator.solver.tolerance)
      .integer("max_iterations", s.integrator.solver.max_iterations)
      .integer("predictor_order", s.integrator.solver.predictor_order);
  JsonObject o;
  if (!s.bodies_format) {
    JsonObject body;
    body.number("mass", s.body().mass()).raw("inertia", inertia_json(s.body())).raw("balls", balls_json(s.body()));
    o.object("body", body);
  } else {
    std::vector<std::string> bodies;
    for (std::size_t a = 0; a < s.bodies(); ++a) {
      const RigidBody& b = s.system.body(a);
      bodies.push_back(fmt::format("{{\"name\": {}, \"mass\": {}, \"inertia\": {}, \"balls\": {}}}",
                                   json_string(s.system.name(a)), json_number(b.mass()), inertia_json(b),
                                   balls_json(b)));
    }
    o.raw("bodies", json_lines(bodies));
  }
  o.object("potential", pot);
  if (s.bodies_format) {
    JsonObject inter;
    inter.string("kind", to_string(s.interaction.kind));
    if (s.interaction.kind == InteractionKind::GravityBalls || s.interaction.kind == InteractionKind::GravityInertia)
      inter.number("G", s.interaction.G)
          .string("model", s.interaction.kind == InteractionKind::GravityBalls ? "balls" : "inertia");
    if (s.interaction.kind == InteractionKind::LennardJones)
      inter.number("epsilon", s.interaction.epsilon)
          .number("sigma", s.interaction.sigma)
          .number("cutoff", s.interaction.cutoff)
          .number("skin", s.interaction.skin);
    o.object("interaction", inter);
  }
  o.object("integrator", integ).integer("output_every", s.output_every);
  return o;
}

/// A body's state on one line, with its name.
std::string body_state_json(const std::string& name, const RigidBodyState& s) {
  const Vector4<double> q = s.q.scalar_first();
  return fmt::format("{{\"name\": {}, \"position\": [{}, {}, {}], \"quaternion\": [{}, {}, {}, {}], "
                     "\"momentum\": [{}, {}, {}], \"w\": [{}, {}, {}]}}",
                     json_string(name), json_number(s.x.x()), json_number(s.x.y()), json_number(s.x.z()),
                     json_number(q(0)), json_number(q(1)), json_number(q(2)), json_number(q(3)), json_number(s.p.x()),
                     json_number(s.p.y()), json_number(s.p.z()), json_number(s.w.x()), json_number(s.w.y()),
                     json_number(s.w.z()));
}

JsonObject state_json(const RigidBodyState& s) {
  JsonObject o;
  o.array("position", to_vector(s.x))
      .array("quaternion", {s.q.w(), s.q.quaternion().x(), s.q.quaternion().y(), s.q.quaternion().z()})
      .array("momentum", to_vector(s.p))
      .array("w", to_vector(s.w));
  return o;
}

// Checkpoint file: magic, version, then fixed fields and length-prefixed arrays.
constexpr char checkpoint_magic[8] = {'L', 'G', 'V', 'I', 'C', 'K', 'P', 'T'};
constexpr std::int64_t checkpoint_version = 3;  // 3: N bodies, linear momentum statistics

}  // namespace

namespace {

SimulationResult simulate_with(const Scenario& sc, const CallablePotential* field, TrajectorySink& sink,
                               const SimulationOptions& opt) {
  if (opt.checkpoint_every > 0 && opt.checkpoint_path.empty())
    throw InvalidInput("checkpoint_every is set but no checkpoint path is given");
  std::int64_t count = 0;
  const ScenarioSystemPotential potential = scenario_system_potential(sc, field, &count);
  SimulationResult r = with_stepper(sc, potential, scenario_parallelism(sc),
                                    [&](auto& stepper) { return run_with(stepper, sc, sink, opt); });
  r.stats.potential_evaluations += count;
  return r;
}
}  // namespace

SimulationResult simulate(const Scenario& sc, TrajectorySink& sink, const SimulationOptions& opt) {
  return simulate_with(sc, nullptr, sink, opt);
}

SimulationResult simulate(const Scenario& sc, const CallablePotential& potential, TrajectorySink& sink,
                          const SimulationOptions& opt) {
  return simulate_with(sc, &potential, sink, opt);
}

std::string summary_json(const Scenario& sc, const SimulationResult& r) {
  const RunStatistics& st = r.stats;
  std::vector<std::string> final_bodies;
  for (std::size_t a = 0; a < r.final_state.size(); ++a)
    final_bodies.push_back(body_state_json(sc.system.name(a), r.final_state.body(a)));
  const double l0 = st.momentum0.norm();
  JsonObject s;
  s.string("scenario", sc.name)
      .boolean("completed", r.completed)
      .string("error", r.error)
      .integer("steps", st.last_k)
      .integer("steps_planned", sc.integrator.steps)
      .number("duration", sc.integrator.step * static_cast<double>(sc.integrator.steps))
      .number("last_time", st.last_t)
      .number("wall_seconds", r.wall_seconds)
      .number("ns_per_step", st.last_k > 0 ? r.wall_seconds * 1e9 / static_cast<double>(st.last_k) : 0.0)
      .number("initial_energy", st.observed ? st.energy0 : std::nan(""))
      .array("initial_angular_momentum", to_vector(st.momentum0))
      .number("max_abs_energy_error", st.max_energy_error)
      .number("max_abs_quat_norm_error", st.max_quat_error)
      .number("max_momentum_error", st.max_momentum_error)
      .number("max_relative_momentum_error", l0 > 0 ? st.max_momentum_error / l0 : st.max_momentum_error)
      .number("max_linear_momentum_error", st.max_linear_momentum_error)
      .number("solver_iterations_mean", st.steps_solved ? static_cast<double>(st.iterations_total) /
                                                              static_cast<double>(st.steps_solved)
                                                        : 0.0)
      .integer("solver_iterations_max", st.iterations_max)
      .integer("potential_evaluations", st.potential_evaluations)
      .object("final", state_json(r.final_state.body(0)))
      .raw("final_bodies", json_lines(final_bodies))
      .object("setup", setup_json(sc));
  return s.str() + "\n";
}

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
           s.linear_momentum0.z(), s.linear_momentum_scale, s.max_linear_momentum_error});
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
  // Version 2 (one body, no linear momentum statistics) still resumes.
  if (version != checkpoint_version && version != 2)
    throw InvalidInput(path + ": checkpoint version " + std::to_string(version) + " is not supported by this lgvi");
  Checkpoint c;
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
  if (s.size() != (version == 2 ? 9u : 14u)) fail();
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
  if (name_size < 0 || pos + static_cast<std::size_t>(name_size) != bytes.size()) fail();
  c.scenario_name = bytes.substr(pos, static_cast<std::size_t>(name_size));
  return c;
}

}  // namespace lgvi::app
