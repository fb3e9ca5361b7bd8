// Pair damping (pair_damping.hpp): its forces and torques against a sum over
// every pair of sites written here from the formula (free space and a
// periodic box, bodies of balls, spheres and points); the momenta a run
// keeps to round-off; the energy it takes equal to minus its work to the
// integrator's second order; two points meeting head-on against an exact
// invariant of the flow; the scenario's keys and their one-line errors.
#include "app/scenario.hpp"
#include "scenario_support.hpp"
#include "test_support.hpp"

#include <lgvi/forcing.hpp>
#include <lgvi/integrate.hpp>
#include <lgvi/interaction.hpp>
#include <lgvi/lgvi.hpp>
#include <lgvi/pair_damping.hpp>
#include <lgvi/potential.hpp>

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace test_pair_damping {

namespace {

namespace t = lgvi::test;
using lgvi::Box;
using lgvi::ForcingSet;
using lgvi::PairDamping;
using lgvi::RigidBody;
using lgvi::S3d;
using lgvi::System;
using lgvi::SystemState;
using lgvi::SystemStepInfo;
using V3 = lgvi::Vector3<double>;
using M3 = lgvi::Matrix3<double>;
using Free = lgvi::ExternalField<lgvi::NoPotential>;

constexpr double eps = std::numeric_limits<double>::epsilon();

/// `molecules` molecules of 3 balls, `spheres` spheres and `points` points
/// (mass and inertia, no radius), in that order, with random balls, masses
/// and inertia.
System mixed_bodies(const Box& box = {}, int molecules = 40, int spheres = 10, int points = 10) {
  std::vector<RigidBody> bodies;
  for (int a = 0; a < molecules + spheres + points; ++a) {
    if (a < molecules)
      bodies.push_back(RigidBody::from_balls({{t::random_vector(0.6), t::uniform(0.5, 2.0), 0.3},
                                              {t::random_vector(0.6), t::uniform(0.5, 2.0), 0.3},
                                              {t::random_vector(0.6), t::uniform(0.5, 2.0), 0.3}}));
    else if (a < molecules + spheres)
      bodies.push_back(RigidBody::sphere(t::uniform(0.5, 2.0), 0.4));
    else
      bodies.emplace_back(t::uniform(0.5, 2.0), V3(0.5, 0.7, 0.9).asDiagonal().toDenseMatrix());
  }
  return System(bodies, {}, box);
}

SystemState random_state(std::size_t n, const V3& centre, double half) {
  SystemState s(n);
  for (std::size_t a = 0; a < n; ++a) {
    s.x[a] = centre + t::random_vector(half);
    s.q[a] = t::random_unit_quaternion();
    s.p[a] = t::random_vector(1.0);
    s.w[a] = t::random_vector(1.0);
  }
  return s;
}

/// The damping's wrench on every body by a sum over every pair of sites of
/// different bodies (the formula of pair_damping.hpp, written again): F
/// inertial, M in body axes.
void all_pairs(const System& sys, const SystemState& s, double gamma, double cutoff, std::vector<V3>& force,
               std::vector<V3>& torque) {
  struct Site {
    std::size_t body;
    V3 arm, velocity;
  };
  std::vector<Site> sites;
  for (std::size_t a = 0; a < sys.size(); ++a) {
    const RigidBody& b = sys.body(a);
    const V3 v = s.p[a] / b.mass();
    // omega = R Omega, Omega = J^-1 w / 2 (a rigid body's rate).
    const V3 omega = s.q[a].act(0.5 * (b.inertia().inverse() * s.w[a]));
    if (b.balls().empty()) sites.push_back({a, V3::Zero(), v});
    for (const lgvi::Ball& ball : b.balls()) {
      const V3 arm = s.q[a].act(ball.position);
      sites.push_back({a, arm, v + omega.cross(arm)});
    }
  }
  force.assign(sys.size(), V3::Zero());
  std::vector<V3> tau(sys.size(), V3::Zero());
  for (const Site& u : sites)
    for (const Site& v : sites) {
      if (u.body == v.body) continue;
      const V3 r = sys.box().minimum_image((s.x[u.body] + u.arm) - (s.x[v.body] + v.arm));
      const double d = r.norm();
      if (d >= cutoff) continue;
      const double w = 1.0 - d / cutoff;
      const V3 f = -gamma * w * w * (r / d).dot(u.velocity - v.velocity) * (r / d);  // on u from v
      force[u.body] += f;
      tau[u.body] += u.arm.cross(f);
    }
  torque.resize(sys.size());
  for (std::size_t a = 0; a < sys.size(); ++a) torque[a] = s.q[a].inverse().act(tau[a]);
}

void expect_wrenches_match(const System& sys, const SystemState& s, double gamma, double cutoff) {
  ForcingSet set;
  set.add(PairDamping(gamma, cutoff, sys.box()));
  std::vector<V3> force, torque, expected_force, expected_torque;
  set.evaluate(0.0, s, sys, force, torque);
  all_pairs(sys, s, gamma, cutoff, expected_force, expected_torque);
  double scale = 0.0, interacting = 0.0;
  for (std::size_t a = 0; a < sys.size(); ++a) {
    scale = std::max({scale, expected_force[a].norm(), expected_torque[a].norm()});
    interacting += expected_force[a].norm() > 0.0 ? 1.0 : 0.0;
  }
  ASSERT_GT(interacting, 0.5 * static_cast<double>(sys.size()));  // most bodies have a site within reach of another's
  // The same terms summed in another order, rotations by matrix against by
  // quaternion: round-off of the sums, a few tens of eps of the largest.
  for (std::size_t a = 0; a < sys.size(); ++a) {
    EXPECT_LT((force[a] - expected_force[a]).norm(), 1e-13 * scale) << a;
    EXPECT_LT((torque[a] - expected_torque[a]).norm(), 1e-13 * scale) << a;
  }
  // Equal and opposite along the line of the sites: the total force, and in
  // free space the total torque about the origin, vanish to round-off.
  V3 total_force = V3::Zero(), total_torque = V3::Zero();
  for (std::size_t a = 0; a < sys.size(); ++a) {
    total_force += force[a];
    total_torque += s.x[a].cross(force[a]) + s.q[a].act(torque[a]);
  }
  EXPECT_LT(total_force.norm(), 1e-13 * scale);
  if (!sys.box().any_periodic()) {
    EXPECT_LT(total_torque.norm(), 1e-12 * scale);
  }
  // It takes energy: the power sum F.v + M.Omega is -gamma sum w^2 (e.v)^2 < 0.
  EXPECT_LT(ForcingSet::power(s, sys, force, torque), 0.0);
}

TEST(PairDamping, ForcesAndTorquesAreTheSumOverEveryPairOfSites) {
  const System sys = mixed_bodies();
  expect_wrenches_match(sys, random_state(sys.size(), V3(1.0, -2.0, 0.5), 2.5), 1.7, 1.2);
}

TEST(PairDamping, InAPeriodicBoxPairsActThroughTheMinimumImage) {
  // Bodies all over a periodic box of 6 x 6 x 6, and of 4.5 and 3 along x:
  // pairs across the faces. In the box of 3 along x the skin (0.24 in the
  // others) shrinks to 0.15, so that the cutoff plus the skin stays below
  // half the box; the neighbour lists have 4 cells along x there (each pair
  // must still be taken once).
  for (const double lx : {6.0, 4.5, 3.0}) {
    const Box box(V3::Zero(), V3(lx, 6.0, 6.0), {true, true, true});
    const System sys = mixed_bodies(box);
    SystemState s = random_state(sys.size(), V3::Zero(), 1.0);
    for (std::size_t a = 0; a < s.size(); ++a) s.x[a] = box.wrap(s.x[a]).x;
    expect_wrenches_match(sys, s, 0.9, 1.2);
  }
  // Few sites, so that the lists' cells (at most about (2 sites)^(1/3) per
  // axis) are 3, 2 and 1 per axis: a cell is its own neighbour along a
  // periodic axis, more than once.
  for (const auto& [molecules, spheres, points] : {std::array{4, 2, 2}, std::array{2, 1, 1}, std::array{0, 1, 1}}) {
    const Box box(V3::Zero(), V3(3.0, 3.0, 3.0), {true, true, true});
    const System sys = mixed_bodies(box, molecules, spheres, points);
    SystemState s = random_state(sys.size(), V3::Zero(), 0.5);
    for (std::size_t a = 0; a < s.size(); ++a) s.x[a] = box.wrap(s.x[a]).x;
    expect_wrenches_match(sys, s, 0.9, 1.2);
  }
}

/// A run of `steps` steps of h of a system under pair damping alone (no
/// potential), by the Hamiltonian LGVI.
template <class F>
SystemState run(const System& sys, SystemState s, double gamma, double cutoff, double h, std::int64_t steps,
                F&& observe) {
  lgvi::LieGroupVariationalIntegrator<Free> stepper(sys, Free::uniform(lgvi::NoPotential{}, sys.size()));
  ForcingSet set;
  set.add(PairDamping(gamma, cutoff, sys.box()));
  stepper.set_forcing(set);
  lgvi::integrate_n_steps(stepper, s, 0.0, h, steps, observe);
  return s;
}

TEST(PairDamping, ARunKeepsBothMomentaToRoundOffAndLosesEnergyAsItsWork) {
  // 60 bodies tumbling through each other's reach for 400 steps. The
  // momenta: each step's balance P_{k+1} - P_k = (h/2)(sum F_k + sum F_{k+1})
  // with sums that vanish to round-off, so the drift is a random walk of a
  // few eps of |p| ~ 1 per step (1e-13 after 400 steps, with room). Energy:
  // E - E0 - W is the integrator's error, second order in h (a ratio near 4
  // per halving; 3.5 to 4.5 allowed, the error's higher orders at this h),
  // while E itself falls by far more.
  const System sys = mixed_bodies();
  const SystemState s0 = random_state(sys.size(), V3::Zero(), 2.0);
  const V3 p0 = lgvi::linear_momentum(s0), l0 = lgvi::angular_momentum(s0);
  std::vector<double> errors;
  double lost = 0.0;
  for (const double h : {0.01, 0.005, 0.0025}) {
    double worst_p = 0.0, worst_l = 0.0, worst_e = 0.0, e0 = 0.0;
    const auto steps = static_cast<std::int64_t>(std::lround(4.0 / h));
    run(sys, s0, 0.8, 1.2, h, steps, [&](const SystemStepInfo& i) {
      const double e = lgvi::kinetic_energy(i.state, sys);
      if (i.k == 0) e0 = e;
      worst_p = std::max(worst_p, (lgvi::linear_momentum(i.state) - p0).norm());
      worst_l = std::max(worst_l, (lgvi::angular_momentum(i.state) - l0).norm());
      worst_e = std::max(worst_e, std::abs(e - e0 - i.work));
      lost = e0 - e;
    });
    EXPECT_LT(worst_p, 1e-13) << h;
    EXPECT_LT(worst_l, 1e-12) << h;  // |L| ~ |x||p| ~ 10
    errors.push_back(worst_e);
  }
  EXPECT_GT(lost, 1e3 * errors.back());  // the damping acted
  for (std::size_t i = 1; i < errors.size(); ++i) {
    const double ratio = errors[i - 1] / errors[i];
    EXPECT_GT(ratio, 3.5) << i;
    EXPECT_LT(ratio, 4.5) << i;
  }
}

TEST(PairDamping, TwoPointsHeadOnFollowTheFlowsExactInvariantAtSecondOrder) {
  // Two points (no balls) of masses m1, m2 approaching along x at relative
  // speed v0, from r0 < r_c. With mu = m1 m2 / (m1 + m2) the relative motion
  // is mu dv/dt = -gamma (1 - r/r_c)^2 v, dr/dt = v, so
  //   I(r, v) = v - (gamma r_c / (3 mu)) (1 - r/r_c)^3
  // is constant along the flow. The step keeps I to O(h^2): a ratio near 4
  // per halving (3.8 to 4.2 allowed), and the total momentum to round-off.
  const double m1 = 1.0, m2 = 3.0, gamma = 2.0, rc = 1.5, mu = m1 * m2 / (m1 + m2);
  const M3 j = V3(0.4, 0.5, 0.6).asDiagonal();
  const System sys({RigidBody(m1, j), RigidBody(m2, j)});
  SystemState s0(2);
  s0.x = {V3(0.0, 0.0, 0.0), V3(1.4, 0.0, 0.0)};
  s0.p = {V3(m1 * 0.6, 0.0, 0.0), V3(m2 * -0.2, 0.0, 0.0)};  // v1 - v2 = 0.8: approaching
  auto invariant = [&](const SystemState& s) {
    const double r = s.x[1].x() - s.x[0].x(), v = s.p[1].x() / m2 - s.p[0].x() / m1;
    return v - gamma * rc / (3.0 * mu) * std::pow(1.0 - r / rc, 3);
  };
  const double i0 = invariant(s0);
  std::vector<double> errors;
  for (const double h : {0.02, 0.01, 0.005}) {
    double worst = 0.0, worst_p = 0.0, closest = 1e300;
    run(sys, s0, gamma, rc, h, std::lround(1.0 / h), [&](const SystemStepInfo& i) {
      worst = std::max(worst, std::abs(invariant(i.state) - i0));
      worst_p = std::max(worst_p, std::abs(i.state.p[0].x() + i.state.p[1].x() - (s0.p[0].x() + s0.p[1].x())));
      closest = std::min(closest, i.state.x[1].x() - i.state.x[0].x());
    });
    EXPECT_LT(worst_p, 8 * eps);
    ASSERT_GT(closest, 0.5);  // they slow down well before they meet: r stays in (0, r_c)
    errors.push_back(worst);
  }
  ASSERT_GT(errors.back(), 1e-10);  // far above round-off: the ratios measure truncation
  for (std::size_t i = 1; i < errors.size(); ++i) {
    const double ratio = errors[i - 1] / errors[i];
    EXPECT_GT(ratio, 3.8) << i;
    EXPECT_LT(ratio, 4.2) << i;
  }
}

TEST(PairDamping, ListsKeptWhileSitesMoveLessThanHalfTheSkinMissNoPair) {
  // One damping evaluated along a motion of every body (translation and
  // rotation, each site moving up to 0.057 per stage, below half the skin of
  // 0.24): the neighbour lists are kept for several stages and built again as
  // sites move farther, and at every stage the wrenches are those of the
  // sum over every pair. In a periodic box, bodies carried across the faces
  // (and wrapped back) as they go.
  for (const bool periodic : {false, true}) {
    const Box box = periodic ? Box(V3::Zero(), V3::Constant(6.0), {true, true, true}) : Box{};
    const System sys = mixed_bodies(box);
    SystemState s = random_state(sys.size(), V3::Constant(periodic ? 3.0 : 0.0), periodic ? 3.0 : 2.5);
    std::vector<V3> drift(sys.size()), spin(sys.size());
    for (std::size_t a = 0; a < sys.size(); ++a) {
      drift[a] = t::random_vector(0.02);  // |dx| <= 0.035 per stage
      // A turn by at most 2 |xi| = 0.0104 rad; arms (balls in a cube of 1.2 about the centre of mass) below
      // 2.1: |dc| <= 0.022 per stage from the turn.
      spin[a] = t::random_vector(0.003);
    }
    PairDamping damping(1.3, 1.2, sys.box());
    std::vector<V3> force, torque, expected_force, expected_torque;
    for (int stage = 0; stage < 40; ++stage) {
      force.assign(sys.size(), V3::Zero());
      torque.assign(sys.size(), V3::Zero());
      damping.add(s, sys, force, torque);
      all_pairs(sys, s, 1.3, 1.2, expected_force, expected_torque);
      double scale = 0.0;
      for (std::size_t a = 0; a < sys.size(); ++a)
        scale = std::max({scale, expected_force[a].norm(), expected_torque[a].norm()});
      for (std::size_t a = 0; a < sys.size(); ++a) {
        EXPECT_LT((force[a] - expected_force[a]).norm(), 1e-13 * scale) << stage << " " << a;
        EXPECT_LT((torque[a] - expected_torque[a]).norm(), 1e-13 * scale) << stage << " " << a;
      }
      for (std::size_t a = 0; a < sys.size(); ++a) {
        s.x[a] += drift[a];
        if (periodic) s.x[a] = box.wrap(s.x[a]).x;
        s.q[a] = S3d::exp(spin[a]) * s.q[a];
      }
    }
    // Built again, but not at every stage: sites move at most 0.057 per stage,
    // so a list lasts at least two stages (0.12 / 0.057), and over 40 stages
    // the fastest sites go well beyond the skin.
    EXPECT_GT(damping.list_builds(), 2) << periodic;
    EXPECT_LT(damping.list_builds(), 21) << periodic;
  }
}

TEST(PairDamping, AResumedRunContinuesBitForBit) {
  // The neighbour lists of a resumed run are built at the resume's state, not
  // where the uninterrupted run built its own: the pairs and their order must
  // not depend on it. 200 steps at once against 77 + a fresh stepper from
  // the state and internal state at step 77.
  const System sys = mixed_bodies();
  const SystemState s0 = random_state(sys.size(), V3::Zero(), 2.0);
  auto make = [&] {
    lgvi::LieGroupVariationalIntegrator<Free> stepper(sys, Free::uniform(lgvi::NoPotential{}, sys.size()));
    ForcingSet set;
    set.add(PairDamping(0.8, 1.2, sys.box()));
    stepper.set_forcing(set);
    return stepper;
  };
  const double h = 0.01;
  auto whole = make();
  SystemState end_whole = s0;
  double work_whole = 0.0;
  lgvi::integrate_n_steps(whole, end_whole, 0.0, h, 200, [&](const SystemStepInfo& i) { work_whole = i.work; });
  auto first = make();
  SystemState mid = s0;
  lgvi::integrate_n_steps(first, mid, 0.0, h, 77, [](const SystemStepInfo&) {});
  auto second = make();
  second.resume(mid, 77 * h, first.internal_state());
  double work = 0.0;
  lgvi::integrate_range(second, mid, 0.0, h, 77, 200, [&](const SystemStepInfo& i) { work = i.work; });
  for (std::size_t a = 0; a < sys.size(); ++a) {
    EXPECT_EQ(mid.x[a], end_whole.x[a]) << a;
    EXPECT_EQ(mid.q[a].scalar_first(), end_whole.q[a].scalar_first()) << a;
    EXPECT_EQ(mid.p[a], end_whole.p[a]) << a;
    EXPECT_EQ(mid.w[a], end_whole.w[a]) << a;
  }
  EXPECT_EQ(work, work_whole);
}

TEST(PairDamping, BadParametersAreRefused) {
  const Box periodic(V3::Zero(), V3(10.0, 4.0, 10.0), {true, true, false});
  EXPECT_THROW(PairDamping(0.0, 1.0, Box{}), lgvi::InvalidInput);
  EXPECT_THROW(PairDamping(1.0, -1.0, Box{}), lgvi::InvalidInput);
  EXPECT_THROW(PairDamping(1.0, 2.0, periodic), lgvi::InvalidInput);  // 2 r_c = 4, not below L_y
  EXPECT_NO_THROW(PairDamping(1.0, 1.99, periodic));
  ForcingSet set;
  EXPECT_THROW(set.add(PairDamping(1.0, 1.0, Box{}), 0), lgvi::InvalidInput);  // acts on every body
}

TEST(PairDampingScenario, KeysAndOneLineErrors) {
  // Two triangle molecules from the gas: the run reads the table; bad values
  // and keys are one line naming the key.
  const std::string gas = R"([[bodies]]
name = "m"
count = 8
position = [0.0, 0.0, 0.0]
spacing = 2.2
seed = 1
temperature = 0.5
[[bodies.ball]]
position = [0.0, 0.0, 0.0]
mass = 1.0
radius = 0.5
[[bodies.ball]]
position = [1.0, 0.0, 0.0]
mass = 1.0
radius = 0.5

[potential]
kind = "none"

[integrator]
method = "lgvi"
step = 0.01
duration = 0.1

)";
  const std::string ok = "[[forcing]]\nkind = \"pair-damping\"\ngamma = 1.0\ncutoff = 2.5\n";
  EXPECT_NO_THROW(lgvi::app::parse_scenario(gas + ok, "ok.toml"));
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"[[forcing]]\nkind = \"pair-damping\"\ngamma = 0.0\ncutoff = 2.5\n", "key 'forcing[0].gamma': must be > 0"},
      {"[[forcing]]\nkind = \"pair-damping\"\ngamma = 1.0\n", "forcing[0].cutoff"},
      {"[[forcing]]\nkind = \"pair-damping\"\ngamma = 1.0\ncutoff = 2.5\nbody = \"m0\"\n",
       "key 'forcing[0].body': unknown key"},
      {"[box]\nlower = [-1.0, -1.0, -1.0]\nupper = [5.0, 5.0, 5.0]\nperiodic = [true, true, true]\n"
       "[[forcing]]\nkind = \"pair-damping\"\ngamma = 1.0\ncutoff = 3.0\n",
       "key 'forcing[0].cutoff': must be less than half the box's shortest periodic length (6)"},
  };
  for (const auto& [forcing, expected] : cases) {
    const std::string message = t::parse_error(gas + forcing, "s.toml");
    EXPECT_NE(message.find(expected), std::string::npos) << "for\n" << forcing << "got: " << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
  // One body: nothing to damp between, refused.
  std::string one = gas;
  one.replace(one.find("count = 8"), 9, "count = 1");
  const std::string message = t::parse_error(one + ok, "one.toml");
  EXPECT_NE(message.find("pair damping acts between bodies"), std::string::npos) << message;
}

}  // namespace

}  // namespace test_pair_damping
