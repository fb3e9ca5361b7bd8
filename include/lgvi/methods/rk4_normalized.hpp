// Classical explicit RK4 on (x, p, q, Pi) with the quaternion renormalized
// after every step: the "ODE solver + projection" approach of NASA 42,
// Fukushima's recommendation for quaternion integration, and MuJoCo's RK4.
// A non-geometric baseline for the LGVI (lgvi.hpp).
//
// Equations (Pi = w/2 the body angular momentum, Omega = J^{-1} Pi,
// F = -dV/dx inertial, M the body torque; potential.hpp):
//   xdot = p/m,  pdot = F(x, q),
//   qdot = (1/2) q (0, Omega)          (Hamilton product, scalar first),
//   Pidot = Pi x Omega + M(x, q)        (Euler: J Omegadot = J Omega x Omega + M).
// One step is the classical tableau (1/2, 1/2, 1; weights 1/6, 1/3, 1/3, 1/6)
// on the raw 4-vector q, then q <- q/|q|. The exact flow keeps |q| fixed
// for any q (qdot is orthogonal to q), so the unnormalized RK4 is 4th order
// on this extension and the O(h^5) projection keeps that order.
//
// The stage quaternions q + c h k have |q| = 1 + O(h^2); the potential is
// evaluated at q/|q| there (pi(q) is a rotation only on S^3, and S3d's
// invariant is |q| = 1). That is a smooth extension of V off S^3, so the
// order is unaffected.
//
// Cost: 4 potential evaluations per step (k2, k3, k4 and the new state,
// whose evaluation is the next step's k1; initialize() adds one).
// Not symplectic, not symmetric: the energy drifts on long runs (see
// tests/test_methods_classical.cpp).
#pragma once

#include <lgvi/lgvi.hpp>
#include <lgvi/methods/explicit_stepper.hpp>

#include <vector>

namespace lgvi {

template <Potential P>
class Rk4NormalizedIntegrator : public detail::ExplicitStepperBase<P> {
  using Base = detail::ExplicitStepperBase<P>;
  using Base::body_;
  using Base::eval_;
  using Base::h_;
  using Base::potential_;

 public:
  Rk4NormalizedIntegrator(const RigidBody& body, P potential, double h, SolverOptions = {})
      : Base(body, std::move(potential), h, "the RK4 integrator") {}

  void step(RigidBodyState& s) {
    const double h = h_;
    const Y y0{s.x, s.p, s.q.quaternion().coeffs(), 0.5 * s.w};
    const Y k1 = derivative(y0, eval_);
    const Y y1 = axpy(y0, 0.5 * h, k1);
    const Y k2 = derivative(y1, evaluate(y1));
    const Y y2 = axpy(y0, 0.5 * h, k2);
    const Y k3 = derivative(y2, evaluate(y2));
    const Y y3 = axpy(y0, h, k3);
    const Y k4 = derivative(y3, evaluate(y3));
    const double h6 = h / 6.0, h3 = h / 3.0;
    s.x = y0.x + h6 * (k1.x + k4.x) + h3 * (k2.x + k3.x);
    s.p = y0.p + h6 * (k1.p + k4.p) + h3 * (k2.p + k3.p);
    const Vector4<double> q = y0.q + h6 * (k1.q + k4.q) + h3 * (k2.q + k3.q);
    s.q = unit(q);
    s.w = 2.0 * (y0.pi + h6 * (k1.pi + k4.pi) + h3 * (k2.pi + k3.pi));
    eval_ = potential_.evaluate(s.x, s.q);
    detail::require_finite(s, eval_);
  }

 private:
  // q as Eigen's coefficient vector (x, y, z, w); only used internally.
  struct Y {
    Vector3<double> x, p;
    Vector4<double> q;
    Vector3<double> pi;
  };
  static Y axpy(const Y& y, double a, const Y& k) { return {y.x + a * k.x, y.p + a * k.p, y.q + a * k.q, y.pi + a * k.pi}; }
  static S3d unit(const Vector4<double>& c) {
    Eigen::Quaterniond q;
    q.coeffs() = c / c.norm();
    return S3d(q);
  }
  PotentialEvaluation evaluate(const Y& y) const { return potential_.evaluate(y.x, unit(y.q)); }
  Y derivative(const Y& y, const PotentialEvaluation& e) const {
    const Vector3<double> omega = body_.inertia_inverse() * y.pi;
    Eigen::Quaterniond q;
    q.coeffs() = y.q;
    const Eigen::Quaterniond qdot = q * Eigen::Quaterniond(0.0, 0.5 * omega.x(), 0.5 * omega.y(), 0.5 * omega.z());
    return {y.p / body_.mass(), e.force, qdot.coeffs(), y.pi.cross(omega) + e.torque};
  }

};

}  // namespace lgvi
