// Reaction wheels: a rigid body with internal rotors (a gyrostat).
//
// A wheel i spins about the body-fixed unit axis a_i with moment j_i about
// that axis and speed Omega_i relative to the body. The body's inertia J is
// the whole spacecraft's with the wheels locked (the usual convention), so
// the kinetic energy of body and wheels is
//   T = 1/2 omega.J omega + sum_i j_i (a_i.omega) Omega_i + 1/2 sum_i j_i Omega_i^2.
// Its momenta: the total angular momentum in body axes
//   Pi = J omega + sum_i j_i Omega_i a_i          (lgvi's w = 2 Pi),
// and each wheel's axial momentum eta_i = j_i (a_i.omega + Omega_i). With
// J_s = J - sum_i j_i a_i a_i^T (the body with the wheels' axial inertia
// taken out) and h_w = sum_i eta_i a_i (the wheels' momentum vector):
//   Pi = J_s omega + h_w,   omega = J_s^{-1} (Pi - h_w),
//   T  = 1/2 (Pi - h_w).J_s^{-1} (Pi - h_w) + sum_i eta_i^2 / (2 j_i).
// A motor torque u_i (on the wheel, and -u_i a_i on the body: internal)
// changes eta_i alone (eta_i' = u_i); external torques change Pi as for a
// rigid body; the wheel angles are cyclic.
//
// The discrete Lagrangian of the quaternion LGVI (lgvi.hpp) with the wheel
// angles reduced out (Routh: the eta_i are constant over a step without
// motor torque) gains the term h omega.h_w with omega ~ (2/h) Im(f):
//   L_d = (2/h) f_v.J_s f_v + 2 h_w.f_v - h (V0 + V1)/2,   f = q0^* q1.
// Its discrete Legendre transforms (the variation q0 -> q0 exp(zeta/2), and
// q1 -> q1 exp(zeta/2)), with P(u) = f_s u + f_v x u and Q(u) = f_s u - f_v x u:
//   w0 = (4/h) P(J_s f_v) + 2 P(h_w) - h M0  ->  P(J_s f_v + (h/2) h_w) = (h/4)(w0 + h M0),
//   w1 = (4/h) Q(J_s f_v) + 2 Q(h_w) + h M1.
// Since Q(u) = pi(f)^T P(u) for every u when |f| = 1 (f^* (f u) f = u f),
//   w1 = pi(f)^T (w0 + h M0) + h M1,
// the rigid body's update unchanged: the total angular momentum in the
// inertial frame, pi(q) w / 2, is carried by the same rotation and is
// conserved to round-off by motor torques of any size. The implicit equation
// is the rigid body's with J_s and the offset c = (h/2) h_w; the same form as
// Manchester & Peck's gyrostat QVI (zacmanchester/quaternion-variational-
// integrators, GyrostatQVI.m).
//
// Motor torques by the discrete Lagrange-d'Alembert principle on the cyclic
// wheel angles, each torque held over the step (a zero-order hold, as a
// flight computer commands it): over [t, t + h] wheel i receives the exact
// impulse I_i of its commanded torque, and the step takes the wheels'
// momentum at the middle of the step,
//   eta_half = eta_k + I/2,   step with h_w(eta_half),   eta_{k+1} = eta_half + I/2,
// a symmetric splitting, second order, that delivers every commanded impulse
// exactly (also across a switch inside a step: I is the integral of the
// piecewise-constant command over the step).
#pragma once

