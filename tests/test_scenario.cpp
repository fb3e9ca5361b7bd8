// Tests of the scenario reader: the shipped scenarios parse with the values
// they state, and every kind of bad input is rejected with a one-line
// InvalidInput that starts with the file name and names the offending key.
#include <gtest/gtest.h>

#include "io/memory_sink.hpp"
#include "app/scenario.hpp"
#include "scenario_support.hpp"
#include "app/simulation.hpp"

#include <lgvi/error.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <typeinfo>
#include <vector>

#include <unistd.h>

namespace test_scenario {

namespace {

using lgvi::InvalidInput;
using lgvi::app::parse_scenario;
using lgvi::app::read_scenario;
using lgvi::app::Scenario;

const std::string scenario_dir = LGVI_SCENARIO_DIR;

// ---------------------------------------------------------------------------
// Helpers

/// A valid scenario, mutated by the bad-input cases below. Every line a case
/// replaces occurs exactly once.
const std::string base_text = R"([body]
mass = 2.0
inertia = [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.5]]

[potential]
kind = "central"
mu = 1.0

[initial]
position = [8.0, 0.0, 0.0]
quaternion = [1.0, 0.0, 0.0, 0.0]
momentum = [0.0, 1.0, 0.0]
w = [1.0, 2.0, 3.0]

[integrator]
method = "lgvi"
solver = "newton"
step = 0.01
duration = 1.0

[output]
every = 10
)";

const std::string base_body = R"([body]
mass = 2.0
inertia = [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.5]]
)";

/// `text` with the single occurrence of `from` replaced by `to`. Throws (and
/// so fails the test loudly) if `from` is not there exactly once: a typo in
/// a case must not turn it into a test of the unmutated text.
std::string replace(const std::string& text, const std::string& from, const std::string& to) {
  const std::size_t at = text.find(from);
  if (at == std::string::npos || text.find(from, at + 1) != std::string::npos)
    throw std::logic_error("test bug: '" + from + "' does not occur exactly once in the base text");
  std::string out = text;
  out.replace(at, from.size(), to);
  return out;
}

std::string mutate(const std::string& from, const std::string& to) { return replace(base_text, from, to); }

/// The base scenario with its [body] made of the given [[body.ball]] entries.
std::string with_balls(const std::string& balls) { return mutate(base_body, "[body]\n" + balls); }

/// Three balls: unit masses, radius 0.1, on a triangle (a valid body).
std::string ball_entry(const std::string& position, const std::string& mass, const std::string& radius) {
  return "[[body.ball]]\nposition = " + position + "\nmass = " + mass + "\nradius = " + radius + "\n";
}

using lgvi::test::parse_error;

std::string read_error(const std::string& path) {
  try {
    read_scenario(path);
  } catch (const InvalidInput& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "threw a " << typeid(e).name() << " that is not an InvalidInput: " << e.what();
    return {};
  }
  ADD_FAILURE() << "read " << path << " without error";
  return {};
}

/// The rules every error message obeys: one line, starting with the file
/// name, naming each of `expected`. Prints the message on failure.
testing::AssertionResult is_good_message(const std::string& message, const std::string& file,
                                         const std::vector<std::string>& expected) {
  if (message.empty()) return testing::AssertionFailure() << "no message";
  if (message.find('\n') != std::string::npos)
    return testing::AssertionFailure() << "message is not one line: \"" << message << "\"";
  if (message.rfind(file + ":", 0) != 0)
    return testing::AssertionFailure() << "message does not start with \"" << file << ":\": \"" << message << "\"";
  for (const std::string& e : expected)
    if (message.find(e) == std::string::npos)
      return testing::AssertionFailure() << "message does not contain \"" << e << "\": \"" << message << "\"";
  return testing::AssertionSuccess() << message;
}

