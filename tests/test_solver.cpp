// The implicit rotation equation g(f) = b (rotation_solver.hpp): analytic
// Jacobians against finite differences, the three solvers against each other
// and against the paper's equation written literally with G and F.
#include <lgvi/paper.hpp>
#include <lgvi/rotation_solver.hpp>

#include "test_support.hpp"

#include <gmock/gmock.h>

#include <cmath>
#include <map>

namespace test_solver {

namespace {

using lgvi::RotationEquation;
using lgvi::RotationSolver;
using lgvi::S3d;
using lgvi::SolverKind;
using V3 = lgvi::Vector3<double>;
using M3 = lgvi::Matrix3<double>;
constexpr double eps = 2.220446049250313e-16;

M3 random_inertia() {
  // A random valid inertia: random principal moments obeying the triangle
  // inequality, in random axes.
  const double a = lgvi::test::uniform(0.5, 2.0), b = lgvi::test::uniform(0.5, 2.0);
  const double c = lgvi::test::uniform(std::abs(a - b) + 0.1, a + b - 0.1);
  const M3 r = lgvi::test::random_unit_quaternion().matrix();
  return r * V3(a, b, c).asDiagonal() * r.transpose();
}

TEST(RotationEquation, CayleyJacobianMatchesFiniteDifferences) {
  for (int trial = 0; trial < 10; ++trial) {
    const RotationEquation eq(random_inertia());
    const V3 u = lgvi::test::random_vector(0.5), b = lgvi::test::random_vector(0.5);
    M3 fd;
    const double h = 1e-6;  // c is quadratic: central differences are exact but for round-off ~eps/h
    for (int j = 0; j < 3; ++j)
      fd.col(j) = (eq.cayley_residual(u + h * V3::Unit(j), b) - eq.cayley_residual(u - h * V3::Unit(j), b)) / (2 * h);
    EXPECT_MAT_NEAR(eq.cayley_jacobian(u, b), fd, 1e-9);
    // c(u) = (1 + |u|^2) (g(f) - b) for f = (1, u)/sqrt(1 + |u|^2).
    const double fs = 1 / std::sqrt(1 + u.squaredNorm());
    const S3d f(fs, fs * u.x(), fs * u.y(), fs * u.z());
    EXPECT_MAT_NEAR(eq.cayley_residual(u, b), ((1 + u.squaredNorm()) * (eq.g(f) - b)).eval(), 16 * eps);
  }
}

TEST(RotationEquation, ExponentialChartJacobianMatchesFiniteDifferences) {
  for (int trial = 0; trial < 10; ++trial) {
    const RotationEquation eq(random_inertia());
    const V3 xi = lgvi::test::random_vector(0.7);
    double c, sinc;
    S3d::cos_and_sinc(xi.norm(), c, sinc);
    M3 fd;
    const double h = 1e-5;  // truncation h^2 |g'''| / 6 ~ 1e-10
    for (int j = 0; j < 3; ++j)
      fd.col(j) = (eq.g(S3d::exp(xi + h * V3::Unit(j))) - eq.g(S3d::exp(xi - h * V3::Unit(j)))) / (2 * h);
    EXPECT_MAT_NEAR(eq.jacobian(xi, S3d::exp(xi), c, sinc), fd, 1e-9);
  }
}

class Solvers : public ::testing::TestWithParam<SolverKind> {};

TEST_P(Solvers, SolveThePapersEquationToRoundOff) {
  // The paper's second Hamiltonian equation, written literally:
  //   w0 = -(4/h) G(q1^* q0) J Im(q1^* q0) + (h/2) F(q0) dV/dq,
  // with F(q0) dV/dq = -2 M0 and q1 = q0 f.
  for (int trial = 0; trial < 20; ++trial) {
    const M3 J = random_inertia();
    const double h = 0.05;
    const V3 M0 = lgvi::test::random_vector(1.0);
    // A step the equation has a root for: a rotation per step |Omega| h ~
    // 2 |J^-1 b| (b = h (w0 + h M0) / 4) below 0.8 rad, under the 0.9 where
    // the solver reports that no root exists (for an isotropic J none does
    // beyond 1 rad). Drawn as before, and again while it is beyond.
    V3 w0 = lgvi::test::random_vector(10.0);
    while (2.0 * (J.inverse() * (0.25 * h * (w0 + h * M0))).norm() > 0.8) w0 = lgvi::test::random_vector(10.0);
    const S3d q0 = lgvi::test::random_unit_quaternion();
    lgvi::SolverOptions opt;
    opt.kind = GetParam();
    const RotationSolver solver(J, opt);
    S3d f = S3d::exp(J.inverse() * (0.25 * h * (w0 + h * M0)));  // first-order guess
    lgvi::SolveReport report;
    solver.solve(0.25 * h * (w0 + h * M0), f, report);
    const S3d q1 = q0 * f;
    const Eigen::Quaterniond q1q0 = q1.quaternion().conjugate() * q0.quaternion();
    const V3 rhs = -(4 / h) * lgvi::G(q1q0) * J * q1q0.vec() + (h / 2) * (-2.0 * M0);
    // Solved to tolerance 4 eps relative to |b| = h|w0|/4; the literal form's
    // own rounding (products with q0, q1 of size 1, times 4/h) adds a few eps |w0|.
    EXPECT_MAT_NEAR(rhs, w0, 64 * eps * w0.norm()) << "solver " << lgvi::to_string(GetParam());
    EXPECT_LE(std::abs(f.norm_error()), 4 * eps);
    EXPECT_GE(report.iterations, 1);
  }
}

TEST_P(Solvers, RotationReachingPiIsReported) {
  // b beyond what any rotation of less than pi per step can produce.
  lgvi::SolverOptions opt;
  opt.kind = GetParam();
  const RotationSolver solver(M3::Identity(), opt);
  S3d f;
  lgvi::SolveReport report;
  try {
    solver.solve(V3(50.0, 0, 0), f, report);
    FAIL() << "expected a StepFailure";
  } catch (const lgvi::StepFailure& e) {
    EXPECT_THAT(std::string(e.what()) + e.hint(), ::testing::AnyOf(::testing::HasSubstr("reached pi"),
                                                                   ::testing::HasSubstr("did not converge")));
    EXPECT_THAT(e.hint(), ::testing::HasSubstr("smaller step"));
  }
}

INSTANTIATE_TEST_SUITE_P(AllSolvers, Solvers,
                         ::testing::Values(SolverKind::Newton, SolverKind::NewtonExp, SolverKind::Broyden),
                         [](const auto& info) {
                           std::string n = lgvi::to_string(info.param);
                           std::replace(n.begin(), n.end(), '-', '_');
                           return n;
                         });

TEST(Solvers, AllThreeFindTheSameRoot) {
  const M3 J = lgvi::paper::three_ball_body().inertia();
  for (int trial = 0; trial < 20; ++trial) {
    const V3 b = lgvi::test::random_vector(0.05);
    S3d f[3];
    int k = 0;
    for (SolverKind kind : {SolverKind::Newton, SolverKind::NewtonExp, SolverKind::Broyden}) {
      lgvi::SolverOptions opt;
      opt.kind = kind;
      lgvi::SolveReport report;
      f[k] = S3d::exp(J.inverse() * b);
      RotationSolver(J, opt).solve(b, f[k], report);
      ++k;
    }
    // Each is within 4 eps |b| of the root in g; g is well conditioned
    // (|dg/df_v| ~ |J|, |J^{-1}| ~ 2) near the identity.
    EXPECT_MAT_NEAR(f[0].scalar_first(), f[1].scalar_first(), 16 * eps);
    EXPECT_MAT_NEAR(f[0].scalar_first(), f[2].scalar_first(), 16 * eps);
  }
}

TEST(Solvers, NewtonIsQuadraticFromAWarmStart) {
  // From the previous step's f (O(h^2) away), Newton needs 2 iterations and
  // Broyden a few more: the paper's choice costs iterations, not accuracy.
  const M3 J = lgvi::paper::three_ball_body().inertia();
  const V3 b(0.0025, 0.005, 0.0075), b_next = b + V3(1e-6, -2e-6, 1e-6);
  lgvi::SolveReport newton, broyden;
  S3d f = S3d::exp(J.inverse() * b);
  RotationSolver(J, {}).solve(b, f, newton);
  S3d f_newton = f, f_broyden = f;
  RotationSolver(J, {}).solve(b_next, f_newton, newton);
  lgvi::SolverOptions bopt;
  bopt.kind = SolverKind::Broyden;
  RotationSolver(J, bopt).solve(b_next, f_broyden, broyden);
  EXPECT_LE(newton.iterations, 2);
  EXPECT_GE(broyden.iterations, newton.iterations);
  EXPECT_LE(broyden.iterations, 6);
}

TEST(Solvers, NonConvergenceIsReportedNotHidden) {
  lgvi::SolverOptions opt;
  opt.max_iterations = 1;
  const M3 J = lgvi::paper::three_ball_body().inertia();
  S3d f;  // a cold start at the identity, far from the root
  lgvi::SolveReport report;
  EXPECT_THROW(RotationSolver(J, opt).solve(V3(0.3, 0.2, 0.1), f, report), lgvi::StepFailure);
}

/// Solves the problems (J, b, guess) in batches of RotationSolveBatch::lanes
/// (the last one partly filled), with the run-time clone and with the
/// baseline code, and each alone with RotationSolver::solve;
/// every lane must be either solved with the scalar solve's f, iterations
/// and residual evaluations, bit for bit, or left unsolved where the scalar
/// solve throws. Returns how many lanes were left unsolved.
int expect_batch_is_scalar(const std::vector<M3>& J, const std::vector<V3>& b, const std::vector<S3d>& guess,
                           const lgvi::SolverOptions& opt) {
  constexpr int lanes = lgvi::RotationSolveBatch::lanes;
  int unsolved = 0;
  for (std::size_t first = 0; first < J.size(); first += lanes) {
    const int count = static_cast<int>(std::min<std::size_t>(lanes, J.size() - first));
    std::vector<RotationSolver> solvers;
    lgvi::RotationSolveBatch batch;
    for (int l = 0; l < count; ++l) {
      solvers.emplace_back(J[first + l], opt);
      solvers.back().load(batch, l, b[first + l], guess[first + l]);
    }
    lgvi::RotationSolveBatch baseline = batch;
    lgvi::detail::newton_cayley_lanes(batch, count, opt.tolerance, opt.max_iterations);
    lgvi::detail::newton_cayley_lanes_baseline(baseline, count, opt.tolerance, opt.max_iterations);
    for (int l = 0; l < count; ++l) {
      // The clone this processor runs (AVX2 on today's) and the baseline's: the same bits.
      EXPECT_EQ(batch.solved[l], baseline.solved[l]);
      if (!batch.solved[l]) continue;
      for (int k = 0; k < 4; ++k) EXPECT_EQ(batch.f[k][l], baseline.f[k][l]);
    }
    for (int l = 0; l < count; ++l) {
      S3d f = guess[first + l];
      lgvi::SolveReport report;
      bool threw = false;
      try {
        solvers[static_cast<std::size_t>(l)].solve(b[first + l], f, report);
      } catch (const lgvi::StepFailure&) {
        threw = true;
      }
      const auto lane = static_cast<std::size_t>(l);
      if (!batch.solved[l]) {
        ++unsolved;
        EXPECT_TRUE(threw) << "problem " << first + lane << ": the batch left unsolved what the scalar solve solves";
        continue;
      }
      EXPECT_FALSE(threw) << "problem " << first + lane;
      EXPECT_EQ(batch.f[0][l], f.w()) << "problem " << first + lane;
      for (int k = 0; k < 3; ++k) EXPECT_EQ(batch.f[k + 1][l], f.vec()(k)) << "problem " << first + lane;
      EXPECT_EQ(batch.iterations[l], report.iterations) << "problem " << first + lane;
      EXPECT_EQ(batch.residual_evaluations[l], report.residual_evaluations) << "problem " << first + lane;
    }
  }
  return unsolved;
}

TEST(Solvers, BatchedNewtonIsTheScalarNewtonBitForBit) {
  // RotationSolveBatch repeats newton_cayley_chart operation for operation
  // on SIMD lanes; any difference of order would change last bits, so 40000
  // random problems (random inertias in random axes, |b| / |J| from 1e-6 to
  // 0.1) must give the same f, iterations and residual evaluations bit for
  // bit: half from the first-order guess exp(J^-1 b) off by up to 10 %, a
  // quarter from the root moved by 1e-16 to 1e-3 (as the predictor's guesses
  // are), a quarter from the root itself, so that every count of iterations
  // from 0 to 4 is represented.
  std::vector<M3> J;
  std::vector<V3> b;
  std::vector<S3d> guess;
  int scalar_failures = 0;
  std::map<int, int> iterations;  // how many problems took each count
  for (int k = 0; k < 40002; ++k) {  // (not a multiple of the lanes: the last batch is partly filled)
    J.push_back(random_inertia() * std::pow(10.0, lgvi::test::uniform(-3.0, 3.0)));
    b.push_back(lgvi::test::random_vector(1.0) * std::pow(10.0, lgvi::test::uniform(-6.0, -1.0)) *
                J.back().norm());
    S3d f = S3d::exp(J.back().inverse() * b.back() * lgvi::test::uniform(0.9, 1.1));
    if (k % 2 == 1) {
      lgvi::SolveReport report;
      try {
        RotationSolver(J.back(), {}).solve(b.back(), f, report);
      } catch (const lgvi::StepFailure&) {
      }
      if (k % 4 == 1)  // (k % 4 == 3: the root itself)
        f = S3d::exp(f.log() + lgvi::test::random_vector(std::pow(10.0, lgvi::test::uniform(-16.0, -3.0))));
    }
    guess.push_back(f);
    lgvi::SolveReport report;
    try {
      RotationSolver(J.back(), {}).solve(b.back(), f, report);
      ++iterations[report.iterations];
    } catch (const lgvi::StepFailure&) {
      ++scalar_failures;  // a b too large for any root: a handful
    }
  }
  // (With the test's seed: 0 to 5 iterations for 10004, 5584, 17751, 6598, 55, 3 problems.)
  for (const int count : {0, 1, 2, 3}) EXPECT_GE(iterations[count], 1000) << count << " iterations";
  EXPECT_GE(iterations[4] + iterations[5], 20);
  EXPECT_LE(scalar_failures, 100);
  EXPECT_EQ(expect_batch_is_scalar(J, b, guess, {}), scalar_failures);
}

TEST(Solvers, BatchedNewtonLeavesFailuresToTheScalarSolve) {
  // Lanes that fail: a guess beyond the branch (f_s <= 0), b without a root,
  // one iteration allowed from far away, non-finite inputs; next to lanes
  // that do not. Each failing lane must be left unsolved (the scalar solve
  // throws, with its message), the others solved bit for bit.
  const M3 J = lgvi::paper::three_ball_body().inertia();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<M3> Js(10, J);
  std::vector<V3> b = {V3(0.01, 0.02, 0.0),  V3(50.0, 0.0, 0.0),  V3(0.01, 0.0, 0.0), V3(nan, 0.0, 0.0),
                       V3(0.0, 0.01, 0.0),   V3(0.02, 0.0, 0.01), V3(0.0, 0.0, 0.0),  V3(0.01, 0.01, 0.01),
                       V3(0.0, 0.0, 1e-300), V3(0.0, 0.03, 0.0)};
  std::vector<S3d> guess(10, S3d());
  guess[2] = S3d(-0.5, 0.5, 0.5, 0.5);  // off the branch
  guess[4] = S3d(nan, 0.0, 0.0, 0.0);
  EXPECT_EQ(expect_batch_is_scalar(Js, b, guess, {}), 4);  // problems 1 to 4
  lgvi::SolverOptions one_iteration;
  one_iteration.max_iterations = 1;
  EXPECT_GE(expect_batch_is_scalar(Js, b, guess, one_iteration), 4);
}

}  // namespace

namespace {

/// `solver`'s root of g(f) = b from the first-order guess J^+ b.
S3d solve_from_first_order(const RotationSolver& solver, const V3& b, const V3& moments) {
  V3 u;
  for (int k = 0; k < 3; ++k) u(k) = moments(k) > 0.0 ? b(k) / moments(k) : 0.0;
  S3d f = S3d(1.0, u.x(), u.y(), u.z()).normalized();
  lgvi::SolveReport report;
  solver.solve(b, f, report);
  return f;
}

}  // namespace

// RotationSolver::for_principal_moments, what fix rigid/nve/lgvi (lammps/) builds per body from LAMMPS's
// principal moments: the solver of the same body as RigidBody makes it, so the same root.
TEST(Solvers, PrincipalMomentsGiveTheBodysOwnSolver) {
  const lgvi::SolverOptions opt;
  const V3 b(0.02, -0.05, 0.03);
  // Three moments: J = diag(moments), bit for bit the solver of that matrix.
  const V3 three(1.0, 2.0, 2.5);
  const S3d full = solve_from_first_order(RotationSolver::for_principal_moments(three, opt), b, three);
  const S3d direct = solve_from_first_order(RotationSolver(M3(three.asDiagonal()), opt), b, three);
  EXPECT_EQ(full.scalar_first(), direct.scalar_first());
  // One zero moment: a linear body along that axis, I the mean of the two others (equal to round-off, as from
  // LAMMPS's eigen-solver), the closed-form root without turn about the axis, as RigidBody's linear body.
  const V3 linear(1.5 * (1 + eps), 0.0, 1.5);
  const S3d rod = solve_from_first_order(RotationSolver::for_principal_moments(linear, opt), b, linear);
  const lgvi::RigidBody body(1.0, M3(V3(1.5, 0.0, 1.5).asDiagonal()));
  ASSERT_EQ(body.rotational_dof(), 2);
  const S3d reference = solve_from_first_order(RotationSolver(body, opt), b, V3(1.5, 0.0, 1.5));
  EXPECT_MAT_NEAR(rod.scalar_first(), reference.scalar_first(), 4 * eps);
  EXPECT_EQ(rod.vec()(1), 0.0);  // no turn about the axis
  // g(f) = b across the axis: f_s I f_v = b_perp.
  EXPECT_MAT_NEAR((rod.w() * 1.5 * rod.vec()).eval(), V3(b(0), 0.0, b(2)), 8 * eps * b.norm());
  // All zero: a point, f = e.
  const S3d point = solve_from_first_order(RotationSolver::for_principal_moments(V3::Zero(), opt), b, V3::Zero());
  EXPECT_EQ(point.scalar_first(), S3d().scalar_first());
  // What no collection of masses has.
  for (const V3& bad : {V3(0.0, 0.0, 1.0), V3(-1.0, 1.0, 1.0), V3(1.0, std::nan(""), 1.0)})
    EXPECT_THROW(RotationSolver::for_principal_moments(bad, opt), lgvi::InvalidInput);
}

}  // namespace test_solver
