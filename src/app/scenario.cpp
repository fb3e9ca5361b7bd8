#include "app/scenario.hpp"

#include "io/formats/registry.hpp"
#include "app/interactions/registry.hpp"
#include "app/lammps_data.hpp"
#include "io/toml_reader.hpp"
#include "io/toml_writer.hpp"

#include <lgvi/error.hpp>

#include <fmt/format.h>
#include <toml++/toml.h>

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <numbers>
#include <random>
#include <span>
#include <sstream>
#include <string_view>

namespace lgvi::app {

namespace {

using Reader = TomlReader;

/// The library names a body's fields "body.*"; a [[bodies]] entry is
/// "bodies[i].*".
std::string renamed(const std::string& message, const std::string& prefix) {
  if (prefix == "body" || message.rfind("body", 0) != 0) return message;
  return prefix + message.substr(4);
}

/// A body given by a shape (`shape` = "sphere" with `radius`, or
/// "ellipsoid" with `semi_axes` along the body axes), uniform, with `density`
/// or `mass`: its mass and inertia computed (RigidBody::sphere, ellipsoid).
RigidBody read_shape(const Reader& r, const toml::table& t, const std::string& prefix) {
  const std::string shape = r.string(t, prefix, "shape", {"sphere", "ellipsoid"});
  for (const char* k : {"inertia", "ball", "physical"})
    if (t.contains(k))
      r.fail(prefix + "." + k, "a shape's mass and inertia are computed (uniform density): give shape with "
                               "density or mass, without inertia, balls or physical");
  if (t.contains("density") == t.contains("mass"))
    r.fail(prefix, "a shape needs exactly one of density (mass = density x volume) or mass");
  const bool sphere = shape == "sphere";
  const char* other = sphere ? "semi_axes" : "radius";
  if (t.contains(other))
    r.fail(prefix + "." + other, sphere ? "belongs to shape = \"ellipsoid\"; a sphere has radius"
                                        : "belongs to shape = \"sphere\"; an ellipsoid has semi_axes = [a, b, c]");
  Vector3<double> axes;
  if (sphere) {
    const double radius = r.number(t, prefix, "radius");
    if (!(radius > 0.0)) r.fail(prefix + ".radius", "must be a number > 0");
    axes.setConstant(radius);
  } else {
    axes = r.vector<3>(t, prefix, "semi_axes");
    if (!(axes.minCoeff() > 0.0)) r.fail(prefix + ".semi_axes", "must be 3 numbers > 0 (along the body axes)");
  }
  double mass = 0.0;
  if (t.contains("density")) {
    const double density = r.number(t, prefix, "density");
    if (!(density > 0.0)) r.fail(prefix + ".density", "must be a number > 0");
    mass = density * ellipsoid_volume(axes);
    if (!(std::isfinite(mass) && mass > 0.0))
      r.fail(prefix + ".density", "density x volume = " + std::to_string(mass) + " is not a finite mass > 0");
  } else {
    mass = r.number(t, prefix, "mass");
    if (!(mass > 0.0)) r.fail(prefix + ".mass", "must be a number > 0");
  }
  try {
    return sphere ? RigidBody::sphere(mass, axes.x()) : RigidBody::ellipsoid(mass, axes);
  } catch (const InvalidInput&) {  // an inertia that overflows or underflows
    r.fail(prefix + (sphere ? ".radius" : ".semi_axes"),
           "gives no finite, positive-definite inertia with mass " + fmt::format("{}", mass) +
               " (m r^2 overflows or underflows); give the body in other units");
  }
}

/// A body from a table with mass + inertia (and optionally a bounding
/// radius), balls, or a shape; `prefix` names it in messages ("body" or
/// "bodies[2]").
RigidBody read_body_table(const Reader& r, const toml::table& t, const std::string& prefix) {
  const std::string ball_table = "[[" + prefix.substr(0, prefix.find('[')) + ".ball]]";
  if (t.contains("shape")) return read_shape(r, t, prefix);
  for (const char* k : {"semi_axes", "density"})
    if (t.contains(k)) r.fail(prefix + "." + k, "belongs to a shape: give shape = \"sphere\" or \"ellipsoid\" too");
  bool physical = true;
  if (const toml::node* n = t.get("physical")) {
    if (!n->is_boolean()) r.fail(prefix + ".physical", "must be true or false");
    physical = n->value<bool>().value();
  }
  const bool has_balls = t.contains("ball");
  const bool has_mass = t.contains("mass") || t.contains("inertia");
  if (has_balls && has_mass) r.fail(prefix, "give either mass + inertia or " + ball_table + " entries, not both");
  if (has_balls && t.contains("radius"))
    r.fail(prefix + ".radius", "a body of balls is bounded by its balls; radius belongs to mass + inertia (a "
                               "bounding sphere) or to shape = \"sphere\"");
  // The library's messages name the field ("body.inertia: ...") but not the file.
  auto checked = [&](auto&& make) -> RigidBody {
    try {
      return make();
    } catch (const InvalidInput& e) {
      r.fail("", renamed(e.what(), prefix));
    }
  };
  if (!has_balls) {
    if (!has_mass)
      r.fail(prefix, "missing: give mass + inertia, one or more " + ball_table + ", or shape = \"sphere\" | "
                     "\"ellipsoid\" with density or mass");
    const double mass = r.number(t, prefix, "mass");
    const Matrix3<double> inertia = r.matrix3(t, prefix, "inertia");
    RigidBody body = checked([&] {
      return RigidBody(mass, inertia,
                       physical ? RigidBody::TriangleInequality::Require : RigidBody::TriangleInequality::Waive);
    });
    if (!t.contains("radius")) return body;
    const double radius = r.number(t, prefix, "radius");
    if (!(radius > 0.0)) r.fail(prefix + ".radius", "must be a number > 0 (a sphere about the centre of mass that "
                                                     "holds the body)");
    return checked([&] { return body.bounded_by(radius); });
  }
  const toml::array* arr = t.get("ball")->as_array();
  if (!arr || arr->empty() || !arr->is_array_of_tables())
    r.fail(prefix + ".ball", "must be one or more " + ball_table + " tables");
  if (arr->size() > 100000) r.fail(prefix + ".ball", "more than 100000 balls; merge them into mass + inertia");
  std::vector<Ball> balls;
  for (std::size_t i = 0; i < arr->size(); ++i) {
    const toml::table& b = *arr->get(i)->as_table();
    const std::string ball = prefix + ".ball[" + std::to_string(i) + "]";
    r.only_keys(b, ball, {"position", "mass", "radius", "type"});
    int type = 1;
    if (b.contains("type")) {
      const std::int64_t t = r.integer(b, ball, "type");
      if (t < 1 || t > max_site_types)
        r.fail(ball + ".type", "must be an integer in [1, " + std::to_string(max_site_types) +
                                   "] (the site's type, which picks the pair coefficients of [[interaction.pair]])");
      type = static_cast<int>(t);
    }
    balls.push_back({r.vector<3>(b, ball, "position"), r.number(b, ball, "mass"), r.number(b, ball, "radius"), type});
  }
  return checked([&] { return RigidBody::from_balls(std::move(balls)); });
}

/// The [[body.wheel]] tables of the body table `owner` ("body", or "bodies[i]" for [[bodies.wheel]]): the
/// wheels (axis, inertia, max_torque, max_speed, name) on `body`, and each wheel's initial speed relative to
/// the body (`speed`, rad/s) in `speeds`.
RigidBody read_wheels(const Reader& r, const toml::table& t, const std::string& owner, const RigidBody& body,
                      std::vector<double>& speeds) {
  const toml::array* arr = t.get("wheel")->as_array();
  const std::string key = owner + ".wheel";
  if (!arr || arr->empty() || !arr->is_array_of_tables()) r.fail(key, "must be one or more [[" + (owner == "body" ? key : "bodies.wheel") + "]] tables");
  if (arr->size() > 64) r.fail(key, "more than 64 wheels");
  std::vector<Wheel> wheels;
  for (std::size_t i = 0; i < arr->size(); ++i) {
    const toml::table& w = *arr->get(i)->as_table();
    const std::string prefix = key + "[" + std::to_string(i) + "]";
    r.only_keys(w, prefix, {"axis", "inertia", "speed", "max_torque", "max_speed", "name"});
    Wheel wheel;
    wheel.axis = r.vector<3>(w, prefix, "axis");
    wheel.inertia = r.number(w, prefix, "inertia");
    if (!w.contains("speed"))
      r.fail(prefix + ".speed", "missing: the wheel's initial speed relative to the body, rad/s (0 for a wheel at rest)");
    speeds.push_back(r.number(w, prefix, "speed"));
    if (w.contains("max_torque")) wheel.max_torque = r.number(w, prefix, "max_torque");
    if (w.contains("max_speed")) wheel.max_speed = r.number(w, prefix, "max_speed");
    wheel.name = "wheel" + std::to_string(i);
    if (const toml::node* n = w.get("name")) {
      if (!n->is_string()) r.fail(prefix + ".name", "must be a string");
      wheel.name = n->value<std::string>().value();
    }
    if (wheel.name.empty() || wheel.name.find_first_of(",\"\n") != std::string::npos)
      r.fail(prefix + ".name", "must be a non-empty name without commas or quotes (it names trajectory columns)");
    for (const Wheel& other : wheels)
      if (other.name == wheel.name) r.fail(prefix + ".name", "\"" + wheel.name + "\" names another wheel too");
    wheels.push_back(std::move(wheel));
  }
  try {
    return body.with_wheels(std::move(wheels), owner);
  } catch (const InvalidInput& e) {
    // The library's "OWNER.wheel[i].key: what", as the reader names keys.
    const std::string message = e.what();
    const std::size_t colon = message.find(": ");
    if (colon == std::string::npos) r.fail(key, message);
    r.fail(message.substr(0, colon), message.substr(colon + 2));
  }
}

RigidBody read_body(const Reader& r, const toml::table& root, std::vector<double>& wheel_speeds) {
  const toml::table& t = r.table(root, "", "body");
  r.only_keys(t, "body", {"mass", "inertia", "ball", "physical", "radius", "shape", "semi_axes", "density", "wheel"});
  const RigidBody body = read_body_table(r, t, "body");
  return t.contains("wheel") ? read_wheels(r, t, "body", body, wheel_speeds) : body;
}

/// The wheels' axial momenta eta_i = j_i (a_i.omega + Omega_i) from their speeds Omega_i and the body's
/// rate, for a body table (`t`, [initial] or a [[bodies]] entry) that gave `omega` or `w`: a given omega
/// is the body's rate, and w becomes 2 (J omega + sum_i j_i Omega_i a_i) (J with the wheels locked); a
/// given w is the total angular momentum of body and wheels, omega = J^-1 (w/2 - sum_i j_i Omega_i a_i).
std::vector<double> initial_wheel_momenta(const Reader& r, const toml::table& t, const std::string& prefix,
                                          const RigidBody& body, const std::vector<double>& speeds, Vector3<double>& w) {
  const Wheels& wheels = body.wheels();
  Vector3<double> relative = Vector3<double>::Zero();
  for (std::size_t i = 0; i < wheels.size(); ++i) relative += wheels[i].inertia * speeds[i] * wheels[i].axis;
  Vector3<double> omega;
  if (t.contains("omega")) {
    omega = r.vector<3>(t, prefix, "omega");
    w = 2.0 * (body.inertia() * omega + relative);
  } else {
    omega = body.inertia_inverse() * (0.5 * w - relative);
  }
  std::vector<double> eta(wheels.size());
  for (std::size_t i = 0; i < wheels.size(); ++i) eta[i] = wheels.axial_momentum(i, speeds[i], omega);
  return eta;
}

PotentialSpec read_potential(const Reader& r, const toml::table& root) {
  const toml::table& t = r.table(root, "", "potential");
  PotentialSpec p;
  const std::string kind = r.string(t, "potential", "kind", {"none", "central", "uniform", "heavy-top"});
  if (kind == "none") {
    r.only_keys(t, "potential", {"kind"});
  } else if (kind == "central") {
    r.only_keys(t, "potential", {"kind", "mu", "stop_at_contact", "j2", "reference_radius", "pole", "model"});
    p.kind = PotentialKind::Central;
    // How a body given by mass + inertia feels the field: "extended" (default), its
    // second-order (gravity-gradient) potential; "point", a point mass. Balls are
    // point masses in both.
    if (t.contains("model")) p.point_masses = r.string(t, "potential", "model", {"extended", "point"}) == "point";
    if (const toml::node* n = t.get("stop_at_contact")) {
      if (!n->is_boolean()) r.fail("potential.stop_at_contact", "must be true or false");
      p.stop_at_contact = n->value<bool>().value();
    }
    p.mu = r.number(t, "potential", "mu");
    if (!(p.mu > 0.0)) r.fail("potential.mu", "must be > 0 (attracting centre of strength mu)");
    // An oblate source: j2 with its reference radius, about the pole (default z).
    if (t.contains("j2")) {
      p.j2 = r.number(t, "potential", "j2");
      if (!t.contains("reference_radius"))
        r.fail("potential.reference_radius", "missing: j2 needs the radius it refers to (the body's equatorial radius)");
      p.reference_radius = r.number(t, "potential", "reference_radius");
      if (!(p.reference_radius > 0.0)) r.fail("potential.reference_radius", "must be > 0");
      if (t.contains("pole")) {
        const Vector3<double> k = r.vector<3>(t, "potential", "pole");
        if (!(k.norm() > 0.0)) r.fail("potential.pole", "must be a non-zero vector (the axis of symmetry)");
        if (std::abs(k.norm() - 1.0) > S3d::unit_tolerance)
          r.fail("potential.pole", "must be a unit vector (|pole| = " + std::to_string(k.norm()) + ")");
        p.pole = k.normalized();
      }
    } else {
      for (const char* key : {"reference_radius", "pole"})
        if (t.contains(key)) r.fail(std::string("potential.") + key, "belongs to an oblate source: give j2 too");
    }
  } else if (kind == "uniform") {
    r.only_keys(t, "potential", {"kind", "g"});
    p.kind = PotentialKind::Uniform;
    p.g = r.vector<3>(t, "potential", "g");
  } else {
    r.only_keys(t, "potential", {"kind", "g", "pivot_to_com"});
    p.kind = PotentialKind::HeavyTop;
    p.g = r.vector<3>(t, "potential", "g");
    p.pivot_to_com = r.vector<3>(t, "potential", "pivot_to_com");
  }
  return p;
}

/// A body's initial state from the keys position, quaternion, momentum |
/// velocity, w | omega of table t (named `prefix` in messages).
RigidBodyState read_state(const Reader& r, const toml::table& t, const std::string& prefix, const RigidBody& body) {
  RigidBodyState s;
  s.x = r.vector<3>(t, prefix, "position");
  const Vector4<double> q = r.vector<4>(t, prefix, "quaternion");
  try {
    s.q = S3d::from_quaternion_checked(q(0), q(1), q(2), q(3));
  } catch (const InvalidInput& e) {
    r.fail(prefix + ".quaternion", e.what());
  }
  if (t.contains("momentum") == t.contains("velocity"))
    r.fail(prefix, "give exactly one of momentum = [px, py, pz] or velocity = [vx, vy, vz]");
  s.p = t.contains("momentum") ? r.vector<3>(t, prefix, "momentum")
                               : Vector3<double>(body.mass() * r.vector<3>(t, prefix, "velocity"));
  if (!s.p.allFinite()) r.fail(prefix + ".velocity", "m v overflows to infinity; give smaller values");
  if (t.contains("w") == t.contains("omega"))
    r.fail(prefix, "give exactly one of w = [...] (the paper's w = 2 J Omega) or omega = [...] (body angular velocity)");
  s.w = t.contains("w") ? r.vector<3>(t, prefix, "w")
                        : Vector3<double>(2.0 * body.inertia() * r.vector<3>(t, prefix, "omega"));
  if (!s.w.allFinite()) r.fail(prefix + ".omega", "2 J omega overflows to infinity; give smaller values");
  return s;
}

/// A rotation by `angle` (rad) about coordinate axis `axis` (0, 1, 2), as a
/// unit quaternion and as a matrix.
S3d axis_quaternion(int axis, double angle) {
  double v[3] = {0.0, 0.0, 0.0};
  v[axis] = std::sin(angle / 2);
  return {std::cos(angle / 2), v[0], v[1], v[2]};
}
Matrix3<double> axis_matrix(int axis, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  const int j = (axis + 1) % 3, k = (axis + 2) % 3;
  Matrix3<double> m = Matrix3<double>::Zero();
  m(axis, axis) = 1.0;
  m(j, j) = c;
  m(j, k) = -s;
  m(k, j) = s;
  m(k, k) = c;
  return m;
}

toml::array toml_vector(const Eigen::Ref<const Eigen::VectorXd>& v) {
  toml::array a;
  for (Eigen::Index i = 0; i < v.size(); ++i) a.push_back(v(i) + 0.0);  // + 0.0: no "-0.0" in the copy
  return a;
}

/// [initial] orbit = {...} and attitude = {...} (single-body scenarios about
/// a central potential), converted once into the plain keys position,
/// momentum, quaternion and w of the same table, which read_initial then reads
/// like any other. Angles in degrees. The orbit's elements refer to the
/// scenario's axes (the equator is the x-y plane when the pole is z); radius
/// is the semi-major axis and altitude the semi-major axis minus
/// potential.reference_radius. The LVLH frame: x radial (from the centre
/// out), z the orbit normal r x v / |r x v|, y = z x x (along-track: the
/// velocity's direction on a circular orbit). The body's attitude in it:
/// pitch about z, then roll about the new y, then yaw about the new x
/// (R_LVLH^T R = Rz(pitch) Ry(roll) Rx(yaw)). rate = "orbit": the body turns
/// with the LVLH frame, Omega = R^T (|r x v| / |r|^2) z_LVLH. Returns the two
/// original tables as TOML comment lines (for the run's scenario copy), empty
/// when there were none.
std::string convert_orbit_attitude(const Reader& r, toml::table& root, const RigidBody& body,
                                   const PotentialSpec& pot) {
  toml::table* t = root.get_as<toml::table>("initial");
  if (!t) return {};  // read_initial names what is missing
  const toml::node* on = t->get("orbit");
  const toml::node* an = t->get("attitude");
  if (!on && !an) return {};
  const std::string which = on ? "initial.orbit" : "initial.attitude";
  if (pot.kind != PotentialKind::Central)
    r.fail(which, "needs [potential] kind = \"central\" (the orbit's centre and mu come from it); "
                  "otherwise give position, momentum and quaternion");
  constexpr double deg = std::numbers::pi / 180.0;
  Vector3<double> x = Vector3<double>::Zero(), v = Vector3<double>::Zero();
  S3d q_lvlh;
  bool have_q_lvlh = false;
  std::string note = "# lgvi converted [initial] orbit / attitude into the plain keys below; they were\n";
  if (on) {
    if (!on->is_table()) r.fail("initial.orbit", "must be a table, e.g. orbit = { altitude = 500e3, inclination = 51.6 }");
    const toml::table& o = *on->as_table();
    r.only_keys(o, "initial.orbit",
                {"altitude", "radius", "eccentricity", "inclination", "raan", "arg_periapsis", "true_anomaly"});
    for (const char* k : {"position", "momentum", "velocity"})
      if (t->contains(k))
        r.fail(std::string("initial.") + k, "conflicts with initial.orbit, which sets the position and momentum; "
                                             "remove one of them");
    if (o.contains("altitude") == o.contains("radius"))
      r.fail("initial.orbit", "give exactly one of altitude (semi-major axis minus potential.reference_radius) or "
                              "radius (the semi-major axis)");
    double a = 0.0;
    std::string a_key = "initial.orbit.radius";
    if (o.contains("altitude")) {
      a_key = "initial.orbit.altitude";
      if (!(pot.reference_radius > 0.0))
        r.fail(a_key, "needs potential.reference_radius to measure from (give it with j2; j2 = 0.0 is allowed), "
                      "or give radius = reference radius + altitude");
      a = pot.reference_radius + r.number(o, "initial.orbit", "altitude");
    } else {
      a = r.number(o, "initial.orbit", "radius");
    }
    if (!(a > 0.0)) r.fail(a_key, "gives a semi-major axis " + std::to_string(a) + " <= 0; it must be > 0");
    auto opt = [&](const char* k) { return o.contains(k) ? r.number(o, "initial.orbit", k) : 0.0; };
    const double e = opt("eccentricity");
    if (!(e >= 0.0 && e < 1.0))
      r.fail("initial.orbit.eccentricity", "must be in [0, 1): orbit sets up closed (circular or elliptic) orbits");
    // An orbit that starts inside the central body or passes through it: its
    // periapsis a (1 - e) below the surface, where the reference radius gives one.
    if (pot.reference_radius > 0.0 && a * (1.0 - e) < pot.reference_radius) {
      const bool too_eccentric = e > 0.0 && a >= pot.reference_radius;
      r.fail(too_eccentric ? "initial.orbit.eccentricity" : a_key,
             fmt::format("the orbit's periapsis {}{} is below the central body's surface, "
                         "potential.reference_radius {}; {}",
                         a * (1.0 - e), e > 0.0 ? fmt::format(" (semi-major axis {} times 1 - eccentricity)", a) : "",
                         pot.reference_radius,
                         too_eccentric                          ? "give a smaller eccentricity or a larger orbit"
                         : a_key == "initial.orbit.altitude" ? "give an altitude above 0 (and the periapsis above it)"
                                                               : "give a radius above it"));
    }
    if (!o.contains("inclination"))
      r.fail("initial.orbit.inclination", "missing (degrees from the scenario's x-y plane, e.g. inclination = 51.6)");
    const double inc = opt("inclination") * deg, raan = opt("raan") * deg, argp = opt("arg_periapsis") * deg,
                 nu = opt("true_anomaly") * deg;
    const double p = a * (1.0 - e * e), radius = p / (1.0 + e * std::cos(nu));
    const Matrix3<double> Q = axis_matrix(2, raan) * axis_matrix(0, inc) * axis_matrix(2, argp);
    x = Q * Vector3<double>(radius * std::cos(nu), radius * std::sin(nu), 0.0);
    v = Q * (std::sqrt(pot.mu / p) * Vector3<double>(-std::sin(nu), e + std::cos(nu), 0.0));
    q_lvlh = axis_quaternion(2, raan) * axis_quaternion(0, inc) * axis_quaternion(2, argp + nu);
    have_q_lvlh = true;
    const Vector3<double> momentum = body.mass() * v;
    t->insert_or_assign("position", toml_vector(x));
    t->insert_or_assign("momentum", toml_vector(momentum));
    note += "#   orbit = " + write_inline_toml(o) + "\n";
  }
  if (an) {
    if (!an->is_table())
      r.fail("initial.attitude", "must be a table, e.g. attitude = { frame = \"lvlh\", pitch = 5.0, rate = \"orbit\" }");
    const toml::table& at = *an->as_table();
    r.only_keys(at, "initial.attitude", {"frame", "roll", "pitch", "yaw", "rate", "error"});
    if (t->contains("quaternion"))
      r.fail("initial.quaternion", "conflicts with initial.attitude, which sets the attitude; remove one of them");
    r.string(at, "initial.attitude", "frame", {"lvlh"});
    if (!on) {
      x = r.vector<3>(*t, "initial", "position");
      if (t->contains("momentum") == t->contains("velocity"))
        r.fail("initial", "give exactly one of momentum = [px, py, pz] or velocity = [vx, vy, vz]");
      v = t->contains("velocity") ? r.vector<3>(*t, "initial", "velocity")
                                  : Vector3<double>(r.vector<3>(*t, "initial", "momentum") / body.mass());
    }
    const Vector3<double> h = x.cross(v);
    if (!(h.norm() > 0.0))
      r.fail("initial.attitude", "the LVLH frame needs an orbit: the position and velocity must not be parallel or zero");
    if (!have_q_lvlh) {
      Matrix3<double> lvlh;
      lvlh.col(0) = x.normalized();
      lvlh.col(2) = h.normalized();
      lvlh.col(1) = lvlh.col(2).cross(lvlh.col(0));
      q_lvlh = S3d::from_rotation_matrix(lvlh);
    }
    auto angle = [&](const char* k) { return at.contains(k) ? r.number(at, "initial.attitude", k) * deg : 0.0; };
    const double roll = angle("roll"), pitch = angle("pitch"), yaw = angle("yaw");
    // An attitude error (e.g. an ensemble's draw): a body-frame rotation after roll, pitch and yaw.
    S3d error;
    if (at.contains("error")) {
      const Vector4<double> e = r.vector<4>(at, "initial.attitude", "error");
      try {
        error = S3d::from_quaternion_checked(e(0), e(1), e(2), e(3));
      } catch (const InvalidInput& ex) {
        r.fail("initial.attitude.error", ex.what());
      }
    }
    const S3d q =
        q_lvlh * (axis_quaternion(2, pitch) * axis_quaternion(1, roll) * axis_quaternion(0, yaw)) * error;
    t->insert_or_assign("quaternion", toml_vector(q.scalar_first()));
    if (at.contains("rate")) {
      r.string(at, "initial.attitude", "rate", {"orbit"});
      if (t->contains("w") || t->contains("omega"))
        r.fail("initial.attitude.rate", "conflicts with initial.w / initial.omega; give one of them");
      // The LVLH frame turns about its z axis at |r x v| / |r|^2.
      const double n = h.norm() / x.squaredNorm();
      const Matrix3<double> A =
          axis_matrix(2, pitch) * axis_matrix(1, roll) * axis_matrix(0, yaw) * error.matrix();
      const Vector3<double> omega = A.transpose() * Vector3<double>(0.0, 0.0, n);
      // A body with reaction wheels: its rate (the wheels' momenta add to w, parse_scenario).
      if (body.has_wheels()) {
        t->insert_or_assign("omega", toml_vector(omega));
      } else {
        const Vector3<double> w = 2.0 * body.inertia() * omega;
        t->insert_or_assign("w", toml_vector(w));
      }
    } else if (!t->contains("w") && !t->contains("omega")) {
      r.fail("initial.attitude", "give rate = \"orbit\" (the body turns with the LVLH frame) or initial.omega = "
                                 "[...] (body angular velocity, body frame)");
    }
    note += "#   attitude = " + write_inline_toml(at) + "\n";
  }
  t->erase("orbit");
  t->erase("attitude");
  return note;
}

RigidBodyState read_initial(const Reader& r, const toml::table& root, const RigidBody& body) {
  const toml::table& t = r.table(root, "", "initial");
  r.only_keys(t, "initial", {"position", "quaternion", "momentum", "velocity", "w", "omega", "orbit", "attitude"});
  return read_state(r, t, "initial", body);
}

/// A block of identical bodies from one [[bodies]] table with `count`: on a
/// cubic lattice of side ceil(count^(1/3)) and spacing `spacing` from
/// `position`; attitudes uniform on S^3 from `seed` (unless `quaternion`);
/// momenta and angular momenta drawn at `temperature` kT (Maxwell-Boltzmann:
/// p ~ N(0, m kT) per component, body angular momentum J Omega ~ N(0, kT J))
/// with the block's total momentum removed (unless momentum | velocity and
/// w | omega are given). Names: `name` followed by the index in the block.
void read_block(const Reader& r, const toml::table& t, const std::string& prefix, const RigidBody& body,
                std::int64_t count, std::vector<RigidBodyState>& states) {
  if (count < 1 || count > 1000000) r.fail(prefix + ".count", "must be an integer in [1, 10^6]");
  const Vector3<double> origin = r.vector<3>(t, prefix, "position");
  const double spacing = count > 1 ? r.number(t, prefix, "spacing") : 0.0;
  if (count > 1 && !(spacing > 0.0)) r.fail(prefix + ".spacing", "must be > 0 (the lattice spacing)");
  std::uint64_t seed = 0;
  const bool random_attitude = !t.contains("quaternion");
  if (t.contains("seed")) {
    const std::int64_t s = r.integer(t, prefix, "seed");
    if (s < 0) r.fail(prefix + ".seed", "must be an integer >= 0");
    seed = static_cast<std::uint64_t>(s);
  } else if (random_attitude) {
    r.fail(prefix, "a block of bodies (count) needs quaternion = [...] or seed = N (random attitudes)");
  }
  const bool thermal = t.contains("temperature");
  double kT = 0.0;
  if (thermal) {
    kT = r.number(t, prefix, "temperature");
    if (!(kT >= 0.0)) r.fail(prefix + ".temperature", "must be >= 0 (kT in the scenario's energy units)");
    for (const char* k : {"momentum", "velocity", "w", "omega"})
      if (t.contains(k))
        r.fail(prefix + "." + k, "give either temperature or the block's momenta and angular velocities, not both");
  }
  RigidBodyState common;
  if (!random_attitude || !thermal) {
    // The keys the block shares, read as for a single body (quaternion, momentum, w).
    toml::table shared = t;
    if (random_attitude) shared.insert_or_assign("quaternion", toml::array{1.0, 0.0, 0.0, 0.0});
    if (thermal) {
      shared.insert_or_assign("momentum", toml::array{0.0, 0.0, 0.0});
      shared.insert_or_assign("w", toml::array{0.0, 0.0, 0.0});
    }
    common = read_state(r, shared, prefix, body);
  }
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const auto side = static_cast<std::int64_t>(std::ceil(std::cbrt(static_cast<double>(count)) - 1e-9));
  const Eigen::LLT<Matrix3<double>> chol(kT * body.inertia());
  const std::size_t first = states.size();
  Vector3<double> total = Vector3<double>::Zero();
  for (std::int64_t i = 0; i < count; ++i) {
    RigidBodyState s = common;
    // Lattice indices (integer division on purpose): i = ix + side (iy + side iz).
    const std::int64_t ix = i % side, iy = (i / side) % side, iz = i / (side * side);
    s.x = origin + spacing * Vector3<double>(static_cast<double>(ix), static_cast<double>(iy), static_cast<double>(iz));
    if (random_attitude) {
      Vector4<double> q(normal(rng), normal(rng), normal(rng), normal(rng));
      q /= q.norm();
      s.q = S3d(q(0), q(1), q(2), q(3));
    }
    if (thermal) {
      s.p = std::sqrt(body.mass() * kT) * Vector3<double>(normal(rng), normal(rng), normal(rng));
      const Vector3<double> z(normal(rng), normal(rng), normal(rng));
      // A linear body: J Omega ~ N(0, kT I) across its axis; a point: none.
      const Vector3<double> pi =
          !(kT > 0.0) || body.rotational_dof() == 0 ? Vector3<double>::Zero()
          : body.rotational_dof() == 2 ? Vector3<double>(std::sqrt(0.5 * kT * body.inertia().trace()) * body.admissible_momentum(z))
                                       : Vector3<double>(chol.matrixL() * z);
      s.w = 2.0 * pi;  // w = 2 J Omega, J Omega ~ N(0, kT J)
      total += s.p;
    }
    states.push_back(s);
  }
  if (thermal)
    for (std::size_t a = first; a < states.size(); ++a) states[a].p -= total / static_cast<double>(count);
}

/// The [[bodies]] tables: each a body and its initial state (or a block of
/// identical bodies, with `count`), with unique names.
/// The bodies as read: their kinds, one per [[bodies]] table (the bodies of
/// a block share theirs, as LAMMPS's types), and each body's kind.
struct BodyList {
  std::vector<RigidBody> kinds;
  std::vector<std::uint32_t> kind;
  std::size_t size() const { return kind.size(); }
  const RigidBody& operator[](std::size_t a) const { return kinds[kind[a]]; }
};

void read_bodies(const Reader& r, const toml::table& root, BodyList& bodies, std::vector<std::string>& names,
                 SystemState& state) {
  const toml::array* arr = root.get("bodies")->as_array();
  if (!arr || arr->empty() || !arr->is_array_of_tables())
    r.fail("bodies", "must be one or more [[bodies]] tables");
  std::vector<RigidBodyState> states;
  std::vector<std::vector<double>> etas;  // the wheels' momenta per body (empty: none has wheels)
  for (std::size_t i = 0; i < arr->size(); ++i) {
    const toml::table& t = *arr->get(i)->as_table();
    const std::string prefix = "bodies[" + std::to_string(i) + "]";
    if (t.contains("wheel") && t.contains("count"))
      r.fail(prefix + ".wheel", "a block of bodies (count) does not take reaction wheels; give each spacecraft "
                                "with wheels a [[bodies]] table of its own");
    r.only_keys(t, prefix, {"name", "mass", "inertia", "ball", "physical", "radius", "shape", "semi_axes", "density",
                            "position", "quaternion", "momentum", "velocity", "w", "omega", "count", "spacing", "seed",
                            "temperature", "wheel"});
    std::string name;
    if (const toml::node* n = t.get("name")) {
      if (!n->is_string()) r.fail(prefix + ".name", "must be a string");
      name = n->value<std::string>().value();
      if (name.empty() || name.size() > 64 || name.find_first_of("\"\\,\n\r\t") != std::string::npos)
        r.fail(prefix + ".name", "must be 1 to 64 characters without quotes, backslashes, commas or control characters");
    }
    std::vector<double> speeds;
    RigidBody body = read_body_table(r, t, prefix);
    if (t.contains("wheel")) body = read_wheels(r, t, prefix, body, speeds);
    const std::size_t before = states.size();
    if (t.contains("count")) {
      read_block(r, t, prefix, body, r.integer(t, prefix, "count"), states);
    } else {
      for (const char* k : {"spacing", "seed", "temperature"})
        if (t.contains(k)) r.fail(prefix + "." + k, "belongs to a block of bodies: give count = N too");
      states.push_back(read_state(r, t, prefix, body));
      if (body.has_wheels()) {
        if (etas.size() < states.size()) etas.resize(states.size());
        etas.back() = initial_wheel_momenta(r, t, prefix, body, speeds, states.back().w);
      }
    }
    if (states.size() > 1000000) r.fail("bodies", "more than 10^6 bodies");
    const bool block = t.contains("count");
    bodies.kinds.push_back(body);
    for (std::size_t a = before; a < states.size(); ++a) {
      bodies.kind.push_back(static_cast<std::uint32_t>(bodies.kinds.size() - 1));
      names.push_back(name.empty() ? "body" + std::to_string(a) : block ? name + std::to_string(a - before) : name);
    }
  }
  // Unique names (sorted copy: O(N log N) for large systems).
  std::vector<std::pair<std::string, std::size_t>> sorted;
  for (std::size_t a = 0; a < names.size(); ++a) sorted.emplace_back(names[a], a);
  std::sort(sorted.begin(), sorted.end());
  for (std::size_t k = 1; k < sorted.size(); ++k)
    if (sorted[k].first == sorted[k - 1].first)
      r.fail("bodies", "the name \"" + printable(sorted[k].first) + "\" is given to two bodies (bodies " +
                           std::to_string(sorted[k - 1].second) + " and " + std::to_string(sorted[k].second) +
                           " in order); names must be unique");
  state = SystemState(bodies.size());
  for (std::size_t a = 0; a < bodies.size(); ++a) state.set_body(a, states[a]);
  if (!etas.empty()) {
    etas.resize(bodies.size());
    state.eta = std::move(etas);
  }
}

/// Bodies must not overlap at the start (ContactDetector: balls, spheres,
/// ellipsoids; a body given by mass + inertia without radius is its centre of
/// mass, which must not lie inside another body). The message names the
/// deepest overlap of the first pair, by body index and name (an imported
/// molecule's "mol<ID>").
void require_no_overlap(const Reader& r, const System& system, const SystemState& s) {
  ContactDetector detector(system);
  const std::optional<Contact> first = detector.first(s);
  if (!first) return;
  const Contact& c = *first;
  auto what = [&](std::size_t a, std::ptrdiff_t ball) {
    return "bodies[" + std::to_string(a) + "]" + (ball >= 0 ? ".ball[" + std::to_string(ball) + "]" : "");
  };
  r.fail(what(c.b, c.ball_b), fmt::format("overlaps {} at the start (centre distance {}, {}); move the bodies apart "
                                          "(\"{}\" and \"{}\")",
                                          what(c.a, c.ball_a), c.distance, describe_reach(system, c),
                                          printable(system.name(c.b)), printable(system.name(c.a))));
}

/// The [interaction] table's keys for a descriptor's `read`, with the
/// reader's messages (each key named interaction.<key>).
class TableInteractionReader final : public InteractionReader {
 public:
  /// `prefix`: the table's name in messages ("interaction", "interaction.pair[0]").
  TableInteractionReader(const Reader& r, const toml::table& t, int site_types, std::string prefix = "interaction")
      : r_(r), t_(t), site_types_(site_types), prefix_(std::move(prefix)) {}
  bool has(std::string_view key) const override { return t_.contains(key); }
  double number(std::string_view key) const override { return r_.number(t_, prefix_, std::string(key)); }
  std::vector<std::int64_t> integers(std::string_view key, std::size_t count) const override {
    const std::string name = prefix_ + "." + std::string(key);
    const toml::node* n = t_.get(key);
    const toml::array* a = n ? n->as_array() : nullptr;
    if (!a || a->size() != count)
      r_.fail(name, (n ? "must be " : "missing: ") + std::string("an array of ") + std::to_string(count) + " integers");
    std::vector<std::int64_t> v;
    for (std::size_t i = 0; i < count; ++i) {
      if (!a->get(i)->is_integer()) r_.fail(name + "[" + std::to_string(i) + "]", "must be an integer");
      v.push_back(a->get(i)->value<std::int64_t>().value());
    }
    return v;
  }
  std::vector<std::unique_ptr<InteractionReader>> tables(std::string_view key,
                                                         std::initializer_list<std::string_view> keys) const override {
    std::vector<std::unique_ptr<InteractionReader>> out;
    const toml::node* n = t_.get(key);
    if (!n) return out;
    const std::string name = prefix_ + "." + std::string(key);
    const toml::array* a = n->as_array();
    if (!a || a->empty() || !a->is_array_of_tables()) r_.fail(name, "must be one or more [[" + name + "]] tables");
    for (std::size_t i = 0; i < a->size(); ++i) {
      const std::string element = name + "[" + std::to_string(i) + "]";
      r_.only_keys(*a->get(i)->as_table(), element, keys);
      out.push_back(std::make_unique<TableInteractionReader>(r_, *a->get(i)->as_table(), site_types_, element));
    }
    return out;
  }
  int site_types() const override { return site_types_; }
  std::string choice(std::string_view key, std::initializer_list<std::string_view> allowed) const override {
    return r_.string(t_, prefix_, std::string(key), allowed);
  }
  [[noreturn]] void fail(std::string_view key, const std::string& what) const override {
    r_.fail(prefix_ + "." + std::string(key), what);
  }

