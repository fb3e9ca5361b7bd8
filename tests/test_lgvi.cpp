// The quaternion LGVI (lgvi.hpp): convergence order against a tight solution
// of the continuous equations, an exact discrete solution, the paper's
// invariants over 1e5 steps, and equivalences between forms and solvers.
#include <lgvi/continuous.hpp>
#include <lgvi/integrate.hpp>
#include <lgvi/paper.hpp>

#include "test_support.hpp"

#include <gmock/gmock.h>

#include <cmath>
#include <vector>

namespace test_lgvi {

namespace {

using lgvi::CentralGravity;
using lgvi::RigidBody;
using lgvi::RigidBodyState;
using lgvi::S3d;
using V3 = lgvi::Vector3<double>;
using M3 = lgvi::Matrix3<double>;
constexpr double eps = 2.220446049250313e-16;

using lgvi::test::distance;
using lgvi::test::LongRun;
using lgvi::test::run;

template <template <class> class Integrator>
RigidBodyState run_paper(double h, std::int64_t n, lgvi::SolverKind kind = lgvi::SolverKind::Newton,
                         RigidBodyState s0 = lgvi::paper::orbit_initial_state()) {
  const RigidBody body = lgvi::paper::three_ball_body();
  lgvi::SolverOptions opt;
  opt.kind = kind;
  lgvi::SingleBody<Integrator, CentralGravity> integ(body, CentralGravity(body, 1.0), opt);
  return run(integ, s0, h, n);
}

// ---------------------------------------------------------------- convergence

RigidBodyState reference_solution(double t_end, double h_ref) {
  const RigidBody body = lgvi::paper::three_ball_body();
  const lgvi::ContinuousEquations<CentralGravity> eqs(body, CentralGravity(body, 1.0));
  const auto c = eqs.rk4(lgvi::to_continuous(lgvi::paper::orbit_initial_state(), body), h_ref,
                         std::lround(t_end / h_ref));
  return lgvi::from_continuous(c, body);
}

TEST(Convergence, ReferenceSolutionIsTight) {
  // RK4's error ~ C h^4: halving h_ref = 1e-3 must change the result by
  // ~ (15/16) C h^4; we need the reference ~1e-12 from the truth to measure
  // LGVI errors down to 1e-6 with 6 digits.
  const double d = distance(reference_solution(1.0, 1e-3), reference_solution(1.0, 5e-4));
  EXPECT_LE(d, 1e-12);
}

template <template <class> class Integrator>
void expect_second_order() {
  const RigidBodyState ref = reference_solution(1.0, 5e-4);
  std::vector<double> errors;
  for (double h : {0.1, 0.05, 0.025, 0.0125}) {
    const RigidBodyState s = run_paper<Integrator>(h, std::lround(1.0 / h));
    errors.push_back(distance(s, ref));
  }
  for (std::size_t i = 0; i + 1 < errors.size(); ++i) {
    const double order = std::log2(errors[i] / errors[i + 1]);
    // Second order: the error ratio on halving h is 4 up to O(h) corrections
    // of the asymptotic regime (|order - 2| <= 0.1 from h = 0.1 down).
    EXPECT_NEAR(order, 2.0, 0.1) << "h = " << 0.1 / std::pow(2, i) << ", errors " << errors[i] << " -> "
                                 << errors[i + 1];
  }
}

TEST(Convergence, HamiltonianFormIsSecondOrder) { expect_second_order<lgvi::LieGroupVariationalIntegrator>(); }
TEST(Convergence, LagrangianFormIsSecondOrder) {
  expect_second_order<lgvi::LagrangianLieGroupVariationalIntegrator>();
}

// ---------------------------------------------------------- exact discrete flow

TEST(ExactSolution, SpinAboutAPrincipalAxisAdvancesByArcsinPerStep) {
  // Free body spinning about the principal axis e3 with rate Omega: the
  // discrete equation g(f) = (h/4) w with f_v || e3 reduces to
  // sin(theta) cos(theta) J3 = h J3 Omega / 2, so each step rotates by
  // 2 theta = asin(h Omega) (exactly, against h Omega for the continuous flow).
  const RigidBody body(2.0, M3(V3(1.0, 2.0, 3.0).asDiagonal()));
  const double h = 0.1, omega = 5.0;
  lgvi::SingleBody<lgvi::LieGroupVariationalIntegrator, lgvi::NoPotential> integ(body, {});
  RigidBodyState s;
  s.w = 2.0 * body.inertia() * V3(0, 0, omega);
  const std::int64_t n = 1000;
  s = run(integ, s, h, n);
  const double angle = static_cast<double>(n) * std::asin(h * omega);
  // Rounding accumulates over n steps like n eps in the angle.
  EXPECT_MAT_NEAR(s.q.scalar_first(), S3d::exp(V3(0, 0, angle / 2)).scalar_first(), 4 * n * eps);
  EXPECT_MAT_NEAR(s.w, (2.0 * body.inertia() * V3(0, 0, omega)).eval(), 8 * eps * s.w.norm());
}

// -------------------------------------------------- the paper's promises, 1e5 steps

LongRun long_run(lgvi::SolverKind kind) {
  const RigidBody body = lgvi::paper::three_ball_body();
  lgvi::SolverOptions opt;
  opt.kind = kind;
  lgvi::SingleBody<lgvi::LieGroupVariationalIntegrator, CentralGravity> integ(body, CentralGravity(body, 1.0), opt);
  return lgvi::test::paper_orbit_long_run(integ, 0.01, 100000, [](const lgvi::SystemStepInfo&) {});
}

class PaperOrbit : public ::testing::TestWithParam<lgvi::SolverKind> {};

TEST_P(PaperOrbit, InvariantsOver1e5Steps) {
  const LongRun r = long_run(GetParam());
  std::printf("[ lgvi     ] %s: max rel |dL| %.3e, max ||q|-1| %.3e, max |dE| first tenth %.3e, last tenth %.3e\n",
              lgvi::to_string(GetParam()), r.max_relative_momentum_error, r.max_quat_error, r.first_tenth_energy,
              r.last_tenth_energy);
  // Discrete Noether: each step conserves L up to the rounding of O(100) flops
  // on numbers of size |L|; 1e5 steps of a random walk of a few eps give ~1e-13.
  EXPECT_LE(r.max_relative_momentum_error, 1e-12);
  // |q| - 1 changes by the rounding of one quaternion product per step.
  EXPECT_LE(r.max_quat_error, 1e-13);
  // Symplectic: the energy error oscillates with the orbit without drift.
  EXPECT_LE(r.last_tenth_energy, 2.0 * r.first_tenth_energy);
  EXPECT_EQ(r.final_t, 100000 * 0.01);  // t = t0 + k h, not accumulated
  // The cubic predictor (RotationPredictor) starts each solve ~1e-10 from the
  // root on this smooth orbit: one Newton (or Broyden) update reaches round-off.
  EXPECT_LE(r.mean_iterations, 1.01);
}

INSTANTIATE_TEST_SUITE_P(Solvers, PaperOrbit, ::testing::Values(lgvi::SolverKind::Newton, lgvi::SolverKind::Broyden),
                         [](const auto& info) { return std::string(lgvi::to_string(info.param)); });

TEST(LagrangianForm, InvariantsOver1e5Steps) {
  // The position-position form keeps the same promises as the Hamiltonian
  // one, with the same bounds and reasons (above): its positions advance by
  // the summed increment d and its rotations by the solved f (lgvi.hpp). The
  // recurrence written as x2 = 2 x1 - x0 + (h^2/m) F1 with f0 = q0^* q1
  // recomputed from the attitudes rounded at the size of x and q each step,
  // 1/h times that in the implied velocities: 1.5e-10 here.
  const RigidBody body = lgvi::paper::three_ball_body();
  lgvi::SingleBody<lgvi::LagrangianLieGroupVariationalIntegrator, CentralGravity> integ(body, CentralGravity(body, 1.0));
  const LongRun r = lgvi::test::paper_orbit_long_run(integ, 0.01, 100000, [](const lgvi::SystemStepInfo&) {});
  std::printf("[ lgvi     ] lagrangian: max rel |dL| %.3e, max ||q|-1| %.3e, max |dE| first tenth %.3e, last tenth %.3e\n",
              r.max_relative_momentum_error, r.max_quat_error, r.first_tenth_energy, r.last_tenth_energy);
  EXPECT_LE(r.max_relative_momentum_error, 1e-12);
  EXPECT_LE(r.max_quat_error, 1e-13);
  EXPECT_LE(r.last_tenth_energy, 2.0 * r.first_tenth_energy);
  EXPECT_EQ(r.final_t, 100000 * 0.01);
}

/// The Lagrangian form on the paper's orbit checkpointed after 300 steps: the
/// state and internals there, and the state 300 steps further.
struct LagrangianCheckpoint {
  RigidBodyState saved, continued;
  std::vector<double> internal;
};
using LagrangianOnTheOrbit = lgvi::SingleBody<lgvi::LagrangianLieGroupVariationalIntegrator, CentralGravity>;
constexpr double lagrangian_h = 0.01;

LagrangianCheckpoint lagrangian_checkpoint() {
  const RigidBody body = lgvi::paper::three_ball_body();
  LagrangianOnTheOrbit a(body, CentralGravity(body, 1.0));
  LagrangianCheckpoint c;
  c.saved = run(a, lgvi::paper::orbit_initial_state(), lagrangian_h, 300);
  c.internal = a.internal_state();
  lgvi::SystemState s(c.saved);
  for (int k = 300; k < 600; ++k) a.step(s, k * lagrangian_h, lagrangian_h);
  c.continued = s.body(0);
  return c;
}

/// A fresh stepper resumed at `saved` with `internal`, 300 steps on.
RigidBodyState resume_lagrangian(RigidBodyState saved, const std::vector<double>& internal) {
  const RigidBody body = lgvi::paper::three_ball_body();
  LagrangianOnTheOrbit b(body, CentralGravity(body, 1.0));
  lgvi::SystemState s(saved);
  b.resume(s, 300 * lagrangian_h, internal);
  for (int k = 300; k < 600; ++k) b.step(s, k * lagrangian_h, lagrangian_h);
  return s.body(0);
}

TEST(LagrangianForm, ResumeIsBitIdentical) {
  // The checkpoint holds the configuration ahead, the increment d, the
  // relative rotation f, the predictor and the positions' carry: everything
  // the next step reads besides the reported state.
  const LagrangianCheckpoint c = lagrangian_checkpoint();
  const RigidBodyState t = resume_lagrangian(c.saved, c.internal);
  EXPECT_EQ(distance(c.continued, t), 0.0);
  EXPECT_EQ(c.continued.q.scalar_first(), t.q.scalar_first());
}

TEST(LagrangianForm, ResumesACheckpointWrittenBeforeTheSummedForm) {
  // Such a checkpoint holds per body x_next and q_next (7 numbers) before the
  // predictor, then a zero carry (or none). Resumed, d = x_next - x and
  // f = q^* q_next are recomputed as the old form did every step: d is off
  // by the rounding of x (|x| eps ~ 8 eps on this orbit, relative
  // 8 eps / |d| ~ 5e-13 with |d| ~ 0.0033), f_v by ~eps, which w = (4/h) G(f)
  // J f_v + ... turns into (4/h) |J| eps ~ 1e-13. Over 300 steps of an orbit
  // whose errors grow at most linearly, the positions drift by at most
  // 300 * 8 eps ~ 5e-13 from the uninterrupted run (measured: 3.8e-14); it
  // is not bit-identical (the arithmetic changed).
  const LagrangianCheckpoint c = lagrangian_checkpoint();
  // Today's layout: 14 numbers (x_next, q_next, d, f), the predictor, the carry (3).
  const auto predictor = static_cast<std::ptrdiff_t>(c.internal.size() - 14 - 3);
  for (const bool with_carry : {true, false}) {
    std::vector<double> old(c.internal.begin(), c.internal.begin() + 7);
    old.insert(old.end(), c.internal.begin() + 14, c.internal.begin() + 14 + predictor);
    if (with_carry) old.insert(old.end(), 3, 0.0);
    const RigidBodyState t = resume_lagrangian(c.saved, old);
    std::printf("[ lgvi     ] old checkpoint (%s carry): 300 steps later %.3e from the uninterrupted run\n",
                with_carry ? "with" : "without", distance(c.continued, t));
    EXPECT_LE(distance(c.continued, t), 300 * 8 * eps);
  }
  // Any other size is refused.
  EXPECT_THROW(resume_lagrangian(c.saved, std::vector<double>(c.internal.begin(), c.internal.end() - 1)),
               lgvi::InvalidInput);
}

// ------------------------------------------------------------ equivalences

TEST(Equivalence, SolversGiveTheSameTrajectory) {
  // Each step's root agrees to ~eps between solvers; the differences then
  // grow with the flow's sensitivity (~ linear in t on this orbit).
  const RigidBodyState a = run_paper<lgvi::LieGroupVariationalIntegrator>(0.01, 1000, lgvi::SolverKind::Newton);
  const RigidBodyState b = run_paper<lgvi::LieGroupVariationalIntegrator>(0.01, 1000, lgvi::SolverKind::NewtonExp);
  const RigidBodyState c = run_paper<lgvi::LieGroupVariationalIntegrator>(0.01, 1000, lgvi::SolverKind::Broyden);
  std::printf("[ lgvi     ] 1000 steps: |newton - newton-exp| %.2e, |newton - broyden| %.2e\n", distance(a, b),
              distance(a, c));
  EXPECT_LE(distance(a, b), 1000 * 16 * eps);
  EXPECT_LE(distance(a, c), 1000 * 16 * eps);
}

TEST(Equivalence, LagrangianAndHamiltonianFormsGiveTheSameTrajectory) {
  // In summed form (lgvi.hpp) the position-position form takes the same
  // increments as the Hamiltonian form in another order of operations (p_k
  // from the increment d, w_k from the solved f rather than rotated), and
  // its solves stop at another residual: the forms agree to a few eps per
  // step, as the solvers do (above; measured 1.2e-13 over 1000 steps). The
  // recurrence 2 x1 - x0 + ... with p_k = m (x_k - x_{k-1})/h paid the
  // cancellation |x| / |x_k - x_{k-1}| ~ 2.4e3 per step instead.
  const RigidBodyState a = run_paper<lgvi::LieGroupVariationalIntegrator>(0.01, 1000);
  const RigidBodyState b = run_paper<lgvi::LagrangianLieGroupVariationalIntegrator>(0.01, 1000);
  std::printf("[ lgvi     ] 1000 steps: |hamiltonian - lagrangian| %.2e\n", distance(a, b));
  EXPECT_LE(distance(a, b), 1000 * 16 * eps);
}

TEST(Equivalence, RotatedFormOfW1EqualsThePapersFormula) {
  // One step: w1 as computed (pi(f)^T (w0 + h M0) + h M1) against the paper's
  // w1 = (4/h) G(q0^* q1) J Im(q0^* q1) - (h/2) F(q1) dV/dq(x1, q1).
  const RigidBody body = lgvi::paper::three_ball_body();
  const CentralGravity pot(body, 1.0);
  const double h = 0.01;
  lgvi::SingleBody<lgvi::LieGroupVariationalIntegrator, CentralGravity> integ(body, pot);
  RigidBodyState s0 = lgvi::paper::orbit_initial_state();
  s0.q = lgvi::test::random_unit_quaternion();
  lgvi::SystemState state(s0);
  integ.initialize(state, 0.0);
  integ.step(state, 0.0, h);
  const RigidBodyState s = state.body(0);
  const lgvi::PotentialEvaluation e1 = integ.evaluation().body(0);
  const Eigen::Quaterniond f = s0.q.quaternion().conjugate() * s.q.quaternion();
  const V3 w1_paper = (4 / h) * lgvi::G(f) * body.inertia() * f.vec() - (h / 2) * lgvi::seed_torque_term(e1.torque);
  // Equal on the solution; the literal form's (4/h) amplifies the rounding of f.
  EXPECT_MAT_NEAR(s.w, w1_paper, 4 / h * 16 * eps * body.inertia().norm());
  // And p1 against m (x1 - x0)/h + (h/2) F1 (cancellation: |x|/|dx| ~ 2.4e3).
  const V3 p1_paper = body.mass() * (s.x - s0.x) / h + (h / 2) * e1.force;
  EXPECT_MAT_NEAR(s.p, p1_paper, 4096 * eps);
}

TEST(Symmetry, ReversingMomentaRetracesTheTrajectory) {
  // L_d(q0, q1) = L_d(q1, q0): the method is symmetric, so flipping (p, w)
  // and stepping n times again returns to the start, up to rounding
  // amplified by the flow (~n eps growth).
  const std::int64_t n = 1000;
  RigidBodyState s = run_paper<lgvi::LieGroupVariationalIntegrator>(0.01, n);
  s.p = -s.p;
  s.w = -s.w;
  s = run_paper<lgvi::LieGroupVariationalIntegrator>(0.01, n, lgvi::SolverKind::Newton, s);
  s.p = -s.p;
  s.w = -s.w;
  const RigidBodyState s0 = lgvi::paper::orbit_initial_state();
  std::printf("[ lgvi     ] forward-backward %lld steps: %.2e\n", static_cast<long long>(n), distance(s, s0));
  EXPECT_LE(distance(s, s0), n * 64 * eps);
}

TEST(Projection, LiftAndProjectAreInverse) {
  const RigidBody body = lgvi::paper::three_ball_body();
  lgvi::RotationMatrixState r{V3(1, 2, 3), lgvi::test::random_unit_quaternion().matrix(), V3(0.1, 0.2, 0.3),
                              V3(-1, 0.5, 2)};
  const RigidBodyState s = lgvi::lift(r, body);
  EXPECT_MAT_NEAR(s.w, (2.0 * body.inertia() * r.omega).eval(), 0.0);
  const lgvi::RotationMatrixState back = lgvi::project(s, body);
  EXPECT_MAT_NEAR(back.R, r.R, 16 * eps);
  EXPECT_MAT_NEAR(back.xdot, r.xdot, 4 * eps);
  EXPECT_MAT_NEAR(back.omega, r.omega, 16 * eps);
}

// ------------------------------------------------------------------ failures

TEST(Failure, RotationReachingPiStopsTheRunAtThatStep) {
  const RigidBody body(1.0, M3(V3(1.0, 2.0, 3.0).asDiagonal()));
  lgvi::SingleBody<lgvi::LieGroupVariationalIntegrator, lgvi::NoPotential> integ(body, {});
  RigidBodyState b;
  b.w = 2.0 * body.inertia() * V3(400.0, 0, 0);  // |Omega| h = 4 rad > pi
  lgvi::SystemState s(b);
  std::int64_t observed = -1;
  try {
    lgvi::integrate_n_steps(integ, s, 0.0, 0.01, 10, [&](const lgvi::SystemStepInfo& i) { observed = i.k; });
    FAIL() << "expected an IntegrationFailure";
  } catch (const lgvi::IntegrationFailure& e) {
    EXPECT_EQ(e.step(), 0);
    EXPECT_EQ(observed, 0);  // the initial state was seen, nothing after it
    EXPECT_THAT(e.what(), ::testing::HasSubstr("smaller step"));
  }
}

TEST(Failure, BodyAtTheCentreOfTheFieldIsNonFinite) {
  const RigidBody point(1.0, M3::Identity());
  lgvi::SingleBody<lgvi::LieGroupVariationalIntegrator, CentralGravity> integ(point, CentralGravity(point, 1.0));
  RigidBodyState s;  // x = 0: V = -inf
  EXPECT_THROW(run(integ, s, 0.01, 1), lgvi::IntegrationFailure);
}

TEST(Failure, InvalidStepIsRejected) {
  const RigidBody point(1.0, M3::Identity());
  // The step size comes with each call: the run loop refuses a bad one before any step.
  lgvi::SingleBody<lgvi::LieGroupVariationalIntegrator, lgvi::NoPotential> integ(point, {});
  EXPECT_THROW(run(integ, RigidBodyState{}, 0.0, 1), lgvi::InvalidInput);
  EXPECT_THROW(run(integ, RigidBodyState{}, -0.01, 1), lgvi::InvalidInput);
  EXPECT_THROW(run(integ, RigidBodyState{}, std::nan(""), 1), lgvi::InvalidInput);
}

}  // namespace

namespace {

TEST(Cost, OnePotentialEvaluationPerStep) {
  // The force and torque at the new point serve the next step: n steps cost
  // n + 1 evaluations (the +1 at initialize), for both forms.
  const RigidBody body = lgvi::paper::three_ball_body();
  const CentralGravity gravity(body, 1.0);
  long calls = 0;
  const lgvi::CallablePotential counting([&](const V3& x, const S3d& q) {
    ++calls;
    return gravity.evaluate(x, q);
  });
  lgvi::SingleBody<lgvi::LieGroupVariationalIntegrator, lgvi::CallablePotential> ham(body, counting);
  run(ham, lgvi::paper::orbit_initial_state(), 0.01, 500);
  EXPECT_EQ(calls, 501);
  calls = 0;
  lgvi::SingleBody<lgvi::LagrangianLieGroupVariationalIntegrator, lgvi::CallablePotential> lag(body, counting);
  run(lag, lgvi::paper::orbit_initial_state(), 0.01, 500);
  EXPECT_EQ(calls, 501);
}

}  // namespace

namespace {

TEST(HeavyTop, VerticalAngularMomentumIsConservedToRoundOff) {
  // V = -m g . (R chi) is invariant under rotations about g: discrete Noether
  // conserves L . g/|g| (the full L changes under gravity's torque).
  const RigidBody body(1.0, M3(V3(0.35, 0.35, 0.05).asDiagonal()));
  const lgvi::HeavyTop top(body, V3(0, 0, -9.81), V3(0, 0, 0.5));
  lgvi::SingleBody<lgvi::LieGroupVariationalIntegrator, lgvi::HeavyTop> integ(body, top);
  RigidBodyState b;
  b.q = S3d::exp(V3(0.15, 0, 0));
  b.w = 2.0 * body.inertia() * V3(0, 0, 50);
  const double lz0 = lgvi::angular_momentum(b).z(), scale = lgvi::angular_momentum(b).norm();
  double max_dlz = 0, max_dl = 0, e0 = 0, max_de = 0;
  lgvi::SystemState s(b);
  lgvi::integrate_n_steps(integ, s, 0.0, 0.001, 20000, [&](const lgvi::SystemStepInfo& i) {
    const V3 l = lgvi::angular_momentum(i.state.body(0));
    const double e = lgvi::total_energy(i.state.body(0), body, i.evaluation.body(0));
    if (i.k == 0) e0 = e;
    max_dlz = std::max(max_dlz, std::abs(l.z() - lz0));
    max_dl = std::max(max_dl, std::abs(l.norm() - scale));
    max_de = std::max(max_de, std::abs(e - e0));
  });
  std::printf("[ lgvi     ] heavy top 2e4 steps: |dLz|/|L| %.2e, max ||L|-|L0||/|L| %.2e, max |dE| %.2e\n",
              max_dlz / scale, max_dl / scale, max_de);
  EXPECT_LE(max_dlz / scale, 1e-12);  // round-off random walk over 2e4 steps
  EXPECT_GT(max_dl / scale, 1e-3);    // the rest of L precesses: the test can tell
}

}  // namespace

}  // namespace test_lgvi
