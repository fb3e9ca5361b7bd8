// Bodies of known extent: shapes (mass and inertia of uniform spheres and
// ellipsoids against the exact formulas), the contact test (two spheres,
// ellipsoids placed to touch by construction, the sweep against all pairs),
// and runs that meet a contact: "stop" at the step computed from the free
// motion, "warn" recording the episode, "ignore" running through.
#include "app/scenario.hpp"
#include "app/simulation.hpp"
#include "io/memory_sink.hpp"
#include "app/summary.hpp"
#include "scenario_support.hpp"
#include "test_support.hpp"

#include <lgvi/contact.hpp>
#include <lgvi/error.hpp>
#include <lgvi/rigid_body.hpp>
#include <lgvi/system.hpp>

#include <gtest/gtest.h>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include <unistd.h>

namespace test_contact {

namespace {

using lgvi::Contact;
using lgvi::ContactDetector;
using lgvi::RigidBody;
using lgvi::S3d;
using lgvi::System;
using lgvi::SystemState;
using M3 = lgvi::Matrix3<double>;
using V3 = lgvi::Vector3<double>;
namespace t = lgvi::test;
constexpr double eps = std::numeric_limits<double>::epsilon();

/// M = R diag(s^2) R^T of an ellipsoid of semi-axes s turned by q.
M3 shape_matrix(const V3& s, const S3d& q) {
  const M3 r = q.matrix();
  return r * s.cwiseProduct(s).asDiagonal() * r.transpose();
}

/// Two [[bodies]] "left" at the origin moving at +v/2 along x and "right" at
/// (d0, 0, 0) moving at -v/2, given by the body keys `left` and `right`; no
/// field, no interaction: free motion, x(t) exact up to round-off.
std::string head_on(const std::string& left, const std::string& right, double d0, double v, double step,
                    double duration, const std::string& run = "", const std::string& right_quaternion = "[1.0, 0.0, 0.0, 0.0]") {
  auto body = [&](const std::string& name, double x, double vx, const std::string& keys, const std::string& q) {
    return "[[bodies]]\nname = \"" + name + "\"\nposition = [" + std::to_string(x) + ", 0.0, 0.0]\nquaternion = " + q +
           "\nvelocity = [" + std::to_string(vx) + ", 0.0, 0.0]\nomega = [0.0, 0.0, 0.0]\n" + keys + "\n";
  };
  return body("left", 0.0, 0.5 * v, left, "[1.0, 0.0, 0.0, 0.0]") + body("right", d0, -0.5 * v, right, right_quaternion) +
         "[potential]\nkind = \"none\"\n[integrator]\nstep = " + std::to_string(step) +
         "\nduration = " + std::to_string(duration) + "\n[output]\nevery = 25\n" + run;
}

const std::string ball_of_radius_1 = "[[bodies.ball]]\nposition = [0.0, 0.0, 0.0]\nmass = 1.0\nradius = 1.0";

struct Outcome {
  lgvi::app::SimulationResult result;
  std::vector<double> rows;  // row-major, bodies_trajectory_columns a row
  nlohmann::json summary;
};

Outcome run(const std::string& text) {
  const lgvi::app::Scenario sc = lgvi::app::parse_scenario(text, "collision.toml");
  lgvi::app::MemorySink sink(0, lgvi::app::scenario_layout(sc));
  Outcome r;
  r.result = lgvi::app::simulate(sc, sink);
  r.rows = sink.take();
  r.summary = nlohmann::json::parse(lgvi::app::summary_json(sc, r.result));
  return r;
}

constexpr int columns = lgvi::app::bodies_trajectory_columns;

// ---------------------------------------------------------------------------
// Shapes

TEST(Shapes, EllipsoidMassAndInertiaAreTheExactFormulas) {
  const double a = 3.0, b = 2.0, c = 0.7, density = 2.5;
  const lgvi::app::Scenario sc = lgvi::app::parse_scenario(
      "[[bodies]]\nshape = \"ellipsoid\"\nsemi_axes = [3.0, 2.0, 0.7]\ndensity = 2.5\nposition = [0.0, 0.0, 0.0]\n"
      "quaternion = [1.0, 0.0, 0.0, 0.0]\nmomentum = [0.0, 0.0, 0.0]\nw = [0.0, 0.0, 0.0]\n"
      "[[bodies]]\nshape = \"sphere\"\nradius = 0.4\nmass = 7.0\nposition = [10.0, 0.0, 0.0]\n"
      "quaternion = [1.0, 0.0, 0.0, 0.0]\nmomentum = [0.0, 0.0, 0.0]\nw = [0.0, 0.0, 0.0]\n"
      "[potential]\nkind = \"none\"\n[integrator]\nstep = 0.1\nduration = 1.0\n",
      "shapes.toml");
  // m = rho 4/3 pi a b c, J = m/5 diag(b^2 + c^2, a^2 + c^2, a^2 + b^2); the
  // code multiplies in another order: a few eps relative.
  const double m = density * 4.0 * std::numbers::pi * a * b * c / 3.0;
  const RigidBody& e = sc.system.body(0);
  EXPECT_NEAR(e.mass(), m, 4 * eps * m);
  const V3 exact(m * (b * b + c * c) / 5.0, m * (a * a + c * c) / 5.0, m * (a * a + b * b) / 5.0);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(e.inertia()(i, i), exact(i), 8 * eps * exact(i)) << i;
    for (int j = 0; j < 3; ++j) {
      if (j != i) {
        EXPECT_EQ(e.inertia()(i, j), 0.0);
      }
    }
  }
  EXPECT_EQ(e.extent(), lgvi::Extent::Ellipsoid);
  EXPECT_EQ(e.bounding_radius(), a);
  // The sphere given by its mass: J = 2/5 m r^2.
  const RigidBody& s = sc.system.body(1);
  EXPECT_EQ(s.mass(), 7.0);
  EXPECT_NEAR(s.inertia()(0, 0), 2.0 * 7.0 * 0.16 / 5.0, 4 * eps);
  EXPECT_EQ(s.extent(), lgvi::Extent::Sphere);
  EXPECT_EQ(s.bounding_radius(), 0.4);
  // And the summary's setup reports them.
  lgvi::app::SimulationResult none;
  none.final_state = sc.initial_state;
  const nlohmann::json setup = nlohmann::json::parse(lgvi::app::summary_json(sc, none))["setup"];
  EXPECT_EQ(setup["bodies"][0]["mass"].get<double>(), e.mass());
  EXPECT_EQ(setup["bodies"][0]["semi_axes"], nlohmann::json({3.0, 2.0, 0.7}));
  EXPECT_EQ(setup["bodies"][1]["radius"].get<double>(), 0.4);
  EXPECT_EQ(setup["on_contact"], "stop");
}

TEST(Shapes, MassAndInertiaWithRadiusIsABoundingSphere) {
  const RigidBody body = RigidBody(2.0, M3(V3(1.0, 2.0, 2.5).asDiagonal())).bounded_by(1.5);
  EXPECT_EQ(body.extent(), lgvi::Extent::Sphere);
  EXPECT_EQ(body.bounding_radius(), 1.5);
  EXPECT_EQ(body.inertia()(2, 2), 2.5);  // the inertia as given
  EXPECT_THROW(body.bounded_by(2.0), lgvi::InvalidInput);       // only a body of unknown extent takes one
  EXPECT_EQ(RigidBody(2.0, M3::Identity()).bounding_radius(), 0.0);  // a point
}

// ---------------------------------------------------------------------------
// The contact test

TEST(ContactReach, TwoSpheresReachTheSumOfTheirRadii) {
  // The Perram-Wertheim maximum for two spheres is d^2 / (r_a + r_b)^2 in
  // closed form; the bisection finds it to round-off of the 3x3 solves (a
  // few eps; 16 eps allowed).
  for (int i = 0; i < 20; ++i) {
    const double ra = t::uniform(0.1, 3.0), rb = t::uniform(0.1, 3.0);
    const V3 u = t::random_vector().normalized();
    const double reach = lgvi::contact_reach(u, M3::Identity() * (ra * ra), false, M3::Identity() * (rb * rb), false);
    EXPECT_NEAR(reach, ra + rb, 16 * eps * (ra + rb)) << ra << " " << rb;
  }
}

TEST(ContactReach, EllipsoidsPlacedToTouchReachTheirCentreDistance) {
  // A touches the plane through P with normal n at its support point P =
  // c_a + M_a n / sqrt(n^T M_a n); B, placed with its support point in the
  // direction -n at P, touches it from the other side: they touch at P, so
  // the reach along their line of centres is |c_b - c_a|. Semi-axes up to
  // 5:1 (shape matrices of condition 25): the construction and the solves
  // are good to ~25 eps relative; 1e-13 allowed.
  for (int i = 0; i < 50; ++i) {
    const V3 sa(t::uniform(0.2, 1.0), t::uniform(0.2, 1.0), t::uniform(0.2, 1.0));
    const V3 sb(t::uniform(0.2, 1.0), t::uniform(0.2, 1.0), t::uniform(0.2, 1.0));
    const M3 ma = shape_matrix(sa, t::random_unit_quaternion()), mb = shape_matrix(sb, t::random_unit_quaternion());
    const V3 n = t::random_vector().normalized();
    const V3 ca = t::random_vector(2.0);
    const V3 p = ca + ma * n / std::sqrt(n.dot(ma * n));
    for (const bool b_point : {false, true}) {
      const M3 m = b_point ? M3::Zero() : mb;
      const V3 cb = b_point ? p : V3(p + mb * n / std::sqrt(n.dot(mb * n)));
      const V3 r = cb - ca;
      const double reach = lgvi::contact_reach(r.normalized(), ma, false, m, b_point);
      EXPECT_NEAR(reach, r.norm(), 1e-13 * r.norm()) << i << (b_point ? " point" : " ellipsoid");
    }
  }
}

TEST(ContactReach, AlignedEllipsoidsOnAPrincipalAxisReachTheSumOfThoseSemiAxes) {
  // Both ellipsoids symmetric about the x axis: each reaches farthest along
  // x on the axis, so they touch tip to tip. 16 eps as for spheres.
  const M3 ma = shape_matrix(V3(2.0, 1.0, 0.5), S3d()), mb = shape_matrix(V3(0.3, 1.5, 0.7), S3d());
  EXPECT_NEAR(lgvi::contact_reach(V3::UnitX(), ma, false, mb, false), 2.3, 16 * eps * 2.3);
  EXPECT_NEAR(lgvi::contact_reach(V3::UnitY(), ma, false, mb, false), 2.5, 16 * eps * 2.5);
}

/// The overlapping pairs by a test of every ball of every pair: (a, b) and
/// the deepest overlap of each (in `reach`), in the order of (a, b).
std::vector<Contact> all_pairs_of_balls(const System& sys, const SystemState& s) {
  std::vector<Contact> expected;
  for (std::size_t a = 0; a < sys.size(); ++a)
    for (std::size_t b = a + 1; b < sys.size(); ++b) {
      double deepest = -1.0;
      for (const lgvi::Ball& u : sys.body(a).balls())
        for (const lgvi::Ball& v : sys.body(b).balls()) {
          const double d = ((s.x[b] + s.q[b].act(v.position)) - (s.x[a] + s.q[a].act(u.position))).norm();
          if (d < u.radius + v.radius) deepest = std::max(deepest, u.radius + v.radius - d);
        }
      if (deepest >= 0.0) expected.push_back({a, b, 0, 0, 0.0, deepest});
    }
  return expected;
}

/// The detector's contacts are those of `expected` (all_pairs_of_balls: the
/// deepest overlap in `reach`), pair by pair, the depths to `tolerance`.
void expect_same_contacts(const std::vector<Contact>& found, const std::vector<Contact>& expected, double tolerance) {
  ASSERT_EQ(found.size(), expected.size());
  for (std::size_t i = 0; i < found.size(); ++i) {
    EXPECT_EQ(found[i].a, expected[i].a) << i;
    EXPECT_EQ(found[i].b, expected[i].b) << i;
    EXPECT_NEAR(found[i].depth(), expected[i].reach, tolerance) << i;
  }
}

TEST(ContactDetector, FindsExactlyThePairsOfOverlappingBallsOfAllPairs) {
  // 300 bodies of two balls each, in a box where a good part of them
  // overlap another: the sweep finds the pairs a test of every ball of every
  // pair finds, with the deepest overlap of each.
  std::vector<RigidBody> bodies;
  SystemState s(300);
  for (std::size_t a = 0; a < 300; ++a) {
    bodies.push_back(RigidBody::from_balls(
        {{V3(-0.2, 0.0, 0.0), 1.0, t::uniform(0.05, 0.3)}, {V3(0.2, 0.0, 0.0), 1.0, t::uniform(0.05, 0.3)}}));
    s.x[a] = t::random_vector(4.0);
    s.q[a] = t::random_unit_quaternion();
  }
  const System sys(bodies);
  const std::vector<Contact> expected = all_pairs_of_balls(sys, s);
  ContactDetector detector(sys);
  const std::vector<Contact>& found = detector.find(s);
  ASSERT_GT(expected.size(), 10u);  // the test would not test much otherwise
  // Rotations by matrix (detector) and by quaternion (here): a few eps of the positions (~6).
  expect_same_contacts(found, expected, 1e-13);
}

TEST(ContactDetector, CellsOfMixedSizesAndFarBodiesFindWhatAllPairsFind) {
  // The cells are sized by the largest body: 250 bodies whose bounding radii
  // range over two decades, most in a box where many overlap, a few 1e12
  // away (which coarsens the cells so their indices stay exact) and two on
  // top of each other out there. The pairs and depths are those of every
  // ball of every pair; first() is what find() lists first, and nothing
  // when no pair overlaps.
  std::vector<RigidBody> bodies;
  SystemState s(250);
  for (std::size_t a = 0; a < 250; ++a) {
    // The last two are the same body (their balls coincide: they overlap whatever the draws).
    const double size = a >= 248 ? 0.1 : a % 25 == 0 ? 1.5 : t::uniform(0.015, 0.15);
    const double r0 = a >= 248 ? 0.05 : t::uniform(0.3, 1.0) * size, r1 = a >= 248 ? 0.05 : t::uniform(0.3, 1.0) * size;
    bodies.push_back(RigidBody::from_balls({{V3(-size, 0.0, 0.0), 1.0, r0}, {V3(size, 0.0, 0.0), 1.0, r1}}));
    s.x[a] = a >= 245 ? V3(1e12, -1e12, 3e11) + V3(0.0, 0.0, a >= 248 ? 0.0 : 10.0 * static_cast<double>(a))
                      : t::random_vector(3.0);
    // Far out unturned, so that both tests place the balls exactly (1e12 has an ulp of 1e-4).
    s.q[a] = a >= 245 ? S3d() : t::random_unit_quaternion();
  }
  const System sys(bodies);
  const std::vector<Contact> expected = all_pairs_of_balls(sys, s);
  ContactDetector detector(sys);
  const std::vector<Contact>& found = detector.find(s);
  ASSERT_GT(expected.size(), 10u);  // the test would not test much otherwise
  EXPECT_EQ(expected.back().a, 248u);  // the two on top of each other, far out
  // Rotations by matrix (detector) and by quaternion (here): a few eps of the positions.
  expect_same_contacts(found, expected, 1e-13);
  if (::testing::Test::HasFatalFailure()) return;
  const Contact front = found.front();  // found is overwritten by the next call
  const std::optional<Contact> first = detector.first(s);
  ASSERT_TRUE(first.has_value());
  EXPECT_EQ(first->a, front.a);
  EXPECT_EQ(first->b, front.b);
  EXPECT_EQ(first->depth(), front.depth());
  SystemState apart = s;
  for (std::size_t a = 0; a < 250; ++a) apart.x[a] = V3(4.0 * static_cast<double>(a), 0.0, 0.0);
  EXPECT_TRUE(detector.find(apart).empty());
  EXPECT_FALSE(detector.first(apart).has_value());
}

TEST(ContactDetector, LongChainsAndAHugeBodyAmongSmallOnesFindWhatAllPairsFind) {
  // Bodies the bounding spheres would bin badly: 200 dumbbells of two balls
  // 40 apart (the broad phase holds them by their balls), 200 compact
  // dumbbells, and one body of two balls 1e6 apart whose bounding sphere
  // holds every other body. Positions in a box of side 12 where many
  // overlap: the pairs and depths are those of every ball of every pair.
  std::vector<RigidBody> bodies;
  SystemState s(401);
  for (std::size_t a = 0; a < 401; ++a) {
    const double half = a == 400 ? 5e5 : a % 2 == 0 ? 20.0 : 0.3;
    bodies.push_back(RigidBody::from_balls({{V3(-half, 0.0, 0.0), 1.0, t::uniform(0.1, 0.6)},
                                            {V3(half, 0.0, 0.0), 1.0, t::uniform(0.1, 0.6)}}));
    // The huge one unturned, its ball 0 in the box: both tests place its
    // balls exactly (5e5 has an ulp of 6e-11).
    s.x[a] = a == 400 ? V3(5e5, 0.0, 0.0) : t::random_vector(6.0);
    s.q[a] = a == 400 ? S3d() : t::random_unit_quaternion();
  }
  const System sys(bodies);
  const std::vector<Contact> expected = all_pairs_of_balls(sys, s);
  ContactDetector detector(sys);
  const std::vector<Contact>& found = detector.find(s);
  ASSERT_GT(expected.size(), 20u);  // the test would not test much otherwise
  // Rotations by matrix (detector) and by quaternion (here): a few eps of
  // the positions (up to 26, and 5e5 for the huge body's far ball).
  expect_same_contacts(found, expected, 1e-12);
  // The broad phase passes on the pairs whose proxies meet: by bounding
  // spheres the huge body alone would give 400 pairs, and the long
  // dumbbells' (radius over 20, all within 21 of each other) another 19 900.
  // By balls, those of the compact dumbbells' bounding spheres (radius under
  // 0.9) that meet: a few times the contacts (129 for 38 in one draw).
  EXPECT_LT(detector.pairs_tested(), 1000u);
}

TEST(ContactDetector, TheBroadPhaseIsLinearForBodiesWithFarApartBalls) {
  // A lattice of 4096 dumbbells of two balls of radius 0.5 4e9 apart (the
  // fuzzer's case that took 3 s): no two balls meet, so no pair is tested,
  // where the bounding spheres (radius 2e9) all meet, 8.4 million pairs.
  std::vector<RigidBody> bodies(4096, RigidBody::from_balls({{V3(0.0, -2e9, 0.0), 1.0, 0.5},
                                                             {V3(0.0, 2e9, 0.0), 1.0, 0.5}}));
  SystemState s(4096);
  for (std::size_t a = 0; a < 4096; ++a) {
    const std::size_t i = a % 16, j = (a / 16) % 16, k = a / 256;  // the lattice's indices
    s.x[a] = 2.2 * V3(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k));
  }
  const System sys(bodies);
  ContactDetector detector(sys);
  EXPECT_TRUE(detector.find(s).empty());
  EXPECT_EQ(detector.pairs_tested(), 0u);
  // Two of them moved onto each other are found, and only that pair tested.
  s.x[7] = s.x[3] + V3(0.3, 0.0, 0.0);
  const std::vector<Contact>& found = detector.find(s);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].a, 3u);
  EXPECT_EQ(found[0].b, 7u);
  EXPECT_NEAR(found[0].depth(), 0.7, 1e-6);  // 0.5 + 0.5 - 0.3, positions of 4e9 (ulp 5e-7)
  EXPECT_EQ(detector.pairs_tested(), 1u);
}

