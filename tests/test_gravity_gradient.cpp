// A body given by mass and inertia in a central field feels the second-order
// (MacCullagh) potential (potential.hpp, CentralGravity): its energy, force
// and torque against an independent evaluation of the inertial-frame formula
// and against finite differences of the energy; the ball model of a mass
// distribution and the inertia model of the same mass and inertia agree to
// O((size / r)^2) in the torque; a spacecraft whose principal axes are
// aligned with LVLH on a circular orbit stays aligned, and a small pitch
// offset librates at the classical gravity-gradient frequency; the scenario
// key `[potential] model` and the summary's statement of the model.
#include "app/scenario.hpp"
#include "scenario_support.hpp"
#include "test_support.hpp"

#include <lgvi/integrate.hpp>
#include <lgvi/interaction.hpp>
#include <lgvi/lgvi.hpp>
#include <lgvi/potential.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

namespace test_gravity_gradient {

namespace {

using lgvi::CentralGravity;
using lgvi::RigidBody;
using lgvi::S3d;
using lgvi::SystemState;
using M3 = lgvi::Matrix3<double>;
using V3 = lgvi::Vector3<double>;
using Model = CentralGravity::Model;

constexpr double eps = std::numeric_limits<double>::epsilon();
constexpr double pi = std::numbers::pi;

/// A spacecraft-like body: mass 2, a full (non-diagonal) inertia that
/// satisfies the triangle inequality.
RigidBody tumbling_body() {
  M3 j;
  j << 0.9, 0.1, -0.05, 0.1, 1.6, 0.2, -0.05, 0.2, 2.1;
  return RigidBody(2.0, j);
}

/// The MacCullagh potential written in the inertial frame with I = R J R^T,
/// independently of CentralGravity's body-frame form:
///   V = -mu m / r - (mu / 2 r^3)(tr I - 3 rhat^T I rhat),
///   F = -mu m r / r^3 - (3 mu / 2 r^5) [(tr I - 5 rhat^T I rhat) r + 2 I r],
///   M = R^T (3 mu / r^3) rhat x I rhat.
lgvi::PotentialEvaluation maccullagh(const RigidBody& b, double mu, const V3& x, const S3d& q) {
  const M3 R = q.matrix();
  const M3 I = R * b.inertia() * R.transpose();
  const double r = x.norm();
  const V3 rhat = x / r;
  const double rir = rhat.dot(I * rhat);
  lgvi::PotentialEvaluation e;
  e.energy = -mu * b.mass() / r - mu / (2 * r * r * r) * (I.trace() - 3 * rir);
  e.force = -mu * b.mass() * x / (r * r * r) -
            3 * mu / (2 * std::pow(r, 5)) * ((I.trace() - 5 * rir) * x + 2 * I * x);
  e.torque = R.transpose() * (3 * mu / (r * r * r) * rhat.cross(I * rhat));
  return e;
}

// The two evaluations differ only by round-off: each value is a short sum of
// terms no larger than the point-mass term mu m / r (energy) or mu m / r^2
// (force), each term rounded a few times, so 64 eps of those scales bounds
// the difference; the torque (no point-mass part) to 64 eps of its own size
// (scaled by the largest product it is formed from, 3 mu |J| / r^3).
TEST(GravityGradient, MatchesAnIndependentEvaluationOfTheFormula) {
  const RigidBody body = tumbling_body();
  const double mu = 3.7;
  for (int trial = 0; trial < 20; ++trial) {
    const V3 x = lgvi::test::random_vector().normalized() * lgvi::test::uniform(2.0, 20.0);
    const S3d q = lgvi::test::random_unit_quaternion();
    const auto got = CentralGravity(body, mu).evaluate(x, q);
    const auto want = maccullagh(body, mu, x, q);
    const double r = x.norm();
    EXPECT_NEAR(got.energy, want.energy, 64 * eps * mu * body.mass() / r);
    EXPECT_MAT_NEAR(got.force, want.force, 64 * eps * mu * body.mass() / (r * r));
    EXPECT_MAT_NEAR(got.torque, want.torque, 64 * eps * 3 * mu * body.inertia().norm() / (r * r * r));
    // Non-trivial: the gradient torque of this body is nowhere near zero.
    EXPECT_GT(got.torque.norm(), 1e-3 * mu * body.inertia().norm() / (r * r * r));
  }
}

// Fourth-order differences of V (check_potential_derivatives): the round-off
// eps |V| / h ~ 1e-13 |V| dominates; the torque ~ |V| (size / r)^2 is then
// checked to ~1e-13 (r / size)^2, 4e-11 at r = 20 here. 1e-8 keeps two orders
// of margin while a wrong sign or factor shows as O(1). With J2 the force and
// energy gain the J2 terms on the centre of mass: the check covers both.
TEST(GravityGradient, ForceAndTorqueMatchFiniteDifferencesOfTheEnergy) {
  const RigidBody body = tumbling_body();
  const CentralGravity point_source(body, 1.0);
  const CentralGravity oblate(body, 1.0, false, 0.05, 1.0, V3(0.1, -0.2, 1.0).normalized());
  for (const CentralGravity* g : {&point_source, &oblate}) {
    EXPECT_TRUE(g->has_gradient_term());
    for (int trial = 0; trial < 10; ++trial) {
      const V3 x = lgvi::test::random_vector().normalized() * lgvi::test::uniform(2.0, 20.0);
      const S3d q = lgvi::test::random_unit_quaternion();
      const auto check = lgvi::check_potential_derivatives(*g, x, q);
      EXPECT_LE(check.force_error, 1e-8) << "x = " << x.transpose();
      EXPECT_LE(check.torque_error, 1e-8) << "x = " << x.transpose();
    }
  }
}

// Model::PointMass is the previous behaviour, exactly: a mass + inertia body
// feels -mu m / r, its force and no torque, whatever its inertia; a body of
// balls is the same under both models (each ball a point mass, its stop at
// contact kept), bit for bit.
TEST(GravityGradient, PointMassModelHasNoTorque) {
  const RigidBody body = tumbling_body();
  const CentralGravity point(body, 2.0, false, Model::PointMass);
  EXPECT_FALSE(point.has_gradient_term());
  const V3 x(3.0, -1.0, 2.0);
  const auto e = point.evaluate(x, lgvi::test::random_unit_quaternion());
  EXPECT_EQ(e.energy, -2.0 * body.mass() / x.norm());
  EXPECT_EQ(e.torque, V3::Zero());
  const RigidBody balls = RigidBody::from_balls({{V3(1, 0, 0), 1.0, 0.1}, {V3(-1, 0.5, 0), 2.0, 0.1}});
  EXPECT_FALSE(CentralGravity(balls, 1.0).has_gradient_term());
  const S3d q = lgvi::test::random_unit_quaternion();
  const auto extended = CentralGravity(balls, 1.0, true, Model::Extended).evaluate(x, q);
  const auto point_balls = CentralGravity(balls, 1.0, true, Model::PointMass).evaluate(x, q);
  EXPECT_EQ(point_balls.energy, extended.energy);
  EXPECT_EQ(point_balls.force, extended.force);
  EXPECT_EQ(point_balls.torque, extended.torque);
  EXPECT_GT(point_balls.torque.norm(), 0.0);
  // stop_at_contact still sees the balls' radii under PointMass: ball 0 at 0.05 from the source.
  const V3 near_ball0 = -q.act(balls.balls()[0].position) + V3(0.05, 0, 0);
  EXPECT_THROW(CentralGravity(balls, 1.0, true, Model::PointMass).evaluate(near_ball0, q), lgvi::StepFailure);
}

// stop_at_contact for a body of known extent without balls: the run stops
// when the source lies inside the sphere (a shape, or a mass + inertia body's
// bounding sphere) or the ellipsoid, not only when the centre of mass reaches
// it. The ellipsoid (2, 0.5, 0.5) turned +30 degrees about z holds the source
// 1.8 away along its long axis, not 1.8 away at -30 degrees (its reach there
// is 0.57), which also tells R from R^T.
TEST(GravityGradient, StopAtContactSeesTheShape) {
  const RigidBody sphere = RigidBody::sphere(1.0, 2.0);
  EXPECT_THROW(CentralGravity(sphere, 1.0, true).evaluate(V3(1.0, 0.5, 0.0), S3d()), lgvi::StepFailure);
  EXPECT_NO_THROW(CentralGravity(sphere, 1.0, true).evaluate(V3(2.1, 0.0, 0.0), S3d()));
  EXPECT_NO_THROW(CentralGravity(sphere, 1.0, false).evaluate(V3(1.0, 0.5, 0.0), S3d()));  // not asked for
  const RigidBody bounded = RigidBody(1.0, M3::Identity()).bounded_by(1.5);
  EXPECT_THROW(CentralGravity(bounded, 1.0, true).evaluate(V3(0.0, 1.4, 0.0), S3d()), lgvi::StepFailure);
  const RigidBody ellipsoid = RigidBody::ellipsoid(1.0, V3(2.0, 0.5, 0.5));
  const S3d turned(std::cos(pi / 12), 0.0, 0.0, std::sin(pi / 12));  // +30 degrees about z
  auto x_at = [](double degrees) {  // the body's centre, seen from the source: the source at -x
    const double a = degrees * pi / 180.0;
    return V3(-1.8 * std::cos(a), -1.8 * std::sin(a), 0.0);
  };
  try {
    CentralGravity(ellipsoid, 1.0, true).evaluate(x_at(30.0), turned);
    ADD_FAILURE() << "the source inside the ellipsoid went unnoticed";
  } catch (const lgvi::StepFailure& e) {
    EXPECT_NE(std::string(e.what()).find("the body's surface reached the centre"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(CentralGravity(ellipsoid, 1.0, true).evaluate(x_at(-30.0), turned));
}

// Six balls in pairs symmetric about the centre of mass (equal masses at
// +rho and -rho, so the odd terms of the multipole expansion cancel): the
// ball model's potential, sum_i -(mu m_i / r) sum_n (rho_i / r)^n P_n(cos g_i),
// is the inertia model's (n <= 2; a ball's own 2/5 m r^2 is isotropic and
// exerts no torque) plus the n = 4, 6, ... terms. With M4 = sum m_i rho_i^4,
// |P_4| <= 1 and |P_4'| <= 10 (|P_n'| <= n (n + 1) / 2), the n = 4 term bounds
//   the energy difference by mu M4 / r^5,
//   the torque difference by 10 mu M4 / r^5 (cos g_i turns at a rate <= 1),
//   the force difference by sqrt(5^2 + 10^2) mu M4 / r^6 (radial: d/dr of
//   r^-5; transverse: P_4' times d cos g / d x, at most 1 / r),
// and the n >= 6 terms add less than (21/10)(s/r)^2 ~ 0.5 % at r = 20 s:
// bounds 1.01 times those. This checks the energy and force of the inertia
// model against an independent physical model, not only the torque. Relative
// to the torque itself (~ mu m s^2 / r^3) the difference is O((s / r)^2), so
// doubling r divides it by 4: the order check, in [3.5, 4.5] (the n = 6 term
// shifts the ratio by ~1 %).
TEST(GravityGradient, BallAndInertiaModelsAgreeToSecondOrderInSize) {
  const RigidBody balls = RigidBody::from_balls({{V3(1.0, 0.2, 0.0), 1.0, 0.1}, {V3(-1.0, -0.2, 0.0), 1.0, 0.1},
                                                 {V3(0.1, 0.6, 0.3), 2.0, 0.1}, {V3(-0.1, -0.6, -0.3), 2.0, 0.1},
                                                 {V3(0.0, 0.2, 0.5), 1.5, 0.1}, {V3(0.0, -0.2, -0.5), 1.5, 0.1}});
  const RigidBody inertia(balls.mass(), balls.inertia());
  double size = 0.0, fourth_moment = 0.0;
  for (const lgvi::Ball& b : balls.balls()) {
    size = std::max(size, b.position.norm());
    fourth_moment += b.mass * std::pow(b.position.norm(), 4);
  }
  for (int trial = 0; trial < 5; ++trial) {
    const V3 dir = lgvi::test::random_vector().normalized();
    const S3d q = lgvi::test::random_unit_quaternion();
    auto difference = [&](double r) {
      const auto b = CentralGravity(balls, 1.0).evaluate(r * dir, q);
      const auto i = CentralGravity(inertia, 1.0).evaluate(r * dir, q);
      return std::pair((b.torque - i.torque).norm(), (b.torque - i.torque).norm() / b.torque.norm());
    };
    const double r = 20 * size;
    const auto [absolute, d1] = difference(r);
    const double d2 = difference(2 * r).second;
    EXPECT_LE(absolute, 1.01 * 10 * fourth_moment / std::pow(r, 5)) << absolute;
    EXPECT_GT(absolute, 0.0);
    const auto b = CentralGravity(balls, 1.0).evaluate(r * dir, q);
    const auto i = CentralGravity(inertia, 1.0).evaluate(r * dir, q);
    EXPECT_LE(std::abs(b.energy - i.energy), 1.01 * fourth_moment / std::pow(r, 5));
    EXPECT_LE((b.force - i.force).norm(), 1.01 * std::sqrt(125.0) * fourth_moment / std::pow(r, 6));
    EXPECT_GT(d1 / d2, 3.5) << d1 << " " << d2;
    EXPECT_LT(d1 / d2, 4.5) << d1 << " " << d2;
  }
}

/// A spacecraft on a circular orbit of radius 1 about mu = 1 (n = 1), with
/// principal moments (yaw, roll, pitch) = J_x, J_y, J_z along LVLH's x
/// (radial), y (along-track) and z (orbit normal) when pitch = 0, turning with
/// the LVLH frame; integrated by the LGVI with `per_orbit` steps an orbit.
/// Returns the pitch angle (body x from the radial direction, about the orbit
/// normal) at every step, and the largest roll/yaw angle (body z from the
/// orbit normal).
struct Libration {
  std::vector<double> t, pitch;
  double out_of_plane = 0.0;
  double momentum_change = 0.0;  ///< max |L - L0| / |L0|
  double eccentricity = 0.0;     ///< the largest of the orbit's (Laplace-Runge-Lenz vector, mu = m = 1)
};

Libration librate(double pitch0, int per_orbit, double orbits, Model model = Model::Extended) {
  // A small body (J ~ 1e-8 m r^2): its gradient force perturbs the orbit by
  // ~1e-8 relative, so the orbit is circular and n = 1 to that level.
  const V3 moments = 1e-8 * V3(1.0, 2.0, 2.5);
  const RigidBody body(1.0, moments.asDiagonal().toDenseMatrix());
  using Field = lgvi::ExternalField<CentralGravity>;
  lgvi::LieGroupVariationalIntegrator<Field> lgvi(lgvi::System(body), Field::uniform(CentralGravity(body, 1.0, false, model), 1));
  SystemState s(1);
  s.x[0] = V3(1, 0, 0);
  s.p[0] = V3(0, 1, 0);
  s.q[0] = S3d(std::cos(pitch0 / 2), 0, 0, std::sin(pitch0 / 2));
  s.w[0] = 2.0 * body.inertia() * V3(0, 0, 1);  // Omega = n z in body axes (pitch about z)
  const V3 l0 = lgvi::angular_momentum(s);
  Libration out;
  const double h = 2 * pi / per_orbit;
  const auto steps = static_cast<std::int64_t>(orbits * per_orbit);
  lgvi::integrate_n_steps(lgvi, s, 0.0, h, steps, [&](const lgvi::SystemStepInfo& i) {
    const M3 R = i.state.q[0].matrix();
    const V3 radial = i.state.x[0].normalized();
    const V3 normal = i.state.x[0].cross(i.state.p[0]).normalized();
    const V3 body_x = R.col(0);
    out.t.push_back(i.t);
    out.pitch.push_back(std::atan2(radial.cross(body_x).dot(normal), radial.dot(body_x)));
    out.out_of_plane = std::max(out.out_of_plane, std::atan2(R.col(2).cross(normal).norm(), R.col(2).dot(normal)));
    const V3 lrl = i.state.p[0].cross(i.state.x[0].cross(i.state.p[0])) - radial;
    out.eccentricity = std::max(out.eccentricity, lrl.norm());
    out.momentum_change = std::max(out.momentum_change, (lgvi::angular_momentum(i.state) - l0).norm() / l0.norm());
  });
  return out;
}

// Aligned with LVLH and turning with it, the body is at the gravity-gradient
// equilibrium of the continuous problem. The discrete flow started from the
// continuous circular orbit's state follows a slightly eccentric orbit,
// e = O(h^2), at most the largest length of the Laplace-Runge-Lenz vector
// along the run (e below). Linearized on an orbit of eccentricity e, the
// pitch obeys theta'' + omega_p^2 theta = 2 e n^2 sin(n t) (the orbital rate's
// variation); from theta = 0 its solution A [sin(n t) - (n / omega_p)
// sin(omega_p t)], A = 2 e n^2 / (omega_p^2 - n^2) = 10 e (omega_p^2 =
// 1.2 n^2), peaks below A (1 + n / omega_p) = 19.2 e: bound 20 e, which the
// linearization's O(e^2) cannot reach. Halving the step divides the pitch by
// about 4 (window [3.5, 4.5]), as an O(h^2) effect of the discretization must.
TEST(GravityGradient, AlignedBodyStaysAtTheEquilibrium) {
  const Libration coarse = librate(0.0, 400, 10.0), fine = librate(0.0, 800, 10.0);
  auto largest = [](const std::vector<double>& v) {
    double m = 0.0;
    for (double a : v) m = std::max(m, std::abs(a));
    return m;
  };
  const double a = largest(coarse.pitch), b = largest(fine.pitch);
  EXPECT_LT(a, 20 * coarse.eccentricity) << a << " e = " << coarse.eccentricity;
  EXPECT_LT(b, 20 * fine.eccentricity) << b << " e = " << fine.eccentricity;
  EXPECT_LT(coarse.eccentricity, 1e-3);  // a nearly circular discrete orbit: the test's premise
  EXPECT_GT(a / b, 3.5) << a << " " << b;
  EXPECT_LT(a / b, 4.5) << a << " " << b;
  // Pitch is decoupled from roll and yaw on a planar orbit: nothing leaves the plane (round-off).
  EXPECT_LT(coarse.out_of_plane, 1e-12);
}

// A pitch offset of 1 degree librates at n sqrt(3 (J_roll - J_yaw) / J_pitch)
// = sqrt(1.2) (Hughes, Spacecraft Attitude Dynamics, 8.3). The period from
// the upward zero crossings (linear interpolation) over ~8 librations: the
// discrete frequency differs by O((omega h)^2) ~ 1e-5 at 2000 steps an
// orbit, the finite amplitude shifts it by (2 theta)^2 / 16 ~ 8e-5, the
// crossing interpolation by less: 1 % (the issue's bound) is met with
// margin, while a torque off by a factor (e.g. 2 instead of 3) shows as 18 %.
// The amplitude stays 1 degree to 10 e / theta0 ~ 0.3 % (the discrete orbit's
// eccentricity forcing, above): bound 1 %. The total angular momentum is
// conserved to round-off (the field and its gradient term are invariant
// under a common rotation: discrete Noether): 1e-12 relative over 14000 steps.
TEST(GravityGradient, PitchLibratesAtTheClassicalFrequency) {
  const Libration run = librate(pi / 180.0, 2000, 7.0);
  std::vector<double> crossings;
  for (std::size_t k = 1; k < run.pitch.size(); ++k)
    if (run.pitch[k - 1] < 0.0 && run.pitch[k] >= 0.0)
      crossings.push_back(run.t[k - 1] +
                          (run.t[k] - run.t[k - 1]) * (-run.pitch[k - 1]) / (run.pitch[k] - run.pitch[k - 1]));
  ASSERT_GE(crossings.size(), 6u);
  const double period = (crossings.back() - crossings.front()) / static_cast<double>(crossings.size() - 1);
  const double expected = std::sqrt(3.0 * (2.0 - 1.0) / 2.5);  // n = 1
  EXPECT_NEAR(2 * pi / period / expected, 1.0, 1e-2) << 2 * pi / period << " vs " << expected;
  double amplitude = 0.0;
  for (double a : run.pitch) amplitude = std::max(amplitude, std::abs(a));
  EXPECT_NEAR(amplitude, pi / 180.0, 0.01 * pi / 180.0);
  EXPECT_LT(run.momentum_change, 1e-12);
  // The point-mass model (the behaviour before issue 26, now only by saying model = "point"): no
  // torque, the body keeps its spin and the 1 degree offset never swings back through 0.
  const Libration point = librate(pi / 180.0, 2000, 7.0, Model::PointMass);
  for (double a : point.pitch) ASSERT_GT(a, 0.5 * pi / 180.0);
}

using lgvi::test::parse_error;

const std::string satellite = R"(
[body]
mass = 30.0
inertia = [[2.98, 0.0, 0.0], [0.0, 20.48, 0.0], [0.0, 0.0, 22.98]]
[initial]
position = [7000e3, 0.0, 0.0]
quaternion = [1.0, 0.0, 0.0, 0.0]
velocity = [0.0, 7546.0, 0.0]
omega = [0.0, 0.0, 0.00107]
[integrator]
step = 10.0
duration = 100.0
[potential]
kind = "central"
mu = 3.986004418e14
)";

TEST(GravityGradient, ScenarioModelKey) {
  EXPECT_FALSE(lgvi::app::parse_scenario(satellite, "gg.toml").potential.point_masses);
  EXPECT_FALSE(lgvi::app::parse_scenario(satellite + "model = \"extended\"\n", "gg.toml").potential.point_masses);
  EXPECT_TRUE(lgvi::app::parse_scenario(satellite + "model = \"point\"\n", "gg.toml").potential.point_masses);
  EXPECT_EQ(parse_error(satellite + "model = \"balls\"\n", "gg.toml"),
            "gg.toml: key 'potential.model': \"balls\" is not one of \"extended\", \"point\"");
}

}  // namespace

}  // namespace test_gravity_gradient
