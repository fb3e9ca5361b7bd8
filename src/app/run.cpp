#include "app/run.hpp"

#include "io/formats/registry.hpp"
#include "io/output.hpp"
#include "app/progress_line.hpp"
#include "app/simulation.hpp"
#include "app/stop_signals.hpp"
#include "app/summary.hpp"

#include <lgvi/error.hpp>

#include <fmt/format.h>
#include <fmt/printf.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

extern char** environ;

namespace lgvi::app {

namespace fs = std::filesystem;

namespace {

/// Folder holding the `lgvi` Python package (for the figures).
std::string python_dir() {
  if (const char* env = std::getenv("LGVI_PYTHON_DIR")) return env;
  std::error_code ec;
  if (fs::exists(fs::path(LGVI_SOURCE_PYTHON_DIR) / "lgvi" / "plot.py", ec)) return LGVI_SOURCE_PYTHON_DIR;
  return LGVI_INSTALLED_PYTHON_DIR;
}

/// The run's progress line (progress_line.hpp), only when standard error is a
/// terminal: step k of N, t, steps per second and the time left, at most
/// every 0.25 s and at the last step. An adaptive run has no N: t of the
/// duration, and the time left from the rate of t.
class Progress {
 public:
  Progress(bool enabled, const IntegratorSpec& integrator)
      : line_(enabled && isatty(STDERR_FILENO)), integrator_(integrator) {}
  void operator()(std::int64_t k, double t) {
    if (!line_.enabled()) return;
    const double elapsed = line_.elapsed();
    if (elapsed - last_ < 0.25 && !integrator_.ends(k, t)) return;
    last_ = elapsed;
    const double rate = static_cast<double>(k - k_start_) / std::max(elapsed, 1e-9);
    if (integrator_.adaptive()) {
      const double duration = integrator_.duration;
      const double time_rate = (t - t_start_) / std::max(elapsed, 1e-9);
      const double eta = time_rate > 0 ? std::max(0.0, duration - t) / time_rate : 0.0;
      line_.show(fmt::sprintf("lgvi: step %lld (t = %.6g of %.6g), %.3g steps/s, ETA %.0f s",
                              static_cast<long long>(k), t, duration, rate, eta));
      return;
    }
    const std::int64_t total = integrator_.steps;
    const double eta = rate > 0 ? static_cast<double>(total - k) / rate : 0.0;
    line_.show(fmt::sprintf("lgvi: step %lld/%lld (t = %.6g), %.3g steps/s, ETA %.0f s", static_cast<long long>(k),
                            static_cast<long long>(total), t, rate, eta));
  }
  void start_at(std::int64_t k, double t) {
    k_start_ = k;
    t_start_ = t;
  }
  bool enabled() const { return line_.enabled(); }