/// A file in the test temporary folder, removed at the end of the scope.
class TempFile {
 public:
  TempFile(const std::string& stem, const std::string& content)
      : path_(testing::TempDir() + "lgvi_test_" + std::to_string(::getpid()) + "_" + stem + ".toml") {
    std::ofstream out(path_, std::ios::binary);
    out.write(content.data(), static_cast<std::streamsize>(content.size()));
  }
  ~TempFile() {
    std::error_code ec;
    std::filesystem::remove(path_, ec);
  }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

// ---------------------------------------------------------------------------
// The shipped scenarios

/// The inertia of the paper's body, computed independently of the reader.
///
/// Three unit point masses on an equilateral triangle of side 1 in the x-y
/// plane; about the centroid each is at distance 1/sqrt(3), so
///   Jzz = sum m |rho|^2 = 3 * 1 * (1/3) = 1.
/// The second-moment tensor S = sum m rho rho^T of the in-plane part has
/// 3-fold symmetry, hence is isotropic in the plane: Sxx = Syy = tr(S)/2 =
/// 1/2, Sxy = 0 (explicitly, with the centroid at the origin the x are
/// -1/2, 1/2, 0 and sum x^2 = 1/2; the y are -c, -c, 2c with c = sqrt(3)/6,
/// sum y^2 = 6 c^2 = 1/2; sum x y = c/2 - c/2 + 0 = 0). The standard inertia
/// J = sum m (|rho|^2 I - rho rho^T) then has
///   Jxx = sum m (|rho|^2 - x^2) = sum y^2 = 1/2,
///   Jyy = sum x^2 = 1/2,  Jzz = 1,  off-diagonal -sum x y = 0, 0, 0.
/// Each ball adds its own 2/5 m r^2 = 0.4 * 1 * 0.01 = 0.004 on the diagonal;
/// three balls add 0.012.
lgvi::Matrix3<double> paper_inertia() {
  lgvi::Matrix3<double> j = lgvi::Matrix3<double>::Zero();
  j.diagonal() << 0.5 + 0.012, 0.5 + 0.012, 1.0 + 0.012;
  return j;
}

void expect_paper_body_and_integrator(const Scenario& s) {
  EXPECT_EQ(s.body().mass(), 3.0);
  ASSERT_EQ(s.body().balls().size(), 3u);
  lgvi::Vector3<double> first_moment = lgvi::Vector3<double>::Zero();
  for (const lgvi::Ball& b : s.body().balls()) {
    EXPECT_EQ(b.mass, 1.0);
    EXPECT_EQ(b.radius, 0.1);
    EXPECT_NEAR(b.position.norm(), 1.0 / std::sqrt(3.0), 1e-15);
    first_moment += b.mass * b.position;
  }
  EXPECT_LE(first_moment.norm(), 1e-15) << "centre of mass not at the origin: " << first_moment.transpose();
  EXPECT_LE((s.body().inertia() - paper_inertia()).cwiseAbs().maxCoeff(), 1e-14) << s.body().inertia();

  EXPECT_EQ(s.potential.kind, lgvi::app::PotentialKind::Central);
  EXPECT_EQ(s.potential.mu, 1.0);
  EXPECT_EQ(s.initial().x, lgvi::Vector3<double>(8.0, 0.0, 0.0));
  EXPECT_EQ(s.initial().q.w(), 1.0);
  EXPECT_EQ(s.initial().q.quaternion().vec(), lgvi::Vector3<double>::Zero());
  EXPECT_EQ(s.initial().w, lgvi::Vector3<double>(1.0, 2.0, 3.0));

  EXPECT_EQ(s.integrator.method, lgvi::app::Method::named("lgvi"));
  EXPECT_EQ(s.integrator.solver.kind, lgvi::SolverKind::Newton);
  EXPECT_EQ(s.integrator.step, 0.01);
  EXPECT_EQ(s.integrator.duration, 1000.0);
  // 1000 / 0.01 = 100000.00000000001 in floating point: must not become 100001.
  EXPECT_EQ(s.integrator.steps, 100000);
  EXPECT_EQ(s.output_every, 10);
}

TEST(ScenarioFiles, PaperParsesWithItsStatedValues) {
  const Scenario s = read_scenario(scenario_dir + "/paper.toml");
  EXPECT_EQ(s.name, "paper");
  expect_paper_body_and_integrator(s);
  EXPECT_EQ(s.initial().p, lgvi::Vector3<double>(1.0, 0.0, 0.0));  // the paper's radial p0
}

TEST(ScenarioFiles, PaperClosePassParsesAsTheAdaptiveStep) {
  // paper.toml's body, field and state with [integrator] time_transform: the
  // fictitious step in `step`, the monitor's c, the composition to order 4,
  // and max_steps by default 100 duration / epsilon = 100 * 1000 / 0.1.
  const Scenario s = read_scenario(scenario_dir + "/paper-close-pass.toml");
  EXPECT_TRUE(s.integrator.adaptive());
  EXPECT_EQ(s.integrator.step, 0.1);
  EXPECT_EQ(s.integrator.monitor_scale, 0.4);
  EXPECT_EQ(s.integrator.composition.order(), 4);
  EXPECT_EQ(s.integrator.duration, 1000.0);
  EXPECT_EQ(s.integrator.steps, 1000000);
  EXPECT_EQ(s.initial().p, lgvi::Vector3<double>(1.0, 0.0, 0.0));
  EXPECT_FALSE(s.integrator.exact_finish);  // the run ends with the first step past the duration
}

TEST(ScenarioInput, ExactFinishEndsTheAdaptiveRunAtTheDuration) {
  // [integrator] exact_finish: the summary's last_time is the duration
  // itself, not the first step past it, and min_step / max_step leave out
  // the shortened last step (no measure of the dynamics). The duration is put
  // 1e-6 past step 150 of a free run, so the last step is far shorter than
  // any other; the steps before it are the free run's, bit for bit, so
  // min_step and max_step are exactly the free run's over steps 1 to 150.
  std::ifstream in(scenario_dir + "/paper-close-pass.toml");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  Scenario free_running = parse_scenario(replace(text, "duration = 1000.0", "duration = 20.0"), "dir/free.toml");
  free_running.output_every = 1;
  lgvi::app::MemorySink a(1000);
  const lgvi::app::SimulationResult r0 = lgvi::app::simulate(free_running, a);
  ASSERT_TRUE(r0.completed);
  const std::vector<double> rows = a.take();
  const auto t = [&](std::size_t k) { return rows[k * static_cast<std::size_t>(lgvi::app::trajectory_columns)]; };
  constexpr std::size_t kept = 150;
  ASSERT_GT(rows.size(), (kept + 1) * static_cast<std::size_t>(lgvi::app::trajectory_columns));
  double min_dt = t(1) - t(0), max_dt = min_dt;
  for (std::size_t k = 1; k <= kept; ++k) {
    min_dt = std::min(min_dt, t(k) - t(k - 1));
    max_dt = std::max(max_dt, t(k) - t(k - 1));
  }
  const double duration = t(kept) + 1e-6;
  Scenario finishing = parse_scenario(
      replace(text, "duration = 1000.0", fmt::format("duration = {}\nexact_finish = true", duration)),
      "dir/finishing.toml");
  ASSERT_TRUE(finishing.integrator.exact_finish);
  lgvi::app::MemorySink b(2);
  const lgvi::app::SimulationResult r1 = lgvi::app::simulate(finishing, b);
  ASSERT_TRUE(r1.completed);
  EXPECT_EQ(r1.stats.last_t, duration);
  EXPECT_EQ(r1.stats.last_k, static_cast<std::int64_t>(kept) + 1);
  EXPECT_EQ(r1.stats.min_time_step, min_dt);
  EXPECT_EQ(r1.stats.max_time_step, max_dt);
  EXPECT_GT(min_dt, 1e-3);  // the shortened step (1e-6) would have been the minimum
}

TEST(ScenarioInput, AdaptiveStepRefusesAPairPotentialWhoseEnergyCanBePositive) {
  // Lennard-Jones: U = -V does not measure closeness (V > 0 inside sigma).
  std::ifstream in(scenario_dir + "/lj-gas.toml");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string message =
      parse_error(replace(text, "step = 0.002", "time_transform = \"potential\"\nepsilon = 0.002"), "dir/bad.toml");
  EXPECT_TRUE(is_good_message(message, "dir/bad.toml", {"interaction.kind", "lennard-jones", "can be positive"}));
}

TEST(ScenarioFiles, PaperOrbitParsesWithItsStatedValues) {
  const Scenario s = read_scenario(scenario_dir + "/paper-orbit.toml");
  EXPECT_EQ(s.name, "paper-orbit");
  expect_paper_body_and_integrator(s);
  EXPECT_EQ(s.initial().p, lgvi::Vector3<double>(0.0, 1.0, 0.0));  // tangential
}

// ---------------------------------------------------------------------------
// Valid variants

TEST(ScenarioInput, BaseTextParses) {
  const Scenario s = parse_scenario(base_text, "dir/base.toml");
  EXPECT_EQ(s.name, "base");
  EXPECT_EQ(s.body().mass(), 2.0);
  EXPECT_TRUE(s.body().balls().empty());
  EXPECT_EQ(s.integrator.steps, 100);
  EXPECT_EQ(s.output_every, 10);
}

TEST(ScenarioInput, DefaultsForOptionalKeys) {
  std::string text = replace(mutate("method = \"lgvi\"\n", ""), "solver = \"newton\"\n", "");
  text = replace(text, "[output]\nevery = 10\n", "");
  const Scenario s = parse_scenario(text, "defaults.toml");
  EXPECT_EQ(s.integrator.method, lgvi::app::Method::named("lgvi"));
  EXPECT_EQ(s.integrator.solver.kind, lgvi::SolverKind::Newton);
  EXPECT_EQ(s.integrator.solver.tolerance, lgvi::SolverOptions{}.tolerance);
  EXPECT_EQ(s.integrator.solver.max_iterations, lgvi::SolverOptions{}.max_iterations);
  EXPECT_EQ(s.output_every, 1);
}

TEST(ScenarioInput, OtherMethodSolverAndPotentials) {
  std::string text = mutate("method = \"lgvi\"", "method = \"lgvi-lagrangian\"");
  text = replace(text, "solver = \"newton\"", "solver = \"broyden\"\ntolerance = 1e-12\nmax_iterations = 7");
  text = replace(text, "kind = \"central\"\nmu = 1.0", "kind = \"uniform\"\ng = [0, 0, -9.81]");
  const Scenario s = parse_scenario(text, "other.toml");
  EXPECT_EQ(s.integrator.method, lgvi::app::Method::named("lgvi-lagrangian"));
  EXPECT_EQ(s.integrator.solver.kind, lgvi::SolverKind::Broyden);
  EXPECT_EQ(s.integrator.solver.tolerance, 1e-12);
  EXPECT_EQ(s.integrator.solver.max_iterations, 7);
  EXPECT_EQ(s.potential.kind, lgvi::app::PotentialKind::Uniform);
  EXPECT_EQ(s.potential.g, lgvi::Vector3<double>(0.0, 0.0, -9.81));

  const Scenario none = parse_scenario(mutate("kind = \"central\"\nmu = 1.0", "kind = \"none\""), "none.toml");
  EXPECT_EQ(none.potential.kind, lgvi::app::PotentialKind::None);
  const Scenario exp = parse_scenario(mutate("solver = \"newton\"", "solver = \"newton-exp\""), "exp.toml");
  EXPECT_EQ(exp.integrator.solver.kind, lgvi::SolverKind::NewtonExp);
}

TEST(ScenarioInput, StepCountIsCeilingForgivingRoundOff) {
  struct Case {
    const char* step;
    const char* duration;
    std::int64_t steps;
  };
  const Case cases[] = {
      {"0.01", "1000.0", 100000},  // 100000.00000000001
      {"0.01", "1.0", 100},        //
      {"0.1", "0.3", 3},           // 2.9999999999999996
      {"0.01", "0.1", 10},         //
      {"0.01", "0.015", 2},        // a partial step is completed: ceil
      {"0.01", "0.0", 0},          //
      {"1", "5", 5},               // integers are numbers
  };
  for (const Case& c : cases) {
    std::string text = mutate("step = 0.01", std::string("step = ") + c.step);
    text = replace(text, "duration = 1.0", std::string("duration = ") + c.duration);
    const Scenario s = parse_scenario(text, "steps.toml");
    EXPECT_EQ(s.integrator.steps, c.steps) << "duration " << c.duration << ", step " << c.step;
  }
}

TEST(ScenarioInput, VelocityGivesMomentumTimesMass) {
  // Mass 2: p = m v.
  const Scenario s = parse_scenario(mutate("momentum = [0.0, 1.0, 0.0]", "velocity = [0.5, -1.0, 2.0]"), "v.toml");
  EXPECT_EQ(s.initial().p, lgvi::Vector3<double>(1.0, -2.0, 4.0));
  // A ball body: m = 3.
  const Scenario b = parse_scenario(
      replace(with_balls(ball_entry("[0, 0, 0]", "1.0", "0.1") + ball_entry("[1, 0, 0]", "2.0", "0.1")),
              "momentum = [0.0, 1.0, 0.0]", "velocity = [0.0, 1.0, 0.0]"),
      "vb.toml");
  EXPECT_EQ(b.initial().p, lgvi::Vector3<double>(0.0, 3.0, 0.0));
}

TEST(ScenarioInput, OmegaGivesTwiceInertiaTimesOmega) {
  // J = [[2, 0.1, 0], [0.1, 3, 0], [0, 0, 4]] (principal moments ~1.99, 3.01,
  // 4: valid); Omega = (1, 2, 3): J Omega = (2 + 0.2, 0.1 + 6, 12) =
  // (2.2, 6.1, 12), w = 2 J Omega = (4.4, 12.2, 24).
  std::string text = mutate("inertia = [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.5]]",
                            "inertia = [[2.0, 0.1, 0.0], [0.1, 3.0, 0.0], [0.0, 0.0, 4.0]]");
  text = replace(text, "w = [1.0, 2.0, 3.0]", "omega = [1.0, 2.0, 3.0]");
  const Scenario s = parse_scenario(text, "omega.toml");
  const lgvi::Vector3<double> expected(4.4, 12.2, 24.0);
  EXPECT_LE((s.initial().w - expected).cwiseAbs().maxCoeff(), 1e-14) << s.initial().w.transpose();
}

TEST(ScenarioInput, NearlyUnitQuaternionIsNormalized) {
  // |(0.50000025, 0.50000025, 0.50000025, 0.50000025)| = 1 + 5e-7 (within 1e-6).
  const Scenario s = parse_scenario(
      mutate("quaternion = [1.0, 0.0, 0.0, 0.0]", "quaternion = [0.50000025, 0.50000025, 0.50000025, 0.50000025]"),
      "q.toml");
  EXPECT_LE(std::abs(s.initial().q.quaternion().norm() - 1.0), 1e-15);
  EXPECT_LE(std::abs(s.initial().q.norm_error()), 1e-15);
  EXPECT_NEAR(s.initial().q.w(), 0.5, 1e-15);
  // A norm 1 - 5e-7 (scalar only).
  const Scenario t = parse_scenario(mutate("quaternion = [1.0, 0.0, 0.0, 0.0]", "quaternion = [0.9999995, 0, 0, 0]"),
                                    "q.toml");
  EXPECT_EQ(t.initial().q.w(), 1.0);
}

TEST(ScenarioInput, QuaternionFurtherThan1e6FromUnitIsRejected) {
  // |(0.500001, ...)| = 1 + 2e-6.
  const std::string message = parse_error(
      mutate("quaternion = [1.0, 0.0, 0.0, 0.0]", "quaternion = [0.500001, 0.500001, 0.500001, 0.500001]"),
      "q.toml");
  EXPECT_TRUE(is_good_message(message, "q.toml", {"initial.quaternion", "unit quaternion"}));
  const std::string zero = parse_error(mutate("quaternion = [1.0, 0.0, 0.0, 0.0]", "quaternion = [0, 0, 0, 0]"),
                                       "q.toml");
  EXPECT_TRUE(is_good_message(zero, "q.toml", {"initial.quaternion"}));
}

TEST(ScenarioInput, IntegerBeyondTwoToThe53IsANumber) {
  // toml++ will not convert an integer above 2^53 to double exactly; the
  // reader must still treat it as a number (it did throw bad_optional_access).
  const Scenario s =
      parse_scenario(mutate("position = [8.0, 0.0, 0.0]", "position = [9007199254740993, 0, 0]"), "big.toml");
  EXPECT_EQ(s.initial().x.x(), 9007199254740992.0);
}

// ---------------------------------------------------------------------------
// Bad input: each case is a mutation of the base text and the substrings its
// message must contain (besides starting with the file name, on one line).

struct BadCase {
  std::string id;           ///< test name suffix
  std::string description;  ///< what is wrong
  std::string text;         ///< the scenario text
  std::vector<std::string> expected;
};

void PrintTo(const BadCase& c, std::ostream* os) { *os << c.description; }

const std::string bad_name = "dir/bad.toml";

/// The line (1-based) of the first occurrence of `s` in `text`.
int line_of(const std::string& text, const std::string& s) {
  const std::size_t at = text.find(s);
  if (at == std::string::npos) throw std::logic_error("test bug: '" + s + "' not in the text");
  int line = 1;
  for (std::size_t i = 0; i < at; ++i) line += text[i] == '\n';
  return line;
}

std::vector<BadCase> bad_cases() {
  const std::string triangle =
      ball_entry("[0, 0, 0]", "1.0", "0.1") + ball_entry("[1, 0, 0]", "1.0", "0.1") +
      ball_entry("[0.5, 0.8660254037844386, 0]", "1.0", "0.1");
  const std::string duplicate = mutate("step = 0.01\n", "step = 0.01\nstep = 0.02\n");
  std::vector<BadCase> c = {
      // Unknown and missing keys and tables.
      {"UnknownTopLevelKey", "unknown key at top level", "title = \"x\"\n" + base_text, {"key 'title'", "unknown key"}},
      {"UnknownTopLevelTable", "unknown table at top level", base_text + "[extra]\na = 1\n", {"key 'extra'"}},
      {"UnknownIntegratorKey", "unknown key in [integrator]", mutate("step = 0.01", "stepp = 0.1\nstep = 0.01"),
       {"integrator.stepp", "unknown key", "step"}},
      {"UnknownInitialKey", "unknown key in [initial]", mutate("w = [1.0, 2.0, 3.0]", "w = [1.0, 2.0, 3.0]\nx = 1"),
       {"initial.x", "unknown key"}},
      {"UnknownBodyKey", "unknown key in [body]", mutate("mass = 2.0", "mass = 2.0\ncolour = 1"),
       {"body.colour", "unknown key"}},
      {"UnknownPotentialKey", "mu given with kind none", mutate("kind = \"central\"", "kind = \"none\""),
       {"potential.mu", "unknown key"}},
      {"UnknownOutputKey", "unknown key in [output]", mutate("every = 10", "every = 10\nfolder = \"x\""),
       {"output.folder", "unknown key"}},
      {"UnknownBallKey", "unknown key in a ball", with_balls(triangle + "colour = \"red\"\n"),
       {"body.ball[2].colour", "unknown key"}},
      {"MissingInitial", "missing [initial]",
       mutate("[initial]\nposition = [8.0, 0.0, 0.0]\nquaternion = [1.0, 0.0, 0.0, 0.0]\nmomentum = [0.0, 1.0, 0.0]\n"
              "w = [1.0, 2.0, 3.0]\n",
              ""),
       {"initial", "missing table"}},
      {"MissingIntegrator", "missing [integrator]",
       mutate("[integrator]\nmethod = \"lgvi\"\nsolver = \"newton\"\nstep = 0.01\nduration = 1.0\n", ""),
       {"integrator", "missing table"}},
      {"MisspelledTable", "[integratorr]", mutate("[integrator]\n", "[integratorr]\n"),
       {"key 'integratorr'", "unknown key"}},
      {"MissingStep", "missing integrator.step", mutate("step = 0.01\n", ""), {"integrator.step", "missing"}},
      {"MissingDuration", "missing integrator.duration", mutate("duration = 1.0\n", ""),
       {"integrator.duration", "missing"}},
      {"MissingPotentialKind", "missing potential.kind", mutate("kind = \"central\"\n", ""),
       {"potential.kind", "missing"}},
      {"MissingPosition", "missing initial.position", mutate("position = [8.0, 0.0, 0.0]\n", ""),
       {"initial.position", "missing"}},
      {"MissingQuaternion", "missing initial.quaternion", mutate("quaternion = [1.0, 0.0, 0.0, 0.0]\n", ""),
       {"initial.quaternion", "missing"}},
      {"EmptyFile", "empty file", "", {"body", "missing table"}},
      {"BodyNotATable", "body = 1", mutate(base_body, "body = 1\n"), {"key 'body'", "table"}},
      {"OutputNotATable", "output = 1", "output = 1\n" + mutate("[output]\nevery = 10\n", ""),
       {"key 'output'", "table"}},

      // Potential.
      {"UnknownPotentialKind", "potential.kind = \"magnetic\"", mutate("kind = \"central\"", "kind = \"magnetic\""),
       {"potential.kind", "magnetic", "central"}},
      {"PotentialKindNotString", "potential.kind = 3", mutate("kind = \"central\"", "kind = 3"),
       {"potential.kind", "must be a string"}},
      {"CentralWithoutMu", "central without mu", mutate("mu = 1.0\n", ""), {"potential.mu", "missing"}},
      {"MuZero", "mu = 0", mutate("mu = 1.0", "mu = 0"), {"potential.mu", "> 0"}},
      {"MuNegative", "mu = -1", mutate("mu = 1.0", "mu = -1.0"), {"potential.mu", "> 0"}},
      {"UniformWithoutG", "uniform without g", mutate("kind = \"central\"\nmu = 1.0", "kind = \"uniform\""),
       {"potential.g", "missing"}},

      // The adaptive step ([integrator] time_transform, time_transformed.hpp).
      {"AdaptiveWithStep", "time_transform with step", mutate("step = 0.01", "time_transform = \"potential\"\nstep = 0.01"),
       {"integrator.step", "adapts", "epsilon"}},
      {"AdaptiveWithoutEpsilon", "time_transform without epsilon",
       mutate("step = 0.01", "time_transform = \"potential\""), {"integrator.epsilon", "missing"}},
      {"AdaptiveUnknownKind", "time_transform = \"log\"", mutate("step = 0.01", "time_transform = \"log\"\nstep = 0.01"),
       {"integrator.time_transform", "log", "potential"}},
      {"AdaptiveEpsilonZero", "epsilon = 0", mutate("step = 0.01", "time_transform = \"potential\"\nepsilon = 0"),
       {"integrator.epsilon", "> 0"}},
      {"AdaptiveMonitorScaleNegative", "monitor_scale = -1",
       mutate("step = 0.01", "time_transform = \"potential\"\nepsilon = 0.02\nmonitor_scale = -1.0"),
       {"integrator.monitor_scale", "> 0"}},
      {"AdaptiveMaxStepsZero", "max_steps = 0",
       mutate("step = 0.01", "time_transform = \"potential\"\nepsilon = 0.02\nmax_steps = 0"),
       {"integrator.max_steps", ">= 1"}},
      {"AdaptiveExactFinishNotBoolean", "exact_finish = 1",
       mutate("step = 0.01", "time_transform = \"potential\"\nepsilon = 0.02\nexact_finish = 1"),
       {"integrator.exact_finish", "true or false"}},
      {"ExactFinishWithoutTimeTransform", "exact_finish with a fixed step",
       mutate("step = 0.01", "step = 0.01\nexact_finish = true"), {"integrator.exact_finish", "time_transform"}},
      {"EpsilonWithoutTimeTransform", "epsilon with a fixed step", mutate("step = 0.01", "step = 0.01\nepsilon = 0.02"),
       {"integrator.epsilon", "time_transform"}},
      {"AdaptiveOtherMethod", "time_transform with rattle-quaternion",
       replace(mutate("step = 0.01", "time_transform = \"potential\"\nepsilon = 0.02"), "method = \"lgvi\"",
               "method = \"rattle-quaternion\""),
       {"integrator.method", "\"lgvi\""}},
      {"AdaptiveUniformField", "time_transform in a uniform field",
       replace(mutate("step = 0.01", "time_transform = \"potential\"\nepsilon = 0.02"), "kind = \"central\"\nmu = 1.0",
               "kind = \"uniform\"\ng = [0.0, 0.0, -1.0]"),
       {"potential.kind", "uniform", "gravity", "time_transform = \"none\""}},
      {"AdaptiveNoPotential", "time_transform with no potential",
       replace(mutate("step = 0.01", "time_transform = \"potential\"\nepsilon = 0.02"), "kind = \"central\"\nmu = 1.0",
               "kind = \"none\""),
       {"integrator.time_transform", "no potential"}},
      {"AdaptiveForcing", "time_transform with a forcing",
       mutate("step = 0.01", "time_transform = \"potential\"\nepsilon = 0.02") +
           "[[forcing]]\nkind = \"torque\"\nvalue = [0.0, 0.0, 1.0]\n",
       {"forcing", "time_transform = \"none\""}},

      // Types and values of numbers and arrays.
      {"StepIsString", "step = \"0.01\"", mutate("step = 0.01", "step = \"0.01\""),
       {"integrator.step", "must be a number", "string"}},
      {"MuIsBoolean", "mu = true", mutate("mu = 1.0", "mu = true"), {"potential.mu", "must be a number"}},
      {"StepIsDate", "step = 1979-05-27", mutate("step = 0.01", "step = 1979-05-27"),
       {"integrator.step", "must be a number"}},
      {"PositionTooShort", "position = [1, 2]", mutate("position = [8.0, 0.0, 0.0]", "position = [1, 2]"),
       {"initial.position", "3 numbers", "got 2"}},
      {"PositionTooLong", "position = [1, 2, 3, 4]", mutate("position = [8.0, 0.0, 0.0]", "position = [1, 2, 3, 4]"),
       {"initial.position", "3 numbers", "got 4"}},
      {"PositionNotArray", "position = 1", mutate("position = [8.0, 0.0, 0.0]", "position = 1"),
       {"initial.position", "array"}},
      {"PositionNestedString", "position = [1, \"a\", 3]",
       mutate("position = [8.0, 0.0, 0.0]", "position = [1, \"a\", 3]"), {"initial.position[1]", "must be a number"}},
      {"PositionNestedArray", "position = [1, [2], 3]",
       mutate("position = [8.0, 0.0, 0.0]", "position = [1, [2], 3]"), {"initial.position[1]", "must be a number"}},
      {"StepNan", "step = nan", mutate("step = 0.01", "step = nan"), {"integrator.step", "finite"}},
      {"PositionInf", "position = [inf, 0, 0]", mutate("position = [8.0, 0.0, 0.0]", "position = [inf, 0, 0]"),
       {"initial.position[0]", "finite"}},
      {"MomentumMinusInf", "momentum = [0, -inf, 0]",
       mutate("momentum = [0.0, 1.0, 0.0]", "momentum = [0, -inf, 0]"), {"initial.momentum[1]", "finite"}},
      {"MassNan", "mass = nan", mutate("mass = 2.0", "mass = nan"), {"body.mass", "finite"}},

      // Integrator.
      {"StepZero", "step = 0", mutate("step = 0.01", "step = 0"), {"integrator.step", "> 0"}},
      {"StepNegative", "step = -0.01", mutate("step = 0.01", "step = -0.01"), {"integrator.step", "> 0"}},
      {"DurationNegative", "duration = -1", mutate("duration = 1.0", "duration = -1"),
       {"integrator.duration", ">= 0"}},
      {"TooManySteps", "duration / step > 2^53 (step = 1e-10, duration = 1e7)",
       replace(mutate("step = 0.01", "step = 1e-10"), "duration = 1.0", "duration = 1e7"),
       {"integrator.duration", "2^53"}},
      {"MethodRk4", "integrator.method = \"rk4\"", mutate("method = \"lgvi\"", "method = \"rk4\""),
       {"integrator.method", "rk4", "lgvi"}},
      {"OrderThree", "integrator.order = 3", mutate("step = 0.01", "step = 0.01\norder = 3"),
       {"integrator.order", "2, 4, 6 or 8", "got 3", "composition"}},
      {"OrderString", "integrator.order = \"4\"", mutate("step = 0.01", "step = 0.01\norder = \"4\""),
       {"integrator.order", "integer"}},
      {"OrderForRk4", "order with rk4-normalized",
       mutate("method = \"lgvi\"", "method = \"rk4-normalized\"\norder = 4"),
       {"integrator.order", "rk4-normalized", "symmetric one-step"}},
      {"OrderForLagrangian", "order with the two-step lgvi-lagrangian",
       mutate("method = \"lgvi\"", "method = \"lgvi-lagrangian\"\norder = 4"),
       {"integrator.order", "lgvi-lagrangian", "symmetric one-step"}},
      {"CompositionForEuler", "composition with euler-exp",
       mutate("method = \"lgvi\"", "method = \"euler-exp\"\ncomposition = [0.5, 0.5]"),
       {"integrator.composition", "euler-exp", "symmetric one-step"}},
      {"OrderAndComposition", "both order and composition",
       mutate("step = 0.01", "step = 0.01\norder = 4\ncomposition = [0.5, 0.5]"),
       {"integrator.composition", "either order or composition"}},
      {"CompositionNotSummingToOne", "composition = [0.5, 0.6]",
       mutate("step = 0.01", "step = 0.01\ncomposition = [0.5, 0.6]"), {"integrator.composition", "sum to 1"}},
      {"CompositionNotPalindromic", "composition = [0.2, 0.3, 0.5]",
       mutate("step = 0.01", "step = 0.01\ncomposition = [0.2, 0.3, 0.5]"),
       {"integrator.composition", "palindromic", "gamma_1"}},
      {"CompositionNotArray", "composition = 1.0", mutate("step = 0.01", "step = 0.01\ncomposition = 1.0"),
       {"integrator.composition", "array"}},
      {"CompositionEntryString", "composition = [0.5, \"a\"]",
       mutate("step = 0.01", "step = 0.01\ncomposition = [0.5, \"a\"]"), {"integrator.composition[1]", "number"}},
      {"SolverGauss", "integrator.solver = \"gauss\"", mutate("solver = \"newton\"", "solver = \"gauss\""),
       {"integrator.solver", "gauss", "newton"}},
      {"ToleranceTooLarge", "tolerance = 0.01", mutate("step = 0.01", "step = 0.01\ntolerance = 0.01"),
       {"integrator.tolerance", "(0, 1e-3)"}},
      {"ToleranceZero", "tolerance = 0", mutate("step = 0.01", "step = 0.01\ntolerance = 0.0"),
       {"integrator.tolerance", "(0, 1e-3)"}},
      {"MaxIterationsZero", "max_iterations = 0", mutate("step = 0.01", "step = 0.01\nmax_iterations = 0"),
       {"integrator.max_iterations"}},
      {"MaxIterationsFraction", "max_iterations = 2.5", mutate("step = 0.01", "step = 0.01\nmax_iterations = 2.5"),
       {"integrator.max_iterations", "integer"}},

      // Initial state.
      {"MomentumAndVelocity", "both momentum and velocity",
       mutate("momentum = [0.0, 1.0, 0.0]", "momentum = [0.0, 1.0, 0.0]\nvelocity = [0.0, 1.0, 0.0]"),
       {"initial", "momentum", "velocity", "exactly one"}},
      {"NeitherMomentumNorVelocity", "neither momentum nor velocity", mutate("momentum = [0.0, 1.0, 0.0]\n", ""),
       {"initial", "momentum", "velocity", "exactly one"}},
      {"WAndOmega", "both w and omega", mutate("w = [1.0, 2.0, 3.0]", "w = [1.0, 2.0, 3.0]\nomega = [1, 1, 1]"),
       {"initial", "w = ", "omega", "exactly one"}},
      {"NeitherWNorOmega", "neither w nor omega", mutate("w = [1.0, 2.0, 3.0]\n", ""),
       {"initial", "w = ", "omega", "exactly one"}},
      {"VelocityWrongLength", "velocity = [1]",
       mutate("momentum = [0.0, 1.0, 0.0]", "velocity = [1]"), {"initial.velocity", "3 numbers"}},
      {"OmegaString", "omega = \"fast\"", mutate("w = [1.0, 2.0, 3.0]", "omega = \"fast\""),
       {"initial.omega", "array"}},

      // Body.
      {"MassAndBalls", "both mass + inertia and balls", mutate(base_body, base_body + triangle),
       {"body", "not both"}},
      {"BodyEmpty", "[body] with neither mass + inertia nor balls", mutate(base_body, "[body]\n"),
       {"body", "missing", "mass + inertia", "body.ball"}},
      {"MassWithoutInertia", "mass without inertia",
       mutate("inertia = [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.5]]\n", ""), {"body.inertia", "missing"}},
      {"InertiaWithoutMass", "inertia without mass", mutate("mass = 2.0\n", ""), {"body.mass", "missing"}},
      {"MassZero", "mass = 0", mutate("mass = 2.0", "mass = 0.0"), {"body.mass", "> 0"}},
      {"MassNegative", "mass = -2", mutate("mass = 2.0", "mass = -2.0"), {"body.mass", "> 0"}},
      {"InertiaNotSymmetric", "inertia not symmetric",
       mutate("[[1.0, 0.0, 0.0], [0.0, 2.0, 0.0]", "[[1.0, 0.1, 0.0], [0.0, 2.0, 0.0]"),
       {"body.inertia", "symmetric"}},
      {"InertiaNotPositiveDefinite", "inertia not positive definite", mutate("[0.0, 0.0, 2.5]]", "[0.0, 0.0, -2.5]]"),
       {"body.inertia", "positive semi-definite"}},
      {"InertiaTriangleInequality", "inertia diag(1, 1, 3) violates the triangle inequality",
       mutate("[[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.5]]", "[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 3.0]]"),
       {"body.inertia", "triangle inequality"}},
      {"InertiaTwoRows", "inertia with two rows",
       mutate("[[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.5]]", "[[1.0, 0.0, 0.0], [0.0, 2.0, 0.0]]"),
       {"body.inertia", "3 rows"}},
      {"InertiaShortRow", "inertia with a row of two",
       mutate("[[1.0, 0.0, 0.0], [0.0, 2.0, 0.0]", "[[1.0, 0.0, 0.0], [0.0, 2.0]"), {"body.inertia[1]", "3 numbers"}},
      {"InertiaNan", "inertia with nan", mutate("[0.0, 0.0, 2.5]]", "[0.0, 0.0, nan]]"),
       {"body.inertia[2][2]", "finite"}},
      {"LinearBodyWithAxialMomentum", "point balls on one line (a linear body) given w along the line",
       with_balls(ball_entry("[0, 0, 0]", "1.0", "0") + ball_entry("[1, 0, 0]", "1.0", "0") +
                  ball_entry("[2, 0, 0]", "1.0", "0")),
       {"initial.w", "a linear body", "no angular momentum about its axis"}},
      {"PointBallWithMomentum", "one ball of radius 0 (a point) given w", with_balls(ball_entry("[1, 2, 3]", "1.0", "0.0")),
       {"initial.w", "a point mass", "give w = 0"}},
      {"BallZeroMass", "second ball has mass 0",
       with_balls(ball_entry("[0, 0, 0]", "1.0", "0.1") + ball_entry("[1, 0, 0]", "0.0", "0.1")),
       {"body.ball[1].mass", "> 0"}},
      {"BallNegativeRadius", "ball with a negative radius", with_balls(ball_entry("[0, 0, 0]", "1.0", "-0.1")),
       {"body.ball[0].radius", ">= 0"}},
      {"BallMissingRadius", "ball without radius", with_balls("[[body.ball]]\nposition = [0, 0, 0]\nmass = 1.0\n"),
       {"body.ball[0].radius", "missing"}},
      {"BallPositionInf", "ball position inf", with_balls(ball_entry("[0, inf, 0]", "1.0", "0.1")),
       {"body.ball[0].position[1]", "finite"}},
      {"BallNotTables", "body.ball = [1, 2]", mutate(base_body, "[body]\nball = [1, 2]\n"),
       {"body.ball", "[[body.ball]]"}},
      {"BallEmptyArray", "body.ball = []", mutate(base_body, "[body]\nball = []\n"), {"body.ball"}},

      // Shapes and extents.
      {"ShapeWithoutDensityOrMass", "shape without density or mass",
       mutate(base_body, "[body]\nshape = \"sphere\"\nradius = 1.0\n"), {"key 'body'", "exactly one of density"}},
      {"ShapeWithDensityAndMass", "shape with density and mass",
       mutate(base_body, "[body]\nshape = \"sphere\"\nradius = 1.0\ndensity = 1.0\nmass = 2.0\n"),
       {"key 'body'", "exactly one of density"}},
      {"ShapeWithInertia", "shape with inertia", mutate("mass = 2.0", "shape = \"sphere\"\nradius = 1.0\nmass = 2.0"),
       {"body.inertia", "computed"}},
      {"ShapeUnknown", "shape = \"cube\"", mutate(base_body, "[body]\nshape = \"cube\"\nmass = 2.0\n"),
       {"body.shape", "cube", "\"ellipsoid\""}},
      {"SemiAxesNegative", "semi_axes with a negative number",
       mutate(base_body, "[body]\nshape = \"ellipsoid\"\nsemi_axes = [1.0, -1.0, 2.0]\ndensity = 1.0\n"),
       {"body.semi_axes", "3 numbers > 0"}},
      {"SemiAxesTwo", "semi_axes of two numbers",
       mutate(base_body, "[body]\nshape = \"ellipsoid\"\nsemi_axes = [1.0, 2.0]\ndensity = 1.0\n"),
       {"body.semi_axes", "3 numbers", "got 2"}},
      {"SphereWithSemiAxes", "a sphere given semi_axes",
       mutate(base_body, "[body]\nshape = \"sphere\"\nsemi_axes = [1.0, 1.0, 1.0]\ndensity = 1.0\n"),
       {"body.semi_axes", "ellipsoid", "radius"}},
      {"SphereInertiaUnderflows", "a sphere so small that m r^2 underflows",
       mutate(base_body, "[body]\nshape = \"sphere\"\nradius = 1e-170\nmass = 1.0\n"),
       {"body.radius", "no finite, positive-definite inertia", "units"}},
      {"DensityWithoutShape", "density with mass + inertia", mutate("mass = 2.0", "mass = 2.0\ndensity = 1"),
       {"body.density", "shape"}},
      {"RadiusZero", "mass + inertia with radius 0", mutate("mass = 2.0", "mass = 2.0\nradius = 0"),
       {"body.radius", "> 0"}},
      {"RadiusWithBalls", "a body of balls given a radius", with_balls("radius = 1.0\n" + triangle),
       {"body.radius", "bounded by its balls"}},
      {"OnContactForOneBody", "[run] on_contact in a single-body scenario", base_text + "[run]\non_contact = \"warn\"\n",
       {"run.on_contact", "[[bodies]]", "stop_at_contact"}},

      // Output.
      {"OutputEveryZero", "output.every = 0", mutate("every = 10", "every = 0"), {"output.every", ">= 1"}},
      {"OutputEveryNegative", "output.every = -3", mutate("every = 10", "every = -3"), {"output.every", ">= 1"}},
      {"OutputEveryFraction", "output.every = 1.5", mutate("every = 10", "every = 1.5"),
       {"output.every", "integer"}},
      {"OutputLayoutUnknown", "output.layout = \"wide\"", mutate("every = 10", "every = 10\nlayout = \"wide\""),
       {"output.layout", "\"wide\"", "\"single-body\", \"long\""}},

      // TOML syntax.
      {"DuplicateKey", "integrator.step given twice (toml++ parse error)", duplicate,
       {bad_name + ":" + std::to_string(line_of(duplicate, "step = 0.02")) + ":", "step"}},
      {"SyntaxError", "a value missing after '='", mutate("mu = 1.0", "mu = "),
       {bad_name + ":" + std::to_string(line_of(base_text, "mu = 1.0")) + ":"}},
      {"UnterminatedString", "unterminated string", mutate("kind = \"central\"", "kind = \"central"),
       {bad_name + ":" + std::to_string(line_of(base_text, "kind = \"central\"")) + ":"}},
      {"DuplicateTable", "[output] given twice", base_text + "[output]\nevery = 2\n", {bad_name + ":", "output"}},
  };
  return c;
}

class ScenarioBadInput : public testing::TestWithParam<BadCase> {};

TEST_P(ScenarioBadInput, ThrowsInvalidInputNamingTheKey) {
  const BadCase& c = GetParam();
  const std::string message = parse_error(c.text, bad_name);
  EXPECT_TRUE(is_good_message(message, bad_name, c.expected)) << c.description << "; scenario text:\n" << c.text;
}

INSTANTIATE_TEST_SUITE_P(Cases, ScenarioBadInput, testing::ValuesIn(bad_cases()),
                         [](const testing::TestParamInfo<BadCase>& info) { return info.param.id; });

// ---------------------------------------------------------------------------
// Files

TEST(ScenarioRead, FileWithNulBytesIsRejected) {
  const TempFile f("nul", base_text + std::string("# \0\0\0\n", 6));
  EXPECT_TRUE(is_good_message(read_error(f.path()), f.path(), {"NUL"}));
}

TEST(ScenarioRead, NonexistentPathIsRejected) {
  const std::string path = testing::TempDir() + "lgvi-no-such-folder/no-such-scenario.toml";
  EXPECT_TRUE(is_good_message(read_error(path), path, {"cannot open"}));
}

TEST(ScenarioRead, DirectoryIsRejected) {
  EXPECT_TRUE(is_good_message(read_error(scenario_dir), scenario_dir, {"directory"}));
}

TEST(ScenarioRead, ErrorsInAFileNameThePath) {
  const TempFile f("bad-step", mutate("step = 0.01", "step = 0"));
  EXPECT_TRUE(is_good_message(read_error(f.path()), f.path(), {"integrator.step"}));
  const TempFile g("bad-syntax", mutate("mu = 1.0", "mu = = 1"));
  EXPECT_TRUE(is_good_message(read_error(g.path()), g.path(),
                              {g.path() + ":" + std::to_string(line_of(base_text, "mu = 1.0")) + ":"}));
}

// ---------------------------------------------------------------------------
// Regression tests of bugs found in src/app/scenario.cpp (now fixed).

// Strings from the file are echoed unescaped: a TOML "\n" in a value or a key
// makes the message two lines.
TEST(ScenarioRegression, UserTextWithNewlineKeepsMessageOneLine) {
  EXPECT_TRUE(is_good_message(parse_error(mutate("kind = \"central\"", "kind = \"mag\\nnetic\""), bad_name), bad_name,
                              {"potential.kind"}));
  EXPECT_TRUE(is_good_message(parse_error("\"a\\nb\" = 1\n" + base_text, bad_name), bad_name, {"unknown key"}));
}

// read_body re-prefixes every message starting with "body" (meant for the
// library's "body.inertia: ..."), so for a file whose name starts with
// "body" its own messages get the file name twice.
TEST(ScenarioRegression, FileNamedBodyIsNamedOnce) {
  const std::string message = parse_error(mutate(base_body, "[body]\n"), "body.toml");
  EXPECT_TRUE(is_good_message(message, "body.toml", {"key 'body'"}));
  EXPECT_EQ(message.find("body.toml: body.toml"), std::string::npos) << message;
}

// p = m v and w = 2 J Omega can overflow to inf from finite input; the reader
// accepts the state and the run then fails at step 0 (exit status 1, "try a
// smaller step") instead of exit status 2 naming the key.
TEST(ScenarioRegression, OverflowingVelocityOrOmegaIsRejected) {
  EXPECT_TRUE(is_good_message(
      parse_error(mutate("momentum = [0.0, 1.0, 0.0]", "velocity = [1e308, 0.0, 0.0]"), bad_name), bad_name,
      {"initial.velocity"}));
  EXPECT_TRUE(is_good_message(parse_error(mutate("w = [1.0, 2.0, 3.0]", "omega = [1e308, 1e308, 1e308]"), bad_name),
                              bad_name, {"initial.omega"}));
}

TEST(ScenarioRead, ValidFileTakesItsStemAsName) {
  const TempFile f("valid", base_text);
  const Scenario s = read_scenario(f.path());
  EXPECT_EQ(s.name, std::filesystem::path(f.path()).stem().string());
  EXPECT_EQ(s.integrator.steps, 100);
}

}  // namespace

