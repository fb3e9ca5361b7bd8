// The exact free rigid body flow (exact_free_body.hpp) against a tight
// numerical solution: ContinuousEquations<NoPotential>::rk4 with h = 1e-4
// (or 1e-3 where stated), itself checked by halving the step.
//
// Tolerances. RK4's truncation error for these bodies (|Omega| ~ 1) is about
// C h^4 t ~ 1e-16 t per unit C at h = 1e-4, below the round-off it
// accumulates (~1e-13 over 1e5-1e6 steps, measured by halving below). The
// exact flow's own round-off is a few eps times the phase omega t. So 1e-10
// is the bound for well-conditioned cases (measured errors ~1e-13, printed by
// each test); cases close to the separatrix, where nearby orbits separate like
// exp(omega t) until the turning point, get a tolerance justified in place.
#include <lgvi/continuous.hpp>
#include <lgvi/exact_free_body.hpp>
#include <lgvi/integrate.hpp>

#include "test_support.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <type_traits>
#include <vector>

namespace lgvi::test_exact {
namespace {

constexpr double kPi = 3.14159265358979323846;

/// The same equations as ContinuousEquations<NoPotential>::derivative,
///   4 J xidot = -8 xi x J xi,  qdot = q (0, xi),
/// in long double (64-bit mantissa on x86-64), for the ill-conditioned cases
/// near the separatrix, where the double-precision reference's accumulated
/// round-off (~1e-13) is magnified to 1e-8 by the flow itself, and for bodies
/// that RigidBody rejects (the Hairer-Lubich-Wanner moments violate the
/// triangle inequality; the free body's equations do not care). Checked
/// against ContinuousEquations in ExactReference.ExtendedMirrorAgrees.
using LD = long double;
using Vec3L = Eigen::Matrix<LD, 3, 1>;
using Vec4L = Eigen::Matrix<LD, 4, 1>;
struct StateL {
  Vec3L xi;
  Vec4L q;  // scalar first
};
StateL rk4_extended(const Matrix3<double>& J, StateL s, LD h, long n) {
  const Eigen::Matrix<LD, 3, 3> JL = J.cast<LD>(), JiL = JL.inverse();
  auto d = [&](const StateL& c) {
    StateL r;
    r.xi = JiL * (LD(-2) * c.xi.cross(JL * c.xi));
    const Vec3L v = c.q.tail<3>();
    r.q(0) = -v.dot(c.xi);  // q (0, xi)
    r.q.tail<3>() = c.q(0) * c.xi + v.cross(c.xi);
    return r;
  };
  auto axpy = [](const StateL& a, const StateL& b, LD c) { return StateL{a.xi + c * b.xi, a.q + c * b.q}; };
  for (long k = 0; k < n; ++k) {
    const StateL k1 = d(s), k2 = d(axpy(s, k1, h / 2)), k3 = d(axpy(s, k2, h / 2)), k4 = d(axpy(s, k3, h));
    s.xi += (h / 6) * (k1.xi + 2 * k2.xi + 2 * k3.xi + k4.xi);
    s.q += (h / 6) * (k1.q + 2 * k2.q + 2 * k3.q + k4.q);
  }
  return s;
}

enum class Ref { Double, Extended };

/// The reference at times dt, 2 dt, ..., n dt (RK4 with step h):
/// ContinuousEquations<NoPotential>::rk4, or its long double mirror.
std::vector<RigidBodyState> reference(const Matrix3<double>& J, const RigidBodyState& s0, double dt, int n,
                                      double h = 1e-4, Ref kind = Ref::Double) {
  const long steps = std::lround(dt / h);
  std::vector<RigidBodyState> out;
  if (kind == Ref::Double) {
    const RigidBody body(1.0, J);
    const ContinuousEquations<NoPotential> eq(body, NoPotential{});
    ContinuousState c = to_continuous(s0, body);
    for (int i = 0; i < n; ++i) {
      c = eq.rk4(c, h, steps);
      out.push_back(from_continuous(c, body));
    }
  } else {
    // xi = Omega/2 = J^{-1} w/4.
    StateL c{(J.cast<LD>().inverse() * s0.w.cast<LD>()) / LD(4), s0.q.scalar_first().cast<LD>()};
    for (int i = 0; i < n; ++i) {
      c = rk4_extended(J, c, static_cast<LD>(dt) / static_cast<LD>(steps), steps);
      const Vector4<double> q = c.q.cast<double>();
      out.push_back({Vector3<double>::Zero(), S3d(q(0), q(1), q(2), q(3)), Vector3<double>::Zero(),
                     (LD(4) * J.cast<LD>() * c.xi).cast<double>()});
    }
  }
  return out;
}

/// q with the sign of `like` (q and -q are the same attitude).
Vector4<double> aligned(const S3d& q, const S3d& like) {
  const Vector4<double> v = q.scalar_first();
  return v.dot(like.scalar_first()) < 0 ? Vector4<double>(-v) : v;
}

struct MaxErrors {
  double q = 0, w = 0, sign_flip = 0;
};

/// Compares at(i dt) with the reference for i = 1..n, prints and returns the
/// max errors in q (sign-aligned) and w. sign_flip records whether the exact
/// q ever had the opposite sign to the reference (it is continuous in t and
/// starts at q0, like the RK4 solution, so it should not).
MaxErrors compare(const std::string& name, const Matrix3<double>& J, const RigidBodyState& s0, double dt, int n,
                  Ref kind = Ref::Double) {
  const ExactFreeRigidBody exact(J, s0.q, s0.w);
  const std::vector<RigidBodyState> ref = reference(J, s0, dt, n, 1e-4, kind);
  MaxErrors e;
  for (int i = 0; i < n; ++i) {
    const RigidBodyState s = exact.at((i + 1) * dt);
    e.q = std::max(e.q, (aligned(s.q, ref[i].q) - ref[i].q.scalar_first()).lpNorm<Eigen::Infinity>());
    e.w = std::max(e.w, (s.w - ref[i].w).lpNorm<Eigen::Infinity>());
    if (s.q.scalar_first().dot(ref[i].q.scalar_first()) < 0) e.sign_flip = 1;
  }
  std::printf("[ exact    ] %-26s k^2 = %-12.9g t <= %5.1f (%s ref): max |dq| = %.2e, max |dw| = %.2e\n",
              name.c_str(), exact.modulus_squared(), dt * n, kind == Ref::Double ? "double" : "long double", e.q, e.w);
  return e;
}

RigidBodyState state_with_momentum(const Vector3<double>& M, const S3d& q0) {
  RigidBodyState s;
  s.q = q0;
  s.w = 2.0 * M;
  return s;
}

const Matrix3<double> kJ123 = Vector3<double>(1, 2, 3).asDiagonal();
const S3d kQ0 = S3d(Eigen::Quaterniond(0.8, 0.2, -0.4, 0.4).normalized());

/// Body momentum with G^2 - 2 E I2 chosen so that 1 - k^2 = kp2 for J = diag(1, 2, 3):
/// M = (1, 0.5, M3) with M3^2 = 3 (1 + eps) (major side, eps > 0) or 3 (1 - eps)
/// (minor side). 1 - k^2 = (J3 - J1)(G^2 - 2E J2)/((J3 - J2)(G^2 - 2E J1)) in
/// the working frame gives eps = kp2 (M2^2/2 + 2 M1^2 (1 +- eps))/2 to first order;
/// the test reads back modulus_squared().
Vector3<double> near_separatrix(double kp2, double side) {
  double eps = kp2 * (0.125 + 2.0) / 2.0;
  for (int i = 0; i < 4; ++i) eps = kp2 * (0.125 + 2.0 * (1.0 + side * eps)) / 2.0;
  return Vector3<double>(1.0, 0.5, std::sqrt(3.0 * (1.0 + side * eps)));
}

// --- Reference self-check -----------------------------------------------------

TEST(ExactReference, Rk4HalvingAgreesTo1e12) {
  // The reference at h = 1e-4 against h = 5e-5 on the Manchester-Peck body
  // over t = 20 (2e5 and 4e5 steps): RK4's truncation error (~h^4) is far
  // below round-off, so the difference is accumulated round-off, ~1e-13.
  const RigidBodyState s0 = state_with_momentum(kJ123 * Vector3<double>(kPi / 10, kPi / 6, kPi / 8), kQ0);
  const auto a = reference(kJ123, s0, 5.0, 4, 1e-4);
  const auto b = reference(kJ123, s0, 5.0, 4, 5e-5);
  double dq = 0, dw = 0;
  for (int i = 0; i < 4; ++i) {
    dq = std::max(dq, (a[i].q.scalar_first() - b[i].q.scalar_first()).lpNorm<Eigen::Infinity>());
    dw = std::max(dw, (a[i].w - b[i].w).lpNorm<Eigen::Infinity>());
  }
  std::printf("[ exact    ] reference halving: |dq| = %.2e, |dw| = %.2e\n", dq, dw);
  EXPECT_LT(dq, 1e-12);
  EXPECT_LT(dw, 1e-12);
}

TEST(ExactReference, ExtendedMirrorAgrees) {
  // The long double mirror against ContinuousEquations::rk4 (both h = 1e-4)
  // on the Manchester-Peck body to t = 20: they differ by the double
  // reference's round-off, ~1e-13 (see the halving test). Bound 1e-12.
  const RigidBodyState s0 = state_with_momentum(kJ123 * Vector3<double>(kPi / 10, kPi / 6, kPi / 8), kQ0);
  const auto a = reference(kJ123, s0, 5.0, 4, 1e-4, Ref::Double);
  const auto b = reference(kJ123, s0, 5.0, 4, 1e-4, Ref::Extended);
  double dq = 0, dw = 0;
  for (int i = 0; i < 4; ++i) {
    dq = std::max(dq, (a[i].q.scalar_first() - b[i].q.scalar_first()).lpNorm<Eigen::Infinity>());
    dw = std::max(dw, (a[i].w - b[i].w).lpNorm<Eigen::Infinity>());
  }
  std::printf("[ exact    ] long double mirror vs ContinuousEquations: |dq| = %.2e, |dw| = %.2e\n", dq, dw);
  EXPECT_LT(dq, 1e-12);
  EXPECT_LT(dw, 1e-12);
}

// --- The exact flow against the reference ---------------------------------------

TEST(ExactFlow, MinorAxisFamily) {
  // G^2 < 2 E I2: M circles the minor axis (I1 = 1). Both signs of the pole
  // component M1 and of M2.
  for (const Vector3<double>& M : {Vector3<double>(1, 0.3, 0.2), Vector3<double>(-1, -0.3, 0.2),
                                  Vector3<double>(-1, 0.3, -0.2), Vector3<double>(1, -0.3, -0.2)}) {
    const RigidBodyState s0 = state_with_momentum(M, kQ0);
    ASSERT_EQ(ExactFreeRigidBody(kJ123, s0.q, s0.w).regime(), ExactFreeRigidBody::Regime::MinorAxisFamily);
    const MaxErrors e = compare("minor-axis family", kJ123, s0, 2.0, 25);
    EXPECT_LT(e.q, 1e-10);
    EXPECT_LT(e.w, 1e-10);
    EXPECT_EQ(e.sign_flip, 0);
  }
}

TEST(ExactFlow, MajorAxisFamily) {
  // G^2 > 2 E I2: M circles the major axis (I3 = 3). Both signs of M3 and M1.
  for (const Vector3<double>& M : {Vector3<double>(0.2, 0.3, 1), Vector3<double>(-0.2, 0.3, -1),
                                  Vector3<double>(0.2, -0.3, -1), Vector3<double>(-0.2, -0.3, 1)}) {
    const RigidBodyState s0 = state_with_momentum(M, kQ0);
    ASSERT_EQ(ExactFreeRigidBody(kJ123, s0.q, s0.w).regime(), ExactFreeRigidBody::Regime::MajorAxisFamily);
    const MaxErrors e = compare("major-axis family", kJ123, s0, 2.0, 25);
    EXPECT_LT(e.q, 1e-10);
    EXPECT_LT(e.w, 1e-10);
    EXPECT_EQ(e.sign_flip, 0);
  }
}

TEST(ExactFlow, NearSeparatrixBothSides) {
  // 1 - k^2 = 1e-6 on both sides, both signs of M3, over t = 60 (two
  // passages near the unstable intermediate axis; omega ~ 1.1, 4K ~ 33).
  // Each passage comes within ~k' G = 1e-3 G of the saddle and magnifies
  // errors by ~1/k' = 1e3: the double reference's own round-off (1e-13)
  // becomes 5e-8 there (measured: it differs from itself at h/2 by that much),
  // so the reference is the long double mirror, whose round-off is 2^11
  // smaller. The exact flow evaluates its elliptic part in long double for the
  // same reason. Measured exact - reference <= 1.2e-10 in w and 1.2e-11 in q;
  // the data's own conditioning (eps in M0 magnified by 1e3 per passage,
  // two passages) is ~1e-10, so 5e-9 is a bound with margin, far below what a
  // wrong modulus or period would give.
  for (const double side : {+1.0, -1.0}) {
    for (const double sign : {+1.0, -1.0}) {
      Vector3<double> M = near_separatrix(1e-6, side);
      M.z() *= sign;
      const RigidBodyState s0 = state_with_momentum(M, kQ0);
      const ExactFreeRigidBody exact(kJ123, s0.q, s0.w);
      EXPECT_NEAR(1.0 - exact.modulus_squared(), 1e-6, 1e-8);
      EXPECT_EQ(exact.regime(), side > 0 ? ExactFreeRigidBody::Regime::MajorAxisFamily
                                         : ExactFreeRigidBody::Regime::MinorAxisFamily);
      const MaxErrors e = compare(side > 0 ? "near separatrix (major)" : "near separatrix (minor)", kJ123, s0, 1.0,
                                  60, Ref::Extended);
      EXPECT_LT(e.q, 5e-9);
      EXPECT_LT(e.w, 5e-9);
      EXPECT_EQ(e.sign_flip, 0);
    }
  }
}

TEST(ExactFlow, NearPrincipalAxes) {
  // 1e-6 off the major and the minor axis (stable): k^2 ~ 1e-12, the
  // alignment frame's angle theta ~ 1e-6. Well conditioned: 1e-10.
  for (const Vector3<double>& M : {Vector3<double>(1e-6, 1e-6, 1), Vector3<double>(1, 1e-6, -1e-6),
                                  Vector3<double>(-1e-6, 2e-6, -1), Vector3<double>(-1, -1e-6, 1e-6)}) {
    const MaxErrors e = compare("near a principal axis", kJ123, state_with_momentum(M, kQ0), 2.0, 25);
    EXPECT_LT(e.q, 1e-10);
    EXPECT_LT(e.w, 1e-10);
  }
}

TEST(ExactFlow, IntermediateAxisFlips) {
  // Dzhanibekov: M = (1e-4, 2, 1e-4) near the unstable intermediate axis. The
  // saddle's rate is lambda = G sqrt((I2 - I1)(I3 - I2)/(I1 I3))/I2 = 0.577,
  // so M2 reverses after ~ln(4 G/1e-4)/lambda ~ 18 time units; we run to 60
  // and require at least two flips of M2 in both solutions. The flow is
  // ill-conditioned here: every passage near the saddle amplifies errors by
  // ~G/1e-4 = 2e4, so double round-off (1e-16) becomes ~1e-12 per passage and
  // ~1e-8 after two; hence the long double reference. Measured 2e-9 in w,
  // 2e-10 in q; tolerance 2e-8 (the conditioning bound above).
  const RigidBodyState s0 = state_with_momentum(Vector3<double>(1e-4, 2, 1e-4), kQ0);
  const ExactFreeRigidBody exact(kJ123, s0.q, s0.w);
  int flips = 0;
  double last = s0.w.y();
  for (int i = 1; i <= 600; ++i) {
    const double w2 = exact.at(0.1 * i).w.y();
    if (w2 * last < 0) ++flips;
    last = w2;
  }
  std::printf("[ exact    ] intermediate axis: %d flips of M2 in t <= 60\n", flips);
  EXPECT_GE(flips, 2);
  const MaxErrors e = compare("intermediate axis", kJ123, s0, 1.0, 60, Ref::Extended);
  EXPECT_LT(e.q, 2e-8);
  EXPECT_LT(e.w, 2e-8);
}

TEST(ExactFlow, Axisymmetric) {
  // Closed form: q(t) = q0 exp(t M0/(2 I_perp)) exp(lambda t a/2). Both an
  // oblate (1, 1, 2) and a prolate (1, 2, 2) body; well conditioned: 1e-10.
  for (const Vector3<double>& I : {Vector3<double>(1, 1, 2), Vector3<double>(1, 2, 2)}) {
    const Matrix3<double> J = I.asDiagonal();
    const RigidBodyState s0 = state_with_momentum(Vector3<double>(0.4, -0.7, 0.9), kQ0);
    EXPECT_EQ(ExactFreeRigidBody(J, s0.q, s0.w).regime(), ExactFreeRigidBody::Regime::Axisymmetric);
    const MaxErrors e = compare("axisymmetric", J, s0, 4.0, 25);
    EXPECT_LT(e.q, 1e-10);
    EXPECT_LT(e.w, 1e-10);
  }
}

TEST(ExactFlow, RotatedPrincipalAxes) {
  // J = Q diag(1, 2, 3) Q^T with a random Q: the flow diagonalizes J once.
  // A rotated axisymmetric J (eigenvalues equal only to round-off) must take
  // the axisymmetric branch. 1e-10.
  const Matrix3<double> Q = test::random_unit_quaternion().matrix();
  for (const Vector3<double>& I : {Vector3<double>(1, 2, 3), Vector3<double>(1.5, 1.5, 2.5)}) {
    Matrix3<double> J = Q * I.asDiagonal() * Q.transpose();
    J = 0.5 * (J + J.transpose()).eval();
    for (const Vector3<double>& M : {Vector3<double>(0.3, -0.8, 0.5), Vector3<double>(-0.9, 0.2, 0.1)}) {
      const MaxErrors e = compare("rotated principal axes", J, state_with_momentum(M, kQ0), 4.0, 25);
      EXPECT_LT(e.q, 1e-10);
      EXPECT_LT(e.w, 1e-10);
    }
  }
}

TEST(ExactFlow, ManchesterPeck) {
  // J = diag(1, 2, 3), Omega0 = (pi/10, pi/6, pi/8): major-axis family (G^2 - 2E I2 > 0). 1e-10.
  const RigidBodyState s0 = state_with_momentum(kJ123 * Vector3<double>(kPi / 10, kPi / 6, kPi / 8), S3d());
  EXPECT_EQ(ExactFreeRigidBody(kJ123, s0.q, s0.w).regime(), ExactFreeRigidBody::Regime::MajorAxisFamily);
  const MaxErrors e = compare("Manchester-Peck", kJ123, s0, 5.0, 20);
  EXPECT_LT(e.q, 1e-10);
  EXPECT_LT(e.w, 1e-10);
}

TEST(ExactFlow, HairerLubichWanner) {
  // Principal moments (2, 1, 2/3) (GNI, section I.2.5 / VII.5), M0 = (cos 1.1, 0,
  // sin 1.1); the axes are listed in descending order, and the moments violate
  // the triangle inequality, so the reference is the same RK4 outside RigidBody.
  const Matrix3<double> J = Vector3<double>(2, 1, 2.0 / 3.0).asDiagonal();
  const RigidBodyState s0 = state_with_momentum(Vector3<double>(std::cos(1.1), 0, std::sin(1.1)), kQ0);
  const MaxErrors e = compare("Hairer-Lubich-Wanner", J, s0, 5.0, 20, Ref::Extended);
  EXPECT_LT(e.q, 1e-10);
  EXPECT_LT(e.w, 1e-10);
}

TEST(ExactFlow, RandomStates) {
  // Random momenta and attitudes on diag(1, 2, 3) (seeded, LGVI_TEST_SEED):
  // generic orbits of both families; a random draw may land near the
  // separatrix, so the tolerance is 1e-8 (see NearSeparatrixBothSides).
  for (int i = 0; i < 6; ++i) {
    const RigidBodyState s0 = state_with_momentum(test::random_vector(1.0), test::random_unit_quaternion());
    const MaxErrors e = compare("random", kJ123, s0, 2.0, 10);
    EXPECT_LT(e.q, 1e-8);
    EXPECT_LT(e.w, 1e-8);
  }
}

// --- Degenerate cases ------------------------------------------------------------

TEST(ExactFlow, SteadyRotationAndRest) {
  // M exactly along a principal axis (including the intermediate one):
  // q(t) = q0 exp(t Omega/2), w constant, bit for bit.
  for (int axis = 0; axis < 3; ++axis) {
    const Vector3<double> M = 0.7 * Vector3<double>::Unit(axis);
    const RigidBodyState s0 = state_with_momentum(M, kQ0);
    const ExactFreeRigidBody exact(kJ123, s0.q, s0.w);
    EXPECT_EQ(exact.regime(), ExactFreeRigidBody::Regime::Steady);
    const RigidBodyState s = exact.at(13.0);
    EXPECT_EQ(s.w, s0.w);
    const Vector3<double> omega = kJ123.inverse() * M;
    EXPECT_MAT_NEAR(s.q.scalar_first(), (kQ0 * S3d::exp(6.5 * omega)).scalar_first(), 1e-15);
  }
  const ExactFreeRigidBody rest(kJ123, kQ0, Vector3<double>::Zero());
  EXPECT_EQ(rest.regime(), ExactFreeRigidBody::Regime::Rest);
  EXPECT_EQ(rest.at(5.0).q.scalar_first(), kQ0.scalar_first());
  EXPECT_EQ(rest.at(5.0).w, Vector3<double>::Zero());
}

TEST(ExactFlow, SphericalBody) {
  // J = 2 I: Omega = M/2 constant, q(t) = q0 exp(t M/4). 1e-14 (a few eps of the phase).
  const Matrix3<double> J = 2.0 * Matrix3<double>::Identity();
  const Vector3<double> M(0.3, -0.5, 0.8);
  const ExactFreeRigidBody exact(J, kQ0, 2.0 * M);
  EXPECT_EQ(exact.regime(), ExactFreeRigidBody::Regime::Spherical);
  const RigidBodyState s = exact.at(7.0);
  EXPECT_MAT_NEAR(s.q.scalar_first(), (kQ0 * S3d::exp(7.0 / 4.0 * M)).scalar_first(), 1e-14);
  EXPECT_MAT_NEAR(s.w, 2.0 * M, 1e-15);
}

// --- Invariants --------------------------------------------------------------------

TEST(ExactFlow, InvariantsToRoundOff) {
  // |M|, the energy and the spatial momentum pi(q) M are constant and |q| = 1
  // at every t, to round-off: each is a few operations on exactly computed
  // elliptic functions, so the error does not grow with t. Bounds: 1e-14
  // relative (about 50 eps), measured ~1e-15, over t up to 1000.
  const Matrix3<double> Jinv = kJ123.inverse();
  for (const Vector3<double>& M : {Vector3<double>(1, 0.3, 0.2), Vector3<double>(0.2, 0.3, -1),
                                  near_separatrix(1e-6, 1.0), near_separatrix(1e-6, -1.0)}) {
    const RigidBodyState s0 = state_with_momentum(M, kQ0);
    const ExactFreeRigidBody exact(kJ123, s0.q, s0.w);
    const double G = M.norm(), E = 0.5 * M.dot(Jinv * M);
    const Vector3<double> m = kQ0.act(M);
    double dG = 0, dE = 0, dm = 0, dq = 0;
    for (int i = 1; i <= 200; ++i) {
      const RigidBodyState s = exact.at(5.0 * i - 0.37);
      const Vector3<double> Mt = 0.5 * s.w;
      dG = std::max(dG, std::abs(Mt.norm() - G) / G);
      dE = std::max(dE, std::abs(0.5 * Mt.dot(Jinv * Mt) - E) / E);
      dm = std::max(dm, (s.q.act(Mt) - m).norm() / G);
      dq = std::max(dq, std::abs(s.q.norm_error()));
    }
    std::printf("[ exact    ] invariants: |M| %.1e, E %.1e, m %.1e, |q| - 1 %.1e\n", dG, dE, dm, dq);
    EXPECT_LT(dG, 1e-14);
    EXPECT_LT(dE, 1e-14);
    EXPECT_LT(dm, 1e-14);
    EXPECT_LT(dq, 1e-14);
  }
}

// --- The sign pitfall of the precession angle ------------------------------------

/// The angle of the rotation R about the unit axis a (R a = a), signed by a.
double rotation_angle_about(const Matrix3<double>& R, const Vector3<double>& a) {
  const Vector3<double> v = S3d::vee(R);  // the skew part of R: sin(angle) a
  return std::atan2(v.dot(a), 0.5 * (R.trace() - 1.0));
}

double wrap(double a) { return std::remainder(a, 2 * kPi); }

TEST(ExactPrecession, SignAndRateAgainstReferenceForBothFamiliesAndSigns) {
  // After one period T of M(t), R(T) R0^T is the rotation about m by the
  // precession angle psi(T) (mod 2 pi), a frame-independent quantity. The
  // reference's angle must match the formula's psi(T) (to 1e-9: RK4 at
  // h = 1e-4 over T ~ 10-30 plus the angle extraction), and must differ
  // clearly (> 0.1) from the value the formula gives with the sign of the
  // elliptic-integral term flipped, 2 G T/J3 - psi(T): so the test would
  // catch that error, for both families and both signs of the pole component.
  for (const Vector3<double>& M :
       {Vector3<double>(1, 0.3, 0.2), Vector3<double>(-1, 0.3, 0.2), Vector3<double>(0.2, 0.3, 1),
        Vector3<double>(0.2, 0.3, -1), Vector3<double>(0.6, -0.5, 0.9), Vector3<double>(-0.6, 0.5, -0.9)}) {
    const RigidBodyState s0 = state_with_momentum(M, kQ0);
    const ExactFreeRigidBody exact(kJ123, s0.q, s0.w);
    const double T = exact.period();
    ASSERT_TRUE(std::isfinite(T) && T > 0);
    const double h = T / std::ceil(T / 1e-4);
    const auto ref = reference(kJ123, s0, T, 1, h);
    const Vector3<double> m_hat = kQ0.act(M).normalized();
    const double psi_ref = rotation_angle_about(ref[0].q.matrix() * kQ0.matrix().transpose(), m_hat);
    const double psi = exact.precession_angle(T);
    const bool major = exact.regime() == ExactFreeRigidBody::Regime::MajorAxisFamily;
    const double J3 = major ? 3.0 : 1.0;  // the pole axis's moment
    const double psi_wrong = 2.0 * M.norm() * T / J3 - psi;
    std::printf("[ exact    ] %s, pole %+g: T = %.4f, psi(T) = %.12f, reference %.12f, wrong sign %.4f\n",
                major ? "major" : "minor", major ? M.z() : M.x(), T, wrap(psi), psi_ref, wrap(psi_wrong));
    EXPECT_LT(std::abs(wrap(psi - psi_ref)), 1e-9);
    EXPECT_GT(std::abs(wrap(psi_wrong - psi_ref)), 0.1);
    // M(T) = M(0): the period is right.
    EXPECT_MAT_NEAR(exact.at(T).w, s0.w, 1e-12);
  }
}

TEST(ExactPrecession, RateBoundsForBothFamilies) {
  // psi' = G (N1^2/J1 + N2^2/J2)/(N1^2 + N2^2) lies between G/I2 and G/I1 in
  // the major-axis family and between G/I3 and G/I2 in the minor-axis family
  // (Landau's precession rate), for either sign of the pole component. Checked
  // by central differences of precession_angle with step 1e-4: the quotient's
  // error is O(dt^2) ~ 1e-8 G, so the bounds get a margin of 1e-6 G.
  struct Case {
    Vector3<double> M;
    double lo, hi;  // in units of G
  };
  for (const Case& c : {Case{{0.2, 0.3, 1}, 1.0 / 2, 1.0}, Case{{0.2, 0.3, -1}, 1.0 / 2, 1.0},
                        Case{{1, 0.3, 0.2}, 1.0 / 3, 1.0 / 2}, Case{{-1, 0.3, 0.2}, 1.0 / 3, 1.0 / 2}}) {
    const ExactFreeRigidBody exact(kJ123, kQ0, 2.0 * c.M);
    const double G = c.M.norm();
    for (int i = 0; i < 50; ++i) {
      const double t = 0.37 * i, dt = 1e-4;
      const double rate = (exact.precession_angle(t + dt) - exact.precession_angle(t - dt)) / (2 * dt) / G;
      EXPECT_GT(rate, c.lo - 1e-6) << "t = " << t;
      EXPECT_LT(rate, c.hi + 1e-6) << "t = " << t;
    }
  }
}

// --- The stepper ------------------------------------------------------------------

TEST(ExactStepper, IsASystemStepperAndMatchesAt) {
  using Exact = SingleBody<ExactFreeBodyStepper, NoPotential>;
  static_assert(SystemStepper<Exact>);
  const RigidBody body(2.0, kJ123);
  RigidBodyState s0 = state_with_momentum(Vector3<double>(0.6, -0.5, 0.9), kQ0);
  s0.x = Vector3<double>(1, 2, 3);
  s0.p = Vector3<double>(0.2, -0.4, 0.6);
  Exact stepper(body, NoPotential{});
  const ExactFreeRigidBody exact(body, s0);
  SystemState s(s0);
  std::vector<RigidBodyState> seen;
  integrate_n_steps(stepper, s, 0.0, 0.01, 1000, [&](const SystemStepInfo& info) { seen.push_back(info.state.body(0)); });
  ASSERT_EQ(seen.size(), 1001u);
  for (int k = 0; k <= 1000; k += 100) {
    // Bit-identical: step k is at(k h) from the initial state, not accumulated.
    const RigidBodyState e = exact.at(0.01 * k);
    EXPECT_EQ(seen[k].q.scalar_first(), e.q.scalar_first());
    EXPECT_EQ(seen[k].w, e.w);
    EXPECT_EQ(seen[k].x, e.x);
  }
  // x = x0 + t p/m, p constant; q continuous (no sign jumps between steps).
  EXPECT_MAT_NEAR(seen[1000].x, s0.x + 10.0 * s0.p / 2.0, 1e-14);
  EXPECT_EQ(seen[1000].p, s0.p);
  for (std::size_t k = 1; k < seen.size(); ++k) EXPECT_GT(seen[k].q.scalar_first().dot(seen[k - 1].q.scalar_first()), 0.9);
  EXPECT_EQ(stepper.evaluation().energy, 0.0);
  EXPECT_EQ(stepper.last_solve().iterations, 0);
}

TEST(ExactStepper, ResumeIsBitIdentical) {
  const RigidBody body(1.0, kJ123);
  const RigidBodyState s0 = state_with_momentum(Vector3<double>(1, 0.3, 0.2), kQ0);
  using Exact = SingleBody<ExactFreeBodyStepper, NoPotential>;
  const double h = 0.05;
  Exact a(body, NoPotential{});
  SystemState sa(s0);
  a.initialize(sa, 0.0);
  for (int k = 0; k < 40; ++k) a.step(sa, k * h, h);
  const std::vector<double> saved = a.internal_state();
  const SystemState at40 = sa;
  for (int k = 40; k < 80; ++k) a.step(sa, k * h, h);
  Exact b(body, NoPotential{});
  SystemState sb = at40;
  b.resume(sb, 40 * h, saved);
  for (int k = 40; k < 80; ++k) b.step(sb, k * h, h);
  EXPECT_EQ(sa.q[0].scalar_first(), sb.q[0].scalar_first());
  EXPECT_EQ(sa.w[0], sb.w[0]);
  // Resuming from {k} alone continues the same flow from the given state.
  Exact c(body, NoPotential{});
  SystemState sc = at40;
  c.resume(sc, 40 * h, {40.0});
  for (int k = 40; k < 80; ++k) c.step(sc, k * h, h);
  EXPECT_MAT_NEAR(aligned(sc.q[0], sa.q[0]), sa.q[0].scalar_first(), 1e-13);
  EXPECT_MAT_NEAR(sc.w[0], sa.w[0], 1e-13);
  EXPECT_EQ(c.internal_state()[0], 80.0);
}

TEST(ExactStepper, CheckpointFieldsInEveryPhase) {
  // What save() writes is what a continuation needs, bit for bit, in each phase: a fresh start not stepped
  // (nothing but started = 0), stepped (k, k_base and the state at k_base), and resumed but not stepped since
  // (the data resumed from; {k} alone as {k, k, the state resumed at}). load() of each continues as the
  // stepper that wrote it does, to the bit (every step is at((k - k_base) h) from the same state).
  using Exact = SingleBody<ExactFreeBodyStepper, NoPotential>;
  const RigidBody body(1.0, kJ123);
  const double h = 0.05;
  const RigidBodyState s0 = state_with_momentum(Vector3<double>(1, 0.3, 0.2), kQ0);
  auto saved = [](const Exact& e) {
    CheckpointFields f;
    e.save(f);
    return f;
  };
  auto continued = [&](Exact& e, SystemState s, std::int64_t from) {
    for (std::int64_t k = from; k < from + 40; ++k) e.step(s, static_cast<double>(k) * h, h);
    return s.body(0);
  };
  Exact a(body, NoPotential{});
  EXPECT_EQ(a.body().mass(), body.mass());  // the one body's accessors
  EXPECT_EQ(a.body().inertia(), body.inertia());
  static_assert(std::is_same_v<decltype(a.body_potential()), const NoPotential&>);
  SystemState s(s0);
  a.initialize(s, 0.0);
  const CheckpointFields fresh = saved(a);
  ASSERT_EQ(fresh.fields().size(), 1u);
  EXPECT_EQ(fresh.i64_value("stepper.started"), 0);
  for (int k = 0; k < 40; ++k) a.step(s, k * h, h);
  const SystemState at40 = s;
  const CheckpointFields stepped = saved(a);
  const std::vector<double> internal40 = a.internal_state();
  EXPECT_EQ(stepped.i64_value("stepper.started"), 1);
  EXPECT_EQ(stepped.i64("stepper.step_count", 2), (std::vector<std::int64_t>{40, 0}));
  const Vector4<double> q0 = s0.q.scalar_first();
  EXPECT_EQ(stepped.f64("stepper.initial_state", 13),
            (std::vector<double>{s0.x.x(), s0.x.y(), s0.x.z(), q0(0), q0(1), q0(2), q0(3), s0.p.x(), s0.p.y(),
                                 s0.p.z(), s0.w.x(), s0.w.y(), s0.w.z()}));
  const RigidBodyState a80 = continued(a, at40, 40);
  // Each phase written, loaded by a fresh stepper, continued.
  Exact b(body, NoPotential{});
  b.load(at40, 40 * h, stepped);
  EXPECT_EQ(saved(b).fields().size(), 3u);  // resumed, not stepped: the same fields
  EXPECT_EQ(saved(b).i64("stepper.step_count"), stepped.i64("stepper.step_count"));
  EXPECT_EQ(saved(b).f64("stepper.initial_state"), stepped.f64("stepper.initial_state"));
  EXPECT_EQ(b.internal_state(), internal40);
  const RigidBodyState b80 = continued(b, at40, 40);
  EXPECT_EQ(b80.q.scalar_first(), a80.q.scalar_first());
  EXPECT_EQ(b80.w, a80.w);
  Exact c(body, NoPotential{});
  c.resume(at40, 40 * h, {40.0});
  const CheckpointFields from_k = saved(c);
  EXPECT_EQ(from_k.i64("stepper.step_count", 2), (std::vector<std::int64_t>{40, 40}));
  const RigidBodyState r = at40.body(0);
  const Vector4<double> qr = r.q.scalar_first();
  EXPECT_EQ(from_k.f64("stepper.initial_state", 13),
            (std::vector<double>{r.x.x(), r.x.y(), r.x.z(), qr(0), qr(1), qr(2), qr(3), r.p.x(), r.p.y(), r.p.z(),
                                 r.w.x(), r.w.y(), r.w.z()}));
  Exact d(body, NoPotential{});
  d.load(at40, 40 * h, from_k);
  const RigidBodyState c80 = continued(c, at40, 40), d80 = continued(d, at40, 40);
  EXPECT_EQ(d80.q.scalar_first(), c80.q.scalar_first());
  EXPECT_EQ(d80.w, c80.w);
  Exact e(body, NoPotential{});
  e.load(at40, 40 * h, fresh);  // a checkpoint of a fresh start: a fresh start from the given state
  EXPECT_TRUE(e.internal_state().empty());
  // Malformed data is refused at the first step, and stays refused (the resume stays pending).
  Exact bad(body, NoPotential{});
  SystemState sb = at40;
  bad.resume(sb, 40 * h, {40.0, 0.0});
  for (int attempt = 0; attempt < 2; ++attempt) {
    try {
      bad.step(sb, 40 * h, h);
      ADD_FAILURE() << "no error for 2 numbers";
    } catch (const InvalidInput& err) {
      EXPECT_THAT(err.what(), ::testing::HasSubstr("must hold 1 or 15 numbers, got 2"));
    }
  }
  EXPECT_EQ(bad.internal_state(), (std::vector<double>{40.0, 0.0}));
}

TEST(ExactStepper, RejectsPotentialsAndBadSteps) {
  const RigidBody body(1.0, kJ123);
  EXPECT_THROW((SingleBody<ExactFreeBodyStepper, UniformGravity>(body, UniformGravity(body, Vector3<double>(0, 0, -9.81)))),
               InvalidInput);
  SingleBody<ExactFreeBodyStepper, NoPotential> exact(body, NoPotential{});
  SystemState s(state_with_momentum(Vector3<double>(1, 0.3, 0.2), kQ0));
  exact.initialize(s, 0.0);
  EXPECT_THROW(exact.step(s, 0.0, 0.0), InvalidInput);  // the flow is built at the first step, with its h
  exact.initialize(s, 0.0);
  exact.step(s, 0.0, 0.1);
  EXPECT_THROW(exact.step(s, 0.1, 0.05), InvalidInput);  // sampled at multiples of one step size
  EXPECT_THROW(ExactFreeBodyStepper<ExternalField<NoPotential>>(System(std::vector<RigidBody>(2, body)),
                                                               ExternalField<NoPotential>::uniform(NoPotential{}, 2)),
               InvalidInput);  // one body only
}

}  // namespace
}  // namespace lgvi::test_exact
