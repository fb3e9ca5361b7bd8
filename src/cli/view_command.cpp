// `lgvi view`: the interactive 3-D view of a run folder (app/run.hpp, write_view).
#include "app/run.hpp"
#include "cli/command.hpp"

#include <memory>
#include <string>

namespace lgvi::cli {

Command add_view_command(CLI::App& parser) {
  struct Options {
    std::string dir;
    app::ViewOptions view;
  };
  auto o = std::make_shared<Options>();
  auto* view = parser.add_subcommand(
      "view", "Write RUN_DIR/view.html: an interactive 3-D view of a run, one file that opens offline");
  view->add_option("RUN_DIR", o->dir, "Run folder (written by lgvi run)")->required();
  view->add_flag("--open", o->view.open, "Open it in the default browser (where there is a display)");
  view->add_option("--movie", o->view.movie, "Also render a movie (.mp4 or .gif) with headless chromium and ffmpeg");
  view->add_option("--movie-seconds", o->view.movie_seconds, "Length of the movie (default 10 s at 30 frames/s)")
      ->check(CLI::PositiveNumber);
  view->add_option("--max-frames", o->view.max_frames,
                   "Frames embedded at most (default 2000; fewer for "
                   "many bodies: the page stays under about 50 MB)")
      ->check(CLI::Range(2, 1000000));
  view->add_flag("-q,--quiet", o->view.quiet, "Print nothing on success");
  view->footer(
      "Examples:\n  lgvi view results/paper-orbit --open\n  lgvi view results/paper-orbit --movie orbit.mp4\n"
      "  lgvi run scenarios/paper-orbit.toml --view    # the same at the end of a run");
  return {view, [o] { return app::write_view(o->dir, o->view); }};
}

}  // namespace lgvi::cli
