// Forcing by the discrete Lagrange-d'Alembert principle (forcing.hpp): the
// discrete momentum balance to round-off, exact solutions of forced
// problems (a damped spherical body, a constant inertial torque, a PD slew
// of a spherical body), a zero-order-hold controller against a hand
// computation, the work bookkeeping E - E0 - W (second order), composition
// to order 4, resume, and failure of a too stiff velocity-dependent forcing.
#include "io/memory_sink.hpp"
#include "app/scenario.hpp"
#include "app/simulation.hpp"
#include "test_support.hpp"

#include <lgvi/composition.hpp>
#include <lgvi/forcing.hpp>
#include <lgvi/integrate.hpp>
#include <lgvi/interaction.hpp>
#include <lgvi/lgvi.hpp>
#include <lgvi/methods/so3_lgvi.hpp>
#include <lgvi/potential.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <limits>
#include <numbers>
#include <vector>

namespace test_forcing {

namespace {

using lgvi::AppliedForce;
using lgvi::AppliedTorque;
using lgvi::AttitudeControl;
using lgvi::Damping;
using lgvi::ForcingFrame;
using lgvi::ForcingSet;
using lgvi::Profile;
using lgvi::RigidBody;
using lgvi::S3d;
using lgvi::System;
using lgvi::SystemState;
using lgvi::SystemStepInfo;
using V3 = lgvi::Vector3<double>;

constexpr double eps = std::numeric_limits<double>::epsilon();

using Free = lgvi::ExternalField<lgvi::NoPotential>;
using Central = lgvi::ExternalField<lgvi::CentralGravity>;

Free free_field(std::size_t n) { return Free::uniform(lgvi::NoPotential{}, n); }

/// A triaxial body (the paper's triangle of balls would do; any J works).
RigidBody triaxial() { return RigidBody(1.0, lgvi::Vector3<double>(0.5, 0.8, 1.1).asDiagonal().toDenseMatrix()); }
RigidBody sphere(double j) { return RigidBody(2.0, (j * lgvi::Matrix3<double>::Identity()).eval()); }

SystemState one_body(const V3& x, const S3d& q, const V3& p, const V3& w) {
  SystemState s(1);
  s.x[0] = x;
  s.q[0] = q;
  s.p[0] = p;
  s.w[0] = w;
  return s;
}

/// Runs n steps of h and calls f(info) at every step (k = 0 included).
template <class Stepper>
SystemState run(Stepper& stepper, SystemState s, double h, std::int64_t n,
                const std::function<void(const SystemStepInfo&)>& f = [](const SystemStepInfo&) {}) {
  lgvi::integrate_n_steps(stepper, s, 0.0, h, n, f);
  return s;
}

/// A forcing that uses every kind at once on a triaxial body: a tabulated
/// inertial force, a tabulated body torque, a constant inertial torque,
/// linear and angular damping.
ForcingSet mixed_forcing() {
  ForcingSet f;
  f.add(AppliedForce{Profile::table({0.0, 1.0, 2.0}, {V3(0.1, 0, 0), V3(0, 0.2, 0), V3(0, 0, -0.3)}),
                     ForcingFrame::Inertial});
  f.add(AppliedTorque{Profile::table({0.0, 2.0}, {V3(0.05, 0, 0.02), V3(-0.05, 0.1, 0)}), ForcingFrame::Body});
  f.add(AppliedTorque{Profile::constant(V3(0.0, 0.03, 0.01)), ForcingFrame::Inertial});
  f.add(Damping{0.07, 0.04});
  return f;
}

// P_{k+1} - P_k = (h/2)(F_k + F_{k+1}) and L_{k+1} - L_k = (h/2)(tau_k + tau_{k+1}),
// tau = x cross F + R M, step by step, recomputing F and M from the states
// (the forcing's own formulas, evaluated independently here). Free body:
// no potential force. Round-off: each step's sums are of numbers of size
// |p| ~ 1, so a few eps per step; the momenta's fixed point is converged
// to 4 eps, so F_{k+1} from the state differs by ~eps from the one the
// step used.
TEST(Forcing, DiscreteMomentumBalanceToRoundOff) {
  const System sys(triaxial());
  ForcingSet forcing = mixed_forcing();
  lgvi::LieGroupVariationalIntegrator<Free> lgvi(sys, free_field(1));
  lgvi.set_forcing(forcing);
  const double h = 0.01;
  SystemState prev = one_body(V3(1, 2, 3), lgvi::test::random_unit_quaternion(), V3(0.3, -0.2, 0.1), V3(0.4, 1.0, -0.7));
  std::vector<V3> F, M;
  auto wrench = [&](double t, const SystemState& s, V3& force, V3& tau) {
    forcing.evaluate(t, s, sys, F, M);
    force = F[0];
    tau = s.x[0].cross(F[0]) + s.q[0].act(M[0]);
  };
  double worst_p = 0.0, worst_l = 0.0;
  run(lgvi, prev, h, 200, [&](const SystemStepInfo& i) {
    if (i.k > 0) {
      V3 f0, t0, f1, t1;
      wrench(i.t - h, prev, f0, t0);
      wrench(i.t, i.state, f1, t1);
      const V3 dp = (i.state.p[0] - prev.p[0]) - 0.5 * h * (f0 + f1);
      const V3 dl = (lgvi::angular_momentum(i.state) - lgvi::angular_momentum(prev)) - 0.5 * h * (t0 + t1);
      worst_p = std::max(worst_p, dp.norm());
      worst_l = std::max(worst_l, dl.norm());
    }
    prev = i.state;
  });
  // |p| ~ 0.4, |L| ~ |x||p| ~ 1.5: differences of such numbers are exact to
  // a few ulps, 1e-15 is ~5 ulps of |L|.
  EXPECT_LT(worst_p, 20 * eps) << worst_p;
  EXPECT_LT(worst_l, 1e-14) << worst_l;
}

// A constant inertial torque tau on a spinning triaxial body in a central
// field: the field conserves L, so L(t) = L0 + tau t, to round-off that
// grows like sqrt(k) eps |L| (random-walk of rounding) - 1e-13 relative
// after 2000 steps leaves ample room (sqrt(2000) eps ~ 1e-14).
TEST(Forcing, ConstantInertialTorqueGivesLinearMomentumGrowth) {
  const System sys(triaxial());
  lgvi::LieGroupVariationalIntegrator<Central> lgvi(
      sys, Central::uniform(lgvi::CentralGravity(sys.body(0), 1.0), 1));
  ForcingSet f;
  const V3 tau(0.02, -0.01, 0.015);
  f.add(AppliedTorque{Profile::constant(tau), ForcingFrame::Inertial});
  lgvi.set_forcing(f);
  const SystemState s0 = one_body(V3(3, 0, 0), lgvi::test::random_unit_quaternion(), V3(0, 0.55, 0.1), V3(0.3, 0.9, 1.4));
  const V3 l0 = lgvi::angular_momentum(s0);
  const double h = 0.01;
  double worst = 0.0;
  run(lgvi, s0, h, 2000, [&](const SystemStepInfo& i) {
    worst = std::max(worst, (lgvi::angular_momentum(i.state) - (l0 + i.t * tau)).norm());
  });
  EXPECT_LT(worst, 1e-13 * (l0.norm() + 20 * tau.norm())) << worst;
}

/// Omega(T) of a damped spherical body (J = j I, torque -c Omega) with step h:
/// exact Omega(t) = Omega0 exp(-c t / j).
template <class Stepper>
double damped_sphere_error(Stepper&& stepper, double h, double T) {
  const double j = 0.7, c = 0.3;
  const V3 omega0(0.4, -1.1, 0.8);
  const SystemState s0 = one_body(V3::Zero(), S3d(), V3::Zero(), 2.0 * j * omega0);
  const auto n = static_cast<std::int64_t>(std::llround(T / h));
  const SystemState s = run(stepper, s0, h, n);
  const V3 omega = s.w[0] / (2.0 * j);
  return (omega - omega0 * std::exp(-c * T / j)).norm();
}

ForcingSet damping(double c) {
  ForcingSet f;
  f.add(Damping{c, 0.0});
  return f;
}

template <class Stepper>
Stepper with_forcing(Stepper s, const ForcingSet& f) {
  s.set_forcing(f);
  return s;
}

// Second order: halving h divides the error by 4 (observed order within
// 0.1 of 2 on these step sizes, where the error is ~1e-5 and far above
// round-off); composed to order 4 (Suzuki), by 16 (within 0.2).
TEST(Forcing, DampedSphereDecaysExponentiallyAtSecondOrderAndComposes) {
  const System sys(sphere(0.7));
  auto make = [&] { return with_forcing(lgvi::LieGroupVariationalIntegrator<Free>(sys, free_field(1)), damping(0.3)); };
  const double e1 = damped_sphere_error(make(), 0.05, 3.0), e2 = damped_sphere_error(make(), 0.025, 3.0);
  EXPECT_NEAR(std::log2(e1 / e2), 2.0, 0.1) << e1 << " " << e2;
  EXPECT_LT(e1, 1e-3);
  auto composed = [&] { return lgvi::ComposedStepper(make(), lgvi::CompositionTable::of_order(4)); };
  const double c1 = damped_sphere_error(composed(), 0.1, 3.0), c2 = damped_sphere_error(composed(), 0.05, 3.0);
  EXPECT_NEAR(std::log2(c1 / c2), 4.0, 0.2) << c1 << " " << c2;
  // The rotation-matrix LGVI takes the same forcing.
  auto so3 = [&] { return with_forcing(lgvi::So3LieGroupVariationalIntegrator<Free>(sys, free_field(1)), damping(0.3)); };
  const double r1 = damped_sphere_error(so3(), 0.05, 3.0), r2 = damped_sphere_error(so3(), 0.025, 3.0);
  EXPECT_NEAR(std::log2(r1 / r2), 2.0, 0.1) << r1 << " " << r2;
}

/// max over the run of |E - E0 - W| for the mixed forcing on a triaxial
/// body in a central field (the work W from the stepper).
double energy_balance_error(double h, double T) {
  const System sys(triaxial());
  lgvi::LieGroupVariationalIntegrator<Central> lgvi(sys, Central::uniform(lgvi::CentralGravity(sys.body(0), 1.0), 1));
  lgvi.set_forcing(mixed_forcing());
  const SystemState s0 = one_body(V3(3, 0, 0), S3d(), V3(0, 0.55, 0.1), V3(0.3, 0.9, 1.4));
  double e0 = 0.0, worst = 0.0;
  run(lgvi, s0, h, static_cast<std::int64_t>(std::llround(T / h)), [&](const SystemStepInfo& i) {
    const double e = lgvi::total_energy(i.state, sys, i.evaluation);
    if (i.k == 0) e0 = e;
    worst = std::max(worst, std::abs(e - e0 - i.work));
  });
  return worst;
}

// E - E0 - W with the trapezoidal work is the integrator's own error:
// second order (the work done is O(1) here, 0.3 of the initial energy,
// and the balance error 1e-5 with h = 0.02).
TEST(Forcing, EnergyMinusWorkIsSecondOrder) {
  const double e1 = energy_balance_error(0.02, 2.0), e2 = energy_balance_error(0.01, 2.0);
  EXPECT_NEAR(std::log2(e1 / e2), 2.0, 0.15) << e1 << " " << e2;
}

/// The angle of the rotation q_target^* q.
double error_angle(const S3d& target, const S3d& q) {
  const S3d e = target.inverse() * q;
  return 2.0 * std::atan2(e.vec().norm(), std::abs(e.w()));
}

// A PD slew of a spherical body by 0.01 rad about z, from rest: for small
// angles j theta'' + k_d theta' + (k_p/2) theta = 0 (forcing.hpp), an
// underdamped oscillator with the solution below. Tolerance: the
// nonlinearity sin(theta/2) ~ theta/2 (1 - theta^2/24) is a relative 4e-6
// and the step's truncation h^2 |theta''''| ~ 1e-7 relative.
TEST(Forcing, AttitudeControlSlewFollowsThePredictedDamping) {
  const double j = 0.5, kp = 2.0, kd = 0.3, theta0 = 0.01;
  const System sys(sphere(j));
  lgvi::LieGroupVariationalIntegrator<Free> lgvi(sys, free_field(1));
  ForcingSet f;
  f.add(AttitudeControl{S3d(), kp, kd});
  lgvi.set_forcing(f);
  const S3d q0 = S3d::exp(V3(0, 0, 0.5 * theta0));
  const double zeta = kd / (2.0 * j), w0sq = kp / (2.0 * j), wd = std::sqrt(w0sq - zeta * zeta);
  double worst = 0.0;
  run(lgvi, one_body(V3::Zero(), q0, V3::Zero(), V3::Zero()), 0.001, 10000, [&](const SystemStepInfo& i) {
    const double exact = theta0 * std::exp(-zeta * i.t) * (std::cos(wd * i.t) + zeta / wd * std::sin(wd * i.t));
    const S3d& q = i.state.q[0];
    const double signed_angle = 2.0 * std::atan2(q.vec().z(), q.w());
    worst = std::max(worst, std::abs(signed_angle - exact));
  });
  EXPECT_LT(worst, 1e-5 * theta0) << worst;
}

// A large slew (2 rad about a tilted axis) on a triaxial body with a torque
// limit settles on the target: after 60 s (about 10 time constants
// 2 j / k_d of the slowest axis) the error angle is below 1e-6 rad and no
// step applied more than max_torque (checked on the body momentum's change:
// |w_{k+1} - w_k|/2 <= h max_torque + gyroscopic change).
TEST(Forcing, LargeSlewWithTorqueLimitSettlesOnTheTarget) {
  const System sys(triaxial());
  lgvi::LieGroupVariationalIntegrator<Free> lgvi(sys, free_field(1));
  const S3d target = S3d::exp(V3(0.3, -0.6, 0.7));
  ForcingSet f;
  f.add(AttitudeControl{target, 1.0, 1.2, 0.2});
  lgvi.set_forcing(f);
  const SystemState s = run(lgvi, one_body(V3::Zero(), S3d(), V3::Zero(), V3(0.2, 0, 0)), 0.01, 6000);
  EXPECT_LT(error_angle(target, s.q[0]), 1e-6);
  EXPECT_LT(s.w[0].norm(), 1e-6);
}

// Sampled control (period = 5 h, zero-order hold) on a spherical body: the
// torque is computed from the state at t = 0, 5h, 10h, ... and held, so
// each step changes the body momentum w/2 by exactly h M_n (for J = j I the
// step's rotation leaves w + h M invariant). Recomputed here by hand from
// the recorded states; equal to round-off of |w| ~ 1.
TEST(Forcing, SampledControlHoldsTheSampledTorque) {
  const double j = 0.5, h = 0.01;
  const int period_steps = 5;
  const System sys(sphere(j));
  lgvi::LieGroupVariationalIntegrator<Free> lgvi(sys, free_field(1));
  const S3d target = S3d::exp(V3(0.1, 0.2, -0.3));
  AttitudeControl control{target, 2.0, 0.8};
  control.period = period_steps * h;
  ForcingSet f;
  f.add(control);
  lgvi.set_forcing(f);
  std::vector<SystemState> states;
  run(lgvi, one_body(V3::Zero(), S3d(), V3::Zero(), V3(0.3, 0.1, 0.2)), h, 40,
      [&](const SystemStepInfo& i) { states.push_back(i.state); });
  double worst = 0.0;
  V3 held = V3::Zero();
  for (std::size_t k = 0; k + 1 < states.size(); ++k) {
    if (k % period_steps == 0) {
      const S3d e = target.inverse() * states[k].q[0];
      held = -2.0 * (e.w() < 0 ? -1.0 : 1.0) * e.vec() - 0.8 * states[k].w[0] / (2.0 * j);
    }
    worst = std::max(worst, ((states[k + 1].w[0] - states[k].w[0]) / 2.0 - h * held).norm());
  }
  EXPECT_LT(worst, 10 * eps) << worst;
  // And it is not the continuous controller: the held torque differs from
  // the one at the current state by O(period |M'|) ~ 1e-3 within a period.
  const S3d e = target.inverse() * states[3].q[0];
  const V3 continuous = -2.0 * (e.w() < 0 ? -1.0 : 1.0) * e.vec() - 0.8 * states[3].w[0] / (2.0 * j);
  const S3d e0 = target.inverse() * states[0].q[0];
  const V3 first = -2.0 * e0.vec() - 0.8 * states[0].w[0] / (2.0 * j);
  EXPECT_GT((continuous - first).norm(), 1e-4);
}

// A damping far too stiff for the step (h c / j = 50) makes the momentum
// iteration diverge: the step fails with a message naming the step.
TEST(Forcing, TooStiffVelocityDependentForcingFailsNamingTheStep) {
  const System sys(sphere(0.1));
  auto lgvi = with_forcing(lgvi::LieGroupVariationalIntegrator<Free>(sys, free_field(1)), damping(500.0));
  try {
    run(lgvi, one_body(V3::Zero(), S3d(), V3::Zero(), V3(0.1, 0.2, 0.3)), 0.01, 10);
    FAIL() << "expected a failure";
  } catch (const lgvi::IntegrationFailure& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("step 0"), std::string::npos) << m;
    EXPECT_NE(m.find("did not converge"), std::string::npos) << m;
  }
}

// A user's forcing that draws new values on every call (noise) is not a
// function of (t, state), which the end-of-step fixed point needs: the run
// stops with a message that says so and how to draw noise instead of blaming
// the step. Caught where it shows: at the first evaluation (called twice at
// the initial state), and, for a function that repeats itself there but not
// later, when the momentum iteration does not converge.
TEST(Forcing, NonRepeatableForcingIsNamedAsSuch) {
  const System sys(sphere(0.1));
  const SystemState s0 = one_body(V3::Zero(), S3d(), V3::Zero(), V3(0.1, 0.2, 0.3));
  auto message = [&](auto&& f) {
    ForcingSet set;
    set.add_callable(f);
    auto lgvi = with_forcing(lgvi::LieGroupVariationalIntegrator<Free>(sys, free_field(1)), set);
    try {
      run(lgvi, s0, 0.01, 10);
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  int calls = 0;
  const std::string every_call = message([&](double, std::size_t, const lgvi::RigidBodyState&) {
    return lgvi::Wrench{V3::Zero(), V3(1e-3 * (++calls % 7), 0, 0)};
  });
  EXPECT_NE(every_call.find("the forcing returned different values for the same time and state (t = 0.0"),
            std::string::npos)
      << every_call;
  const std::string later = message([&](double t, std::size_t, const lgvi::RigidBodyState&) {
    return lgvi::Wrench{V3::Zero(), V3(t > 0.0 ? 1e-3 * (++calls % 7) : 0.0, 0, 0)};
  });
  EXPECT_NE(later.find("the forcing returned different values for the same time and state (t = 0.01"),
            std::string::npos)
      << later;
  EXPECT_EQ(later.find("too stiff"), std::string::npos) << later;
}

// A checkpoint's internal state (work, forcing at the current state, held
// samples) continues a forced, sampled, composed run bit for bit.
TEST(Forcing, ResumeContinuesBitForBit) {
  const System sys(triaxial());
  auto make = [&] {
    ForcingSet f = mixed_forcing();
    AttitudeControl c{S3d::exp(V3(0.2, 0.1, 0.0)), 0.5, 0.2};
    c.period = 0.07;
    f.add(c);
    return lgvi::ComposedStepper(with_forcing(lgvi::LieGroupVariationalIntegrator<Free>(sys, free_field(1)), f),
                                 lgvi::CompositionTable::of_order(4));
  };
  const double h = 0.01;
  const SystemState s0 = one_body(V3(1, 0, 0), S3d(), V3(0, 0.3, 0), V3(0.3, 0.9, 1.4));
  auto whole = make();
  double work_whole = 0.0;
  const SystemState end_whole = run(whole, s0, h, 120, [&](const SystemStepInfo& i) { work_whole = i.work; });
  auto first = make();
  SystemState mid = run(first, s0, h, 53);
  const std::vector<double> internal = first.internal_state();
  auto second = make();
  second.resume(mid, 53 * h, internal);
  double work = 0.0;
  lgvi::integrate_range(second, mid, 0.0, h, 53, 120, [&](const SystemStepInfo& i) { work = i.work; });
  EXPECT_EQ(mid.x[0], end_whole.x[0]);
  EXPECT_EQ(mid.q[0].scalar_first(), end_whole.q[0].scalar_first());
  EXPECT_EQ(mid.p[0], end_whole.p[0]);
  EXPECT_EQ(mid.w[0], end_whole.w[0]);
  EXPECT_EQ(work, work_whole);
}

// A tabulated profile interpolates linearly and holds its end values outside.
TEST(Forcing, ProfileInterpolatesAndRefusesTimesOutsideTheTable) {
  const Profile p = Profile::table({0.0, 1.0, 3.0}, {V3(0, 0, 0), V3(1, 2, 3), V3(3, 2, 1)});
  EXPECT_EQ(p.at(0.5), V3(0.5, 1.0, 1.5));
  EXPECT_EQ(p.at(2.0), V3(2.0, 2.0, 2.0));
  EXPECT_EQ(p.at(3.0), V3(3, 2, 1));
  EXPECT_EQ(p.at(3.5), V3(3, 2, 1));
  EXPECT_EQ(p.at(-0.1), V3(0, 0, 0));
  EXPECT_THROW(Profile::table({0.0, 0.0}, {V3::Zero(), V3::Zero()}), lgvi::InvalidInput);
}

// ---- Scenario files: [[forcing]] ----------------------------------------

const std::string forced_base = R"(
[body]
mass = 2.0
inertia = [[0.5, 0.0, 0.0], [0.0, 0.8, 0.0], [0.0, 0.0, 1.1]]
[potential]
kind = "central"
mu = 1.0
[initial]
position = [3.0, 0.0, 0.0]
quaternion = [1.0, 0.0, 0.0, 0.0]
momentum = [0.0, 1.1, 0.2]
w = [0.3, 0.9, 1.4]
[integrator]
method = "lgvi"
step = 0.01
duration = 2.0
)";

lgvi::app::Scenario parse(const std::string& forcing, const std::string& method = "lgvi") {
  std::string text = forced_base + forcing;
  if (method != "lgvi") text.replace(text.find("method = \"lgvi\""), 15, "method = \"" + method + "\"");
  return lgvi::app::parse_scenario(text, "forced.toml");
}

std::string error_of(const std::string& forcing, const std::string& method = "lgvi") {
  try {
    parse(forcing, method);
  } catch (const lgvi::InvalidInput& e) {
    return e.what();
  }
  return "(no error)";
}

// Each mistake gets one message naming the key and the fix.
TEST(ForcingScenario, BadInputIsRefusedNamingTheKey) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"[[forcing]]\nkind = \"thrust\"\n", "key 'forcing[0].kind': \"thrust\" is not one of"},
      {"[[forcing]]\nkind = \"torque\"\n", "give exactly one of value"},
      {"[[forcing]]\nkind = \"torque\"\nvalue = [1, 2, 3]\ntable = [[0, 1, 2, 3], [2, 1, 2, 3]]\n", "give exactly one of"},
      {"[[forcing]]\nkind = \"torque\"\ntable = [[0, 1, 2, 3], [1, 1, 2, 3]]\n", "covers t in [0.000000, 1.000000]; the run needs [0, 2.000000]"},
      {"[[forcing]]\nkind = \"torque\"\ntable = [[0, 1, 2, 3], [0, 1, 2, 3]]\n", "the times must increase strictly"},
      {"[[forcing]]\nkind = \"torque\"\ntable = \"no-such-profile.csv\"\n", "cannot open the table"},
      {"[[forcing]]\nkind = \"force\"\nframe = \"lvlh\"\nvalue = [1, 2, 3]\n", "key 'forcing[0].frame'"},
      {"[[forcing]]\nkind = \"damping\"\n", "give c > 0"},
      {"[[forcing]]\nkind = \"damping\"\nc = -1.0\n", "key 'forcing[0].c': must be >= 0"},
      {"[[forcing]]\nkind = \"damping\"\nc = 1.0\nbody = \"sat\"\n", "key 'forcing[0].body': no body is named \"sat\""},
      {"[[forcing]]\nkind = \"attitude-control\"\ntarget = [1, 0, 0, 0]\nk_p = 1.0\n", "needs the gains k_p and k_d"},
      {"[[forcing]]\nkind = \"attitude-control\"\ntarget = [1, 1, 0, 0]\nk_p = 1.0\nk_d = 1.0\n",
       "key 'forcing[0].target': must be a unit quaternion"},
      {"[[forcing]]\nkind = \"attitude-control\"\ntarget = [1, 0, 0, 0]\nk_p = 1.0\nk_d = 1.0\nperiod = 0.0\n",
       "key 'forcing[0].period': must be > 0"},
      {"[[forcing]]\nkind = \"damping\"\nc = 1.0\ngain = 2\n", "key 'forcing[0].gain': unknown key"},
      {"[forcing]\nkind = \"damping\"\n", "must be one or more [[forcing]] tables"},
  };
  for (const auto& [forcing, expected] : cases) {
    const std::string m = error_of(forcing);
    EXPECT_NE(m.find(expected), std::string::npos) << "for\n" << forcing << "got: " << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;
  }
  // Methods that do not discretize a forcing refuse it.
  const std::string m = error_of("[[forcing]]\nkind = \"damping\"\nc = 1.0\n", "rk4-normalized");
  EXPECT_NE(m.find("\"rk4-normalized\" does not take [[forcing]]"), std::string::npos) << m;
}

