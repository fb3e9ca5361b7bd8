// The exact flow of the free rigid body (Euler-Poinsot motion), after
// Celledoni, Fasso, Safstrom & Zanna, "The exact computation of the free
// rigid body motion and its use in splitting methods", SIAM J. Sci. Comput.
// 30 (2008), with Jacobi elliptic functions and elliptic integrals from
// Boost.Math. Used as method = "exact" for free bodies and as the oracle of
// the convergence tests.
//
// Notation. Principal moments I1 < I2 < I3 (J = V diag(I) V^T, V a proper
// rotation), body angular momentum M = J Omega = w/2 in principal axes,
// G = |M|, Delta = 2E = sum M_i^2/I_i. Euler's equations Mdot = M x Omega.
//
// 1. The family. G^2 - Delta I2 = M3^2 (I3 - I2)/I3 - M1^2 (I2 - I1)/I1 is
//    positive when M circles the major axis (I3) and negative when it circles
//    the minor axis (I1). We work in a "working frame" N = V'^T M whose third
//    axis is that pole: V' = V (moments J = (I1, I2, I3)) for the major-axis
//    family, V' = (V e3, -V e2, V e1) (moments J = (I3, I2, I1), still a
//    proper rotation) for the minor-axis family. Both families then read the
//    same with eta = sign(J3 - J2) = +1 (major) or -1 (minor):
//
//      N1 = sigma1 a1 cn(u),  N2 = sigma1 eta s a2 sn(u),  N3 = s a3 dn(u),
//      u = omega t + u0,
//
//    with s = sign N3 (constant), sigma1 = sign N1(0) (the symmetry
//    (N1, N2) -> -(N1, N2) of Euler's equations; it keeps u0 in [-K, K], which
//    matters on the separatrix where K is infinite), and, written as sums of
//    non-negative terms so that nothing cancels,
//
//      a1^2 = J1 (Delta J3 - G^2)/(J3 - J1) = N1^2 + N2^2 J1 (J3 - J2)/(J2 (J3 - J1)),
//      a2^2 = J2 (Delta J3 - G^2)/(J3 - J2) = N2^2 + N1^2 J2 (J3 - J1)/(J1 (J3 - J2)),
//      a3^2 = J3 (G^2 - Delta J1)/(J3 - J1) = N3^2 + N2^2 J3 (J2 - J1)/(J2 (J3 - J1)),
//      k^2  = (J2 - J1)(Delta J3 - G^2)/((J3 - J2)(G^2 - Delta J1)) = (J2 - J1) J3 a1^2 / ((J3 - J2) J1 a3^2),
//      omega = (a3/J3) sqrt((J3 - J2)(J3 - J1)/(J1 J2)),
//
//    (Landau & Lifshitz, Mechanics, section 37, in terms of M). The signs
//    follow from N1dot = (1/J3 - 1/J2) N2 N3: a1 omega = (1/J2 - 1/J3) b2 b3
//    for N2 = b2 sn, N3 = b3 dn, so sign(b2 b3) = eta. The initial phase is
//    u0 = F(phi0, k), phi0 = atan2(sn u0, cn u0) = atan2(sigma1 eta s N2/a2, |N1|/a1).
//
// 2. The attitude. m = R M is constant. With n = N/G and the frame
//    C(n) = Rz(gamma) Rx(theta), gamma = alpha + pi/2, alpha = atan2(N2, N1),
//    theta = atan2(|(N1, N2)|, N3), so that C(n) e3 = (cos alpha sin theta,
//    sin alpha sin theta, cos theta) = n (Euler angles), the attitude in working axes is
//
//      R_w(t) = R_w(0) C(n(0)) Rz(psi(t)) C(n(t))^T,   psi(0) = 0,
//
//    which maps N(t) to R_w(0) N(0) = m for any psi. Requiring
//    R_w^T R_w' = hat(Omega) gives psi' = n . Omega + (twist of C about n)
//    = 2E/G + n3 alpha' = G (N1^2/J1 + N2^2/J2)/(N1^2 + N2^2) (Landau's
//    precession rate phi'). With G^2 - N3^2 = a1^2 + a3^2 k^2 sn^2 u and
//    (Delta J3 - G^2)/a1^2 = (J3 - J1)/J1:
//
//      psi'(t) = G/J3 + G (J3 - J1)/(J1 J3) / (1 - nu sn^2 u),
//      nu = -J3 (J2 - J1)/(J1 (J3 - J2))  (< 0; a constant of the body),
//
//      psi(t) = G t/J3 + G (J3 - J1)/(J1 J3 omega) [Pi(nu; am u, k) - Pi(nu; am u0, k)],
//
//    Pi the incomplete elliptic integral of the third kind (Boost's
//    ellint_3(k, nu, phi), convention 1 - nu sin^2). am u is continued past
//    pi/2 by u = 2 K m + r, |r| <= K: am u = m pi + am r and
//    Pi(nu; am u) = 2 m Pi(nu, k) + Pi(nu; am r).
//
//    Sign check against the published forms: the coefficient of Pi is
//    G (J3 - J1)/(J1 J3 omega), which is *positive* for the major-axis family
//    (J3 = I3) and *negative* for the minor-axis family (J3 = I1): there
//    psi' = G/I1 - G (I3 - I1)/(I1 I3)/(1 - nu sn^2), between G/I3 and G/I2.
//    Writing the minor-axis case with the major-axis sign (or with the
//    characteristic of the wrong sign) makes psi drift at the wrong rate; the
//    tests compare psi's direction and rate for both families and both signs
//    of the pole component against a tight numerical solution. In this frame
//    psi' does not depend on the sign s of the pole component (only N3^2
//    enters), unlike in the minimal-rotation alignment of Celledoni et al.,
//    where the (1 +- n3) factor changes with the hemisphere.
//
//    Quaternions (library convention: z(phi) = exp(phi/2 e3) rotates by phi):
//      c(n) = z(gamma) x(theta),  q_w(t) = q_w(0) c(n0) z(psi) c(n(t))^*,
//    with alpha unwrapped (alpha = alpha0-branch + eta s m pi) so that q(t) is
//    continuous in t and q(0) = q0 (same sign). Back in the body frame,
//    q = q_w v'^* and w = 2 V' N.
//
// 3. Degenerate cases, each in closed form:
//    * zero angular momentum: q(t) = q0, w = 0;
//    * M parallel to a principal axis (to 8 eps G): steady rotation
//      q(t) = q0 exp(t M0/(2 I_i)), w constant;
//    * axisymmetric body (two moments equal to 64 eps I3), symmetry axis a:
//      lambda = (M0 . a)(1/I_a - 1/I_perp),
//      q(t) = q0 exp(t M0/(2 I_perp)) exp(lambda t a/2),  M(t) = exp(-lambda t a/2) M0 exp(...)^*
//      (R(t) = exp(t hat(m)/I_perp) R0 Rot(a, lambda t)); a sphere has lambda = 0.
//    * the separatrix itself (k^2 rounds to 1): sn = tanh, cn = dn = sech and
//      no period reduction (K is infinite). Near it (k'^2 ~ 1e-6) the formulas
//      stay valid; the flow itself is ill-conditioned there (nearby orbits
//      separate like exp(omega t) for a while), see the tests.
#pragma once

