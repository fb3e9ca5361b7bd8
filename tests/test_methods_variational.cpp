// Other variational integrators of the same discrete Lagrangian as the
// quaternion LGVI: the rotation-matrix LGVI of Lee, Leok & McClamroch
// (methods/so3_lgvi.hpp) and the constrained quaternion (RATTLE) integrator of
// Wendlandt & Marsden (methods/rattle_quaternion.hpp). Same L_d => the same
// trajectory as the LGVI to rounding; plus each method's own checks.
#include <lgvi/continuous.hpp>
#include <lgvi/integrate.hpp>
#include <lgvi/methods/rattle_quaternion.hpp>
#include <lgvi/methods/so3_lgvi.hpp>
#include <lgvi/paper.hpp>

#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

namespace test_methods_variational {

namespace {

using lgvi::CentralGravity;
using lgvi::RigidBody;
using lgvi::RigidBodyState;
using lgvi::S3d;
using V3 = lgvi::Vector3<double>;
using V4 = lgvi::Vector4<double>;
using M3 = lgvi::Matrix3<double>;
constexpr double eps = 2.220446049250313e-16;

static_assert(lgvi::SystemStepper<lgvi::SingleBody<lgvi::So3LieGroupVariationalIntegrator, CentralGravity>>);
static_assert(lgvi::SystemStepper<lgvi::SingleBody<lgvi::So3LieGroupVariationalIntegrator, lgvi::NoPotential>>);
static_assert(lgvi::SystemStepper<lgvi::SingleBody<lgvi::RattleQuaternionIntegrator, CentralGravity>>);
static_assert(lgvi::SystemStepper<lgvi::SingleBody<lgvi::RattleQuaternionIntegrator, lgvi::NoPotential>>);

using lgvi::test::distance;
using lgvi::test::LongRun;
using lgvi::test::run;

template <template <class> class Integrator>
RigidBodyState run_paper(double h, std::int64_t n, RigidBodyState s0 = lgvi::paper::orbit_initial_state()) {
  const RigidBody body = lgvi::paper::three_ball_body();
  lgvi::SingleBody<Integrator, CentralGravity> integ(body, CentralGravity(body, 1.0));
  return run(integ, s0, h, n);
}

template <template <class> class Integrator>
RigidBodyState run_free(const RigidBody& body, double h, std::int64_t n, const RigidBodyState& s0) {
  lgvi::SingleBody<Integrator, lgvi::NoPotential> integ(body, {});
  return run(integ, s0, h, n);
}

/// As distance, with the attitudes compared as rotations pi(q).
double distance_so3(const RigidBodyState& a, const RigidBodyState& b) {
  return std::max({(a.x - b.x).norm(), (a.q.matrix() - b.q.matrix()).norm(), (a.p - b.p).norm(), (a.w - b.w).norm()});
}

/// Largest norm among the state's components (the scale of its rounding).
double scale_of(const RigidBodyState& s) { return std::max({s.x.norm(), 1.0, s.p.norm(), s.w.norm()}); }

/// The flow's amplification of a perturbation over n steps (of the LGVI,
/// h = 0.01): a relative perturbation delta of x, p and w at t = 0 gives a
/// final difference A delta scale. Rounding errors ~eps scale made at each
/// step grow by at most A, so two methods that agree per step to c eps scale
/// agree after n steps to about n c eps scale A.
template <class Pot>
double amplification(const RigidBody& body, const Pot& pot, const RigidBodyState& s0, std::int64_t n) {
  const double delta = 1e-8;
  RigidBodyState s1 = s0;
  s1.x += delta * V3(1, -1, 1).normalized() * s0.x.norm();
  s1.p += delta * V3(-1, 1, 1).normalized() * s0.p.norm();
  s1.w += delta * V3(1, 1, -1).normalized() * s0.w.norm();
  lgvi::SingleBody<lgvi::LieGroupVariationalIntegrator, Pot> a(body, pot), b(body, pot);
  const RigidBodyState e0 = run(a, s0, 0.01, n), e1 = run(b, s1, 0.01, n);
  return std::max(1.0, distance(e0, e1) / (delta * scale_of(s0)));
}

RigidBody asymmetric_body() { return RigidBody(2.0, M3(V3(1.0, 2.0, 2.5).asDiagonal())); }

RigidBodyState free_initial_state() {
  RigidBodyState s;
  s.x = V3(0.1, -0.2, 0.3);
  s.p = V3(0.5, 0.25, -1.0);
  s.q = S3d::exp(V3(0.3, -0.2, 0.4));
  // Spin near the intermediate axis: a tumbling (sensitive) motion.
  s.w = 2.0 * asymmetric_body().inertia() * V3(0.2, 3.0, 0.3);
  return s;
}

// ---------------------------------------------------------- convergence

RigidBodyState reference_solution(double t_end, double h_ref) {
  const RigidBody body = lgvi::paper::three_ball_body();
  const lgvi::ContinuousEquations<CentralGravity> eqs(body, CentralGravity(body, 1.0));
  const auto c = eqs.rk4(lgvi::to_continuous(lgvi::paper::orbit_initial_state(), body), h_ref,
                         std::lround(t_end / h_ref));
  return lgvi::from_continuous(c, body);
}

template <template <class> class Integrator>
void expect_second_order(const char* name) {
  const RigidBodyState ref = reference_solution(1.0, 5e-4);
  std::vector<double> errors;
  for (double h : {0.1, 0.05, 0.025, 0.0125}) errors.push_back(distance(run_paper<Integrator>(h, std::lround(1.0 / h)), ref));
  for (std::size_t i = 0; i + 1 < errors.size(); ++i) {
    const double order = std::log2(errors[i] / errors[i + 1]);
    std::printf("[ lgvi     ] %s: h = %g error %.3e, order %.3f\n", name, 0.1 / std::pow(2, i), errors[i], order);
    EXPECT_NEAR(order, 2.0, 0.1) << "h = " << 0.1 / std::pow(2, i);
  }
}

// ------------------------------------------------------------ long runs

template <class Integ, class Extra>
LongRun long_run(Integ& integ, std::int64_t n, Extra&& extra) {
  return lgvi::test::paper_orbit_long_run(integ, 0.01, n, extra);
}

template <template <class> class Integrator>
void expect_bit_identical_resume() {
  const RigidBody body = lgvi::paper::three_ball_body();
  const double h = 0.01;
  lgvi::SingleBody<Integrator, CentralGravity> a(body, CentralGravity(body, 1.0));
  const RigidBodyState saved = run(a, lgvi::paper::orbit_initial_state(), h, 300);
  const std::vector<double> internal = a.internal_state();
  lgvi::SystemState s(saved);
  for (int k = 300; k < 600; ++k) a.step(s, k * h, h);
  lgvi::SingleBody<Integrator, CentralGravity> b(body, CentralGravity(body, 1.0));
  lgvi::SystemState t(saved);
  b.resume(t, 300 * h, internal);
  for (int k = 300; k < 600; ++k) b.step(t, k * h, h);
  EXPECT_EQ(distance(s.body(0), t.body(0)), 0.0);
  EXPECT_EQ(s.q[0].scalar_first(), t.q[0].scalar_first());
}

template <template <class> class Integrator>
void expect_one_evaluation_per_step() {
  const RigidBody body = lgvi::paper::three_ball_body();
  const CentralGravity gravity(body, 1.0);
  long calls = 0;
  const lgvi::CallablePotential counting([&](const V3& x, const S3d& q) {
    ++calls;
    return gravity.evaluate(x, q);
  });
  lgvi::SingleBody<Integrator, lgvi::CallablePotential> integ(body, counting);
  run(integ, lgvi::paper::orbit_initial_state(), 0.01, 500);
  EXPECT_EQ(calls, 501);
}

// ============================================================== SO(3) LGVI

TEST(VariationalSo3, DiscreteLagrangianEqualsTheQuaternionOne) {
  // tr[(I - F) J_d] = 2 f_v^T J f_v for F = pi(f), f = q0^* q1, on random
  // rotations and random valid inertias: both sides are O(tr J) sums of a
  // dozen products, so they agree to a few eps tr(J).
  for (int trial = 0; trial < 200; ++trial) {
    const M3 rot = lgvi::test::random_unit_quaternion().matrix();
    const V3 moments(lgvi::test::uniform(0.5, 2.0), lgvi::test::uniform(0.5, 2.0), lgvi::test::uniform(0.5, 2.0));
    const M3 J = rot * moments.asDiagonal() * rot.transpose();
    const M3 jd = 0.5 * J.trace() * M3::Identity() - J;
    const S3d q0 = lgvi::test::random_unit_quaternion(), q1 = lgvi::test::random_unit_quaternion();
    const S3d f = q0.inverse() * q1;
    const M3 F = f.matrix();
    const double lhs = ((M3::Identity() - F) * jd).trace();
    const double rhs = 2.0 * f.vec().dot(J * f.vec());
    EXPECT_NEAR(lhs, rhs, 8 * eps * J.trace()) << "trial " << trial;
    // And the step equations: (F J_d - J_d F^T)^vee = 2 (f_s J f_v + f_v x J f_v).
    const V3 lee = S3d::vee(F * jd - jd * F.transpose());
    const V3 quat = 2.0 * (f.w() * J * f.vec() + f.vec().cross(J * f.vec()));
    EXPECT_MAT_NEAR(lee, quat, 16 * eps * J.trace()) << "trial " << trial;
    // Cayley: cay(u) = pi(f) for u = f_v / f_s.
    if (std::abs(f.w()) > 0.1) {
      EXPECT_MAT_NEAR(lgvi::detail::cayley(f.vec() / f.w()), F, 64 * eps);
    }
  }
}

TEST(VariationalSo3, StepSolvesLeesMatrixEquation) {
  // One step from a random attitude: F_k = R_k^T R_{k+1} satisfies
  // h Pi_k + (h^2/2) M_k = (F_k J_d - J_d F_k^T)^vee and
  // Pi_{k+1} = F_k^T Pi_k + (h/2) F_k^T M_k + (h/2) M_{k+1}.
  const RigidBody body = lgvi::paper::three_ball_body();
  const double h = 0.05;
  lgvi::SingleBody<lgvi::So3LieGroupVariationalIntegrator, CentralGravity> integ(body, CentralGravity(body, 1.0));
  RigidBodyState s0 = lgvi::paper::orbit_initial_state();
  s0.q = lgvi::test::random_unit_quaternion();
  lgvi::SystemState state(s0);
  integ.initialize(state, 0.0);
  const M3 r0 = integ.rotation_matrix(0);
  const V3 pi0 = 0.5 * s0.w, m0 = integ.evaluation().torque[0];
  integ.step(state, 0.0, h);
  const RigidBodyState s = state.body(0);
  const M3 F = r0.transpose() * integ.rotation_matrix(0);
  const M3& jd = integ.nonstandard_inertia(0);
  // vee(A) here is (A - A^T)^vee / 2, so (F J_d - J_d F^T)^vee = 2 vee(F J_d).
  const V3 lhs = h * pi0 + (h * h / 2) * m0;
  EXPECT_MAT_NEAR(lhs, (2.0 * S3d::vee(F * jd)).eval(), 32 * eps * body.inertia().norm());
  const V3 pi1 = F.transpose() * pi0 + (h / 2) * F.transpose() * m0 + (h / 2) * integ.evaluation().torque[0];
  EXPECT_MAT_NEAR((0.5 * s.w).eval(), pi1, 32 * eps * pi0.norm());
  // The reported q is a unit lift of R with the previous q's sign.
  EXPECT_MAT_NEAR(s.q.matrix(), integ.rotation_matrix(0), 8 * eps);
}

template <template <class> class Integrator>
void expect_same_trajectory_as_lgvi(const char* name, double per_step) {
  // Same L_d and, on S^3 / SO(3), the same step equations: the trajectories
  // differ only by rounding, c eps scale per step (c = per_step), propagated
  // by the flow: the bound is n c eps scale A with the amplification A
  // measured above. Three motions: the paper's orbit (A ~ linear in t, the
  // orbit's shear), a free body spinning near its major axis (stable), and a
  // free body tumbling near its intermediate axis (unstable: A large).
  const std::int64_t n = 1000;
  const RigidBody paper = lgvi::paper::three_ball_body();
  const RigidBody free = asymmetric_body();
  RigidBodyState stable = free_initial_state();
  stable.w = 2.0 * free.inertia() * V3(0.2, 0.3, 3.0);
  struct Case {
    const char* label;
    double d, d_so3, bound;
  };
  std::vector<Case> cases;
  {
    const RigidBodyState s0 = lgvi::paper::orbit_initial_state();
    const RigidBodyState a = run_paper<lgvi::LieGroupVariationalIntegrator>(0.01, n, s0);
    const RigidBodyState b = run_paper<Integrator>(0.01, n, s0);
    const double amp = amplification(paper, CentralGravity(paper, 1.0), s0, n);
    cases.push_back({"paper orbit", distance(a, b), distance_so3(a, b), n * per_step * eps * scale_of(s0) * amp});
  }
  for (const auto& [label, s0] : {std::pair{"free, major axis", stable}, std::pair{"free, tumbling", free_initial_state()}}) {
    const RigidBodyState a = run_free<lgvi::LieGroupVariationalIntegrator>(free, 0.01, n, s0);
    const RigidBodyState b = run_free<Integrator>(free, 0.01, n, s0);
    const double amp = amplification(free, lgvi::NoPotential{}, s0, n);
    cases.push_back({label, distance(a, b), distance_so3(a, b), n * per_step * eps * scale_of(s0) * amp});
  }
  for (const Case& c : cases) {
    std::printf("[ lgvi     ] %s vs quaternion LGVI, %lld steps, %s: %.2e (as rotations %.2e), bound %.2e\n", name,
                static_cast<long long>(n), c.label, c.d, c.d_so3, c.bound);
    EXPECT_LE(c.d, c.bound) << c.label;  // q itself, sign included
    EXPECT_LE(c.d_so3, c.bound) << c.label;
  }
}

TEST(VariationalSo3, SameTrajectoryAsQuaternionLgvi) {
  expect_same_trajectory_as_lgvi<lgvi::So3LieGroupVariationalIntegrator>("SO(3) LGVI", 4.0);
}

TEST(VariationalSo3, IsSecondOrder) { expect_second_order<lgvi::So3LieGroupVariationalIntegrator>("SO(3) LGVI"); }

TEST(VariationalSo3, InvariantsOver1e5Steps) {
  const RigidBody body = lgvi::paper::three_ball_body();
  lgvi::SingleBody<lgvi::So3LieGroupVariationalIntegrator, CentralGravity> integ(body, CentralGravity(body, 1.0));
  double max_orth = 0;
  const LongRun r = long_run(integ, 100000, [&](const lgvi::SystemStepInfo&) {
    max_orth = std::max(max_orth, integ.orthogonality_error(0));
  });
  std::printf("[ lgvi     ] SO(3) LGVI 1e5 steps: max rel |dL| %.3e, max |dE| first tenth %.3e, last tenth %.3e, "
              "max ||R^T R - I|| %.3e, mean Newton iterations %.3f\n",
              r.max_relative_momentum_error, r.first_tenth_energy, r.last_tenth_energy, max_orth, r.mean_iterations);
  // As for the quaternion LGVI (tests/test_lgvi.cpp): discrete Noether to
  // rounding, energy error bounded without drift.
  EXPECT_LE(r.max_relative_momentum_error, 1e-12);
  EXPECT_LE(r.last_tenth_energy, 2.0 * r.first_tenth_energy);
  // R_{k+1} = R_k F_k: each product adds ~eps of non-orthogonality, a random
  // walk over 1e5 steps (sqrt(n) eps ~ 1e-13; a linear drift would be 2e-11).
  EXPECT_LE(max_orth, 1e-12);
  EXPECT_LE(r.mean_iterations, 1.01);
}

TEST(VariationalSo3, ResumeIsBitIdentical) { expect_bit_identical_resume<lgvi::So3LieGroupVariationalIntegrator>(); }
TEST(VariationalSo3, OnePotentialEvaluationPerStep) {
  expect_one_evaluation_per_step<lgvi::So3LieGroupVariationalIntegrator>();
}

TEST(VariationalSo3, LiftFollowsThePreviousSign) {
  const S3d q = lgvi::test::random_unit_quaternion();
  const S3d minus(-q.w(), -q.vec().x(), -q.vec().y(), -q.vec().z());
  const M3 r = q.matrix();
  using I = lgvi::So3LieGroupVariationalIntegrator<lgvi::ExternalField<lgvi::NoPotential>>;
  EXPECT_MAT_NEAR(I::lift(r, q).scalar_first(), q.scalar_first(), 8 * eps);
  EXPECT_MAT_NEAR(I::lift(r, minus).scalar_first(), minus.scalar_first(), 8 * eps);
}

TEST(VariationalSo3, RotationReachingPiFails) {
  const RigidBody body(1.0, M3(V3(1.0, 2.0, 3.0).asDiagonal()));
  lgvi::SingleBody<lgvi::So3LieGroupVariationalIntegrator, lgvi::NoPotential> integ(body, {});
  RigidBodyState s;
  s.w = 2.0 * body.inertia() * V3(400.0, 0, 0);
  EXPECT_THROW(run(integ, s, 0.01, 10), lgvi::IntegrationFailure);
}

// ==================================================== RATTLE quaternion

TEST(VariationalRattle, MomentumInR4IsConjugateToQdot) {
  // pi_q = dL/dqdot for L = 2 xi^T J xi, xi = Im(q^* qdot) = F(q) qdot: by
  // central differences of L in each of the 4 directions of qdot (L is
  // quadratic: the difference is exact up to rounding), at qdot = q (0, xi).
  const RigidBody body = asymmetric_body();
  const M3& J = body.inertia();
  const S3d q = lgvi::test::random_unit_quaternion();
  const V3 xi = lgvi::test::random_vector();
  const V4 qv = q.scalar_first();
  const V4 qdot = lgvi::rattle::FT_times(qv, xi);
  auto lagrangian = [&](const V4& v) {
    const V3 x = lgvi::rattle::F_times(qv, v);
    return 2.0 * x.dot(J * x);
  };
  V4 grad;
  for (int i = 0; i < 4; ++i) {
    const double d = 1e-3;
    const V4 e = V4::Unit(i);
    grad(i) = (lagrangian(qdot + d * e) - lagrangian(qdot - d * e)) / (2 * d);
  }
  const V3 w = 4.0 * J * xi;
  using Rattle = lgvi::RattleQuaternionIntegrator<lgvi::ExternalField<lgvi::NoPotential>>;
  const V4 pi_q = Rattle::momentum_r4(q, w);
  EXPECT_MAT_NEAR(pi_q, grad, 1e-12 * w.norm());
  EXPECT_MAT_NEAR(pi_q, (4.0 * lgvi::rattle::F_matrix(qv).transpose() * J * xi).eval(), 8 * eps * w.norm());
  EXPECT_NEAR(pi_q.dot(qv), 0.0, 8 * eps * w.norm());  // orthogonal to q
  EXPECT_MAT_NEAR(Rattle::momentum_w(q, pi_q), w, 8 * eps * w.norm());
}

TEST(VariationalRattle, JacobianMatchesFiniteDifferences) {
  const RigidBody body = lgvi::paper::three_ball_body();
  const M3& J = body.inertia();
  const V4 q0 = lgvi::test::random_unit_quaternion().scalar_first();
  const V4 q1 = lgvi::test::random_unit_quaternion().scalar_first();
  const V4 rhs = lgvi::rattle::FT_times(q0, lgvi::test::random_vector());
  const double nu = 0.3;
  const lgvi::rattle::Matrix5 jac = lgvi::rattle::jacobian(J, q0, q1);
  lgvi::rattle::Matrix5 fd;
  const double d = 1e-4;  // the system is quadratic: central differences are exact up to rounding
  for (int j = 0; j < 5; ++j) {
    lgvi::rattle::Vector5 z = lgvi::rattle::Vector5::Zero();
    z(j) = d;
    auto r = [&](double sign) {
      return lgvi::rattle::residual(J, q0, rhs, q1 + sign * z.head<4>(), nu + sign * z(4));
    };
    fd.col(j) = (r(1.0) - r(-1.0)) / (2 * d);
  }
  EXPECT_MAT_NEAR(jac, fd, 1e-10);
}

TEST(VariationalRattle, SameTrajectoryAsQuaternionLgvi) {
  // w1 = F(q1) D2 L_d takes (4/h) times the solve's residual (~4 eps |b|):
  // ~4 eps |w| per step, a larger constant than the LGVI's rotated form.
  expect_same_trajectory_as_lgvi<lgvi::RattleQuaternionIntegrator>("RATTLE", 16.0);
}

TEST(VariationalRattle, MultiplierIsTheRotationalKineticTerm) {
  // Multiplying the first RATTLE equation by q0^T: lambda = (4/h) a^T J a, a = Im(q0^* q1).
  const RigidBody body = lgvi::paper::three_ball_body();
  const double h = 0.05;
  lgvi::SingleBody<lgvi::RattleQuaternionIntegrator, CentralGravity> integ(body, CentralGravity(body, 1.0));
  RigidBodyState s0 = lgvi::paper::orbit_initial_state();
  s0.q = lgvi::test::random_unit_quaternion();
  lgvi::SystemState s(s0);
  integ.initialize(s, 0.0);
  integ.step(s, 0.0, h);
  const V3 a = (s0.q.inverse() * s.q[0]).vec();
  const double expected = (4 / h) * a.dot(body.inertia() * a);
  EXPECT_NEAR(integ.last_multiplier(0), expected, 64 * eps * expected);
}

TEST(VariationalRattle, IsSecondOrder) { expect_second_order<lgvi::RattleQuaternionIntegrator>("RATTLE quaternion"); }

TEST(VariationalRattle, InvariantsOver1e5Steps) {
  const RigidBody body = lgvi::paper::three_ball_body();
  lgvi::SingleBody<lgvi::RattleQuaternionIntegrator, CentralGravity> integ(body, CentralGravity(body, 1.0));
  const LongRun r = long_run(integ, 100000, [](const lgvi::SystemStepInfo&) {});
  std::printf("[ lgvi     ] RATTLE 1e5 steps: max rel |dL| %.3e, max |dE| first tenth %.3e, last tenth %.3e, "
              "max ||q|-1| %.3e, mean Newton iterations %.3f\n",
              r.max_relative_momentum_error, r.first_tenth_energy, r.last_tenth_energy, r.max_quat_error,
              r.mean_iterations);
  EXPECT_LE(r.max_relative_momentum_error, 1e-12);
  EXPECT_LE(r.last_tenth_energy, 2.0 * r.first_tenth_energy);
  // The constraint is imposed afresh each step: |q| - 1 is the Newton
  // residual, round-off, not accumulated.
  EXPECT_LE(r.max_quat_error, 1e-15);
  EXPECT_LE(r.mean_iterations, 1.01);
}

TEST(VariationalRattle, ResumeIsBitIdentical) { expect_bit_identical_resume<lgvi::RattleQuaternionIntegrator>(); }
TEST(VariationalRattle, OnePotentialEvaluationPerStep) {
  expect_one_evaluation_per_step<lgvi::RattleQuaternionIntegrator>();
}

TEST(VariationalRattle, RotationReachingPiFails) {
  const RigidBody body(1.0, M3(V3(1.0, 2.0, 3.0).asDiagonal()));
  lgvi::SingleBody<lgvi::RattleQuaternionIntegrator, lgvi::NoPotential> integ(body, {});
  RigidBodyState s;
  s.w = 2.0 * body.inertia() * V3(400.0, 0, 0);
  EXPECT_THROW(run(integ, s, 0.01, 10), lgvi::IntegrationFailure);
}

}  // namespace

}  // namespace test_methods_variational
