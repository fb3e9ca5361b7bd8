// The rotation-matrix Lie group variational integrator of Lee, Leok &
// McClamroch ("A Lie group variational integrator for the attitude dynamics
// of a rigid body with applications to the 3D pendulum", 2005; "Lie group
// variational integrators for the full body problem", 2007), on the same
// interface as the quaternion LGVI (lgvi.hpp).
//
// Internal state: R_k in SO(3) (9 numbers, against 4 for q), with
// J_d = tr(J)/2 I - J (the nonstandard inertia), Pi = J Omega = w / 2 (exact:
// a power-of-two scaling, so w stays the state crossing the interface).
// One step (F_k = R_k^T R_{k+1}, M the body torque, F^x the force):
//   h Pi_k + (h^2/2) M_k = (F_k J_d - J_d F_k^T)^vee           solve for F_k
//   R_{k+1} = R_k F_k
//   x_{k+1} = x_k + (h/m)(p_k + (h/2) F^x_k)
//   p_{k+1} = p_k + (h/2)(F^x_k + F^x_{k+1})
//   Pi_{k+1} = F_k^T Pi_k + (h/2) F_k^T M_k + (h/2) M_{k+1}
//            i.e. w_{k+1} = F_k^T (w_k + h M_k) + h M_{k+1}.
// The implicit equation is solved as Lee et al. do, in the Cayley chart
// F = cay(u) = (I + hat u)(I - hat u)^{-1} = I + 2/(1 + |u|^2) (hat u + hat u^2):
//   (F J_d - J_d F^T)^vee = 2 (J u + u x J u) / (1 + |u|^2),
// i.e. J u + u x J u - (1 + |u|^2) b = 0 with b = (h/4)(w_k + h M_k), by
// Newton with the exact Jacobian J + hat(u) J - hat(J u) - 2 b u^T (the
// polynomial and Jacobian of rotation_solver.hpp's RotationEquation). The
// start is the cubic extrapolation of the last steps' u (as RotationPredictor
// does for f_v in the quaternion method).
//
// Equivalence with the quaternion LGVI. For F = pi(f), f = (f_s, f_v) unit,
//   tr[(I - F) J_d] = 2 f_v^T J f_v   and   (F J_d - J_d F^T)^vee = 2 (f_s J f_v + f_v x J f_v),
// so the discrete Lagrangians and the step equations coincide (u = f_v / f_s
// is the quaternion solver's Cayley chart): the two methods compute the same
// trajectory, up to rounding (tests/test_methods_variational.cpp).
//
// The reported attitude. The state crossing the interface holds q, so each
// step lifts R_{k+1} to a unit quaternion (Shepperd's method, normalized),
// choosing the sign of the lift closest to the previous q (q_{k+1} . q_k > 0):
// the reported q then follows the quaternion LGVI's q, sign included. The
// potential is evaluated at that q. Because the lift is normalized, |q| - 1 is
// NOT a diagnostic of this method (it is rounding of the normalization, ~eps,
// whatever R does); R's own deviation from SO(3), ||R^T R - I||, is:
// `orthogonality_error()`. Nothing re-orthonormalizes R.
//
// step() continues from the R it keeps: a caller that changes the state's q
// between steps must call initialize() (as for the other methods, whose
// potential evaluation is also cached).
#pragma once

#include <lgvi/methods/method_traits.hpp>
#include <lgvi/error.hpp>
#include <lgvi/methods/implicit_stepper.hpp>
#include <lgvi/potential.hpp>
#include <lgvi/rigid_body.hpp>
#include <lgvi/rotation_solver.hpp>
#include <lgvi/s3.hpp>
#include <lgvi/state.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

namespace lgvi {

namespace detail {

/// Cubic (or lower-order) extrapolation of the last steps' Cayley vectors u.
class CayleyPredictor {
 public:
  explicit CayleyPredictor(int order = 3) : order_(std::clamp(order, 0, 3)) {}
  void reset(const Vector3<double>& u) {
    count_ = 0;
    push(u);
  }
  void push(const Vector3<double>& u) {
    for (int i = 3; i > 0; --i) v_[static_cast<std::size_t>(i)] = v_[static_cast<std::size_t>(i - 1)];
    v_[0] = u;
    count_ = std::min(count_ + 1, 4);
  }
  Vector3<double> predict() const {
    switch (std::min(count_, order_ + 1)) {
      case 4: return 4.0 * (v_[0] + v_[2]) - 6.0 * v_[1] - v_[3];
      case 3: return 3.0 * (v_[0] - v_[1]) + v_[2];
      case 2: return 2.0 * v_[0] - v_[1];
      default: return v_[0];
    }
  }
  std::vector<double> serialize() const {
    std::vector<double> out{static_cast<double>(count_)};
    for (const auto& v : v_) out.insert(out.end(), {v.x(), v.y(), v.z()});
    return out;
  }
  bool empty() const { return count_ == 0; }
  void deserialize(const std::vector<double>& in) {
    if (in.size() != serialized_size) throw InvalidInput("checkpoint: predictor data has the wrong size");
    count_ = std::clamp(static_cast<int>(in[0]), 0, 4);
    for (int i = 0; i < 4; ++i) v_[static_cast<std::size_t>(i)] = Vector3<double>(in[1 + 3 * i], in[2 + 3 * i], in[3 + 3 * i]);
  }
  static constexpr std::size_t serialized_size = 13;