 private:
  const Reader& r_;
  const toml::table& t_;
  int site_types_;
  std::string prefix_;
};

/// [interaction]: kind "none" or a registered kind (interactions/registry.hpp),
/// its keys only, read and checked by its descriptor.
InteractionSpec read_interaction(const Reader& r, const toml::table& root, int site_types) {
  InteractionSpec spec;
  const toml::table* t = r.optional_table(root, "", "interaction");
  if (!t) return spec;
  std::vector<std::string_view> kinds{"none"};
  for (const InteractionDescriptor* d : interaction_kinds()) kinds.push_back(d->kind);
  const std::string kind = r.string(*t, "interaction", "kind", kinds);
  spec.descriptor = find_interaction(kind);
  std::vector<std::string_view> keys{"kind"};
  if (spec.descriptor) keys.insert(keys.end(), spec.descriptor->keys.begin(), spec.descriptor->keys.end());
  r.only_keys(*t, "interaction", keys);
  if (spec.descriptor) spec.descriptor->read(TableInteractionReader(r, *t, site_types), spec);
  return spec;
}

/// A table's `periodic`: three booleans, one per axis (default all true).
std::array<bool, 3> read_periodic(const Reader& r, const toml::table& t, const std::string& prefix) {
  std::array<bool, 3> periodic{true, true, true};
  if (const toml::node* n = t.get("periodic")) {
    const toml::array* a = n->as_array();
    if (!a || a->size() != 3)
      r.fail(prefix + ".periodic", "must be an array of 3 booleans, one per axis, e.g. [true, true, false]");
    for (std::size_t k = 0; k < 3; ++k) {
      if (!a->get(k)->is_boolean())
        r.fail(prefix + ".periodic[" + std::to_string(k) + "]", "must be true (periodic) or false (open)");
      periodic[k] = a->get(k)->value<bool>().value();
    }
  }
  return periodic;
}

/// [import] lammps_data = "FILE" (lammps_data.hpp): the bodies, their initial
/// state and the box of a LAMMPS data file, in place of [[bodies]] and [box].
/// Keys: atom_style (where the Atoms section does not name it), radius
/// (one, or one per atom type; default 0: point masses),
/// periodic (default [true, true, true], LAMMPS's `boundary p p p`) and
/// checksum (written by the run into its copy of the scenario, whose
/// lammps_data is then absolute: a resume refuses a changed file). `root`'s
/// table is rewritten so.
Box read_import(const Reader& r, toml::table& root, const std::string& scenario_name, BodyList& bodies,
                std::vector<std::string>& names, SystemState& state, int& site_types, FileIds& ids) {
  for (const char* other : {"bodies", "body", "initial", "box"})
    if (root.contains(other))
      r.fail(other, std::string("an [import] gives the bodies, their initial state and the box; remove [") + other +
                        (std::string(other) == "bodies" ? "]]" : "]") + " (or the [import])");
  toml::table& t = *root.get("import")->as_table();
  r.only_keys(t, "import", {"lammps_data", "atom_style", "radius", "periodic", "checksum"});
  const toml::node* file_node = t.get("lammps_data");
  if (!file_node || !file_node->is_string())
    r.fail("import.lammps_data", "missing (a string: the LAMMPS data file, relative to the scenario file)");
  std::filesystem::path file(file_node->value<std::string>().value());
  if (file.is_relative()) file = std::filesystem::path(scenario_name).parent_path() / file;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec))
    r.fail("import.lammps_data", "\"" + printable(file.string()) + "\" is not a file (the path is relative to the "
                                                                   "scenario file)");
  std::vector<double> radius;
  if (t.contains("radius")) {
    bool scalar = false;
    radius = r.numbers(*t.get("radius"), "import.radius", scalar);
    for (std::size_t k = 0; k < radius.size(); ++k)
      if (!(radius[k] >= 0.0))
        r.fail("import.radius", "must be >= 0 (a ball's radius per atom type; 0: point masses)");
  }
  const std::array<bool, 3> periodic = read_periodic(r, t, "import");
  // A resumed run's copy of the scenario holds the file's checksum: a file
  // changed since is refused with that reason, even where it no longer
  // parses (then, and only then, the file is read a second time).
  std::optional<std::string> recorded;
  if (const toml::node* n = t.get("checksum")) {
    if (!n->is_string()) r.fail("import.checksum", "must be a string (the data file's checksum, written by the run)");
    recorded = n->value<std::string>().value();
  }
  const auto changed = [&](const std::string& checksum) {
    r.fail("import.checksum", "the data file " + printable(file.string()) + " is not the one this run began with " +
                                  "(its checksum is now " + checksum +
                                  "); restore it, or start the run again without this key");
  };
  const std::string atom_style =
      t.contains("atom_style") ? r.string(t, "import", "atom_style", {"full", "molecular", "bond", "angle"}) : "";
  LammpsDataBodies data;
  try {
    data = read_lammps_data(file.string(), radius, periodic, atom_style);
  } catch (const std::exception&) {  // (a changed header can also ask for more memory than there is)
    if (recorded)
      if (const std::string now = file_checksum(file.string()); now != *recorded) changed(now);
    throw;
  }
  if (recorded && data.checksum != *recorded) changed(data.checksum);
  const std::string& checksum = data.checksum;
  site_types = data.atom_types;
  if (data.kind.size() > 1000000) r.fail("import.lammps_data", "more than 10^6 bodies");
  const auto first_kind = static_cast<std::uint32_t>(bodies.kinds.size());
  for (RigidBody& b : data.kinds) bodies.kinds.push_back(std::move(b));
  for (const std::uint32_t k : data.kind) bodies.kind.push_back(first_kind + k);
  names = std::move(data.names);
  ids = std::move(data.ids);
  state = SystemState(data.states.size());
  for (std::size_t a = 0; a < data.states.size(); ++a) state.set_body(a, data.states[a]);
  t.insert_or_assign("lammps_data", std::filesystem::absolute(file).lexically_normal().string());
  t.insert_or_assign("checksum", checksum);
  return Box(data.lower, data.upper, periodic);
}