TEST(ContactDetector, InAPeriodicBoxBallProxiesFindWhatAllPairsOfImagesFind) {
  // Long dumbbells (held by their balls) and compact ones in a periodic
  // cube of side 10, placed all over it: every pair is tested by brute
  // force with b at the image of its centre of mass nearest a (as the
  // detector's exact test does).
  std::vector<RigidBody> bodies;
  SystemState s(150);
  for (std::size_t a = 0; a < 150; ++a) {
    const double half = a % 3 == 0 ? 3.0 : 0.2;
    bodies.push_back(RigidBody::from_balls({{V3(-half, 0.0, 0.0), 1.0, t::uniform(0.1, 0.5)},
                                            {V3(half, 0.0, 0.0), 1.0, t::uniform(0.1, 0.5)}}));
    s.x[a] = V3::Constant(5.0) + t::random_vector(5.0);
    s.q[a] = t::random_unit_quaternion();
  }
  const lgvi::Box box(V3::Zero(), V3::Constant(10.0), {true, true, true});
  const System sys(bodies, {}, box);
  std::vector<Contact> expected;
  for (std::size_t a = 0; a < 150; ++a)
    for (std::size_t b = a + 1; b < 150; ++b) {
      const V3 xb = s.x[a] + box.minimum_image(s.x[b] - s.x[a]);
      double deepest = -1.0;
      for (const lgvi::Ball& u : sys.body(a).balls())
        for (const lgvi::Ball& v : sys.body(b).balls()) {
          const double d = ((xb + s.q[b].matrix() * v.position) - (s.x[a] + s.q[a].matrix() * u.position)).norm();
          if (d < u.radius + v.radius) deepest = std::max(deepest, u.radius + v.radius - d);
        }
      if (deepest >= 0.0) expected.push_back({a, b, 0, 0, 0.0, deepest});
    }
  ContactDetector detector(sys);
  const std::vector<Contact>& found = detector.find(s);
  ASSERT_GT(expected.size(), 20u);  // the test would not test much otherwise
  expect_same_contacts(found, expected, 1e-13);  // the same sums: a few eps of 10
}