 private:
  std::array<Vector3<double>, 4> v_{Vector3<double>::Zero(), Vector3<double>::Zero(), Vector3<double>::Zero(),
                                    Vector3<double>::Zero()};
  int count_ = 0;
  int order_;
};

/// cay(u) = I + 2/(1 + |u|^2) (hat u + hat u^2), hat u^2 = u u^T - |u|^2 I.
inline Matrix3<double> cayley(const Vector3<double>& u) {
  const double n2 = u.squaredNorm();
  const double k = 2.0 / (1.0 + n2);
  const Vector3<double> ku = k * u;
  Matrix3<double> f;
  const double d = 1.0 - k * n2;
  f(0, 0) = d + ku.x() * u.x();
  f(1, 1) = d + ku.y() * u.y();
  f(2, 2) = d + ku.z() * u.z();
  const double xy = ku.x() * u.y(), xz = ku.x() * u.z(), yz = ku.y() * u.z();
  f(0, 1) = xy - ku.z();
  f(1, 0) = xy + ku.z();
  f(0, 2) = xz + ku.y();
  f(2, 0) = xz - ku.y();
  f(1, 2) = yz - ku.x();
  f(2, 1) = yz + ku.x();
  return f;
}

}  // namespace detail

template <SystemPotential I>
class So3LieGroupVariationalIntegrator : public detail::ImplicitStepperBase<I, detail::CayleyPredictor> {
  using Base = detail::ImplicitStepperBase<I, detail::CayleyPredictor>;

 public:
  static constexpr MethodTraits traits{"so3-lgvi", "the rotation-matrix LGVI of Lee, Leok & McClamroch", 2,
                                      /*symmetric=*/true, /*two_step=*/false, /*implicit=*/true,
                                      /*accepts_forcing=*/true, /*needs_principal_axes=*/false,
                                      /*free_body_only=*/false, /*linear_bodies=*/false};

  /// `solver.tolerance`, `max_iterations` and `predictor_order` apply;
  /// `solver.kind` does not: this method always uses Newton in the Cayley
  /// chart (Lee et al.'s choice).
  So3LieGroupVariationalIntegrator(System system, I potential, SolverOptions solver = {}, Parallelism par = {})
      : Base(std::move(system), std::move(potential), solver, par) {
    detail::require_three_moments(this->system_, "the SO(3) LGVI");
    const std::size_t n = this->system_.size();
    for (const RigidBody& b : system_bodies(this->system_)) {
      equations_.emplace_back(b.inertia());
      jd_.emplace_back((0.5 * b.inertia().trace()) * Matrix3<double>::Identity() - b.inertia());
    }
    R_.assign(n, Matrix3<double>::Identity());
    w_half_.resize(n);
    F_.resize(n);
  }

  /// R = pi(q); the potential is evaluated at s; the first solve starts from
  /// the first-order estimate u ~ J^{-1} b.
  void initialize(const SystemState& s, double t) {
    Base::initialize(s, t);
    for (std::size_t a = 0; a < s.size(); ++a) R_[a] = s.q[a].matrix();
  }

  /// One step; with a forcing, F and M are the potential's plus the
  /// forcing's at both ends (forcing.hpp), as in the quaternion LGVI.
  void step(SystemState& s, double t, double h) {
    const System& sys = this->system_;
    this->begin_step(s, t);
    detail::for_each_body(sys, this->par_, [&](std::size_t a) {
      w_half_[a] = s.w[a] + h * this->torque(a);  // 2 (Pi_k + (h/2) M_k)
      detail::CayleyPredictor& predictor = this->predictor(a);
      if (predictor.empty()) predictor.reset(sys.body(a).inertia_inverse() * ((0.25 * h) * w_half_[a]));
      Vector3<double> u = predictor.predict();
      solve(a, (0.25 * h) * w_half_[a], u);
      predictor.push(u);
      F_[a] = detail::cayley(u);
      this->drift(s, a, h);
      R_[a] = (R_[a] * F_[a]).eval();
      s.q[a] = lift(R_[a], s.q[a]);
    });
    this->evaluate_at(s);
    this->end_step(s, t + h, h, [&](std::size_t a) {
      this->kick(s, a, h);
      s.w[a] = F_[a].transpose() * w_half_[a] + h * this->torque(a);
    });
    this->finish_step(s);
  }

