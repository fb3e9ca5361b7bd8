// The adaptive (time-transformed) LGVI (time_transformed.hpp): a fixed step of
// the LGVI's order when the monitor is 1, second order in the fictitious step
// (fourth when composed) through the paper's close pass against a tight
// solution of the continuous equations, exact reversibility, the drift's
// kinetic energy, and the paper's radial orbit, its bound orbit and a close
// binary against the fixed step with as many evaluations.
#include <lgvi/continuous.hpp>
#include <lgvi/interaction.hpp>
#include <lgvi/lgvi.hpp>
#include <lgvi/mutual_gravity.hpp>
#include <lgvi/paper.hpp>
#include <lgvi/time_transformed.hpp>

#include "test_support.hpp"

#include <gmock/gmock.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

namespace test_time_transformed {

namespace {

using lgvi::CentralGravity;
using lgvi::RigidBody;
using lgvi::RigidBodyState;
using lgvi::System;
using lgvi::SystemState;
using V3 = lgvi::Vector3<double>;
using Field = lgvi::ExternalField<CentralGravity>;
using Adaptive = lgvi::TimeTransformedLieGroupVariationalIntegrator<Field>;
constexpr double eps = 2.220446049250313e-16;

Field paper_field() {
  const RigidBody body = lgvi::paper::three_ball_body();
  return Field({CentralGravity(body, 1.0)});
}

Adaptive paper_stepper(double c, const lgvi::CompositionTable& composition = {},
                       double finish_time = std::numeric_limits<double>::infinity()) {
  return Adaptive(System(lgvi::paper::three_ball_body()), paper_field(), lgvi::TimeTransformOptions{c, finish_time},
                  {}, {}, composition);
}

/// A system potential that counts its evaluations (the cost measure).
template <lgvi::SystemPotential P>
struct Counted {
  P inner;
  std::int64_t* count;
  void evaluate(const SystemState& s, lgvi::SystemEvaluation& e) {
    ++*count;
    inner.evaluate(s, e);
  }
};

/// What a run records: the extremes of the invariants' errors along it.
struct RunRecord {
  std::int64_t steps = 0;
  double max_energy_error = 0.0, max_norm_error = 0.0, max_momentum_error = 0.0;
  double min_dt = 1e300, max_dt = 0.0;
};

/// E = K + V of a state whose evaluation the stepper holds.
template <class S>
double energy(const S& stepper, const SystemState& s) {
  return lgvi::total_energy(s, stepper.system(), stepper.evaluation());
}

/// Steps `stepper` (initialized at s, time t0) until its time reaches t_end
/// (the first step that reaches it is the last): the largest |E - E0|, ||q| - 1|
/// over the bodies and |L - L0| / |L0| along the way.
template <class S>
RunRecord run_until(S& stepper, SystemState& s, double t_end, double epsilon) {
  RunRecord r;
  const double e0 = energy(stepper, s);
  const V3 l0 = lgvi::angular_momentum(s);
  while (stepper.time() < t_end) {
    stepper.step(s, 0.0, epsilon);
    ++r.steps;
    r.max_energy_error = std::max(r.max_energy_error, std::abs(energy(stepper, s) - e0));
    for (const lgvi::S3d& q : s.q) r.max_norm_error = std::max(r.max_norm_error, std::abs(q.norm_error()));
    r.max_momentum_error = std::max(r.max_momentum_error, (lgvi::angular_momentum(s) - l0).norm() / l0.norm());
    r.min_dt = std::min(r.min_dt, stepper.last_time_step());
    r.max_dt = std::max(r.max_dt, stepper.last_time_step());
  }
  return r;
}

/// The fixed-step LGVI's largest |E - E0| over n steps of size h from s.
template <class Potential>
double fixed_step_energy_error(const System& sys, Potential pot, SystemState s, double h, std::int64_t n) {
  lgvi::LieGroupVariationalIntegrator<Potential> fixed(sys, std::move(pot));
  fixed.initialize(s, 0.0);
  const double e0 = energy(fixed, s);
  double worst = 0.0;
  for (std::int64_t k = 0; k < n; ++k) {
    fixed.step(s, static_cast<double>(k) * h, h);
    worst = std::max(worst, std::abs(energy(fixed, s) - e0));
  }
  return worst;
}

TEST(TimeTransformed, WithAUnitMonitorItIsAFixedStepOfTheLgvisOrder) {
  // c = 1e100: (u/c)^4 rounds away and g = 1 exactly: the step is a fixed
  // step eps (the time advances by eps/2 + eps/2 exactly), the Strang
  // splitting drift-kick-drift of the LGVI's pieces. It and the fixed-step
  // LGVI (kick-drift-kick) are both second order: their difference at t = 10
  // falls by 4 per halving of the step (ratios within [3.8, 4.2]).
  std::vector<double> differences;
  for (const double h : {0.02, 0.01, 0.005}) {
    SystemState a(lgvi::paper::orbit_initial_state()), b = a;
    Adaptive adaptive = paper_stepper(1e100);
    lgvi::LieGroupVariationalIntegrator<Field> fixed(System(lgvi::paper::three_ball_body()), paper_field());
    adaptive.initialize(a, 0.0);
    fixed.initialize(b, 0.0);
    const auto n = std::lround(10.0 / h);
    for (long k = 0; k < n; ++k) {
      adaptive.step(a, 0.0, h);
      EXPECT_EQ(adaptive.last_time_step(), h);
      fixed.step(b, static_cast<double>(k) * h, h);
    }
    EXPECT_NEAR(adaptive.time(), 10.0, 4 * eps * 10.0);  // a compensated sum of n steps h
    differences.push_back(lgvi::test::distance(a.body(0), b.body(0)));
  }
  EXPECT_THAT(differences[0] / differences[1], ::testing::AllOf(::testing::Gt(3.8), ::testing::Lt(4.2)));
  EXPECT_THAT(differences[1] / differences[2], ::testing::AllOf(::testing::Gt(3.8), ::testing::Lt(4.2)));
}

TEST(TimeTransformed, TheMonitorIsOneFarAndTheDynamicalTimeNear) {
  // g(0) = 1; g(u) -> (c/u)^(3/2) for u >> c (the local dynamical time ~ d^(3/2)
  // of a point mass, u ~ 1/d); g(c) = 2^(-3/8).
  EXPECT_EQ(lgvi::time_transform_monitor(0.0, 0.4), 1.0);
  EXPECT_NEAR(lgvi::time_transform_monitor(0.4, 0.4), std::pow(2.0, -0.375), 4 * eps);
  const double u = 4e3;
  EXPECT_NEAR(lgvi::time_transform_monitor(u, 0.4) / std::pow(0.4 / u, 1.5), 1.0, 1e-12);  // (1 + r^-4)^(-3/8), r = 1e4
}

TEST(TimeTransformed, TheDriftKeepsTheKineticEnergy) {
  // No potential: every step is a drift at g(K - E0) = g(0) = 1, the LGVI's
  // free step, which keeps w^T J^-1 w exactly in exact arithmetic; here 1000
  // steps of a fast tumbling body keep K to a few hundred ulps.
  using Free = lgvi::ExternalField<lgvi::NoPotential>;
  const RigidBody body = lgvi::paper::three_ball_body();
  lgvi::TimeTransformedLieGroupVariationalIntegrator<Free> stepper(System(body), Free::uniform(lgvi::NoPotential{}, 1),
                                                                  lgvi::TimeTransformOptions{1.0});
  SystemState s(lgvi::paper::orbit_initial_state());
  s.w[0] = V3(3.0, -7.0, 11.0);
  stepper.initialize(s, 0.0);
  const double k0 = lgvi::kinetic_energy(s, stepper.system());
  double worst = 0.0;
  for (int k = 0; k < 1000; ++k) {
    stepper.step(s, 0.0, 0.05);
    worst = std::max(worst, std::abs(lgvi::kinetic_energy(s, stepper.system()) - k0));
    EXPECT_EQ(stepper.last_time_step(), 0.05);  // g(K - E0) = g(0) = 1
  }
  EXPECT_LT(worst, 1e3 * eps * k0);
  std::printf("[ lgvi     ] free drifts: |K - K0| <= %.2g eps K0 over 1000 steps\n", worst / (eps * k0));
}

TEST(TimeTransformed, ThePapersRadialOrbitThroughItsClosePass) {
  // The paper's literal p0 = (1, 0, 0): the balls pass close to the centre at
  // t ~ 108. The plain step at eps = 0.02 reproduces the issue's prototype:
  // 76 693 steps, max |E - E0| 6.4e-5 over [0, 1000] (bounds here, not values:
  // past the pass the motion depends on round-off), |q| - 1 <= 1e-12, relative
  // Delta L <= 1e-10. Each step evaluates twice (the kick's midpoint, the new
  // state's energy): 1.5e5 evaluations; the composed step below meets the
  // issue's 1e5. The fixed step with as many evaluations (twice the steps)
  // misses the energy by order 1 (4.8), with as many steps by 54.
  Adaptive stepper = paper_stepper(0.4);
  SystemState s(lgvi::paper::radial_initial_state());
  stepper.initialize(s, 0.0);
  const RunRecord r = run_until(stepper, s, 1000.0, 0.02);
  EXPECT_LE(r.steps, 100000);
  EXPECT_LT(r.max_energy_error, 1e-4);
  EXPECT_LT(r.max_norm_error, 1e-12);
  EXPECT_LT(r.max_momentum_error, 1e-10);
  EXPECT_LT(r.min_dt, 1e-3 * r.max_dt);  // the step did adapt, by more than 10^3
  const double fixed = fixed_step_energy_error(System(lgvi::paper::three_ball_body()), paper_field(),
                                               SystemState(lgvi::paper::radial_initial_state()),
                                               500.0 / static_cast<double>(r.steps), 2 * r.steps);
  EXPECT_GT(fixed, 1e4 * r.max_energy_error);
  std::printf("[ lgvi     ] radial: %lld steps, max |E - E0| %.3g (fixed step, as many evaluations: %.3g), "
              "||q| - 1| %.2g, dL/|L0| %.2g, dt in [%.3g, %.3g]\n",
              static_cast<long long>(r.steps), r.max_energy_error, fixed, r.max_norm_error, r.max_momentum_error,
              r.min_dt, r.max_dt);
}

TEST(TimeTransformed, ComposedToOrderFourItMeetsTheIssuesBoundInEvaluations) {
  // The issue's bound for the radial run: max |E - E0| <= 1e-4 over [0, 1000]
  // with at most 1e5 potential evaluations, every one counted (Suzuki's
  // five-stage fourth-order composition at eps = 0.1: five midpoint
  // evaluations and one at the new state per step); |q| - 1 <= 1e-12,
  // relative Delta L <= 1e-10.
  std::int64_t count = 0;
  lgvi::TimeTransformedLieGroupVariationalIntegrator<Counted<Field>> stepper(
      System(lgvi::paper::three_ball_body()), Counted<Field>{paper_field(), &count}, lgvi::TimeTransformOptions{0.4},
      {}, {}, lgvi::CompositionTable::of_order(4));
  SystemState s(lgvi::paper::radial_initial_state());
  stepper.initialize(s, 0.0);
  const RunRecord r = run_until(stepper, s, 1000.0, 0.1);
  EXPECT_EQ(count, 6 * r.steps + 1);
  EXPECT_LE(count, 100000);
  EXPECT_LT(r.max_energy_error, 1e-4);
  EXPECT_LT(r.max_norm_error, 1e-12);
  EXPECT_LT(r.max_momentum_error, 1e-10);
  std::printf("[ lgvi     ] radial, order 4: %lld steps, %lld evaluations, max |E - E0| %.3g, ||q| - 1| %.2g, "
              "dL/|L0| %.2g\n",
              static_cast<long long>(r.steps), static_cast<long long>(count), r.max_energy_error, r.max_norm_error,
              r.max_momentum_error);
}

TEST(TimeTransformed, TheBoundOrbitHasNoDriftAndBeatsTheFixedStepAtEqualCost) {
  // p0 = (0, 1, 0): eccentric bound orbit, period ~121. Over [0, 10^4] (83
  // periods) the largest |E - E0| over the last tenth is no larger than over
  // the first tenth (bounded, no drift: a drift would grow it ~10x). At equal
  // evaluations the plain step only matches the fixed step here (3.46e-7
  // against 3.48e-7: the orbit's pericentre, 1.2 from the centre, is not close);
  // composed to order 4 it is far below it.
  Adaptive stepper = paper_stepper(0.4);
  SystemState s(lgvi::paper::orbit_initial_state());
  stepper.initialize(s, 0.0);
  const RunRecord first = run_until(stepper, s, 1000.0, 0.02);
  run_until(stepper, s, 9000.0, 0.02);
  RunRecord last;
  {
    const double e0 = stepper.reference_energy();
    while (stepper.time() < 10000.0) {
      stepper.step(s, 0.0, 0.02);
      ++last.steps;
      last.max_energy_error = std::max(last.max_energy_error, std::abs(energy(stepper, s) - e0));
    }
  }
  EXPECT_LT(last.max_energy_error, 1.5 * first.max_energy_error);
  Adaptive composed = paper_stepper(0.4, lgvi::CompositionTable::of_order(4));
  SystemState c(lgvi::paper::orbit_initial_state());
  composed.initialize(c, 0.0);
  const RunRecord four = run_until(composed, c, 1000.0, 0.1);
  const std::int64_t evaluations = 6 * four.steps + 1;  // five midpoints and the new state per step
  const double fixed = fixed_step_energy_error(System(lgvi::paper::three_ball_body()), paper_field(),
                                               SystemState(lgvi::paper::orbit_initial_state()),
                                               1000.0 / static_cast<double>(evaluations), evaluations);
  EXPECT_LT(four.max_energy_error, 0.1 * fixed);
  std::printf("[ lgvi     ] bound orbit: max |E - E0| on [0, 1000] %.3g, on [9000, 10000] %.3g; order 4 at %lld "
              "evaluations %.3g (fixed step, as many evaluations, %.3g)\n",
              first.max_energy_error, last.max_energy_error, static_cast<long long>(evaluations),
              four.max_energy_error, fixed);
}

// ------------------------------------------------- against the continuous equations

/// The continuous equations (continuous.hpp) in the fictitious time of the
/// same transformation (ContinuousEquations::rk4_time_transformed, with this
/// c): the time the method discretizes, smooth through the close pass.
struct Reference {
  RigidBody body = lgvi::paper::three_ball_body();
  CentralGravity potential{body, 1.0};
  lgvi::ContinuousEquations<CentralGravity> eqs{body, potential};
  double c = 0.4;