TEST(ContactDetector, TwoRubblePilesThroughEachOtherGiveTheDeepestPairOfAllBalls) {
  // Two bodies of 400 balls each (radii 0.02 to 0.1 in a ball of radius 1),
  // their centres 0.5 apart: the balls swept along x find the deepest
  // overlap that a test of all 160000 pairs of balls finds.
  std::vector<lgvi::Ball> balls;
  for (int i = 0; i < 400; ++i) {
    V3 p = t::random_vector();
    while (p.norm() > 1.0) p = t::random_vector();
    balls.push_back({p, 1.0, t::uniform(0.02, 0.1)});
  }
  const System sys({RigidBody::from_balls(balls), RigidBody::from_balls(balls)});
  SystemState s(2);
  s.x[1] = V3(0.5, 0.1, -0.2);
  s.q = {t::random_unit_quaternion(), t::random_unit_quaternion()};
  double deepest = -1.0;
  for (const lgvi::Ball& u : sys.body(0).balls())
    for (const lgvi::Ball& v : sys.body(1).balls()) {
      const double d = ((s.x[1] + s.q[1].matrix() * v.position) - (s.x[0] + s.q[0].matrix() * u.position)).norm();
      if (d < u.radius + v.radius) deepest = std::max(deepest, u.radius + v.radius - d);
    }
  ASSERT_GT(deepest, 0.0);
  ContactDetector detector(sys);
  const std::vector<Contact>& found = detector.find(s);
  ASSERT_EQ(found.size(), 1u);
  // The same rotations (matrices) and sums: equal to round-off of the order
  // of the positions (a few eps); 1e-14 allowed.
  EXPECT_NEAR(found[0].depth(), deepest, 1e-14);
}

