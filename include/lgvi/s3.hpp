// The unit quaternions S^3 as a Lie group, in the conventions of Shen & Leok,
// "Lie group variational integrators for rigid body problems using quaternions"
// (shared/paper/shen-leok-lgvi-quaternions.tex, section "Unit quaternions").
//
// Conventions, fixed once for the whole library:
//   * A quaternion q = (q_s, q_v) is written scalar first everywhere in this
//     library's API, files and docs. Eigen's Quaternion constructor takes
//     (w, x, y, z) but *stores* (x, y, z, w); we only ever touch it through
//     w() and vec(), never through coeffs().
//   * The Lie algebra is R^3 with exp(xi) = (cos|xi|, sin|xi| xi/|xi|), the
//     paper's eq. for exp. Note the factor: pi(exp(xi)) is the rotation by the
//     angle 2|xi| about xi/|xi|, i.e. pi(exp(xi)) = expm(hat(2 xi)). (Sophus and
//     most robotics code use exp(w) = (cos|w|/2, ...), our xi = w/2.)
//   * A 4-vector "d/dq" (the paper's dV/dq) is ordered (d/dq_s, d/dq_v).
#pragma once

#include <lgvi/error.hpp>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cmath>
#include <limits>
#include <string>

namespace lgvi {

template <class Scalar>
using Vector3 = Eigen::Matrix<Scalar, 3, 1>;
template <class Scalar>
using Vector4 = Eigen::Matrix<Scalar, 4, 1>;
template <class Scalar>
using Matrix3 = Eigen::Matrix<Scalar, 3, 3>;
template <class Scalar>
using Matrix34 = Eigen::Matrix<Scalar, 3, 4>;

namespace detail {
/// Threshold below which a series truncated after the term of order `order`
/// is exact to machine precision: the first neglected term is O(x^(order+1)),
/// so x < eps^(1/(order+1)) keeps it below eps (Pinocchio's rule).
template <class Scalar>
Scalar taylor_threshold(int order) {
  using std::pow;
  return pow(std::numeric_limits<Scalar>::epsilon(), Scalar(1) / Scalar(order + 1));
}
}  // namespace detail

/// Element of the Lie group S^3 of unit quaternions.
///
/// Class invariant: |q| = 1 up to round-off. Nothing here normalizes: the
/// integrators keep |q| = 1 by construction (q1 = q0 * exp(xi)), and the
/// library's promise is that |q| - 1 stays at round-off without projection.
/// `norm_error()` reports the deviation.
template <class Scalar>
class S3 {
 public:
  using Quaternion = Eigen::Quaternion<Scalar>;
  using Tangent = Vector3<Scalar>;

  /// The identity e = (1, 0, 0, 0).
  S3() : q_(Scalar(1), Scalar(0), Scalar(0), Scalar(0)) {}

  /// Wraps a quaternion that the caller guarantees to be unit (not checked,
  /// not normalized). Use `from_quaternion_checked` for user input.
  explicit S3(const Quaternion& q) : q_(q) {}

  /// Scalar-first constructor: (q_s, q_x, q_y, q_z).
  S3(Scalar qs, Scalar qx, Scalar qy, Scalar qz) : q_(qs, qx, qy, qz) {}

  /// How far from 1 the norm of a user's quaternion may be: 1e-6 accepts
  /// quaternions written with 7 or more significant digits (and their
  /// round-off) and rejects any that is not meant to be unit.
  static constexpr double unit_tolerance = 1e-6;

  /// A unit quaternion from user input (scalar first): its norm must be
  /// within unit_tolerance of 1, and it is then normalized (the only place
  /// where S3 normalizes: input, never a step). Throws InvalidInput with
  /// "must be a unit quaternion, ...": callers prefix the field's name.
  static S3 from_quaternion_checked(Scalar qs, Scalar qx, Scalar qy, Scalar qz) {
    using std::sqrt;
    const Scalar n = sqrt(qs * qs + qx * qx + qy * qy + qz * qz);
    using std::abs;
    if (!(abs(n - Scalar(1)) <= Scalar(unit_tolerance)))
      throw InvalidInput("must be a unit quaternion, scalar-first (w, x, y, z); its norm is " +
                         std::to_string(static_cast<double>(n)) + ", more than 1e-6 from 1");
    return S3(qs / n, qx / n, qy / n, qz / n);
  }

