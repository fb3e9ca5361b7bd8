// Composition methods (composition.hpp): the tables' order conditions, the
// observed orders 4, 6 and 8 of every symmetric one-step method composed,
// against the free body's exact flow and against tight solutions of the
// continuous equations (paper orbit, heavy top), and for N bodies against a
// tight reference; what composition keeps exactly (|q| = 1, momentum,
// time symmetry, bounded energy); the predictor's iterations per sub-step;
// the scenario keys and their errors.
#include "app/method_registry.hpp"
#include "app/scenario.hpp"
#include "app/simulation.hpp"
#include "io/memory_sink.hpp"

#include <lgvi/composition.hpp>
#include <lgvi/continuous.hpp>
#include <lgvi/exact_free_body.hpp>
#include <lgvi/integrate.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <numeric>
#include <string>
#include <vector>

namespace test_composition {

namespace {

using lgvi::CompositionTable;
using lgvi::RigidBodyState;
using lgvi::SystemState;
using lgvi::app::Method;
using lgvi::app::Scenario;

constexpr double eps = std::numeric_limits<double>::epsilon();

Scenario scenario(const std::string& name) {
  return lgvi::app::read_scenario(std::string(LGVI_SCENARIO_DIR) + "/" + name + ".toml");
}

/// Runs n steps of h with `method` composed to `order` from `s0` (all bodies).
SystemState run(Scenario sc, Method m, const CompositionTable& table, double h, std::int64_t n, const SystemState& s0,
                double* iterations_per_solve = nullptr) {
  sc.integrator.method = m;
  sc.integrator.step = h;
  sc.integrator.composition = table;
  SystemState s = s0;
  std::int64_t evaluations = 0, iterations = 0;
  const auto potential = lgvi::app::scenario_system_potential(sc, nullptr, &evaluations);
  lgvi::app::with_stepper(sc, potential, lgvi::Parallelism{}, [&](auto& stepper) {
    lgvi::integrate_n_steps(stepper, s, 0.0, h, n, [&](const lgvi::SystemStepInfo& i) { iterations += i.solve.iterations; });
    return 0;
  });
  if (iterations_per_solve)
    *iterations_per_solve = static_cast<double>(iterations) /
                            static_cast<double>(n * static_cast<std::int64_t>(sc.bodies() * sc.integrator.composition.stages()));
  return s;
}
SystemState run(const Scenario& sc, Method m, int order, double h, std::int64_t n, const SystemState& s0,
                double* iterations_per_solve = nullptr) {
  return run(sc, m, CompositionTable::of_order(order), h, n, s0, iterations_per_solve);
}

/// max over bodies of max(|x - x'|, |R - R'|_F, |p - p'|, |w - w'|).
double distance(const SystemState& a, const SystemState& b) {
  double d = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    d = std::max({d, (a.x[i] - b.x[i]).norm(), (a.q[i].matrix() - b.q[i].matrix()).norm(), (a.p[i] - b.p[i]).norm(),
                  (a.w[i] - b.w[i]).norm()});
  }
  return d;
}

std::string name_of(Method m) {
  std::string n = lgvi::app::to_string(m);
  for (char& c : n)
    if (c == '-') c = '_';
  return n;
}

// ---------------------------------------------------------------------------
// The tables

TEST(CompositionTable, DefaultTablesAreSymmetricConsistentAndSatisfyTheOrderConditions) {
  for (int order : {2, 4, 6, 8}) {
    const CompositionTable t = CompositionTable::of_order(order);
    EXPECT_EQ(t.order(), order);
    const std::vector<double>& g = t.gamma();
    // Consistency: the 26-digit coefficients round to doubles, each within
    // eps/2 relative; the sum of s of them is 1 within s eps.
    EXPECT_NEAR(std::accumulate(g.begin(), g.end(), 0.0), 1.0, static_cast<double>(g.size()) * eps);
    for (std::size_t i = 0; i < g.size(); ++i) EXPECT_EQ(g[i], g[g.size() - 1 - i]);
    // Order conditions of symmetric compositions (GNI V.3.2): order 4 needs
    // sum gamma^3 = 0; order 6 also sum gamma^5 = 0 (plus one condition on
    // a commutator term, checked by the observed orders below). Round-off:
    // |gamma| < 1, so each sum is within s eps of its exact value.
    double s3 = 0, s5 = 0;
    for (const double x : g) {
      s3 += x * x * x;
      s5 += x * x * x * x * x;
    }
    if (order >= 4) {
      EXPECT_NEAR(s3, 0.0, 4 * static_cast<double>(g.size()) * eps) << order;
    }
    if (order >= 6) {
      EXPECT_NEAR(s5, 0.0, 4 * static_cast<double>(g.size()) * eps) << order;
    }
  }
  EXPECT_EQ(CompositionTable::of_order(4).stages(), 5u);
  EXPECT_EQ(CompositionTable::of_order(6).stages(), 9u);
  EXPECT_EQ(CompositionTable::of_order(8).stages(), 15u);
  // Suzuki: gamma_1 = 1/(4 - 4^{1/3}) = 0.41449077179437573...
  EXPECT_NEAR(CompositionTable::of_order(4).gamma()[0], 0.41449077179437573, 2 * eps);
}

TEST(CompositionTable, CustomTablesAreChecked) {
  EXPECT_NO_THROW(CompositionTable::custom({0.5, 0.5}));
  EXPECT_NO_THROW(CompositionTable::custom({1.0}));
  // Not summing to 1, not palindromic, empty, zero or non-finite entries.
  EXPECT_THROW(CompositionTable::custom({0.5, 0.6}), lgvi::InvalidInput);
  EXPECT_THROW(CompositionTable::custom({0.2, 0.3, 0.5}), lgvi::InvalidInput);
  EXPECT_THROW(CompositionTable::custom({}), lgvi::InvalidInput);
  EXPECT_THROW(CompositionTable::custom({0.5, 0.0, 0.5}), lgvi::InvalidInput);
  EXPECT_THROW(CompositionTable::custom({0.5, std::nan(""), 0.5}), lgvi::InvalidInput);
  EXPECT_THROW(CompositionTable::of_order(3), lgvi::InvalidInput);
  // Suzuki's table typed with 17 digits passes (within 8 eps per stage) and
  // is made exactly palindromic.
  const CompositionTable t = CompositionTable::custom(
      {0.41449077179437573, 0.41449077179437573, -0.65796308717750292, 0.41449077179437573, 0.41449077179437573});
  EXPECT_EQ(t.stages(), 5u);
}

// ---------------------------------------------------------------------------
// Observed orders

struct OrderCase {
  Method method;
  int order;
  double h0;   ///< the largest step of the ladder h0, h0/2, ...
  int levels;  ///< steps in the ladder (levels - 1 observed orders)
};

/// The methods the registry declares composable (symmetric one-step methods
/// of order 2): every one of them is composed and measured below.
std::vector<Method> composable_methods() {
  std::vector<Method> v;
  for (const lgvi::MethodTraits& t : Method::all())
    if (t.composable()) v.push_back(Method::named(t.name));
  return v;
}

TEST(ComposableMethods, AreTheSymmetricOneStepMethodsOfOrderTwo) {
  // The literature's list (composition.hpp's header), against the registry's declarations.
  std::vector<std::string> names;
  for (Method m : composable_methods()) names.emplace_back(m.name());
  EXPECT_EQ(names, (std::vector<std::string>{"lgvi", "so3-lgvi", "rattle-quaternion", "no-squish", "splitting-dlm"}));
}

std::string case_name(const ::testing::TestParamInfo<OrderCase>& info) {
  return name_of(info.param.method) + "_order" + std::to_string(info.param.order);
}

/// Every composable method at orders 4, 6, 8, with the ladders given per
/// order; `special` replaces the default ladder of some (method, order).
std::vector<OrderCase> cases(std::vector<OrderCase> per_order, const std::vector<OrderCase>& special = {}) {
  std::vector<OrderCase> v;
  for (Method m : composable_methods()) {
    for (OrderCase c : per_order) {
      c.method = m;
      for (const OrderCase& x : special)
        if (x.method == m && x.order == c.order) c = x;
      v.push_back(c);
    }
  }
  return v;
}

/// The observed orders log2(e(h) / e(h/2)) along the ladder, each within 0.2
/// of the order (the issue's criterion).
///
/// A ladder must lie in the window where the ratio has reached its
/// asymptotic value 2^p (large h: higher-order terms) and the smaller error
/// is still far above the method's round-off floor (1e-13 to 1e-11 here, the
/// rattle's highest: it solves for a 4-vector and a multiplier). That window
/// is narrow at orders 6 and 8 (the error falls by 64 to 256 per halving),
/// and it sits at different h for different methods on the same problem:
/// no-squish and splitting-dlm integrate the heavy top's fast spin exactly
/// and are 100-1000 times more accurate there. The ladders below were read
/// off the full ladders of 7 steps, which LGVI_PRINT_LADDER=1 prints
/// (errors, ratios and Newton iterations per sub-step) instead of testing.
void expect_orders(const Scenario& sc, const OrderCase& c, double T, const SystemState& ref) {
  double previous = 0.0;
  const bool print = std::getenv("LGVI_PRINT_LADDER") != nullptr;
  const int levels = print ? 7 : c.levels;
  for (int j = 0; j < levels; ++j) {
    const double h = c.h0 / std::pow(2.0, j);
    double iterations = 0;
    const double e = distance(run(sc, c.method, c.order, h, std::lround(T / h), sc.initial_state, &iterations), ref);
    if (print) {
      std::printf("LADDER %s order %d h=%g error=%.3e p=%.3f iterations/sub-step=%.3f\n",
                  lgvi::app::to_string(c.method), c.order, h, e, j ? std::log2(previous / e) : 0.0, iterations);
    } else if (j > 0) {
      EXPECT_NEAR(std::log2(previous / e), c.order, 0.2)
          << lgvi::app::to_string(c.method) << " order " << c.order << " h = " << h << ": " << previous << " -> " << e;
    }
    previous = e;
  }
}

class FreeBodyOrders : public ::testing::TestWithParam<OrderCase> {};

TEST_P(FreeBodyOrders, AgainstTheExactFlow) {
  // The Manchester & Peck free body to T = 8; the exact flow is ~1e-12 from
  // the truth (test_exact.cpp). The ladders keep the smallest error above
  // 1e-10, where round-off (~1e-13 over these step counts) cannot bend the ratio.
  const Scenario sc = scenario("free-body-manchester-peck");
  const double T = 8.0;
  expect_orders(sc, GetParam(), T, SystemState(lgvi::ExactFreeRigidBody(sc.body(), sc.initial()).at(T)));
}

// Free body, T = 8 (|Omega| ~ 0.7): errors 1e-6 .. 1e-12.
INSTANTIATE_TEST_SUITE_P(Composed, FreeBodyOrders,
                         ::testing::ValuesIn(cases({{Method::named("lgvi"), 4, 0.1, 3}, {Method::named("lgvi"), 6, 0.2, 3},
                                                    {Method::named("lgvi"), 8, 0.4, 2}})),
                         case_name);

/// A tight RK4 solve of the continuous equations (continuous.hpp) of a
/// single-body scenario to T with step h_ref.
SystemState tight_reference(const Scenario& sc, double T, double h_ref) {
  const auto n = std::lround(T / h_ref);
  return std::visit(
      [&](const auto& potential) {
        const lgvi::ContinuousEquations eqs(sc.body(), potential);
        return SystemState(
            lgvi::from_continuous(eqs.rk4(lgvi::to_continuous(sc.initial(), sc.body()), T / static_cast<double>(n), n),
                                  sc.body()));
      },
      lgvi::app::scenario_potential(sc));
}

class PaperOrbitOrders : public ::testing::TestWithParam<OrderCase> {};

TEST_P(PaperOrbitOrders, AgainstATightSolveOfTheContinuousEquations) {
  // The paper's orbit to T = 4. RK4 at h = 2.5e-4: its error, ~(2.5e-4)^4
  // times the flow's fourth derivatives, is below 1e-12 (it changes by less
  // than that when halved), under the smallest error measured here.
  const Scenario sc = scenario("paper-orbit");
  const double T = 4.0;
  static const SystemState ref = tight_reference(sc, T, 2.5e-4);
  expect_orders(sc, GetParam(), T, ref);
}

// Paper orbit, T = 4: errors 1e-5 .. 1e-12.
INSTANTIATE_TEST_SUITE_P(Composed, PaperOrbitOrders,
                         ::testing::ValuesIn(cases({{Method::named("lgvi"), 4, 0.05, 3}, {Method::named("lgvi"), 6, 0.05, 3},
                                                    {Method::named("lgvi"), 8, 0.1, 2}})),
                         case_name);

class HeavyTopOrders : public ::testing::TestWithParam<OrderCase> {};

TEST_P(HeavyTopOrders, AgainstATightSolveOfTheContinuousEquations) {
  // The fast heavy top (spin 50 rad/s) to T = 0.5, RK4 reference at 1e-6.
  const Scenario sc = scenario("heavy-top");
  const double T = 0.5;
  static const SystemState ref = tight_reference(sc, T, 1e-6);
  expect_orders(sc, GetParam(), T, ref);
}

// Heavy top, T = 0.5, spin 50 rad/s: the variational methods need h <=
// 0.005 to be asymptotic; no-squish and splitting-dlm reach their floor at
// larger h (see expect_orders).
INSTANTIATE_TEST_SUITE_P(
    Composed, HeavyTopOrders,
    ::testing::ValuesIn(cases({{Method::named("lgvi"), 4, 0.00125, 3}, {Method::named("lgvi"), 6, 0.0025, 3},
                               {Method::named("lgvi"), 8, 0.005, 3}},
                              {{Method::named("rattle-quaternion"), 6, 0.0025, 2}, {Method::named("rattle-quaternion"), 8, 0.005, 2},
                               {Method::named("no-squish"), 4, 0.005, 3}, {Method::named("no-squish"), 6, 0.01, 2},
                               {Method::named("no-squish"), 8, 0.02, 2}, {Method::named("splitting-dlm"), 4, 0.005, 3},
                               {Method::named("splitting-dlm"), 6, 0.01, 3}, {Method::named("splitting-dlm"), 8, 0.01, 2}})),
    case_name);

// ---------------------------------------------------------------------------
// N bodies

TEST(ComposedNBody, BinaryAsteroidOrdersAgainstATightRk4Reference) {
  // The binary asteroid (two bodies, 9 balls, mutual gravity) to T = 20 (half
  // a mutual orbit). Reference: rk4-normalized, a different, non-geometric
  // method, at h = 0.005 (4000 steps): the composed errors level off at
  // 6e-13, its error; the ladders end above 1e-11.
  Scenario sc = scenario("binary-asteroid");
  const double T = 20.0;
  SystemState ref = sc.initial_state;
  {
    Scenario r = sc;
    r.integrator.method = Method::named("rk4-normalized");
    std::int64_t evaluations = 0;
    const auto potential = lgvi::app::scenario_system_potential(r, nullptr, &evaluations);
    lgvi::app::with_stepper(r, potential, lgvi::Parallelism{}, [&](auto& stepper) {
      lgvi::integrate_n_steps(stepper, ref, 0.0, 0.005, 4000, [](const lgvi::SystemStepInfo&) {});
      return 0;
    });
  }
  for (const OrderCase& c : {OrderCase{Method::named("lgvi"), 4, 0.2, 3}, OrderCase{Method::named("lgvi"), 6, 0.2, 3},
                             OrderCase{Method::named("lgvi"), 8, 0.5, 2}})
    expect_orders(sc, c, T, ref);
}

// ---------------------------------------------------------------------------
// What composition keeps

TEST(ComposedConservation, PaperOrbitUnitQuaternionMomentumAndBoundedEnergy) {
  // The paper's orbit composed to order 4 and 8 at h = 0.05 for 2e4 steps
  // (t = 1000, the paper's span), with 5 and 15 sub-steps each: |q| - 1 and
  // the angular momentum stay at round-off, growing like a random walk over
  // the 1e5..3e5 sub-steps (eps sqrt(n) ~ 1e-13, allowed 1e-12, relative to
  // |L| ~ 10 for the momentum). The energy error: at order 4 the truncation
  // error (1.4e-8) oscillates without drift, its maximum over the second half
  // within twice that over the first; at order 8 the truncation error is
  // below round-off, and the error is the round-off's random walk, measured
  // 0.9e-13 and 1.9e-13 over the two halves: allowed 4 eps |E0| sqrt(n s)
  // (1e-12 for the 3e5 sub-steps), the size of a walk of eps |E0| per sub-step.
  for (int order : {4, 8}) {
    Scenario sc = scenario("paper-orbit");
    sc.integrator.composition = CompositionTable::of_order(order);
    const double h = 0.05;
    const std::int64_t n = 20000;
    SystemState s = sc.initial_state;
    double e0 = 0, max_q = 0, max_l = 0, max_e_first = 0, max_e_second = 0;
    lgvi::Vector3<double> l0;
    std::int64_t evaluations = 0;
    const auto potential = lgvi::app::scenario_system_potential(sc, nullptr, &evaluations);
    lgvi::app::with_stepper(sc, potential, lgvi::Parallelism{}, [&](auto& stepper) {
      lgvi::integrate_n_steps(stepper, s, 0.0, h, n, [&](const lgvi::SystemStepInfo& i) {
        const double e = lgvi::total_energy(i.state, sc.system, i.evaluation);
        const lgvi::Vector3<double> l = lgvi::angular_momentum(i.state);
        if (i.k == 0) {
          e0 = e;
          l0 = l;
        }
        max_q = std::max(max_q, std::abs(i.state.q[0].norm_error()));
        max_l = std::max(max_l, (l - l0).norm());
        double& m = i.k <= n / 2 ? max_e_first : max_e_second;
        m = std::max(m, std::abs(e - e0));
      });
      return 0;
    });
    EXPECT_LE(max_q, 1e-12) << order;
    EXPECT_LE(max_l, 1e-11) << order;
    EXPECT_GT(max_e_first, 0.0);
    if (order == 4) {
      EXPECT_LE(max_e_second, 2 * max_e_first) << order;
    } else {
      const double substeps = static_cast<double>(n * static_cast<std::int64_t>(sc.integrator.composition.stages()));
      EXPECT_LE(std::max(max_e_first, max_e_second),
                4 * std::numeric_limits<double>::epsilon() * std::abs(e0) * std::sqrt(substeps))
          << order;
    }
  }
}

class ComposedSymmetry : public ::testing::TestWithParam<Method> {};

TEST_P(ComposedSymmetry, FlippingMomentaRetracesTheTrajectory) {
  // A palindromic composition of symmetric steps is symmetric: forward 100
  // steps of order 6 (900 sub-steps), flip w, forward 100, flip back -> the
  // start, up to rounding amplified by the flow (1800 sub-steps: ~1e-12).
  const Scenario sc = scenario("free-body-manchester-peck");
  SystemState s = run(sc, GetParam(), 6, 0.1, 100, sc.initial_state);
  s.w[0] = -s.w[0];
  s = run(sc, GetParam(), 6, 0.1, 100, s);
  s.w[0] = -s.w[0];
  EXPECT_LE(distance(s, sc.initial_state), 1e-11) << lgvi::app::to_string(GetParam());
}

INSTANTIATE_TEST_SUITE_P(Composed, ComposedSymmetry,
                         ::testing::ValuesIn(composable_methods()),
                         [](const auto& info) { return name_of(info.param); });

TEST(ComposedSolver, NewtonIterationsPerSubStepStayNearOne) {
  // Each stage keeps its own predictor: at the paper's step h = 0.01 the
  // solves of every stage start within the predictor's O(h^4) of the root.
  // Measured 1.00004 per sub-step at orders 4, 6, 8 on 1000 steps (the first
  // steps, before the cubic predictor has its history, take 2); the aim of
  // the issue is at most 1.5.
  const Scenario sc = scenario("paper-orbit");
  for (int order : {4, 6, 8}) {
    double iterations = 0;
    run(sc, Method::named("lgvi"), order, 0.01, 1000, sc.initial_state, &iterations);
    EXPECT_LE(iterations, 1.01) << order;
  }
}

TEST(ComposedSolver, ResumeFromInternalStateIsBitIdentical) {
  // 2n composed steps in one go equal n steps, a checkpoint of the state and
  // the per-stage predictors, a fresh stepper resumed from it, n more steps.
  Scenario sc = scenario("paper-orbit");
  sc.integrator.composition = CompositionTable::of_order(6);
  const double h = 0.02;
  std::int64_t evaluations = 0;
  const auto potential = lgvi::app::scenario_system_potential(sc, nullptr, &evaluations);
  SystemState whole = sc.initial_state, half = sc.initial_state;
  std::vector<double> internal;
  lgvi::app::with_stepper(sc, potential, lgvi::Parallelism{}, [&](auto& stepper) {
    lgvi::integrate_n_steps(stepper, whole, 0.0, h, 40, [](const lgvi::SystemStepInfo&) {});
    return 0;
  });
  lgvi::app::with_stepper(sc, potential, lgvi::Parallelism{}, [&](auto& stepper) {
    lgvi::integrate_n_steps(stepper, half, 0.0, h, 20, [](const lgvi::SystemStepInfo&) {});
    internal = stepper.internal_state();
    return 0;
  });
  // 9 stages of 13 numbers each (count and 4 vectors of history), then the
  // body's position carry (3).
  EXPECT_EQ(internal.size(), 9u * 13u + 3u);
  lgvi::app::with_stepper(sc, potential, lgvi::Parallelism{}, [&](auto& stepper) {
    stepper.resume(half, 20 * h, internal);
    lgvi::integrate_range(stepper, half, 0.0, h, 20, 40, [](const lgvi::SystemStepInfo&) {});
    return 0;
  });
  for (int i = 0; i < 4; ++i) EXPECT_EQ(half.q[0].scalar_first()(i), whole.q[0].scalar_first()(i));
  EXPECT_EQ(half.x[0], whole.x[0]);
  EXPECT_EQ(half.w[0], whole.w[0]);
  EXPECT_EQ(half.p[0], whole.p[0]);
}

TEST(ComposedScenario, OrderAndCompositionKeysReachTheStepper) {
  Scenario sc = lgvi::app::parse_scenario(R"([body]
mass = 1.0
inertia = [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]
[potential]
kind = "none"
[initial]
position = [0.0, 0.0, 0.0]
quaternion = [1.0, 0.0, 0.0, 0.0]
momentum = [0.0, 0.0, 0.0]
omega = [0.1, 0.2, 0.3]
[integrator]
method = "no-squish"
order = 6
step = 0.1
duration = 1.0
)",
                                          "order.toml");
  EXPECT_EQ(sc.integrator.composition.order(), 6);
  EXPECT_EQ(sc.integrator.composition.stages(), 9u);
  // A user's table: Suzuki's, typed in with 17 digits, gives the steps of
  // order = 4 to round-off (the typed and the computed gamma differ by at
  // most an ulp).
  const CompositionTable suzuki = CompositionTable::custom(
      {0.41449077179437573, 0.41449077179437573, -0.65796308717750292, 0.41449077179437573, 0.41449077179437573});
  EXPECT_LE(distance(run(sc, Method::named("no-squish"), suzuki, 0.1, 10, sc.initial_state),
                     run(sc, Method::named("no-squish"), 4, 0.1, 10, sc.initial_state)),
            1e-14);
}

}  // namespace

}  // namespace test_composition
