// Semi-implicit Euler with the exponential map: the game-physics / robotics
// default (Bullet, ODE, PhysX, Box2D's 2-D analogue; "symplectic Euler" for
// the translation). A first-order, non-geometric baseline.
//
// The exact variant (Pi = w/2, Omega = J^{-1} Pi, F and M at the step's start):
//   p1  = p0 + h F(x0, q0)                      (kick)
//   x1  = x0 + h p1 / m                          (drift with the new momentum)
//   Pi1 = Pi0 + h (Pi0 x Omega0 + M(x0, q0))     (explicit Euler, old gyroscopic term)
//   q1  = normalize(q0 * exp(h Omega1 / 2))      (new angular velocity, Omega1 = J^{-1} Pi1)
// exp is S3d::exp, exp(xi) = (cos|xi|, sin|xi| xi/|xi|), so exp(h Omega1/2)
// is the body rotation by the angle vector h Omega1. The product of unit
// quaternions stays unit up to rounding; the normalization (as the engines
// do) only removes that rounding.
//
// Translation alone is symplectic Euler; the rotation is not (the explicit
// gyroscopic term pumps energy), so the whole method is first order and
// neither symplectic nor symmetric.
//
// Cost: 1 potential evaluation per step (the evaluation at the new state is
// the next step's F0, M0; initialize() adds one).
#pragma once

#include <lgvi/lgvi.hpp>
#include <lgvi/methods/explicit_stepper.hpp>

#include <vector>

namespace lgvi {

template <Potential P>
class EulerExpIntegrator : public detail::ExplicitStepperBase<P> {
  using Base = detail::ExplicitStepperBase<P>;
  using Base::body_;
  using Base::eval_;
  using Base::h_;
  using Base::potential_;

 public:
  EulerExpIntegrator(const RigidBody& body, P potential, double h, SolverOptions = {})
      : Base(body, std::move(potential), h, "the Euler integrator") {}

  void step(RigidBodyState& s) {
    const double h = h_;
    const Matrix3<double>& jinv = body_.inertia_inverse();
    s.p += h * eval_.force;
    s.x += (h / body_.mass()) * s.p;
    const Vector3<double> pi0 = 0.5 * s.w;
    const Vector3<double> pi1 = pi0 + h * (pi0.cross(jinv * pi0) + eval_.torque);
    const Vector3<double> omega1 = jinv * pi1;
    Eigen::Quaterniond q = (s.q * S3d::exp((0.5 * h) * omega1)).quaternion();
    q.normalize();
    s.q = S3d(q);
    s.w = 2.0 * pi1;
    eval_ = potential_.evaluate(s.x, s.q);
    detail::require_finite(s, eval_);
  }
};

}  // namespace lgvi