/// [box]: lower, upper and periodic (default [true, true, true]); free space
/// without the table.
Box read_box(const Reader& r, const toml::table& root, bool many_body_form) {
  const toml::table* t = r.optional_table(root, "", "box");
  if (!t) return {};
  if (!many_body_form)
    r.fail("box", "a box holds [[bodies]]; a single-body scenario ([body] + [initial]) has no pairs to wrap");
  r.only_keys(*t, "box", {"lower", "upper", "periodic"});
  const Vector3<double> lower = r.vector<3>(*t, "box", "lower"), upper = r.vector<3>(*t, "box", "upper");
  const std::array<bool, 3> periodic = read_periodic(r, *t, "box");
  for (int k = 0; k < 3; ++k) {
    const std::string at = "[" + std::to_string(k) + "]";
    if (!(upper(k) > lower(k)))
      r.fail("box.upper" + at, fmt::format("must be greater than box.lower{} = {} (the box's extent)", at, lower(k)));
    if (!std::isfinite(upper(k) - lower(k)))
      r.fail("box.upper" + at, "the box's width upper - lower overflows a double; use smaller units");
  }
  return Box(lower, upper, periodic);
}

/// What a periodic box needs of the rest of the scenario: a field and an
/// interaction that are periodic too (no central field or pivot, no
/// long-range interaction), a reach below half the shortest periodic length
/// (so that a pair has one image within reach) and bodies small enough that
/// no body meets two images of another, or its own (twice the largest
/// bounding radius below half that length).
void require_fits_box(const Reader& r, const Box& box, const BodyList& bodies,
                      const PotentialSpec& potential, const InteractionSpec& interaction) {
  if (!box.any_periodic()) return;
  const double half = 0.5 * box.shortest_periodic_length();
  if (potential.kind == PotentialKind::Central || potential.kind == PotentialKind::HeavyTop)
    r.fail("box.periodic", std::string("a ") + to_string(potential.kind) +
                               " field is not periodic; a periodic box takes [potential] kind = \"none\" or "
                               "\"uniform\" (or make the box open: periodic = [false, false, false])");
  if (!interaction.none() && !interaction.descriptor->reach)
    r.fail("box.periodic", "mutual gravity is long-range and has no minimum image (a periodic box would need Ewald "
                           "summation); use an open box (periodic = [false, false, false]) or a short-range pair "
                           "interaction (lennard-jones, wca)");
  if (!interaction.none()) {
    const double reach = interaction.descriptor->reach(interaction);
    if (!(reach < half))
      r.fail("box", fmt::format("the interaction's reach, cutoff + skin = {}, must be less than half the shortest "
                                "periodic length ({}), so that a pair has one image within reach; enlarge the box or "
                                "shorten interaction.cutoff or interaction.skin",
                                reach, half));
  }
  for (std::size_t a = 0; a < bodies.size(); ++a)
    if (!(2.0 * bodies[a].bounding_radius() < half))
      r.fail("bodies[" + std::to_string(a) + "]",
             fmt::format("its bounding radius {} is too large for the box: twice it must be less than half the "
                         "shortest periodic length ({}), so that no body meets two images of another; enlarge the box",
                         bodies[a].bounding_radius(), half));
}

