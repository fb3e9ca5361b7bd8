// `lgvi run`: integrate a scenario into a run folder (trajectory, summary,
// scenario copy, figures, checkpoints), stopping cleanly on SIGINT/SIGTERM
// and resuming from a checkpoint.
#pragma once

#include "app/scenario.hpp"

#include <cstdint>
#include <string>

namespace lgvi::app {

struct RunOptions {
  std::string out_dir;             ///< output folder (created if missing)
  bool figures = true;             ///< draw the PNG figures with matplotlib
  bool quiet = false;              ///< no summary line, no progress line
  std::int64_t checkpoint_every = 0;  ///< write DIR/checkpoint.bin every N steps (0: never)
  int threads = 0;                    ///< --threads (0: the scenario's [run] threads, else all cores)
  bool view = false;                  ///< write DIR/view.html at the end (lgvi view)
  bool force = false;                 ///< --force: write into an existing non-empty output folder
};

struct ViewOptions {
  bool open = false;           ///< open the page in the default browser (xdg-open) where there is a display
  std::string movie;           ///< also render this movie (.mp4 or .gif): headless chromium + ffmpeg
  double movie_seconds = 0;    ///< its length (0: lgvi.viewer's default, 10 s)
  int max_frames = 0;          ///< frames embedded at most (0: lgvi.viewer's default, 2000)
  bool quiet = false;          ///< print nothing on success
};

/// Exit statuses of `lgvi run`.
enum ExitStatus : int {
  kSuccess = 0,
  kRunFailed = 1,
  kBadInput = 2,
  kInterruptedSigint = 130,
  kInterruptedSigterm = 143
};

/// Throws InvalidInput (one line naming --force) if `dir` exists and is not an empty folder, unless `force`:
/// `lgvi run` and `lgvi compare` do not overwrite an earlier run's files by accident.
void require_new_output_folder(const std::string& dir, bool force);

/// Runs the scenario; prints errors on stderr; returns the exit status. The
/// run starts from the scenario's initial state itself (moved, not copied:
/// one state of N bodies less to hold).
int run_scenario(Scenario scenario, const RunOptions& options);

/// Continues the run in `dir` from its checkpoint (DIR/checkpoint.bin, with
/// the scenario copy DIR/scenario.toml), appending to its trajectory.
int resume_run(const std::string& dir, RunOptions options);

/// Draws the figures of a finished run folder with `lgvi.plot` (Python,
/// matplotlib). Throws std::runtime_error if the plotting process fails.
void draw_figures(const std::string& run_dir);

/// Draws the figures of `lgvi compare` in `dir` with `lgvi.compare_plot`.
void draw_compare_figures(const std::string& dir);

/// `lgvi view`: writes RUN_DIR/view.html, the interactive 3-D view, with `lgvi.viewer` (Python, the same
/// code as lgvi.view()). Returns the exit status: 0, 2 for bad input (lgvi.viewer printed one line), 1 else.
int write_view(const std::string& run_dir, const ViewOptions& options);

}  // namespace lgvi::app
