// The commands of the lgvi tool, one file each (cli/NAME_command.cpp): a
// command adds its subcommand (options, help, examples) to the parser and
// returns what to do when it is the one given. main.cpp lists them, in the
// order `lgvi --help` shows them, and reports their errors.
#pragma once

#include <CLI/CLI.hpp>

#include <functional>

namespace lgvi::cli {

/// A parsed command's action: returns the exit status (app::ExitStatus).
/// Bad input throws lgvi::InvalidInput or CLI::Error (one line, status 2);
/// any other exception is a failed run (one line, status 1).
using CommandAction = std::function<int()>;

/// A subcommand of the parser and its action.
struct Command {
  CLI::App* subcommand = nullptr;
  CommandAction action;
};

Command add_run_command(CLI::App& parser);       ///< lgvi run SCENARIO | --resume DIR
Command add_compare_command(CLI::App& parser);   ///< lgvi compare SCENARIO --methods ...
Command add_ensemble_command(CLI::App& parser);  ///< lgvi ensemble SWEEP | --resume DIR
Command add_view_command(CLI::App& parser);      ///< lgvi view RUN_DIR
Command add_show_command(CLI::App& parser);      ///< lgvi show DIR

}  // namespace lgvi::cli
