// libFuzzer target: the scenario reader and the run it describes (what
// `lgvi run` does with a file), on arbitrary bytes.
//
// Contract checked: any input either is rejected with lgvi::InvalidInput (one
// line, starting with the file name; or, from the run, one line before the
// trajectory is opened), or runs (at most 200 steps, and at most
// 20000 site-steps for many bodies, to bound the time per input) to completion or to a reported IntegrationFailure
// whose rows are all finite. Any other exception, crash, sanitizer report or
// hang is a finding; each becomes a file in fuzz/regressions/.
#include "app/scenario.hpp"
#include "app/simulation.hpp"

#include <lgvi/error.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>

namespace {

struct CheckingSink final : lgvi::app::TrajectorySink {
  explicit CheckingSink(int columns) : columns_(columns) {}
  void row(const double* v) override {
    for (int i = 0; i < columns_; ++i)
      if (!std::isfinite(v[i])) std::abort();  // a non-finite row must never be written
  }
  lgvi::app::SinkPosition sync() override { return {}; }
  void close(const std::string&, const std::string&) override {}
  int columns_;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  lgvi::app::Scenario scenario = [&] {
    try {
      return std::optional(lgvi::app::parse_scenario(text, "fuzz.toml"));
    } catch (const lgvi::InvalidInput& e) {
      const std::string m = e.what();
      if (m.find('\n') != std::string::npos || m.rfind("fuzz.toml", 0) != 0) std::abort();
      return std::optional<lgvi::app::Scenario>();
    }
  }()
                                           .value_or(lgvi::app::parse_scenario(
                                               "[body]\nmass = 1.0\ninertia = [[1,0,0],[0,1,0],[0,0,1]]\n"
                                               "[potential]\nkind = \"none\"\n[initial]\nposition = [0,0,0]\n"
                                               "quaternion = [1,0,0,0]\nmomentum = [0,0,0]\nw = [0,0,0]\n"
                                               "[integrator]\nstep = 0.1\nduration = 0.0\n",
                                               "fallback.toml"));
  std::int64_t sites = 0;
  for (const lgvi::RigidBody& b : lgvi::system_bodies(scenario.system))
    sites += std::max<std::int64_t>(1, static_cast<std::int64_t>(b.balls().size()));
  scenario.integrator.steps =
      std::min<std::int64_t>({scenario.integrator.steps, 200, std::max<std::int64_t>(1, 20000 / sites)});
  scenario.threads = 1;
  CheckingSink sink(lgvi::app::scenario_layout(scenario).columns);
  bool opened = false;
  const lgvi::app::SinkOpener open_sink = [&]() -> lgvi::app::TrajectorySink& {
    opened = true;
    return sink;
  };
  try {
    const lgvi::app::SimulationResult r = lgvi::app::simulate(scenario, open_sink, {});
    if (!r.completed && r.error.empty()) std::abort();  // a failure must say why
  } catch (const lgvi::InvalidInput& e) {
    // Refused at the initial state before the trajectory is opened (an
    // adaptive step with V = 0 there and no monitor_scale): one line, as the
    // reader's. After it is opened, a refusal would leave a half-written run.
    const std::string m = e.what();
    if (opened || m.empty() || m.find('\n') != std::string::npos) std::abort();
  }
  return 0;
}
