// Every method against the free body's exact flow (exact_free_body.hpp) as
// the oracle: observed order by halving h, and time symmetry where the method
// is symmetric. The same stepper classes `lgvi run` uses, built through the
// same method table (src/method_dispatch.hpp).
#include "method_dispatch.hpp"
#include "scenario.hpp"

#include <lgvi/exact_free_body.hpp>
#include <lgvi/integrate.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <string>

namespace {

using lgvi::RigidBodyState;
using lgvi::app::Method;

lgvi::app::Scenario manchester_peck() {
  return lgvi::app::read_scenario(std::string(LGVI_SCENARIO_DIR) + "/free-body-manchester-peck.toml");
}

RigidBodyState run(lgvi::app::Scenario sc, Method m, double h, std::int64_t n, const RigidBodyState& s0) {
  sc.integrator.method = m;
  sc.integrator.step = h;
  lgvi::SystemState s(s0);
  std::int64_t evaluations = 0;
  const auto potential = lgvi::app::scenario_system_potential(sc, nullptr, &evaluations);
  lgvi::app::with_stepper(sc, potential, lgvi::Parallelism{}, [&](auto& stepper) {
    lgvi::integrate_n_steps(stepper, s, 0.0, h, n, [](const lgvi::SystemStepInfo&) {});
    return 0;
  });
  return s.body(0);
}

double distance(const RigidBodyState& a, const RigidBodyState& b) {
  return std::max((a.q.matrix() - b.q.matrix()).norm(), (a.w - b.w).norm());
}

struct OrderCase {
  Method method;
  double order;
};

class MethodOrders : public ::testing::TestWithParam<OrderCase> {};

TEST_P(MethodOrders, AgainstTheExactFlow) {
  // T = 8 on the Manchester & Peck body, h = 0.2 ... 0.025. The exact flow is
  // ~1e-12 from the truth (test_exact.cpp), far below every error here.
  const auto sc = manchester_peck();
  const double T = 8.0;
  const lgvi::ExactFreeRigidBody exact(sc.body(), sc.initial());
  const RigidBodyState ref = exact.at(T);
  double previous = 0;
  for (int j = 0; j < 4; ++j) {
    const double h = 0.2 / std::pow(2.0, j);
    const double e = distance(run(sc, GetParam().method, h, std::lround(T / h), sc.initial()), ref);
    if (j > 0) {
      // Asymptotic regime: the ratio of errors on halving h is 2^p up to O(h) corrections.
      EXPECT_NEAR(std::log2(previous / e), GetParam().order, 0.15)
          << lgvi::app::to_string(GetParam().method) << " h = " << h << ": " << previous << " -> " << e;
    }
    previous = e;
  }
}

INSTANTIATE_TEST_SUITE_P(
    AllMethods, MethodOrders,
    ::testing::Values(OrderCase{Method::Hamiltonian, 2}, OrderCase{Method::Lagrangian, 2},
                      OrderCase{Method::So3Lgvi, 2}, OrderCase{Method::RattleQuaternion, 2},
                      OrderCase{Method::Rk4Normalized, 4}, OrderCase{Method::EulerExp, 1},
                      OrderCase{Method::NoSquish, 2}, OrderCase{Method::SplittingDlm, 2}),
    [](const auto& info) {
      std::string n = lgvi::app::to_string(info.param.method);
      for (char& c : n)
        if (c == '-') c = '_';
      return n;
    });

TEST(MethodOrders, ExactMethodHasNoErrorAtAnyStep) {
  // method = "exact" evaluates the flow at t = k h: no truncation error.
  const auto sc = manchester_peck();
  const lgvi::ExactFreeRigidBody exact(sc.body(), sc.initial());
  for (double h : {0.5, 0.05})
    EXPECT_LE(distance(run(sc, Method::Exact, h, std::lround(8.0 / h), sc.initial()), exact.at(8.0)), 1e-13);
}

class MethodSymmetry : public ::testing::TestWithParam<Method> {};

TEST_P(MethodSymmetry, FlippingMomentaRetracesTheTrajectory) {
  // Symmetric methods: forward n steps, flip w, forward n steps, flip back ->
  // the start, up to rounding amplified by the flow (n = 200: ~1e-13).
  const auto sc = manchester_peck();
  RigidBodyState s = run(sc, GetParam(), 0.1, 200, sc.initial());
  s.w = -s.w;
  s = run(sc, GetParam(), 0.1, 200, s);
  s.w = -s.w;
  // The position-position form reports w_k = (4/h) g(q_{k-1}^* q_k) + h M_k,
  // recomputed from two stored quaternions: each step's rounding of the
  // product (~eps) is amplified by (4/h)|J| ~ 120, so over 400 steps its
  // round-off bound is 400 * 120 * eps ~ 1e-11 rather than 1e-12.
  const double bound = GetParam() == Method::Lagrangian ? 400 * (4 / 0.1) * 3 * 2.2e-16 : 1e-12;
  EXPECT_LE(distance(s, sc.initial()), bound) << lgvi::app::to_string(GetParam());
}

INSTANTIATE_TEST_SUITE_P(SymmetricMethods, MethodSymmetry,
                         ::testing::Values(Method::Hamiltonian, Method::Lagrangian, Method::So3Lgvi,
                                           Method::RattleQuaternion, Method::NoSquish, Method::SplittingDlm),
                         [](const auto& info) {
                           std::string n = lgvi::app::to_string(info.param);
                           for (char& c : n)
                             if (c == '-') c = '_';
                           return n;
                         });

}  // namespace
