// A gyrostat (a rigid body with reaction wheels) with the quaternion LGVI,
// using only the header-only library: Manchester & Peck's gyrostat demo
// (GyrostatDemo.m: their I = diag(1, 2, 3) is the body without the rotors'
// axial inertia, J_s here; rotor momentum (-0.01, 0.02, 0.01) in body axes,
// Omega0 = (pi/10, pi/6, pi/8), q0 = identity), with three wheels of moment
// j = 0.01 on the body axes so that J (wheels locked) = J_s + j I.
//
//   gyrostat [--motor] H T [CSV]
//
// steps with h = H to t = T and prints (or writes to CSV) every step's t, q
// (scalar first), the body rate omega = J_s^{-1} (Pi - h_w) and the inertial
// total angular momentum pi(q) Pi. With --motor the wheels are driven by held
// motor torques (set_wheel_torques): u = (+0.002, -0.001, +0.0015) N m on the
// x, y, z wheels for 0 <= t < 20, -u for 20 <= t < 40, none after (the
// script's MOTOR_TORQUE and MOTOR_SWITCHES), so that their momentum in body
// axes is h_w(t) = rho0 + the integral of u, back at rho0 from t = 40 on; the
// rows then also carry h_w (three more columns, hwx, hwy, hwz).
// scripts/compare_manchester_peck_gyrostat.py runs it beside their
// GyrostatQVI.m under Octave (--case motor: with the torques).
#include <lgvi/gyrostat.hpp>
#include <lgvi/interaction.hpp>
#include <lgvi/lgvi.hpp>
#include <lgvi/potential.hpp>

#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

int main(int argc, char** argv) {
  using V3 = lgvi::Vector3<double>;
  const bool motor = argc > 1 && std::strcmp(argv[1], "--motor") == 0;
  if (motor) {
    --argc;
    ++argv;
  }
  if (argc < 3) {
    std::fprintf(stderr, "usage: gyrostat [--motor] H T [CSV]\n");
    return 2;
  }
  const double h = std::atof(argv[1]), T = std::atof(argv[2]);
  const double pi = std::acos(-1.0), j = 0.01;
  const V3 rotor(-0.01, 0.02, 0.01), omega0(pi / 10, pi / 6, pi / 8);
  const lgvi::Matrix3<double> js = V3(1.0, 2.0, 3.0).asDiagonal();
  std::vector<lgvi::Wheel> wheels;
  for (int k = 0; k < 3; ++k) {
    lgvi::Wheel w;
    w.axis = V3::Unit(k);
    w.inertia = j;
    wheels.push_back(w);
  }
  const lgvi::RigidBody body = lgvi::RigidBody(1.0, js + j * lgvi::Matrix3<double>::Identity()).with_wheels(wheels);
  using Free = lgvi::ExternalField<lgvi::NoPotential>;
  lgvi::LieGroupVariationalIntegrator<Free> stepper(lgvi::System(body), Free::uniform(lgvi::NoPotential{}, 1));
  if (motor) {
    // Wheel k's command, held: u_k on [0, 20), -u_k on [20, 40), 0 from 40 on. The switches fall on the
    // steps' grid for the script's step sizes, where a held command's impulse over a step is u h exactly.
    const V3 u(0.002, -0.001, 0.0015);
    std::vector<lgvi::WheelTorque> torques;
    for (int k = 0; k < 3; ++k)
      torques.push_back({0, static_cast<std::size_t>(k), lgvi::HeldTorque({0.0, 20.0, 40.0}, {u(k), -u(k), 0.0})});
    stepper.set_wheel_torques(torques);
  }
  lgvi::SystemState s(1);
  s.eta = {{rotor.x(), rotor.y(), rotor.z()}};  // axis-aligned wheels: h_w = (eta_x, eta_y, eta_z)
  s.w[0] = 2.0 * (js * omega0 + rotor);        // w = 2 Pi, Pi = J_s omega + h_w
  stepper.initialize(s, 0.0);
  std::FILE* out = argc > 3 ? std::fopen(argv[3], "w") : stdout;
  if (!out) {
    std::perror(argv[3]);
    return 1;
  }
  std::fprintf(out, motor ? "t,qw,qx,qy,qz,wx,wy,wz,Lx,Ly,Lz,hwx,hwy,hwz\n" : "t,qw,qx,qy,qz,wx,wy,wz,Lx,Ly,Lz\n");
  auto row = [&](double t) {
    const V3 omega = body.wheels().body_rate(s.w[0], s.eta[0].data());
    const V3 l = s.q[0].act(0.5 * s.w[0]);
    const auto q = s.q[0].scalar_first();
    std::fprintf(out, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g", t, q(0), q(1), q(2), q(3),
                 omega.x(), omega.y(), omega.z(), l.x(), l.y(), l.z());
    if (motor) {
      const V3 hw = body.wheels().momentum(s.eta[0].data());
      std::fprintf(out, ",%.17g,%.17g,%.17g", hw.x(), hw.y(), hw.z());
    }
    std::fputc('\n', out);
  };
  const auto n = static_cast<long>(std::llround(T / h));
  row(0.0);
  const auto start = std::chrono::steady_clock::now();
  for (long k = 0; k < n; ++k) {
    stepper.step(s, static_cast<double>(k) * h, h);
    row(static_cast<double>(k + 1) * h);
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (out != stdout) std::fclose(out);
  std::fprintf(stderr, "gyrostat: %ld steps in %.6f s (%.0f ns/step, rows written included)\n", n, seconds,
               1e9 * seconds / static_cast<double>(n));
  return 0;
}