#include <lgvi/checkpoint_fields.hpp>
#include <lgvi/methods/method_traits.hpp>
#include <lgvi/error.hpp>
#include <lgvi/lgvi.hpp>
#include <lgvi/potential.hpp>
#include <lgvi/rigid_body.hpp>
#include <lgvi/s3.hpp>
#include <lgvi/state.hpp>

#include <Eigen/Eigenvalues>
#include <boost/math/special_functions/ellint_1.hpp>
#include <boost/math/special_functions/ellint_3.hpp>
#include <boost/math/special_functions/jacobi_elliptic.hpp>

#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

namespace lgvi {

/// The exact free rigid body flow from (J, q0, w0); see the file comment.
class ExactFreeRigidBody {
 public:
  enum class Regime { Rest, Steady, Spherical, Axisymmetric, MajorAxisFamily, MinorAxisFamily };

  /// Rotational part only: at(t) leaves x and p at zero.
  ExactFreeRigidBody(const Matrix3<double>& inertia, const S3d& q0, const Vector3<double>& w0) {
    RigidBodyState s;
    s.q = q0;
    s.w = w0;
    setup(inertia, s, 0.0);
  }

  /// Rotation and translation: at(t) has x = x0 + t p0/m, p = p0.
  ExactFreeRigidBody(const RigidBody& body, const RigidBodyState& s0) { setup(body.inertia(), s0, 1.0 / body.mass()); }