TEST(ContactDetector, EllipsoidsAndABallJustApartAndJustOverlapping) {
  // Ellipsoid B placed to touch A on the side n (as above), a body of two
  // balls on the side -n with its ball 0 touching A (its centre rb out along
  // -n from A's support point Q in the direction -n; ball 1, 0.6 farther
  // out, is clear); then both moved 1e-9 away from or towards A along n.
  // 1e-9 is far above the round-off of the placement (~1e-15).
  for (int i = 0; i < 20; ++i) {
    const V3 sa(t::uniform(0.2, 1.0), t::uniform(0.2, 1.0), t::uniform(0.2, 1.0));
    const V3 sb(t::uniform(0.2, 1.0), t::uniform(0.2, 1.0), t::uniform(0.2, 1.0));
    const double rb = t::uniform(0.1, 1.0);
    const System sys({RigidBody::ellipsoid(1.0, sa), RigidBody::ellipsoid(1.0, sb),
                      RigidBody::from_balls({{V3(0.3, 0.0, 0.0), 1.0, rb}, {V3(-0.3, 0.0, 0.0), 1.0, rb}})});
    const V3 n = t::random_vector().normalized();
    SystemState s(3);
    // Body 2's x axis along n: ball 0 at x_2 + 0.3 n, towards A.
    s.q = {t::random_unit_quaternion(), t::random_unit_quaternion(),
           S3d(Eigen::Quaterniond::FromTwoVectors(V3::UnitX(), n))};
    const M3 ma = shape_matrix(sa, s.q[0]), mb = shape_matrix(sb, s.q[1]);
    s.x[0] = V3::Zero();
    const V3 p = ma * n / std::sqrt(n.dot(ma * n));
    const V3 touching = p + mb * n / std::sqrt(n.dot(mb * n));
    const V3 ball_touching = -p - rb * n - 0.3 * n;  // Q = -P by symmetry
    ContactDetector detector(sys);
    for (const double shift : {1e-9, -1e-9}) {
      s.x[1] = touching + shift * n;
      s.x[2] = ball_touching - shift * n;
      const std::vector<Contact>& found = detector.find(s);
      if (shift > 0.0) {
        EXPECT_TRUE(found.empty()) << i;
        continue;
      }
      ASSERT_EQ(found.size(), 2u) << i;
      EXPECT_EQ(found[0].b, 1u);
      EXPECT_EQ(found[1].b, 2u);
      EXPECT_EQ(found[1].ball_b, 0);
      // The depth along the line of centres: of the order of the shift (the
      // line is not the normal); positive and well below 1e-6.
      for (const Contact& c : found) {
        EXPECT_GT(c.depth(), 0.0);
        EXPECT_LT(c.depth(), 1e-6);
      }
    }
  }
}

