// Helpers shared by the tests: reproducible randomness (a fixed seed that is
// printed and that LGVI_TEST_SEED overrides, as in Eigen's tests), and
// comparisons that print both values on failure (as in manif's tests).
#pragma once

#include <lgvi/s3.hpp>

#include <gtest/gtest.h>

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

}  // namespace lgvi::test

/// |a - b|_inf <= tol for Eigen objects, printing both on failure.
#define EXPECT_MAT_NEAR(a, b, tol) EXPECT_PRED_FORMAT3(::lgvi::test::near, a, b, tol)
#define ASSERT_MAT_NEAR(a, b, tol) ASSERT_PRED_FORMAT3(::lgvi::test::near, a, b, tol)
