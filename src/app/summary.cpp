#include "app/summary.hpp"

#include "app/interactions/registry.hpp"
#include "io/json_io.hpp"
#include "io/output.hpp"

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

namespace lgvi::app {

namespace {

std::vector<double> to_vector(const Eigen::Ref<const Eigen::VectorXd>& v) { return {v.data(), v.data() + v.size()}; }

/// A body's inertia (its three rows) and balls.
Json inertia_json(const RigidBody& b) {
  Json rows = Json::array();
  for (int i = 0; i < 3; ++i) rows.push_back({b.inertia()(i, 0), b.inertia()(i, 1), b.inertia()(i, 2)});
  return rows;
}
Json balls_json(const RigidBody& b) {
  Json balls = Json::array();
  for (const Ball& ball : b.balls()) {
    balls.push_back({{"position", to_vector(ball.position)}, {"mass", ball.mass}, {"radius", ball.radius}});
    if (ball.type != 1) balls.back()["type"] = ball.type;  // (written where it is not the default)
  }
  return balls;
}

/// A body's mass, inertia and balls, and its extent where it is a shape or
/// has a bounding radius (mass + inertia + radius); for a linear body or a
/// point its rotational degrees of freedom (2 or 0) and a linear body's axis.
Json body_json(const RigidBody& b) {
  Json o = {{"mass", b.mass()}, {"inertia", inertia_json(b)}, {"balls", balls_json(b)}};
  if (b.rotational_dof() != 3) o["rotational_dof"] = b.rotational_dof();
  if (b.rotational_dof() == 2) o["linear_axis"] = to_vector(b.linear_axis());
  if (b.extent() == Extent::Sphere) o["radius"] = b.semi_axes().x();
  if (b.extent() == Extent::Ellipsoid) o["semi_axes"] = to_vector(b.semi_axes());
  if (b.has_wheels()) {  // the reaction wheels (inertia above: the whole body's, wheels locked)
    Json wheels = Json::array();
    for (const Wheel& w : b.wheels().list()) {
      Json j = {{"name", w.name}, {"axis", to_vector(w.axis)}, {"inertia", w.inertia}};
      if (std::isfinite(w.max_torque)) j["max_torque"] = w.max_torque;
      if (std::isfinite(w.max_speed)) j["max_speed"] = w.max_speed;
      wheels.push_back(std::move(j));
    }
    o["wheels"] = std::move(wheels);
  }
  return o;
}

/// What is checked for contact between bodies, in words.
std::string contact_check(const Scenario& s) {
  if (s.on_contact == OnContact::Ignore)
    return s.on_contact_given ? "not checked during the run ([run] on_contact = \"ignore\"); overlaps at the start are "
                                "errors"
                              : "not checked during the run: a " +
                                    std::string(s.interaction.descriptor ? s.interaction.descriptor->title : "?") +
                                    " system, whose balls' radii only shape the inertia (give [run] on_contact to "
                                    "check); overlaps at the start are errors";
  return "after every step: bounding spheres binned in cells of their largest diameter, then exactly: balls and "
         "spheres by their radii, ellipsoids by the Perram-Wertheim contact function; a body given by mass + inertia "
         "without radius is its centre of mass";
}

Json setup_json(const Scenario& s) {
  Json pot;
  pot["kind"] = to_string(s.potential.kind);
  if (s.potential.kind == PotentialKind::Central) {
    // How the field acts on each kind of body, stated with the run (the model is a choice that changes
    // the torque: a mass + inertia body as a point mass feels none).
    pot["model"] = s.potential.point_masses ? "point" : "extended";
    pot["model_acts"] = s.potential.point_masses
                            ? "each ball a point mass; a body given by mass + inertia or a shape a point mass at "
                              "its centre of mass (no gravity-gradient torque)"
                            : "each ball a point mass; a body given by mass + inertia or a shape by its "
                              "second-order (MacCullagh) potential, with the gravity-gradient torque";
    pot["mu"] = s.potential.mu;
    pot["stop_at_contact"] = s.potential.stop_at_contact;
  }
  if (s.potential.kind == PotentialKind::Central && s.potential.j2 != 0.0) {
    pot["j2"] = s.potential.j2;
    pot["j2_acts"] = "on each ball; on the centre of mass of a body given by mass + inertia or a shape (its J2 "
                     "torque, smaller than the gravity-gradient torque by J2 (R/r)^2, is not modelled)";
    pot["reference_radius"] = s.potential.reference_radius;
    pot["pole"] = to_vector(s.potential.pole);
  }
  if (s.potential.kind == PotentialKind::Uniform || s.potential.kind == PotentialKind::HeavyTop)
    pot["g"] = to_vector(s.potential.g);
  if (s.potential.kind == PotentialKind::HeavyTop) pot["pivot_to_com"] = to_vector(s.potential.pivot_to_com);
  Json integ;
  integ["method"] = to_string(s.integrator.method);
  integ["solver"] = to_string(s.integrator.solver.kind);
  if (s.integrator.adaptive()) {
    integ["time_transform"] = "potential";
    integ["epsilon"] = s.integrator.step;
    // null: |V| at the start (time_transformed.hpp)
    integ["monitor_scale"] = s.integrator.monitor_scale > 0.0 ? Json(s.integrator.monitor_scale) : Json();
    integ["max_steps"] = s.integrator.steps;
    if (s.integrator.exact_finish) integ["exact_finish"] = true;  // absent: the run ends with the first step past it
  } else {
    integ["step"] = s.integrator.step;
  }
  integ["tolerance"] = s.integrator.solver.tolerance;
  integ["max_iterations"] = s.integrator.solver.max_iterations;
  integ["predictor_order"] = s.integrator.solver.predictor_order;
  if (!s.integrator.composition.is_plain()) {
    integ["order"] = s.integrator.composition.order();
    integ["composition"] = s.integrator.composition.gamma();
  }
  Json o;
  if (!s.many_body_form) {
    o["body"] = body_json(s.body());
  } else if (s.body_lists == BodyLists::summary) {
    o["bodies"] = Json::array();  // setup_body_json's, one body at a time as it is written (summary_json)
  }
  o["potential"] = std::move(pot);
  if (s.many_body_form) {
    Json inter;
    inter["kind"] = interaction_kind(s.interaction);
    if (s.interaction.descriptor) s.interaction.descriptor->describe(s.interaction, inter);
    o["interaction"] = std::move(inter);
    if (const Box& box = s.system.box(); !box.free_space())
      o["box"] = {{"lower", to_vector(box.lower())},
                  {"upper", to_vector(box.upper())},
                  {"periodic", {box.periodic(0), box.periodic(1), box.periodic(2)}}};
    o["on_contact"] = to_string(s.on_contact);
    o["contact_check"] = contact_check(s);
  }
  o["integrator"] = std::move(integ);
  o["output_every"] = s.output_every;
  if (!s.forcing.empty()) o["forcing_terms"] = s.forcing.size();
  return o;
}

/// setup.bodies[a] of a [[bodies]] scenario: the body's name, mass, inertia, balls, ...
Json setup_body_json(const Scenario& s, std::size_t a) {
  Json b = {{"name", s.system.name(a)}};
  b.update(body_json(s.system.body(a)));
  return b;
}

/// A body's state: position, quaternion (scalar first), momentum, w.
Json state_json(const RigidBodyState& s) {
  return {{"position", to_vector(s.x)},
          {"quaternion", to_vector(s.q.scalar_first())},
          {"momentum", to_vector(s.p)},
          {"w", to_vector(s.w)}};
}

/// What the scenario conserves (conservation_laws), and which "error" keys
/// are changes.
Json conserved_json(const Scenario& sc) {
  using Angular = ConservationLaws::Angular;
  const ConservationLaws laws = conservation_laws(sc);
  Json conserved = Json::array();
  Json changes = Json::array();
  conserved.push_back(laws.forced ? "energy_minus_work" : "energy");
  if (laws.angular_momentum == Angular::Conserved)
    conserved.push_back("angular_momentum");
  else if (laws.angular_momentum == Angular::AlongPole)
    conserved.push_back("angular_momentum_along_pole");
  if (laws.angular_momentum != Angular::Conserved) {
    changes.push_back("max_momentum_error");
    changes.push_back("max_relative_momentum_error");
  }
  if (laws.linear_momentum)
    conserved.push_back("linear_momentum");
  else
    changes.push_back("max_linear_momentum_error");
  return {{"quantities", std::move(conserved)}, {"changes_not_errors", std::move(changes)}};
}

/// The bodies' rotation: kinetic energy T and spin angular momentum S = sum
/// R Pi (initial value, range, largest change), and the total energy's error
/// relative to T (the attitude's scale when the orbit dominates the totals).
Json rotation_json(const RunStatistics& st) {
  return {{"initial_kinetic_energy", st.rot_energy0},
          {"min_kinetic_energy", st.min_rot_energy},
          {"max_kinetic_energy", st.max_rot_energy},
          {"initial_spin_angular_momentum", to_vector(st.spin0)},
          {"min_spin_magnitude", st.min_spin},
          {"max_spin_magnitude", st.max_spin},
          {"max_spin_change", st.max_spin_change},
          {"energy_error_over_max_kinetic_energy",
           st.max_rot_energy > 0.0 ? st.max_energy_error / st.max_rot_energy : std::nan("")}};
}

/// The summary's document and its layout, given to `use` (which writes it:
/// the lists of bodies are made one body at a time as they are written).
template <class Use>
auto with_summary(const Scenario& sc, const SimulationResult& r, Use&& use) {
  const RunStatistics& st = r.stats;
  const double l0 = st.momentum0.norm();
  Json s;
  s["scenario"] = sc.name;
  s["completed"] = r.completed;
  s["error"] = r.error;
  s["steps"] = st.last_k;
  if (sc.integrator.adaptive()) {
    // The step adapts: the run ends with the first step that reaches the duration (last_time).
    s["steps_planned"] = Json();
    s["duration"] = sc.integrator.duration;
    s["min_step"] = st.min_time_step;
    s["max_step"] = st.max_time_step;
  } else {
    s["steps_planned"] = sc.integrator.steps;
    s["duration"] = sc.integrator.step * static_cast<double>(sc.integrator.steps);
  }
  s["last_time"] = st.last_t;
  s["wall_seconds"] = r.wall_seconds;
  s["ns_per_step"] = st.last_k > 0 ? r.wall_seconds * 1e9 / static_cast<double>(st.last_k) : 0.0;
  s["initial_energy"] = st.observed ? st.energy0 : std::nan("");
  s["initial_angular_momentum"] = to_vector(st.momentum0);
  s["max_abs_energy_error"] = st.max_energy_error;
  s["max_abs_quat_norm_error"] = st.max_quat_error;
  s["max_momentum_error"] = st.max_momentum_error;
  s["max_relative_momentum_error"] = l0 > 0 ? st.max_momentum_error / l0 : st.max_momentum_error;
  s["max_linear_momentum_error"] = st.max_linear_momentum_error;
  s["rotation"] = rotation_json(st);
  s["conserved"] = conserved_json(sc);
  // Per solve: per step, body and sub-step of a composed step (the bodies'
  // and sub-steps' solves are summed in iterations_total).
  s["solver_iterations_mean"] =
      st.steps_solved ? static_cast<double>(st.iterations_total) / static_cast<double>(st.steps_solved) /
                            static_cast<double>(sc.bodies()) / static_cast<double>(sc.integrator.composition.stages())
                      : 0.0;
  s["solver_iterations_max"] = st.iterations_max;
  s["potential_evaluations"] = st.potential_evaluations;
  // (No state: a run that failed before its first step, e.g. writing its folder.)
  s["final"] = r.final_state.size() > 0 ? state_json(r.final_state.body(0)) : Json();
  if (sc.body_lists == BodyLists::summary)
    s["final_bodies"] = Json::array();  // one body at a time as it is written (below)
  else  // setup.bodies and final_bodies, a body a line in the file beside the summary (write_summary_file)
    s["body_lists"] = {{"file", kBodyListsFile}, {"bodies", sc.bodies()}};
  if (sc.many_body_form && sc.on_contact != OnContact::Ignore) {
    // The episodes of overlap (the one that stopped the run under "stop").
    Json contacts = Json::array();
    for (const ContactEpisode& e : st.contacts)
      contacts.push_back({{"bodies", {sc.system.name(static_cast<std::size_t>(e.a)),
                                      sc.system.name(static_cast<std::size_t>(e.b))}},
                          {"first_time", e.first_t},
                          {"last_time", e.last_t},
                          {"first_step", e.first_k},
                          {"last_step", e.last_k},
                          {"max_depth", e.max_depth},
                          {"distance_at_max_depth", e.distance}});
    s["contact_episodes"] = st.contact_episodes;
    s["contacts"] = std::move(contacts);
  }
  s["setup"] = setup_json(sc);
  if (!sc.forcing.empty() && !sc.forcing.internal_only()) {
    // energy errors above are E - E0 - W; angular and linear momentum
    // "errors" are their changes under the forcing, not errors.
    s["work"] = st.work;
    s["energy_error_is"] = "E - E0 - work";
    s["momentum_error_is"] = "the change of L and P, which the forcing does not conserve";
  } else if (!sc.forcing.empty() || !sc.wheel_torques.empty() || sc.wheel_control) {
    // Motor torques and pair damping do work, but are internal: the momenta are still conserved (errors, not
    // changes; conservation_laws says which).
    s["work"] = st.work;
    s["energy_error_is"] = "E - E0 - work";
  }
  if (sc.system.has_wheels() && !st.wheels.empty()) {
    // Per wheel, body by body (a system's entries name their body), as RunStatistics::wheels.
    const SystemState& end = r.final_state;
    Json list = Json::array();
    std::size_t at = 0;  // the wheel's index in st.wheels
    for (std::size_t a = 0; a < sc.bodies() && at < st.wheels.size(); ++a) {
      const Wheels& wheels = sc.system.body(a).wheels();
      if (wheels.empty()) continue;
      const bool has_end = end.eta.size() == end.size() && end.size() == sc.bodies() && end.eta[a].size() == wheels.size();
      const Vector3<double> omega = has_end ? wheels.body_rate(end.w[a], end.eta[a].data()) : Vector3<double>::Zero();
      for (std::size_t w = 0; w < wheels.size() && at < st.wheels.size(); ++w, ++at) {
        const RunStatistics::WheelStatistics& ws = st.wheels[at];
        Json entry;
        if (sc.many_body_form) entry["body"] = sc.system.name(a);
        entry["name"] = wheels[w].name;
        entry["max_abs_speed"] = ws.max_speed;
        entry["max_abs_torque"] = ws.max_torque;
        entry["time_at_a_limit"] = ws.time_limited;
        if (has_end) {  // with "final": the state a run continuing from it needs
          entry["final_speed"] = wheels.relative_speed(w, end.eta[a].data(), omega);
          entry["final_momentum"] = end.eta[a][w];
        }
        list.push_back(std::move(entry));
      }
    }
    s["wheels"] = std::move(list);
    // Over all wheels: the motors' total torque impulse (the control effort) and the time during which at
    // least one wheel was at a limit.
    s["wheel_totals"] = {{"control_effort", st.wheel_effort}, {"time_saturated", st.wheels_saturated_time}};
  }
  if (const ThermoColumns thermo = thermo_columns(sc); thermo != ThermoColumns::none) {
    // Over the written frames (the trajectory's temperature and pressure columns).
    const ThermoStatistics& th = st.thermo;
    const double frames = static_cast<double>(th.frames);
    auto values = [&](double first, double last, double sum) {
      return Json{{"initial", first}, {"final", last}, {"mean", th.frames > 0 ? sum / frames : std::nan("")}};
    };
    Json t = {{"degrees_of_freedom", degrees_of_freedom(sc)},
              {"boltzmann_constant", 1.0},
              {"frames", th.frames},
              {"temperature", values(th.temperature0, th.temperature, th.temperature_sum)}};
    if (thermo == ThermoColumns::temperature_and_pressure) {
      t["volume"] = sc.system.box().volume();
      t["pressure"] = values(th.pressure0, th.pressure, th.pressure_sum);
    }
    s["thermodynamics"] = std::move(t);
  }
  // The short diagnostics on one line each, the lists of bodies one body a line.
  // The lists of bodies are made one body at a time as they are written, so
  // that a large system's summary holds its text, not also a JSON object per
  // body (several times the text's size).
  JsonLayout layout{{"rotation", "conserved", "thermodynamics", "body_lists"}, {"contacts"}, {}};
  if (sc.body_lists == BodyLists::summary) {
    layout.generated.push_back({&s["final_bodies"], r.final_state.size(), [&](std::size_t a) {
                                  Json body = {{"name", sc.system.name(a)}};
                                  body.update(state_json(r.final_state.body(a)));
                                  return body;
                                }});
    if (sc.many_body_form)
      layout.generated.push_back(
          {&s["setup"]["bodies"], sc.bodies(), [&](std::size_t a) { return setup_body_json(sc, a); }});
  }
  return use(s, layout);
}

/// Line a of bodies.jsonl: body a's entry of setup.bodies, and "final", its
/// entry of final_bodies but the name (none for a run that failed before its
/// first step).
Json body_line_json(const Scenario& sc, const SimulationResult& r, std::size_t a) {
  Json body = setup_body_json(sc, a);
  if (a < r.final_state.size()) body["final"] = state_json(r.final_state.body(a));
  return body;
}

}  // namespace

std::string summary_json(const Scenario& sc, const SimulationResult& r) {
  return with_summary(sc, r, [](const Json& doc, const JsonLayout& layout) { return json_text(doc, layout) + "\n"; });
}

void write_summary_file(const std::string& path, const Scenario& sc, const SimulationResult& r) {
  if (sc.body_lists == BodyLists::file)  // first, so that a summary never names a file not yet there
    write_file_atomically((std::filesystem::path(path).parent_path() / kBodyListsFile).string(), [&](std::FILE* file) {
      return write_json_lines(file, sc.bodies(), [&](std::size_t a) { return body_line_json(sc, r, a); });
    });
  write_file_atomically(path, [&](std::FILE* file) {
    return with_summary(sc, r, [&](const Json& doc, const JsonLayout& layout) {
      return write_json(file, doc, layout) && std::fputc('\n', file) != EOF;
    });
  });
}

}  // namespace lgvi::app