/// A forcing table's rows (t, a, b, c) from a CSV file: numbers separated
/// by commas, an optional header line, '#' comments.
void read_profile_csv(const Reader& r, const std::string& key, const std::filesystem::path& file,
                      std::vector<double>& t, std::vector<Vector3<double>>& v) {
  std::ifstream in(file);
  if (!in) r.fail(key, "cannot open the table \"" + printable(file.string()) + "\" (paths are relative to the scenario file)");
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    double row[4];
    const char* c = line.c_str();
    int n = 0;
    for (; n < 4; ++n) {
      char* end = nullptr;
      row[n] = std::strtod(c, &end);
      if (end == c) break;
      c = end;
      while (*c == ' ' || *c == '\t') ++c;
      if (n < 3 && *c == ',') ++c;
    }
    if (n == 0 && t.empty()) continue;  // the header line
    if (n != 4 || *c != '\0')
      r.fail(key, printable(file.string()) + ":" + std::to_string(number) +
                      ": expected 4 numbers t, x, y, z separated by commas");
    t.push_back(row[0]);
    v.emplace_back(row[1], row[2], row[3]);
  }
}

/// [[forcing]] tables (forcing.hpp): kind = "torque" | "force" | "damping" | "pair-damping" |
/// "attitude-control", on `body = "name"` or every body. A torque or force is
/// `value = [a, b, c]` or `table` = a CSV file (t, a, b, c; relative to the
/// scenario file) or inline rows [[t, a, b, c], ...]; file tables are inlined
/// into *inlined (the run's copy of the scenario is then self-contained).
/// The body a [[forcing]] table names (`body`, a body's name), or all_bodies when it names none.
std::size_t forcing_body(const Reader& r, const toml::table& t, const std::string& prefix, const System& system) {
  const toml::node* b = t.get("body");
  if (!b) return ForcingSet::all_bodies;
  if (!b->is_string()) r.fail(prefix + ".body", "must be a body's name (a string)");
  const std::string name = b->value<std::string>().value();
  const std::size_t index = system.index_of(name);
  if (index == system.size())
    r.fail(prefix + ".body", "no body is named \"" + printable(name) + "\"" +
                                 (system.size() <= 8 ? "; the bodies are " + [&] {
                                   std::string l;
                                   for (std::size_t a = 0; a < system.size(); ++a)
                                     l += (l.empty() ? "\"" : ", \"") + system.name(a) + "\"";
                                   return l;
                                 }()
                                                     : std::string()));
  return index;
}

