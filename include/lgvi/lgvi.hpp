// The quaternion Lie group variational integrator of Shen & Leok, in its
// Hamiltonian form (the default) and its Lagrangian (position-position) form.
//
// Discrete Lagrangian (paper eq. "discrtelag", from Wendlandt & Marsden):
//   L_d = h( m|x1 - x0|^2/(2h^2) + (2/h^2) Im(q0^* q1)^T J Im(q0^* q1) - (V0 + V1)/2 ).
// With force F = -dV/dx and body torque M (F(q) dV/dq = -2 M, potential.hpp)
// and f = q0^* q1 = exp(xi0), the paper's Hamiltonian system "eqhamilton" is
//   p0 = m (x1 - x0)/h - (h/2) F0                   -> x1 = x0 + (h/m)(p0 + (h/2) F0)
//   w0 = (4/h)(f_s J f_v + f_v x J f_v) - h M0      -> solve for xi0 (rotation_solver.hpp)
//   p1 = m (x1 - x0)/h + (h/2) F1                   =  p0 + (h/2)(F0 + F1)
//   w1 = (4/h) G(f) J Im(f) + h M1                  =  (4/h)(f_s J f_v - f_v x J f_v) + h M1
// p1 and w1 are computed in their second, algebraically equal forms:
//  * m (x1 - x0)/h loses about log10(|x|/|x1 - x0|) digits to cancellation
//    (two orders on the paper's orbit), which shows directly in x cross p;
//  * (4/h)(f_s J f_v - f_v x J f_v) = pi(f)^T (4/h)(f_s J f_v + f_v x J f_v)
//    = pi(f)^T (w0 + h M0) holds for |f| = 1 exactly; evaluated as the paper
//    writes it, the solver's residual and the rounding of |f| (the same each
//    step for a steady spin) enter w1 as a systematic error, which made the
//    angular momentum drift linearly (4e-12 over 1e5 steps on the paper's
//    orbit, against 3e-13 with the rotated form; see tests/test_lgvi.cpp).
#pragma once

#include <lgvi/error.hpp>
#include <lgvi/potential.hpp>
#include <lgvi/rigid_body.hpp>
#include <lgvi/rotation_solver.hpp>
#include <lgvi/s3.hpp>
#include <lgvi/state.hpp>

#include <cmath>
#include <concepts>
#include <string>
#include <vector>

namespace lgvi {

/// The contract of a one-step method: initialize at a state (evaluating the
/// potential there), then advance by step() in place. evaluation() is the
/// potential at the current state, for diagnostics, with no extra cost.
template <class S>
concept Stepper = requires(S& s, const S& cs, RigidBodyState& state) {
  { s.initialize(state) };
  { s.step(state) };
  { cs.step_size() } -> std::convertible_to<double>;
  { cs.evaluation() } -> std::convertible_to<PotentialEvaluation>;
  { cs.last_solve() } -> std::convertible_to<SolveReport>;
};

namespace detail {
inline void require_finite(const RigidBodyState& s, const PotentialEvaluation& e) {
  // One test on a sum: a NaN or infinity anywhere makes it non-finite
  // (inf - inf is NaN), so the common case costs one branch.
  const double sum = s.x.sum() + s.q.quaternion().coeffs().sum() + s.p.sum() + s.w.sum() + e.energy + e.force.sum() +
                     e.torque.sum();
  if (std::isfinite(sum)) return;
  if (!s.all_finite()) throw StepFailure("the state became non-finite", "try a smaller step");
  if (!e.all_finite())
    throw StepFailure("the potential returned a non-finite energy, force or torque (a ball at the field's centre?)",
                      "check the initial state; a smaller step resolves close encounters better");
}
inline void require_valid_step(double h) {
  if (!(std::isfinite(h) && h > 0.0))
    throw InvalidInput("integrator.step: must be a finite number > 0, got " + std::to_string(h));
}
}  // namespace detail

/// The Hamiltonian-side quaternion LGVI on (x, q, p, w).
template <Potential P>
class LieGroupVariationalIntegrator {
 public:
  LieGroupVariationalIntegrator(const RigidBody& body, P potential, double h, SolverOptions solver = {})
      : body_(body),
        potential_(std::move(potential)),
        h_(h),
        solver_(body.inertia(), solver),
        predictor_(solver.predictor_order) {
    detail::require_valid_step(h);
  }