// ---------------------------------------------------------------------------
// Runs that meet a contact

// Free motion: d(k) = d0 - v k h (round-off ~1e-14 over the few hundred
// steps). Two balls of radius 1 overlap when d < 2: from k = floor((d0 - 2) /
// (v h)) + 1 on, until d < -2. The numbers put every boundary a good part of
// a step (>= 0.14 h) from the nearest step, so round-off cannot move them.
constexpr double d0 = 10.0, v = 1.0, h = 0.07;

TEST(OnContact, StopEndsTheRunAtTheFirstStepOfOverlapWithItsRowWritten) {
  const std::int64_t k_contact = static_cast<std::int64_t>(std::floor((d0 - 2.0) / (v * h))) + 1;  // 115
  ASSERT_EQ(k_contact, 115);
  const Outcome r = run(head_on(ball_of_radius_1, ball_of_radius_1, d0, v, h, 20.0));
  EXPECT_FALSE(r.result.completed);
  EXPECT_EQ(r.result.stats.last_k, k_contact);
  // Rows at k = 0, 25, ..., 100 and the contact step 115 (not a multiple of
  // every = 25), both bodies each: whole rows.
  ASSERT_EQ(r.rows.size(), 6u * 2u * columns);
  const double* last = r.rows.data() + 10 * columns;
  EXPECT_EQ(last[0], static_cast<double>(k_contact) * h);
  const double gap = last[columns + 2] - last[2];  // x of right minus x of left
  EXPECT_NEAR(gap, d0 - v * static_cast<double>(k_contact) * h, 1e-12);
  EXPECT_LT(gap, 2.0);
  EXPECT_GT(d0 - v * static_cast<double>(k_contact - 1) * h, 2.0);  // the step before: apart
  const std::string& e = r.result.error;
  for (const char* part : {"contact: ball 0 of bodies[0] (\"left\") and ball 0 of bodies[1] (\"right\") overlap",
                           "(step 115)", "centre distance 1.9", "contact depth 0.0", "radii 1 + 1",
                           "on_contact = \"warn\""})
    EXPECT_NE(e.find(part), std::string::npos) << part << " not in: " << e;
  EXPECT_EQ(e.find('\n'), std::string::npos);
  EXPECT_EQ(r.summary["completed"], false);
  EXPECT_EQ(r.summary["steps"], k_contact);
  EXPECT_EQ(r.summary["error"], e);
  ASSERT_EQ(r.summary["contacts"].size(), 1u);
  EXPECT_EQ(r.summary["contacts"][0]["first_step"], k_contact);
}