  Regime regime() const { return regime_; }
  /// k^2 of the elliptic functions (0 outside the triaxial families).
  double modulus_squared() const { return static_cast<double>(k_ * k_); }
  /// |M| of the initial state.
  double momentum_norm() const { return G_; }
  /// The period 4 K/omega of M(t) in the triaxial families (infinite on the
  /// separatrix, 0 in the other regimes). After one period, R(T) R0^T is the
  /// rotation about m by precession_angle(T) (mod 2 pi).
  double period() const {
    if (regime_ != Regime::MajorAxisFamily && regime_ != Regime::MinorAxisFamily) return 0.0;
    return static_cast<double>(4 * K_ / omega_);
  }

  /// The exact state at time t (t of either sign).
  RigidBodyState at(double t) const {
    if (t == 0.0) return s0_;
    RigidBodyState s = s0_;
    s.x = s0_.x + (t * inv_mass_) * s0_.p;
    switch (regime_) {
      case Regime::Rest: break;
      case Regime::Steady: s.q = s0_.q * S3d::exp((0.5 * t / steady_moment_) * M0_); break;
      case Regime::Spherical:
      case Regime::Axisymmetric: {
        const S3d spin = S3d::exp((0.5 * lambda_ * t) * axis_);
        s.q = s0_.q * S3d::exp((0.5 * t / I_perp_) * M0_) * spin;
        s.w = 2.0 * spin.inverse().act(M0_);
        break;
      }
      default: {
        Vector3<double> N;
        S3d qw;
        triaxial(t, N, qw, nullptr);
        s.q = qw * vq_.inverse();
        s.w = 2.0 * (V_ * N);
      }
    }
    return s;
  }

  /// The precession angle psi(t) about m (triaxial families; 0 otherwise).
  double precession_angle(double t) const {
    if (regime_ != Regime::MajorAxisFamily && regime_ != Regime::MinorAxisFamily) return 0.0;
    Vector3<double> N;
    S3d qw;
    double psi = 0.0;
    triaxial(t, N, qw, &psi);
    return psi;
  }

 private:
  static S3d z_rotation(double angle) { return S3d(std::cos(0.5 * angle), 0.0, 0.0, std::sin(0.5 * angle)); }
  static S3d x_rotation(double angle) { return S3d(std::cos(0.5 * angle), std::sin(0.5 * angle), 0.0, 0.0); }

