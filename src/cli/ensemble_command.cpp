// `lgvi ensemble`: many members of a scenario on threads or MPI ranks (app/ensemble.hpp).
#include "app/ensemble.hpp"
#include "cli/command.hpp"

#include <memory>
#include <string>

namespace lgvi::cli {

Command add_ensemble_command(CLI::App& parser) {
  struct Options {
    std::string sweep, resume;
    app::EnsembleOptions ensemble;
    bool no_figures = false;
  };
  auto o = std::make_shared<Options>();
  auto* ensemble = parser.add_subcommand(
      "ensemble", "Run many members of a scenario with varied numbers (sweeps, Monte Carlo) on threads or MPI ranks");
  auto* sweep_opt = ensemble->add_option("SWEEP", o->sweep, "Sweep file (TOML), see docs/guide/ensembles.md");
  auto* resume_opt =
      ensemble->add_option("--resume", o->resume, "Run the members of this ensemble folder that have no row yet");
  sweep_opt->excludes(resume_opt);
  ensemble->add_option("--out", o->ensemble.out_dir, "Output folder (default: a folder named after the sweep)")
      ->excludes(resume_opt);
  ensemble->add_option("--threads", o->ensemble.threads,
                       "Members run at once (default: all cores; under mpirun, per rank, default 1)")
      ->check(CLI::Range(1, 1024));
  ensemble->add_flag("-q,--quiet", o->ensemble.quiet, "Print nothing on success");
  ensemble->add_flag("--progress", o->ensemble.progress,
                     "Show the progress line even where stderr is not a terminal (under mpirun: a pipe)");
  ensemble->add_flag("--no-figures", o->no_figures, "Do not draw error_distribution.png and error_vs_varied.png");
  ensemble->footer(
      "Examples:\n  lgvi ensemble sweep.toml --out results/sweep --threads 2\n"
      "  mpirun -n 4 lgvi ensemble sweep.toml --out results/sweep\n"
      "  lgvi ensemble --resume results/sweep     # after Ctrl-C, SIGTERM or a lost rank\n"
      "members.csv does not depend on the threads or ranks. Exit status: 0 every member ran (failed members are\n"
      "rows with completed = 0), 2 bad input (no member runs), 130/143 stopped by SIGINT/SIGTERM");
  return {ensemble, [o] {
#ifdef LGVI_HAVE_MPI
            app::set_mpi_runner(&app::run_ensemble_mpi);
#endif
            if (!o->resume.empty()) {
              o->ensemble.resume = true;
              o->ensemble.out_dir = o->resume;
            } else if (o->sweep.empty()) {
              throw CLI::RequiredError("SWEEP (or --resume DIR)");
            }
            o->ensemble.figures = !o->no_figures;
            return app::run_ensemble(o->sweep, o->ensemble);
          }};
}

}  // namespace lgvi::cli
