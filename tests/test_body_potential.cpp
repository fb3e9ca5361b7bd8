// Rigid bodies (rigid_body.hpp) and potentials (potential.hpp): inertia from
// balls against hand computations, validation, and every force and torque
// against finite differences of the energy.
#include <lgvi/paper.hpp>
#include <lgvi/potential.hpp>
#include <lgvi/rigid_body.hpp>

#include "test_support.hpp"

#include <gmock/gmock.h>

namespace test_body_potential {

namespace {

using lgvi::Ball;
using lgvi::RigidBody;
using lgvi::S3d;
using V3 = lgvi::Vector3<double>;
using M3 = lgvi::Matrix3<double>;
constexpr double eps = 2.220446049250313e-16;

TEST(RigidBody, InertiaFromBallsMatchesHandComputation) {
  // Two balls m = 2, r = 0.5 at x = 1 and x = 3: centre of mass at x = 2, arms +-1.
  // J = sum m (|rho|^2 I - rho rho^T) + 2/5 m r^2 I = diag(0, 4, 4) + 2 * 0.2 I.
  const RigidBody b = RigidBody::from_balls({{{1, 0, 0}, 2.0, 0.5}, {{3, 0, 0}, 2.0, 0.5}});
  EXPECT_EQ(b.mass(), 4.0);
  EXPECT_MAT_NEAR(b.inertia(), M3(V3(0.4, 4.4, 4.4).asDiagonal()), 4 * eps);
  EXPECT_MAT_NEAR(b.balls()[0].position, V3(-1, 0, 0), 0.0);
}

TEST(RigidBody, PaperBodyHasLaminaInertia) {
  // Equilateral triangle of side 1, unit masses at distance 1/sqrt(3) from the
  // centroid: Jzz = 3 * 1/3 = 1, and by the perpendicular-axis theorem and
  // symmetry Jxx = Jyy = 1/2; each ball adds 2/5 * 0.01 = 0.004, three 0.012.
  const RigidBody b = lgvi::paper::three_ball_body();
  EXPECT_MAT_NEAR(b.inertia(), M3(V3(0.512, 0.512, 1.012).asDiagonal()), 8 * eps);
  V3 c = V3::Zero();
  for (const Ball& ball : b.balls()) c += ball.mass * ball.position;
  EXPECT_MAT_NEAR(c, V3::Zero(), 4 * eps);
}

TEST(RigidBody, PlanarPointMassesSatisfyTriangleEqualityAndAreAccepted) {
  // A lamina of point masses has J3 = J1 + J2 exactly: the boundary case is valid.
  const double s = std::sqrt(3.0) / 2;
  EXPECT_NO_THROW(RigidBody::from_balls({{{0, 0, 0}, 1, 0}, {{1, 0, 0}, 1, 0}, {{0.5, s, 0}, 1, 0}}));
}

TEST(RigidBody, InvalidBodiesAreRejectedWithTheFieldNamed) {
  using ::testing::HasSubstr;
  auto message = [](auto&& f) {
    try {
      f();
    } catch (const lgvi::InvalidInput& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_THAT(message([] { RigidBody(0.0, M3::Identity()); }), HasSubstr("body.mass"));
  EXPECT_THAT(message([] { RigidBody(-1.0, M3::Identity()); }), HasSubstr("body.mass"));
  M3 nonsym = M3::Identity();
  nonsym(0, 1) = 0.1;
  EXPECT_THAT(message([&] { RigidBody(1.0, nonsym); }), HasSubstr("symmetric"));
  EXPECT_THAT(message([] { RigidBody(1.0, M3(V3(1, 1, -1).asDiagonal())); }), HasSubstr("positive semi-definite"));
  EXPECT_THAT(message([] { RigidBody(1.0, M3(V3(1, 1, 3).asDiagonal())); }), HasSubstr("triangle inequality"));
  // A zero moment with unequal others: no mass on a line has it (balls on a
  // line are a linear body, tests/test_linear_bodies.cpp).
  EXPECT_THAT(message([] { RigidBody(1.0, M3(V3(0, 1, 1.5).asDiagonal())); }), HasSubstr("a zero moment is a linear body"));
  // A solid shape whose m r^2 underflows is no line or point.
  EXPECT_THAT(message([] { RigidBody::sphere(1.0, 1e-170); }), HasSubstr("body.radius"));
  EXPECT_THAT(message([] { RigidBody::from_balls({{{0, 0, 0}, 1, 0.1}, {{1, 0, 0}, 0, 0.1}}); }),
              HasSubstr("body.ball[1].mass"));
  EXPECT_THAT(message([] { RigidBody::from_balls({{{0, 0, 0}, 1, -0.1}}); }), HasSubstr("body.ball[0].radius"));
  EXPECT_THAT(message([] { RigidBody::from_balls({}); }), HasSubstr("at least one ball"));
}

struct PotentialCase {
  std::string name;
  double distance;  // |x|
};

class PotentialDerivatives : public ::testing::TestWithParam<PotentialCase> {};

// Fourth-order differences (check_potential_derivatives): the round-off
// eps |V| / h ~ 1e-13 |V| dominates. The force ~ |V| / r is then checked to
// ~1e-12; the torque, a tidal effect ~ |V| (rho / r)^2, to ~1e-13 (r/rho)^2,
// 1e-10 at r = 20. 1e-8 keeps two orders of margin, while an error in a
// formula (a sign, a missing factor 2) shows as O(1).
TEST_P(PotentialDerivatives, CentralGravityForceAndTorqueMatchFiniteDifferences) {
  const RigidBody body = lgvi::paper::three_ball_body();
  const lgvi::CentralGravity pot(body, 1.0);
  for (int trial = 0; trial < 10; ++trial) {
    const V3 x = lgvi::test::random_vector().normalized() * GetParam().distance;
    const S3d q = lgvi::test::random_unit_quaternion();
    const auto check = lgvi::check_potential_derivatives(pot, x, q);
    EXPECT_LE(check.force_error, 1e-8) << "x = " << x.transpose();
    EXPECT_LE(check.torque_error, 1e-8) << "x = " << x.transpose();
  }
}

TEST_P(PotentialDerivatives, SeedsRotationalTermIsMinusTwiceTheTorque) {
  // The paper's F(q) dV/dq, with dV/dq the gradient in R^4 of V(x, pi(q))
  // (pi by the paper's formula, extended off S^3), equals -2 M.
  const RigidBody body = lgvi::paper::three_ball_body();
  const lgvi::CentralGravity pot(body, 1.0);
  const V3 x = lgvi::test::random_vector().normalized() * GetParam().distance;
  const S3d q = lgvi::test::random_unit_quaternion();
  lgvi::Vector4<double> grad;
  const double h = 1e-6;
  for (int i = 0; i < 4; ++i) {
    lgvi::Vector4<double> dq = lgvi::Vector4<double>::Zero();
    dq(i) = h;
    const lgvi::Vector4<double> a = q.scalar_first() + dq, b = q.scalar_first() - dq;
    grad(i) = (pot.evaluate(x, S3d(a(0), a(1), a(2), a(3))).energy - pot.evaluate(x, S3d(b(0), b(1), b(2), b(3))).energy) /
              (2 * h);
  }
  const V3 seed_term = lgvi::F(q.quaternion()) * grad;
  EXPECT_MAT_NEAR(seed_term, lgvi::seed_torque_term(pot.evaluate(x, q).torque), 1e-8);
}

TEST_P(PotentialDerivatives, CentralGravityExertsNoTotalTorqueAboutTheCentre) {
  // Rotation invariance of V: x cross F + pi(q) M = 0 (what makes the angular
  // momentum a conserved quantity), to the round-off of the sums.
  const RigidBody body = lgvi::paper::three_ball_body();
  const lgvi::CentralGravity pot(body, 1.0);
  const V3 x = lgvi::test::random_vector().normalized() * GetParam().distance;
  const S3d q = lgvi::test::random_unit_quaternion();
  const auto e = pot.evaluate(x, q);
  EXPECT_MAT_NEAR((x.cross(e.force) + q.act(e.torque)).eval(), V3::Zero(), 64 * eps * x.norm() * e.force.norm());
}

INSTANTIATE_TEST_SUITE_P(Distances, PotentialDerivatives,
                         ::testing::Values(PotentialCase{"near", 2.0}, PotentialCase{"paper", 8.0},
                                           PotentialCase{"far", 20.0}),
                         [](const auto& info) { return info.param.name; });

TEST(Potential, PointMassAndUniformGravity) {
  const RigidBody point(2.0, M3::Identity());
  const lgvi::CentralGravity central(point, 3.0);
  const V3 x(3, 4, 0);
  const auto e = central.evaluate(x, S3d());
  EXPECT_DOUBLE_EQ(e.energy, -3.0 * 2.0 / 5.0);  // -mu m / r
  EXPECT_MAT_NEAR(e.force, (-3.0 * 2.0 / 125.0 * x).eval(), 4 * eps);
  EXPECT_MAT_NEAR(e.torque, V3::Zero(), 0.0);

  const lgvi::UniformGravity uniform(point, V3(0, 0, -9.81));
  const auto u = uniform.evaluate(V3(1, 2, 3), lgvi::test::random_unit_quaternion());
  EXPECT_DOUBLE_EQ(u.energy, 2.0 * 9.81 * 3.0);  // m g z
  EXPECT_MAT_NEAR(u.force, V3(0, 0, -19.62), 0.0);
  const auto check = lgvi::check_potential_derivatives(uniform, V3(1, 2, 3), lgvi::test::random_unit_quaternion());
  EXPECT_LE(check.force_error, 1e-8);
  EXPECT_LE(check.torque_error, 1e-8);
}

TEST(Potential, DerivativeCheckCatchesAWrongTorque) {
  // A user potential whose torque has the wrong sign must fail the check.
  const RigidBody body = lgvi::paper::three_ball_body();
  const lgvi::CentralGravity good(body, 1.0);
  const lgvi::CallablePotential wrong([&](const V3& x, const S3d& q) {
    auto e = good.evaluate(x, q);
    e.torque = -e.torque;
    return e;
  });
  const lgvi::CallablePotential right([&](const V3& x, const S3d& q) { return good.evaluate(x, q); });
  const V3 x(2.0, 0.5, 0.3);
  const S3d q = lgvi::test::random_unit_quaternion();
  EXPECT_GT(lgvi::check_potential_derivatives(wrong, x, q).torque_error, 0.5);
  EXPECT_TRUE(lgvi::check_potential_derivatives(right, x, q).passed(1e-8));
}

}  // namespace

namespace {

TEST(Potential, HeavyTopTorqueMatchesFiniteDifferencesAndForceIsZero) {
  // V = -m g . (R chi): torque chi x R^T (m g) against 4th-order differences
  // (round-off ~1e-13 |V| / |M|, |M| ~ |V| here), no force on the pivot's x.
  const RigidBody body(1.5, M3(V3(0.3, 0.35, 0.05).asDiagonal()));
  const lgvi::HeavyTop top(body, V3(0, 0, -9.81), V3(0.1, -0.05, 0.5));
  for (int trial = 0; trial < 10; ++trial) {
    const S3d q = lgvi::test::random_unit_quaternion();
    const auto check = lgvi::check_potential_derivatives(top, V3::Zero(), q);
    EXPECT_LE(check.torque_error, 1e-9);
    EXPECT_EQ(top.evaluate(V3::Zero(), q).force, V3::Zero());
  }
}

}  // namespace

}  // namespace test_body_potential
