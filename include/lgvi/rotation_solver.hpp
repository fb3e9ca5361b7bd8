// The implicit equation of the quaternion LGVI for the relative rotation
// f = q0^* q1 = exp(xi0).
//
// The paper's second Hamiltonian equation,
//     w0 = -(4/h) G(q1^* q0) J Im(q1^* q0) + (h/2) F(q0) dV/dq(x0, q0),
// with q1^* q0 = f^* = (f_s, -f_v), G(f^*) = f_s I + hat(f_v) and
// F(q0) dV/dq = -2 M0 (potential.hpp), reads
//     g(xi) := f_s J f_v + f_v x (J f_v) = b,    b = (h/4) (w0 + h M0),
// and the Lagrangian side's discrete Euler-Lagrange equation has the same
// left side with another b (lgvi.hpp). The unknown is the unit quaternion
// f = exp(xi0), q1 = q0 f. Three solvers, all for that same root:
//   * Newton (default) with the analytic Jacobian, iterating on the Cayley
//     (Gibbs) chart u = f_v / f_s = tan|xi0| xi0/|xi0| of f, f = (1, u)/sqrt(1 + |u|^2),
//     the chart Lee, Leok & McClamroch use for the rotation-matrix LGVI. In
//     it the equation is a quadratic polynomial, with no square root or
//     trigonometric function in the loop:
//       c(u) := J u + u x J u - (1 + |u|^2) b = (1 + |u|^2) (g(f) - b) = 0,
//       dc/du = J + hat(u) J - hat(J u) - 2 b u^T.
//     The chart covers exactly the branch f_s > 0 (a rotation of less than pi
//     per step), where the paper's solution lives.
//   * Newton on xi0 itself (the paper's exponential chart), analytic Jacobian
//       dg/dxi = -(J f_v) f_v^T + (f_s J - hat(J f_v) + hat(f_v) J) dIm(exp)/dxi.
//   * The paper's choice: a forward-difference Jacobian in xi0 at the first
//     iterate of each step, then Broyden's rank-one updates (of the inverse,
//     Sherman-Morrison).
// All stop when the residual reaches tolerance * |b| (Broyden also when the
// update reaches tolerance * |xi|; Newton when it reaches tolerance * |f_v|),
// default tolerance 4 eps: round-off level. xi0 = log(f) where it is wanted.
//
// A linear body (rigid_body.hpp: J = I (1 - n n^T)) has a one-parameter
// family of roots, the rotations about n, which its Lagrangian does not see
// (the first component of g along n is 0 for every f). The root without
// rotation about n (f_v . n = 0, as LAMMPS keeps omega_n = 0) has J f_v = I f_v
// and f_v x J f_v = 0, so g(f) = I f_s f_v = b_perp (b's part across n, the
// only part the equation has) is solved in closed form: with k = |b_perp| / I,
//     f_s^2 = (1 + sqrt(1 - 4 k^2)) / 2,   f_v = b_perp / (I f_s),
// the root near f = e (rotation 2 asin(|f_v|) per step, sin of it = 2k: none
// beyond 2k = 1, a quarter turn per step). A point (J = 0) has g = 0: f = e.
#pragma once

#include <lgvi/error.hpp>
#include <lgvi/rigid_body.hpp>
#include <lgvi/s3.hpp>

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