  /// The state at time t_end from `start` at t0, with RK4 steps ds in the fictitious time.
  RigidBodyState at(const RigidBodyState& start, double t0, double t_end, double ds) const {
    return lgvi::from_continuous(eqs.rk4_time_transformed(lgvi::to_continuous(start, body), t0, t_end, ds,
                                                          [&](double u) { return lgvi::time_transform_monitor(u, c); }),
                                 body);
  }
};

TEST(TimeTransformed, SecondOrderThroughTheClosestPassAgainstTheContinuousEquations) {
  // From a tight reference state at t = 100, through the pass (closest at
  // t ~ 108) to the first step past t = 109, at eps = 0.02, 0.01, 0.005; each
  // compared with the reference at the time it reached. Second order: the
  // error falls by 4 per halving (ratios within [3.6, 4.4]: the eps^3 terms at
  // these steps). The reference's own error, measured by halving its ds, is
  // below 1e-3 of the smallest error it judges.
  const Reference ref;
  const double ds = 2.5e-4;
  const RigidBodyState start = ref.at(lgvi::paper::radial_initial_state(), 0.0, 100.0, ds);
  std::vector<double> errors;
  double reference_error = 0.0;
  for (const double epsilon : {0.02, 0.01, 0.005}) {
    Adaptive stepper = paper_stepper(0.4);
    SystemState s(start);
    stepper.initialize(s, 100.0);
    const RunRecord r = run_until(stepper, s, 109.0, epsilon);
    const double t = stepper.time();
    errors.push_back(lgvi::test::distance(s.body(0), ref.at(start, 100.0, t, ds)));
    reference_error = std::max(reference_error, lgvi::test::distance(ref.at(start, 100.0, t, ds),
                                                                     ref.at(start, 100.0, t, ds / 2)));
    EXPECT_LT(r.min_dt, 1e-3);  // the pass was resolved with small steps
  }
  std::printf("[ lgvi     ] through the pass: errors %.3g %.3g %.3g, ratios %.3f %.3f, reference %.2g\n", errors[0],
              errors[1], errors[2], errors[0] / errors[1], errors[1] / errors[2], reference_error);
  EXPECT_LT(reference_error, 1e-3 * errors[2]);
  EXPECT_THAT(errors[0] / errors[1], ::testing::AllOf(::testing::Gt(3.6), ::testing::Lt(4.4)));
  EXPECT_THAT(errors[1] / errors[2], ::testing::AllOf(::testing::Gt(3.6), ::testing::Lt(4.4)));
  // Composed to order 4 (Suzuki's five stages): errors fall by 16 per halving
  // (ratios within [14, 18]), each still 1e3 times the reference's own error.
  std::vector<double> composed;
  for (const double epsilon : {0.08, 0.04, 0.02}) {
    Adaptive stepper = paper_stepper(0.4, lgvi::CompositionTable::of_order(4));
    SystemState s(start);
    stepper.initialize(s, 100.0);
    run_until(stepper, s, 109.0, epsilon);
    composed.push_back(lgvi::test::distance(s.body(0), ref.at(start, 100.0, stepper.time(), ds)));
  }
  std::printf("[ lgvi     ] through the pass, order 4: errors %.3g %.3g %.3g, ratios %.3f %.3f\n", composed[0],
              composed[1], composed[2], composed[0] / composed[1], composed[1] / composed[2]);
  EXPECT_LT(1e3 * reference_error, composed[2]);
  EXPECT_THAT(composed[0] / composed[1], ::testing::AllOf(::testing::Gt(14.0), ::testing::Lt(18.0)));
  EXPECT_THAT(composed[1] / composed[2], ::testing::AllOf(::testing::Gt(14.0), ::testing::Lt(18.0)));
}

TEST(TimeTransformed, FinishTimeEndsTheRunThereAtTheMethodsOrder) {
  // With a finish time, the step that would pass it is retaken shorter: the
  // run ends at t = 109 exactly (within the pass's aftermath, where the step is
  // still small), and its state there against the reference at 109 keeps the
  // method's order: errors fall by 4 per halving of eps (ratios in [3.6, 4.4],
  // as the test above), and by 16 composed to order 4 (ratios in [14, 18]):
  // one shortened step of the same method adds an error of the same order.
  const Reference ref;
  const double ds = 2.5e-4, t_end = 109.0;
  const RigidBodyState start = ref.at(lgvi::paper::radial_initial_state(), 0.0, 100.0, ds);
  const RigidBodyState exact = ref.at(start, 100.0, t_end, ds);
  const auto errors = [&](const lgvi::CompositionTable& composition, std::initializer_list<double> epsilons) {
    std::vector<double> e;
    for (const double epsilon : epsilons) {
      Adaptive stepper = paper_stepper(0.4, composition, t_end);
      SystemState s(start);
      stepper.initialize(s, 100.0);
      const RunRecord r = run_until(stepper, s, t_end, epsilon);
      EXPECT_EQ(stepper.time(), t_end);  // exactly: the last step was fitted to end there
      EXPECT_LT(stepper.last_time_step(), r.max_dt);
      // |q| = 1 and L are kept by the shortened step as by every other: |q| - 1
      // random-walks by a few eps per step, ~sqrt(n) few eps over these n < 10^4
      // steps, below 1e-13.
      EXPECT_LT(r.max_norm_error, 1e-13);
      EXPECT_LT(r.max_momentum_error, 1e-12);
      e.push_back(lgvi::test::distance(s.body(0), exact));
    }
    return e;
  };
  const std::vector<double> plain = errors({}, {0.02, 0.01, 0.005});
  const std::vector<double> four = errors(lgvi::CompositionTable::of_order(4), {0.08, 0.04, 0.02});
  std::printf("[ lgvi     ] finishing at t = 109: errors %.3g %.3g %.3g (ratios %.3f %.3f); order 4: %.3g %.3g %.3g "
              "(ratios %.3f %.3f)\n",
              plain[0], plain[1], plain[2], plain[0] / plain[1], plain[1] / plain[2], four[0], four[1], four[2],
              four[0] / four[1], four[1] / four[2]);
  EXPECT_THAT(plain[0] / plain[1], ::testing::AllOf(::testing::Gt(3.6), ::testing::Lt(4.4)));
  EXPECT_THAT(plain[1] / plain[2], ::testing::AllOf(::testing::Gt(3.6), ::testing::Lt(4.4)));
  EXPECT_THAT(four[0] / four[1], ::testing::AllOf(::testing::Gt(14.0), ::testing::Lt(18.0)));
  EXPECT_THAT(four[1] / four[2], ::testing::AllOf(::testing::Gt(14.0), ::testing::Lt(18.0)));
}

TEST(TimeTransformed, FinishTimeLeavesEveryEarlierStepAsItWas) {
  // The steps before the last are the same with or without a finish time,
  // bit for bit (only a step that can reach it keeps a copy of its start).
  const double t_end = 30.0;
  Adaptive free_running = paper_stepper(0.4), finishing = paper_stepper(0.4, {}, t_end);
  SystemState a(lgvi::paper::radial_initial_state()), b(lgvi::paper::radial_initial_state());
  free_running.initialize(a, 0.0);
  finishing.initialize(b, 0.0);
  std::int64_t steps = 0;
  while (finishing.time() < t_end) {
    free_running.step(a, 0.0, 0.02);
    finishing.step(b, 0.0, 0.02);
    ++steps;
    if (free_running.time() > t_end) {
      EXPECT_EQ(finishing.time(), t_end);
      EXPECT_LT(finishing.last_time_step(), free_running.last_time_step());
      break;
    }
    ASSERT_EQ(a.x[0], b.x[0]) << "step " << steps;
    ASSERT_EQ(a.p[0], b.p[0]) << "step " << steps;
    ASSERT_EQ(a.w[0], b.w[0]) << "step " << steps;
    ASSERT_EQ(a.q[0].w(), b.q[0].w()) << "step " << steps;
    ASSERT_EQ(a.q[0].vec(), b.q[0].vec()) << "step " << steps;
    ASSERT_EQ(free_running.time(), finishing.time()) << "step " << steps;
  }
  EXPECT_EQ(finishing.time(), t_end);
}

TEST(TimeTransformed, IsReversible) {
  // Forward n steps, flip p and w, n steps more: back at the start with flipped
  // momenta (the step is symmetric and each piece is reversible), here through
  // the close pass; to round-off amplified by the pass (its Lyapunov growth
  // over the ~6000 steps), bounded by 1e-9 of the state's size.
  Adaptive stepper = paper_stepper(0.4);
  SystemState s(lgvi::paper::radial_initial_state());
  const SystemState start = s;
  stepper.initialize(s, 0.0);
  const RunRecord forward = run_until(stepper, s, 112.0, 0.02);
  s.p[0] = -s.p[0];
  s.w[0] = -s.w[0];
  Adaptive back = paper_stepper(0.4);
  back.initialize(s, 0.0);
  back.set_reference_energy(stepper.reference_energy());  // the same Gamma (K + V there differs by the energy error)
  for (std::int64_t k = 0; k < forward.steps; ++k) back.step(s, 0.0, 0.02);
  EXPECT_NEAR(back.time(), stepper.time(), 1e-9 * stepper.time());
  const double scale = 8.0;
  EXPECT_LT((s.x[0] - start.x[0]).norm(), 1e-9 * scale);
  EXPECT_LT((s.p[0] + start.p[0]).norm(), 1e-9 * scale);
  EXPECT_LT((s.w[0] + start.w[0]).norm(), 1e-9 * scale);
  EXPECT_LT((s.q[0].scalar_first() - start.q[0].scalar_first()).norm(), 1e-9);
  std::printf("[ lgvi     ] reversed through the pass: |x - x0| %.2g, |p + p0| %.2g\n", (s.x[0] - start.x[0]).norm(),
              (s.p[0] + start.p[0]).norm());
}

TEST(TimeTransformed, ACloseBinaryKeepsItsAngularMomentumAndBeatsTheFixedStep) {
  // Two of the paper's bodies under mutual gravity (balls), on an eccentric
  // mutual orbit (e ~ 0.67 for the centres: periapsis ~1.6, apoapsis 8, period
  // ~20), over [0, 60]: three periapses, the centres 1.3 to 1.6 apart, balls
  // of the two bodies closer than their size (tides spin the bodies up; later
  // periapses come closer until they touch, near t ~ 80). Every substep
  // keeps the total angular momentum (the kicks by a rotation-invariant
  // potential, the drifts body by body): to round-off. With as many
  // evaluations as the fixed step (twice its steps: the adaptive step
  // evaluates at the midpoint and at the new state) the plain step's energy
  // error is 9 times below the fixed step's (5.5e-7 against 4.8e-6); composed
  // to order 4, with as many evaluations again, far below.
  const RigidBody body = lgvi::paper::three_ball_body();
  const System sys({body, body});
  using Pair = lgvi::Coupled<lgvi::ExternalField<lgvi::NoPotential>, lgvi::MutualGravityBalls>;
  auto potential = [&] {
    return Pair(lgvi::ExternalField<lgvi::NoPotential>::uniform(lgvi::NoPotential{}, 2), lgvi::MutualGravityBalls(sys, 1.0));
  };
  SystemState s0(2);
  s0.x = {V3(-4.0, 0.0, 0.0), V3(4.0, 0.0, 0.0)};
  s0.q = {lgvi::S3d(), lgvi::S3d(Eigen::Quaterniond(Eigen::AngleAxisd(1.0, V3(1, 2, 3).normalized())))};
  s0.p = {V3(0.0, -0.75, 0.0), V3(0.0, 0.75, 0.0)};
  s0.w = {V3(0.3, -0.2, 0.5), V3(-0.1, 0.4, 0.2)};
  lgvi::TimeTransformedLieGroupVariationalIntegrator<Pair> stepper(sys, potential(), lgvi::TimeTransformOptions{});
  SystemState s = s0;
  stepper.initialize(s, 0.0);
  const double e0 = energy(stepper, s);
  const V3 l0 = lgvi::angular_momentum(s);
  double worst_energy = 0.0, worst_momentum = 0.0, closest = 1e300;
  std::int64_t steps = 0;
  while (stepper.time() < 60.0) {
    stepper.step(s, 0.0, 0.01);
    ++steps;
    worst_energy = std::max(worst_energy, std::abs(energy(stepper, s) - e0));
    worst_momentum = std::max(worst_momentum, (lgvi::angular_momentum(s) - l0).norm());
    closest = std::min(closest, (s.x[0] - s.x[1]).norm());
  }
  const double fixed = fixed_step_energy_error(sys, potential(), s0, 60.0 / static_cast<double>(steps), steps);
  const double fixed_twice = fixed_step_energy_error(sys, potential(), s0, 30.0 / static_cast<double>(steps), 2 * steps);
  std::printf("[ lgvi     ] binary: %lld steps, closest centres %.3g, max |E - E0| %.3g (fixed, as many steps %.3g, "
              "twice as many %.3g), |dL| %.2g of |L0| %.3g\n",
              static_cast<long long>(steps), closest, worst_energy, fixed, fixed_twice, worst_momentum, l0.norm());
  EXPECT_LT(closest, 1.5);  // the periapses were close
  EXPECT_LT(worst_momentum, 1e3 * eps * l0.norm());
  EXPECT_LT(worst_energy, 0.5 * fixed_twice);
  lgvi::TimeTransformedLieGroupVariationalIntegrator<Pair> composed(sys, potential(), lgvi::TimeTransformOptions{}, {},
                                                                    {}, lgvi::CompositionTable::of_order(4));
  s = s0;
  composed.initialize(s, 0.0);
  const RunRecord four = run_until(composed, s, 60.0, 0.04);
  const std::int64_t evaluations = 6 * four.steps + 1;
  const double fixed_equal = fixed_step_energy_error(sys, potential(), s0, 60.0 / static_cast<double>(evaluations),
                                                     evaluations);
  std::printf("[ lgvi     ] binary, order 4: %lld evaluations, max |E - E0| %.3g (fixed step, as many evaluations, "
              "%.3g), |dL|/|L0| %.2g\n",
              static_cast<long long>(evaluations), four.max_energy_error, fixed_equal, four.max_momentum_error);
  EXPECT_LT(four.max_momentum_error, 1e3 * eps);
  EXPECT_LT(four.max_energy_error, 1e-2 * fixed_equal);
}

}  // namespace

}  // namespace test_time_transformed