TEST(OnContact, WarnRecordsTheWholeEpisodeAndGoesOn) {
  const std::int64_t first = 115, last = static_cast<std::int64_t>(std::floor((d0 + 2.0) / (v * h)));  // 171
  ASSERT_EQ(last, 171);
  const Outcome r = run(head_on(ball_of_radius_1, ball_of_radius_1, d0, v, h, 20.0, "[run]\non_contact = \"warn\"\n"));
  EXPECT_TRUE(r.result.completed);
  EXPECT_EQ(r.result.stats.last_k, 286);  // ceil(20 / 0.07)
  ASSERT_EQ(r.summary["contacts"].size(), 1u);
  const nlohmann::json& c = r.summary["contacts"][0];
  EXPECT_EQ(c["bodies"], nlohmann::json({"left", "right"}));
  EXPECT_EQ(c["first_step"], first);
  EXPECT_EQ(c["last_step"], last);
  EXPECT_EQ(c["first_time"].get<double>(), static_cast<double>(first) * h);
  // Deepest at the step nearest to d = 0: k = 143, d = -0.01 (|d| as distance).
  EXPECT_NEAR(c["max_depth"].get<double>(), 2.0 - 0.01, 1e-12);
  EXPECT_NEAR(c["distance_at_max_depth"].get<double>(), 0.01, 1e-12);
  EXPECT_EQ(r.summary["contact_episodes"], 1);
}

