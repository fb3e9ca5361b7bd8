#include "summary.hpp"

#include "output.hpp"

#include <fmt/format.h>

#include <cmath>
#include <string>
#include <vector>

namespace lgvi::app {

namespace {

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
  if (s.potential.kind == PotentialKind::Central && s.potential.j2 != 0.0)
    pot.number("j2", s.potential.j2)
        .number("reference_radius", s.potential.reference_radius)
        .array("pole", to_vector(s.potential.pole));
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
  if (!s.integrator.composition.is_plain())
    integ.integer("order", s.integrator.composition.order()).array("composition", s.integrator.composition.gamma());
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
  if (!s.forcing.empty()) o.integer("forcing_terms", static_cast<std::int64_t>(s.forcing.size()));
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

/// What the scenario conserves (conservation_laws), and which "error" keys
/// are changes.
std::string conserved_json(const Scenario& sc) {
  using Angular = ConservationLaws::Angular;
  const ConservationLaws laws = conservation_laws(sc);
  std::vector<std::string> conserved, changes;
  conserved.emplace_back(laws.forced ? "\"energy_minus_work\"" : "\"energy\"");
  if (laws.angular_momentum == Angular::Conserved)
    conserved.emplace_back("\"angular_momentum\"");
  else if (laws.angular_momentum == Angular::AlongPole)
    conserved.emplace_back("\"angular_momentum_along_pole\"");
  if (laws.angular_momentum != Angular::Conserved)
    changes.insert(changes.end(), {"\"max_momentum_error\"", "\"max_relative_momentum_error\""});
  if (laws.linear_momentum)
    conserved.emplace_back("\"linear_momentum\"");
  else
    changes.emplace_back("\"max_linear_momentum_error\"");
  auto list = [](const std::vector<std::string>& v) {
    std::string o = "[";
    for (std::size_t i = 0; i < v.size(); ++i) o += (i ? ", " : "") + v[i];
    return o + "]";
  };
  return fmt::format("{{\"quantities\": {}, \"changes_not_errors\": {}}}", list(conserved), list(changes));
}

/// The bodies' rotation on one line: kinetic energy T and spin angular
/// momentum S = sum R Pi (initial value, range, largest change), and the
/// total energy's error relative to T (the attitude's scale when the orbit
/// dominates the totals).
std::string rotation_json(const RunStatistics& st) {
  return fmt::format(
      "{{\"initial_kinetic_energy\": {}, \"min_kinetic_energy\": {}, \"max_kinetic_energy\": {}, "
      "\"initial_spin_angular_momentum\": [{}, {}, {}], \"min_spin_magnitude\": {}, \"max_spin_magnitude\": {}, "
      "\"max_spin_change\": {}, \"energy_error_over_max_kinetic_energy\": {}}}",
      json_number(st.rot_energy0), json_number(st.min_rot_energy), json_number(st.max_rot_energy),
      json_number(st.spin0.x()), json_number(st.spin0.y()), json_number(st.spin0.z()), json_number(st.min_spin),
      json_number(st.max_spin), json_number(st.max_spin_change),
      json_number(st.max_rot_energy > 0.0 ? st.max_energy_error / st.max_rot_energy : std::nan("")));
}

}  // namespace

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
      .raw("rotation", rotation_json(st))
      .raw("conserved", conserved_json(sc))
      // Per solve: per step, body and sub-step of a composed step (the
      // bodies' and sub-steps' solves are summed in iterations_total).
      .number("solver_iterations_mean", st.steps_solved ? static_cast<double>(st.iterations_total) /
                                                              static_cast<double>(st.steps_solved) /
                                                              static_cast<double>(sc.bodies()) /
                                                              static_cast<double>(sc.integrator.composition.stages())
                                                        : 0.0)
      .integer("solver_iterations_max", st.iterations_max)
      .integer("potential_evaluations", st.potential_evaluations)
      .object("final", state_json(r.final_state.body(0)))
      .raw("final_bodies", json_lines(final_bodies))
      .object("setup", setup_json(sc));
  if (!sc.forcing.empty())
    // energy errors above are E - E0 - W; angular and linear momentum
    // "errors" are their changes under the forcing, not errors.
    s.number("work", st.work)
        .string("energy_error_is", "E - E0 - work")
        .string("momentum_error_is", "the change of L and P, which the forcing does not conserve");
  return s.str() + "\n";
}

}  // namespace lgvi::app