/// A [[forcing]] kind = "wheel-torque" table: a motor torque on one wheel (`wheel`, its name or index) of the
/// body named `body` (of the only body when the system has one), `value` (N m) or `table` = [[t, u], ...]
/// covering [0, duration], held between rows.
WheelTorque read_wheel_torque(const Reader& r, const toml::table& t, const std::string& prefix, const System& system,
                              double duration) {
  r.only_keys(t, prefix, {"kind", "body", "wheel", "value", "table"});
  WheelTorque u;
  const std::size_t named = forcing_body(r, t, prefix, system);
  if (named == ForcingSet::all_bodies && system.size() != 1)
    r.fail(prefix + ".body", "missing: the name of the body whose wheel this turns");
  u.body = named == ForcingSet::all_bodies ? 0 : named;
  const Wheels& wheels = system.body(u.body).wheels();
  if (wheels.empty())
    r.fail(prefix + ".kind", "\"wheel-torque\" turns a reaction wheel: give the body [[body.wheel]] tables" +
                                 std::string(system.size() != 1 ? " ([[bodies.wheel]] after its [[bodies]] table)" : ""));
  const toml::node* which = t.get("wheel");
  if (!which) r.fail(prefix + ".wheel", "missing: the wheel's name, or its index from 0");
  if (which->is_string()) {
    const std::string name = which->value<std::string>().value();
    std::size_t i = 0;
    while (i < wheels.size() && wheels[i].name != name) ++i;
    if (i == wheels.size()) r.fail(prefix + ".wheel", "no wheel is named \"" + printable(name) + "\"");
    u.wheel = i;
  } else {
    const std::int64_t i = r.integer(t, prefix, "wheel");
    if (i < 0 || static_cast<std::size_t>(i) >= wheels.size())
      r.fail(prefix + ".wheel", "must be a wheel's name or an index in [0, " + std::to_string(wheels.size() - 1) + "]");
    u.wheel = static_cast<std::size_t>(i);
  }
  if (t.contains("value") == t.contains("table"))
    r.fail(prefix, "give exactly one of value = u (N m, constant) or table = [[t, u], ...] (held between rows)");
  if (t.contains("value")) {
    u.torque = HeldTorque::constant(r.number(t, prefix, "value"));
    return u;
  }
  const std::string key = prefix + ".table";
  const toml::array* rows = t.get("table")->as_array();
  if (!rows || rows->empty()) r.fail(key, "must be rows [[t, u], ...]");
  std::vector<double> times, values;
  for (std::size_t k = 0; k < rows->size(); ++k) {
    const Eigen::Vector2d row = r.vector<2>(*rows->get(k), key + "[" + std::to_string(k) + "]");
    times.push_back(row(0));
    values.push_back(row(1));
  }
  try {
    u.torque = HeldTorque(times, values);
  } catch (const InvalidInput& e) {
    r.fail(key, e.what());
  }
  if (times.front() > 0.0)
    r.fail(key, "starts at t = " + std::to_string(times.front()) + "; the run needs a command from t = 0");
  (void)duration;  // the last row is held to the end
  return u;
}

ForcingSet read_forcing(const Reader& r, toml::table& root, const System& system, double duration,
                        const std::filesystem::path& folder, bool& inlined, std::vector<WheelTorque>& wheel_torques,
                        std::optional<WheelAttitudeControl>& wheel_control, std::vector<S3d>& attitude_targets) {
  ForcingSet set;
  toml::node* node = root.get("forcing");
  if (!node) return set;
  toml::array* arr = node->as_array();
  if (!arr || arr->empty() || !arr->is_array_of_tables()) r.fail("forcing", "must be one or more [[forcing]] tables");
  for (std::size_t i = 0; i < arr->size(); ++i) {
    toml::table& t = *arr->get(i)->as_table();
    const std::string prefix = "forcing[" + std::to_string(i) + "]";
    const std::string kind =
        r.string(t, prefix, "kind", {"torque", "force", "damping", "attitude-control", "wheel-torque", "pair-damping"});
    if (kind == "wheel-torque") {
      // One command per wheel: the motor's limits apply to what it is commanded, as one torque.
      WheelTorque u = read_wheel_torque(r, t, prefix, system, duration);
      for (const WheelTorque& other : wheel_torques)
        if (other.body == u.body && other.wheel == u.wheel)
          r.fail(prefix + ".wheel", "wheel \"" + system.body(u.body).wheels()[u.wheel].name + "\" has a wheel-torque "
                                    "already; give one command per wheel (a table can hold every change)");
      wheel_torques.push_back(std::move(u));
      continue;
    }
    if (kind == "pair-damping") {
      // Between the sites of different bodies (pair_damping.hpp): every body, no `body`.
      r.only_keys(t, prefix, {"kind", "gamma", "cutoff"});
      if (system.size() < 2)
        r.fail(prefix + ".kind", "pair damping acts between bodies; this scenario has one ([[bodies]] gives several)");
      if (system.has_wheels())
        r.fail(prefix + ".kind", "pair damping is not taken beside reaction wheels (the gyrostat step completes the "
                                 "wheels' momenta after the momentum iteration a velocity-dependent forcing needs); "
                                 "give it to a system without [[bodies.wheel]]");
      const double gamma = r.number(t, prefix, "gamma"), cutoff = r.number(t, prefix, "cutoff");
      if (!(gamma > 0.0)) r.fail(prefix + ".gamma", "must be > 0 (the force per relative speed at zero distance)");
      if (!(cutoff > 0.0)) r.fail(prefix + ".cutoff", "must be > 0 (the distance beyond which sites do not act)");
      if (system.box().any_periodic() && !(2.0 * cutoff < system.box().shortest_periodic_length()))
        r.fail(prefix + ".cutoff", fmt::format("must be less than half the box's shortest periodic length ({}); give a "
                                               "smaller cutoff or a larger box",
                                               system.box().shortest_periodic_length()));
      set.add(PairDamping(gamma, cutoff, system.box()));
      continue;
    }
    const std::size_t body = forcing_body(r, t, prefix, system);
    // Damping and the body-torque controller read the body's rate as a rigid body's, J^-1 w / 2, which for a
    // gyrostat is not its rate: not on a body with reaction wheels. (A torque or a force reads no rate.)
    auto reads_no_gyrostat_rate = [&](const std::string& what) {
      const bool wheels = body == ForcingSet::all_bodies ? system.has_wheels() : system.body(body).has_wheels();
      if (wheels)
        r.fail(prefix + ".kind", what + " reads the body's rate as a rigid body's, which a body with reaction wheels "
                                        "does not have; give it to a body without wheels (body = \"name\")" +
                                        (kind == "attitude-control" ? ", or actuator = \"wheels\"" : ""));
    };
    // A controller's max_torque and period (attitude-control, or a torque the wheels make); `without_period`
    // says what leaving the period out means.
    auto read_sampling = [&](AttitudeControl& c, const std::string& without_period) {
      if (t.contains("max_torque")) {
        c.max_torque = r.number(t, prefix, "max_torque");
        if (!(c.max_torque > 0.0)) r.fail(prefix + ".max_torque", "must be > 0 (leave it out for no limit)");
      }
      if (t.contains("period")) {
        c.period = r.number(t, prefix, "period");
        if (!(c.period > 0.0)) r.fail(prefix + ".period", "must be > 0 (leave it out " + without_period + ")");
      }
    };
    // The body's reaction wheels make the controller's body torque: u = -A^+ M over them, or D M
    // (gyrostat.hpp); attitude-control's PD law, or a torque table (set after).
    auto drive_wheels = [&](const toml::table& t, const std::string& prefix, const AttitudeControl& c) {
      if (system.size() != 1)
        r.fail(prefix + ".actuator", "\"wheels\" drives the wheels of a single body so far; this system has " +
                                         std::to_string(system.size()) + " bodies");
      if (!system.body(0).has_wheels())
        r.fail(prefix + ".actuator", "\"wheels\" turns the body with its reaction wheels: give it [[body.wheel]] "
                                     "tables");
      if (wheel_control) r.fail(prefix + ".actuator", "one attitude controller drives the wheels; give only one");
      try {
        wheel_control = WheelAttitudeControl(c, system.body(0).wheels());
      } catch (const InvalidInput& e) {
        r.fail(prefix + ".actuator", e.what());
      }
      if (const toml::node* d = t.get("distribution")) {
        // u = D M: one row per wheel, in the wheels' order.
        const std::string key = prefix + ".distribution";
        const std::size_t k = system.body(0).wheels().size();
        const toml::array* rows = d->as_array();
        if (!rows || rows->size() != k)
          r.fail(key, "must have one row [dx, dy, dz] per wheel (" + std::to_string(k) + " rows): u = D M");
        Eigen::Matrix<double, Eigen::Dynamic, 3> m(static_cast<Eigen::Index>(k), 3);
        for (std::size_t i = 0; i < k; ++i)
          m.row(static_cast<Eigen::Index>(i)) = r.vector<3>(*rows->get(i), key + "[" + std::to_string(i) + "]").transpose();
        try {
          wheel_control = WheelAttitudeControl(c, system.body(0).wheels(), m);
        } catch (const InvalidInput& e) {
          r.fail(key, e.what());
        }
      }
    };
    auto non_negative = [&](const char* key) {
      if (!t.contains(key)) return 0.0;
      const double v = r.number(t, prefix, key);
      if (!(v >= 0.0)) r.fail(prefix + "." + key, "must be >= 0");
      return v;
    };
    if (kind == "torque" || kind == "force") {
      const bool torque = kind == "torque";
      const bool through_wheels =
          torque && t.contains("actuator") && r.string(t, prefix, "actuator", {"torque", "wheels"}) == "wheels";
      if (through_wheels)
        r.only_keys(t, prefix, {"kind", "body", "frame", "value", "table", "actuator", "max_torque", "period",
                                "distribution"});
      else if (torque)
        for (const char* k : {"max_torque", "period", "distribution"})
          if (t.contains(k))
            r.fail(prefix + "." + k, "belongs to a torque the reaction wheels make: give actuator = \"wheels\"");
      if (!through_wheels) r.only_keys(t, prefix, {"kind", "body", "frame", "value", "table", "actuator"});
      if (t.contains("actuator") && !torque) r.fail(prefix + ".actuator", "belongs to kind = \"torque\"");
      ForcingFrame frame = torque ? ForcingFrame::Body : ForcingFrame::Inertial;
      if (t.contains("frame")) frame = r.string(t, prefix, "frame", {"body", "inertial"}) == "body" ? ForcingFrame::Body
                                                                                                  : ForcingFrame::Inertial;
      if (t.contains("value") == t.contains("table"))
        r.fail(prefix, "give exactly one of value = [a, b, c] (constant) or table = \"file.csv\" (t, a, b, c)");
      Profile profile;
      if (t.contains("value")) {
        profile = Profile::constant(r.vector<3>(t, prefix, "value"));
      } else {
        const std::string key = prefix + ".table";
        std::vector<double> times;
        std::vector<Vector3<double>> values;
        const toml::node& table = *t.get("table");
        if (table.is_string()) {
          const std::filesystem::path file = folder / table.value<std::string>().value();
          read_profile_csv(r, key, file, times, values);
          toml::array rows;
          for (std::size_t k = 0; k < times.size(); ++k)
            rows.push_back(toml::array{times[k], values[k].x(), values[k].y(), values[k].z()});
          t.insert_or_assign("table", std::move(rows));
          inlined = true;
        } else if (const toml::array* rows = table.as_array()) {
          for (std::size_t k = 0; k < rows->size(); ++k) {
            const Vector4<double> row = r.vector<4>(*rows->get(k), key + "[" + std::to_string(k) + "]");
            times.push_back(row(0));
            values.emplace_back(row(1), row(2), row(3));
          }
        } else {
          r.fail(key, "must be a CSV file's name or rows [[t, a, b, c], ...]");
        }
        try {
          profile = Profile::table(std::move(times), std::move(values));
        } catch (const InvalidInput& e) {
          r.fail(key, e.what());
        }
        if (profile.t_begin() > 0.0 || profile.t_end() < duration)
          r.fail(key, "covers t in [" + std::to_string(profile.t_begin()) + ", " + std::to_string(profile.t_end()) +
                          "]; the run needs [0, " + std::to_string(duration) + "]: extend the table");
      }
      if (through_wheels) {
        // The wheels make the table's body torque, sampled at `period` (every step without one) and held.
        if (frame != ForcingFrame::Body)
          r.fail(prefix + ".frame", "the wheels make a torque in body axes: give frame = \"body\"");
        AttitudeControl c;
        read_sampling(c, "to sample every step");
        drive_wheels(t, prefix, c);
        wheel_control->set_torque_table(profile);
        continue;
      }
      if (torque) set.add(AppliedTorque{profile, frame}, body);
      else set.add(AppliedForce{profile, frame}, body);
    } else if (kind == "damping") {
      r.only_keys(t, prefix, {"kind", "body", "c", "c_linear"});
      Damping d{non_negative("c"), non_negative("c_linear")};
      if (!(d.c > 0.0 || d.c_linear > 0.0))
        r.fail(prefix, "give c > 0 (body torque -c Omega) and/or c_linear > 0 (force -c_linear v)");
      if (d.c > 0.0) reads_no_gyrostat_rate("damping with c > 0");  // c_linear reads p alone
      set.add(d, body);
    } else {
      r.only_keys(t, prefix, {"kind", "body", "target", "k_p", "k_d", "max_torque", "period", "actuator", "distribution"});
      AttitudeControl c;
      const Vector4<double> q = r.vector<4>(t, prefix, "target");
      try {
        c.target = S3d::from_quaternion_checked(q(0), q(1), q(2), q(3));
      } catch (const InvalidInput& e) {
        r.fail(prefix + ".target", e.what());
      }
      c.k_p = non_negative("k_p");
      c.k_d = non_negative("k_d");
      if (!t.contains("k_p") || !t.contains("k_d"))
        r.fail(prefix, "attitude-control needs the gains k_p and k_d (M = -k_p sgn(e_s) e_v - k_d Omega)");
      read_sampling(c, "for a continuous controller");
      attitude_targets.push_back(c.target);
      if (t.contains("actuator") && r.string(t, prefix, "actuator", {"torque", "wheels"}) == "wheels") {
        // The body's reaction wheels make the torque: u = -A^+ M over them (gyrostat.hpp).
        drive_wheels(t, prefix, c);
        continue;
      }
      if (t.contains("distribution"))
        r.fail(prefix + ".distribution", "splits the torque over reaction wheels: give actuator = \"wheels\"");
      reads_no_gyrostat_rate("attitude-control with actuator = \"torque\"");
      set.add(c, body);
    }
  }
  return set;
}