  /// The inner product in R^4 (q and -q are the same rotation: the sign of
  /// dot tells which of the two is nearer another quaternion).
  Scalar dot(const S3& other) const { return q_.coeffs().dot(other.q_.coeffs()); }

  /// q / |q|: for methods that project onto S^3 after a step (RK4 with
  /// normalization, semi-implicit Euler); the LGVI never calls it.
  S3 normalized() const { return S3(q_.normalized()); }

  /// Whether every coefficient is finite.
  bool all_finite() const { return q_.coeffs().allFinite(); }

  /// The sum of the coefficients (a cheap non-finite test over a state).
  Scalar coefficient_sum() const { return q_.coeffs().sum(); }

  /// The exponential map of the paper, exp(xi) = (cos|xi|, sin|xi| xi/|xi|).
  /// For |xi| below eps^(1/6), sin|xi|/|xi| is its Taylor series
  /// 1 - |xi|^2/6 + |xi|^4/120, exact to round-off there.
  static S3 exp(const Tangent& xi) {
    Scalar c, sinc;
    cos_and_sinc(xi.norm(), c, sinc);
    return S3(Quaternion(c, sinc * xi.x(), sinc * xi.y(), sinc * xi.z()));
  }

  /// cos(theta) and sin(theta)/theta, with the small-angle series.
  static void cos_and_sinc(Scalar theta, Scalar& c, Scalar& sinc) {
    using std::cos;
    using std::sin;
    static const Scalar small = detail::taylor_threshold<Scalar>(5);
    if (theta < small) {
      const Scalar t2 = theta * theta;
      c = Scalar(1) - t2 / Scalar(2) + t2 * t2 / Scalar(24);
      sinc = Scalar(1) - t2 / Scalar(6) + t2 * t2 / Scalar(120);
    } else {
      c = cos(theta);
      sinc = sin(theta) / theta;
    }
  }

  /// The inverse of exp on the open ball |xi| < pi:
  ///   xi = atan2(|q_v|, q_s) q_v / |q_v|.
  /// Near the identity (|q_v| small, q_s > 0) atan(n/w)/n uses its series
  /// (1/w)(1 - u^2/3 + u^4/5), u = n/w, below eps^(1/6). A rotation by pi in
  /// SO(3) (q_s = 0) maps to |xi| = pi/2, well inside the domain. At q = -1
  /// exactly (|xi| = pi, every direction) the direction x is returned.
  Tangent log() const {
    using std::atan2;
    const Scalar n = q_.vec().norm();
    const Scalar w = q_.w();
    static const Scalar small = detail::taylor_threshold<Scalar>(5);
    if (n == Scalar(0)) {
      if (w >= Scalar(0)) return Tangent::Zero();
      return Tangent(Scalar(EIGEN_PI), Scalar(0), Scalar(0));
    }
    if (w > Scalar(0) && n < small * w) {
      const Scalar u2 = (n / w) * (n / w);
      return q_.vec() * ((Scalar(1) - u2 / Scalar(3) + u2 * u2 / Scalar(5)) / w);
    }
    return q_.vec() * (atan2(n, w) / n);
  }

  /// hat: R^3 -> so(3), hat(x) y = x cross y.
  static Matrix3<Scalar> hat(const Tangent& v) {
    Matrix3<Scalar> m;
    m << Scalar(0), -v.z(), v.y(), v.z(), Scalar(0), -v.x(), -v.y(), v.x(), Scalar(0);
    return m;
  }

  /// vee: the inverse of hat on skew-symmetric matrices (the skew part of any
  /// other matrix).
  static Tangent vee(const Matrix3<Scalar>& m) {
    return Tangent(m(2, 1) - m(1, 2), m(0, 2) - m(2, 0), m(1, 0) - m(0, 1)) / Scalar(2);
  }

