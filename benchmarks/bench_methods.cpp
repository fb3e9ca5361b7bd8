// ns per step of every method on each standard problem (the scenario files in
// scenarios/), and of one potential evaluation of each problem's potential
// (the floor for the methods that need one per step). Every run goes through
// the same stepper classes `lgvi run` uses, built by the same method table.
// Run: build/benchmarks/bench_methods --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
// (scripts/bench.sh prints the tables with ratios against the quaternion LGVI).
#include "app/method_registry.hpp"
#include "app/scenario.hpp"
#include "app/simulation.hpp"

#include <benchmark/benchmark.h>

#include <string>
#include <variant>

namespace {

using lgvi::app::Method;

const char* const problems[] = {"paper-orbit", "free-body-manchester-peck", "free-body-hairer", "dzhanibekov",
                                "heavy-top"};

lgvi::app::Scenario load(const std::string& problem) {
  return lgvi::app::read_scenario(std::string(LGVI_SCENARIO_DIR) + "/" + problem + ".toml");
}

void BM_Potential(benchmark::State& st, std::string problem) {
  const lgvi::app::Scenario sc = load(problem);
  const auto potential = lgvi::app::scenario_potential(sc);
  lgvi::RigidBodyState s = sc.initial();
  std::visit(
      [&](const auto& p) {
        for (auto _ : st) {
          auto e = p.evaluate(s.x, s.q);
          benchmark::DoNotOptimize(e);
          s.x.y() += 1e-12;  // defeat hoisting
        }
      },
      potential);
}

void BM_Method(benchmark::State& st, std::string problem, Method method) {
  lgvi::app::Scenario sc = load(problem);
  sc.integrator.method = method;
  std::int64_t evaluations = 0;
  const auto potential = lgvi::app::scenario_system_potential(sc, nullptr, &evaluations);
  const double h = sc.integrator.step;
  lgvi::app::with_stepper(sc, potential, lgvi::Parallelism{}, [&](auto& stepper) {
    lgvi::SystemState s = sc.initial_state;
    stepper.initialize(s, 0.0);
    std::int64_t n = 0;
    for (auto _ : st) {
      // Restart from the initial state every 1024 steps (amortized cost
      // 1/1024 of a step): unstable methods (euler-exp) would otherwise blow
      // up over the millions of steps a benchmark takes.
      if (++n % 1024 == 0) {
        s = sc.initial_state;
        stepper.initialize(s, 0.0);
      }
      stepper.step(s, static_cast<double>(n % 1024) * h, h);
      benchmark::DoNotOptimize(s.x.data());
    }
    return 0;
  });
}

const int registered = [] {
  for (const char* problem : problems) {
    benchmark::RegisterBenchmark((std::string("potential/") + problem).c_str(), BM_Potential, std::string(problem));
    const bool free_body = load(problem).potential.kind == lgvi::app::PotentialKind::None;
    for (const lgvi::MethodTraits& t : Method::all()) {
      if (t.free_body_only && !free_body) continue;
      if (t.needs_principal_axes && !load(problem).body().inertia().isDiagonal()) continue;
      benchmark::RegisterBenchmark((std::string(t.name) + "/" + problem).c_str(), BM_Method, std::string(problem),
                                   Method::named(t.name));
    }
  }
  return 0;
}();

}  // namespace

BENCHMARK_MAIN();
