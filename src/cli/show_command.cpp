// `lgvi show`: a run's or an ensemble's summary as a table (app/show.hpp, app/ensemble.hpp).
#include "app/ensemble.hpp"
#include "app/run.hpp"
#include "app/show.hpp"
#include "cli/command.hpp"

#include <filesystem>
#include <iostream>
#include <memory>
#include <string>

namespace lgvi::cli {

Command add_show_command(CLI::App& parser) {
  auto dir = std::make_shared<std::string>();
  auto* show = parser.add_subcommand("show", "Print the summary of a run folder (or an ensemble folder) as a table");
  show->add_option("DIR", *dir, "Run folder (written by lgvi run)")->required();
  show->footer("Example:\n  lgvi show results/paper-orbit");
  return {show, [dir] {
            const std::filesystem::path folder(*dir);
            if (std::filesystem::exists(folder / "members.csv") || std::filesystem::exists(folder / "journal.csv"))
              app::show_ensemble(*dir, std::cout);
            else
              app::show_run(*dir, std::cout);
            return static_cast<int>(app::kSuccess);
          }};
}

}  // namespace lgvi::cli