namespace {

TEST(ScenarioInput, StepWhoseRotationReachesPiIsRejected) {
  // |Omega0| h with Omega0 = J^{-1} w / 2: w = (1, 2, 3), J = diag(1, 2, 2.5)
  // gives Omega0 = (0.5, 0.5, 0.6), |Omega0| = 0.927; a step of 4 rotates 3.7 rad > pi.
  const std::string message = parse_error(mutate("step = 0.01", "step = 4.0"), "s.toml");
  EXPECT_NE(message.find("integrator.step"), std::string::npos) << message;
  EXPECT_NE(message.find("reaches pi"), std::string::npos) << message;
  // Just below pi it is accepted (the run itself then reports a step without a root).
  EXPECT_NO_THROW(lgvi::app::parse_scenario(mutate("step = 0.01", "step = 3.0"), "ok.toml"));
}

}  // namespace

namespace {

TEST(ScenarioRegression, FuzzFindingsAreCleanErrors) {
  // Every input libFuzzer found a crash with (fuzz/regressions/) now reads as
  // one clean line naming the file, or as a valid scenario.
  int files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(LGVI_FUZZ_REGRESSIONS_DIR)) {
    ++files;
    const std::string path = entry.path().string();
    try {
      lgvi::app::read_scenario(path);
    } catch (const lgvi::InvalidInput& e) {
      const std::string m = e.what();
      EXPECT_EQ(m.find('\n'), std::string::npos) << m;
      EXPECT_EQ(m.rfind(path, 0), 0u) << m;
    }
  }
  EXPECT_GE(files, 2);
}

