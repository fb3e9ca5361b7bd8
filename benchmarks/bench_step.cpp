// ns per step of the quaternion LGVI on the paper-orbit problem, against the
// floor: one force-and-torque evaluation of the same potential (the method
// needs exactly one per step). Run:
//   build/benchmarks/bench_step --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <lgvi/integrate.hpp>
#include <lgvi/paper.hpp>

#include <benchmark/benchmark.h>

namespace {

using lgvi::CentralGravity;
using lgvi::RigidBodyState;

// One evaluation of central gravity over the three balls, at states along the
// orbit so that the branch predictor sees the same data as in a run.
void BM_PotentialEvaluation(benchmark::State& st) {
  const auto body = lgvi::paper::three_ball_body();
  const CentralGravity pot(body, 1.0);
  RigidBodyState s = lgvi::paper::orbit_initial_state();
  for (auto _ : st) {
    auto e = pot.evaluate(s.x, s.q);
    benchmark::DoNotOptimize(e);
    s.x.y() += 1e-9;  // defeat hoisting
  }
}
BENCHMARK(BM_PotentialEvaluation);

// Steps of h = 0.01 at t = k h, as the run loop takes them.
template <lgvi::SystemStepper Integrator>
void run_steps(benchmark::State& st, Integrator& integ) {
  const double h = 0.01;
  lgvi::SystemState s(lgvi::paper::orbit_initial_state());
  integ.initialize(s, 0.0);
  std::int64_t iters = 0, evals = 0, n = 0;
  for (auto _ : st) {
    integ.step(s, static_cast<double>(n) * h, h);
    benchmark::DoNotOptimize(s);
    iters += integ.last_solve().iterations;
    evals += integ.last_solve().residual_evaluations;
    ++n;
  }
  st.counters["solver_iterations"] = static_cast<double>(iters) / static_cast<double>(n);
  st.counters["residual_evaluations"] = static_cast<double>(evals) / static_cast<double>(n);
}

void BM_LgviStep(benchmark::State& st, lgvi::SolverKind kind, int predictor_order) {
  const auto body = lgvi::paper::three_ball_body();
  lgvi::SolverOptions opt;
  opt.kind = kind;
  opt.predictor_order = predictor_order;
  lgvi::SingleBody<lgvi::LieGroupVariationalIntegrator, CentralGravity> integ(body, CentralGravity(body, 1.0), opt);
  run_steps(st, integ);
}
// Default: cubic predictor of the initial guess.
BENCHMARK_CAPTURE(BM_LgviStep, newton, lgvi::SolverKind::Newton, 3);
BENCHMARK_CAPTURE(BM_LgviStep, newton_exp, lgvi::SolverKind::NewtonExp, 3);
BENCHMARK_CAPTURE(BM_LgviStep, broyden, lgvi::SolverKind::Broyden, 3);
// Warm start from the previous step's f only, as the paper's description would do.
BENCHMARK_CAPTURE(BM_LgviStep, newton_warm_start, lgvi::SolverKind::Newton, 0);
BENCHMARK_CAPTURE(BM_LgviStep, broyden_warm_start, lgvi::SolverKind::Broyden, 0);

void BM_LagrangianLgviStep(benchmark::State& st) {
  const auto body = lgvi::paper::three_ball_body();
  lgvi::SingleBody<lgvi::LagrangianLieGroupVariationalIntegrator, CentralGravity> integ(body, CentralGravity(body, 1.0));
  run_steps(st, integ);
}
BENCHMARK(BM_LagrangianLgviStep);

}  // namespace

BENCHMARK_MAIN();