namespace lgvi {

namespace detail {
/// The cure of a step that failed because the rotation per step was too
/// large (every implicit method says it the same way). The discrete
/// equations have roots up to about 1 rad per step, and none at pi.
inline constexpr const char* smaller_step_hint =
    "take a smaller step, so that the rotation |Omega| h per step stays well below 1 rad";
inline constexpr const char* smaller_step_hint_pi =
    "take a smaller step, so that the rotation |Omega| h per step stays well below pi";

/// Solves a r = y for a 3x3 matrix by its adjugate (Cramer's rule): about 40
/// flops and one division (docs/tuning.md). A singular or non-finite system
/// gives non-finite values, which the solvers report as a failed step.
/// x = a^{-1} y, for T double or SIMD lanes of doubles (RotationSolveBatch):
/// one operation order for both.
template <class T>
[[gnu::always_inline]] inline void solve_3x3_entries(const T (&a)[3][3], const T (&y)[3], T (&x)[3]) {
  const T c00 = a[1][1] * a[2][2] - a[1][2] * a[2][1];
  const T c01 = a[1][2] * a[2][0] - a[1][0] * a[2][2];
  const T c02 = a[1][0] * a[2][1] - a[1][1] * a[2][0];
  const T c10 = a[0][2] * a[2][1] - a[0][1] * a[2][2];
  const T c11 = a[0][0] * a[2][2] - a[0][2] * a[2][0];
  const T c12 = a[0][1] * a[2][0] - a[0][0] * a[2][1];
  const T c20 = a[0][1] * a[1][2] - a[0][2] * a[1][1];
  const T c21 = a[0][2] * a[1][0] - a[0][0] * a[1][2];
  const T c22 = a[0][0] * a[1][1] - a[0][1] * a[1][0];
  const T inv_det = 1.0 / ((a[0][0] * c00 + a[0][1] * c01) + a[0][2] * c02);
  x[0] = ((c00 * y[0] + c10 * y[1]) + c20 * y[2]) * inv_det;
  x[1] = ((c01 * y[0] + c11 * y[1]) + c21 * y[2]) * inv_det;
  x[2] = ((c02 * y[0] + c12 * y[1]) + c22 * y[2]) * inv_det;
}

/// The same for an Eigen matrix and vector.
inline Vector3<double> solve_3x3(const Matrix3<double>& m, const Vector3<double>& v) {
  const double a[3][3] = {{m(0, 0), m(0, 1), m(0, 2)}, {m(1, 0), m(1, 1), m(1, 2)}, {m(2, 0), m(2, 1), m(2, 2)}};
  const double y[3] = {v(0), v(1), v(2)};
  double x[3];
  solve_3x3_entries(a, y, x);
  return Vector3<double>(x[0], x[1], x[2]);
}
}  // namespace detail

enum class SolverKind {
  Newton,     ///< analytic Jacobian, Cayley chart u = f_v / f_s (the default)
  NewtonExp,  ///< analytic Jacobian, exponential chart xi
  Broyden     ///< the paper's finite-difference Jacobian + Broyden updates, chart xi
};

inline const char* to_string(SolverKind k) {
  switch (k) {
    case SolverKind::Newton: return "newton";
    case SolverKind::NewtonExp: return "newton-exp";
    case SolverKind::Broyden: return "broyden";
  }
  return "?";
}

struct SolverOptions {
  SolverKind kind = SolverKind::Newton;
  /// Relative stopping tolerance on the residual (against |b|) and on the
  /// update (against |xi|). 4 eps is the floor of a double-precision
  /// evaluation of g.
  double tolerance = 4 * std::numeric_limits<double>::epsilon();
  int max_iterations = 50;
  /// Degree of the polynomial extrapolation of the last steps' f that starts
  /// each solve (RotationPredictor): 0 = the previous step's f, 3 = cubic.
  int predictor_order = 3;
};

struct SolveReport {
  int iterations = 0;          ///< linear solves (Newton or Broyden updates)
  int residual_evaluations = 0;  ///< evaluations of g, finite differences included
  int worst_iterations = 0;  ///< for a system: the most iterations one body needed (stepper.hpp's combine)
};

/// g(xi) = f_s J f_v + f_v x J f_v for f = exp(xi), and its Jacobian.
class RotationEquation {
 public:
  explicit RotationEquation(const Matrix3<double>& inertia) : J_(inertia), J_norm_(inertia.norm()) {}

  /// g evaluated at the unit quaternion f (f = exp(xi)).
  Vector3<double> g(const S3d& f) const {
    const Vector3<double> fv = f.vec();
    const Vector3<double> jfv = J_ * fv;
    return f.w() * jfv + fv.cross(jfv);
  }

  /// dg/dxi at xi, given f = exp(xi) and its cos, sinc.
  Matrix3<double> jacobian(const Vector3<double>& xi, const S3d& f, double c, double sinc) const {
    const Vector3<double> fv = f.vec();
    const Vector3<double> jfv = J_ * fv;
    const Matrix3<double> dg_dfv = f.w() * J_ - S3d::hat(jfv) + S3d::hat(fv) * J_;
    return -jfv * fv.transpose() + dg_dfv * exp_imaginary_jacobian<double>(xi, c, sinc);
  }

  /// c(u) = J u + u x J u - (1 + |u|^2) b, the equation in the Cayley chart.
  Vector3<double> cayley_residual(const Vector3<double>& u, const Vector3<double>& b) const {
    const Vector3<double> ju = J_ * u;
    return ju + u.cross(ju) - (1.0 + u.squaredNorm()) * b;
  }