TEST(OnContact, AnEpisodeGoingOnAtACheckpointContinuesAfterResume) {
  // A checkpoint at k = 150, inside the episode 115..171: the resumed run
  // lists the same one episode as the run without a break.
  const lgvi::app::Scenario sc = lgvi::app::parse_scenario(
      head_on(ball_of_radius_1, ball_of_radius_1, d0, v, h, 20.0, "[run]\non_contact = \"warn\"\n"), "resume");
  const std::string path = (std::filesystem::temp_directory_path() /
                            ("lgvi-test-contact-" + std::to_string(::getpid()) + ".bin")).string();
  lgvi::app::SimulationOptions opt;
  opt.checkpoint_every = 150;
  opt.checkpoint_path = path;
  lgvi::app::MemorySink whole(0, lgvi::app::scenario_layout(sc));
  const lgvi::app::SimulationResult full = lgvi::app::simulate(sc, whole, opt);
  const lgvi::app::Checkpoint c = lgvi::app::read_checkpoint(path);
  std::filesystem::remove(path);
  ASSERT_EQ(c.k, 150);
  ASSERT_EQ(c.stats.contacts.size(), 1u);
  EXPECT_EQ(c.stats.contacts[0].last_k, 150);
  lgvi::app::SimulationOptions again;
  again.resume = &c;
  lgvi::app::MemorySink rest(0, lgvi::app::scenario_layout(sc));
  const lgvi::app::SimulationResult resumed = lgvi::app::simulate(sc, rest, again);
  ASSERT_TRUE(resumed.completed);
  ASSERT_EQ(resumed.stats.contacts.size(), 1u);
  const lgvi::app::ContactEpisode &a = full.stats.contacts.at(0), &b = resumed.stats.contacts[0];
  EXPECT_EQ(b.first_k, 115);
  EXPECT_EQ(b.last_k, 171);
  // The resumed run is bit-identical, so are its depths.
  EXPECT_EQ(b.max_depth, a.max_depth);
  EXPECT_EQ(resumed.stats.contact_episodes, 1);
}

TEST(OnContact, IgnoreRunsThroughAsBefore) {
  const Outcome r = run(head_on(ball_of_radius_1, ball_of_radius_1, d0, v, h, 20.0, "[run]\non_contact = \"ignore\"\n"));
  EXPECT_TRUE(r.result.completed);
  EXPECT_FALSE(r.summary.contains("contacts"));
  EXPECT_EQ(r.summary["setup"]["on_contact"], "ignore");
}

TEST(OnContact, EllipsoidsHeadOnStopWhereTheirSemiAxesAlongTheLineMeet) {
  // Long axes along x: they touch at d = 2 + 1.5 = 3.5 (tip to tip), first
  // overlap at k = floor(6.5 / 0.07) + 1 = 93 (6.5 / 0.07 = 92.86). The right
  // one turned by 90 degrees about z presents its b = 0.5 along x: d = 2.5,
  // k = floor(7.5 / 0.07) + 1 = 108 (107.14).
  const std::string left = "shape = \"ellipsoid\"\nsemi_axes = [2.0, 1.0, 0.5]\ndensity = 1.0";
  const std::string right = "shape = \"ellipsoid\"\nsemi_axes = [1.5, 0.5, 0.5]\ndensity = 1.0";
  const Outcome along = run(head_on(left, right, d0, v, h, 20.0));
  EXPECT_EQ(along.result.stats.last_k, 93);
  const Outcome turned = run(head_on(left, right, d0, v, h, 20.0, "", "[0.70710678118654757, 0.0, 0.0, 0.70710678118654757]"));
  EXPECT_EQ(turned.result.stats.last_k, 108);
  EXPECT_NE(turned.result.error.find("the ellipsoid (2, 1, 0.5) and the ellipsoid (1.5, 0.5, 0.5) would just touch"),
            std::string::npos)
      << turned.result.error;
  // The depth is the reach 2.5 along this line minus the distance: round-off
  // of the positions (~1e-14) and of the reach (16 eps).
  const double d = d0 - v * 108 * h;
  EXPECT_NEAR(turned.summary["contacts"][0]["max_depth"].get<double>(), 2.5 - d, 1e-12);
}

TEST(OnContact, LennardJonesIsExemptUnlessOnContactIsGiven) {
  const std::string lj = "[interaction]\nkind = \"lennard-jones\"\nepsilon = 1.0\nsigma = 1.0\n";
  EXPECT_EQ(lgvi::app::parse_scenario(head_on(ball_of_radius_1, ball_of_radius_1, d0, v, h, 1.0, lj), "lj").on_contact,
            lgvi::app::OnContact::Ignore);
  EXPECT_EQ(lgvi::app::parse_scenario(
                head_on(ball_of_radius_1, ball_of_radius_1, d0, v, h, 1.0, lj + "[run]\non_contact = \"stop\"\n"), "lj")
                .on_contact,
            lgvi::app::OnContact::Stop);
  EXPECT_EQ(lgvi::app::parse_scenario(head_on(ball_of_radius_1, ball_of_radius_1, d0, v, h, 1.0), "g").on_contact,
            lgvi::app::OnContact::Stop);
}

