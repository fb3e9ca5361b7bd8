// The classical (non-variational) comparison methods in include/lgvi/methods:
// RK4 with renormalization, semi-implicit Euler with the exponential map,
// and the symplectic splittings NO_SQUISH (Miller et al. 2002) and DLM
// (Dullweber, Leimkuhler & McLachlan 1997). Orders against tight references,
// reversibility, long-run energy and angular momentum, cost, resume.
#include <lgvi/continuous.hpp>
#include <lgvi/integrate.hpp>
#include <lgvi/methods/euler_exp.hpp>
#include <lgvi/methods/no_squish.hpp>
#include <lgvi/methods/rk4_normalized.hpp>
#include <lgvi/methods/splitting_dlm.hpp>
#include <lgvi/paper.hpp>

#include "test_support.hpp"

#include <gmock/gmock.h>

#include <cmath>
#include <cstdio>
#include <vector>

namespace test_methods_classical {

namespace {

using lgvi::CentralGravity;
using lgvi::NoPotential;
using lgvi::RigidBody;
using lgvi::RigidBodyState;
using lgvi::S3d;
using V3 = lgvi::Vector3<double>;
using M3 = lgvi::Matrix3<double>;
constexpr double eps = 2.220446049250313e-16;
constexpr double pi = 3.14159265358979323846;

static_assert(lgvi::SystemStepper<lgvi::SingleBody<lgvi::Rk4NormalizedIntegrator, CentralGravity>>);
static_assert(lgvi::SystemStepper<lgvi::SingleBody<lgvi::EulerExpIntegrator, CentralGravity>>);
static_assert(lgvi::SystemStepper<lgvi::SingleBody<lgvi::NoSquishIntegrator, CentralGravity>>);
static_assert(lgvi::SystemStepper<lgvi::SingleBody<lgvi::SplittingDlmIntegrator, CentralGravity>>);
static_assert(lgvi::SystemStepper<lgvi::SingleBody<lgvi::Rk4NormalizedIntegrator, NoPotential>>);
static_assert(lgvi::SystemStepper<lgvi::SingleBody<lgvi::SplittingDlmIntegrator, lgvi::CallablePotential>>);

using lgvi::test::distance;
using lgvi::test::run;

// The two test problems: the paper's orbit and a free asymmetric top.
RigidBody free_body() { return RigidBody(1.0, M3(V3(1.0, 2.0, 3.0).asDiagonal())); }
RigidBodyState free_initial_state() {
  RigidBodyState s;
  s.w = 2.0 * free_body().inertia() * V3(pi / 10, pi / 6, pi / 8);
  return s;
}

template <template <class> class Integrator>
RigidBodyState run_orbit(double h, std::int64_t n, RigidBodyState s0 = lgvi::paper::orbit_initial_state()) {
  const RigidBody body = lgvi::paper::three_ball_body();
  lgvi::SingleBody<Integrator, CentralGravity> integ(body, CentralGravity(body, 1.0));
  return run(integ, s0, h, n);
}

template <template <class> class Integrator>
RigidBodyState run_free(double h, std::int64_t n, RigidBodyState s0 = free_initial_state()) {
  lgvi::SingleBody<Integrator, NoPotential> integ(free_body(), {});
  return run(integ, s0, h, n);
}

RigidBodyState orbit_reference(double t_end, double h_ref) {
  const RigidBody body = lgvi::paper::three_ball_body();
  const lgvi::ContinuousEquations<CentralGravity> eqs(body, CentralGravity(body, 1.0));
  const auto c = eqs.rk4(lgvi::to_continuous(lgvi::paper::orbit_initial_state(), body), h_ref,
                         std::lround(t_end / h_ref));
  return lgvi::from_continuous(c, body);
}

RigidBodyState free_reference(double t_end, double h_ref) {
  const RigidBody body = free_body();
  const lgvi::ContinuousEquations<NoPotential> eqs(body, {});
  const auto c = eqs.rk4(lgvi::to_continuous(free_initial_state(), body), h_ref, std::lround(t_end / h_ref));
  return lgvi::from_continuous(c, body);
}

constexpr double orbit_t = 1.0, orbit_h_ref = 2.5e-4;
constexpr double free_t = 4.0, free_h_ref = 1e-3;

TEST(ClassicalConvergence, ReferencesAreTight) {
  // RK4's error ~ C h^4, so halving h_ref changes the result by (15/16) of
  // the coarser error: a change <= 1e-13 bounds the reference error below
  // 1e-13 (and the finer one below 1e-14), far under the errors measured.
  const double d_orbit = distance(orbit_reference(orbit_t, 2 * orbit_h_ref), orbit_reference(orbit_t, orbit_h_ref));
  const double d_free = distance(free_reference(free_t, 2 * free_h_ref), free_reference(free_t, free_h_ref));
  std::printf("[ lgvi     ] reference halving: orbit %.2e, free body %.2e\n", d_orbit, d_free);
  EXPECT_LE(d_orbit, 1e-13);
  EXPECT_LE(d_free, 1e-13);
}

template <class Run>
std::vector<double> errors_by_halving(Run&& run_at, const RigidBodyState& ref, double h0, double t, int levels) {
  std::vector<double> e;
  for (int i = 0; i < levels; ++i) {
    const double h = h0 / std::pow(2.0, i);
    e.push_back(distance(run_at(h, std::lround(t / h)), ref));
  }
  return e;
}

void expect_order(const char* name, const std::vector<double>& errors, double h0, double nominal, double tol) {
  std::printf("[ lgvi     ] %s: errors", name);
  for (double e : errors) std::printf(" %.3e", e);
  std::printf(", orders");
  for (std::size_t i = 0; i + 1 < errors.size(); ++i) std::printf(" %.3f", std::log2(errors[i] / errors[i + 1]));
  std::printf("\n");
  for (std::size_t i = 0; i + 1 < errors.size(); ++i) {
    const double order = std::log2(errors[i] / errors[i + 1]);
    EXPECT_NEAR(order, nominal, tol) << name << ": h = " << h0 / std::pow(2, i) << ", errors " << errors[i] << " -> "
                                     << errors[i + 1];
  }
}

template <template <class> class Integrator>
void expect_orbit_order(const char* name, double h0, double nominal, double tol = 0.15) {
  const RigidBodyState ref = orbit_reference(orbit_t, orbit_h_ref);
  auto at = [](double h, std::int64_t n) { return run_orbit<Integrator>(h, n); };
  expect_order(name, errors_by_halving(at, ref, h0, orbit_t, 4), h0, nominal, tol);
}

template <template <class> class Integrator>
void expect_free_order(const char* name, double h0, double nominal, double tol = 0.15) {
  const RigidBodyState ref = free_reference(free_t, free_h_ref);
  auto at = [](double h, std::int64_t n) { return run_free<Integrator>(h, n); };
  expect_order(name, errors_by_halving(at, ref, h0, free_t, 4), h0, nominal, tol);
}

TEST(ClassicalConvergence, Rk4IsFourthOrderOnTheOrbit) { expect_orbit_order<lgvi::Rk4NormalizedIntegrator>("rk4 orbit", 0.2, 4.0); }
TEST(ClassicalConvergence, EulerIsFirstOrderOnTheOrbit) { expect_orbit_order<lgvi::EulerExpIntegrator>("euler orbit", 0.1, 1.0); }
TEST(ClassicalConvergence, NoSquishIsSecondOrderOnTheOrbit) { expect_orbit_order<lgvi::NoSquishIntegrator>("no-squish orbit", 0.1, 2.0); }
TEST(ClassicalConvergence, DlmIsSecondOrderOnTheOrbit) { expect_orbit_order<lgvi::SplittingDlmIntegrator>("dlm orbit", 0.1, 2.0); }
TEST(ClassicalConvergence, Rk4IsFourthOrderOnTheFreeBody) { expect_free_order<lgvi::Rk4NormalizedIntegrator>("rk4 free", 0.2, 4.0); }
TEST(ClassicalConvergence, EulerIsFirstOrderOnTheFreeBody) { expect_free_order<lgvi::EulerExpIntegrator>("euler free", 0.1, 1.0); }
TEST(ClassicalConvergence, NoSquishIsSecondOrderOnTheFreeBody) { expect_free_order<lgvi::NoSquishIntegrator>("no-squish free", 0.1, 2.0); }
TEST(ClassicalConvergence, DlmIsSecondOrderOnTheFreeBody) { expect_free_order<lgvi::SplittingDlmIntegrator>("dlm free", 0.1, 2.0); }

// ------------------------------------------------------------- reversibility

template <template <class> class Integrator>
double forward_backward(double h, std::int64_t n) {
  RigidBodyState s = run_orbit<Integrator>(h, n);
  s.p = -s.p;
  s.w = -s.w;
  s = run_orbit<Integrator>(h, n, s);
  s.p = -s.p;
  s.w = -s.w;
  return distance(s, lgvi::paper::orbit_initial_state());
}

TEST(ClassicalSymmetry, SplittingsRetraceTheirTrajectory) {
  const std::int64_t n = 1000;
  const double ns = forward_backward<lgvi::NoSquishIntegrator>(0.01, n);
  const double dlm = forward_backward<lgvi::SplittingDlmIntegrator>(0.01, n);
  std::printf("[ lgvi     ] forward-backward %lld steps of 0.01: no-squish %.2e, dlm %.2e\n",
              static_cast<long long>(n), ns, dlm);
  // Palindromic compositions of exact flows and kicks: the only error is
  // rounding, amplified by the flow (~n eps growth), as for the LGVI.
  EXPECT_LE(ns, n * 64 * eps);
  EXPECT_LE(dlm, n * 64 * eps);
}

TEST(ClassicalSymmetry, Rk4AndEulerDoNotRetraceTheirTrajectory) {
  const std::int64_t n = 100;
  const double rk4 = forward_backward<lgvi::Rk4NormalizedIntegrator>(0.1, n);
  const double euler = forward_backward<lgvi::EulerExpIntegrator>(0.1, n);
  const double dlm = forward_backward<lgvi::SplittingDlmIntegrator>(0.1, n);
  std::printf("[ lgvi     ] forward-backward %lld steps of 0.1: rk4 %.2e, euler %.2e (dlm %.2e)\n",
              static_cast<long long>(n), rk4, euler, dlm);
  // Not symmetric: the return error is the method's own error of the round
  // trip (O(h^4), O(h) over t = 20), orders of magnitude above the round-off
  // bound n 64 eps ~ 1.4e-12 that the splittings meet at the same step.
  EXPECT_LE(dlm, n * 64 * eps);
  EXPECT_GE(rk4, 1e3 * n * 64 * eps);
  EXPECT_GE(euler, 1e9 * n * 64 * eps);
}

// ------------------------------------------------------- long runs, invariants

struct LongRun {
  double first_tenth_energy = 0, last_tenth_energy = 0, final_energy = 0;
  double max_momentum_error = 0;     // |L - L0| / |L0|, L the total (spatial) angular momentum
  double max_body_momentum_error = 0;  // ||Pi| - |Pi0|| / |Pi0|
  double max_quat_error = 0;
};

template <lgvi::SystemStepper Stepper>
LongRun long_run(Stepper& integ, const RigidBody& body, const RigidBodyState& s0, double h, std::int64_t n) {
  double e0 = 0, b0 = 0;
  V3 l0;
  LongRun r;
  lgvi::SystemState s(s0);
  lgvi::integrate_n_steps(integ, s, 0.0, h, n, [&](const lgvi::SystemStepInfo& i) {
    const RigidBodyState one = i.state.body(0);
    const double e = lgvi::total_energy(one, body, i.evaluation.body(0));
    const V3 l = lgvi::angular_momentum(one);
    const double b = one.w.norm();
    if (i.k == 0) e0 = e, l0 = l, b0 = b;
    r.max_momentum_error = std::max(r.max_momentum_error, (l - l0).norm() / l0.norm());
    r.max_body_momentum_error = std::max(r.max_body_momentum_error, std::abs(b - b0) / b0);
    r.max_quat_error = std::max(r.max_quat_error, std::abs(one.q.norm_error()));
    if (i.k <= n / 10) r.first_tenth_energy = std::max(r.first_tenth_energy, std::abs(e - e0) / std::abs(e0));
    if (i.k >= n - n / 10) r.last_tenth_energy = std::max(r.last_tenth_energy, std::abs(e - e0) / std::abs(e0));
    r.final_energy = (e - e0) / std::abs(e0);
  });
  return r;
}

void print(const char* name, const LongRun& r) {
  std::printf(
      "[ lgvi     ] %s: rel |dE| max first tenth %.3e, last tenth %.3e, final %.3e; rel |dL| %.3e; rel d|Pi| %.3e; "
      "||q|-1| %.3e\n",
      name, r.first_tenth_energy, r.last_tenth_energy, r.final_energy, r.max_momentum_error,
      r.max_body_momentum_error, r.max_quat_error);
}

template <template <class> class Integrator>
LongRun orbit_long_run(const char* name) {
  const RigidBody body = lgvi::paper::three_ball_body();
  lgvi::SingleBody<Integrator, CentralGravity> integ(body, CentralGravity(body, 1.0));
  const LongRun r = long_run(integ, body, lgvi::paper::orbit_initial_state(), 0.01, 100000);
  print(name, r);
  return r;
}

template <template <class> class Integrator>
void expect_symplectic_orbit(const char* name) {
  const LongRun r = orbit_long_run<Integrator>(name);
  // 1e5 steps of 0.01 = 8 orbits: the energy error oscillates with the orbit
  // (symplectic: a modified energy is conserved to O(h^2)) without drift.
  EXPECT_LE(r.last_tenth_energy, 2.0 * r.first_tenth_energy);
  // Kicks change x cross p + pi(q) Pi by (h/2)(x cross F + pi(q) M) = 0 for the
  // central field, the drift keeps x cross p, each exact rotation keeps
  // pi(q) Pi: the total angular momentum is conserved to rounding, which
  // random-walks like the LGVI's (same bound as tests/test_lgvi.cpp).
  EXPECT_LE(r.max_momentum_error, 1e-12);
  // No normalization: |q| - 1 random-walks with the rounding of 5 rotations a step.
  EXPECT_LE(r.max_quat_error, 1e-13);
}

TEST(ClassicalLongRun, NoSquishEnergyIsBoundedAndMomentumConservedOnTheOrbit) {
  expect_symplectic_orbit<lgvi::NoSquishIntegrator>("no-squish orbit 1e5 x 0.01");
}
TEST(ClassicalLongRun, DlmEnergyIsBoundedAndMomentumConservedOnTheOrbit) {
  expect_symplectic_orbit<lgvi::SplittingDlmIntegrator>("dlm orbit 1e5 x 0.01");
}
TEST(ClassicalLongRun, Rk4AndEulerOnTheOrbit) {
  // Reported for comparison: RK4 conserves L only to its truncation error
  // (~7e-10 here, growing), Euler not at all (its energy grows by orders of
  // magnitude: the explicit gyroscopic term).
  const LongRun rk4 = orbit_long_run<lgvi::Rk4NormalizedIntegrator>("rk4 orbit 1e5 x 0.01");
  const LongRun euler = orbit_long_run<lgvi::EulerExpIntegrator>("euler orbit 1e5 x 0.01");
  EXPECT_GE(rk4.max_momentum_error, 1e-12);
  EXPECT_GE(euler.max_momentum_error, 1e-6);
}

template <template <class> class Integrator>
LongRun free_long_run(const char* name, double h, std::int64_t n) {
  const RigidBody body = free_body();
  lgvi::SingleBody<Integrator, NoPotential> integ(body, {});
  const LongRun r = long_run(integ, body, free_initial_state(), h, n);
  print(name, r);
  return r;
}

TEST(ClassicalLongRun, SplittingsOnTheFreeBody) {
  // h = 0.2 (|Omega0| h ~ 0.13 rad), 1e5 steps: ~2000 periods of the top.
  for (const LongRun& r : {free_long_run<lgvi::NoSquishIntegrator>("no-squish free 1e5 x 0.2", 0.2, 100000),
                           free_long_run<lgvi::SplittingDlmIntegrator>("dlm free 1e5 x 0.2", 0.2, 100000)}) {
    EXPECT_LE(r.last_tenth_energy, 2.0 * r.first_tenth_energy);
    // Each sub-step is an exact rotation: |Pi| and pi(q) Pi are conserved up
    // to the rounding of ~5 rotations a step, a random walk: sqrt(1e5) * 5 *
    // a few eps ~ 1e-12.
    EXPECT_LE(r.max_body_momentum_error, 1e-12);
    EXPECT_LE(r.max_momentum_error, 1e-12);
  }
}

TEST(ClassicalLongRun, Rk4EnergyDriftsOnTheFreeBodyWithALargeStep) {
  // The same run: RK4's energy error has a secular part (its truncation
  // error is not a modified Hamiltonian's), so the last tenth's error is far
  // above the first tenth's; the splittings above stay bounded.
  const LongRun r = free_long_run<lgvi::Rk4NormalizedIntegrator>("rk4 free 1e5 x 0.2", 0.2, 100000);
  EXPECT_GE(r.last_tenth_energy, 5.0 * r.first_tenth_energy);
}

TEST(ClassicalLongRun, EulerEnergyGrowsOnTheFreeBody) {
  // The explicit gyroscopic term Pi x Omega pumps energy every step: with
  // h = 0.2 the energy grows without bound and the state overflows at step
  // ~459 (t ~ 92). Over the first 400 steps the growth is already manifest.
  const LongRun e = free_long_run<lgvi::EulerExpIntegrator>("euler free 400 x 0.2", 0.2, 400);
  EXPECT_GE(e.last_tenth_energy, 5.0 * e.first_tenth_energy);
  lgvi::SingleBody<lgvi::EulerExpIntegrator, NoPotential> integ(free_body(), {});
  EXPECT_THROW(run(integ, free_initial_state(), 0.2, 1000), lgvi::IntegrationFailure);
}

// ------------------------------------------------------------ cost, resume, input

TEST(ClassicalCost, PotentialEvaluationsPerStep) {
  const RigidBody body = lgvi::paper::three_ball_body();
  const CentralGravity gravity(body, 1.0);
  long calls = 0;
  const lgvi::CallablePotential counting([&](const V3& x, const S3d& q) {
    ++calls;
    return gravity.evaluate(x, q);
  });
  auto count = [&](auto integ) {
    calls = 0;
    run(integ, lgvi::paper::orbit_initial_state(), 0.01, 500);
    return calls;
  };
  EXPECT_EQ(count(lgvi::SingleBody<lgvi::Rk4NormalizedIntegrator, lgvi::CallablePotential>(body, counting)), 4 * 500 + 1);
  EXPECT_EQ(count(lgvi::SingleBody<lgvi::EulerExpIntegrator, lgvi::CallablePotential>(body, counting)), 500 + 1);
  EXPECT_EQ(count(lgvi::SingleBody<lgvi::NoSquishIntegrator, lgvi::CallablePotential>(body, counting)), 500 + 1);
  EXPECT_EQ(count(lgvi::SingleBody<lgvi::SplittingDlmIntegrator, lgvi::CallablePotential>(body, counting)), 500 + 1);
}

template <template <class> class Integrator>
void expect_bit_identical_resume() {
  const RigidBody body = lgvi::paper::three_ball_body();
  using Stepper = lgvi::SingleBody<Integrator, CentralGravity>;
  const double h = 0.01;
  Stepper a(body, CentralGravity(body, 1.0));
  lgvi::SystemState whole(lgvi::paper::orbit_initial_state());
  lgvi::integrate_n_steps(a, whole, 0.0, h, 200, [](const lgvi::SystemStepInfo&) {});
  Stepper b(body, CentralGravity(body, 1.0));
  lgvi::SystemState half(lgvi::paper::orbit_initial_state());
  lgvi::integrate_n_steps(b, half, 0.0, h, 100, [](const lgvi::SystemStepInfo&) {});
  const std::vector<double> internal = b.internal_state();
  EXPECT_TRUE(internal.empty());
  Stepper c(body, CentralGravity(body, 1.0));
  c.resume(half, 100 * h, internal);
  lgvi::integrate_range(c, half, 0.0, h, 100, 200, [](const lgvi::SystemStepInfo&) {});
  EXPECT_EQ(distance(whole.body(0), half.body(0)), 0.0);
  EXPECT_THROW(c.resume(half, 200 * h, {1.0}), lgvi::InvalidInput);
}

TEST(ClassicalResume, BitIdentical) {
  expect_bit_identical_resume<lgvi::Rk4NormalizedIntegrator>();
  expect_bit_identical_resume<lgvi::EulerExpIntegrator>();
  expect_bit_identical_resume<lgvi::NoSquishIntegrator>();
  expect_bit_identical_resume<lgvi::SplittingDlmIntegrator>();
}

TEST(ClassicalInput, SplittingsNeedPrincipalAxes) {
  M3 j = M3(V3(1.0, 2.0, 3.0).asDiagonal());
  j(0, 1) = j(1, 0) = 0.1;
  const RigidBody tilted(1.0, j);
  EXPECT_THROW((lgvi::SingleBody<lgvi::NoSquishIntegrator, NoPotential>(tilted, {})), lgvi::InvalidInput);
  EXPECT_THROW((lgvi::SingleBody<lgvi::SplittingDlmIntegrator, NoPotential>(tilted, {})), lgvi::InvalidInput);
  // The explicit general methods accept it.
  EXPECT_NO_THROW((lgvi::SingleBody<lgvi::Rk4NormalizedIntegrator, NoPotential>(tilted, {})));
  EXPECT_NO_THROW((lgvi::SingleBody<lgvi::EulerExpIntegrator, NoPotential>(tilted, {})));
  // Rounding-level off-diagonal entries (a computed inertia) are accepted.
  M3 k = M3(V3(1.0, 2.0, 3.0).asDiagonal());
  k(0, 2) = k(2, 0) = 1e-17;
  EXPECT_NO_THROW((lgvi::SingleBody<lgvi::SplittingDlmIntegrator, NoPotential>(RigidBody(1.0, k), {})));
}

TEST(ClassicalInput, InvalidStepAndNonFiniteStateFail) {
  const RigidBody point(1.0, M3::Identity());
  // The step comes with each call: the run loop refuses a bad one for every method.
  lgvi::SingleBody<lgvi::Rk4NormalizedIntegrator, NoPotential> rk4(point, {});
  lgvi::SingleBody<lgvi::EulerExpIntegrator, NoPotential> euler(point, {});
  lgvi::SingleBody<lgvi::NoSquishIntegrator, NoPotential> no_squish(point, {});
  lgvi::SingleBody<lgvi::SplittingDlmIntegrator, NoPotential> dlm(point, {});
  EXPECT_THROW(run(rk4, RigidBodyState{}, 0.0, 1), lgvi::InvalidInput);
  EXPECT_THROW(run(euler, RigidBodyState{}, -1.0, 1), lgvi::InvalidInput);
  EXPECT_THROW(run(no_squish, RigidBodyState{}, std::nan(""), 1), lgvi::InvalidInput);
  EXPECT_THROW(run(dlm, RigidBodyState{}, 0.0, 1), lgvi::InvalidInput);
  RigidBodyState s;  // x = 0: at the field's centre, V = -inf
  lgvi::SingleBody<lgvi::Rk4NormalizedIntegrator, CentralGravity> a(point, CentralGravity(point, 1.0));
  EXPECT_THROW(run(a, s, 0.01, 1), lgvi::IntegrationFailure);
  lgvi::SingleBody<lgvi::NoSquishIntegrator, CentralGravity> b(point, CentralGravity(point, 1.0));
  EXPECT_THROW(run(b, s, 0.01, 1), lgvi::IntegrationFailure);
  // A finite start whose step overflows: a huge force.
  RigidBodyState far = s;
  far.x = V3(1e-300, 0, 0);
  lgvi::SingleBody<lgvi::SplittingDlmIntegrator, CentralGravity> c(point, CentralGravity(point, 1.0));
  EXPECT_THROW(run(c, far, 0.01, 1), lgvi::IntegrationFailure);
  lgvi::SingleBody<lgvi::EulerExpIntegrator, CentralGravity> d(point, CentralGravity(point, 1.0));
  EXPECT_THROW(run(d, far, 0.01, 1), lgvi::IntegrationFailure);
}

}  // namespace

}  // namespace test_methods_classical