  /// dc/du = J + hat(u) J - hat(J u) - 2 b u^T, assembled column by column
  /// (column j: J_j + u x J_j - 2 u_j b, then - hat(J u)).
  Matrix3<double> cayley_jacobian(const Vector3<double>& u, const Vector3<double>& b) const {
    Matrix3<double> d;
    for (int j = 0; j < 3; ++j) {
      const Vector3<double> c = J_.col(j);
      d.col(j) = c + u.cross(c) - (2.0 * u(j)) * b;
    }
    const Vector3<double> ju = J_ * u;
    d(0, 1) += ju(2);
    d(0, 2) -= ju(1);
    d(1, 0) -= ju(2);
    d(1, 2) += ju(0);
    d(2, 0) += ju(1);
    d(2, 1) -= ju(0);
    return d;
  }

  const Matrix3<double>& inertia() const { return J_; }
  /// Frobenius norm of J, an upper bound of its 2-norm.
  double inertia_norm() const { return J_norm_; }

 private:
  Matrix3<double> J_;
  double J_norm_;
};

/// Initial guesses for the rotation solve: the relative rotations f of the
/// last (up to) four steps, extrapolated in k by the polynomial through them.
/// On a smooth trajectory the cubic's error is O(h^4 |d^4 f_v/dk^4|) ~ h^5,
/// small enough (~1e-10 at h = 0.01 on the paper's orbit) that one Newton
/// iteration reaches round-off, where the previous step's f (error O(h^2))
/// needs two. It only changes the starting point: the root is the same.
class RotationPredictor {
 public:
  explicit RotationPredictor(int order = 3) : order_(std::clamp(order, 0, 3)) {}

  static constexpr std::size_t serialized_size = 13;
  /// No history yet (a fresh stepper: the first step seeds it).
  bool empty() const { return count_ == 0; }

  /// Forgets the history and starts from f.
  void reset(const S3d& f) {
    count_ = 0;
    push(f);
  }

  void push(const S3d& f) {
    for (int i = 3; i > 0; --i) v_[i] = v_[i - 1];
    v_[0] = f.vec();
    count_ = std::min(count_ + 1, 4);
  }

  S3d predict() const {
    Vector3<double> v;
    switch (std::min(count_, order_ + 1)) {
      case 4: v = 4.0 * (v_[0] + v_[2]) - 6.0 * v_[1] - v_[3]; break;
      case 3: v = 3.0 * (v_[0] - v_[1]) + v_[2]; break;
      case 2: v = 2.0 * v_[0] - v_[1]; break;
      default: v = v_[0];
    }
    double s2 = 1.0 - v.squaredNorm();
    if (!(s2 > 0.25)) {  // extrapolated out of the chart's comfortable range: use the last f
      v = v_[0];
      s2 = 1.0 - v.squaredNorm();
    }
    return S3d(std::sqrt(std::max(s2, 0.0)), v.x(), v.y(), v.z());
  }

  /// The history (count, then the 4 vectors newest first): what a
  /// checkpoint keeps for a bit-identical resume.
  std::vector<double> serialize() const {
    std::vector<double> out{static_cast<double>(count_)};
    for (const auto& v : v_) out.insert(out.end(), {v.x(), v.y(), v.z()});
    return out;
  }
  void deserialize(const std::vector<double>& in) {
    if (in.size() != 13) throw InvalidInput("checkpoint: predictor data has the wrong size");
    count_ = std::clamp(static_cast<int>(in[0]), 0, 4);
    for (int i = 0; i < 4; ++i) v_[static_cast<std::size_t>(i)] = Vector3<double>(in[1 + 3 * i], in[2 + 3 * i], in[3 + 3 * i]);
  }