// A bounding radius must be able to hold the body: any mass within radius R
// of its centre has tr J = 2 sum m |rho|^2 <= 2 m R^2, so R >= sqrt(tr J / 2m)
// (here sqrt(1.5) = 1.22): a smaller one would make contact detection miss.
TEST(OnContact, ABoundingRadiusTooSmallForTheInertiaIsRefused) {
  const RigidBody body(1.0, lgvi::Matrix3<double>::Identity());
  EXPECT_THROW(body.bounded_by(1.2), lgvi::InvalidInput);
  EXPECT_EQ(body.bounded_by(1.25).bounding_radius(), 1.25);
  // From a scenario file: one line naming the file and the key.
  const std::string message = lgvi::test::parse_error(
      "[[bodies]]\nmass = 1.0\ninertia = [[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]\nradius = 1.2\n"
      "position = [0.0, 0.0, 0.0]\nquaternion = [1.0, 0.0, 0.0, 0.0]\nvelocity = [0.0, 0.0, 0.0]\n"
      "omega = [0.0, 0.0, 0.0]\n[potential]\nkind = \"none\"\n[integrator]\nstep = 0.1\nduration = 0.1\n",
      "r.toml");
  EXPECT_EQ(message.rfind("r.toml: bodies[0].radius: 1.200000 cannot hold a body of this mass and inertia", 0), 0u)
      << message;
}

// The ellipsoid's orientation: semi-axes (2, 0.5, 0.5) turned +30 degrees
// about z lie along the direction at +30 degrees, where a point 1.8 away is
// inside (the long axis reaches 2), while at -30 degrees it is outside (the
// reach there, 1/sqrt(cos^2 60 / 4 + sin^2 60 / 0.25) = 0.57, is less): a test
// that tells R from R^T, which a turn about a symmetry axis cannot.
TEST(OnContact, EllipsoidOrientationIsTheBodyToInertialRotation) {
  const std::string ellipsoid = "shape = \"ellipsoid\"\nsemi_axes = [2.0, 0.5, 0.5]\nmass = 1.0\n"
                                "quaternion = [0.9659258262890683, 0.0, 0.0, 0.25881904510252074]";  // +30 deg about z
  auto scenario = [&](double angle_deg) {
    const double a = angle_deg * std::numbers::pi / 180.0;
    return "[[bodies]]\nname = \"e\"\n" + ellipsoid + "\nposition = [0.0, 0.0, 0.0]\nvelocity = [0.0, 0.0, 0.0]\n"
           "omega = [0.0, 0.0, 0.0]\n[[bodies]]\nname = \"p\"\nmass = 1.0\n"
           "inertia = [[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]\nposition = [" +
           fmt::format("{}, {}", 1.8 * std::cos(a), 1.8 * std::sin(a)) +
           ", 0.0]\nquaternion = [1.0, 0.0, 0.0, 0.0]\nvelocity = [0.0, 0.0, 0.0]\nomega = [0.0, 0.0, 0.0]\n"
           "[potential]\nkind = \"none\"\n[integrator]\nstep = 0.1\nduration = 0.1\n";
  };
  EXPECT_THROW(lgvi::app::parse_scenario(scenario(30.0), "turned.toml"), lgvi::InvalidInput);
  EXPECT_NO_THROW(lgvi::app::parse_scenario(scenario(-30.0), "turned.toml"));
}

TEST(OnContact, OverlapAtTheStartIsAnErrorForEveryExtent) {
  // Ellipsoid (tip at x = 2) and a sphere of radius 1 at x = 2.9: overlap;
  // a body given by mass + inertia with radius 1 likewise; without radius it
  // is its centre, outside the ellipsoid at 2.9: no error.
  const std::string ellipsoid = "shape = \"ellipsoid\"\nsemi_axes = [2.0, 1.0, 0.5]\nmass = 1.0";
  for (const std::string& right : {std::string("shape = \"sphere\"\nradius = 1.0\nmass = 1.0"),
                                   std::string("mass = 1.0\ninertia = [[0.4, 0, 0], [0, 0.4, 0], [0, 0, 0.4]]\nradius = 1.0")}) {
    try {
      lgvi::app::parse_scenario(head_on(ellipsoid, right, 2.9, 0.0, h, 1.0), "start.toml");
      ADD_FAILURE() << "no error for " << right;
    } catch (const lgvi::InvalidInput& e) {
      EXPECT_NE(std::string(e.what()).find("key 'bodies[1]': overlaps bodies[0] at the start"), std::string::npos)
          << e.what();
    }
  }
  EXPECT_NO_THROW(lgvi::app::parse_scenario(
      head_on(ellipsoid, "mass = 1.0\ninertia = [[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]", 2.9, 0.0, h, 1.0), "s.toml"));
  EXPECT_THROW(lgvi::app::parse_scenario(
                   head_on(ellipsoid, "mass = 1.0\ninertia = [[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]", 1.9, 0.0, h, 1.0),
                   "s.toml"),
               lgvi::InvalidInput);
}

}  // namespace

}  // namespace test_contact