  void setup(const Matrix3<double>& J, const RigidBodyState& s0, double inv_mass) {
    constexpr double eps = std::numeric_limits<double>::epsilon();
    if (!J.allFinite() || !s0.all_finite()) throw InvalidInput("exact free body: non-finite inertia or state");
    s0_ = s0;
    inv_mass_ = inv_mass;
    M0_ = 0.5 * s0.w;
    G_ = M0_.norm();
    const Eigen::SelfAdjointEigenSolver<Matrix3<double>> es(J);
    const Vector3<double>& I = es.eigenvalues();  // ascending
    if (!(I(0) > 0.0)) throw InvalidInput("exact free body: the inertia must be positive definite");
    Matrix3<double> V = es.eigenvectors();
    if (V.determinant() < 0.0) V.col(2) = -V.col(2);
    if (G_ == 0.0) {
      regime_ = Regime::Rest;
      return;
    }
    const Vector3<double> Mp = V.transpose() * M0_;
    // Steady rotation: M along a principal axis to round-off.
    for (int i = 0; i < 3; ++i) {
      const double perp = std::hypot(Mp((i + 1) % 3), Mp((i + 2) % 3));
      if (perp <= 8 * eps * G_) {
        regime_ = Regime::Steady;
        steady_moment_ = I(i);
        return;
      }
    }
    // Axisymmetric: two equal moments (to the eigen-solver's round-off).
    const double tol = 64 * eps * I(2);
    const bool low_pair = I(1) - I(0) <= tol, high_pair = I(2) - I(1) <= tol;
    if (low_pair && high_pair) {
      regime_ = Regime::Spherical;
      I_perp_ = I.mean();
      lambda_ = 0.0;
      axis_ = Vector3<double>::UnitZ();
      return;
    }
    if (low_pair || high_pair) {
      regime_ = Regime::Axisymmetric;
      const int a = low_pair ? 2 : 0;
      axis_ = V.col(a);
      I_perp_ = low_pair ? 0.5 * (I(0) + I(1)) : 0.5 * (I(1) + I(2));
      lambda_ = M0_.dot(axis_) * (1.0 / I(a) - 1.0 / I_perp_);
      return;
    }
    // Triaxial: the family from the sign of G^2 - Delta I2.
    const double D = Mp(2) * Mp(2) * (I(2) - I(1)) / I(2) - Mp(0) * Mp(0) * (I(1) - I(0)) / I(0);
    if (D >= 0.0) {
      regime_ = Regime::MajorAxisFamily;
      V_ = V;
      J_ = I;
    } else {
      regime_ = Regime::MinorAxisFamily;
      V_.col(0) = V.col(2);
      V_.col(1) = -V.col(1);
      V_.col(2) = V.col(0);
      J_ = Vector3<double>(I(2), I(1), I(0));
    }
    vq_ = S3d::from_rotation_matrix(V_);
    const Vector3<double> N = V_.transpose() * M0_;
    // The elliptic part in extended precision (long double: 64-bit mantissa on
    // x86-64): near the separatrix Boost recomputes k' = sqrt(1 - k^2) from k,
    // which loses log10(1/k'^2) digits, and the flow there magnifies phase
    // errors; 11 more bits keep the error at the double data's level.
    const Real n1 = N(0), n2 = N(1), n3 = N(2), J1 = J_(0), J2 = J_(1), J3 = J_(2);
    eta_ = J3 > J2 ? 1 : -1;
    s_ = n3 >= 0 ? 1 : -1;
    sigma1_ = n1 >= 0 ? 1 : -1;
    a1_ = std::sqrt(n1 * n1 + n2 * n2 * J1 * (J3 - J2) / (J2 * (J3 - J1)));
    a2_ = std::sqrt(n2 * n2 + n1 * n1 * J2 * (J3 - J1) / (J1 * (J3 - J2)));
    a3_ = std::sqrt(n3 * n3 + n2 * n2 * J3 * (J2 - J1) / (J2 * (J3 - J1)));
    const Real k2 = (J2 - J1) * J3 * a1_ * a1_ / ((J3 - J2) * J1 * a3_ * a3_);
    k_ = std::sqrt(std::min(k2, Real(1)));
    omega_ = (a3_ / J3) * std::sqrt((J3 - J2) * (J3 - J1) / (J1 * J2));
    nu_ = -J3 * (J2 - J1) / (J1 * (J3 - J2));
    psi_rate_ = Real(G_) / J3;
    psi_coef_ = Real(G_) * (J3 - J1) / (J1 * J3 * omega_);
    const Real phi0 = std::atan2(sigma1_ * eta_ * s_ * n2 / a2_, std::abs(n1) / a1_);
    const Real half_pi = boost::math::constants::half_pi<Real>();
    if (k_ < 1) {
      u0_ = boost::math::ellint_1(k_, phi0);
      K_ = boost::math::ellint_1(k_);
      PiK_ = boost::math::ellint_3(k_, nu_, half_pi);
    } else {
      u0_ = std::atanh(std::sin(phi0));  // F(phi, 1) = atanh(sin phi)
      K_ = std::numeric_limits<Real>::infinity();
      PiK_ = 0;
    }
    Pi0_ = boost::math::ellint_3(k_, nu_, phi0);
    // The fixed left factor q_w(0) c(n0), with alpha0 on the branch used by triaxial().
    const S3d qw0 = s0.q * vq_;
    const double alpha0 = static_cast<double>(std::atan2(eta_ * s_ * a2_ * std::sin(phi0), a1_ * std::cos(phi0))) +
                          (sigma1_ < 0 ? EIGEN_PI : 0.0);
    const double theta0 = std::atan2(std::hypot(N(0), N(1)), N(2));
    left_ = qw0 * z_rotation(alpha0 + 0.5 * EIGEN_PI) * x_rotation(theta0);
  }