 private:
  std::array<Vector3<double>, 4> v_{Vector3<double>::Zero(), Vector3<double>::Zero(), Vector3<double>::Zero(),
                                    Vector3<double>::Zero()};
  int count_ = 0;
  int order_;
};

/// The Newton solves (Cayley chart) of up to `lanes` bodies at once, lane l
/// of every array one body's: what RotationSolver::solve does for it, the
/// same IEEE operations in the same order on each lane, so the same result
/// bit for bit (tests/test_rotation_solver.cpp). One lane's iteration costs
/// about what one body's does, for all lanes together (SIMD); a lane that
/// has converged waits for the others. A lane that would fail (a guess off
/// the branch, no convergence, a number that is not finite) is not solved
/// here: `solved` is false, and the caller solves it with
/// RotationSolver::solve, which fails in the same way, with its message.
struct RotationSolveBatch {
  static constexpr int lanes = 4;
  // Inputs.
  double inertia[9][lanes];  ///< J(i, j) at [3 i + j]
  double inertia_norm[lanes];
  double b[3][lanes];
  double guess[4][lanes];  ///< (f_s, f_x, f_y, f_z)
  // Outputs.
  double f[4][lanes];
  int iterations[lanes];
  int residual_evaluations[lanes];
  bool solved[lanes];
};

namespace detail {

/// Four doubles, and four 64-bit masks (all bits set: true), as GCC and
/// Clang vector extensions: each operation is one instruction per two lanes
/// (SSE2), or per four in the AVX2 clone below. Only ever local: vectors
/// passed by value between functions built for different targets change
/// the ABI.
using Lanes = double __attribute__((vector_size(32)));
using LaneMask = long long __attribute__((vector_size(32)));

[[gnu::always_inline]] inline void load_lanes(Lanes& v, const double* p) { std::memcpy(&v, p, sizeof v); }
[[gnu::always_inline]] inline void abs_lanes(Lanes& out, const Lanes& v) {
  const LaneMask magnitude = LaneMask{} + 0x7fffffffffffffffLL;  // every bit but the sign
  out = __builtin_bit_cast(Lanes, __builtin_bit_cast(LaneMask, v) & magnitude);  // (builtins: no calls)
}
[[gnu::always_inline]] inline void max3_abs_lanes(Lanes& out, const Lanes& a, const Lanes& b, const Lanes& c) {
  Lanes x, y, z;
  abs_lanes(x, a);
  abs_lanes(y, b);
  abs_lanes(z, c);
  out = x > y ? x : y;  // the max of finite numbers, in any order
  out = out > z ? out : z;
}
[[gnu::always_inline]] inline bool any_lane(const LaneMask& m) { return (m[0] | m[1] | m[2] | m[3]) != 0; }
/// Lanes where v is finite (|v| < infinity is false for NaN too).
[[gnu::always_inline]] inline void finite_lanes(LaneMask& out, const Lanes& v) {
  Lanes magnitude;
  abs_lanes(magnitude, v);
  out = magnitude < Lanes{} + std::numeric_limits<double>::infinity();
}
/// Moves the active lanes where `sum` is not finite to `failed` (the sum of
/// a lane's numbers: a NaN or infinity in any makes it so, as may an overflow).
[[gnu::always_inline]] inline void fail_non_finite_lanes(LaneMask& active, LaneMask& failed, const Lanes& sum) {
  LaneMask finite;
  finite_lanes(finite, sum);
  failed |= active & ~finite;
  active &= finite;
}

/// RotationSolveBatch's solves of lanes [0, count): newton_cayley_chart
/// written for vectors of lanes, operation for operation. Each Eigen
/// expression of the scalar code is spelled out in the order Eigen
/// evaluates it (J u: (J_i0 u_0 + J_i1 u_1) + J_i2 u_2 for rows 0 and 1, a
/// packet, and J_20 u_0 + (J_21 u_1 + J_22 u_2) for row 2, a reduction;
/// squared norms (x_0^2 + x_1^2) + x_2^2). No fused multiply-add: AVX2
/// does not include FMA, and the project's build does not target it.
[[gnu::always_inline]] inline void newton_cayley_lanes_body(RotationSolveBatch& batch, int count, double tolerance,
                                                              int max_iterations) {
  constexpr int lanes = RotationSolveBatch::lanes;
  static_assert(lanes == 4, "Lanes holds 4 doubles");
  // Lanes from count on: lane 0's problem, solved and ignored.
  for (int l = count; l < lanes; ++l) {
    for (auto& row : batch.inertia) row[l] = row[0];
    for (auto& row : batch.b) row[l] = row[0];
    for (auto& row : batch.guess) row[l] = row[0];
    batch.inertia_norm[l] = batch.inertia_norm[0];
  }
  Lanes J[9], b[3], g[4], j_norm;
  for (int k = 0; k < 9; ++k) load_lanes(J[k], batch.inertia[k]);
  for (int k = 0; k < 3; ++k) load_lanes(b[k], batch.b[k]);
  for (int k = 0; k < 4; ++k) load_lanes(g[k], batch.guess[k]);
  load_lanes(j_norm, batch.inertia_norm);
  const Lanes zero{}, one = zero + 1.0, tol = zero + tolerance;
  LaneMask used{};
  for (int l = 0; l < count; ++l) used[l] = -1;
  // Lanes that start: f_s > 0, and b and the guess finite (anything else
  // goes to the scalar solver, which knows what to say).
  const Lanes input_sum = ((b[0] + b[1]) + b[2]) + ((g[0] + g[1]) + (g[2] + g[3]));
  LaneMask inputs_finite;
  finite_lanes(inputs_finite, input_sum);
  LaneMask active = used & (g[0] > zero) & inputs_finite;
  LaneMask failed = used & ~active;
  Lanes u[3] = {g[1] / g[0], g[2] / g[0], g[3] / g[0]};
  Lanes b_scale;
  max3_abs_lanes(b_scale, b[0], b[1], b[2]);
  Lanes quadratic_factor = (b[0] * b[0] + b[1] * b[1]) + b[2] * b[2];  // |J| + |b|, below
  for (int l = 0; l < lanes; ++l) quadratic_factor[l] = std::sqrt(quadratic_factor[l]);
  quadratic_factor = j_norm + quadratic_factor;
  const Lanes tol_b_scale = tol * b_scale;
  LaneMask iterations{}, evaluations{};
  const LaneMask iteration_limit = LaneMask{} + max_iterations;
  while (any_lane(active)) {
    // c(u) = J u + u x J u - (1 + |u|^2) b.
    const Lanes ju[3] = {(J[0] * u[0] + J[1] * u[1]) + J[2] * u[2], (J[3] * u[0] + J[4] * u[1]) + J[5] * u[2],
                         J[6] * u[0] + (J[7] * u[1] + J[8] * u[2])};
    const Lanes s = one + ((u[0] * u[0] + u[1] * u[1]) + u[2] * u[2]);
    const Lanes r[3] = {(ju[0] + (u[1] * ju[2] - u[2] * ju[1])) - s * b[0],
                        (ju[1] + (u[2] * ju[0] - u[0] * ju[2])) - s * b[1],
                        (ju[2] + (u[0] * ju[1] - u[1] * ju[0])) - s * b[2]};
    evaluations -= active;
    fail_non_finite_lanes(active, failed, (r[0] + r[1]) + r[2]);
    Lanes r_max;
    max3_abs_lanes(r_max, r[0], r[1], r[2]);
    active &= ~(r_max <= tol * (s * b_scale));
    const LaneMask out_of_iterations = active & (iterations >= iteration_limit);
    failed |= out_of_iterations;
    active &= ~out_of_iterations;
    if (!any_lane(active)) break;
    // dc/du, column j: J_j + u x J_j - 2 u_j b, then - hat(J u).
    Lanes d[3][3];
    for (int j = 0; j < 3; ++j) {
      const Lanes& c0 = J[j];
      const Lanes& c1 = J[3 + j];
      const Lanes& c2 = J[6 + j];
      const Lanes two_uj = 2.0 * u[j];
      d[0][j] = (c0 + (u[1] * c2 - u[2] * c1)) - two_uj * b[0];
      d[1][j] = (c1 + (u[2] * c0 - u[0] * c2)) - two_uj * b[1];
      d[2][j] = (c2 + (u[0] * c1 - u[1] * c0)) - two_uj * b[2];
    }
    d[0][1] += ju[2];
    d[0][2] -= ju[1];
    d[1][0] -= ju[2];
    d[1][2] += ju[0];
    d[2][0] += ju[1];
    d[2][1] -= ju[0];
    Lanes delta[3];
    solve_3x3_entries(d, r, delta);
    for (int k = 0; k < 3; ++k) u[k] = active ? u[k] - delta[k] : u[k];
    iterations -= active;
    fail_non_finite_lanes(active, failed, (u[0] + u[1]) + u[2]);
    const Lanes d2 = (delta[0] * delta[0] + delta[1] * delta[1]) + delta[2] * delta[2];
    active &= ~(quadratic_factor * d2 <= tol_b_scale);
    Lanes delta_max, u_max;
    max3_abs_lanes(delta_max, delta[0], delta[1], delta[2]);
    max3_abs_lanes(u_max, u[0], u[1], u[2]);
    active &= ~(delta_max <= tol * u_max);
  }
  // f_s = 1/sqrt(1 + |u|^2), f_v = f_s u.
  Lanes fs = one + ((u[0] * u[0] + u[1] * u[1]) + u[2] * u[2]);
  for (int l = 0; l < lanes; ++l) fs[l] = std::sqrt(fs[l]);
  fs = one / fs;
  failed |= used & ~(fs > zero);
  for (int l = 0; l < lanes; ++l) {
    batch.f[0][l] = fs[l];
    for (int k = 0; k < 3; ++k) batch.f[k + 1][l] = fs[l] * u[k][l];
    batch.iterations[l] = static_cast<int>(iterations[l]);
    batch.residual_evaluations[l] = static_cast<int>(evaluations[l]);
    batch.solved[l] = l < count && failed[l] == 0;
  }
}

/// The solves for the baseline x86-64 (SSE2, two lanes per instruction):
/// the code a processor without AVX2 runs (tests call it directly).
inline void newton_cayley_lanes_baseline(RotationSolveBatch& batch, int count, double tolerance, int max_iterations) {
  newton_cayley_lanes_body(batch, count, tolerance, max_iterations);
}

/// The solves, with a clone for AVX2 (four lanes per instruction) picked at
/// run time where the processor has it.
#if defined(__GNUC__) && defined(__x86_64__) && !defined(__clang__)
__attribute__((target_clones("avx2", "default")))
#endif
inline void newton_cayley_lanes(RotationSolveBatch& batch, int count, double tolerance, int max_iterations) {
  newton_cayley_lanes_body(batch, count, tolerance, max_iterations);
}

}  // namespace detail

/// Solves g(f) = b for f = exp(xi0). The initial guess and the result are
/// held in `f` (in/out): a warm start from the previous step. Throws
/// StepFailure if the iterate leaves the branch f_s > 0 (a rotation by pi in
/// one step) or the iteration does not converge.
class RotationSolver {
 public:
  RotationSolver(const Matrix3<double>& inertia, SolverOptions options) : eq_(inertia), opt_(options) {}
  /// The solver of `body`'s equation: a linear body's or a point's in
  /// closed form (the file comment), whatever the options' kind.
  RotationSolver(const RigidBody& body, SolverOptions options)
      : eq_(body.inertia()), opt_(options), rotational_dof_(body.rotational_dof()), axis_(body.linear_axis()),
        moment_(body.rotational_dof() == 2 ? 0.5 * body.inertia().trace() : 0.0) {}