  /// Adds a forcing by the discrete Lagrange-d'Alembert principle (forcing.hpp). Before initialize().
  void set_forcing(ForcingSet forcing) { this->install_forcing(std::move(forcing)); }

  /// The attitude of body a as this method keeps it.
  const Matrix3<double>& rotation_matrix(std::size_t a = 0) const { return R_[a]; }
  /// J_d = tr(J)/2 I - J of body a.
  const Matrix3<double>& nonstandard_inertia(std::size_t a = 0) const { return jd_[a]; }
  /// ||R^T R - I||_F of body a: R's deviation from SO(3) (rounding of the
  /// products R_k F_k accumulates; nothing projects it back).
  double orthogonality_error(std::size_t a = 0) const {
    return (R_[a].transpose() * R_[a] - Matrix3<double>::Identity()).norm();
  }

  /// For a bit-identical resume, per body: R (9 numbers, row-major), then the
  /// predictor's history (count and 4 vectors u, newest first).
  void resume(const SystemState& s, double t, const std::vector<double>& internal) {
    initialize(s, t);
    this->restore(internal, "SO(3) integrator");
  }
  /// Resumes from a checkpoint's fields: the base's (ImplicitStepperBase::save)
  /// and "stepper.rotation_matrix", per body R (9 numbers, row-major).
  void load(const SystemState& s, double t, const CheckpointFields& in) {
    initialize(s, t);
    this->load_fields(in, "SO(3) integrator");
  }

  /// The unit quaternion of R closest to `previous` (sign with positive
  /// inner product), by Shepperd's method, normalized.
  static S3d lift(const Matrix3<double>& r, const S3d& previous) {
    Eigen::Quaterniond q(r);
    const double d = S3d(q).dot(previous);
    const double n = q.norm();
    q.coeffs() *= (d < 0.0 ? -1.0 : 1.0) / n;
    return S3d(q);
  }

 private:
  void serialize_extra(std::size_t a, std::vector<double>& v) const override {
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) v.push_back(R_[a](i, j));
  }
  std::size_t extra_size() const override { return 9; }
  void save_extra(CheckpointFields& out) const override {
    std::vector<double> r;
    for (const Matrix3<double>& m : R_)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) r.push_back(m(i, j));
    out.put_f64("stepper.rotation_matrix", std::move(r));
  }
  void load_extra(const CheckpointFields& in) override {
    const std::vector<double>& r = in.f64("stepper.rotation_matrix", 9 * R_.size());
    for (std::size_t a = 0; a < R_.size(); ++a)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) R_[a](i, j) = r[9 * a + static_cast<std::size_t>(3 * i + j)];
  }
  void deserialize_extra(std::size_t a, const double* d) override {
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) R_[a](i, j) = d[i * 3 + j];
  }

  /// Newton on c(u) = J u + u x J u - (1 + |u|^2) b = 0, with the stopping
  /// rules of RotationSolver's Cayley-chart Newton.
  void solve(std::size_t a, const Vector3<double>& b, Vector3<double>& u) {
    SolveReport& report = this->reports_[a];
    const RotationEquation& equation = equations_[a];
    const SolverOptions& opt = this->opt_;
    report = {};
    const double b_scale = b.lpNorm<Eigen::Infinity>();
    for (;;) {
      const Vector3<double> r = equation.cayley_residual(u, b);
      ++report.residual_evaluations;
      if (r.lpNorm<Eigen::Infinity>() <= opt.tolerance * (1.0 + u.squaredNorm()) * b_scale) break;
      if (report.iterations >= opt.max_iterations)
        throw StepFailure("SO(3) LGVI: Newton iteration for F_k did not converge in " +
                              std::to_string(opt.max_iterations) + " iterations",
                          detail::smaller_step_hint);
      const Vector3<double> delta = detail::solve_3x3(equation.cayley_jacobian(u, b), r);
      u -= delta;
      ++report.iterations;
      if (!u.allFinite())
        throw StepFailure("SO(3) LGVI: the rotation in one step reached pi (the Cayley chart's boundary)",
                          detail::smaller_step_hint_pi);
      // The residual after a Newton step of this quadratic is
      // delta x J delta - |delta|^2 b: stop when its bound is below tolerance.
      const double d2 = delta.squaredNorm();
      if ((equation.inertia_norm() + b.norm()) * d2 <= opt.tolerance * b_scale) break;
      if (delta.lpNorm<Eigen::Infinity>() <= opt.tolerance * u.lpNorm<Eigen::Infinity>()) break;
    }
  }

  std::vector<RotationEquation> equations_;
  std::vector<Matrix3<double>> jd_, R_, F_;
  std::vector<Vector3<double>> w_half_;
};

}  // namespace lgvi
