// The gyrostat (a body with reaction wheels, wheels.hpp) in the quaternion
// LGVI: against the continuous gyrostat equations integrated by RK4 at a
// step small enough for round-off (the order, with and without motor
// torques), the total angular momentum to round-off under motor torques that
// switch inside steps, every commanded impulse delivered exactly, the limits,
// the energy, and the model's checks.
#include "app/checkpoint.hpp"
#include "io/memory_sink.hpp"
#include "app/scenario.hpp"
#include "app/simulation.hpp"

#include <lgvi/gyrostat.hpp>
#include <lgvi/interaction.hpp>
#include <lgvi/lgvi.hpp>
#include <lgvi/potential.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

#include <unistd.h>

namespace test_gyrostat {

namespace {

using lgvi::HeldTorque;
using lgvi::RigidBody;
using lgvi::S3d;
using lgvi::System;
using lgvi::SystemState;
using lgvi::Wheel;
using lgvi::WheelTorque;
using M3 = lgvi::Matrix3<double>;
using V3 = lgvi::Vector3<double>;
using Free = lgvi::ExternalField<lgvi::NoPotential>;
using Gyrostat = lgvi::LieGroupVariationalIntegrator<Free>;

/// A wheel on `axis` of moment j, with limits (none by default).
Wheel wheel(const V3& axis, double j, double max_torque = INFINITY, double max_speed = INFINITY,
            const std::string& name = {}) {
  return Wheel{axis, j, max_torque, max_speed, name};
}

/// A spacecraft of locked inertia diag(10, 15, 20) with three wheels (j = 0.05, 0.04, 0.06) on the body
/// axes and a fourth skewed one (j = 0.03).
RigidBody spacecraft() {
  const V3 skew = V3(1.0, 1.0, 1.0).normalized();
  return RigidBody(100.0, V3(10.0, 15.0, 20.0).asDiagonal().toDenseMatrix())
      .with_wheels({wheel(V3::UnitX(), 0.05, INFINITY, INFINITY, "x"), wheel(V3::UnitY(), 0.04, INFINITY, INFINITY, "y"),
                    wheel(V3::UnitZ(), 0.06, INFINITY, INFINITY, "z"), wheel(skew, 0.03, INFINITY, INFINITY, "skew")});
}

/// The initial state: a tumble omega = (0.3, -0.2, 0.25) rad/s and wheel speeds (relative) of 20, -35, 50, 10 rad/s.
SystemState start(const RigidBody& body) {
  SystemState s(1);
  s.q[0] = S3d(std::cos(0.3), std::sin(0.3) * 0.6, 0.0, std::sin(0.3) * 0.8);
  const V3 omega(0.3, -0.2, 0.25);
  const double speeds[] = {20.0, -35.0, 50.0, 10.0};
  const lgvi::Wheels& wheels = body.wheels();
  s.eta.assign(1, std::vector<double>(wheels.size()));
  V3 pi = body.inertia() * omega;
  for (std::size_t i = 0; i < wheels.size(); ++i) {
    s.eta[0][i] = wheels.axial_momentum(i, speeds[i], omega);
    pi += wheels[i].inertia * speeds[i] * wheels[i].axis;
  }
  s.w[0] = 2.0 * pi;
  return s;
}

/// The spin-up and spin-down commands: wheel x at +0.02 N m until t = 1.3, then -0.03; wheel skew at -0.01
/// from t = 0.7 on (switch times inside steps of 0.1 and 0.05, not on their boundaries).
std::vector<WheelTorque> commands() {
  return {{0, 0, HeldTorque({0.0, 1.3}, {0.02, -0.03})}, {0, 3, HeldTorque({0.0, 0.7}, {0.0, -0.01})}};
}

V3 inertial_momentum(const SystemState& s) { return s.q[0].act(0.5 * s.w[0]); }

/// The continuous equations: Pi' = Pi x omega + M, eta_i' = u_i(t), q' = q (0, omega) / 2, omega = J_s^{-1}
/// (Pi - h_w), M a constant external torque in body axes, by classical RK4 with step dt (the commands'
/// switches on its grid).
struct Continuous {
  S3d q;
  V3 pi;
  std::vector<double> eta;
};
Continuous reference(const RigidBody& body, const SystemState& s0, const std::vector<WheelTorque>& u, double T,
                     double dt, const V3& external = V3::Zero()) {
  const lgvi::Wheels& wheels = body.wheels();
  const M3 js_inverse = wheels.reduced_inertia().inverse();
  struct D {
    lgvi::Vector4<double> q;
    V3 pi;
    std::vector<double> eta;
  };
  auto rate = [&](double t, const lgvi::Vector4<double>& q, const V3& pi, const std::vector<double>& eta) {
    const V3 omega = js_inverse * (pi - wheels.momentum(eta.data()));
    const S3d qq(q(0), q(1), q(2), q(3));
    const S3d dq = qq * S3d(0.0, omega.x(), omega.y(), omega.z());
    D d{0.5 * dq.scalar_first(), pi.cross(omega) + external, std::vector<double>(eta.size(), 0.0)};
    for (const WheelTorque& c : u) d.eta[c.wheel] += c.torque.at(t);  // t: the step's middle (below)
    return d;
  };
  lgvi::Vector4<double> q = s0.q[0].scalar_first();
  V3 pi = 0.5 * s0.w[0];
  std::vector<double> eta = s0.eta[0];
  const auto n = static_cast<long>(std::llround(T / dt));
  auto add = [](const std::vector<double>& a, const std::vector<double>& b, double c) {
    std::vector<double> r = a;
    for (std::size_t i = 0; i < r.size(); ++i) r[i] += c * b[i];
    return r;
  };
  for (long k = 0; k < n; ++k) {
    // The command held over [t, t + dt] (a switch on the grid): every stage reads it at the step's middle,
    // which no rounding of k dt moves across a switch.
    const double t = (static_cast<double>(k) + 0.5) * dt;
    const D k1 = rate(t, q, pi, eta);
    const D k2 = rate(t, q + 0.5 * dt * k1.q, pi + 0.5 * dt * k1.pi, add(eta, k1.eta, 0.5 * dt));
    const D k3 = rate(t, q + 0.5 * dt * k2.q, pi + 0.5 * dt * k2.pi, add(eta, k2.eta, 0.5 * dt));
    const D k4 = rate(t, q + dt * k3.q, pi + dt * k3.pi, add(eta, k3.eta, dt));
    q += dt / 6.0 * (k1.q + 2.0 * k2.q + 2.0 * k3.q + k4.q);
    pi += dt / 6.0 * (k1.pi + 2.0 * k2.pi + 2.0 * k3.pi + k4.pi);
    for (std::size_t i = 0; i < eta.size(); ++i) eta[i] += dt / 6.0 * (k1.eta[i] + 2.0 * k2.eta[i] + 2.0 * k3.eta[i] + k4.eta[i]);
    q.normalize();
  }
  return {S3d(q(0), q(1), q(2), q(3)), pi, eta};
}

SystemState run(const RigidBody& body, const std::vector<WheelTorque>& u, double h, double T, double* work = nullptr,
                lgvi::ForcingSet forcing = {}) {
  Gyrostat stepper(System(body), Free::uniform(lgvi::NoPotential{}, 1));
  stepper.set_wheel_torques(u);
  if (!forcing.empty()) stepper.set_forcing(std::move(forcing));
  SystemState s = start(body);
  stepper.initialize(s, 0.0);
  const auto n = static_cast<long>(std::llround(T / h));
  for (long k = 0; k < n; ++k) stepper.step(s, static_cast<double>(k) * h, h);
  if (work) *work = stepper.wheel_work();
  return s;
}

/// The error of a run against the reference: the rotation angle between the attitudes plus |Pi - Pi_ref| / |Pi_ref|.
double error(const SystemState& s, const Continuous& ref) {
  const double angle = 2.0 * std::asin(std::min(1.0, (s.q[0].inverse() * ref.q).vec().norm()));
  return angle + (0.5 * s.w[0] - ref.pi).norm() / ref.pi.norm();
}

TEST(Gyrostat, ConvergesAtSecondOrderToTheContinuousEquations) {
  // Free (constant wheel momenta) and with the spin-up/down commands, whose switches (t = 0.7, 1.3) fall on
  // the steps' grid at h = 0.1 and its halvings (a switch inside a step: the momentum test below): error ratios
  // 4 per halving, within 5 % (measured 4.0024 and 4.0006 both ways: the O(h^3) terms are small here). RK4 at
  // dt = 1e-4: its error, ~1e-15, is far below the LGVI's 4.4e-5 at the finest step.
  const RigidBody body = spacecraft();
  for (const bool torques : {false, true}) {
    const std::vector<WheelTorque> u = torques ? commands() : std::vector<WheelTorque>{};
    const double T = 4.0;
    const Continuous ref = reference(body, start(body), u, T, 1e-4);
    double previous = 0.0;
    for (const double h : {0.1, 0.05, 0.025}) {
      const double e = error(run(body, u, h, T), ref);
      std::printf("[ lgvi     ] gyrostat, torques %d, h %.3f: error %.3e%s\n", torques, h, e,
                  previous > 0.0 ? (", ratio " + std::to_string(previous / e)).c_str() : "");
      if (previous > 0.0) {
        EXPECT_NEAR(previous / e, 4.0, 0.2) << "torques " << torques << " h " << h;
      }
      previous = e;
    }
    EXPECT_LT(previous, 2e-4);
  }
}

TEST(Gyrostat, AnExternalTorqueBesideTheWheelsConvergesAtSecondOrder) {
  // A constant body-frame torque (a [[forcing]] kind = "torque", discrete Lagrange-d'Alembert: half of each
  // step's impulse at either end) on the tumbling spacecraft under the spin-up/down commands, against RK4 of
  // Pi' = Pi x omega + M at dt = 1e-4 (error ~1e-15): ratios 4 per halving within 5 %, as without it.
  const RigidBody body = spacecraft();
  const V3 m(0.04, -0.03, 0.05);  // N m
  lgvi::ForcingSet torque;
  torque.add(lgvi::AppliedTorque{lgvi::Profile::constant(m), lgvi::ForcingFrame::Body});
  const double T = 4.0;
  const Continuous ref = reference(body, start(body), commands(), T, 1e-4, m);
  const Continuous without = reference(body, start(body), commands(), T, 1e-4);
  // The torque moves Pi by far more than the errors compared (their |Pi - Pi_ref| / |Pi_ref| < 1e-3).
  EXPECT_GT((ref.pi - without.pi).norm(), 0.01 * ref.pi.norm());
  double previous = 0.0;
  for (const double h : {0.1, 0.05, 0.025}) {
    const double e = error(run(body, commands(), h, T, nullptr, torque), ref);
    std::printf("[ lgvi     ] gyrostat with an external torque, h %.3f: error %.3e%s\n", h, e,
                previous > 0.0 ? (", ratio " + std::to_string(previous / e)).c_str() : "");
    if (previous > 0.0) {
      EXPECT_NEAR(previous / e, 4.0, 0.2) << "h " << h;
    }
    previous = e;
  }
  EXPECT_LT(previous, 2e-4);
}

TEST(Gyrostat, MotorTorquesKeepTheTotalAngularMomentumToRoundOff) {
  // 10^4 steps of 0.013 (switches inside steps): the inertial total momentum pi(q) w / 2 changes only by
  // rounding, a random walk of ~1e-16 per step (measured ~1e-14), while the wheels' momentum changes by
  // ~0.1 of it; each wheel's eta changes by exactly the integral of its command (summed steps: rounding of
  // 10^4 additions, 1e-12 relative at most).
  const RigidBody body = spacecraft();
  const SystemState s0 = start(body);
  const double h = 0.013, T = 130.0;
  const SystemState s = run(body, commands(), h, T);
  const V3 l0 = inertial_momentum(s0), l1 = inertial_momentum(s);
  std::printf("[ lgvi     ] gyrostat 10^4 steps under motor torques: |L - L0| / |L0| = %.2e, eta_x error %.2e\n",
              (l1 - l0).norm() / l0.norm(), s.eta[0][0] - s0.eta[0][0] - (0.02 * 1.3 - 0.03 * (T - 1.3)));
  EXPECT_LT((l1 - l0).norm() / l0.norm(), 1e-13);
  const double impulse_x = 0.02 * 1.3 - 0.03 * (T - 1.3), impulse_skew = -0.01 * (T - 0.7);
  EXPECT_NEAR(s.eta[0][0] - s0.eta[0][0], impulse_x, 1e-12 * std::abs(impulse_x));
  EXPECT_NEAR(s.eta[0][3] - s0.eta[0][3], impulse_skew, 1e-12 * std::abs(impulse_skew));
  EXPECT_EQ(s.eta[0][1], s0.eta[0][1]);
  EXPECT_EQ(s.eta[0][2], s0.eta[0][2]);
  // The wheels' momentum (inertial frame) did change, by a tenth of the total at least: the body's own,
  // J_s omega, changed by the opposite to the same round-off (the total's conservation above).
  const lgvi::Wheels& wheels = body.wheels();
  const V3 wheels0 = s0.q[0].act(wheels.momentum(s0.eta[0].data())), wheels1 = s.q[0].act(wheels.momentum(s.eta[0].data()));
  EXPECT_GT((wheels1 - wheels0).norm(), 0.1 * l0.norm());

}

TEST(Gyrostat, TheEnergyBalanceClosesAtSecondOrder) {
  // Free: E bounded, its error at T = 4 falling by 4 per halving; with the commands, E - E0 - W (W the motor
  // work, wheel_work) falls by 4 too (within 10 %: one sample of an error that oscillates; measured 4.00 and
  // 4.00), where E alone changes by the work: W = -1.38 J against |E - E0 - W| = 2.3e-5 J at h = 0.05.
  const RigidBody body = spacecraft();
  const System sys(body);
  const double e0 = lgvi::kinetic_energy(start(body), sys);
  for (const bool torques : {false, true}) {
    const std::vector<WheelTorque> u = torques ? commands() : std::vector<WheelTorque>{};
    double previous = 0.0;
    for (const double h : {0.05, 0.025}) {
      double work = 0.0;
      const SystemState s = run(body, u, h, 4.0, &work);
      const double e = std::abs(lgvi::kinetic_energy(s, sys) - e0 - work);
      std::printf("[ lgvi     ] gyrostat energy, torques %d, h %.3f: |E - E0 - W| = %.3e, W = %.3e\n", torques, h, e, work);
      if (torques) {
        EXPECT_GT(std::abs(work), 100.0 * e);
      }
      if (previous > 0.0) {
        EXPECT_NEAR(previous / e, 4.0, 0.4) << "torques " << torques;
      }
      previous = e;
    }
  }
}

TEST(Gyrostat, LimitsClipTheTorqueAndStopAWheelAtItsSpeed) {
  // A wheel limited to 0.01 N m receives 0.01 h per step of a 0.05 command; with max_speed 60 rad/s it
  // stops accelerating once its speed reaches 60 (within the last step's increment).
  const RigidBody body = RigidBody(100.0, V3(10.0, 15.0, 20.0).asDiagonal().toDenseMatrix())
                             .with_wheels({wheel(V3::UnitZ(), 0.05, 0.01, 60.0, "z")});
  Gyrostat stepper(System(body), Free::uniform(lgvi::NoPotential{}, 1));
  stepper.set_wheel_torques({{0, 0, HeldTorque::constant(0.05)}});
  SystemState s(1);
  s.eta.assign(1, {0.0});
  stepper.initialize(s, 0.0);
  const double h = 0.1;
  double top = 0.0;
  for (int k = 0; k < 6000; ++k) {
    stepper.step(s, k * h, h);
    const double impulse = stepper.last_wheel_impulses()[0][0];
    // 0.01 x ((t + h) - t), the interval's length as rounded near t <= 600: within 0.01 ulp(600) of 0.01 h.
    EXPECT_TRUE(impulse == 0.0 || std::abs(impulse - 0.01 * h) <= 2e-15) << impulse;
    const V3 omega = body.wheels().body_rate(s.w[0], s.eta[0].data());
    top = std::max(top, body.wheels().relative_speed(0, s.eta[0].data(), omega));
  }
  // 0.01 N m into j = 0.05 with the body reacting: Omega' = u (1/j + 1/(J_z - j)) = 0.2005 rad/s^2, 60 rad/s
  // after ~300 s of the 600 s; then held at the limit, at most one step's increment 0.02 above.
  EXPECT_GE(top, 60.0);
  EXPECT_LE(top, 60.0 + 0.0201);
}

TEST(Gyrostat, HeldTorqueIntegratesExactlyAcrossSwitches) {
  const HeldTorque u({0.0, 1.0, 2.5}, {2.0, -1.0, 4.0});
  EXPECT_EQ(u.at(0.5), 2.0);
  EXPECT_EQ(u.at(1.0), -1.0);  // a switch on a boundary: the new value from there on
  EXPECT_EQ(u.at(-1.0), 2.0);
  EXPECT_EQ(u.at(9.0), 4.0);
  EXPECT_DOUBLE_EQ(u.impulse(0.5, 3.0), 2.0 * 0.5 - 1.0 * 1.5 + 4.0 * 0.5);
  EXPECT_DOUBLE_EQ(u.impulse(0.0, 1.0), 2.0);  // ends on a switch: no part of the next value
  EXPECT_DOUBLE_EQ(u.impulse(0.5, 3.0, 1.5), 1.5 * 0.5 - 1.0 * 1.5 + 1.5 * 0.5);  // clipped to +-1.5
  EXPECT_THROW(HeldTorque({0.0, 0.0}, {1.0, 2.0}), lgvi::InvalidInput);
  EXPECT_THROW(HeldTorque({0.0}, {NAN}), lgvi::InvalidInput);
}

TEST(Gyrostat, BadWheelsAreOneClearError) {
  const RigidBody rigid(100.0, V3(10.0, 15.0, 20.0).asDiagonal().toDenseMatrix());
  auto message = [&](const Wheel& w) {
    try {
      (void)rigid.with_wheels({w}, "body");
    } catch (const lgvi::InvalidInput& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message(wheel(V3::Zero(), 0.1)).find("body.wheel[0].axis: must be a finite, non-zero vector"), std::string::npos);
  EXPECT_NE(message(wheel(V3(1.0, 1.0, 0.0), 0.1)).find("body.wheel[0].axis: must be a unit vector"), std::string::npos);
  EXPECT_NE(message(wheel(V3::UnitX(), -0.1)).find("body.wheel[0].inertia: must be a finite number > 0"), std::string::npos);
  EXPECT_NE(message(wheel(V3::UnitX(), 12.0)).find("body.wheel[0].inertia: 12.0"), std::string::npos);
  EXPECT_NE(message(wheel(V3::UnitX(), 0.1, -1.0)).find("body.wheel[0].max_torque: must be > 0"), std::string::npos);
  EXPECT_NE(message(wheel(V3::UnitX(), 0.1, 1.0, 0.0)).find("body.wheel[0].max_speed: must be > 0"), std::string::npos);
  // Three wheels each below its axis's moment, together leaving J - sum j a a^T indefinite about x.
  const V3 a = V3(1.0, 0.1, 0.0).normalized(), b = V3(1.0, -0.1, 0.0).normalized();
  EXPECT_THROW((void)rigid.with_wheels({wheel(a, 9.0), wheel(b, 9.0)}), lgvi::InvalidInput);
  // A linear body takes none.
  const RigidBody rod = RigidBody::from_balls({{V3(-1.0, 0.0, 0.0), 1.0, 0.0, 1}, {V3(1.0, 0.0, 0.0), 1.0, 0.0, 1}});
  EXPECT_THROW((void)rod.with_wheels({wheel(V3::UnitY(), 0.01)}), lgvi::InvalidInput);
}

TEST(Gyrostat, WithoutWheelMomentumItsEquationIsTheRigidBodys) {
  // c = 0: the gyrostat's solver finds the root of the rigid body's equation (RotationSolver's Newton in
  // the same chart, another order of operations in the Jacobian): the same f to round-off (4 eps on the
  // solvers' tolerance, for b up to 0.3 rad of rotation), and its own residual P(J_s f_v + c) - b at 4 eps
  // with c != 0.
  const M3 js = V3(10.0, 15.0, 20.0).asDiagonal().toDenseMatrix() + 0.5 * (V3(1, 2, 3) * V3(1, 2, 3).transpose());
  const lgvi::GyrostatRotationSolver gyro(js, {});
  const lgvi::RotationSolver rigid(js, {});
  for (int i = 0; i < 20; ++i) {
    const V3 b = 0.15 * V3(std::sin(1.7 * i), std::cos(2.3 * i), std::sin(0.9 * i + 1.0)) * 20.0;
    S3d f1, f2;
    lgvi::SolveReport r1, r2;
    gyro.solve(b, V3::Zero(), f1, r1);
    rigid.solve(b, f2, r2);
    EXPECT_LT((f1.scalar_first() - f2.scalar_first()).norm(), 1e-14) << i;
    const V3 c(0.3, -0.2, 0.5 * std::cos(i));
    S3d f3;
    gyro.solve(b, c, f3, r1);
    const V3 u = js * f3.vec() + c;
    EXPECT_LT((f3.w() * u + f3.vec().cross(u) - b).norm(), 4e-15 * (b.norm() + c.norm()) * 4.0) << i;
  }
}

}  // namespace

// The sensors (sensors.hpp): a reading is a function of its sample number alone. Reading sample 7 after
// samples 0..6 equals reading it directly (the bias walks through the skipped samples with the same
// draws), to the last bit; a reset starts over; samples out of order are refused; a missing sensor reads
// the truth exactly.
TEST(Sensors, AReadingDependsOnItsSampleNumberAlone) {
  lgvi::GyroModel gyro;
  gyro.noise_density = 1e-4;
  gyro.bias_walk = 1e-5;
  gyro.initial_bias = V3(1e-4, -2e-4, 3e-4);
  gyro.seed = 5;
  lgvi::StarTrackerModel tracker;
  tracker.noise = V3(1e-5, 2e-5, 3e-5);
  tracker.seed = 6;
  const S3d q = S3d::exp(V3(0.1, -0.2, 0.3));
  const V3 omega(0.01, 0.02, -0.03);
  lgvi::AttitudeSensors stepped(gyro, tracker, 0.1), jumped(gyro, tracker, 0.1);
  lgvi::AttitudeMeasurement last;
  for (int n = 0; n <= 7; ++n) last = stepped.measure(n, q, omega);
  const lgvi::AttitudeMeasurement direct = jumped.measure(7, q, omega);
  EXPECT_EQ(last.omega, direct.omega);
  EXPECT_EQ(last.gyro_bias, direct.gyro_bias);
  EXPECT_EQ(last.q.quaternion().coeffs(), direct.q.quaternion().coeffs());
  EXPECT_NE(last.gyro_bias, gyro.initial_bias);
  EXPECT_THROW(jumped.measure(3, q, omega), std::logic_error);
  jumped.reset();
  EXPECT_EQ(jumped.measure(0, q, omega).gyro_bias, gyro.initial_bias);
  lgvi::AttitudeSensors none(std::nullopt, std::nullopt, 0.1);
  const lgvi::AttitudeMeasurement truth = none.measure(0, q, omega);
  EXPECT_EQ(truth.omega, omega);
  EXPECT_EQ(truth.q.quaternion().coeffs(), q.quaternion().coeffs());
  EXPECT_THROW(lgvi::AttitudeSensors(gyro, tracker, 0.0), lgvi::InvalidInput);
}

// Checkpoint and resume with reaction wheels (simulation.cpp, checkpoint.cpp): a run resumed from a
// checkpoint continues bit for bit, since the checkpoint holds every number the rest of the run reads —
// the wheels' momenta eta, the stepper's wheel work and its controller's held commands and sample count,
// the sensors' bias walk, the recorder's copy of the controller, the readings so far and the wheel
// statistics. Two runs: scenarios/slew-wheels.toml (a sampled controller with a gyro and a star tracker
// under gravity gradient; its period made 0.7 s = 7 steps so that the checkpoint at step 995 falls inside
// a held command, and 995 is not an output step either) and scenarios/wheel-slew.toml (torque tables).
namespace {

std::string replaced(std::string text, const std::string& old, const std::string& with) {
  const std::size_t at = text.find(old);
  if (at == std::string::npos || text.find(old, at + 1) != std::string::npos)
    throw std::logic_error("test: '" + old + "' is not in the scenario once");
  return text.replace(at, old.size(), with);
}

std::string scenario_text(const std::string& file) {
  std::ifstream in(std::string(LGVI_SCENARIO_DIR) + "/" + file);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

struct Leg {
  lgvi::app::SimulationResult result;
  std::vector<double> rows;
  std::int64_t columns = 0;
};

Leg run_leg(const lgvi::app::Scenario& sc, const lgvi::app::SimulationOptions& opt) {
  lgvi::app::MemorySink sink(0, lgvi::app::scenario_layout(sc));
  Leg leg;
  leg.result = lgvi::app::simulate(sc, sink, opt);
  leg.columns = sink.layout().columns;
  leg.rows = sink.take();
  return leg;
}

std::string file_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// The numbers of a side table's first `rows` rows (its header skipped).
std::vector<double> side_table_rows(const std::string& text, std::int64_t rows) {
  std::vector<double> values;
  const char* at = text.c_str() + text.find('\n') + 1;
  for (std::int64_t r = 0; r < rows; ++r)
    for (char* end = nullptr;; at = end + 1) {
      values.push_back(std::strtod(at, &end));
      if (*end == '\n') {
        at = end + 1;
        break;
      }
    }
  return values;
}

void expect_resume_is_bit_identical(const lgvi::app::Scenario& sc, std::int64_t every) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("lgvi-test-wheels-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir / "old");
  const std::string path = (dir / "checkpoint.bin").string();
  lgvi::app::SimulationOptions opt;
  opt.checkpoint_every = every;
  opt.checkpoint_path = path;
  opt.open_side_table = lgvi::app::side_tables_in(dir.string());
  const Leg full = run_leg(sc, opt);
  ASSERT_TRUE(full.result.completed) << full.result.error;
  std::vector<std::string> written;  // the side tables this scenario writes, as the whole run wrote them
  for (const std::string& file : lgvi::app::side_table_files())
    if (std::filesystem::exists(dir / file)) written.push_back(file);
  // sensors.csv with sensors, wheels.csv for a system's wheels (a single body's wheels are trajectory columns).
  EXPECT_EQ(written.size(), (lgvi::app::sensor_header(sc).empty() ? 0u : 1u) +
                                (lgvi::app::wheel_row_header(sc).empty() ? 0u : 1u));
  std::vector<std::string> whole(written.size());
  for (std::size_t i = 0; i < written.size(); ++i) whole[i] = file_text(dir / written[i]);
  const lgvi::app::Checkpoint c = lgvi::app::read_checkpoint(path);
  ASSERT_EQ(c.k, every);  // the only checkpoint: the runs have fewer than 2 x every steps
  ASSERT_EQ(c.state.eta.size(), sc.bodies());
  // The checkpoint holds each side table's position, not its rows: a resume truncates the files back to
  // it and streams on, giving the whole run's files byte for byte.
  lgvi::app::SimulationOptions again;
  again.resume = &c;
  again.open_side_table = lgvi::app::side_tables_in(dir.string());
  const Leg rest = run_leg(sc, again);
  ASSERT_TRUE(rest.result.completed) << rest.result.error;
  for (std::size_t i = 0; i < written.size(); ++i) EXPECT_EQ(file_text(dir / written[i]), whole[i]) << written[i];
  // A checkpoint of an lgvi that held the side tables' rows (recorder.sensor_readings, recorder.wheel_rows)
  // resumes into a new folder with the same files.
  lgvi::app::Checkpoint old = c;
  old.recorder = {};
  for (const lgvi::CheckpointFields::Field& f : c.recorder.fields()) {
    const std::string table = f.name == "recorder.sensors.position" ? "sensors.csv"
                              : f.name == "recorder.wheels.position" ? "wheels.csv"
                                                                     : "";
    if (table.empty()) {
      old.recorder.put(f);
      continue;
    }
    const std::size_t i = static_cast<std::size_t>(std::find(written.begin(), written.end(), table) - written.begin());
    ASSERT_LT(i, written.size()) << f.name;
    old.recorder.put_f64(table == "sensors.csv" ? "recorder.sensor_readings" : "recorder.wheel_rows",
                         side_table_rows(whole[i], f.i64.at(0)));
  }
  again.resume = &old;
  again.open_side_table = lgvi::app::side_tables_in((dir / "old").string());
  const Leg from_old = run_leg(sc, again);
  ASSERT_TRUE(from_old.result.completed) << from_old.result.error;
  for (std::size_t i = 0; i < written.size(); ++i)
    EXPECT_EQ(file_text(dir / "old" / written[i]), whole[i]) << "from rows: " << written[i];
  std::filesystem::remove_all(dir);
  // The rows after the checkpoint: the tail of the whole run's, to the bit.
  ASSERT_GT(rest.rows.size(), 0u);
  ASSERT_LE(rest.rows.size(), full.rows.size());
  const std::vector<double> tail(full.rows.end() - static_cast<std::ptrdiff_t>(rest.rows.size()), full.rows.end());
  EXPECT_EQ(rest.rows, tail);
  const SystemState &a = full.result.final_state, &b = rest.result.final_state;
  EXPECT_EQ(a.eta, b.eta);
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a.w[i], b.w[i]);
    EXPECT_EQ(a.q[i].quaternion().coeffs(), b.q[i].quaternion().coeffs());
  }
  const lgvi::app::RunStatistics &s = full.result.stats, &r = rest.result.stats;
  ASSERT_EQ(s.wheels.size(), r.wheels.size());
  for (std::size_t i = 0; i < s.wheels.size(); ++i) {
    EXPECT_EQ(s.wheels[i].max_speed, r.wheels[i].max_speed);
    EXPECT_EQ(s.wheels[i].max_torque, r.wheels[i].max_torque);
    EXPECT_EQ(s.wheels[i].time_limited, r.wheels[i].time_limited);
  }
  EXPECT_EQ(s.wheel_effort, r.wheel_effort);
  EXPECT_EQ(s.wheels_saturated_time, r.wheels_saturated_time);
  EXPECT_EQ(s.max_energy_error, r.max_energy_error);  // E - E0 - W: the motors' work W carried over
  EXPECT_EQ(s.max_momentum_error, r.max_momentum_error);
}

}  // namespace

TEST(WheelCheckpoint, AResumedControlledRunWithSensorsIsBitIdentical) {
  std::string text = replaced(scenario_text("slew-wheels.toml"), "period = 0.1 ", "period = 0.7 ");
  text = replaced(text, "duration = 300.0", "duration = 150.0");
  const lgvi::app::Scenario sc = lgvi::app::parse_scenario(text, "slew-wheels");
  ASSERT_TRUE(sc.wheel_control && sc.wheel_control->sensors());
  expect_resume_is_bit_identical(sc, 995);
}

TEST(WheelCheckpoint, AResumedRunOfTorqueTablesIsBitIdentical) {
  expect_resume_is_bit_identical(lgvi::app::parse_scenario(scenario_text("wheel-slew.toml"), "wheel-slew"), 350);
}

// A side table the checkpoint's position does not fit (deleted, or cut shorter since) is refused, naming the
// file, before the trajectory is touched: not resumed into a file padded with zeros.
TEST(WheelCheckpoint, AMissingOrCutSideTableIsRefused) {
  std::string text = replaced(scenario_text("slew-wheels.toml"), "duration = 300.0", "duration = 150.0");
  const lgvi::app::Scenario sc = lgvi::app::parse_scenario(text, "slew-wheels");
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("lgvi-test-cut-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  lgvi::app::SimulationOptions opt;
  opt.checkpoint_every = 995;
  opt.checkpoint_path = (dir / "checkpoint.bin").string();
  opt.open_side_table = lgvi::app::side_tables_in(dir.string());
  ASSERT_TRUE(run_leg(sc, opt).result.completed);
  const lgvi::app::Checkpoint c = lgvi::app::read_checkpoint(opt.checkpoint_path);
  const std::filesystem::path sensors = dir / "sensors.csv";
  const std::uintmax_t position = static_cast<std::uintmax_t>(c.recorder.i64("recorder.sensors.position", 3)[1]);
  ASSERT_GT(std::filesystem::file_size(sensors), position);
  lgvi::app::SimulationOptions again;
  again.resume = &c;
  again.open_side_table = opt.open_side_table;
  bool opened = false;
  for (const bool cut : {true, false}) {
    if (cut) std::filesystem::resize_file(sensors, position - 1);
    else std::filesystem::remove(sensors);
    try {
      lgvi::app::simulate(sc, [&]() -> lgvi::app::TrajectorySink& {
        opened = true;
        throw std::logic_error("the trajectory must not be opened");
      }, again);
      ADD_FAILURE() << "resumed with a side table that does not fit";
    } catch (const lgvi::app::CheckpointError& e) {
      EXPECT_NE(std::string(e.what()).find("sensors.csv"), std::string::npos) << e.what();
    }
  }
  EXPECT_FALSE(opened);
  std::filesystem::remove_all(dir);
}

// A system's spacecraft with wheels ([[bodies.wheel]], tests/reference/formation-wheels.toml): the checkpoint
// holds every body's wheel momenta and the rows of wheels.csv so far; the resumed run gives the same rows
// and wheel table.
TEST(WheelCheckpoint, AResumedSystemWithWheelsIsBitIdentical) {
  std::ifstream in(std::string(LGVI_TEST_REFERENCE_DIR) + "/formation-wheels.toml");
  const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  const lgvi::app::Scenario sc = lgvi::app::parse_scenario(text, "formation");
  ASSERT_EQ(sc.bodies(), 2u);
  expect_resume_is_bit_identical(sc, 355);
}

// A checkpoint resumed with a scenario whose body has other wheels, or whose controller has another
// period, is refused, naming the field (not run on with the wrong state); a run with a control law of one's
// own (Python's) is not checkpointed (the law's state is not lgvi's).
TEST(WheelCheckpoint, MismatchesAndLawsOfOnesOwnAreRefused) {
  const std::string path = (std::filesystem::temp_directory_path() /
                            ("lgvi-test-wheels-refused-" + std::to_string(::getpid()) + ".bin")).string();
  const std::string text = scenario_text("wheel-slew.toml");
  const lgvi::app::Scenario sc = lgvi::app::parse_scenario(text, "wheel-slew");
  lgvi::app::SimulationOptions opt;
  opt.checkpoint_every = 350;
  opt.checkpoint_path = path;
  run_leg(sc, opt);
  const lgvi::app::Checkpoint c = lgvi::app::read_checkpoint(path);
  std::filesystem::remove(path);
  auto refused = [](const lgvi::app::Scenario& other, const lgvi::app::Checkpoint& from, const std::string& field) {
    lgvi::app::SimulationOptions again;
    again.resume = &from;
    try {
      run_leg(other, again);
      ADD_FAILURE() << "resumed a checkpoint that does not fit";
    } catch (const lgvi::app::CheckpointError& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  // A second wheel on the body (its moment within the body's).
  refused(lgvi::app::parse_scenario(replaced(text, "max_torque = 0.05", "max_torque = 0.05\n[[body.wheel]]\n"
                                                                         "axis = [1.0, 0.0, 0.0]\ninertia = 0.01\n"
                                                                         "speed = 0.0\n"),
                                    "two-wheels"),
          c, "'run.wheel_counts'");
  // The controller's period doubled after a checkpoint inside a held command (at 995, period 0.7 s).
  std::string slew = replaced(scenario_text("slew-wheels.toml"), "period = 0.1 ", "period = 0.7 ");
  slew = replaced(slew, "duration = 300.0", "duration = 150.0");
  opt.checkpoint_every = 995;
  run_leg(lgvi::app::parse_scenario(slew, "slew-wheels"), opt);
  const lgvi::app::Checkpoint held = lgvi::app::read_checkpoint(path);
  std::filesystem::remove(path);
  refused(lgvi::app::parse_scenario(replaced(slew, "period = 0.7 ", "period = 1.4 "), "slew-wheels"), held,
          "wheel_control.samples'");
  lgvi::app::Scenario own = lgvi::app::parse_scenario(scenario_text("slew-wheels.toml"), "slew-wheels");
  own.wheel_control->set_law([](double, const lgvi::AttitudeMeasurement&, const std::vector<double>&) { return V3::Zero().eval(); });
  opt.checkpoint_path = path;
  try {
    run_leg(own, opt);
    ADD_FAILURE() << "checkpointed a law of one's own";
  } catch (const lgvi::InvalidInput& e) {
    // Refused before the run (simulate's check), not at its first checkpoint.
    EXPECT_EQ(std::string(e.what()).rfind("checkpoint_every: a run with a control law of one's own", 0), 0u) << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(path));
}

// The temperature's degrees of freedom (simulation.cpp, degrees_of_freedom): a reaction wheel's spin is
// one, since the kinetic energy the temperature divides holds it. Two spacecraft (3 + 3 each) with three
// wheels, less the total momentum's 3.
TEST(WheelThermodynamics, EachWheelIsOneDegreeOfFreedom) {
  std::ifstream in(std::string(LGVI_TEST_REFERENCE_DIR) + "/formation-wheels.toml");
  const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  EXPECT_EQ(lgvi::app::degrees_of_freedom(lgvi::app::parse_scenario(text, "formation")), 2 * 6 - 3 + 3);
}

}  // namespace test_gyrostat