  /// N(t) (working frame) and q_w(t); psi(t) if asked.
  void triaxial(double t, Vector3<double>& N, S3d& qw, double* psi_out) const {
    const Real u = u0_ + omega_ * Real(t);
    Real m = 0, r = u;
    if (std::isfinite(K_)) {
      m = std::round(u / (2 * K_));
      r = u - 2 * K_ * m;
    }
    Real cn, dn;
    const Real sn = boost::math::jacobi_elliptic(k_, r, &cn, &dn);
    const Real parity = std::fmod(m, Real(2)) == 0 ? 1 : -1;
    N(0) = static_cast<double>(sigma1_ * parity * a1_ * cn);
    N(1) = static_cast<double>(sigma1_ * parity * eta_ * s_ * a2_ * sn);
    N(2) = static_cast<double>(s_ * a3_ * dn);
    const Real phi = std::atan2(sn, cn);  // am r, in [-pi/2, pi/2] since cn r >= 0
    const double psi =
        static_cast<double>(psi_rate_ * Real(t) + psi_coef_ * (2 * m * PiK_ + boost::math::ellint_3(k_, nu_, phi) - Pi0_));
    // alpha only matters mod 4 pi (through z(gamma)): keep m mod 4, exactly,
    // so that alpha stays small and its rounding does not grow with t.
    const double alpha = static_cast<double>(eta_ * s_ * std::fmod(m, Real(4)) * boost::math::constants::pi<Real>() +
                                             std::atan2(eta_ * s_ * a2_ * sn, a1_ * cn)) +
                         (sigma1_ < 0 ? EIGEN_PI : 0.0);
    const double theta = std::atan2(std::hypot(N(0), N(1)), N(2));
    const S3d c = z_rotation(alpha + 0.5 * EIGEN_PI) * x_rotation(theta);
    qw = left_ * z_rotation(psi) * c.inverse();
    if (psi_out) *psi_out = psi;
  }

  using Real = long double;