  /// The solver of a body stored as molecular-dynamics codes store it: its
  /// principal moments, the body frame being the principal frame (LAMMPS's
  /// fix rigid/small, which sets a moment below 1e-7 of the largest to
  /// exactly 0). Three moments > 0: the body's J = diag(moments). One moment
  /// 0: a linear body along that axis, with I the mean of the other two
  /// (equal to round-off for point masses on a line), as RigidBody stores it.
  /// All three 0: a point. Throws InvalidInput for anything else (negative,
  /// not finite, two zeros), which no collection of masses has.
  static RotationSolver for_principal_moments(const Vector3<double>& moments, SolverOptions options) {
    if (!moments.allFinite() || (moments.array() < 0.0).any())
      throw InvalidInput("principal moments must be finite and >= 0");
    const auto zeros = (moments.array() == 0.0).count();
    RotationSolver solver(Matrix3<double>(moments.asDiagonal()), options);
    if (zeros == 0) return solver;
    if (zeros == 1) {
      Eigen::Index k = 0;
      moments.minCoeff(&k);
      solver.rotational_dof_ = 2;
      solver.axis_ = Vector3<double>::Unit(k);
      solver.moment_ = 0.5 * moments.sum();
      return solver;
    }
    if (zeros == 3) {
      solver.rotational_dof_ = 0;
      return solver;
    }
    throw InvalidInput("principal moments with exactly two zeros belong to no body of point masses");
  }

