// The quaternion variational integrator of Wendlandt & Marsden ("Mechanical
// integrators derived from a discrete variational principle", Physica D 106,
// 1997): the attitude q is a vector of R^4, the unit length is a holonomic
// constraint g(q) = |q|^2 - 1 = 0 imposed with a Lagrange multiplier, and the
// constrained discrete Euler-Lagrange equations are taken in RATTLE form
// (position-momentum, one multiplier for the configuration constraint, one
// for the momentum's hidden constraint).
//
// Discrete Lagrangian (the same as the quaternion LGVI's, lgvi.hpp), with
// a(q0, q1) = Im(q0^* q1) = F(q0) q1 = -F(q1) q0 (bilinear in R^4):
//   L_d = h( m|x1 - x0|^2/(2h^2) + (2/h^2) a^T J a - (V(q0) + V(q1))/2 ).
// V is extended off S^3 by V(q) = V(q/|q|), so dV/dq has no radial part and
// F(q) dV/dq = -2 M (potential.hpp) gives dV/dq = -2 F(q)^T M for unit q
// (F(q) F(q)^T = |q|^2 I, F(q) q = 0). Then
//   D1 L_d = -(4/h) F(q1)^T J a + h F(q0)^T M0,   D2 L_d = (4/h) F(q0)^T J a + h F(q1)^T M1.
//
// Momentum in R^4. For the continuous Lagrangian 2 xi^T J xi, xi = Im(q^* qdot)
// = F(q) qdot, the conjugate momentum in R^4 is
//   pi_q = dL/dqdot = 4 F(q)^T J xi = F(q)^T w     (w = 4 J xi = 2 J Omega),
// i.e. pi_q = q (0, w) (the quaternion product; F's definition). It is
// orthogonal to q (F(q) q = 0), and w = F(q) pi_q = Im(q^* pi_q) for unit q.
// (The R^4 Lagrangian is degenerate along q: L does not see qdot || q.) These
// are the conversions at the boundary: the state crossing the interface is w.
//
// One step (RATTLE), unknowns q1 in R^4 and the multiplier lambda:
//   pi_0 = -D1 L_d(q0, q1) + lambda q0,   |q1|^2 = 1,
//   pi_1 =  D2 L_d(q0, q1) + mu q1,       q1 . pi_1 = 0  (the hidden constraint).
// With b = (h/4)(w0 + h M0) and nu = (h/4) lambda (a better-scaled unknown),
// the first line is the 5 x 5 system solved by Newton (analytic Jacobian):
//   r(q1, nu) = F(q1)^T J F(q0) q1 + nu q0 - q0 (0, b) = 0,   |q1|^2 - 1 = 0,
//   d r/d q1 = Rp(J F(q0) q1) + F(q1)^T J F(q0),  d r/d nu = q0,
// Rp(c) the right multiplication by (0, c): q (0, c) = Rp(c) q = F(q)^T c.
// Multiplying the first line by F(q0) gives the LGVI's g(f) = b (f = q0^* q1),
// by q0^T gives nu = f_v^T J f_v: the multiplier is the rotational kinetic
// term, lambda = (4/h) a^T J a. The second line's mu drops out of
// w1 = F(q1) pi_1 (F(q1) q1 = 0), so
//   w1 = Im(q1^* ((4/h) q0 (0, J a) + h q1 (0, M1))),
// equal to the LGVI's (4/h)(f_s J f_v - f_v x J f_v) + h M1. This literal
// form takes (4/h) times the solve's residual into w1, as lgvi.hpp notes for
// the paper's formula; this class keeps Wendlandt & Marsden's D2 L_d rather
// than the LGVI's rotated form pi(f)^T (w0 + h M0) + h M1 (the difference in
// angular momentum, measured: docs/tuning.md). The translational
// part is the LGVI's (x1 = x0 + (h/m)(p0 + h/2 F0), p1 = p0 + h/2 (F0 + F1)).
// Same L_d, same equations on the constraint: the same trajectory as the
// LGVI, to rounding. Unlike the LGVI, q1 comes out of the solve rather than a
// product of unit quaternions, so |q| - 1 is the constraint residual after
// Newton (round-off, not accumulated: each step imposes it afresh).
#pragma once

#include <lgvi/methods/method_traits.hpp>
#include <lgvi/error.hpp>
#include <lgvi/methods/implicit_stepper.hpp>
#include <lgvi/potential.hpp>
#include <lgvi/rigid_body.hpp>
#include <lgvi/rotation_solver.hpp>
#include <lgvi/s3.hpp>
#include <lgvi/state.hpp>

#include <Eigen/LU>

#include <cmath>
#include <string>
#include <vector>

