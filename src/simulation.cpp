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

ScenarioPotential scenario_potential(const Scenario& s) {
  switch (s.potential.kind) {
    case PotentialKind::Central: return CentralGravity(s.body, s.potential.mu, s.potential.stop_at_contact);
    case PotentialKind::Uniform: return UniformGravity(s.body, s.potential.g);
    case PotentialKind::HeavyTop: return HeavyTop(s.body, s.potential.g, s.potential.pivot_to_com);
    case PotentialKind::None: break;
  }
  return NoPotential{};
}

namespace {

/// The observer: diagnostics at every step, a row every `output_every` steps.
struct Recorder {
  const Scenario& scenario;
  TrajectorySink& sink;
  RunStatistics& stats;

  void operator()(const StepInfo& i) {
    const RigidBodyState& s = i.state;
    const double energy = total_energy(s, scenario.body, i.evaluation);
    const Vector3<double> L = angular_momentum(s);
    if (i.k == 0) {
      stats.energy0 = energy;
      stats.momentum0 = L;
    } else {
      stats.iterations_total += i.solve.iterations;
      stats.iterations_max = std::max<std::int64_t>(stats.iterations_max, i.solve.iterations);
      ++stats.steps_solved;
    }
    const double de = energy - stats.energy0, dq = s.q.norm_error(), dl = (L - stats.momentum0).norm();
    stats.max_energy_error = std::max(stats.max_energy_error, std::abs(de));
    stats.max_quat_error = std::max(stats.max_quat_error, std::abs(dq));
    stats.max_momentum_error = std::max(stats.max_momentum_error, dl);
    stats.last_t = i.t;
    stats.last_k = i.k;
    stats.observed = true;
    if (i.k % scenario.output_every == 0 || i.k == scenario.integrator.steps) {
      const auto& q = s.q.quaternion();
      const double row[trajectory_columns] = {i.t,    s.x.x(), s.x.y(), s.x.z(), q.w(),   q.x(),   q.y(),
                                              q.z(),  s.p.x(), s.p.y(), s.p.z(), s.w.x(), s.w.y(), s.w.z(),
                                              energy, de,      dq,      L.x(),   L.y(),   L.z(),   dl};
      sink.row(row);
    }
  }
};

template <class Stepper>
SimulationResult run_with(Stepper& stepper, const Scenario& sc, TrajectorySink& sink, const SimulationOptions& opt) {
  SimulationResult result;
  RunStatistics& stats = result.stats;
  RigidBodyState state = sc.initial;
  std::int64_t k0 = 0;
  if (opt.resume) {
    stats = opt.resume->stats;
    state = opt.resume->state;
    k0 = opt.resume->k;
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
        stepper.resume(state, opt.resume->stepper_internal);
      } catch (const StepFailure& f) {
        throw IntegrationFailure(k0, static_cast<double>(k0) * h, f);
      }
    } else {
      try {
        stepper.initialize(state);
      } catch (const StepFailure& f) {
        throw IntegrationFailure(0, 0.0, f);
      }
      recorder(StepInfo{0, 0.0, state, stepper.evaluation(), SolveReport{}});
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
      reached = integrate_range(stepper, state, 0.0, reached, end, recorder, stop_requested);
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

JsonObject setup_json(const Scenario& s) {
  JsonObject body;
  body.number("mass", s.body.mass());
  std::string inertia = "[";
  for (int i = 0; i < 3; ++i)
    inertia += (i ? ", [" : "[") + json_number(s.body.inertia()(i, 0)) + ", " + json_number(s.body.inertia()(i, 1)) +
               ", " + json_number(s.body.inertia()(i, 2)) + "]";
  body.raw("inertia", inertia + "]");
  std::string balls = "[";
  for (std::size_t i = 0; i < s.body.balls().size(); ++i) {
    const Ball& b = s.body.balls()[i];
    balls += fmt::format("{}{{\"position\": [{}, {}, {}], \"mass\": {}, \"radius\": {}}}", i ? ", " : "",
                         json_number(b.position.x()), json_number(b.position.y()), json_number(b.position.z()),
                         json_number(b.mass), json_number(b.radius));
  }
  body.raw("balls", balls + "]");
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
  o.object("body", body).object("potential", pot).object("integrator", integ).integer("output_every", s.output_every);
  return o;
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
constexpr std::int64_t checkpoint_version = 2;

}  // namespace

namespace {

/// Counts evaluations (reported as potential_evaluations: the cost measure
/// of `lgvi compare`), at the price of one increment each.
template <Potential P>
struct CountingPotential {
  P inner;
  std::int64_t* count;
  PotentialEvaluation evaluate(const Vector3<double>& x, const S3d& q) const {
    ++*count;
    return inner.evaluate(x, q);
  }
};

template <class AnyP>
SimulationResult simulate_with(const Scenario& sc, const AnyP& potential, TrajectorySink& sink,
                               const SimulationOptions& opt) {
  if (opt.checkpoint_every > 0 && opt.checkpoint_path.empty())
    throw InvalidInput("checkpoint_every is set but no checkpoint path is given");
  return std::visit(
      [&](const auto& pot) -> SimulationResult {
        using P = std::decay_t<decltype(pot)>;
        std::int64_t count = 0;
        const CountingPotential<P> counted{pot, &count};
        SimulationResult r = with_stepper<std::is_same_v<P, NoPotential>>(
            sc, counted, [&](auto& stepper) { return run_with(stepper, sc, sink, opt); });
        r.stats.potential_evaluations += count;
        return r;
      },
      potential);
}
}  // namespace

SimulationResult simulate(const Scenario& sc, TrajectorySink& sink, const SimulationOptions& opt) {
  return simulate_with(sc, scenario_potential(sc), sink, opt);
}

SimulationResult simulate(const Scenario& sc, const CallablePotential& potential, TrajectorySink& sink,
                          const SimulationOptions& opt) {
  return simulate_with(sc, std::variant<CallablePotential>(potential), sink, opt);
}

std::string summary_json(const Scenario& sc, const SimulationResult& r) {
  const RunStatistics& st = r.stats;
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
      .number("solver_iterations_mean", st.steps_solved ? static_cast<double>(st.iterations_total) /
                                                              static_cast<double>(st.steps_solved)
                                                        : 0.0)
      .integer("solver_iterations_max", st.iterations_max)
      .integer("potential_evaluations", st.potential_evaluations)
      .object("final", state_json(r.final_state))
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
  put_vec({c.state.x.x(), c.state.x.y(), c.state.x.z(), c.state.q.w(), c.state.q.vec().x(), c.state.q.vec().y(),
           c.state.q.vec().z(), c.state.p.x(), c.state.p.y(), c.state.p.z(), c.state.w.x(), c.state.w.y(),
           c.state.w.z()});
  put_vec(c.stepper_internal);
  const RunStatistics& s = c.stats;
  put_vec({s.energy0, s.momentum0.x(), s.momentum0.y(), s.momentum0.z(), s.max_energy_error, s.max_quat_error,
           s.max_momentum_error, s.last_t, s.wall_seconds_before});
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
    if (n < 0 || n > 1 << 20) fail();
    v.resize(static_cast<std::size_t>(n));
    for (double& d : v) get(d);
  };
  if (bytes.size() < sizeof checkpoint_magic || std::memcmp(bytes.data(), checkpoint_magic, sizeof checkpoint_magic) != 0)
    fail();
  pos = sizeof checkpoint_magic;
  std::int64_t version = 0;
  get(version);
  if (version != checkpoint_version) throw InvalidInput(path + ": checkpoint version " + std::to_string(version) +
                                                        " is not supported by this lgvi");
  Checkpoint c;
  get(c.k);
  std::vector<double> st;
  get_vec(st);
  if (st.size() != 13) fail();
  c.state.x = {st[0], st[1], st[2]};
  c.state.q = S3d(st[3], st[4], st[5], st[6]);
  c.state.p = {st[7], st[8], st[9]};
  c.state.w = {st[10], st[11], st[12]};
  get_vec(c.stepper_internal);
  std::vector<double> s;
  get_vec(s);
  if (s.size() != 9) fail();
  RunStatistics& r = c.stats;
  r.energy0 = s[0];
  r.momentum0 = {s[1], s[2], s[3]};
  r.max_energy_error = s[4];
  r.max_quat_error = s[5];
  r.max_momentum_error = s[6];
  r.last_t = s[7];
  r.wall_seconds_before = s[8];
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