 private:
  ProgressLine line_;
  const IntegratorSpec& integrator_;
  std::int64_t k_start_ = 0;
  double t_start_ = 0.0, last_ = -1.0;
};

/// The shared part of a fresh and a resumed run.
/// `start`: the state a new run starts from (taken), the scenario's initial
/// state, which `sc` no longer holds (not read after the set-up: summaries
/// and figures come from the run's own records).
int execute(const Scenario& sc, SystemState start, const std::string& dir, const RunOptions& opt,
            const Checkpoint* resume) {
  const fs::path trajectory_path = fs::path(dir) / trajectory_file_name(sc.output_format);
  const fs::path summary_path = fs::path(dir) / "summary.json";
  const fs::path checkpoint_path = fs::path(dir) / "checkpoint.bin";
  // The folder is written when simulate() opens the sink: for a resume only
  // once the checkpoint has loaded, since reopening the trajectory truncates
  // it back to the checkpoint: a refused resume leaves the folder as it was.
  std::unique_ptr<TrajectorySink> sink;
  std::string folder_error;
  auto open_sink = [&]() -> TrajectorySink& {
    try {
      fs::create_directories(dir);
      // A summary left by an earlier run must not describe this one.
      fs::remove(summary_path);
      fs::remove(fs::path(dir) / kBodyListsFile);  // nor the lists of bodies beside it
      if (!resume) {
        fs::remove(checkpoint_path);
        // Nor side tables (SimulationResult::sensors, wheels) that this run may not write.
        for (const std::string& side : side_table_files()) fs::remove(fs::path(dir) / side);
        write_file_atomically((fs::path(dir) / "scenario.toml").string(), sc.source_text);
      }
      sink = open_trajectory(sc.output_format, trajectory_path.string(), scenario_layout(sc),
                             resume ? &resume->sink : nullptr);
    } catch (const std::exception& e) {
      folder_error = e.what();
      throw;
    }
    return *sink;
  };

  Progress progress(!opt.quiet, sc.integrator);
  SimulationOptions so;
  so.checkpoint_every = opt.checkpoint_every;
  so.checkpoint_path = checkpoint_path.string();
  so.resume = resume;
  so.start = &start;
  so.stop_flag = stop_flag();
  so.open_side_table = side_tables_in(dir);
  if (progress.enabled()) {
    progress.start_at(resume ? resume->k : 0, resume ? resume->stats.last_t : 0.0);
    so.progress = [&](std::int64_t k, double t) { progress(k, t); };
    so.progress_every = 4096;
  }
  SimulationResult result;
  {
    StopSignals signals;
    try {
      result = simulate(sc, open_sink, so);
    } catch (const CheckpointError& e) {  // the checkpoint's fields: nothing was run or written
      std::cerr << "lgvi: error: " << e.what() << "\n";
      return kBadInput;
    } catch (const std::exception& e) {
      if (!sink) {  // the folder could not be written: nothing was run
        if (folder_error.empty()) throw;
        std::cerr << "lgvi: error: output folder '" << dir << "' cannot be written: " << folder_error
                  << "; choose another with --out\n";
        return kBadInput;
      }
      result.error = e.what();  // I/O while checkpointing
    }
    if (result.interrupted)
      result.error = std::string("interrupted by ") + stop_signal_name() +
                     " at t = " + fmt::format("{}", result.stats.last_t) +
                     (opt.checkpoint_every > 0 ? "; continue with: lgvi run --resume " + dir : "");
  }
  const std::string stored_summary = sink->stores_summary() ? summary_json(sc, result) : std::string();
  try {
    sink->close(sc.source_text, stored_summary);
  } catch (const std::exception& e) {
    if (result.error.empty()) result.error = e.what();
    result.completed = false;
  }
  try {
    write_summary_file(summary_path.string(), sc, result);
  } catch (const std::exception& e) {
    std::cerr << "lgvi: error: " << e.what() << "\n";
    return kRunFailed;
  }
  if (result.interrupted) {
    std::cerr << "lgvi: " << result.error << "\n";
    return stop_exit_status();
  }
  if (!result.completed) {
    std::cerr << "lgvi: error: " << result.error << "\n";
    if (result.stats.observed)
      std::cerr << "lgvi: the trajectory up to t = " << result.stats.last_t << " is in " << trajectory_path.string()
                << "; summary.json says \"completed\": false\n";
    else
      std::cerr << "lgvi: no state could be evaluated, " << trajectory_path.string()
                << " holds no rows; summary.json says \"completed\": false\n";
    return kRunFailed;
  }
  if (opt.checkpoint_every > 0) fs::remove(checkpoint_path);  // the run is complete: nothing to resume
  const RunStatistics& st = result.stats;
  const double l0 = st.momentum0.norm();
  // As summary.json's "conserved" says: under a forcing the energy error is E - E0 - W, and an angular
  // momentum the dynamics does not conserve (a periodic box, a field, a forcing) has changed, not erred.
  const ConservationLaws laws = conservation_laws(sc);
  if (!opt.quiet)
    std::cout << fmt::format(
        "{}: {} steps in {:.3f} s ({:.0f} ns/step); max |{}| = {:.3e}, max ||q|-1| = {:.3e}, max |dL|/|L0| = {:.3e}{}; "
        "output in {}\n",
        sc.name, st.last_k, result.wall_seconds,
        st.last_k ? result.wall_seconds * 1e9 / static_cast<double>(st.last_k) : 0.0,
        laws.forced ? "E - E0 - W" : "dE", st.max_energy_error, st.max_quat_error,
        l0 > 0 ? st.max_momentum_error / l0 : st.max_momentum_error,
        laws.angular_momentum == ConservationLaws::Angular::Conserved ? "" : " (a change: not conserved here)", dir);
  // The figures are drawn from the trajectory's columns; the particle exports
  // (xyz, vtk, lammps-dump) do not hold them (lgvi.load refuses them), so those runs have none.
  if (opt.figures && !holds_columns(sc.output_format)) {
    if (!opt.quiet)
      std::cerr << "lgvi: no figures: they are drawn from csv, npz or hdf5 trajectories, this run wrote the "
                << to_string(sc.output_format) << " export " << trajectory_path.string() << "\n";
  } else if (opt.figures) {
    try {
      draw_figures(dir);
    } catch (const std::exception& e) {
      std::cerr << "lgvi: error: the run completed and its files are written, but " << e.what() << "\n";
      return kRunFailed;
    }
  }
  if (opt.view) {
    ViewOptions view;
    view.quiet = opt.quiet;
    if (write_view(dir, view) != kSuccess) return kRunFailed;  // lgvi.viewer said why, in one line
  }
  return kSuccess;
}

}  // namespace

namespace {
/// Runs `python ARGS...` with the lgvi package on PYTHONPATH; returns its exit status (-1 if it did not
/// exit). Throws std::runtime_error if it cannot start, naming what it was for (`purpose`) and the fix.
int run_python(const std::vector<std::string>& python_args, const std::string& purpose) {
  const char* py_env = std::getenv("LGVI_PYTHON");
  const std::string python = py_env ? py_env : "/usr/bin/python3";
  std::string pythonpath = python_dir();
  if (const char* old = std::getenv("PYTHONPATH")) pythonpath += std::string(":") + old;
  std::vector<std::string> env_strings{"PYTHONPATH=" + pythonpath, "MPLBACKEND=Agg"};
  for (char** e = environ; *e; ++e)
    if (std::strncmp(*e, "PYTHONPATH=", 11) != 0 && std::strncmp(*e, "MPLBACKEND=", 11) != 0) env_strings.emplace_back(*e);
  std::vector<char*> envp;
  envp.reserve(env_strings.size() + 1);
  for (auto& e : env_strings) envp.push_back(e.data());
  envp.push_back(nullptr);
  std::vector<std::string> args{python};
  args.insert(args.end(), python_args.begin(), python_args.end());
  std::vector<char*> argv;
  argv.reserve(args.size() + 1);
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid;
  if (posix_spawn(&pid, python.c_str(), nullptr, nullptr, argv.data(), envp.data()) != 0)
    throw std::runtime_error("cannot start " + python + " to " + purpose);
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/// Runs `python -m MODULE DIR` (the figures); throws std::runtime_error if it fails.
void run_python_module(const std::string& module, const std::string& run_dir) {
  if (run_python({"-m", module, run_dir},
                 "draw the figures (install python3-matplotlib, or set LGVI_PYTHON; --no-figures skips them)") != 0)
    throw std::runtime_error("drawing the figures with python3 -m " + module +
                             " failed (see its message above; --no-figures skips them)");
}
}  // namespace

void draw_figures(const std::string& run_dir) { run_python_module("lgvi.plot", run_dir); }
void draw_compare_figures(const std::string& dir) { run_python_module("lgvi.compare_plot", dir); }

int write_view(const std::string& run_dir, const ViewOptions& options) {
  std::vector<std::string> args{"-m", "lgvi.viewer", run_dir};
  if (options.open) args.emplace_back("--open");
  if (!options.movie.empty()) args.insert(args.end(), {"--movie", options.movie});
  if (options.movie_seconds > 0) args.insert(args.end(), {"--movie-seconds", fmt::format("{}", options.movie_seconds)});
  if (options.max_frames > 0) args.insert(args.end(), {"--max-frames", std::to_string(options.max_frames)});
  if (options.quiet) args.emplace_back("-q");
  const int status = run_python(args, "write the view (set LGVI_PYTHON to a Python with numpy)");
  return status == kSuccess || status == kBadInput ? status : kRunFailed;
}

void require_new_output_folder(const std::string& dir, bool force) {
  if (force) return;
  std::error_code ec;
  const fs::path path(dir);
  if (!fs::exists(path, ec)) return;  // created by the run (or it says why it cannot be)
  if (fs::is_directory(path, ec) && fs::is_empty(path, ec) && !ec) return;
  throw InvalidInput("output folder '" + dir +
                     "' already exists and is not empty; add --force to overwrite its files, or choose another "
                     "folder with --out");
}

int run_scenario(Scenario sc, const RunOptions& opt) {
  const std::string dir = opt.out_dir.empty() ? sc.name : opt.out_dir;
  require_new_output_folder(dir, opt.force);
  SystemState start = std::move(sc.initial_state);
  return execute(sc, std::move(start), dir, opt, nullptr);
}

int resume_run(const std::string& dir, RunOptions opt) {
  Scenario sc = read_scenario((fs::path(dir) / "scenario.toml").string());
  const Checkpoint c = read_checkpoint((fs::path(dir) / "checkpoint.bin").string());
  if (!c.scenario_name.empty()) sc.name = c.scenario_name;
  if (opt.threads > 0) sc.threads = opt.threads;
  if (opt.checkpoint_every == 0) opt.checkpoint_every = c.checkpoint_every;
  if (c.k > sc.integrator.steps)
    throw InvalidInput(dir + "/checkpoint.bin: step " + std::to_string(c.k) + " is beyond the scenario's " +
                       std::to_string(sc.integrator.steps) + " steps");
  // A run that a contact stopped (its last episode ends at the checkpoint's step) would take one step
  // and stop again: say how to go on instead.
  if (sc.on_contact == OnContact::Stop && !c.stats.contacts.empty() && c.stats.contacts.back().last_k == c.k)
    throw InvalidInput(dir + ": the run stopped at step " + std::to_string(c.k) +
                       " because two bodies touched; to go on through the contact, set [run] on_contact = \"warn\" "
                       "(or \"ignore\") in " + dir + "/scenario.toml and resume");
  if (c.version < 4 && has_gravity_gradient_body(sc))
    throw InvalidInput(dir + "/checkpoint.bin: written by an lgvi that ran a body given by mass + inertia as a point "
                       "mass in the central field; this one gives it the gravity-gradient torque, and continuing would "
                       "change the physics mid-run. Add model = \"point\" to [potential] in " + dir +
                       "/scenario.toml to continue as it began, or run the scenario again from the start");
  SystemState start = std::move(sc.initial_state);  // (overwritten by the checkpoint's)
  return execute(sc, std::move(start), dir, opt, &c);
}

}  // namespace lgvi::app