  /// Evaluates the potential at s and seeds the solver's initial guess with
  /// the first-order estimate xi0 ~ J^{-1} b.
  void initialize(const RigidBodyState& s) {
    eval_ = potential_.evaluate(s.x, s.q);
    detail::require_finite(s, eval_);
    // b = (h/4)(w0 + h M0), the right side of g(xi0) = b; xi0 ~ J^{-1} b.
    predictor_.reset(S3d::exp(body_.inertia_inverse() * ((0.25 * h_) * (s.w + h_ * eval_.torque))));
  }

  /// One step of the paper's system "eqhamilton" (forms above). The solver
  /// starts from the RotationPredictor's extrapolation of the last steps' f.
  void step(RigidBodyState& s) {
    const double h = h_;
    const Vector3<double> p_half = s.p + (0.5 * h) * eval_.force;
    const Vector3<double> w_half = s.w + h * eval_.torque;  // w0 + h M0 = (4/h) g(f)
    S3d f = predictor_.predict();
    solver_.solve((0.25 * h) * w_half, f, report_);
    predictor_.push(f);
    s.x += (h / body_.mass()) * p_half;
    s.q = s.q * f;
    const PotentialEvaluation e1 = potential_.evaluate(s.x, s.q);
    s.p = p_half + (0.5 * h) * e1.force;
    s.w = f.inverse().act(w_half) + h * e1.torque;
    eval_ = e1;
    detail::require_finite(s, eval_);
  }

  double step_size() const { return h_; }
  const PotentialEvaluation& evaluation() const { return eval_; }
  const SolveReport& last_solve() const { return report_; }
  const RigidBody& body() const { return body_; }
  const P& potential() const { return potential_; }
  /// What a checkpoint must keep besides the state for a bit-identical
  /// resume: the predictor's history of the last steps' f.
  std::vector<double> internal_state() const { return predictor_.serialize(); }
  /// Resumes at `s` (evaluating the potential there) with saved internals.
  void resume(const RigidBodyState& s, const std::vector<double>& internal) {
    initialize(s);
    predictor_.deserialize(internal);
  }

 private:
  RigidBody body_;
  P potential_;
  double h_;
  RotationSolver solver_;
  PotentialEvaluation eval_;
  RotationPredictor predictor_;
  SolveReport report_;
};

/// The Lagrangian-side (position-position) form: the paper's discrete
/// Euler-Lagrange equations
///   m (x2 - 2 x1 + x0)/h^2 = F1,
///   G(q0^* q1) J Im(q0^* q1) + G(q2^* q1) J Im(q2^* q1) = (h^2/4) F(q1) dV/dq(x1, q1) = -(h^2/2) M1,
/// i.e. with f0 = q0^* q1, f1 = q1^* q2 (G(f1^*) J Im(f1^*) = -g(f1)):
///   g(f1) = f0_s J f0_v - f0_v x J f0_v + (h^2/2) M1.
/// The first step from (x0, q0, p0, w0) comes from the discrete Legendre
/// transform p0 = -D1 L_d, the same equation as the Hamiltonian step; the
/// momenta reported along the way are p_k = D2 L_d(k-1, k):
///   p_k = m (x_k - x_{k-1})/h + (h/2) F_k,  w_k = (4/h)(f_s J f_v - f_v x J f_v) + h M_k.
/// (That p_k pays the cancellation in x_k - x_{k-1}, inherent to this form.)
template <Potential P>
class LagrangianLieGroupVariationalIntegrator {
 public:
  LagrangianLieGroupVariationalIntegrator(const RigidBody& body, P potential, double h, SolverOptions solver = {})
      : body_(body),
        potential_(std::move(potential)),
        h_(h),
        solver_(body.inertia(), solver),
        predictor_(solver.predictor_order) {
    detail::require_valid_step(h);
  }

