// `lgvi compare`: methods against each other on one scenario (app/compare.hpp).
#include "app/compare.hpp"
#include "app/method.hpp"
#include "app/scenario.hpp"
#include "cli/command.hpp"

#include <memory>
#include <sstream>
#include <string>

namespace lgvi::cli {

Command add_compare_command(CLI::App& parser) {
  struct Options {
    std::string scenario, methods = "lgvi,lgvi-lagrangian";
    app::CompareOptions compare;
    bool no_figures = false;
  };
  auto o = std::make_shared<Options>();
  auto* compare = parser.add_subcommand(
      "compare", "Compare integration methods on a scenario: work-precision, long-time behaviour, tables, figures");
  compare->add_option("SCENARIO", o->scenario, "Scenario file (TOML)")->required();
  auto* methods_opt = compare->add_option(
      "--methods", o->methods,
      "Comma-separated methods (see docs/guide/compare.md); NAME:ORDER composes a symmetric one-step method to "
      "order 4, 6 or 8 (e.g. lgvi:4); lgvi+tt, lgvi:ORDER+tt the adaptive LGVI (time_transform). Default: "
      "lgvi,lgvi-lagrangian; for a scenario with time_transform, its adaptive step and the fixed one at its order "
      "(e.g. lgvi:4+tt,lgvi:4)");
  compare->add_option("--out", o->compare.out_dir,
                      "Output folder (default: NAME-compare, NAME the scenario's name); it must not exist or be "
                      "empty, unless --force");
  compare->add_flag("--force", o->compare.force,
                    "Write into an existing non-empty output folder, overwriting the comparison's files");
  compare->add_option("--timing-budget", o->compare.timing_budget,
                      "Seconds of repeated runs per timed point: after an untimed first run, each work-precision "
                      "run is repeated until the repeats add up to this, at least 3 times; medians and quartiles "
                      "are reported (default 0.2; the errors do not depend on it)");
  compare->add_option("--ladder", o->compare.ladder, "Number of step sizes h, h/2, ... (default 5)");
  compare->add_option("--ladder-from", o->compare.ladder_from,
                      "Largest step of the ladder (default: the scenario's step; higher orders pay off at larger "
                      "steps). The long runs keep the scenario's step");
  compare->add_option("--error-time", o->compare.error_time,
                      "Time of the work-precision runs (default: min(duration, 1e4 h))");
  compare->add_option("--long-steps", o->compare.long_steps,
                      "Length of the equal-cost long runs, in steps of h (default 1e6)");
  compare->add_flag("--no-figures", o->no_figures, "Do not draw the PNG figures");
  compare->add_flag("-q,--quiet", o->compare.quiet, "Print nothing on success");
  compare->footer(app::method_table() +
                  "Example:\n  lgvi compare scenarios/free-body-manchester-peck.toml --methods "
                  "lgvi,so3-lgvi,rk4-normalized --out results/compare");
  return {compare, [o, methods_opt] {
            const app::Scenario scenario = app::read_scenario(o->scenario);
            if (methods_opt->count() == 0) {
              o->compare.methods = app::default_method_choices(scenario);
            } else {
              std::stringstream list(o->methods);
              for (std::string name; std::getline(list, name, ',');)
                o->compare.methods.push_back(app::method_choice_from_string(name));
            }
            o->compare.figures = !o->no_figures;
            return app::compare_methods(scenario, o->compare);
          }};
}

}  // namespace lgvi::cli