  /// pi: S^3 -> SO(3), pi(q) = (2 q_s^2 - 1) I + 2 q_v q_v^T + 2 q_s hat(q_v)
  /// (the paper's formula). A group homomorphism: pi(q1 q2) = pi(q1) pi(q2).
  /// Entry by entry, the operations of the Eigen expression
  ///   r = (2 v) v^T;  r.diagonal() += 2 s s - 1;  r += (2 s) hat(v)
  /// in its order (u_i v_j, then + d on the diagonal, then + 2 s hat(v)_ij,
  /// the diagonal's 2 s 0 included, which matters only for values that are
  /// not finite), so the bits are that expression's (tests/test_s3.cpp) where
  /// the compiler contracts neither into fused multiply-adds (x86-64 at its
  /// baseline, as built here); written out because GCC calls the expression
  /// rather than inlining it, at a cost in a many-body step (two per body).
  Matrix3<Scalar> matrix() const {
    const Scalar s = q_.w(), x = q_.x(), y = q_.y(), z = q_.z();
    const Scalar ux = Scalar(2) * x, uy = Scalar(2) * y, uz = Scalar(2) * z;
    const Scalar d = Scalar(2) * s * s - Scalar(1);
    const Scalar s2 = Scalar(2) * s;
    const Scalar zero = s2 * Scalar(0);
    Matrix3<Scalar> r;
    r(0, 0) = (ux * x + d) + zero;
    r(0, 1) = ux * y + s2 * -z;
    r(0, 2) = ux * z + s2 * y;
    r(1, 0) = uy * x + s2 * z;
    r(1, 1) = (uy * y + d) + zero;
    r(1, 2) = uy * z + s2 * -x;
    r(2, 0) = uz * x + s2 * -y;
    r(2, 1) = uz * y + s2 * x;
    r(2, 2) = (uz * z + d) + zero;
    return r;
  }

  /// Lift of a rotation matrix R to one of its two preimages +-q under pi
  /// (Shepperd's method, as in Eigen). The sign picked is q_s >= 0.
  static S3 from_rotation_matrix(const Matrix3<Scalar>& r) {
    Quaternion q(r);
    if (q.w() < Scalar(0)) q.coeffs() = -q.coeffs();
    return S3(q);
  }

  /// Rotates a vector: pi(q) v = q (0, v) q^*, evaluated as
  ///   u = 2 q_v x v,  pi(q) v = v + q_s u + q_v x u
  /// (30 flops). These are the operations of Eigen's q * v in its order, so
  /// the results are the same bit for bit (tests/test_s3.cpp); written out
  /// because GCC does not inline Eigen's, and in a many-body step the call
  /// cost as much as the arithmetic. Each cross-product component is one
  /// expression, as in Eigen's cross(), and the products q_s u separate
  /// statements, as Eigen's functors are: a compiler that fuses multiply-adds
  /// only within an expression (Clang's default) then fuses the same ones in
  /// both. Always inlined (a hot path GCC kept out of line; docs/tuning.md).
  [[gnu::always_inline]] Tangent act(const Tangent& v) const {
    const Scalar qs = q_.w(), qx = q_.x(), qy = q_.y(), qz = q_.z();
    Scalar ux = qy * v.z() - qz * v.y(), uy = qz * v.x() - qx * v.z(), uz = qx * v.y() - qy * v.x();
    ux += ux;
    uy += uy;
    uz += uz;
    const Scalar cx = qy * uz - qz * uy, cy = qz * ux - qx * uz, cz = qx * uy - qy * ux;
    const Scalar sx = qs * ux, sy = qs * uy, sz = qs * uz;
    const Scalar ax = v.x() + sx, ay = v.y() + sy, az = v.z() + sz;
    return Tangent(ax + cx, ay + cy, az + cz);
  }

  S3 operator*(const S3& other) const { return S3(q_ * other.q_); }