  void solve(const Vector3<double>& b, S3d& f, SolveReport& report) const {
    report = {};
    if (rotational_dof_ == 0) {
      f = S3d();
      return;
    }
    if (rotational_dof_ == 2) {
      f = linear_rotor(b);
      return;
    }
    switch (opt_.kind) {
      case SolverKind::Newton: f = newton_cayley_chart(b, f, report); return;
      case SolverKind::NewtonExp: {
        Vector3<double> xi = f.log();
        f = newton_exp_chart(b, xi, report);
        return;
      }
      case SolverKind::Broyden: {
        Vector3<double> xi = f.log();
        f = broyden(b, xi, report);
        return;
      }
    }
  }

  const SolverOptions& options() const { return opt_; }
  const RotationEquation& equation() const { return eq_; }

  /// Whether solve() can be done in a RotationSolveBatch (the default
  /// solver, Newton in the Cayley chart, for a body with three moments).
  bool batchable() const { return opt_.kind == SolverKind::Newton && rotational_dof_ == 3; }
  /// Puts this body's solve of g(f) = b from `guess` into lane l of `batch`.
  /// A body that is not batchable() loads a problem solved at once (b = 0
  /// from f = e): the caller ignores the lane and solves the body alone.
  void load(RotationSolveBatch& batch, int lane, const Vector3<double>& b, const S3d& guess) const {
    const auto l = static_cast<std::size_t>(lane);
    if (!batchable()) {
      for (int i = 0; i < 9; ++i) batch.inertia[i][l] = i % 4 == 0 ? 1.0 : 0.0;
      batch.inertia_norm[l] = 1.0;
      for (int i = 0; i < 3; ++i) batch.b[i][l] = 0.0;
      batch.guess[0][l] = 1.0;
      for (int i = 1; i < 4; ++i) batch.guess[i][l] = 0.0;
      return;
    }
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) batch.inertia[3 * i + j][l] = eq_.inertia()(i, j);
    batch.inertia_norm[l] = eq_.inertia_norm();
    for (int i = 0; i < 3; ++i) batch.b[i][l] = b(i);
    batch.guess[0][l] = guess.w();
    for (int i = 0; i < 3; ++i) batch.guess[i + 1][l] = guess.vec()(i);
  }