  void initialize(const RigidBodyState& s) {
    eval_ = potential_.evaluate(s.x, s.q);
    detail::require_finite(s, eval_);
    x_prev_ = s.x;
    q_prev_ = s.q;
    // Configuration 1 from the Legendre transform p0 = -D1 L_d(0, 1).
    const Vector3<double> b = (0.25 * h_) * (s.w + h_ * eval_.torque);
    S3d f = S3d::exp(body_.inertia_inverse() * b);
    solver_.solve(b, f, report_);
    predictor_.reset(f);
    x_next_ = s.x + (h_ / body_.mass()) * (s.p + (0.5 * h_) * eval_.force);
    q_next_ = s.q * f;
  }

  /// Advances from configuration k to k + 1 (computed one step ahead), reports
  /// p_{k+1}, w_{k+1}, and solves the DEL for configuration k + 2.
  void step(RigidBodyState& s) {
    const double h = h_;
    const PotentialEvaluation e1 = potential_.evaluate(x_next_, q_next_);
    const S3d f0 = q_prev_.inverse() * q_next_;
    const Vector3<double> f0v = f0.vec();
    const Vector3<double> jf0v = body_.inertia() * f0v;
    const Vector3<double> g_backward = f0.w() * jf0v - f0v.cross(jf0v);
    s.x = x_next_;
    s.q = q_next_;
    s.p = (body_.mass() / h) * (x_next_ - x_prev_) + (0.5 * h) * e1.force;
    s.w = (4.0 / h) * g_backward + h * e1.torque;
    eval_ = e1;
    detail::require_finite(s, eval_);
    // DEL for configuration k + 2.
    S3d f = predictor_.predict();
    solver_.solve(g_backward + (0.5 * h * h) * e1.torque, f, report_);
    predictor_.push(f);
    const Vector3<double> x2 = 2.0 * x_next_ - x_prev_ + (h * h / body_.mass()) * e1.force;
    x_prev_ = x_next_;
    q_prev_ = q_next_;
    x_next_ = x2;
    q_next_ = q_next_ * f;
  }

  double step_size() const { return h_; }
  const PotentialEvaluation& evaluation() const { return eval_; }
  const SolveReport& last_solve() const { return report_; }
  const RigidBody& body() const { return body_; }

  /// Besides the state: the configuration one step ahead and the predictor.
  std::vector<double> internal_state() const {
    std::vector<double> v{x_next_.x(), x_next_.y(), x_next_.z(), q_next_.w(), q_next_.vec().x(),
                          q_next_.vec().y(), q_next_.vec().z()};
    const std::vector<double> p = predictor_.serialize();
    v.insert(v.end(), p.begin(), p.end());
    return v;
  }
  void resume(const RigidBodyState& s, const std::vector<double>& internal) {
    if (internal.size() < 7) throw InvalidInput("checkpoint: Lagrangian integrator data too short");
    eval_ = potential_.evaluate(s.x, s.q);
    detail::require_finite(s, eval_);
    x_prev_ = s.x;
    q_prev_ = s.q;
    x_next_ = Vector3<double>(internal[0], internal[1], internal[2]);
    q_next_ = S3d(internal[3], internal[4], internal[5], internal[6]);
    predictor_.deserialize(std::vector<double>(internal.begin() + 7, internal.end()));
  }

 private:
  RigidBody body_;
  P potential_;
  double h_;
  RotationSolver solver_;
  PotentialEvaluation eval_;
  RotationPredictor predictor_;
  SolveReport report_;
  Vector3<double> x_prev_ = Vector3<double>::Zero(), x_next_ = Vector3<double>::Zero();
  S3d q_prev_, q_next_;
};

}  // namespace lgvi
