// The lgvi command-line tool.
#include "run.hpp"
#include "scenario.hpp"

#include <lgvi/error.hpp>

#include <CLI/CLI.hpp>

#include <iostream>

int main(int argc, char** argv) {
  CLI::App app{"lgvi: rigid-body simulation with the quaternion Lie group variational integrator (Shen & Leok)"};
  app.set_version_flag("--version", std::string("lgvi ") + LGVI_VERSION);
  app.require_subcommand(1);
  app.footer("Example:\n  lgvi run scenarios/paper-orbit.toml --out results/paper-orbit");

  auto* run = app.add_subcommand("run", "Integrate a scenario file; write trajectory.csv, summary.json and figures");
  std::string scenario_path;
  lgvi::app::RunOptions options;
  bool no_figures = false;
  run->add_option("SCENARIO", scenario_path, "Scenario file (TOML), see README 'Scenario files'")->required();
  run->add_option("--out", options.out_dir, "Output folder (default: a folder named after the scenario)");
  run->add_flag("--no-figures", no_figures, "Do not draw the PNG figures");
  run->add_flag("-q,--quiet", options.quiet, "Print nothing on success");
  run->footer("Example:\n  lgvi run scenarios/paper.toml --out results/paper\nExit status: 0 success, 1 the run "
              "failed (the error names the step), 2 bad usage or bad input");

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // One line, like every other error; --help has the details.
    std::cerr << "lgvi: error: " << e.what() << " (see lgvi --help or lgvi run --help)\n";
    return lgvi::app::kBadInput;
  }
  options.figures = !no_figures;
  try {
    const lgvi::app::Scenario scenario = lgvi::app::read_scenario(scenario_path);
    return lgvi::app::run_scenario(scenario, options);
  } catch (const lgvi::InvalidInput& e) {
    std::cerr << "lgvi: error: " << e.what() << "\n";
    return lgvi::app::kBadInput;
  } catch (const std::exception& e) {
    std::cerr << "lgvi: error: " << e.what() << "\n";
    return lgvi::app::kRunFailed;
  }
}
