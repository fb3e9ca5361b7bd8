// The continuous equations of motion on T(R^3 x S^3), the paper's
// Euler-Lagrange equations (section "Continuous time equation"):
//
//     m xddot = -dV/dx = F,
//     4 J xidot + 8 xi x (J xi) = -F(q) dV/dq = 2 M,
//     qdot = q (0, xi),
//
// with xi = Omega / 2. Two typos of the paper are corrected here: it writes
// "xi x (J epsilon)" for xi x (J xi), and "+ F(q) dV/dq" on the right where
// its own variation (the term -(dV/dq)^T dq/dlambda) gives the minus sign.
// With Omega = 2 xi and F(q) dV/dq = -2 M the second equation is Euler's
// J Omegadot = J Omega x Omega + M, which fixes the sign independently.
//
// Used as the reference of the convergence tests (a tight RK4 solve), and
// available to anyone who wants a non-geometric comparison.
#pragma once

#include <lgvi/potential.hpp>
#include <lgvi/rigid_body.hpp>
#include <lgvi/s3.hpp>
#include <lgvi/state.hpp>

#include <stdexcept>
#include <string>

namespace lgvi {

/// A point of T(R^3 x S^3) in the paper's variables: (x, xdot, q, xi),
/// with q kept as a raw quaternion (the ODE solver moves it off S^3 by its
/// truncation error; nothing here projects it back).
struct ContinuousState {
  Vector3<double> x, v, xi;
  Eigen::Quaterniond q;

  ContinuousState operator+(const ContinuousState& o) const {
    return {x + o.x, v + o.v, xi + o.xi, Eigen::Quaterniond(q.coeffs() + o.q.coeffs())};
  }
  ContinuousState operator*(double s) const { return {x * s, v * s, xi * s, Eigen::Quaterniond(q.coeffs() * s)}; }
};

/// Conversions with the Hamiltonian state: p = m xdot, w = 4 J xi = 2 J Omega.
inline ContinuousState to_continuous(const RigidBodyState& s, const RigidBody& body) {
  return {s.x, s.p / body.mass(), 0.25 * body.inertia_inverse() * s.w, s.q.quaternion()};
}
inline RigidBodyState from_continuous(const ContinuousState& c, const RigidBody& body) {
  return {c.x, S3d(c.q), body.mass() * c.v, 4.0 * body.inertia() * c.xi};
}

template <Potential P>
class ContinuousEquations {
 public:
  ContinuousEquations(const RigidBody& body, P potential) : body_(body), potential_(std::move(potential)) {}

  /// The time derivative of (x, xdot, q, xi).
  ContinuousState derivative(const ContinuousState& s) const {
    // The potential sees the rotation pi(q) (the paper's formula, defined off S^3 too).
    const PotentialEvaluation e = potential_.evaluate(s.x, S3d(s.q));
    const Matrix3<double>& J = body_.inertia();
    ContinuousState d;
    d.x = s.v;
    d.v = e.force / body_.mass();
    d.xi = body_.inertia_inverse() * (0.5 * e.torque - 2.0 * s.xi.cross(J * s.xi));  // 4 J xidot = 2M - 8 xi x J xi
    const Eigen::Quaterniond pure(0.0, s.xi.x(), s.xi.y(), s.xi.z());
    d.q = s.q * pure;
    return d;
  }

  /// Classical RK4 over n steps of size h (a tight reference for small h).
  ContinuousState rk4(ContinuousState s, double h, long n) const {
    for (long k = 0; k < n; ++k) {
      const ContinuousState k1 = derivative(s);
      const ContinuousState k2 = derivative(s + k1 * (h / 2));
      const ContinuousState k3 = derivative(s + k2 * (h / 2));
      const ContinuousState k4 = derivative(s + k3 * h);
      s = s + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6);
    }
    return s;
  }

  /// The state at time t_end >= t0 from s at t0 by RK4 in the fictitious
  /// time tau of the time transformation dt/dtau = g(-V) (g: the monitor of
  /// time_transformed.hpp, a callable): steps dtau (t integrated with them)
  /// while they end before t_end, then RK4 in t over the rest (less than one
  /// step's dt, in 16 sub-steps). Smooth through a close pass, where RK4 in t
  /// would need tiny steps: a tight reference for the adaptive LGVI.
  /// std::runtime_error if t stops advancing (not finite: a collision).
  template <class Monitor>
  ContinuousState rk4_time_transformed(ContinuousState s, double t0, double t_end, double dtau, Monitor&& g) const {
    // The equations in tau: d(state)/dtau = g(U) d(state)/dt, dt/dtau = g(U), U = -V.
    const auto d = [&](const ContinuousState& x, double& rate) {
      rate = g(-potential_.evaluate(x.x, S3d(x.q)).energy);
      return derivative(x) * rate;
    };
    double t = t0;
    for (;;) {
      double r1 = 0, r2 = 0, r3 = 0, r4 = 0;
      const ContinuousState k1 = d(s, r1);
      const ContinuousState k2 = d(s + k1 * (dtau / 2), r2);
      const ContinuousState k3 = d(s + k2 * (dtau / 2), r3);
      const ContinuousState k4 = d(s + k3 * dtau, r4);
      const double t_next = t + (r1 + 2 * r2 + 2 * r3 + r4) * (dtau / 6);
      if (!(t_next > t))  // not finite, or g so small that t stands still (a collision)
        throw std::runtime_error("the time-transformed RK4 reference stopped advancing at t = " + std::to_string(t) +
                                 " (t + dt = " + std::to_string(t_next) + "): a collision, or a step too large");
      if (t_next > t_end) break;
      s = s + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (dtau / 6);
      t = t_next;
    }
    constexpr long rest_steps = 16;
    return rk4(s, (t_end - t) / rest_steps, rest_steps);
  }

 private:
  RigidBody body_;
  P potential_;
};

}  // namespace lgvi
