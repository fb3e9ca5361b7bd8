// Property tests of S^3 (s3.hpp), run over the identity, near-identity,
// random and hard elements (rotation by pi, -q, tiny angles), in the manner
// of manif's common tester. Tolerances are multiples of eps = 2.2e-16: each
// identity is exact in real arithmetic, so only the rounding of O(10)
// floating-point operations on O(1) numbers separates the two sides.
#include <lgvi/s3.hpp>

#include "test_support.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <vector>

namespace test_s3 {

namespace {

using lgvi::S3d;
using V3 = lgvi::Vector3<double>;
using M3 = lgvi::Matrix3<double>;
constexpr double eps = 2.220446049250313e-16;
const double pi = std::acos(-1.0);

struct Element {
  std::string name;
  V3 xi;  // q = exp(xi)
};

std::vector<Element> elements() {
  std::vector<Element> e{{"identity", V3::Zero()},
                         {"near_identity_1em8", V3(1e-8, -2e-8, 0.5e-8)},
                         {"tiny_1em12", V3(0, 0, 1e-12)},
                         {"small_1em4", V3(1e-4, 0, -1e-4)},
                         {"taylor_boundary", V3(2.4e-3, 0, 0)},
                         {"rotation_by_pi_x", V3(pi / 2, 0, 0)},
                         {"rotation_by_pi_skew", V3(1, 1, 1).normalized() * (pi / 2)},
                         {"near_minus_identity", V3(0, 3.1, 0)},
                         {"large", V3(1.2, -0.7, 0.4)}};
  for (int i = 0; i < 8; ++i) e.push_back({"random_" + std::to_string(i), lgvi::test::random_vector(1.5)});
  return e;
}

class S3Property : public ::testing::TestWithParam<Element> {};

TEST_P(S3Property, ExpIsUnitAndMatchesAngleAxis) {
  const V3 xi = GetParam().xi;
  const S3d q = S3d::exp(xi);
  EXPECT_LE(std::abs(q.norm_error()), 2 * eps);
  // pi(exp(xi)) is the rotation by 2|xi| about xi/|xi| (Eigen's independent construction).
  const double theta = xi.norm();
  const M3 r = theta > 0 ? Eigen::AngleAxisd(2 * theta, xi / theta).toRotationMatrix() : M3::Identity();
  EXPECT_MAT_NEAR(q.matrix(), r, 8 * eps);
}

TEST_P(S3Property, LogInvertsExp) {
  const V3 xi = GetParam().xi;
  // log is Lipschitz away from |xi| = pi: error relative to |xi| at round-off;
  // near -1 (|xi| = 3.1) the direction q_v/|q_v| costs a factor 1/sin|xi| ~ 24.
  const double cond = 1.0 / std::max(std::sin(xi.norm()) / std::max(xi.norm(), 1e-300), 1e-3);
  EXPECT_MAT_NEAR(S3d::exp(xi).log(), xi, 8 * eps * cond * std::max(1.0, xi.norm()));
}

TEST_P(S3Property, ExpInvertsLog) {
  const S3d q = S3d::exp(GetParam().xi);
  EXPECT_MAT_NEAR(S3d::exp(q.log()).scalar_first(), q.scalar_first(), 8 * eps);
  // -q is another element (same rotation): log/exp round trip as well.
  const S3d mq(-q.w(), -q.vec().x(), -q.vec().y(), -q.vec().z());
  EXPECT_MAT_NEAR(S3d::exp(mq.log()).scalar_first(), mq.scalar_first(), 64 * eps);
  EXPECT_MAT_NEAR(mq.matrix(), q.matrix(), 4 * eps);  // pi(-q) = pi(q)
}

TEST_P(S3Property, PiIsAHomomorphismIntoSO3) {
  const S3d q1 = S3d::exp(GetParam().xi);
  const S3d q2 = lgvi::test::random_unit_quaternion();
  EXPECT_MAT_NEAR((q1 * q2).matrix(), q1.matrix() * q2.matrix(), 16 * eps);
  EXPECT_MAT_NEAR(q1.matrix() * q1.matrix().transpose(), M3::Identity(), 8 * eps);
  EXPECT_NEAR(q1.matrix().determinant(), 1.0, 8 * eps);
  EXPECT_MAT_NEAR(q1.matrix(), q1.quaternion().toRotationMatrix(), 8 * eps);  // Eigen's formula
  EXPECT_MAT_NEAR(q1.inverse().matrix(), q1.matrix().transpose(), 8 * eps);
  const V3 v = lgvi::test::random_vector();
  EXPECT_MAT_NEAR(q1.act(v), q1.matrix() * v, 8 * eps);
  // act() is Eigen's q * v written out, operation for operation: equal bit for
  // bit (the reason it may replace it without changing any output).
  EXPECT_EQ(q1.act(v), q1.quaternion() * v);
  for (int k = 0; k < 100; ++k) {
    const S3d q = lgvi::test::random_unit_quaternion();
    const V3 w = lgvi::test::random_vector(10.0);
    EXPECT_EQ(q.act(w), q.quaternion() * w);
  }
}

// matrix() is the Eigen expression of the paper's formula written out, entry by
// entry in its operations' order: equal bit for bit (so that it replaced the
// expression without changing any output), here over random attitudes and the
// hard cases (the identity, half turns with q_s = +-0, a near-identity).
TEST(S3Matrix, IsThePapersFormulaAsAnEigenExpressionBitForBit) {
  auto expression = [](const S3d& q) {
    const double s = q.w();
    const V3 v = q.quaternion().vec();
    M3 r = (2.0 * v) * v.transpose();
    r.diagonal().array() += 2.0 * s * s - 1.0;
    r += (2.0 * s) * S3d::hat(v);
    return r;
  };
  std::vector<S3d> cases = {S3d(), S3d(0.0, 1.0, 0.0, 0.0), S3d(-0.0, 0.0, -1.0, 0.0), S3d(0.0, 0.6, 0.0, -0.8),
                            S3d::exp(V3(1e-9, -2e-9, 3e-9))};
  for (int k = 0; k < 1000; ++k) cases.push_back(lgvi::test::random_unit_quaternion());
  for (const S3d& q : cases) {
    const M3 written = q.matrix(), reference = expression(q);
    for (int i = 0; i < 9; ++i)
      EXPECT_EQ(std::bit_cast<std::uint64_t>(written(i)), std::bit_cast<std::uint64_t>(reference(i)))
          << "entry " << i << " of q = " << q.quaternion().coeffs().transpose();
  }
}

TEST_P(S3Property, LiftOfRotationMatrixIsAPreimage) {
  const S3d q = S3d::exp(GetParam().xi);
  const S3d lifted = S3d::from_rotation_matrix(q.matrix());
  EXPECT_GE(lifted.w(), 0.0);
  EXPECT_MAT_NEAR(lifted.matrix(), q.matrix(), 16 * eps);
  EXPECT_NEAR(std::abs(lifted.quaternion().dot(q.quaternion())), 1.0, 16 * eps);  // +-q
}

TEST_P(S3Property, ExpJacobianMatchesFiniteDifferences) {
  const V3 xi = GetParam().xi;
  double c, sinc;
  S3d::cos_and_sinc(xi.norm(), c, sinc);
  const M3 d = lgvi::exp_imaginary_jacobian<double>(xi, c, sinc);
  // Central differences: truncation ~ h^2 |d^3 f| / 6 <= h^2, round-off ~ eps / h;
  // h = 1e-5 gives ~1e-10 at worst.
  const double h = 1e-5;
  M3 fd;
  for (int j = 0; j < 3; ++j) {
    V3 dx = V3::Zero();
    dx(j) = h;
    fd.col(j) = (S3d::exp(xi + dx).vec() - S3d::exp(xi - dx).vec()) / (2 * h);
  }
  EXPECT_MAT_NEAR(d, fd, 2e-10);
  // d Re(exp)/dxi = -Im(exp)^T.
  for (int j = 0; j < 3; ++j) {
    V3 dx = V3::Zero();
    dx(j) = h;
    EXPECT_NEAR((S3d::exp(xi + dx).w() - S3d::exp(xi - dx).w()) / (2 * h), -S3d::exp(xi).vec()(j), 2e-10);
  }
}

TEST_P(S3Property, LeftTrivializedTangentIsQTimesPureQuaternion) {
  // d/dl q exp(l eta) at l = 0 equals q (0, eta) = F(q)^T eta (the paper's delta q).
  const S3d q = S3d::exp(GetParam().xi);
  const V3 eta = lgvi::test::random_vector();
  const double h = 1e-5;
  const lgvi::Vector4<double> fd =
      ((q * S3d::exp(h * eta)).scalar_first() - (q * S3d::exp(-h * eta)).scalar_first()) / (2 * h);
  EXPECT_MAT_NEAR(fd, (lgvi::F(q.quaternion()).transpose() * eta).eval(), 1e-10);
}

TEST_P(S3Property, TimesNearIdentityIsTheProduct) {
  // q + q (f - e) is q f: a few roundings of O(1) numbers apart (f_s <= 0,
  // near -identity, takes the plain product).
  const S3d f = S3d::exp(GetParam().xi), q = lgvi::test::random_unit_quaternion();
  EXPECT_MAT_NEAR(q.times_near_identity(f).scalar_first(), (q * f).scalar_first(), 8 * eps);
}

INSTANTIATE_TEST_SUITE_P(Elements, S3Property, ::testing::ValuesIn(elements()),
                         [](const auto& info) { return info.param.name; });

TEST(S3, HatAndVee) {
  const V3 a = lgvi::test::random_vector(), b = lgvi::test::random_vector();
  EXPECT_MAT_NEAR((S3d::hat(a) * b).eval(), a.cross(b), 4 * eps);
  EXPECT_EQ(S3d::vee(S3d::hat(a)), a);  // exact: vee reads the entries hat wrote
  EXPECT_MAT_NEAR((S3d::hat(a) + S3d::hat(a).transpose()).eval(), M3::Zero(), 0.0);
}

TEST(S3, FAndGDefiningIdentitiesOnAllOfH) {
  // F and G are defined on all quaternions, not only unit ones.
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Quaterniond q(lgvi::test::uniform(-2, 2), lgvi::test::uniform(-2, 2), lgvi::test::uniform(-2, 2),
                               lgvi::test::uniform(-2, 2));
    const V3 v = lgvi::test::random_vector();
    const Eigen::Quaterniond pv(0.0, v.x(), v.y(), v.z());
    const Eigen::Quaterniond prod = q * pv;
    const lgvi::Vector4<double> prod_sf(prod.w(), prod.x(), prod.y(), prod.z());
    EXPECT_MAT_NEAR((lgvi::F(q).transpose() * v).eval(), prod_sf, 16 * eps);  // q (0, v) = F(q)^T v
    EXPECT_MAT_NEAR((lgvi::G(q).transpose() * v).eval(), prod.vec(), 16 * eps);  // Im(q (0, v)) = G(q)^T v
  }
}

TEST(S3, SmallAngleSeriesAreContinuousAtTheirThresholds) {
  // Either side of each threshold the series and the closed forms agree to
  // round-off, so switching branches leaves no visible step.
  const double t6 = lgvi::detail::taylor_threshold<double>(5), t4 = lgvi::detail::taylor_threshold<double>(3);
  for (double t : {t6 * (1 - 1e-9), t6 * (1 + 1e-9)}) {
    double c, sinc;
    S3d::cos_and_sinc(t, c, sinc);
    EXPECT_NEAR(c, std::cos(t), eps);
    EXPECT_NEAR(sinc, std::sin(t) / t, eps);
  }
  const V3 below = V3(1, 2, 2).normalized() * (t4 * 0.999), above = V3(1, 2, 2).normalized() * (t4 * 1.001);
  double c1, s1, c2, s2;
  S3d::cos_and_sinc(below.norm(), c1, s1);
  S3d::cos_and_sinc(above.norm(), c2, s2);
  // The jacobian varies by O(|xi| d|xi|) ~ 1e-11 across the 0.2% gap.
  EXPECT_MAT_NEAR(lgvi::exp_imaginary_jacobian<double>(below, c1, s1),
                  lgvi::exp_imaginary_jacobian<double>(above, c2, s2), 1e-10);
}

TEST(S3, RepeatedStepOfASteadySpinKeepsTheNormAtRoundOff) {
  // A steady spin repeats one relative rotation f, so the rounding of q f is
  // not random from step to step: f's scalar part is within |f_v|^2 of 1,
  // where its stored value carries an absolute error of up to eps/4, the
  // same every step. With q <- q f, |q| - 1 then grows linearly (1e-16 per
  // step measured in a Lennard-Jones gas). q + q (f - e) lets that error enter
  // only times |f_v|, and leaves the rounding of the sum, which varies with q
  // and random-walks. Over 16 random steady spins of 1e5 steps each, |q| - 1
  // stays within 4 eps sqrt(n) (the walk of eps per step, with margin), where
  // the plain product exceeds that bound (the test tells the two apart).
  const int n = 100000;
  const double walk = 4 * eps * std::sqrt(static_cast<double>(n));
  double worst = 0, worst_plain = 0;
  for (int spin = 0; spin < 16; ++spin) {
    const S3d f = S3d::exp(lgvi::test::random_vector(1e-2));
    S3d q_plain = lgvi::test::random_unit_quaternion(), q = q_plain;
    for (int k = 0; k < n; ++k) {
      q_plain = q_plain * f;
      q = q.times_near_identity(f);
      worst = std::max(worst, std::abs(q.norm_error()));
    }
    worst_plain = std::max(worst_plain, std::abs(q_plain.norm_error()));
  }
  EXPECT_LE(worst, walk);
  EXPECT_GE(worst_plain, walk);
  std::printf("[ lgvi     ] 16 steady spins, 1e5 steps: max |q| - 1 %.2g (bound %.2g), plain product %.2g\n", worst,
              walk, worst_plain);
}

TEST(S3, LogOfMinusIdentityAndPureRotationByPi) {
  EXPECT_NEAR(S3d(-1, 0, 0, 0).log().norm(), pi, 0.0);
  const V3 xi = S3d(0, 0, 1, 0).log();  // rotation by pi about y
  EXPECT_MAT_NEAR(xi, V3(0, pi / 2, 0), 2 * eps);
}

}  // namespace

}  // namespace test_s3
