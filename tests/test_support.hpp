// Helpers shared by the tests: reproducible randomness (a fixed seed that is
// printed and that LGVI_TEST_SEED overrides, as in Eigen's tests), and
// comparisons that print both values on failure (as in manif's tests).
#pragma once

#include <lgvi/integrate.hpp>
#include <lgvi/paper.hpp>
#include <lgvi/s3.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace lgvi::test {

inline unsigned seed() {
  static const unsigned s = [] {
    unsigned v = 20261121u;
    if (const char* env = std::getenv("LGVI_TEST_SEED")) v = static_cast<unsigned>(std::strtoul(env, nullptr, 10));
    return v;
  }();
  return s;
}

/// Prints the seed when tests run (not when they are listed).
class SeedPrinter : public ::testing::Environment {
 public:
  void SetUp() override { std::printf("[ lgvi     ] random seed %u (override with LGVI_TEST_SEED)\n", seed()); }
};
inline ::testing::Environment* const seed_printer = ::testing::AddGlobalTestEnvironment(new SeedPrinter);

inline std::mt19937_64& rng() {
  static std::mt19937_64 g(seed());
  return g;
}

inline double uniform(double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng()); }

inline Vector3<double> random_vector(double scale = 1.0) {
  return Vector3<double>(uniform(-scale, scale), uniform(-scale, scale), uniform(-scale, scale));
}

inline S3d random_unit_quaternion() {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Quaterniond q(n(rng()), n(rng()), n(rng()), n(rng()));
  q.normalize();
  return S3d(q);
}

template <class A, class B>
::testing::AssertionResult near(const char* ea, const char* eb, const char* etol, const A& a, const B& b,
                                double tol) {
  const double err = (a - b).template lpNorm<Eigen::Infinity>();
  if (err <= tol) return ::testing::AssertionSuccess();
  std::ostringstream os;
  os.precision(17);
  os << ea << " and " << eb << " differ by " << err << " > " << etol << " = " << tol << "\n  " << ea << " =\n"
     << a << "\n  " << eb << " =\n"
     << b;
  return ::testing::AssertionFailure() << os.str();
}

/// Advances `stepper` (of one body: SingleBody) n steps of h from s,
/// initializing it there, and returns the state.
template <SystemStepper Stepper>
RigidBodyState run(Stepper& stepper, const RigidBodyState& s0, double h, std::int64_t n) {
  SystemState s(s0);
  integrate_n_steps(stepper, s, 0.0, h, n, [](const SystemStepInfo&) {});
  return s.body(0);
}

/// max(|x - x'|, |q - q'|, |p - p'|, |w - w'|), q compared as 4-vectors (its sign counts).
inline double distance(const RigidBodyState& a, const RigidBodyState& b) {
  return std::max({(a.x - b.x).norm(), (a.q.scalar_first() - b.q.scalar_first()).norm(), (a.p - b.p).norm(),
                   (a.w - b.w).norm()});
}

/// The paper's promises over a long run on the paper's orbit: maxima of the
/// relative angular momentum error and of ||q| - 1|, the energy error's
/// maxima over the first and the last tenth, the mean solver iterations.
struct LongRun {
  double max_relative_momentum_error = 0, max_quat_error = 0, first_tenth_energy = 0, last_tenth_energy = 0;
  double final_t = 0;
  double mean_iterations = 0;
};

/// Runs `integ` (built on the paper's body: SingleBody) n steps of h from
/// the paper-orbit state, calling extra(SystemStepInfo) at every step too.
template <SystemStepper Integ, class Extra>
LongRun paper_orbit_long_run(Integ& integ, double h, std::int64_t n, Extra&& extra) {
  const RigidBody body = paper::three_ball_body();
  SystemState s(paper::orbit_initial_state());
  double e0 = 0;
  Vector3<double> l0 = Vector3<double>::Zero();
  LongRun r;
  integrate_n_steps(integ, s, 0.0, h, n, [&](const SystemStepInfo& i) {
    const RigidBodyState b = i.state.body(0);
    const double e = total_energy(b, body, i.evaluation.body(0));
    const Vector3<double> l = angular_momentum(b);
    if (i.k == 0) e0 = e, l0 = l;
    r.max_relative_momentum_error = std::max(r.max_relative_momentum_error, (l - l0).norm() / l0.norm());
    r.max_quat_error = std::max(r.max_quat_error, std::abs(b.q.norm_error()));
    if (i.k <= n / 10) r.first_tenth_energy = std::max(r.first_tenth_energy, std::abs(e - e0));
    if (i.k >= n - n / 10) r.last_tenth_energy = std::max(r.last_tenth_energy, std::abs(e - e0));
    r.final_t = i.t;
    r.mean_iterations += static_cast<double>(i.solve.iterations) / static_cast<double>(n);
    extra(i);
  });
  return r;
}

}  // namespace lgvi::test

/// |a - b|_inf <= tol for Eigen objects, printing both on failure.
#define EXPECT_MAT_NEAR(a, b, tol) EXPECT_PRED_FORMAT3(::lgvi::test::near, a, b, tol)
#define ASSERT_MAT_NEAR(a, b, tol) ASSERT_PRED_FORMAT3(::lgvi::test::near, a, b, tol)