 private:
  static constexpr double half_pi = 1.5707963267948966;

  S3d newton_cayley_chart(const Vector3<double>& b, const S3d& guess, SolveReport& report) const {
    if (!(guess.w() > 0.0)) throw left_branch();
    Vector3<double> u = guess.vec() / guess.w();
    // |c| <= tolerance (1 + |u|^2) |b| is |g(f) - b| <= tolerance |b|.
    const double b_scale = b.lpNorm<Eigen::Infinity>();
    for (;;) {
      const Vector3<double> r = eq_.cayley_residual(u, b);
      ++report.residual_evaluations;
      const double scale = (1.0 + u.squaredNorm()) * b_scale;
      if (r.lpNorm<Eigen::Infinity>() <= opt_.tolerance * scale) break;
      if (report.iterations >= opt_.max_iterations) throw not_converged(r, scale, b);
      const Vector3<double> delta = detail::solve_3x3(eq_.cayley_jacobian(u, b), r);
      u -= delta;
      ++report.iterations;
      if (!u.allFinite()) throw left_branch();
      // c is quadratic, so after the Newton update the residual is exactly
      // c(u - delta) = delta x J delta - |delta|^2 b, bounded by
      // (|J| + |b|) |delta|^2: stop without evaluating it when that bound is
      // below the tolerance (saves one evaluation in the usual 2-iteration step).
      const double d2 = delta.squaredNorm();
      if ((eq_.inertia_norm() + b.norm()) * d2 <= opt_.tolerance * b_scale) break;
      if (delta.lpNorm<Eigen::Infinity>() <= opt_.tolerance * u.lpNorm<Eigen::Infinity>()) break;
    }
    // f_s = 1/sqrt(1 + |u|^2) > 0; a rotation of pi per step is |u| = infinity.
    const double fs = 1.0 / std::sqrt(1.0 + u.squaredNorm());
    if (!(fs > 0.0)) throw left_branch();
    return S3d(fs, fs * u.x(), fs * u.y(), fs * u.z());
  }

  S3d newton_exp_chart(const Vector3<double>& b, Vector3<double>& xi, SolveReport& report) const {
    const double b_scale = b.lpNorm<Eigen::Infinity>();
    for (;;) {
      double c, sinc;
      S3d::cos_and_sinc(xi.norm(), c, sinc);
      S3d f(c, sinc * xi.x(), sinc * xi.y(), sinc * xi.z());
      const Vector3<double> r = eq_.g(f) - b;
      ++report.residual_evaluations;
      if (r.lpNorm<Eigen::Infinity>() <= opt_.tolerance * b_scale) return f;
      if (report.iterations >= opt_.max_iterations) throw not_converged(r, b_scale, b);
      const Matrix3<double> d = eq_.jacobian(xi, f, c, sinc);
      const Vector3<double> delta = detail::solve_3x3(d, r);
      xi -= delta;
      ++report.iterations;
      check_branch(xi);
      if (delta.lpNorm<Eigen::Infinity>() <= opt_.tolerance * xi.lpNorm<Eigen::Infinity>()) return S3d::exp(xi);
    }
  }