TEST(ScenarioRegression, NonAsciiOutsideCommentsIsRejectedBeforeToml) {
  // toml++ 3.3.0 has undefined behaviour on e.g. U+0429 after a number.
  const std::string m = parse_error(mutate("step = 0.01", "step = 0.01\xd0\xa9"), "u.toml");
  EXPECT_NE(m.find("u.toml:18:"), std::string::npos) << m;
  EXPECT_NE(m.find("non-ASCII"), std::string::npos) << m;
  // In comments they are welcome; a '#' inside a string does not start one.
  EXPECT_NO_THROW(lgvi::app::parse_scenario(mutate("step = 0.01", "step = 0.01  # \xce\xbc = 1, h = 0.01"), "c.toml"));
  EXPECT_NE(parse_error(mutate("kind = \"central\"", "kind = \"cen#tral\xce\xbc\""), "s.toml").find("non-ASCII"),
            std::string::npos);
}

}  // namespace

namespace {

TEST(ScenarioInput, PhysicalFalseWaivesOnlyTheTriangleInequality) {
  const std::string hlw = "inertia = [[2.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.6666666666666666]]";
  const std::string from = "inertia = [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.5]]";
  EXPECT_NE(parse_error(mutate(from, hlw), "h.toml").find("triangle inequality"), std::string::npos);
  EXPECT_NO_THROW(lgvi::app::parse_scenario(mutate(from, hlw + "\nphysical = false"), "h.toml"));
  // Still symmetric positive semi-definite, whatever `physical` says.
  EXPECT_NE(parse_error(mutate(from, "inertia = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]]\nphysical = false"),
                        "h.toml")
                .find("positive semi-definite"),
            std::string::npos);
  EXPECT_NE(parse_error(mutate(from, from + "\nphysical = 1"), "h.toml").find("body.physical"), std::string::npos);
}

}  // namespace

