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

#include <lgvi/methods/method_traits.hpp>
#include <lgvi/methods/explicit_stepper.hpp>

#include <vector>

namespace lgvi {

template <SystemPotential I>
class EulerExpIntegrator : public detail::ExplicitStepperBase<I> {
 public:
  static constexpr MethodTraits traits{"euler-exp", "semi-implicit Euler with the exponential map", 1,
                                      /*symmetric=*/false, /*two_step=*/false, /*implicit=*/false,
                                      /*accepts_forcing=*/false, /*needs_principal_axes=*/false,
                                      /*free_body_only=*/false, /*linear_bodies=*/false};

  EulerExpIntegrator(System system, I potential, SolverOptions = {}, Parallelism par = {})
      : detail::ExplicitStepperBase<I>(std::move(system), std::move(potential), par, "the Euler integrator") {}

  void step(SystemState& s, double /*t*/, double h) {
    const System& sys = this->system_;
    detail::for_each_body(sys, this->par_, [&](std::size_t a) {
      const RigidBody& body = sys.body(a);
      const Matrix3<double>& jinv = body.inertia_inverse();
      s.p[a] += h * this->eval_.force[a];
      s.x[a] += (h / body.mass()) * s.p[a];
      const Vector3<double> pi0 = 0.5 * s.w[a];
      const Vector3<double> pi1 = pi0 + h * (pi0.cross(jinv * pi0) + this->eval_.torque[a]);
      const Vector3<double> omega1 = jinv * pi1;
      s.q[a] = (s.q[a] * S3d::exp((0.5 * h) * omega1)).normalized();
      s.w[a] = 2.0 * pi1;
    });
    this->evaluate_at(s);
    this->finish_step(s);
  }
};

}  // namespace lgvi
