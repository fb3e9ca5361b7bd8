// The lgvi command-line tool.
#include "run.hpp"
#include "scenario.hpp"
#include "show.hpp"
#include "compare.hpp"
#include "ensemble.hpp"

#include <sstream>

#include <lgvi/error.hpp>

#include <CLI/CLI.hpp>

#include <filesystem>
#include <iostream>

namespace {
int run_cli(int argc, char** argv) {
  CLI::App app{"lgvi: rigid-body simulation with the quaternion Lie group variational integrator (Shen & Leok)"};
  app.set_version_flag("--version", std::string("lgvi ") + LGVI_VERSION);
  app.require_subcommand(1);
  app.footer("Example:\n  lgvi run scenarios/paper-orbit.toml --out results/paper-orbit");

  auto* run = app.add_subcommand("run", "Integrate a scenario file; write trajectory.csv, summary.json and figures");
  std::string scenario_path;
  lgvi::app::RunOptions options;
  bool no_figures = false;
  std::string resume_dir;
  auto* scenario_opt = run->add_option("SCENARIO", scenario_path, "Scenario file (TOML), see docs/guide/scenario-files.md");
  auto* resume_opt =
      run->add_option("--resume", resume_dir, "Continue the interrupted run in this folder from its checkpoint");
  scenario_opt->excludes(resume_opt);
  run->add_option("--out", options.out_dir,
                  "Output folder (default: a folder named after the scenario); it must not exist or be empty, "
                  "unless --force")
      ->excludes(resume_opt);
  run->add_flag("--force", options.force,
                "Write into an existing non-empty output folder, overwriting the files this run writes (others "
                "stay)")
      ->excludes(resume_opt);
  run->add_option("--checkpoint-every", options.checkpoint_every,
                  "Write the full state to DIR/checkpoint.bin every N steps (and on SIGINT/SIGTERM)")
      ->check(CLI::NonNegativeNumber);
  int threads = 0;
  run->add_option("--threads", threads,
                  "Threads for the per-body loops of many-body runs (default: [run] threads, else all cores); "
                  "results do not depend on it")
      ->check(CLI::Range(1, 1024));
  run->add_flag("--no-figures", no_figures, "Do not draw the PNG figures");
  run->add_flag("--view", options.view, "Also write DIR/view.html, the interactive 3-D view (lgvi view)");
  run->add_flag("-q,--quiet", options.quiet, "Print nothing on success");
  run->footer(
      lgvi::app::method_table() +
      "Examples:\n  lgvi run scenarios/paper.toml --out results/paper\n"
      "  lgvi run long.toml --checkpoint-every 100000   # then, after Ctrl-C: lgvi run --resume long\n"
      "Exit status: 0 success, 1 the run failed (the error names the step), 2 bad usage or bad input,\n"
      "130/143 stopped by SIGINT/SIGTERM (the files are valid up to the last step; summary.json says so)");

  auto* compare = app.add_subcommand(
      "compare", "Compare integration methods on a scenario: work-precision, long-time behaviour, tables, figures");
  std::string compare_scenario, compare_methods_list = "lgvi,lgvi-lagrangian";
  lgvi::app::CompareOptions compare_options;
  bool compare_no_figures = false;
  compare->add_option("SCENARIO", compare_scenario, "Scenario file (TOML)")->required();
  auto* compare_methods_opt = compare->add_option(
      "--methods", compare_methods_list,
      "Comma-separated methods (see docs/guide/compare.md); NAME:ORDER composes a symmetric one-step method to "
      "order 4, 6 or 8 (e.g. lgvi:4); lgvi+tt, lgvi:ORDER+tt the adaptive LGVI (time_transform). Default: "
      "lgvi,lgvi-lagrangian; for a scenario with time_transform, its adaptive step and the fixed one at its order "
      "(e.g. lgvi:4+tt,lgvi:4)");
  compare->add_option("--out", compare_options.out_dir,
                      "Output folder (default: NAME-compare, NAME the scenario's name); it must not exist or be "
                      "empty, unless --force");
  compare->add_flag("--force", compare_options.force,
                    "Write into an existing non-empty output folder, overwriting the comparison's files");
  compare->add_option("--timing-budget", compare_options.timing_budget,
                      "Seconds of repeated runs per timed point: after an untimed first run, each work-precision "
                      "run is repeated until the repeats add up to this, at least 3 times; medians and quartiles "
                      "are reported (default 0.2; the errors do not depend on it)");
  compare->add_option("--ladder", compare_options.ladder, "Number of step sizes h, h/2, ... (default 5)");
  compare->add_option("--ladder-from", compare_options.ladder_from,
                      "Largest step of the ladder (default: the scenario's step; higher orders pay off at larger "
                      "steps). The long runs keep the scenario's step");
  compare->add_option("--error-time", compare_options.error_time,
                      "Time of the work-precision runs (default: min(duration, 1e4 h))");
  compare->add_option("--long-steps", compare_options.long_steps,
                      "Length of the equal-cost long runs, in steps of h (default 1e6)");
  compare->add_flag("--no-figures", compare_no_figures, "Do not draw the PNG figures");
  compare->add_flag("-q,--quiet", compare_options.quiet, "Print nothing on success");
  compare->footer(lgvi::app::method_table() +
                  "Example:\n  lgvi compare scenarios/free-body-manchester-peck.toml --methods "
                  "lgvi,so3-lgvi,rk4-normalized --out results/compare");

  auto* ensemble = app.add_subcommand(
      "ensemble", "Run many members of a scenario with varied numbers (sweeps, Monte Carlo) on threads or MPI ranks");
  std::string ensemble_sweep;
  lgvi::app::EnsembleOptions ensemble_options;
  std::string ensemble_resume;
  auto* sweep_opt = ensemble->add_option("SWEEP", ensemble_sweep, "Sweep file (TOML), see docs/guide/ensembles.md");
  auto* ensemble_resume_opt =
      ensemble->add_option("--resume", ensemble_resume, "Run the members of this ensemble folder that have no row yet");
  sweep_opt->excludes(ensemble_resume_opt);
  ensemble->add_option("--out", ensemble_options.out_dir, "Output folder (default: a folder named after the sweep)")
      ->excludes(ensemble_resume_opt);
  ensemble->add_option("--threads", ensemble_options.threads,
                       "Members run at once (default: all cores; under mpirun, per rank, default 1)")
      ->check(CLI::Range(1, 1024));
  ensemble->add_flag("-q,--quiet", ensemble_options.quiet, "Print nothing on success");
  ensemble->add_flag("--progress", ensemble_options.progress,
                     "Show the progress line even where stderr is not a terminal (under mpirun: a pipe)");
  bool ensemble_no_figures = false;
  ensemble->add_flag("--no-figures", ensemble_no_figures,
                     "Do not draw error_distribution.png and error_vs_varied.png");
  ensemble->footer(
      "Examples:\n  lgvi ensemble sweep.toml --out results/sweep --threads 2\n"
      "  mpirun -n 4 lgvi ensemble sweep.toml --out results/sweep\n"
      "  lgvi ensemble --resume results/sweep     # after Ctrl-C, SIGTERM or a lost rank\n"
      "members.csv does not depend on the threads or ranks. Exit status: 0 every member ran (failed members are\n"
      "rows with completed = 0), 2 bad input (no member runs), 130/143 stopped by SIGINT/SIGTERM");

  auto* view = app.add_subcommand(
      "view", "Write RUN_DIR/view.html: an interactive 3-D view of a run, one file that opens offline");
  std::string view_dir;
  lgvi::app::ViewOptions view_options;
  view->add_option("RUN_DIR", view_dir, "Run folder (written by lgvi run)")->required();
  view->add_flag("--open", view_options.open, "Open it in the default browser (where there is a display)");
  view->add_option("--movie", view_options.movie,
                   "Also render a movie (.mp4 or .gif) with headless chromium and ffmpeg");
  view->add_option("--movie-seconds", view_options.movie_seconds, "Length of the movie (default 10 s at 30 frames/s)")
      ->check(CLI::PositiveNumber);
  view->add_option("--max-frames", view_options.max_frames, "Frames embedded at most (default 2000; fewer for "
                   "many bodies: the page stays under about 50 MB)")->check(CLI::Range(2, 1000000));
  view->add_flag("-q,--quiet", view_options.quiet, "Print nothing on success");
  view->footer("Examples:\n  lgvi view results/paper-orbit --open\n  lgvi view results/paper-orbit --movie orbit.mp4\n"
               "  lgvi run scenarios/paper-orbit.toml --view    # the same at the end of a run");

  auto* show = app.add_subcommand("show", "Print the summary of a run folder (or an ensemble folder) as a table");
  std::string show_dir;
  show->add_option("DIR", show_dir, "Run folder (written by lgvi run)")->required();
  show->footer("Example:\n  lgvi show results/paper-orbit");

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
    if (compare->parsed()) {
      const lgvi::app::Scenario scenario = lgvi::app::read_scenario(compare_scenario);
      if (compare_methods_opt->count() == 0) {
        compare_options.methods = lgvi::app::default_method_choices(scenario);
      } else {
        std::stringstream list(compare_methods_list);
        for (std::string name; std::getline(list, name, ',');)
          compare_options.methods.push_back(lgvi::app::method_choice_from_string(name));
      }
      compare_options.figures = !compare_no_figures;
      return lgvi::app::compare_methods(scenario, compare_options);
    }
    if (ensemble->parsed()) {
#ifdef LGVI_HAVE_MPI
      lgvi::app::set_mpi_runner(&lgvi::app::run_ensemble_mpi);
#endif
      if (!ensemble_resume.empty()) {
        ensemble_options.resume = true;
        ensemble_options.out_dir = ensemble_resume;
      } else if (ensemble_sweep.empty()) {
        throw CLI::RequiredError("SWEEP (or --resume DIR)");
      }
      ensemble_options.figures = !ensemble_no_figures;
      return lgvi::app::run_ensemble(ensemble_sweep, ensemble_options);
    }
    if (view->parsed()) return lgvi::app::write_view(view_dir, view_options);
    if (show->parsed()) {
      if (std::filesystem::exists(std::filesystem::path(show_dir) / "members.csv") ||
          std::filesystem::exists(std::filesystem::path(show_dir) / "journal.csv"))
        lgvi::app::show_ensemble(show_dir, std::cout);
      else
        lgvi::app::show_run(show_dir, std::cout);
      return lgvi::app::kSuccess;
    }
    options.threads = threads;
    if (!resume_dir.empty()) return lgvi::app::resume_run(resume_dir, options);
    if (scenario_path.empty()) throw CLI::RequiredError("SCENARIO (or --resume DIR)");
    lgvi::app::Scenario scenario = lgvi::app::read_scenario(scenario_path);
    if (threads > 0) scenario.threads = threads;
    return lgvi::app::run_scenario(scenario, options);
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
