// The ensemble plan (ensemble.hpp): members' values from (seed, index)
// alone, grids in product order, the member scenarios written back exactly,
// and the refusal of a build without MPI started as several ranks.
#include "app/ensemble.hpp"

#include <lgvi/error.hpp>

#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

namespace test_ensemble {

namespace {

using lgvi::app::EnsemblePlan;

const std::string base = R"([body]
mass = 1.0
inertia = [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]
[potential]
kind = "central"
mu = 1.0
[initial]
position = [8.0, 0.0, 0.0]
quaternion = [1.0, 0.0, 0.0, 0.0]
momentum = [0.0, 0.35, 0.0]
omega = [0.1, 0.2, 0.3]
[integrator]
step = 0.01
duration = 0.1
)";

EnsemblePlan plan(const std::string& vary, const std::string& head = "members = 50\nseed = 11\n") {
  return lgvi::app::parse_ensemble_text("[ensemble]\nscenario = \"base.toml\"\n" + head + vary, "sweep.toml", base);
}

TEST(EnsemblePlan, DrawsDependOnSeedAndIndexOnly) {
  const std::string vary = "[[vary]]\nkey = \"initial.omega\"\nnormal = { mean = [0.1, 0.2, 0.3], std = [0.01, 0.01, 0.01] }\n";
  const EnsemblePlan a = plan(vary);
  const EnsemblePlan more = plan(vary, "members = 80\nseed = 11\n");  // a longer ensemble: the first 50 agree
  const EnsemblePlan other = plan(vary, "members = 50\nseed = 12\n");
  ASSERT_EQ(a.members(), 50);
  for (std::int64_t i = 0; i < 50; ++i) {
    EXPECT_EQ(a.varied[static_cast<std::size_t>(i)], more.varied[static_cast<std::size_t>(i)]);
    EXPECT_NE(a.varied[static_cast<std::size_t>(i)][0], other.varied[static_cast<std::size_t>(i)][0]);
  }
  // Components and members draw independently: no two values repeat.
  EXPECT_NE(a.varied[0][0], a.varied[0][1]);
  EXPECT_NE(a.varied[0][0], a.varied[1][0]);
}

TEST(EnsemblePlan, GridsAreTheProductWithTheLastKeyFastest) {
  const EnsemblePlan p = plan("[[vary]]\nkey = \"integrator.step\"\nvalues = [0.01, 0.02]\n"
                              "[[vary]]\nkey = \"potential.mu\"\nvalues = [1.0, 2.0, 3.0]\n",
                              "");
  ASSERT_EQ(p.members(), 6);
  EXPECT_EQ(p.varied[0], (std::vector<double>{0.01, 1.0}));
  EXPECT_EQ(p.varied[2], (std::vector<double>{0.01, 3.0}));
  EXPECT_EQ(p.varied[3], (std::vector<double>{0.02, 1.0}));
  EXPECT_EQ(p.header.substr(0, 43), "index,integrator.step,potential.mu,complete");
}

TEST(EnsemblePlan, MemberScenarioHoldsTheDrawnValuesExactly) {
  // The member's TOML text carries each double with 17 digits: read back, the
  // scenario has the drawn value bit for bit.
  const EnsemblePlan p = plan("[[vary]]\nkey = \"initial.position\"\nuniform = { low = [7.0, -1.0, 0.0], high = [9.0, 1.0, 0.0] }\n");
  for (std::int64_t i : {0, 17, 49}) {
    const lgvi::app::Scenario sc = lgvi::app::parse_scenario(p.member_toml(i), "m");
    for (int c = 0; c < 3; ++c) EXPECT_EQ(sc.initial().x(c), p.varied[static_cast<std::size_t>(i)][static_cast<std::size_t>(c)]);
  }
}

TEST(EnsemblePlan, BundledSweepsAreValid) {
  // Every member of the bundled sweeps passes the scenario reader.
  const std::string dir = std::string(LGVI_SCENARIO_DIR) + "/ensembles/";
  EXPECT_EQ(lgvi::app::read_ensemble(dir + "paper-orbit-attitudes.toml").members(), 256);
  const EnsemblePlan ladder = lgvi::app::read_ensemble(dir + "step-ladder.toml");
  ASSERT_EQ(ladder.members(), 20);
  EXPECT_EQ(lgvi::app::parse_scenario(ladder.member_toml(19), "m").integrator.composition.order(), 8);
}

TEST(EnsembleMpi, ABuildWithoutMpiStartedAsSeveralRanksRefusesToRun) {
  // lgvi_tests links no MPI runner: started as one of 2 ranks it must say so
  // rather than run the whole ensemble once per rank.
  ::setenv("OMPI_COMM_WORLD_SIZE", "2", 1);
  try {
    lgvi::app::run_ensemble("does-not-matter.toml", {});
    ADD_FAILURE() << "ran";
  } catch (const lgvi::InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("built without MPI"), std::string::npos) << e.what();
  }
  ::unsetenv("OMPI_COMM_WORLD_SIZE");
}

}  // namespace

}  // namespace test_ensemble