#include <lgvi/error.hpp>
#include <lgvi/s3.hpp>

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace lgvi {

/// One reaction wheel of a body. Invariants (checked by Wheels): `axis` is a
/// unit vector in body axes, `inertia` > 0, the limits > 0 (infinite: none).
struct Wheel {
  Vector3<double> axis = Vector3<double>::UnitZ();
  double inertia = 0.0;  ///< j, the wheel's moment about its axis
  double max_torque = std::numeric_limits<double>::infinity();  ///< |u| at most this (N m)
  double max_speed = std::numeric_limits<double>::infinity();   ///< |Omega| at most this (rad/s, relative to the body)
  std::string name;

  /// What the wheel gets of a torque (or an impulse) u at relative speed `speed`: nothing that would
  /// speed it up further once at max_speed (u of the speed's sign when |speed| >= max_speed), u
  /// otherwise. The one speed-limit rule of the step (lgvi.hpp) and of the recorded torques.
  double speed_limited(double u, double speed) const {
    return std::abs(speed) >= max_speed && u * speed > 0.0 ? 0.0 : u;
  }
  /// The motor torque a command gives at relative speed `speed`: clipped to +-max_torque, then
  /// speed_limited.
  double applied_torque(double command, double speed) const {
    return speed_limited(std::clamp(command, -max_torque, max_torque), speed);
  }
};

/// The wheels of one body, with the body's locked inertia J: J_s and the
/// maps between (w, eta) and (omega, Omega) of the file comment. Immutable.
class Wheels {
 public:
  Wheels() = default;
  /// Throws InvalidInput, naming `prefix` + ".wheel[i].key", for an axis that
  /// is not a finite unit vector (to 1e-9), a moment that is not > 0, a limit
  /// that is not > 0, or wheels whose axial moments leave J_s not positive
  /// definite (a wheel's moment j must be smaller than the body's moment
  /// a.J a about its axis, the body being the wheel plus the rest).
  Wheels(const Matrix3<double>& locked_inertia, std::vector<Wheel> wheels, const std::string& prefix = "body")
      : wheels_(std::move(wheels)) {
    Matrix3<double> js = locked_inertia;
    for (std::size_t i = 0; i < wheels_.size(); ++i) {
      const Wheel& w = wheels_[i];
      const std::string key = prefix + ".wheel[" + std::to_string(i) + "].";
      if (!w.axis.allFinite() || w.axis.norm() == 0.0)
        throw InvalidInput(key + "axis: must be a finite, non-zero vector (a unit vector in body axes)");
      if (std::abs(w.axis.norm() - 1.0) > 1e-9)
        throw InvalidInput(key + "axis: must be a unit vector (|axis| = " + std::to_string(w.axis.norm()) +
                           "); give it normalized");
      if (!(std::isfinite(w.inertia) && w.inertia > 0.0))
        throw InvalidInput(key + "inertia: must be a finite number > 0 (the wheel's moment about its axis)");
      if (!(w.max_torque > 0.0)) throw InvalidInput(key + "max_torque: must be > 0");
      if (!(w.max_speed > 0.0)) throw InvalidInput(key + "max_speed: must be > 0");
      const double about_axis = w.axis.dot(locked_inertia * w.axis);
      if (!(w.inertia < about_axis))
        throw InvalidInput(key + "inertia: " + std::to_string(w.inertia) + " is not smaller than the body's moment " +
                           std::to_string(about_axis) + " about the wheel's axis (the body's inertia is the whole "
                           "spacecraft's, wheels locked)");
      js -= w.inertia * w.axis * w.axis.transpose();
    }
    Eigen::LLT<Matrix3<double>> llt(js);
    if (llt.info() != Eigen::Success)
      throw InvalidInput(prefix + ".wheel: the wheels' axial moments leave the rest of the body without a positive "
                                  "definite inertia (J - sum j a a^T); the wheels' moments are too large");
    js_ = js;
    js_inverse_ = js.inverse();
  }

  std::size_t size() const { return wheels_.size(); }
  bool empty() const { return wheels_.empty(); }
  const Wheel& operator[](std::size_t i) const { return wheels_[i]; }
  const std::vector<Wheel>& list() const { return wheels_; }
  /// J_s = J - sum j_i a_i a_i^T.
  const Matrix3<double>& reduced_inertia() const { return js_; }

  /// h_w = sum_i eta_i a_i, the wheels' angular momentum in body axes.
  Vector3<double> momentum(const double* eta) const {
    Vector3<double> h = Vector3<double>::Zero();
    for (std::size_t i = 0; i < wheels_.size(); ++i) h += eta[i] * wheels_[i].axis;
    return h;
  }
  /// The body's angular velocity omega = J_s^{-1} (w/2 - h_w), body axes.
  Vector3<double> body_rate(const Vector3<double>& w, const double* eta) const {
    return js_inverse_ * (0.5 * w - momentum(eta));
  }
  /// Wheel i's speed relative to the body, Omega_i = eta_i / j_i - a_i.omega.
  double relative_speed(std::size_t i, const double* eta, const Vector3<double>& omega) const {
    return eta[i] / wheels_[i].inertia - wheels_[i].axis.dot(omega);
  }
  /// eta_i from a relative speed: j_i (a_i.omega + Omega_i).
  double axial_momentum(std::size_t i, double speed, const Vector3<double>& omega) const {
    return wheels_[i].inertia * (wheels_[i].axis.dot(omega) + speed);
  }
  /// T = 1/2 (Pi - h_w).J_s^{-1} (Pi - h_w) + sum_i eta_i^2 / (2 j_i), Pi = w/2.
  double kinetic_energy(const Vector3<double>& w, const double* eta) const {
    const Vector3<double> m = 0.5 * w - momentum(eta);
    double t = 0.5 * m.dot(js_inverse_ * m);
    for (std::size_t i = 0; i < wheels_.size(); ++i) t += 0.5 * eta[i] * eta[i] / wheels_[i].inertia;
    return t;
  }

 private:
  std::vector<Wheel> wheels_;
  Matrix3<double> js_ = Matrix3<double>::Identity();
  Matrix3<double> js_inverse_ = Matrix3<double>::Identity();
};

}  // namespace lgvi