/// [[sensor]] kind = "gyro" | "star-tracker" (sensors.hpp): what the attitude controller through the
/// wheels sees at its samples; at most one of each.
void read_sensors(const Reader& r, const toml::table& root, std::optional<WheelAttitudeControl>& wheel_control) {
  const toml::node* node = root.get("sensor");
  if (!node) return;
  const toml::array* arr = node->as_array();
  if (!arr || arr->empty() || !arr->is_array_of_tables()) r.fail("sensor", "must be one or more [[sensor]] tables");
  if (!wheel_control)
    r.fail("sensor", "a sensor feeds a control law: give [[forcing]] kind = \"attitude-control\" with actuator = "
                     "\"wheels\" (the sensors are read at its samples)");
  if (!(wheel_control->law().period > 0.0))
    r.fail("sensor", "sensors are read at the controller's samples: give the attitude-control forcing a period");
  std::optional<GyroModel> gyro;
  std::optional<StarTrackerModel> tracker;
  for (std::size_t i = 0; i < arr->size(); ++i) {
    const toml::table& t = *arr->get(i)->as_table();
    const std::string prefix = "sensor[" + std::to_string(i) + "]";
    const std::string kind = r.string(t, prefix, "kind", {"gyro", "star-tracker"});
    auto non_negative = [&](const char* key) {
      if (!t.contains(key)) return 0.0;
      const double v = r.number(t, prefix, key);
      if (!(v >= 0.0)) r.fail(prefix + "." + key, "must be >= 0");
      return v;
    };
    std::uint64_t seed = 0;
    if (t.contains("seed")) {
      const std::int64_t s = r.integer(t, prefix, "seed");
      if (s < 0) r.fail(prefix + ".seed", "must be an integer >= 0");
      seed = static_cast<std::uint64_t>(s);
    }
    if ((kind == "gyro" && gyro) || (kind == "star-tracker" && tracker))
      r.fail(prefix + ".kind", "a second \"" + kind + "\": give one of each kind");
    if (kind == "gyro") {
      r.only_keys(t, prefix, {"kind", "noise_density", "bias_walk", "initial_bias", "seed"});
      GyroModel g;
      g.noise_density = non_negative("noise_density");
      g.bias_walk = non_negative("bias_walk");
      if (t.contains("initial_bias")) g.initial_bias = r.vector<3>(t, prefix, "initial_bias");
      g.seed = seed;
      gyro = g;
    } else {
      r.only_keys(t, prefix, {"kind", "noise_arcsec", "seed"});
      StarTrackerModel s;
      const Vector3<double> arcsec = r.vector<3>(t, prefix, "noise_arcsec");
      if (!(arcsec.minCoeff() >= 0.0)) r.fail(prefix + ".noise_arcsec", "must be >= 0 per axis");
      s.noise = arcsec * (std::numbers::pi / (180.0 * 3600.0));
      s.seed = seed;
      tracker = s;
    }
  }
  wheel_control->set_sensors(AttitudeSensors(gyro, tracker, wheel_control->law().period));
}

/// [integrator] order = 2 | 4 | 6 | 8 or composition = [gamma_1, ...]: a
/// symmetric composition of a symmetric one-step method (composition.hpp).
void read_composition(const Reader& r, const toml::table& t, IntegratorSpec& s) {
  const bool has_order = t.contains("order"), has_table = t.contains("composition");
  if (!has_order && !has_table) return;
  if (has_order && has_table)
    r.fail("integrator.composition", "give either order or composition, not both (composition is its own table)");
  const std::string key = has_order ? "integrator.order" : "integrator.composition";
  if (!s.method.traits().composable())
    r.fail(key, std::string("\"") + to_string(s.method) +
                    "\" cannot be composed to higher order: composition needs a symmetric one-step method (" +
                    method_names_where([](const MethodTraits& m) { return m.composable(); }, ", ", ", ", false) +
                    ")");
  int order = 0;
  std::vector<double> gamma;
  if (has_order) {
    const std::int64_t o = r.integer(t, "integrator", "order");
    if (o != 2 && o != 4 && o != 6 && o != 8)
      r.fail(key, "must be 2, 4, 6 or 8 (got " + std::to_string(o) +
                      "); for another table give integrator.composition = [gamma_1, ..., gamma_s]");
    order = static_cast<int>(o);
  } else {
    const toml::array* a = t.get("composition")->as_array();
    if (!a) r.fail(key, "must be an array of numbers [gamma_1, ..., gamma_s]");
    for (std::size_t i = 0; i < a->size(); ++i) gamma.push_back(r.number(*a->get(i), key + "[" + std::to_string(i) + "]"));
  }
  try {
    s.composition = has_order ? CompositionTable::of_order(order) : CompositionTable::custom(std::move(gamma));
  } catch (const InvalidInput& e) {
    r.fail(key, e.what());
  }
}

}  // namespace

std::optional<std::int64_t> default_max_steps(double duration, double epsilon) {
  const double planned = std::ceil(100.0 * duration / epsilon);
  if (!(planned <= 9007199254740992.0)) return std::nullopt;  // 2^53
  return std::max<std::int64_t>(1, static_cast<std::int64_t>(planned));
}

std::optional<TimeTransformRefusal> time_transform_refusal(const PotentialSpec& potential,
                                                          const InteractionSpec& interaction, bool forced) {
  const std::string why = "time_transform = \"potential\" adapts the step to U = -V, which measures closeness "
                          "only under gravity";
  if (potential.kind == PotentialKind::Uniform || potential.kind == PotentialKind::HeavyTop)
    return TimeTransformRefusal{"potential.kind",
                                fmt::format("\"{}\" is not taken: {} (a central field or mutual gravity)",
                                            to_string(potential.kind), why)};
  if (!interaction.none() && !interaction.descriptor->attractive)
    return TimeTransformRefusal{"interaction.kind",
                                fmt::format("\"{}\" is not taken: {}, and {}'s V can be positive",
                                            interaction_kind(interaction), why, interaction.descriptor->title)};
  if (potential.kind == PotentialKind::None && interaction.none())
    return TimeTransformRefusal{"integrator.time_transform", why + "; this scenario has no potential"};
  if (forced)
    return TimeTransformRefusal{"forcing", "is not taken with time_transform = \"potential\" (the forcing's work has "
                                           "no place in the time-transformed Hamiltonian)"};
  return std::nullopt;
}

