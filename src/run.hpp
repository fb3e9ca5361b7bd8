// `lgvi run`: integrate a scenario, write trajectory.csv, summary.json and figures.
#pragma once

#include "scenario.hpp"

#include <string>

namespace lgvi::app {

struct RunOptions {
  std::string out_dir;      ///< output folder (created if missing)
  bool figures = true;      ///< draw the PNG figures with matplotlib
  bool quiet = false;       ///< no summary line on standard output
};

/// Exit statuses of `lgvi run`.
enum ExitStatus : int { kSuccess = 0, kRunFailed = 1, kBadInput = 2 };

/// Runs the scenario; prints errors on stderr; returns the exit status.
int run_scenario(const Scenario& scenario, const RunOptions& options);

/// Draws the figures of a finished run folder with `lgvi.plot` (Python,
/// matplotlib). Throws std::runtime_error if the plotting process fails.
void draw_figures(const std::string& run_dir);

}  // namespace lgvi::app