  S3d broyden(const Vector3<double>& b, Vector3<double>& xi, SolveReport& report) const {
    const double b_scale = b.lpNorm<Eigen::Infinity>();
    S3d f = S3d::exp(xi);
    Vector3<double> r = eq_.g(f) - b;
    ++report.residual_evaluations;
    if (r.lpNorm<Eigen::Infinity>() <= opt_.tolerance * b_scale) return f;
    // Forward differences with step sqrt(eps) max(1, |xi_j|): the Jacobian's
    // error O(sqrt(eps)) only slows Broyden's superlinear convergence.
    Matrix3<double> jac;
    const double sqrt_eps = std::sqrt(std::numeric_limits<double>::epsilon());
    for (int j = 0; j < 3; ++j) {
      Vector3<double> xj = xi;
      const double step = sqrt_eps * std::max(1.0, std::abs(xi(j)));
      xj(j) += step;
      jac.col(j) = (eq_.g(S3d::exp(xj)) - b - r) / step;
      ++report.residual_evaluations;
    }
    Matrix3<double> inv = jac.inverse();
    for (;;) {
      if (report.iterations >= opt_.max_iterations) throw not_converged(r, b_scale, b);
      const Vector3<double> delta = -(inv * r);
      xi += delta;
      ++report.iterations;
      check_branch(xi);
      f = S3d::exp(xi);
      const Vector3<double> r_new = eq_.g(f) - b;
      ++report.residual_evaluations;
      if (r_new.lpNorm<Eigen::Infinity>() <= opt_.tolerance * b_scale ||
          delta.lpNorm<Eigen::Infinity>() <= opt_.tolerance * xi.lpNorm<Eigen::Infinity>())
        return f;
      // "Good" Broyden update of the inverse: H += (s - H y) s^T H / (s^T H y).
      const Vector3<double> y = r_new - r;
      const Vector3<double> hy = inv * y;
      const double denom = delta.dot(hy);
      if (denom != 0.0 && std::isfinite(denom)) inv += ((delta - hy) * (delta.transpose() * inv)) / denom;
      r = r_new;
    }
  }

  /// The closed-form root of a linear body (the file comment). 1 - 4 k^2 is
  /// formed as (1 - 2k)(1 + 2k), exact near 2k = 1; |f_v|^2 = 1 - f_s^2 then
  /// holds to round-off.
  S3d linear_rotor(const Vector3<double>& b) const {
    const Vector3<double> across = b - b.dot(axis_) * axis_;
    const double k = across.norm() / moment_;
    const double root = (1.0 - 2.0 * k) * (1.0 + 2.0 * k);
    if (!(root >= 0.0))
      throw StepFailure("a linear body's rotation equation has no root for this step (sin of the rotation per step "
                        "would be " + std::to_string(2.0 * k) + " > 1: more than a quarter turn per step)",
                        detail::smaller_step_hint);
    const double fs = std::sqrt(0.5 * (1.0 + std::sqrt(root)));
    const Vector3<double> fv = across / (moment_ * fs);
    return S3d(fs, fv.x(), fv.y(), fv.z());
  }

  static StepFailure left_branch() {
    return StepFailure("the rotation in one step reached pi (|xi0| >= pi/2, Re(q0^* q1) <= 0), where the discrete "
                       "flow is not defined",
                       detail::smaller_step_hint_pi);
  }

  static void check_branch(const Vector3<double>& xi) {
    if (!xi.allFinite() || xi.norm() >= half_pi) throw left_branch();
  }

  /// No convergence. The first-order estimate of the rotation per step,
  /// |Omega| h ~ 2 |J^{-1} b| (b = h J Omega / 2), tells whether the step is
  /// simply too large for a root to exist: for an isotropic J the equation is
  /// sin(2 theta) = |Omega| h (rotation 2 theta per step), with no solution
  /// beyond |Omega| h = 1; the same scale holds for other inertias.
  StepFailure not_converged(const Vector3<double>& r, double scale, const Vector3<double>& b) const {
    const double rotation = 2.0 * eq_.inertia().ldlt().solve(b).norm();
    const std::string estimate = "estimated rotation per step |Omega| h = " + std::to_string(rotation) + " rad";
    const std::string hint = detail::smaller_step_hint;
    if (rotation >= std::numbers::pi)
      return StepFailure("the rotation in one step reached pi (" + estimate +
                             "), where the discrete flow is not defined; the solver found no root",
                         hint);
    if (rotation > 0.9)
      return StepFailure("the rotation equation has no root for this step (" + estimate +
                             "; the discrete equations admit about 1 rad at most)",
                         hint);
    return StepFailure(std::string(to_string(opt_.kind)) + " iteration for the rotation did not converge in " +
                           std::to_string(opt_.max_iterations) + " iterations (relative residual " +
                           std::to_string(r.lpNorm<Eigen::Infinity>() / std::max(scale, 1e-300)) + ", " + estimate +
                           ")",
                       "try a smaller step");
  }

  RotationEquation eq_;
  SolverOptions opt_;
  int rotational_dof_ = 3;
  Vector3<double> axis_ = Vector3<double>::Zero();  ///< a linear body's axis n
  double moment_ = 0.0;                             ///< a linear body's I: J = I (1 - n n^T)
};

}  // namespace lgvi