namespace lgvi {

namespace rattle {

using Vector5 = Eigen::Matrix<double, 5, 1>;
using Matrix5 = Eigen::Matrix<double, 5, 5>;
using Matrix4 = Eigen::Matrix<double, 4, 4>;

/// Quaternion product of 4-vectors, scalar first.
inline Vector4<double> product(const Vector4<double>& a, const Vector4<double>& b) {
  return Vector4<double>(a(0) * b(0) - a(1) * b(1) - a(2) * b(2) - a(3) * b(3),
                         a(0) * b(1) + a(1) * b(0) + a(2) * b(3) - a(3) * b(2),
                         a(0) * b(2) - a(1) * b(3) + a(2) * b(0) + a(3) * b(1),
                         a(0) * b(3) + a(1) * b(2) - a(2) * b(1) + a(3) * b(0));
}
/// F(q) y = Im(q^* y) (s3.hpp's F, on 4-vectors).
inline Vector3<double> F_times(const Vector4<double>& q, const Vector4<double>& y) {
  const Vector3<double> qv = q.tail<3>(), yv = y.tail<3>();
  return q(0) * yv - y(0) * qv - qv.cross(yv);
}
/// F(q)^T c = q (0, c).
inline Vector4<double> FT_times(const Vector4<double>& q, const Vector3<double>& c) {
  const Vector3<double> qv = q.tail<3>();
  Vector4<double> r;
  r(0) = -qv.dot(c);
  r.tail<3>() = q(0) * c + qv.cross(c);
  return r;
}
inline Matrix34<double> F_matrix(const Vector4<double>& q) {
  return F<double>(Eigen::Quaterniond(q(0), q(1), q(2), q(3)));
}

/// The 5 equations r(q1, nu) (the first 4) and |q1|^2 - 1.
inline Vector5 residual(const Matrix3<double>& J, const Vector4<double>& q0, const Vector4<double>& rhs,
                        const Vector4<double>& q1, double nu) {
  Vector5 r;
  r.head<4>() = FT_times(q1, J * F_times(q0, q1)) + nu * q0 - rhs;
  r(4) = q1.squaredNorm() - 1.0;
  return r;
}

/// Its Jacobian in (q1, nu).
inline Matrix5 jacobian(const Matrix3<double>& J, const Vector4<double>& q0, const Vector4<double>& q1) {
  const Vector3<double> c = J * F_times(q0, q1);
  Matrix4 rp;  // q (0, c) = rp q
  rp(0, 0) = 0.0;
  rp.block<1, 3>(0, 1) = -c.transpose();
  rp.block<3, 1>(1, 0) = c;
  rp.block<3, 3>(1, 1) = -S3d::hat(c);
  Matrix5 d;
  d.topLeftCorner<4, 4>() = rp + F_matrix(q1).transpose() * J * F_matrix(q0);
  d.block<4, 1>(0, 4) = q0;
  d.block<1, 4>(4, 0) = 2.0 * q1.transpose();
  d(4, 4) = 0.0;
  return d;
}

}  // namespace rattle

template <SystemPotential I>
class RattleQuaternionIntegrator : public detail::ImplicitStepperBase<I, RotationPredictor> {
  using Base = detail::ImplicitStepperBase<I, RotationPredictor>;

 public:
  static constexpr MethodTraits traits{"rattle-quaternion", "RATTLE on quaternions (Wendlandt & Marsden): unit length by a multiplier", 2,
                                      /*symmetric=*/true, /*two_step=*/false, /*implicit=*/true,
                                      /*accepts_forcing=*/false, /*needs_principal_axes=*/false,
                                      /*free_body_only=*/false, /*linear_bodies=*/false};

  /// `solver.tolerance`, `max_iterations` and `predictor_order` apply;
  /// `solver.kind` does not (always Newton on the 5 x 5 system).
  RattleQuaternionIntegrator(System system, I potential, SolverOptions solver = {}, Parallelism par = {})
      : Base(std::move(system), std::move(potential), solver, par) {
    detail::require_three_moments(this->system_, "the RATTLE integrator");
    const std::size_t n = this->system_.size();
    for (const RigidBody& b : system_bodies(this->system_)) J_norm_.push_back(b.inertia().norm());
    q0_.resize(n);
    lambda_.assign(n, 0.0);
  }

  using Base::initialize;