namespace {

TEST(ScenarioInput, HugeNumberOfBallsIsRejected) {
  // More than 100000 [[body.ball]] entries: one line asking for mass + inertia instead.
  std::string text = "[potential]\nkind = \"none\"\n[initial]\nposition = [0,0,0]\nquaternion = [1,0,0,0]\n"
                     "momentum = [0,0,0]\nw = [0,0,0]\n[integrator]\nstep = 0.1\nduration = 1.0\n[body]\n";
  for (int i = 0; i <= 100000; ++i) text += "[[body.ball]]\nposition = [0,0,0]\nmass = 1\nradius = 1\n";
  const std::string m = parse_error(text, "many.toml");
  EXPECT_NE(m.find("body.ball"), std::string::npos) << m.substr(0, 200);
  EXPECT_NE(m.find("more than 100000 balls"), std::string::npos) << m.substr(0, 200);
}

}  // namespace

// [import] lammps_data: identical molecules share one kind (lammps_data.cpp, KindMatcher), as the bodies
// of a [[bodies]] block do. Three triangles turned three ways, a fourth with one atom moved by 1e-7 (its
// own kind), two linear molecules turned two ways and two single atoms make 8 bodies of 4 kinds; every
// body still puts its atoms where the file does (x + R(q) p_i, to 1e-14 of the coordinates, from the
// kind's positions and the attitude turned by the fit) and has the angular momentum of its atoms' rigid
// projection, sum m (r - c) x v (to 1e-14).
TEST(ImportedKinds, IdenticalMoleculesShareAKindAndKeepTheirAtomsAndMomenta) {
  using V3 = lgvi::Vector3<double>;
  struct Atom {
    int molecule, type;
    V3 x, v;
  };
  const V3 triangle[] = {V3(0.0, 0.0, 0.0), V3(1.0, 0.0, 0.0), V3(0.3, 0.8, 0.0)};
  const V3 line[] = {V3(0.0, 0.0, 0.0), V3(1.1, 0.0, 0.0)};
  const lgvi::S3d turns[] = {lgvi::S3d(1.0, 0.0, 0.0, 0.0), lgvi::S3d(0.5, 0.5, -0.5, 0.5),
                             lgvi::S3d(std::cos(0.4), 0.0, std::sin(0.4) * 0.6, std::sin(0.4) * 0.8)};
  std::vector<Atom> atoms;
  auto velocity = [&] {  // a different, non-rigid velocity per atom
    const double k = static_cast<double>(atoms.size());
    return V3(0.1 * std::sin(k), 0.2 * std::cos(1.3 * k), -0.05 * k);
  };
  for (int m = 0; m < 4; ++m)
    for (int i = 0; i < 3; ++i) {
      V3 p = turns[m % 3].act(triangle[i]) + V3(4.0 * m, 0.0, 0.0);
      if (m == 3 && i == 2) p.y() += 1e-7;
      atoms.push_back({m + 1, i == 2 ? 2 : 1, p, velocity()});
    }
  for (int m = 0; m < 2; ++m)
    for (int i = 0; i < 2; ++i)
      atoms.push_back({5 + m, i + 1, turns[m + 1].act(line[i]) + V3(4.0 * m, 5.0, 0.0), velocity()});
  for (int m = 0; m < 2; ++m) atoms.push_back({0, 1, V3(4.0 * m, -5.0, 1.0), velocity()});
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("lgvi-test-kinds-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  {
    std::ofstream data(dir / "kinds.data");
    data << "kinds\n\n" << atoms.size() << " atoms\n2 atom types\n-10.0 30.0 xlo xhi\n-10.0 30.0 ylo yhi\n"
         << "-10.0 30.0 zlo zhi\n\nMasses\n\n1 1.0\n2 3.0\n\nAtoms # molecular\n\n";
    for (std::size_t i = 0; i < atoms.size(); ++i)
      data << fmt::format("{} {} {} {:.17g} {:.17g} {:.17g}\n", i + 1, atoms[i].molecule, atoms[i].type,
                          atoms[i].x.x(), atoms[i].x.y(), atoms[i].x.z());
    data << "\nVelocities\n\n";
    for (std::size_t i = 0; i < atoms.size(); ++i)
      data << fmt::format("{} {:.17g} {:.17g} {:.17g}\n", i + 1, atoms[i].v.x(), atoms[i].v.y(), atoms[i].v.z());
  }
  const Scenario sc = parse_scenario(
      "[import]\nlammps_data = \"kinds.data\"\nperiodic = [false, false, false]\n[potential]\nkind = \"none\"\n"
      "[integrator]\nstep = 0.001\nduration = 0.01\n",
      (dir / "kinds.toml").string());
  std::filesystem::remove_all(dir);
  ASSERT_EQ(sc.bodies(), 8u);
  EXPECT_EQ(sc.system.kinds(), 4u);
  // The bodies in the file's order: molecules 1-6, then the atoms of molecule 0.
  std::size_t next = 0;
  for (std::size_t a = 0; a < sc.bodies(); ++a) {
    const lgvi::RigidBody& body = sc.system.body(a);
    const lgvi::S3d& q = sc.initial_state.q[a];
    EXPECT_NEAR(q.quaternion().norm(), 1.0, 4e-16);
    V3 l = V3::Zero();
    for (const lgvi::Ball& ball : body.balls()) {
      const Atom& atom = atoms[next++];
      EXPECT_LT((sc.initial_state.x[a] + q.act(ball.position) - atom.x).norm(), 1e-14 * 20.0) << "body " << a;
      l += ball.mass * (atom.x - sc.initial_state.x[a]).cross(atom.v);
    }
    EXPECT_LT((q.act(0.5 * sc.initial_state.w[a]) - l).norm(), 1e-14) << "body " << a;
  }
  EXPECT_EQ(next, atoms.size());
}

}  // namespace test_scenario
