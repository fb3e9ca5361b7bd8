// The lgvi command-line tool: the parser, its commands (cli/command.hpp, one
// file each) and the one place their errors become one line and an exit status.
#include "app/run.hpp"
#include "cli/command.hpp"

#include <lgvi/error.hpp>

#include <CLI/CLI.hpp>

#include <iostream>
#include <string>
#include <vector>

namespace {
int run_cli(int argc, char** argv) {
  CLI::App app{"lgvi: rigid-body simulation with the quaternion Lie group variational integrator (Shen & Leok)"};
  app.set_version_flag("--version", std::string("lgvi ") + LGVI_VERSION);
  app.require_subcommand(1);
  app.footer("Example:\n  lgvi run scenarios/paper-orbit.toml --out results/paper-orbit");
  const std::vector<lgvi::cli::Command> commands{
      lgvi::cli::add_run_command(app),  lgvi::cli::add_compare_command(app), lgvi::cli::add_ensemble_command(app),
      lgvi::cli::add_view_command(app), lgvi::cli::add_show_command(app)};

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
  try {
    for (const lgvi::cli::Command& command : commands)
      if (command.subcommand->parsed()) return command.action();
    throw CLI::RequiredError("a command");  // (require_subcommand(1): not reached)
  } catch (const CLI::Error& e) {
    std::cerr << "lgvi: error: " << e.what() << " (see lgvi run --help)\n";
    return lgvi::app::kBadInput;
  } catch (const lgvi::InvalidInput& e) {
    std::cerr << "lgvi: error: " << e.what() << "\n";
    return lgvi::app::kBadInput;
  } catch (const std::exception& e) {
    std::cerr << "lgvi: error: " << e.what() << "\n";
    return lgvi::app::kRunFailed;
  }
}
}  // namespace

int main(int argc, char** argv) {
  // Nothing escapes main: an unexpected exception is still one line and status 1.
  try {
    return run_cli(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "lgvi: error: " << e.what() << "\n";
  } catch (...) {
    std::cerr << "lgvi: error: unknown failure\n";
  }
  return 1;
}