  void step(SystemState& s, double /*t*/, double h) {
    const System& sys = this->system_;
    detail::for_each_body(sys, this->par_, [&](std::size_t a) {
      const RigidBody& body = sys.body(a);
      const Matrix3<double>& J = body.inertia();
      const Vector4<double> q0 = s.q[a].scalar_first();
      const Vector3<double> b = (0.25 * h) * (s.w[a] + h * this->eval_.torque[a]);
      // pi_0 + h F(q0)^T M0 = F(q0)^T (w0 + h M0), scaled by h/4.
      const Vector4<double> rhs = rattle::FT_times(q0, b);
      RotationPredictor& predictor = this->predictor(a);
      if (predictor.empty()) predictor.reset(S3d::exp(body.inertia_inverse() * b));
      const S3d guess = predictor.predict();
      Vector4<double> q1 = rattle::product(q0, guess.scalar_first());
      const Vector3<double> gv = guess.vec();
      double nu = gv.dot(J * gv);
      solve(a, q0, rhs, b, q1, nu);
      const Vector4<double> f = rattle::product(Vector4<double>(q0(0), -q0(1), -q0(2), -q0(3)), q1);
      if (!(f(0) > 0.0))
        throw StepFailure("RATTLE quaternion: the rotation in one step reached pi (Re(q0^* q1) <= 0)",
                          detail::smaller_step_hint_pi);
      predictor.push(S3d(f(0), f(1), f(2), f(3)));
      lambda_[a] = (4.0 / h) * nu;
      this->drift(s, a, h);
      q0_[a] = q0;
      s.q[a] = S3d(q1(0), q1(1), q1(2), q1(3));
    });
    this->evaluate_at(s);
    detail::for_each_body(sys, this->par_, [&](std::size_t a) {
      this->kick(s, a, h);
      // pi_1 = D2 L_d (mu q1 dropped: F(q1) q1 = 0), w1 = F(q1) pi_1.
      const Vector4<double> q1 = s.q[a].scalar_first();
      const Vector3<double> fa = rattle::F_times(q0_[a], q1);
      const Vector4<double> pi1 = (4.0 / h) * rattle::FT_times(q0_[a], sys.body(a).inertia() * fa) +
                                  h * rattle::FT_times(q1, this->eval_.torque[a]);
      s.w[a] = rattle::F_times(q1, pi1);
    });
    this->finish_step(s);
  }

  /// The last step's multiplier lambda of |q1|^2 = 1 (= (4/h) a^T J a) of body a.
  double last_multiplier(std::size_t a = 0) const { return lambda_[a]; }

  /// The momentum conjugate to q in R^4 and back (see the header comment).
  static Vector4<double> momentum_r4(const S3d& q, const Vector3<double>& w) {
    return rattle::FT_times(q.scalar_first(), w);
  }
  static Vector3<double> momentum_w(const S3d& q, const Vector4<double>& pi_q) {
    return rattle::F_times(q.scalar_first(), pi_q);
  }

  void resume(const SystemState& s, double t, const std::vector<double>& internal) {
    initialize(s, t);
    this->restore(internal, "the predictor");
  }
  /// Resumes from a checkpoint's fields (ImplicitStepperBase::save).
  void load(const SystemState& s, double t, const CheckpointFields& in) {
    initialize(s, t);
    this->load_fields(in, "the predictor");
  }

 private:
  void solve(std::size_t a, const Vector4<double>& q0, const Vector4<double>& rhs, const Vector3<double>& b,
             Vector4<double>& q1, double& nu) {
    SolveReport& report = this->reports_[a];
    const SolverOptions& opt = this->opt_;
    report = {};
    const Matrix3<double>& J = this->system_.body(a).inertia();
    const double scale = b.lpNorm<Eigen::Infinity>();
    for (;;) {
      const rattle::Vector5 r = rattle::residual(J, q0, rhs, q1, nu);
      ++report.residual_evaluations;
      if (r.head<4>().lpNorm<Eigen::Infinity>() <= opt.tolerance * scale && std::abs(r(4)) <= opt.tolerance) break;
      if (report.iterations >= opt.max_iterations)
        throw StepFailure("RATTLE quaternion: Newton iteration for (q1, lambda) did not converge in " +
                              std::to_string(opt.max_iterations) + " iterations",
                          detail::smaller_step_hint);
      const rattle::Vector5 delta = rattle::jacobian(J, q0, q1).partialPivLu().solve(r);
      q1 -= delta.head<4>();
      nu -= delta(4);
      ++report.iterations;
      if (!(q1.allFinite() && std::isfinite(nu)))
        throw StepFailure("RATTLE quaternion: the Newton iteration diverged",
                          detail::smaller_step_hint);
      // The system is quadratic: after a Newton update the residual is
      // exactly (F(dq)^T J F(q0) dq, |dq|^2), bounded by (|J| |dq|^2, |dq|^2).
      const double d2 = delta.head<4>().squaredNorm();
      if (J_norm_[a] * d2 <= opt.tolerance * scale && d2 <= opt.tolerance) break;
      if (delta.head<4>().lpNorm<Eigen::Infinity>() <= opt.tolerance) break;
    }
  }

  std::vector<double> J_norm_;
  std::vector<Vector4<double>> q0_;
  std::vector<double> lambda_;
};

}  // namespace lgvi
