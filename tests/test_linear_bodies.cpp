// Linear bodies (point masses on one line, J = I (1 - n n^T)) and point
// bodies (J = 0), rigid_body.hpp: what they are, and the LGVI's closed-form
// step for them (rotation_solver.hpp) against exact solutions.
#include "test_support.hpp"

#include <lgvi/integrate.hpp>
#include <lgvi/lennard_jones.hpp>
#include <lgvi/exact_free_body.hpp>
#include <lgvi/forcing.hpp>
#include <lgvi/lgvi.hpp>
#include <lgvi/methods/euler_exp.hpp>
#include <lgvi/methods/no_squish.hpp>
#include <lgvi/methods/rattle_quaternion.hpp>
#include <lgvi/methods/rk4_normalized.hpp>
#include <lgvi/methods/so3_lgvi.hpp>
#include <lgvi/methods/splitting_dlm.hpp>
#include <lgvi/system.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

namespace test_linear_bodies {

namespace {

using lgvi::Ball;
using lgvi::RigidBody;
using lgvi::RigidBodyState;
using lgvi::S3d;
using lgvi::System;
using lgvi::SystemState;
using M3 = lgvi::Matrix3<double>;
using V3 = lgvi::Vector3<double>;
constexpr double eps = std::numeric_limits<double>::epsilon();

/// Three point masses on the line through the origin along d.
RigidBody rod(const V3& d) {
  return RigidBody::from_balls({{-0.7 * d, 1.0, 0.0}, {0.2 * d, 2.0, 0.0}, {1.1 * d, 0.5, 0.0}});
}

TEST(LinearBodies, PointMassesOnALineMakeALinearBody) {
  const V3 d = V3(1.0, 2.0, 2.0) / 3.0;
  const RigidBody body = rod(d);
  ASSERT_EQ(body.rotational_dof(), 2);
  EXPECT_NEAR(std::abs(body.linear_axis().dot(d)), 1.0, 4 * eps);
  // I = sum m_i s_i^2 about the centre of mass, by hand: s = -0.7, 0.2, 1.1
  // less their mass-weighted mean (0.05 / 3.5).
  const double c = (-0.7 * 1.0 + 0.2 * 2.0 + 1.1 * 0.5) / 3.5;
  const double moment = 1.0 * (-0.7 - c) * (-0.7 - c) + 2.0 * (0.2 - c) * (0.2 - c) + 0.5 * (1.1 - c) * (1.1 - c);
  const M3 across = M3::Identity() - d * d.transpose();
  EXPECT_MAT_NEAR(body.inertia(), (moment * across).eval(), 8 * eps * moment);
  // The pseudo-inverse: J J+ J = J, J+ n = 0.
  EXPECT_MAT_NEAR((body.inertia() * body.inertia_inverse() * body.inertia()).eval(), body.inertia(), 8 * eps * moment);
  EXPECT_LE((body.inertia_inverse() * d).norm(), 8 * eps / moment);
  // What it cannot have: momentum along the axis.
  const V3 w(0.3, -1.0, 2.0);
  EXPECT_LE(std::abs(body.admissible_momentum(w).dot(body.linear_axis())), 4 * eps * w.norm());
  // One point mass: no rotation at all.
  const RigidBody point = RigidBody::from_balls({{V3(1.0, 2.0, 3.0), 2.0, 0.0}});
  EXPECT_EQ(point.rotational_dof(), 0);
  EXPECT_EQ(point.inertia(), M3::Zero());
  EXPECT_EQ(point.admissible_momentum(w), V3::Zero());
  // A moment of 1e-9 of the others is LAMMPS's zero (below 1e-7); 1e-6 is not.
  EXPECT_EQ(RigidBody(1.0, M3(V3(1e-9, 1.0, 1.0).asDiagonal())).rotational_dof(), 2);
  EXPECT_EQ(RigidBody(1.0, M3(V3(1e-6, 1.0, 1.0).asDiagonal())).rotational_dof(), 3);
  // A zero moment with two unequal others is no mass distribution.
  try {
    const RigidBody bad(1.0, M3(V3(0.0, 1.0, 2.0).asDiagonal()), RigidBody::TriangleInequality::Waive);
    ADD_FAILURE() << "accepted";
  } catch (const lgvi::InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("a zero moment is a linear body"), std::string::npos) << e.what();
  }
  // A body with three moments keeps w bit for bit.
  const RigidBody full(1.0, M3(V3(1.0, 2.0, 2.5).asDiagonal()));
  EXPECT_EQ(full.rotational_dof(), 3);
  EXPECT_EQ(std::memcmp(full.admissible_momentum(w).data(), w.data(), sizeof(V3)), 0);
}

/// The free rotor: body frame angular velocity Omega across the axis at
/// attitude q0. Its space angular momentum L = R(q0) J Omega is constant and
/// the axis turns about L at the rate |Omega|.
struct Rotor {
  RigidBody body = rod(V3(0.0, 0.6, 0.8));
  RigidBodyState start;
  double omega = 3.0;
  Rotor() {
    const V3 n = body.linear_axis();
    const V3 across = n.cross(V3(1.0, 0.0, 0.0)).normalized();
    start.q = S3d::exp(V3(0.3, -0.5, 0.2));
    start.w = 2.0 * body.inertia() * (omega * across);
    start.p = V3(0.1, 0.0, -0.2);
  }
  V3 axis(const RigidBodyState& s) const { return s.q.act(body.linear_axis()); }
  /// The start's axis turned by `angle` about L.
  V3 turned(double angle) const {
    const V3 l = start.q.act(start.w).normalized();
    return S3d::exp(0.5 * angle * l).act(axis(start));
  }
};

TEST(LinearBodies, FreeRotationIsTheExactDiscreteFlow) {
  // The step rotates about L by 2 asin|f_v| with sin of it = 2k = h |Omega|
  // (rotation_solver.hpp): the axis after n steps is the start's turned by
  // n asin(h |Omega|), the discrete flow's exact solution, to the rounding of
  // n steps (~n eps). w stays the same in the body frame (f turns about w),
  // and stays across the axis; |q| = 1 to round-off, without normalizing.
  const Rotor r;
  const double h = 0.05;
  const std::int64_t n = 2000;
  lgvi::SingleBody<lgvi::LieGroupVariationalIntegrator, lgvi::NoPotential> integ(r.body, {});
  const RigidBodyState s = lgvi::test::run(integ, r.start, h, n);
  EXPECT_MAT_NEAR(r.axis(s), r.turned(static_cast<double>(n) * std::asin(h * r.omega)), 4 * n * eps);
  EXPECT_MAT_NEAR(s.w, r.start.w, 16 * eps * r.start.w.norm());
  EXPECT_LE(std::abs(s.w.dot(r.body.linear_axis())), 4 * eps * s.w.norm());
  EXPECT_LE(s.q.norm_error(), 8 * eps);
  EXPECT_MAT_NEAR(s.x, (r.start.x + static_cast<double>(n) * h * r.start.p / r.body.mass()).eval(), 4 * n * eps);
  // The position-position form is the same discrete flow: the same axis to
  // the rounding of the two ways of computing it.
  lgvi::SingleBody<lgvi::LagrangianLieGroupVariationalIntegrator, lgvi::NoPotential> lagrangian(r.body, {});
  const RigidBodyState sl = lgvi::test::run(lagrangian, r.start, h, n);
  EXPECT_MAT_NEAR(r.axis(sl), r.axis(s), 8 * n * eps);
  // (Its w is formed from f each step, not rotated: a random walk of n
  // roundings across the axis, ~sqrt(n) eps.)
  EXPECT_MAT_NEAR(sl.w, s.w, 8 * std::sqrt(static_cast<double>(n)) * eps * r.start.w.norm());
}

TEST(LinearBodies, FreeRotationConvergesAtSecondOrderToTheExactFlow) {
  // Against the continuous flow (the axis turned by |Omega| T): the phase
  // error is n asin(h w) - w T = T w^3 h^2 / 6 (1 + 0.45 (h w)^2 + ...), the
  // distance of the axes 2 sin(phase / 2), to the rounding of n steps; the
  // order from halving h is 2 to 0.02 (the (h w)^2 term moves it by 0.011 at
  // h w = 0.15).
  const Rotor r;
  const double t_end = 10.0;
  std::vector<double> err;
  for (const double h : {0.05, 0.025, 0.0125}) {
    const auto n = static_cast<std::int64_t>(std::lround(t_end / h));
    lgvi::SingleBody<lgvi::LieGroupVariationalIntegrator, lgvi::NoPotential> integ(r.body, {});
    const RigidBodyState s = lgvi::test::run(integ, r.start, h, n);
    err.push_back((r.axis(s) - r.turned(r.omega * t_end)).norm());
    const double phase = static_cast<double>(n) * std::asin(h * r.omega) - r.omega * t_end;
    EXPECT_NEAR(err.back(), 2.0 * std::sin(0.5 * phase), 4 * static_cast<double>(n) * eps) << "h " << h;
  }
  for (std::size_t i = 1; i < err.size(); ++i) EXPECT_NEAR(std::log2(err[i - 1] / err[i]), 2.0, 0.02);
}

TEST(LinearBodies, ATorqueAlongTheAxisDoesNothingInEitherForm) {
  // A torque with a part along the axis (a heavy top pivoted off the rod's
  // line: a test of the step, not a body) acts only through its part across
  // it. The two forms are the same discrete flow: the axis agrees to the
  // rounding of n steps, grown by the top's sensitivity (measured 6 n eps;
  // an axial torque mishandled in one form is an O(h) ~ 1e-3 difference),
  // and halving h shrinks the difference
  // between successive runs by 4 (second order; taking the axial part into
  // w and rotating it across would leave an O(h) error: order 1).
  const RigidBody body = rod(V3(0.0, 0.6, 0.8));
  const lgvi::HeavyTop top(body, V3(0.0, 0.0, -9.81), V3(0.3, 0.1, 0.2));
  RigidBodyState start;
  start.q = S3d::exp(V3(0.3, -0.5, 0.2));
  start.w = body.admissible_momentum(2.0 * body.inertia() * V3(1.0, -2.0, 0.5));
  auto axis_at = [&](auto& integ, double h, std::int64_t n) {
    return lgvi::test::run(integ, start, h, n).q.act(body.linear_axis()).eval();
  };
  const std::int64_t n = 400;
  lgvi::SingleBody<lgvi::LieGroupVariationalIntegrator, lgvi::HeavyTop> hamiltonian(body, top);
  lgvi::SingleBody<lgvi::LagrangianLieGroupVariationalIntegrator, lgvi::HeavyTop> lagrangian(body, top);
  EXPECT_MAT_NEAR(axis_at(hamiltonian, 0.005, n), axis_at(lagrangian, 0.005, n), 16 * n * eps);
  std::vector<V3> axes;
  for (const double h : {0.004, 0.002, 0.001, 0.0005}) {
    lgvi::SingleBody<lgvi::LieGroupVariationalIntegrator, lgvi::HeavyTop> integ(body, top);
    axes.push_back(axis_at(integ, h, std::lround(1.0 / h)));
  }
  for (std::size_t i = 2; i < axes.size(); ++i)
    EXPECT_NEAR(std::log2((axes[i - 2] - axes[i - 1]).norm() / (axes[i - 1] - axes[i]).norm()), 2.0, 0.1);
}

TEST(LinearBodies, APointMassDoesNotRotate) {
  const RigidBody point = RigidBody::from_balls({{V3::Zero(), 2.0, 0.0}});
  RigidBodyState start;
  start.q = S3d::exp(V3(0.1, 0.2, 0.3));
  start.p = V3(1.0, -2.0, 0.5);
  lgvi::SingleBody<lgvi::LieGroupVariationalIntegrator, lgvi::NoPotential> integ(point, {});
  const RigidBodyState s = lgvi::test::run(integ, start, 0.1, 100);
  EXPECT_EQ(std::memcmp(s.q.scalar_first().data(), start.q.scalar_first().data(), 4 * sizeof(double)), 0);
  EXPECT_EQ(s.w, V3::Zero());
  EXPECT_MAT_NEAR(s.x, (10.0 * start.p / 2.0).eval(), 64 * eps);
}

/// Constructing Method on `body` is one InvalidInput whose message holds `what`.
template <template <class> class Method>
void expect_refused(const RigidBody& body, const std::string& what) {
  try {
    const lgvi::SingleBody<Method, lgvi::NoPotential> stepper(body, {});
    ADD_FAILURE() << "no error for a body of " << body.rotational_dof() << " rotational degrees of freedom";
  } catch (const lgvi::InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
  }
}

TEST(LinearBodies, TheOtherMethodsRefuseThemInTheLibraryToo) {
  // As the scenario reader does, the library's steppers other than the LGVI's two forms refuse a linear body or a
  // point on construction: their equations divide by the principal moments, and would give infinities or a wrong
  // motion, not an error.
  const RigidBody rod = RigidBody::from_balls({{V3(-0.5, 0.0, 0.0), 1.0, 0.0}, {V3(0.5, 0.0, 0.0), 1.0, 0.0}});
  const RigidBody point = RigidBody::from_balls({{V3::Zero(), 2.0, 0.0}});
  for (const auto& [body, what] : {std::pair{rod, std::string("a linear body")}, std::pair{point, std::string("a point mass")}}) {
    ASSERT_NE(body.rotational_dof(), 3);
    expect_refused<lgvi::So3LieGroupVariationalIntegrator>(body, what);
    expect_refused<lgvi::RattleQuaternionIntegrator>(body, what);
    expect_refused<lgvi::Rk4NormalizedIntegrator>(body, what);
    expect_refused<lgvi::EulerExpIntegrator>(body, what);
    expect_refused<lgvi::NoSquishIntegrator>(body, what);
    expect_refused<lgvi::SplittingDlmIntegrator>(body, what);
    expect_refused<lgvi::ExactFreeBodyStepper>(body, what);
  }
}

TEST(LinearBodies, AttitudeControlSpendsItsTorqueAcrossTheAxis) {
  // A rod (axis x) an attitude error about an axis that mixes x and y: the PD law's torque has a part along the
  // rod, which cannot turn it; the controller gives the rest, and max_torque limits only that (the whole budget
  // goes where it acts). Unclipped, the part across the axis is the three-moment law's, bit for bit but the
  // removed component.
  const RigidBody rod = RigidBody::from_balls({{V3(-0.5, 0.0, 0.0), 1.0, 0.0}, {V3(0.5, 0.0, 0.0), 1.0, 0.0}});
  ASSERT_EQ(rod.linear_axis(), V3(1.0, 0.0, 0.0));
  RigidBodyState s;
  s.q = S3d::exp(V3(0.3, 0.2, 0.0));
  s.w = rod.admissible_momentum(V3(0.5, 0.1, -0.2));
  lgvi::AttitudeControl control{S3d(), 2.0, 0.5};
  const V3 free = control(0.0, s, rod).torque;
  EXPECT_EQ(free.x(), 0.0);
  const V3 whole = (-2.0) * (S3d().inverse() * s.q).vec() - 0.25 * (rod.inertia_inverse() * s.w);
  EXPECT_EQ(free.y(), whole.y());
  EXPECT_EQ(free.z(), whole.z());
  ASSERT_GT(std::abs(whole.x()), 0.1);  // the part removed is not small
  control.max_torque = 0.5 * free.norm();
  const V3 clipped = control(0.0, s, rod).torque;
  EXPECT_EQ(clipped.x(), 0.0);
  EXPECT_NEAR(clipped.norm(), control.max_torque, 4 * eps * control.max_torque);  // (one scaling's round-off)
}

using LjSystem = lgvi::Coupled<lgvi::ExternalField<lgvi::NoPotential>, lgvi::LennardJones>;

/// Twelve molecules in a cluster, in turn a bent triatomic, a linear
/// triatomic, a two-atom rod and a single atom, with random attitudes and
/// momenta (drawn with a seed of its own: the same cluster in every run):
/// more than two batches of the rotation solves (RotationSolveBatch), with
/// linear bodies and points among the lanes.
struct Cluster {
  System system;
  SystemState start{12};
  Cluster() {
    const std::vector<std::vector<Ball>> shapes = {
        {{V3(0.0, 0.0, 0.0), 1.0, 0.0}, {V3(1.0, 0.0, 0.0), 1.0, 0.0}, {V3(0.4, 0.9, 0.0), 2.0, 0.0}},
        {{V3(-1.1, 0.0, 0.0), 1.0, 0.0}, {V3(0.0, 0.0, 0.0), 1.5, 0.0}, {V3(1.1, 0.0, 0.0), 1.0, 0.0}},
        {{V3(0.0, 0.0, 0.0), 1.0, 0.0}, {V3(0.3, 0.6, 0.6), 1.0, 0.0}},
        {{V3(0.0, 0.0, 0.0), 2.0, 0.0}}};
    std::vector<RigidBody> kinds;
    for (const auto& s : shapes) kinds.push_back(RigidBody::from_balls(s));
    std::vector<std::uint32_t> kind;
    for (std::uint32_t a = 0; a < 12; ++a) kind.push_back(a % 4);
    system = System(kinds, kind, {});
    std::mt19937_64 rng(2026);
    std::normal_distribution<double> normal;
    auto draw = [&] { return V3(normal(rng), normal(rng), normal(rng)); };
    for (std::size_t a = 0; a < 12; ++a) {
      const RigidBody& b = system.body(a);
      start.x[a] = 2.5 * V3(static_cast<double>(a % 3), static_cast<double>((a / 3) % 2), static_cast<double>(a / 6));
      start.q[a] = S3d::exp(draw());
      start.p[a] = b.mass() * 0.2 * draw();
      start.w[a] = b.admissible_momentum(2.0 * b.inertia() * (0.5 * draw()));
    }
  }
  LjSystem potential(lgvi::Parallelism par) const {
    return {lgvi::ExternalField<lgvi::NoPotential>::uniform(lgvi::NoPotential{}, system.size(), par),
            lgvi::LennardJones(system, 1.0, 1.0, 2.5, par)};
  }
};

TEST(LinearBodies, AMixedClusterHasASecondOrderEnergyError) {
  // The cluster binds and heats up (K to about 22 by t = 4), with close
  // passes: the largest energy error over t <= 4 falls by 4 per halving of h
  // (measured log2 ratios 1.99 and 1.81; 2 +- 0.3 allows for the close
  // passes' higher-order terms). A linear body's torque or momentum handled
  // wrongly would leave an O(1) or O(h) error here.
  const Cluster c;
  std::vector<double> worst;
  for (const double h : {0.004, 0.002, 0.001}) {
    const auto n = static_cast<std::int64_t>(std::lround(4.0 / h));
    lgvi::LieGroupVariationalIntegrator<LjSystem> integ(c.system, c.potential({}), lgvi::SolverOptions{}, {});
    SystemState s = c.start;
    double e0 = 0.0, w = 0.0;
    lgvi::integrate_n_steps(integ, s, 0.0, h, n, [&](const lgvi::SystemStepInfo& i) {
      const double e = lgvi::total_energy(i.state, c.system, i.evaluation);
      if (i.k == 0) e0 = e;
      w = std::max(w, std::abs(e - e0));
    });
    worst.push_back(w);
  }
  for (std::size_t i = 1; i < worst.size(); ++i) EXPECT_NEAR(std::log2(worst[i - 1] / worst[i]), 2.0, 0.3);
}

TEST(LinearBodies, AMixedClusterKeepsItsMomentaAndEnergyOnAnyThreads) {
  // Linear and point bodies among full ones under Lennard-Jones in free
  // space: total linear and angular momentum conserved to round-off (each
  // substep preserves them; the axial part removed from w is round-off, since
  // a linear body's torque has none), |q| = 1 without normalizing, and the
  // same bits on 1 and 2 threads.
  const Cluster c;
  const double h = 0.002;
  const std::int64_t n = 5000;
  std::vector<SystemState> ends;
  for (const int threads : {1, 2}) {
    const lgvi::Parallelism par{threads, 1};
    lgvi::LieGroupVariationalIntegrator<LjSystem> integ(c.system, c.potential(par), lgvi::SolverOptions{}, par);
    SystemState s = c.start;
    const V3 p0 = lgvi::linear_momentum(s), l0 = lgvi::angular_momentum(s);
    double worst_axial = 0.0;
    lgvi::integrate_n_steps(integ, s, 0.0, h, n, [&](const lgvi::SystemStepInfo& i) {
      for (std::size_t a = 1; a < 12; a += 4)
        worst_axial = std::max(worst_axial, std::abs(i.state.w[a].dot(c.system.body(a).linear_axis())));
    });
    double p_scale = 0.0, l_scale = 0.0;
    for (std::size_t a = 0; a < 12; ++a) {
      p_scale += s.p[a].norm();
      l_scale += s.x[a].cross(s.p[a]).norm() + 0.5 * s.w[a].norm();
      EXPECT_LE(s.q[a].norm_error(), 4 * std::sqrt(static_cast<double>(n)) * eps) << "body " << a;  // a random walk of n roundings
      if (c.system.body(a).rotational_dof() == 0) {
        EXPECT_EQ(s.w[a], V3::Zero());
      }
    }
    EXPECT_LE((lgvi::linear_momentum(s) - p0).norm(), 1e-13 * p_scale);
    EXPECT_LE((lgvi::angular_momentum(s) - l0).norm(), 1e-12 * l_scale);
    EXPECT_LE(worst_axial, 1e-14);
    ends.push_back(s);
  }
  for (std::size_t a = 0; a < 12; ++a) {
    EXPECT_EQ(std::memcmp(ends[0].x[a].data(), ends[1].x[a].data(), sizeof(V3)), 0) << "body " << a;
    EXPECT_EQ(std::memcmp(ends[0].w[a].data(), ends[1].w[a].data(), sizeof(V3)), 0) << "body " << a;
  }
}

}  // namespace

}  // namespace test_linear_bodies