  /// q f for a step's relative rotation f near the identity (f_s > 0),
  /// evaluated as q + q (f - e) with f - e = (-|f_v|^2 / (1 + f_s), f_v)
  /// (1 - f_s = |f_v|^2 / (1 + f_s) on S^3). Why: f_s is within ~|f_v|^2 of 1,
  /// where a double's spacing is eps/2, so the stored f_s carries an error of
  /// up to eps/4 and |f| - 1 with it; q f multiplies |q| by |f|. In a steady
  /// spin f repeats exactly, and so would that error: |q| - 1 would grow linearly
  /// (1e-16 per step in a Lennard-Jones gas, 1.6e-11 after 1e5 steps). Here
  /// the increment f - e is small and carries relative, not absolute,
  /// rounding; what is left is the rounding of the sum q + ..., which varies
  /// with q and so random-walks. Nothing is normalized: f_s - 1 is the same
  /// element's coordinate, evaluated without cancellation. For f_s <= 0 (a
  /// rotation of more than pi, never a step of the integrators) it is q f.
  /// (act() is already of this form: it rotates v as v + 2 q_s (q_v x v)
  /// + 2 q_v x (q_v x v), so w1 = pi(f)^T w needs no counterpart.)
  S3 times_near_identity(const S3& f) const {
    if (!(f.w() > Scalar(0))) return *this * f;
    const Tangent fv = f.vec();
    const Quaternion d = q_ * Quaternion(-fv.squaredNorm() / (Scalar(1) + f.w()), fv.x(), fv.y(), fv.z());
    return S3(q_.w() + d.w(), q_.x() + d.x(), q_.y() + d.y(), q_.z() + d.z());
  }

  /// The inverse on S^3 is the conjugate q^* = (q_s, -q_v).
  S3 inverse() const { return S3(q_.conjugate()); }

  const Quaternion& quaternion() const { return q_; }
  Scalar w() const { return q_.w(); }
  Tangent vec() const { return q_.vec(); }
  /// (q_s, q_x, q_y, q_z).
  Vector4<Scalar> scalar_first() const { return Vector4<Scalar>(q_.w(), q_.x(), q_.y(), q_.z()); }
  /// |q| - 1: the deviation from the group, zero to round-off by invariant.
  Scalar norm_error() const { return q_.norm() - Scalar(1); }

 private:
  Quaternion q_;
};

/// F(q): H -> R^{3x4}, defined by q (0, v) = F(q)^T v for all v in R^3
/// (paper, section "Continuous time equation"):
///   F(q) = ( -q_v , q_s I - hat(q_v) ),
/// with the 4 columns ordered (scalar, vector) like dV/dq. For a potential,
/// F(q) dV/dq is the derivative of V along the left-trivialized variation
/// delta q = q (0, eta); see potential.hpp for F(q) dV/dq = -2 M.
template <class Scalar>
Matrix34<Scalar> F(const Eigen::Quaternion<Scalar>& q) {
  Matrix34<Scalar> f;
  f.col(0) = -q.vec();
  f.template rightCols<3>() = q.w() * Matrix3<Scalar>::Identity() - S3<Scalar>::hat(q.vec());
  return f;
}

/// G(q): H -> R^{3x3}, defined by Im(q (0, v)) = G(q)^T v (paper, section
/// "Variational integrator on the Lagrangian side"):  G(q) = q_s I - hat(q_v).
template <class Scalar>
Matrix3<Scalar> G(const Eigen::Quaternion<Scalar>& q) {
  return q.w() * Matrix3<Scalar>::Identity() - S3<Scalar>::hat(q.vec());
}

/// Jacobian of Im(exp(xi)) = sin|xi| xi/|xi| with respect to xi:
///   d Im(exp(xi)) / d xi = s I + ((c - s)/|xi|^2) xi xi^T,  s = sin|xi|/|xi|, c = cos|xi|,
/// and d Re(exp(xi)) / d xi = -Im(exp(xi))^T. (c - s)/|xi|^2 -> -1/3 + |xi|^2/30
/// is taken from its series below eps^(1/4), where the direct formula cancels.
template <class Scalar>
Matrix3<Scalar> exp_imaginary_jacobian(const Vector3<Scalar>& xi, Scalar c, Scalar sinc) {
  const Scalar t2 = xi.squaredNorm();
  static const Scalar small = detail::taylor_threshold<Scalar>(3);
  const Scalar k = t2 < small * small ? Scalar(-1) / Scalar(3) + t2 / Scalar(30) - t2 * t2 / Scalar(840)
                                      : (c - sinc) / t2;
  Matrix3<Scalar> d = (k * xi) * xi.transpose();
  d.diagonal().array() += sinc;
  return d;
}

using S3d = S3<double>;

}  // namespace lgvi
