// Many bodies: ns per step (and per body-step) of the N-body quaternion LGVI
// for a Lennard-Jones gas of rigid triangle molecules (cell lists: cost ~ N)
// and for mutual gravity of ball bodies (direct sums: cost ~ N^2), on 1 and 2
// threads; and the memory of the state per body, quaternion against rotation
// matrix (the paper's "4 versus 9"). Run:
//   build/benchmarks/bench_system --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <lgvi/integrate.hpp>
#include <lgvi/lennard_jones.hpp>
#include <lgvi/lgvi.hpp>
#include <lgvi/mutual_gravity.hpp>
#include <lgvi/system.hpp>

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <type_traits>
#include <vector>

namespace {

using lgvi::Parallelism;
using lgvi::RigidBody;
using lgvi::S3d;
using lgvi::System;
using lgvi::SystemState;
using V3 = lgvi::Vector3<double>;

RigidBody triangle() {
  const double s3 = std::sqrt(3.0);
  return RigidBody::from_balls(
      {{V3(0.0, 0.0, 0.0), 1.0, 0.5}, {V3(1.0, 0.0, 0.0), 1.0, 0.5}, {V3(0.5, 0.5 * s3, 0.0), 1.0, 0.5}});
}

/// n molecules on a cubic lattice of spacing 2.2 (no balls of different
/// molecules closer than 1.05 sigma), random orientations, a low temperature,
/// zero total momentum. Seeded: the same state every run.
SystemState lattice(std::size_t n, double spacing) {
  std::mt19937_64 rng(42);
  std::normal_distribution<double> normal(0.0, 1.0);
  SystemState s(n);
  const auto side = static_cast<std::size_t>(std::ceil(std::cbrt(static_cast<double>(n))));
  V3 total = V3::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    s.x[i] = spacing * V3(static_cast<double>(i % side), static_cast<double>((i / side) % side),
                          static_cast<double>(i / (side * side)));
    Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
    q.normalize();
    s.q[i] = S3d(q);
    s.p[i] = 0.3 * V3(normal(rng), normal(rng), normal(rng));
    s.w[i] = 0.3 * V3(normal(rng), normal(rng), normal(rng));
    total += s.p[i];
  }
  for (V3& p : s.p) p -= total / static_cast<double>(n);
  return s;
}

template <class Mutual>
using Coupled = lgvi::Coupled<lgvi::ExternalField<lgvi::NoPotential>, Mutual>;

template <class Mutual, class Make>
void run(benchmark::State& st, std::size_t n, int threads, double h, Make make_mutual) {
  const System sys(std::vector<RigidBody>(n, triangle()));
  const Parallelism par{threads};
  lgvi::LieGroupVariationalIntegrator<Coupled<Mutual>> integ(
      sys, Coupled<Mutual>(lgvi::ExternalField<lgvi::NoPotential>::uniform(lgvi::NoPotential{}, n, par), make_mutual(sys, par)),
      lgvi::SolverOptions{}, par);
  SystemState s = lattice(n, 2.2);
  integ.initialize(s, 0.0);
  std::int64_t k = 0;
  for (auto _ : st) {
    integ.step(s, static_cast<double>(k) * h, h);
    benchmark::DoNotOptimize(s.x.data());
    ++k;
  }
  st.counters["bodies"] = static_cast<double>(n);  // ns per body-step = time / bodies
  if constexpr (std::is_same_v<Mutual, lgvi::LennardJones>)
    st.counters["steps_per_list_build"] =
        static_cast<double>(k) / static_cast<double>(std::max<std::int64_t>(1, integ.potential().mutual().list_builds()));
}

void BM_LennardJonesGas(benchmark::State& st) {
  run<lgvi::LennardJones>(st, static_cast<std::size_t>(st.range(0)), static_cast<int>(st.range(1)), 0.002,
                          [](const System& sys, Parallelism par) { return lgvi::LennardJones(sys, 1.0, 1.0, 2.5, par); });
}
// A fixed number of steps for each N (2e6 / N body-steps, at least 200),
// the same for 1 and 2 threads. Each run integrates from the same lattice,
// and the trajectory is bit-identical for any thread count, so the runs
// compared do exactly the same work. With Google Benchmark's default (as
// many steps as fit in its time budget), the faster run integrated further
// into the gas's warming, where the lists are rebuilt more often: at
// N = 1000, every 38.5 steps on 1 thread against every 25.9 on 2.
// (Iterations() holds for a whole registration, hence one per size.)
#define LGVI_LJ_SIZE(n, threads) \
  BENCHMARK(BM_LennardJonesGas)->ArgNames({"N", "threads"})->Args({n, threads})->Iterations(std::max(200, 2000000 / (n)))->UseRealTime()
LGVI_LJ_SIZE(10, 1);
LGVI_LJ_SIZE(100, 1);
LGVI_LJ_SIZE(1000, 1);
LGVI_LJ_SIZE(10000, 1);
LGVI_LJ_SIZE(1000, 2);
LGVI_LJ_SIZE(10000, 2);

void BM_MutualGravityBalls(benchmark::State& st) {
  run<lgvi::MutualGravityBalls>(st, static_cast<std::size_t>(st.range(0)), static_cast<int>(st.range(1)), 0.01,
                                [](const System& sys, Parallelism par) { return lgvi::MutualGravityBalls(sys, 1e-3, par); });
}
BENCHMARK(BM_MutualGravityBalls)
    ->ArgNames({"N", "threads"})
    ->Args({10, 1})
    ->Args({100, 1})
    ->Args({1000, 1})
    ->Args({1000, 2})
    ->UseRealTime();

/// Bytes of the state per body as stored (structure of arrays), against the
/// same state with a rotation matrix in place of the quaternion.
void BM_StateMemoryPerBody(benchmark::State& st) {
  const std::size_t n = 1000;
  const SystemState s = lattice(n, 2.2);
  double bytes = 0.0;
  for (auto _ : st) {
    bytes = static_cast<double>(s.x.capacity() * sizeof(V3) + s.p.capacity() * sizeof(V3) +
                                s.w.capacity() * sizeof(V3) + s.q.capacity() * sizeof(S3d)) /
            static_cast<double>(n);
    benchmark::DoNotOptimize(bytes);
  }
  st.counters["bytes_per_body_quaternion"] = bytes;
  st.counters["bytes_per_body_rotation_matrix"] =
      bytes - static_cast<double>(sizeof(S3d)) + static_cast<double>(sizeof(lgvi::Matrix3<double>));
  st.counters["attitude_doubles_quaternion"] = 4;
  st.counters["attitude_doubles_matrix"] = 9;
}
BENCHMARK(BM_StateMemoryPerBody)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