namespace {

/// The reader's refusal of a time transformation (time_transform_refusal).
void require_attraction(const Reader& r, const PotentialSpec& potential, const InteractionSpec& interaction,
                        bool forced) {
  if (const auto refusal = time_transform_refusal(potential, interaction, forced))
    r.fail(refusal->key, refusal->reason + "; use time_transform = \"none\"");
}

/// [integrator] with time_transform = "potential" (time_transformed.hpp):
/// epsilon, the fictitious-time step, in place of step (order / composition
/// compose the step in epsilon, read before); monitor_scale, c
/// (default |V| at the start); exact_finish, whether the last step is
/// shortened to end at the duration; max_steps, the most steps the run may take
/// before it reaches duration (default 100 duration / epsilon: the physical
/// step 100 times below epsilon on average, a run that is stuck).
void read_time_transform(const Reader& r, const toml::table& t, IntegratorSpec& s) {
  s.time_transform = TimeTransform::Potential;
  if (t.contains("step"))
    r.fail("integrator.step", "with time_transform = \"potential\" the physical step adapts; give epsilon, the "
                              "fictitious-time step, instead (e.g. epsilon = 0.02)");
  if (s.method.traits().name != std::string_view("lgvi"))
    r.fail("integrator.method", "time_transform = \"potential\" is built from the LGVI's Hamiltonian form: use "
                                "method = \"lgvi\" (the default), or time_transform = \"none\"");
  s.step = r.number(t, "integrator", "epsilon");
  if (!(s.step > 0.0 && std::isfinite(s.step)))
    r.fail("integrator.epsilon", "must be a finite number > 0, got " + std::to_string(s.step));
  if (t.contains("monitor_scale")) {
    s.monitor_scale = r.number(t, "integrator", "monitor_scale");
    if (!(s.monitor_scale > 0.0 && std::isfinite(s.monitor_scale)))
      r.fail("integrator.monitor_scale", "must be a finite number > 0 (the size of -V where steps start to shrink), "
                                         "got " + std::to_string(s.monitor_scale));
  }
  s.duration = r.number(t, "integrator", "duration");
  if (!(s.duration >= 0.0 && std::isfinite(s.duration)))
    r.fail("integrator.duration", "must be a finite number >= 0, got " + std::to_string(s.duration));
  if (const toml::node* n = t.get("exact_finish")) {
    if (!n->is_boolean()) r.fail("integrator.exact_finish", "must be true or false");
    s.exact_finish = n->value<bool>().value();
  }
  if (t.contains("max_steps")) {
    s.steps = r.integer(t, "integrator", "max_steps");
    if (s.steps < 1) r.fail("integrator.max_steps", "must be an integer >= 1");
  } else if (const auto planned = default_max_steps(s.duration, s.step)) {
    s.steps = *planned;
  } else {
    r.fail("integrator.epsilon", "gives a default max_steps (100 duration / epsilon) beyond 2^53; enlarge epsilon");
  }
}

IntegratorSpec read_integrator(const Reader& r, const toml::table& root) {
  const toml::table& t = r.table(root, "", "integrator");
  r.only_keys(t, "integrator", {"method", "solver", "step", "duration", "tolerance", "max_iterations", "predictor_order",
                                "order", "composition", "time_transform", "epsilon", "monitor_scale", "max_steps",
                                "exact_finish"});
  IntegratorSpec s;
  if (t.contains("method")) {
    const toml::node* n = t.get("method");
    if (!n->is_string()) r.fail("integrator.method", "must be a string naming the method");
    try {
      s.method = Method::named(n->value<std::string>().value(), "integrator.method");
    } catch (const InvalidInput& e) {
      r.fail("", e.what());
    }
  }
  if (t.contains("solver")) {
    const std::string k = r.string(t, "integrator", "solver", {"newton", "newton-exp", "broyden"});
    s.solver.kind = k == "newton" ? SolverKind::Newton : k == "newton-exp" ? SolverKind::NewtonExp : SolverKind::Broyden;
  }
  if (t.contains("tolerance")) {
    s.solver.tolerance = r.number(t, "integrator", "tolerance");
    if (!(s.solver.tolerance > 0.0 && s.solver.tolerance < 1e-3))
      r.fail("integrator.tolerance", "must be in (0, 1e-3); the default 4 eps ~ 8.9e-16 is round-off level");
  }
  if (t.contains("max_iterations")) {
    const std::int64_t m = r.integer(t, "integrator", "max_iterations");
    if (m < 1 || m > 10000) r.fail("integrator.max_iterations", "must be an integer in [1, 10000]");
    s.solver.max_iterations = static_cast<int>(m);
  }
  if (t.contains("predictor_order")) {
    const std::int64_t o = r.integer(t, "integrator", "predictor_order");
    if (o < 0 || o > 3) r.fail("integrator.predictor_order", "must be an integer in [0, 3] (3, cubic, is the default)");
    s.solver.predictor_order = static_cast<int>(o);
  }
  read_composition(r, t, s);
  if (t.contains("time_transform") &&
      r.string(t, "integrator", "time_transform", {"none", "potential"}) == "potential") {
    read_time_transform(r, t, s);
    return s;
  }
  for (const char* key : {"epsilon", "monitor_scale", "max_steps", "exact_finish"})
    if (t.contains(key))
      r.fail(std::string("integrator.") + key, "belongs to the adaptive step; set time_transform = \"potential\" "
                                               "or remove it");
  s.step = r.number(t, "integrator", "step");
  if (!(s.step > 0.0)) r.fail("integrator.step", "must be > 0, got " + std::to_string(s.step));
  s.duration = r.number(t, "integrator", "duration");
  if (!(s.duration >= 0.0)) r.fail("integrator.duration", "must be >= 0, got " + std::to_string(s.duration));
  // n = ceil(duration / step), forgiving the round-off of the division
  // (1000 / 0.01 = 100000.00000000001, an error of a few eps * ratio); the
  // run ends at t = n step.
  const double ratio = s.duration / s.step;
  if (!(ratio <= 9007199254740992.0))  // 2^53: beyond it t0 + k h no longer tells steps apart
    r.fail("integrator.duration", "needs more than 2^53 steps of the given step; shorten it or enlarge the step");
  const double nearest = std::round(ratio);
  const double slack = std::min(0.25, 1e-9 + 64 * std::numeric_limits<double>::epsilon() * ratio);
  s.steps = static_cast<std::int64_t>(std::abs(ratio - nearest) <= slack ? nearest : std::ceil(ratio));
  return s;
}

/// Scenario files are ASCII but for comments. Checked before toml++ sees the
/// text: toml++ 3.3.0 (Debian 12) reaches __builtin_unreachable, undefined
/// behaviour, on some non-ASCII characters outside strings and comments
/// (e.g. U+00A1..U+0499 after a number; found by fuzz/fuzz_scenario.cpp, input
/// in fuzz/regressions/). No key or value of a scenario needs them.
void require_ascii_outside_comments(const std::string& text, const std::string& name) {
  enum class In { Code, Comment, Basic, Literal, MultiBasic, MultiLiteral } in = In::Code;
  int line = 1, column = 0;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    ++column;
    if (c == '\n') {
      ++line;
      column = 0;
      if (in == In::Comment || in == In::Basic || in == In::Literal) in = In::Code;  // single-line constructs end
      continue;
    }
    if (c >= 0x80 && in != In::Comment)
      throw InvalidInput(name + ":" + std::to_string(line) + ":" + std::to_string(column) +
                         ": non-ASCII character outside a comment; scenario keys and values are ASCII");
    auto starts = [&](const char* s) { return text.compare(i, std::strlen(s), s) == 0; };
    switch (in) {
      case In::Code:
        if (c == '#') in = In::Comment;
        else if (starts("\"\"\"")) in = In::MultiBasic, i += 2, column += 2;
        else if (starts("'''")) in = In::MultiLiteral, i += 2, column += 2;
        else if (c == '"') in = In::Basic;
        else if (c == '\'') in = In::Literal;
        break;
      case In::Basic:
      case In::MultiBasic:
        if (c == '\\') ++i, ++column;  // an escape: skip the escaped character
        else if (in == In::Basic && c == '"') in = In::Code;
        else if (in == In::MultiBasic && starts("\"\"\"")) in = In::Code, i += 2, column += 2;
        break;
      case In::Literal:
        if (c == '\'') in = In::Code;
        break;
      case In::MultiLiteral:
        if (starts("'''")) in = In::Code, i += 2, column += 2;
        break;
      case In::Comment: break;
    }
  }
}

}  // namespace