  RigidBodyState s0_;
  double inv_mass_ = 0.0;
  Vector3<double> M0_ = Vector3<double>::Zero();
  double G_ = 0.0;
  Regime regime_ = Regime::Rest;
  // Steady / axisymmetric.
  double steady_moment_ = 1.0, I_perp_ = 1.0, lambda_ = 0.0;
  Vector3<double> axis_ = Vector3<double>::UnitZ();
  // Triaxial.
  Matrix3<double> V_ = Matrix3<double>::Identity();
  S3d vq_;
  Vector3<double> J_ = Vector3<double>::Ones();
  Real eta_ = 1, s_ = 1, sigma1_ = 1, a1_ = 0, a2_ = 0, a3_ = 0, k_ = 0, omega_ = 0, nu_ = 0;
  Real psi_rate_ = 0, psi_coef_ = 0, u0_ = 0, K_ = 0, PiK_ = 0, Pi0_ = 0;
  S3d left_;
};

namespace detail {
/// True for ExternalField<P> with P anything but NoPotential: a field the
/// exact flow of a free body cannot take (a run's potential is checked by the
/// scenario reader instead).
template <class I>
constexpr bool is_potential_field = false;
template <class P>
constexpr bool is_potential_field<ExternalField<P>> = !std::is_same_v<P, NoPotential>;
}  // namespace detail

/// The exact flow on the stepper contract (method = "exact"): one free body
/// (three principal moments > 0), checked on construction. Step k gives
/// at((k - k_base) h) from the state at step k_base (0 unless resumed from
/// {k} alone), never accumulated, so the step size must stay the same from
/// call to call; t is not used. The flow is built at the first step, when h
/// is known.
template <class I>
class ExactFreeBodyStepper {
 public:
  static constexpr MethodTraits traits{"exact", "the free rigid body's exact flow (Celledoni, Fasso, Safstrom & Zanna 2008)", 0,
                                      /*symmetric=*/true, /*two_step=*/false, /*implicit=*/false,
                                      /*accepts_forcing=*/false, /*needs_principal_axes=*/false,
                                      /*free_body_only=*/true, /*linear_bodies=*/false};

  /// `potential` must be the free body's: an ExternalField of anything but
  /// NoPotential is refused here; for other types the caller checks (the
  /// exact flow knows no forces). More than one body is refused.
  ExactFreeBodyStepper(System system, I potential, SolverOptions = {}, Parallelism = {})
      : system_(std::move(system)), potential_(std::move(potential)), eval_(1) {
    if constexpr (detail::is_potential_field<I>)
      throw InvalidInput("integrator.method: \"exact\" is only available for the free body (no potential)");
    if (system_.size() != 1)
      throw InvalidInput("integrator.method: \"exact\" is the exact flow of one free body; this scenario has " +
                         std::to_string(system_.size()) + " bodies");
    detail::require_three_moments(system_, "the exact flow");
  }

  void initialize(const SystemState& s, double /*t*/) {
    h_ = 0.0;
    flow_.reset();
    pending_resume_ = false;
    state0_ = s.body(0);  // the free body: no potential to evaluate (eval_ stays zero)
  }

  void step(SystemState& s, double /*t*/, double h) {
    if (!flow_) start(h);
    if (h != h_)
      throw InvalidInput("integrator.step: the exact flow is sampled at multiples of one step size; got " +
                         std::to_string(h) + " after " + std::to_string(h_));
    ++k_;
    s.set_body(0, flow_->at(static_cast<double>(k_ - k_base_) * h_));
  }

  const System& system() const { return system_; }
  const I& potential() const { return potential_; }
  const SystemEvaluation& evaluation() const { return eval_; }
  const SolveReport& last_solve() const { return report_; }

  /// {k, k_base, x0 (3), q0 (4, scalar first), p0 (3), w0 (3)}: the step
  /// count and the state at step k_base, what a bit-identical resume needs.
  /// Once stepped, the flow's; resumed and not stepped since, the data
  /// resumed from ({k} alone as {k, k, the state resumed at}); {} after
  /// initialize() and before the first step.
  std::vector<double> internal_state() const {
    std::vector<double> v;
    if (flow_) {
      v = {static_cast<double>(k_), static_cast<double>(k_base_)};
      append_state(v, flow_->at(0.0));
    } else if (pending_resume_) {
      v = resume_data_;
      if (v.size() == 1) {  // the flow from the state resumed at, taken as step k
        v.push_back(v[0]);
        append_state(v, state0_);
      }
    }
    return v;
  }
  /// Checkpoint fields: "stepper.started" (0 when internal_state() is empty:
  /// a fresh start not stepped yet, then nothing else); "stepper.step_count",
  /// k and k_base, and "stepper.initial_state", the state the flow starts
  /// from at step k_base (13 numbers: x, q scalar first, p, w).
  void save(CheckpointFields& out) const {
    const std::vector<double> v = internal_state();
    out.put_i64("stepper.started", {v.empty() ? 0 : 1});
    if (v.empty()) return;
    out.put_i64("stepper.step_count", {static_cast<std::int64_t>(v[0]), static_cast<std::int64_t>(v[1])});
    out.put_f64("stepper.initial_state", std::vector<double>(v.begin() + 2, v.end()));
  }
  void load(const SystemState& s, double t, const CheckpointFields& in) {
    if (in.has("stepper.internal")) {
      const std::vector<double>& internal = in.f64("stepper.internal");
      detail::reading_stepper_internal([&] { resume(s, t, internal); });
      return;
    }
    if (in.i64_value("stepper.started") == 0) {
      resume(s, t, {});
      return;
    }
    const std::vector<std::int64_t>& k = in.i64("stepper.step_count", 2);
    std::vector<double> v{static_cast<double>(k[0]), static_cast<double>(k[1])};
    const std::vector<double>& s0 = in.f64("stepper.initial_state", 13);
    v.insert(v.end(), s0.begin(), s0.end());
    resume(s, t, v);
  }