// A run of a forced scenario through the run loop: rows gain the column
// "work", the energy error is E - E0 - W to the last bit, and the work is
// the stepper's (computed independently here from the same rows: the
// trapezoidal sum needs the forcing at every step, so only its sign and
// size are checked - a damping takes energy out: W < 0 and
// E(T) - E0 = W up to the integrator's error, 1e-5 at this step).
TEST(ForcingScenario, RunRowsCarryTheWorkAndTheEnergyBalance) {
  const lgvi::app::Scenario sc = parse("[[forcing]]\nkind = \"damping\"\nc = 0.2\n");
  const lgvi::app::TrajectoryLayout layout = lgvi::app::scenario_layout(sc);
  ASSERT_EQ(layout.columns, 22);
  EXPECT_EQ(std::string(layout.header).substr(std::string(layout.header).size() - 5), ",work");
  lgvi::app::MemorySink sink(0, layout);
  const lgvi::app::SimulationResult r = lgvi::app::simulate(sc, sink);
  ASSERT_TRUE(r.completed) << r.error;
  const std::vector<double> rows = sink.take();
  const std::size_t n = rows.size() / 22;
  ASSERT_EQ(n, 201u);
  const double e0 = rows[14];
  for (std::size_t k = 0; k < n; ++k) {
    const double* row = &rows[k * 22];
    EXPECT_EQ(row[15], row[14] - e0 - row[21]) << "row " << k;  // the same expression as the run loop's
  }
  const double work = rows[(n - 1) * 22 + 21];
  EXPECT_LT(work, -1e-2);
  EXPECT_LT(std::abs(rows[(n - 1) * 22 + 15]), 1e-4 * std::abs(work));
  // Unforced scenarios keep their 21 columns (outputs byte-identical).
  EXPECT_EQ(lgvi::app::scenario_layout(parse("")).columns, 21);
}