Scenario parse_scenario(const std::string& text, const std::string& name) {
  const Reader r(name);
  require_ascii_outside_comments(text, name);
  toml::table root;
  try {
    root = toml::parse(text, name);
  } catch (const toml::parse_error& e) {
    std::ostringstream os;
    // toml++ quotes the offending input in its description: escape it so the
    // message stays one line.
    os << name << ":" << e.source().begin.line << ":" << e.source().begin.column << ": "
       << printable(e.description());
    throw InvalidInput(os.str());
  }
  r.only_keys(root, "", {"body", "bodies", "potential", "initial", "interaction", "integrator", "output", "run",
                         "forcing", "box", "import", "sensor"});
  if (root.contains("import") && !root.get("import")->is_table()) r.fail("import", "must be a table [import]");
  const bool imported = root.contains("import");
  const bool many_body_form = root.contains("bodies") || imported;
  if (many_body_form && (root.contains("body") || root.contains("initial")))
    r.fail("bodies", "give either [body] + [initial] (one body) or [[bodies]] tables, not both");
  BodyList bodies;
  std::vector<std::string> names;
  SystemState initial;
  std::vector<double> wheel_speeds;  // [[body.wheel]] speed, per wheel
  Box box;
  int site_types = 1;  // the data file's atom types (declared, used or not), or the balls' largest type
  FileIds file_ids;
  if (imported) {
    box = read_import(r, root, name, bodies, names, initial, site_types, file_ids);
  } else if (many_body_form) {
    read_bodies(r, root, bodies, names, initial);
  } else {
    bodies.kinds.push_back(read_body(r, root, wheel_speeds));
    bodies.kind.push_back(0);
  }
  PotentialSpec potential = read_potential(r, root);
  const std::string converted = many_body_form ? std::string() : convert_orbit_attitude(r, root, bodies[0], potential);
  if (!many_body_form) initial = SystemState(read_initial(r, root, bodies[0]));
  if (!wheel_speeds.empty())
    initial.eta.assign(1, initial_wheel_momenta(r, *root.get_as<toml::table>("initial"), "initial", bodies[0],
                                                wheel_speeds, initial.w[0]));
  for (const RigidBody& kind : bodies.kinds)
    for (const Ball& ball : kind.balls()) site_types = std::max(site_types, ball.type);
  const InteractionSpec interaction = read_interaction(r, root, site_types);
  if (!imported) box = read_box(r, root, many_body_form);
  require_fits_box(r, box, bodies, potential, interaction);
  // The state is unwrapped, but a body placed millions of box lengths away
  // would have lost its place in the box to rounding.
  for (std::size_t a = 0; a < initial.size() && box.any_periodic(); ++a)
    for (int k = 0; k < 3; ++k)
      if (box.periodic(k) && !(std::abs(initial.x[a](k) - box.lower()(k)) < 0x1p20 * box.periodic_length()(k)))
        r.fail("bodies[" + std::to_string(a) + "].position",
               "lies 2^20 or more periodic lengths from the box along axis " + std::to_string(k) +
                   "; place the bodies in or near the box");
  IntegratorSpec integrator = read_integrator(r, root);
  if (bodies.size() > 1 && potential.kind == PotentialKind::HeavyTop)
    r.fail("potential.kind", "\"heavy-top\" is a single body on a pivot; this scenario has " +
                                 std::to_string(bodies.size()) + " bodies");
  if (potential.kind == PotentialKind::HeavyTop && bodies[0].rotational_dof() != 3) {
    // A linear body pivoted off its line (or a point off its pivot) is no
    // body: J about the pivot would then have three moments.
    const RigidBody& top = bodies[0];
    const Vector3<double>& chi = potential.pivot_to_com;
    const Vector3<double> off = top.rotational_dof() == 2 ? chi - chi.dot(top.linear_axis()) * top.linear_axis() : chi;
    if (off.norm() > 1e-12 * std::max(chi.norm(), 1e-300))
      r.fail("potential.pivot_to_com", top.rotational_dof() == 2
                                           ? "must lie on the linear body's axis (the inertia about a pivot off "
                                             "its line has three moments)"
                                           : "must be zero for a point mass (its inertia about the pivot would "
                                             "not be zero)");
  }
  const MethodTraits& method = integrator.method.traits();
  if (method.free_body_only && potential.kind != PotentialKind::None)
    r.fail("integrator.method", "\"" + std::string(method.name) +
                                    "\" is the free body's exact flow: it needs [potential] kind = \"none\"");
  if (method.free_body_only && (bodies.size() > 1 || !interaction.none()))
    r.fail("integrator.method", "\"" + std::string(method.name) + "\" is the exact flow of one free body; this scenario has " +
                                    std::to_string(bodies.size()) + " bodies" +
                                    (!interaction.none() ? " and an [interaction]" : ""));
  if (method.needs_principal_axes) {
    for (std::size_t a = 0; a < bodies.size(); ++a) {
      if (!bodies[a].has_principal_axes())
        r.fail("integrator.method", std::string("\"") + to_string(integrator.method) +
                                        "\" rotates about the principal axes: " +
                                        (many_body_form ? "bodies[" + std::to_string(a) + "]" : std::string("body")) +
                                        ".inertia must be diagonal in body axes (give the body in its principal axes)");
    }
  }
  // Linear bodies and points: only methods that take them, and no angular
  // momentum along a linear body's axis (none at all for a point) beyond
  // round-off, which is removed (rigid_body.hpp).
  for (std::size_t a = 0; a < bodies.size(); ++a) {
    const RigidBody& body = bodies[a];
    if (body.rotational_dof() == 3) continue;
    const std::string which = many_body_form ? fmt::format("bodies[{}] (\"{}\")", a, names[a]) : "the body";
    const std::string what = body.rotation_description();
    if (!method.linear_bodies)
      r.fail("integrator.method",
             fmt::format("\"{}\" needs three principal moments > 0; {} is {}; use {}", method.name, which, what,
                         method_names_where([](const MethodTraits& m) { return m.linear_bodies; }, ", ", " or ",
                                            false)));
    if (!body.admits_momentum(initial.w[a]))
      r.fail(many_body_form ? fmt::format("bodies[{}].w", a) : std::string("initial.w"),
             fmt::format("{} is {}: it has no angular momentum{}", which, what,
                         body.rotational_dof() == 2 ? " about its axis; give w across the axis, or omega"
                                                    : "; give w = 0"));
    initial.w[a] = body.admissible_momentum(initial.w[a]);
  }
  // The rotation per step |Omega| h: at pi the discrete flow is undefined
  // (and the rotation equation has no root well before, near 1 rad). An
  // adaptive step's physical step is at most epsilon (g <= 1), its size far
  // from the sources.
  const char* step_key = integrator.adaptive() ? "epsilon" : "step";
  for (std::size_t a = 0; a < bodies.size(); ++a) {
    const double rotation = (0.5 * bodies[a].inertia_inverse() * initial.w[a]).norm() * integrator.step;
    if (rotation >= std::numbers::pi)
      r.fail(std::string("integrator.") + step_key,
             fmt::format("the initial rotation per step |Omega| {}{} = {} rad reaches pi; use {} below {} (0.1 rad "
                         "per step)",
                         integrator.adaptive() ? "epsilon" : "h",
                         many_body_form ? " of bodies[" + std::to_string(a) + "]" : std::string(),
                         std::to_string(rotation), integrator.adaptive() ? "an epsilon" : "a step",
                         std::to_string(integrator.step / rotation * 0.1)));
  }
  int threads = 0;
  std::optional<OnContact> on_contact;
  if (const toml::table* run = r.optional_table(root, "", "run")) {
    r.only_keys(*run, "run", {"threads", "on_contact"});
    if (run->contains("threads")) {
      const std::int64_t n = r.integer(*run, "run", "threads");
      if (n < 1 || n > 1024) r.fail("run.threads", "must be an integer in [1, 1024] (default: all cores)");
      threads = static_cast<int>(n);
    }
    if (run->contains("on_contact")) {
      if (!many_body_form)
        r.fail("run.on_contact", "is about contact between [[bodies]]; a single body has none (a central field's "
                                 "own contact: potential.stop_at_contact)");
      const std::string v = r.string(*run, "run", "on_contact", {"stop", "warn", "ignore"});
      on_contact = v == "stop" ? OnContact::Stop : v == "warn" ? OnContact::Warn : OnContact::Ignore;
    }
  }
  std::int64_t every = 1;
  std::optional<BodyLists> body_lists;  // [output] body_lists, if given
  TrajectoryFormat format;
  RowLayout layout = many_body_form ? RowLayout::long_format : RowLayout::single_body;
  if (const toml::table* out = r.optional_table(root, "", "output")) {
    r.only_keys(*out, "output", {"every", "format", "body_lists", "layout"});
    if (out->contains("every")) {
      every = r.integer(*out, "output", "every");
      if (every < 1) r.fail("output.every", "must be an integer >= 1");
    }
    if (out->contains("body_lists")) {
      if (!many_body_form)
        r.fail("output.body_lists", "is about the lists of [[bodies]]; a single body's final state is "
                                    "summary.json's \"final\": remove the key");
      body_lists = r.string(*out, "output", "body_lists", {"summary", "file"}) == "file" ? BodyLists::file
                                                                                         : BodyLists::summary;
    }
    if (out->contains("format")) {
      std::vector<std::string_view> format_names;
      for (const FormatDescriptor* d : trajectory_formats()) format_names.push_back(d->name);
      format = TrajectoryFormat::named(r.string(*out, "output", "format", format_names));
    }
    if (out->contains("layout")) {
      const std::string v = r.string(*out, "output", "layout", {row_layout_names[0], row_layout_names[1]});
      layout = v == row_layout_names[0] ? RowLayout::single_body : RowLayout::long_format;
      if (layout == RowLayout::single_body && bodies.size() != 1)
        r.fail("output.layout", fmt::format("\"single-body\" holds one body's columns, and the scenario has {} "
                                            "bodies: use \"long\" (one row a step and body)", bodies.size()));
      if (layout == RowLayout::single_body && interaction.descriptor && interaction.descriptor->reach)
        r.fail("output.layout", "\"single-body\" has no temperature column, which a run with a short-range "
                                "interaction writes: use \"long\"");
    }
  }
  const std::string stem = std::filesystem::path(name).stem().string();
  Scenario sc;
  sc.name = stem;
  sc.source = name;
  try {
    sc.system = System(std::move(bodies.kinds), std::move(bodies.kind), std::move(names), box);
  } catch (const InvalidInput& e) {
    r.fail("", e.what());
  }
  if (many_body_form) require_no_overlap(r, sc.system, initial);
  // Contact between bodies is checked at every step unless [run] on_contact
  // says otherwise; a Lennard-Jones system is exempt unless it says so (its
  // balls' radii only shape the inertia: the potential keeps molecules apart;
  // so is any interaction whose descriptor says it keeps bodies apart).
  sc.on_contact_given = on_contact.has_value();
  sc.on_contact = on_contact.value_or(!many_body_form || (interaction.descriptor && interaction.descriptor->keeps_bodies_apart)
                                          ? OnContact::Ignore
                                          : OnContact::Stop);
  bool inlined = false;
  sc.forcing = read_forcing(r, root, sc.system,
                            integrator.adaptive() ? integrator.duration
                                                  : static_cast<double>(integrator.steps) * integrator.step,
                            std::filesystem::path(name).parent_path(), inlined, sc.wheel_torques, sc.wheel_control,
                            sc.attitude_targets);
  if (sc.wheel_control && !sc.wheel_torques.empty())
    r.fail("forcing", "attitude control through the wheels (actuator = \"wheels\") drives every wheel: give no "
                      "kind = \"wheel-torque\" with it");
  read_sensors(r, root, sc.wheel_control);
  if (sc.system.has_wheels()) {
    // The gyrostat step (wheels.hpp) is the Hamiltonian LGVI's, at one step size (read_forcing refuses a
    // forcing that reads a gyrostat's rate).
    if (integrator.method.traits().name != std::string_view("lgvi"))
      r.fail("integrator.method", "a body with reaction wheels ([[body.wheel]]) is stepped by \"lgvi\" only");
    if (integrator.composition.gamma().size() != 1)
      r.fail("integrator.order", "a body with reaction wheels takes the plain step (order 2) so far");
    if (integrator.adaptive())
      r.fail("integrator.time_transform", "a body with reaction wheels takes a fixed step so far");
    if (integrator.solver.kind != SolverKind::Newton)
      r.fail("integrator.solver", "a body with reaction wheels is solved by \"newton\" (the Cayley chart) only so far");
  }
  if (!sc.forcing.empty() && !integrator.method.traits().accepts_forcing)
    r.fail("forcing", std::string("integrator.method \"") + to_string(integrator.method) +
                          "\" does not take [[forcing]]; the discrete Lagrange-d'Alembert forcing is built into " +
                          method_names_where([](const MethodTraits& m) { return m.accepts_forcing; }, ", ", " and ",
                                             true) +
                          " (composed to any order or not)");
  if (integrator.adaptive()) require_attraction(r, potential, interaction, !sc.forcing.empty());
  sc.potential = potential;
  sc.interaction = interaction;
  sc.initial_state = std::move(initial);
  sc.many_body_form = many_body_form;
  sc.layout = layout;
  sc.threads = threads;
  sc.integrator = integrator;
  sc.output_every = every;
  sc.output_format = format;
  sc.body_lists = body_lists.value_or(many_body_form && sc.bodies() > kBodyListsInSummaryUpTo ? BodyLists::file
                                                                                             : BodyLists::summary);
  sc.source_text = text;
  sc.imported = imported;
  sc.file_ids = std::move(file_ids);
  if (inlined || !converted.empty() || imported) {
    // File tables were read into the document, [initial] orbit / attitude
    // converted into plain keys, or an [import]'s file made absolute with its
    // checksum: the run's copy of the scenario holds them (toml++ prints each
    // double to round-trip).
    sc.source_text = converted + write_toml(root) + "\n";
  }
  return sc;
}

Scenario read_scenario(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw InvalidInput(path + ": is a directory, not a scenario file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InvalidInput(path + ": cannot open the scenario file");
  std::ostringstream ss;
  ss << in.rdbuf();
  const std::string text = ss.str();
  if (text.find('\0') != std::string::npos) throw InvalidInput(path + ": not a text file (contains NUL bytes)");
  return parse_scenario(text, path);
}

ConservationLaws conservation_laws(const Scenario& sc) {
  ConservationLaws laws;
  // Motor torques on reaction wheels, and pair damping, do work but are internal: they keep both momenta.
  const bool external = !sc.forcing.empty() && !sc.forcing.internal_only();
  laws.forced = !sc.forcing.empty() || !sc.wheel_torques.empty() || sc.wheel_control.has_value();
  const PotentialKind k = sc.potential.kind;
  // A periodic box is not invariant under rotations: no angular momentum.
  if (sc.system.box().any_periodic())
    laws.angular_momentum = ConservationLaws::Angular::NotConserved;
  else if (!external && (k == PotentialKind::None || (k == PotentialKind::Central && sc.potential.j2 == 0.0)))
    laws.angular_momentum = ConservationLaws::Angular::Conserved;
  else if (!external && k == PotentialKind::Central)
    laws.angular_momentum = ConservationLaws::Angular::AlongPole;
  laws.linear_momentum = !external && k == PotentialKind::None;
  return laws;
}

bool has_gravity_gradient_body(const Scenario& sc) {
  if (sc.potential.kind != PotentialKind::Central || sc.potential.point_masses) return false;
  for (const RigidBody& b : system_bodies(sc.system))
    if (b.balls().empty()) return true;
  return false;
}

std::string describe_reach(const System& system, const Contact& c) {
  auto radius = [&](std::size_t a, std::ptrdiff_t ball) {
    const RigidBody& b = system.body(a);
    return ball >= 0 ? b.balls()[static_cast<std::size_t>(ball)].radius
                     : b.extent() == Extent::Sphere ? b.semi_axes().x() : 0.0;
  };
  auto piece = [&](std::size_t a, std::ptrdiff_t ball) {
    const RigidBody& b = system.body(a);
    if (ball < 0 && b.extent() == Extent::Ellipsoid)
      return fmt::format("the ellipsoid ({}, {}, {})", b.semi_axes().x(), b.semi_axes().y(), b.semi_axes().z());
    const double r = radius(a, ball);
    return r > 0.0 ? fmt::format("the {} of radius {}", ball >= 0 ? "ball" : "sphere", r) : std::string("a point");
  };
  if (system.body(c.a).extent() != Extent::Ellipsoid && system.body(c.b).extent() != Extent::Ellipsoid)
    return fmt::format("radii {} + {}", radius(c.a, c.ball_a), radius(c.b, c.ball_b));
  return fmt::format("{} and {} would just touch at centre distance {} along their line", piece(c.a, c.ball_a),
                     piece(c.b, c.ball_b), c.reach);
}

const char* to_string(OnContact c) {
  switch (c) {
    case OnContact::Stop: return "stop";
    case OnContact::Warn: return "warn";
    case OnContact::Ignore: return "ignore";
  }
  return "?";
}

const char* to_string(PotentialKind k) {
  switch (k) {
    case PotentialKind::None: return "none";
    case PotentialKind::Central: return "central";
    case PotentialKind::Uniform: return "uniform";
    case PotentialKind::HeavyTop: return "heavy-top";
  }
  return "?";
}

const char* to_string(Method m) { return m.name(); }

}  // namespace lgvi::app
