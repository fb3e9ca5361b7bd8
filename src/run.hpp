// `lgvi run`: integrate a scenario into a run folder (trajectory, summary,
// scenario copy, figures, checkpoints), stopping cleanly on SIGINT/SIGTERM
// and resuming from a checkpoint.
#pragma once

#include "scenario.hpp"

#include <cstdint>
#include <string>

namespace lgvi::app {

struct RunOptions {
  std::string out_dir;             ///< output folder (created if missing)
  bool figures = true;             ///< draw the PNG figures with matplotlib
  bool quiet = false;              ///< no summary line, no progress line
  std::int64_t checkpoint_every = 0;  ///< write DIR/checkpoint.bin every N steps (0: never)
  int threads = 0;                    ///< --threads (0: the scenario's [run] threads, else all cores)
};

/// Exit statuses of `lgvi run`.
enum ExitStatus : int {
  kSuccess = 0,
  kRunFailed = 1,
  kBadInput = 2,
  kInterruptedSigint = 130,
  kInterruptedSigterm = 143
};

/// Runs the scenario; prints errors on stderr; returns the exit status.
int run_scenario(const Scenario& scenario, const RunOptions& options);

/// Continues the run in `dir` from its checkpoint (DIR/checkpoint.bin, with
/// the scenario copy DIR/scenario.toml), appending to its trajectory.
int resume_run(const std::string& dir, RunOptions options);

/// Draws the figures of a finished run folder with `lgvi.plot` (Python,
/// matplotlib). Throws std::runtime_error if the plotting process fails.
void draw_figures(const std::string& run_dir);

/// Draws the figures of `lgvi compare` in `dir` with `lgvi.compare_plot`.
void draw_compare_figures(const std::string& dir);

}  // namespace lgvi::app