  /// Resumes with saved internals (checked at the next step, when the flow
  /// is built): with the initial state saved (15 numbers), exactly as if
  /// never interrupted; with {k} only, from `s` taken as the state at step k
  /// (the same flow, not bit-identical).
  void resume(const SystemState& s, double t, const std::vector<double>& internal) {
    initialize(s, t);
    if (internal.empty()) return;
    resume_data_ = internal;
    pending_resume_ = true;  // (initialize() took s's body as state0_: the state resumed at)
  }

 private:
  static void append_state(std::vector<double>& v, const RigidBodyState& s) {
    const Vector4<double> q = s.q.scalar_first();
    v.insert(v.end(), {s.x.x(), s.x.y(), s.x.z(), q(0), q(1), q(2), q(3), s.p.x(), s.p.y(), s.p.z(), s.w.x(),
                       s.w.y(), s.w.z()});
  }

  /// The first step after initialize() or resume(): fixes h and builds the
  /// flow. On an error nothing changes (a resume stays pending).
  void start(double h) {
    detail::require_valid_step(h);
    if (!pending_resume_) {
      begin_flow(state0_, 0, 0);
    } else {
      resume_flow();
      pending_resume_ = false;
    }
    h_ = h;
  }
  void resume_flow() {
    const std::vector<double>& internal = resume_data_;
    if (internal.size() == 15) {
      RigidBodyState s0;
      s0.x = Vector3<double>(internal[2], internal[3], internal[4]);
      s0.q = S3d(internal[5], internal[6], internal[7], internal[8]);
      s0.p = Vector3<double>(internal[9], internal[10], internal[11]);
      s0.w = Vector3<double>(internal[12], internal[13], internal[14]);
      begin_flow(s0, static_cast<std::int64_t>(internal[1]), static_cast<std::int64_t>(internal[0]));
    } else if (internal.size() == 1) {
      begin_flow(state0_, static_cast<std::int64_t>(internal[0]), static_cast<std::int64_t>(internal[0]));
    } else {
      throw InvalidInput("checkpoint: exact free body data must hold 1 or 15 numbers, got " +
                         std::to_string(internal.size()));
    }
  }
  /// The flow from `s`, taken as the state at step k_base, at step k.
  void begin_flow(const RigidBodyState& s, std::int64_t k_base, std::int64_t k) {
    if (!s.all_finite()) throw InvalidInput("exact free body: the initial state must be finite");
    flow_.emplace(system_.body(0), s);
    k_base_ = k_base;
    k_ = k;
  }

  System system_;
  I potential_;
  SystemEvaluation eval_;
  SolveReport report_;
  double h_ = 0.0;  ///< the step size, fixed by the first step
  std::optional<ExactFreeRigidBody> flow_;  ///< the flow from the state at step k_base_ (empty before the first step)
  std::int64_t k_ = 0, k_base_ = 0;
  RigidBodyState state0_;  ///< the state given to initialize() or resume()
  std::vector<double> resume_data_;
  bool pending_resume_ = false;
};

}  // namespace lgvi