// A table from a CSV file is read relative to the scenario file and inlined
// into the scenario's text, which then parses to the same profile (the
// run's copy of the scenario is self-contained).
TEST(ForcingScenario, FileTablesAreInlinedIntoTheRunsCopy) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "lgvi-forcing-table";
  std::filesystem::create_directories(dir);
  {
    std::ofstream csv(dir / "profile.csv");
    csv << "t,mx,my,mz\n0,0.1,0,0\n1.5,0,0.2,0\n3,0,0,0.3\n";
  }
  const std::string text = forced_base + "[[forcing]]\nkind = \"torque\"\ntable = \"profile.csv\"\n";
  const lgvi::app::Scenario a = lgvi::app::parse_scenario(text, (dir / "s.toml").string());
  EXPECT_EQ(a.source_text.find("profile.csv"), std::string::npos) << a.source_text;
  const lgvi::app::Scenario b = lgvi::app::parse_scenario(a.source_text, "/elsewhere/copy.toml");
  lgvi::app::MemorySink sa(0, lgvi::app::scenario_layout(a)), sb(0, lgvi::app::scenario_layout(b));
  ASSERT_TRUE(lgvi::app::simulate(a, sa).completed);
  ASSERT_TRUE(lgvi::app::simulate(b, sb).completed);
  EXPECT_EQ(sa.take(), sb.take());
  std::filesystem::remove_all(dir);
}

}  // namespace

}  // namespace test_forcing
