// `lgvi run`: integrate a scenario into a run folder, or resume one (app/run.hpp).
#include "app/method.hpp"
#include "app/run.hpp"
#include "app/scenario.hpp"
#include "cli/command.hpp"

#include <memory>
#include <string>

namespace lgvi::cli {

Command add_run_command(CLI::App& parser) {
  struct Options {
    std::string scenario_path, resume_dir;
    app::RunOptions run;
    bool no_figures = false;
    int threads = 0;
  };
  auto o = std::make_shared<Options>();
  auto* run = parser.add_subcommand("run", "Integrate a scenario file; write trajectory.csv, summary.json and figures");
  auto* scenario_opt =
      run->add_option("SCENARIO", o->scenario_path, "Scenario file (TOML), see docs/guide/scenario-files.md");
  auto* resume_opt =
      run->add_option("--resume", o->resume_dir, "Continue the interrupted run in this folder from its checkpoint");
  scenario_opt->excludes(resume_opt);
  run->add_option("--out", o->run.out_dir,
                  "Output folder (default: a folder named after the scenario); it must not exist or be empty, "
                  "unless --force")
      ->excludes(resume_opt);
  run->add_flag("--force", o->run.force,
                "Write into an existing non-empty output folder, overwriting the files this run writes (others "
                "stay)")
      ->excludes(resume_opt);
  run->add_option("--checkpoint-every", o->run.checkpoint_every,
                  "Write the full state to DIR/checkpoint.bin every N steps (and on SIGINT/SIGTERM)")
      ->check(CLI::NonNegativeNumber);
  run->add_option("--threads", o->threads,
                  "Threads for the per-body loops of many-body runs (default: [run] threads, else all cores); "
                  "results do not depend on it")
      ->check(CLI::Range(1, 1024));
  run->add_flag("--no-figures", o->no_figures, "Do not draw the PNG figures");
  run->add_flag("--view", o->run.view, "Also write DIR/view.html, the interactive 3-D view (lgvi view)");
  run->add_flag("-q,--quiet", o->run.quiet, "Print nothing on success");
  run->footer(
      app::method_table() +
      "Examples:\n  lgvi run scenarios/paper.toml --out results/paper\n"
      "  lgvi run long.toml --checkpoint-every 100000   # then, after Ctrl-C: lgvi run --resume long\n"
      "Exit status: 0 success, 1 the run failed (the error names the step), 2 bad usage or bad input,\n"
      "130/143 stopped by SIGINT/SIGTERM (the files are valid up to the last step; summary.json says so)");
  return {run, [o] {
            o->run.figures = !o->no_figures;
            o->run.threads = o->threads;
            if (!o->resume_dir.empty()) return app::resume_run(o->resume_dir, o->run);
            if (o->scenario_path.empty()) throw CLI::RequiredError("SCENARIO (or --resume DIR)");
            app::Scenario scenario = app::read_scenario(o->scenario_path);
            if (o->threads > 0) scenario.threads = o->threads;
            return app::run_scenario(std::move(scenario), o->run);
          }};
}

}  // namespace lgvi::cli
