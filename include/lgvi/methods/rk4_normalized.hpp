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

#include <lgvi/methods/method_traits.hpp>
#include <lgvi/methods/explicit_stepper.hpp>

#include <vector>

namespace lgvi {

template <SystemPotential I>
class Rk4NormalizedIntegrator : public detail::ExplicitStepperBase<I> {
 public:
  static constexpr MethodTraits traits{"rk4-normalized", "classical Runge-Kutta 4, q normalized after each step", 4,
                                      /*symmetric=*/false, /*two_step=*/false, /*implicit=*/false,
                                      /*accepts_forcing=*/false, /*needs_principal_axes=*/false,
                                      /*free_body_only=*/false, /*linear_bodies=*/false};

  Rk4NormalizedIntegrator(System system, I potential, SolverOptions = {}, Parallelism par = {})
      : detail::ExplicitStepperBase<I>(std::move(system), std::move(potential), par, "the RK4 integrator") {
    const std::size_t n = this->system_.size();
    y0_.resize(n);
    k1_.resize(n);
    k2_.resize(n);
    k3_.resize(n);
    k4_.resize(n);
    stage_ = SystemState(n);
    stage_eval_ = SystemEvaluation(n);
  }

  void step(SystemState& s, double /*t*/, double h) {
    const System& sys = this->system_;
    const std::size_t n = sys.size();
    for (std::size_t a = 0; a < n; ++a) {
      y0_[a] = Y{s.x[a], s.p[a], s.q[a].quaternion().coeffs(), 0.5 * s.w[a]};
      k1_[a] = derivative(a, y0_[a], this->eval_);
    }
    stage(0.5 * h, k1_, k2_);
    stage(0.5 * h, k2_, k3_);
    stage(h, k3_, k4_);
    const double h6 = h / 6.0, h3 = h / 3.0;
    for (std::size_t a = 0; a < n; ++a) {
      const Y& y0 = y0_[a];
      const Y &k1 = k1_[a], &k2 = k2_[a], &k3 = k3_[a], &k4 = k4_[a];
      s.x[a] = y0.x + h6 * (k1.x + k4.x) + h3 * (k2.x + k3.x);
      s.p[a] = y0.p + h6 * (k1.p + k4.p) + h3 * (k2.p + k3.p);
      const Vector4<double> q = y0.q + h6 * (k1.q + k4.q) + h3 * (k2.q + k3.q);
      s.q[a] = unit(q);
      s.w[a] = 2.0 * (y0.pi + h6 * (k1.pi + k4.pi) + h3 * (k2.pi + k3.pi));
    }
    this->evaluate_at(s);
    this->finish_step(s);
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
  /// k_out = f(y0 + c k_in), with one evaluation of the system at the stage.
  void stage(double c, const std::vector<Y>& k_in, std::vector<Y>& k_out) {
    const std::size_t n = this->system_.size();
    std::vector<Y> y(n);
    for (std::size_t a = 0; a < n; ++a) {
      y[a] = axpy(y0_[a], c, k_in[a]);
      stage_.x[a] = y[a].x;
      stage_.q[a] = unit(y[a].q);
    }
    this->potential_.evaluate(stage_, stage_eval_);
    for (std::size_t a = 0; a < n; ++a) k_out[a] = derivative(a, y[a], stage_eval_);
  }
  Y derivative(std::size_t a, const Y& y, const SystemEvaluation& e) const {
    const RigidBody& body = this->system_.body(a);
    const Vector3<double> omega = body.inertia_inverse() * y.pi;
    Eigen::Quaterniond q;
    q.coeffs() = y.q;
    const Eigen::Quaterniond qdot = q * Eigen::Quaterniond(0.0, 0.5 * omega.x(), 0.5 * omega.y(), 0.5 * omega.z());
    return {y.p / body.mass(), e.force[a], qdot.coeffs(), y.pi.cross(omega) + e.torque[a]};
  }

  std::vector<Y> y0_, k1_, k2_, k3_, k4_;
  SystemState stage_;
  SystemEvaluation stage_eval_;
};

}  // namespace lgvi
