// Every method against the free body's exact flow (exact_free_body.hpp) as
// the oracle: observed order by halving h, and time symmetry where the method
// is symmetric. The same stepper classes `lgvi run` uses, built through the
// same method table (src/app/method_registry.hpp).
#include "app/method_registry.hpp"
#include "app/scenario.hpp"

#include <lgvi/exact_free_body.hpp>
#include <lgvi/integrate.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

namespace test_methods_orders {

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

/// The orders of the literature (not the registry's declarations, which
/// OrdersAreTheDeclaredOnes checks against these).
std::vector<OrderCase> literature_orders() {
  return {OrderCase{Method::named("lgvi"), 2},           OrderCase{Method::named("lgvi-lagrangian"), 2},
          OrderCase{Method::named("so3-lgvi"), 2},       OrderCase{Method::named("rattle-quaternion"), 2},
          OrderCase{Method::named("rk4-normalized"), 4}, OrderCase{Method::named("euler-exp"), 1},
          OrderCase{Method::named("no-squish"), 2},      OrderCase{Method::named("splitting-dlm"), 2}};
}

std::string test_name(Method m) {
  std::string n = lgvi::app::to_string(m);
  for (char& c : n)
    if (c == '-') c = '_';
  return n;
}

INSTANTIATE_TEST_SUITE_P(AllMethods, MethodOrders, ::testing::ValuesIn(literature_orders()),
                         [](const auto& info) { return test_name(info.param.method); });

TEST(MethodRegistry, EveryMethodIsMeasuredAndDeclaresTheOrderMeasured) {
  // A method added to the registry must be added to the table above (its
  // order measured against the exact flow); what it declares (traits.order,
  // read by lgvi compare and the docs) must be the order measured.
  for (const lgvi::MethodTraits& t : Method::all()) {
    if (t.free_body_only) {
      EXPECT_EQ(t.order, 0) << t.name << ": an exact flow declares order 0";
      continue;
    }
    bool measured = false;
    for (const OrderCase& c : literature_orders()) {
      if (c.method != Method::named(t.name)) continue;
      measured = true;
      EXPECT_EQ(t.order, c.order) << t.name;
    }
    EXPECT_TRUE(measured) << t.name << " is registered but its order is not measured here";
  }
}

TEST(MethodRegistry, NamesAreReadBackAndUnknownNamesListEveryMethod) {
  for (const lgvi::MethodTraits& t : Method::all()) EXPECT_STREQ(Method::named(t.name).name(), t.name);
  EXPECT_STREQ(Method().name(), "lgvi") << "the default of [integrator] method";
  try {
    (void)Method::named("rk4", "integrator.method");
    FAIL() << "an unknown name is refused";
  } catch (const lgvi::InvalidInput& e) {
    std::string expected = "key 'integrator.method': \"rk4\" is not one of ";
    for (std::size_t k = 0; k < Method::all().size(); ++k)
      expected += (k ? ", \"" : "\"") + std::string(Method::all()[k].name) + "\"";
    EXPECT_EQ(e.what(), expected);
  }
}

TEST(MethodOrders, ExactMethodHasNoErrorAtAnyStep) {
  // method = "exact" evaluates the flow at t = k h: no truncation error.
  const auto sc = manchester_peck();
  const lgvi::ExactFreeRigidBody exact(sc.body(), sc.initial());
  for (double h : {0.5, 0.05})
    EXPECT_LE(distance(run(sc, Method::named("exact"), h, std::lround(8.0 / h), sc.initial()), exact.at(8.0)), 1e-13);
}

class MethodSymmetry : public ::testing::TestWithParam<Method> {};

TEST_P(MethodSymmetry, FlippingMomentaRetracesTheTrajectoryIfAndOnlyIfDeclaredSymmetric) {
  // Forward n steps, flip w, forward n steps, flip back. A symmetric method
  // returns to the start up to rounding amplified by the flow (n = 200:
  // ~1e-13); a method that is not (traits.symmetric false) leaves a
  // truncation-sized gap, which must then be far above that bound (1e3 x),
  // so that the declaration, read by composition, is the behaviour.
  const auto sc = manchester_peck();
  RigidBodyState s = run(sc, GetParam(), 0.1, 200, sc.initial());
  s.w = -s.w;
  s = run(sc, GetParam(), 0.1, 200, s);
  s.w = -s.w;
  // The position-position form reports w_k = (4/h) g(q_{k-1}^* q_k) + h M_k,
  // recomputed from two stored quaternions: each step's rounding of the
  // product (~eps) is amplified by (4/h)|J| ~ 120, so over 400 steps its
  // round-off bound is 400 * 120 * eps ~ 1e-11 rather than 1e-12.
  const double bound = GetParam() == Method::named("lgvi-lagrangian") ? 400 * (4 / 0.1) * 3 * 2.2e-16 : 1e-12;
  if (GetParam().traits().symmetric)
    EXPECT_LE(distance(s, sc.initial()), bound) << lgvi::app::to_string(GetParam());
  else
    EXPECT_GE(distance(s, sc.initial()), 1e3 * bound) << lgvi::app::to_string(GetParam());
}

/// Every registered method but the exact flow (symmetric by construction).
std::vector<Method> stepping_methods() {
  std::vector<Method> v;
  for (const lgvi::MethodTraits& t : Method::all())
    if (!t.free_body_only) v.push_back(Method::named(t.name));
  return v;
}

INSTANTIATE_TEST_SUITE_P(RegisteredMethods, MethodSymmetry, ::testing::ValuesIn(stepping_methods()),
                         [](const auto& info) { return test_name(info.param); });

}  // namespace

}  // namespace test_methods_orders
