// An oblate central body (J2, potential.hpp): the energy and force at a
// hand-computed point, force and torque against finite differences of the
// energy, the angular momentum about the pole conserved to round-off by the
// LGVI while the other components change, and the secular regression of
// the node of an inclined orbit against first-order perturbation theory.
#include "scenario.hpp"
#include "test_support.hpp"

#include <lgvi/integrate.hpp>
#include <lgvi/interaction.hpp>
#include <lgvi/lgvi.hpp>
#include <lgvi/potential.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <numbers>
#include <vector>

namespace {

using lgvi::Ball;
using lgvi::CentralGravity;
using lgvi::RigidBody;
using lgvi::S3d;
using lgvi::SystemState;
using V3 = lgvi::Vector3<double>;

constexpr double eps = std::numeric_limits<double>::epsilon();

RigidBody point_mass() { return RigidBody(1.0, lgvi::Matrix3<double>::Identity()); }

RigidBody three_balls() {
  return RigidBody::from_balls({{V3(0.3, 0.0, 0.0), 1.0, 0.05}, {V3(-0.2, 0.25, 0.0), 1.0, 0.05},
                                {V3(-0.1, -0.2, 0.15), 1.0, 0.05}});
}

// On the pole at distance 2 (mu = m = R = 1, J2 = 0.1): P2 = 1, so
// V = -1/z + J2/z^3 = -0.4875 and F = -dV/dz = -(1/z^2 - 3 J2/z^4) = -0.23125
// along the pole; in the equatorial plane at distance 2, P2 = -1/2:
// V = -1/r - J2/(2 r^3) = -0.50625, F = -(1/r^2 + 3 J2/(2 r^4)) = -0.259375 radially.
TEST(J2, EnergyAndForceAtHandComputedPoints) {
  const CentralGravity g(point_mass(), 1.0, false, 0.1, 1.0, V3(0, 0, 1));
  const auto pole = g.evaluate(V3(0, 0, 2), S3d());
  EXPECT_NEAR(pole.energy, -0.4875, 4 * eps);
  EXPECT_NEAR((pole.force - V3(0, 0, -0.23125)).norm(), 0.0, 4 * eps);
  const auto equator = g.evaluate(V3(0, 2, 0), S3d());
  EXPECT_NEAR(equator.energy, -0.50625, 4 * eps);
  EXPECT_NEAR((equator.force - V3(0, -0.259375, 0)).norm(), 0.0, 4 * eps);
  // J2 = 0 is the point source, bit for bit.
  const CentralGravity point(three_balls(), 1.0), zero(three_balls(), 1.0, false, 0.0, 1.0, V3(1, 0, 0));
  const S3d q = lgvi::test::random_unit_quaternion();
  EXPECT_EQ(point.evaluate(V3(1, 2, 3), q).force, zero.evaluate(V3(1, 2, 3), q).force);
}

// Fourth-order central differences of the energy (check_potential_derivatives):
// round-off eps |V| / h dominates, ~1e-12 relative for the force and, for
// the tidal torque ~ |V| (rho/r)^2, ~1e-10 at r/rho ~ 10; 1e-8 keeps margin
// while a wrong sign or factor shows as O(1). J2 = 0.3 makes the J2 term a
// third of the field at r ~ 1.2 R, so an error in it cannot hide.
TEST(J2, ForceAndTorqueMatchFiniteDifferencesOfTheEnergy) {
  for (int trial = 0; trial < 20; ++trial) {
    const V3 pole = lgvi::test::random_vector().normalized();
    const CentralGravity g(three_balls(), 1.3, false, 0.3, 2.0, pole);
    const V3 x = lgvi::test::random_vector().normalized() * lgvi::test::uniform(2.2, 4.0);
    const S3d q = lgvi::test::random_unit_quaternion();
    const auto check = lgvi::check_potential_derivatives(g, x, q);
    EXPECT_LE(check.force_error, 1e-8) << "x = " << x.transpose();
    EXPECT_LE(check.torque_error, 1e-8) << "x = " << x.transpose();
  }
}

using Field = lgvi::ExternalField<CentralGravity>;

// The field is symmetric about the pole: the discrete flow conserves k . L
// (discrete Noether), to round-off of |L| per step (1e-13 relative after
// 20000 steps of an inclined, tumbling orbit), while L itself precesses:
// |L - L0| reaches O(J2) relative.
TEST(J2, AngularMomentumAboutThePoleIsConserved) {
  const V3 pole = V3(0.2, -0.3, 1.0).normalized();
  const RigidBody body = three_balls();
  const lgvi::System sys(body);
  lgvi::LieGroupVariationalIntegrator<Field> lgvi(sys, Field::uniform(CentralGravity(body, 1.0, false, 0.05, 1.0, pole), 1));
  SystemState s(1);
  s.x[0] = V3(1.6, 0.0, 0.3);
  s.p[0] = body.mass() * V3(0.0, 0.62, 0.45);
  s.w[0] = V3(0.3, -0.5, 0.9);
  s.q[0] = lgvi::test::random_unit_quaternion();
  const V3 l0 = lgvi::angular_momentum(s);
  double worst_pole = 0.0, largest_change = 0.0;
  lgvi::integrate_n_steps(lgvi, s, 0.0, 0.005, 20000, [&](const lgvi::SystemStepInfo& i) {
    const V3 l = lgvi::angular_momentum(i.state);
    worst_pole = std::max(worst_pole, std::abs(pole.dot(l - l0)));
    largest_change = std::max(largest_change, (l - l0).norm());
  });
  EXPECT_LT(worst_pole, 1e-13 * l0.norm()) << worst_pole;
  EXPECT_GT(largest_change, 1e-3 * l0.norm()) << largest_change;
}

// The node of a circular orbit of radius a and inclination i regresses at
// the secular rate dOmega/dt = -(3/2) n J2 (R/a)^2 cos i (first-order theory;
// Vallado 9.6). Over 30 orbits the fitted rate agrees to 1 % (the theory's
// neglected O(J2) relative terms are 1e-3 here, and the difference between
// osculating and mean initial elements shifts the rate by O(J2) relative too).
TEST(J2, NodeRegressesAtTheSecularRate) {
  const double mu = 1.0, j2 = 1e-3, R = 1.0, a = 1.5, incl = 40.0 * std::numbers::pi / 180.0;
  const RigidBody body = point_mass();
  const lgvi::System sys(body);
  lgvi::LieGroupVariationalIntegrator<Field> lgvi(sys, Field::uniform(CentralGravity(body, mu, false, j2, R, V3(0, 0, 1)), 1));
  SystemState s(1);
  const double v = std::sqrt(mu / a), n = std::sqrt(mu / (a * a * a));
  s.x[0] = V3(a, 0, 0);
  s.p[0] = V3(0, v * std::cos(incl), v * std::sin(incl));
  const double period = 2 * std::numbers::pi / n, h = period / 400;
  const auto steps = static_cast<std::int64_t>(30 * 400);
  // Least-squares slope of the node's longitude atan2(L_x, -L_y) over the run.
  double st = 0, so = 0, stt = 0, sto = 0, count = 0;
  lgvi::integrate_n_steps(lgvi, s, 0.0, h, steps, [&](const lgvi::SystemStepInfo& i) {
    const V3 l = lgvi::angular_momentum(i.state);
    const double node = std::atan2(l.x(), -l.y());
    st += i.t;
    so += node;
    stt += i.t * i.t;
    sto += i.t * node;
    ++count;
  });
  const double rate = (count * sto - st * so) / (count * stt - st * st);
  const double theory = -1.5 * n * j2 * (R / a) * (R / a) * std::cos(incl);
  EXPECT_NEAR(rate / theory, 1.0, 1e-2) << rate << " vs " << theory;
}

// The scenario keys: the bundled LEO scenario reads with Earth's values;
// each mistake gets one message naming the key.
TEST(J2, ScenarioKeys) {
  const auto leo = lgvi::app::read_scenario(std::string(LGVI_SCENARIO_DIR) + "/leo-gravity-gradient.toml");
  EXPECT_EQ(leo.potential.j2, 1.08262668e-3);
  EXPECT_EQ(leo.potential.reference_radius, 6378137.0);
  EXPECT_EQ(leo.potential.pole, V3(0, 0, 1));
  const std::string base = R"(
[body]
mass = 1.0
inertia = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
[initial]
position = [3.0, 0.0, 0.0]
quaternion = [1.0, 0.0, 0.0, 0.0]
momentum = [0.0, 0.5, 0.0]
w = [0.0, 0.0, 0.0]
[integrator]
step = 0.01
duration = 1.0
[potential]
kind = "central"
mu = 1.0
)";
  auto error = [&](const std::string& extra) {
    try {
      lgvi::app::parse_scenario(base + extra, "j2.toml");
    } catch (const lgvi::InvalidInput& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  EXPECT_NE(error("j2 = 0.001\n").find("key 'potential.reference_radius': missing"), std::string::npos);
  EXPECT_NE(error("j2 = 0.001\nreference_radius = -1.0\n").find("must be > 0"), std::string::npos);
  EXPECT_NE(error("j2 = 0.001\nreference_radius = 1.0\npole = [0, 0, 0]\n").find("key 'potential.pole'"),
            std::string::npos);
  EXPECT_NE(error("j2 = 0.001\nreference_radius = 1.0\npole = [0, 1, 1]\n").find("must be a unit vector"),
            std::string::npos);
  EXPECT_NE(error("pole = [0, 0, 1]\n").find("give j2 too"), std::string::npos);
  EXPECT_EQ(error("j2 = 0.001\nreference_radius = 1.0\npole = [0, 1, 0]\n"), "(no error)");
}

}  // namespace
