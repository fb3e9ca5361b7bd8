// One run of a scenario: the integrator, the diagnostics at every step, the
// rows handed to a TrajectorySink, checkpoints, and stopping on request.
// Shared by the command line (run.cpp) and the Python package, so both give
// the same numbers to the last bit.
#pragma once

#include "scenario.hpp"
#include "trajectory_sink.hpp"

#include <lgvi/potential.hpp>
#include <lgvi/state.hpp>

#include <csignal>
#include <cstdint>
#include <functional>
#include <optional>
#include <variant>
#include <string>
#include <vector>

namespace lgvi::app {

/// The built-in potentials a scenario can name.
using ScenarioPotential = std::variant<NoPotential, CentralGravity, UniformGravity, HeavyTop>;

/// The scenario's [potential].
ScenarioPotential scenario_potential(const Scenario& s);

/// Diagnostics over every step, written or not.
struct RunStatistics {
  double energy0 = 0.0;
  Vector3<double> momentum0 = Vector3<double>::Zero();
  double max_energy_error = 0.0, max_quat_error = 0.0, max_momentum_error = 0.0;
  std::int64_t iterations_total = 0, steps_solved = 0;
  std::int64_t potential_evaluations = 0;  ///< the cost measure of method comparisons
  std::int64_t iterations_max = 0;
  std::int64_t last_k = 0;  ///< the last step reached (and observed)
  double last_t = 0.0;
  bool observed = false;          ///< the initial state was evaluated
  double wall_seconds_before = 0.0;  ///< integration time of earlier legs of a resumed run
};

/// Everything needed to continue a run bit-identically: the step index, the
/// state, the integrator's internals (e.g. the solver's warm start), the
/// statistics, and where the trajectory file ended.
struct Checkpoint {
  std::int64_t k = 0;
  RigidBodyState state;
  std::vector<double> stepper_internal;
  RunStatistics stats;
  SinkPosition sink;
  std::int64_t checkpoint_every = 0;
  std::string scenario_name;  ///< the original file's stem (the copy in the run folder is scenario.toml)
};

/// Writes `path` atomically (temporary file + rename). Binary, native
/// byte order, with a magic header and version.
void write_checkpoint(const std::string& path, const Checkpoint& c);
/// Reads a checkpoint; throws InvalidInput naming the file if it is missing,
/// truncated or not a checkpoint.
Checkpoint read_checkpoint(const std::string& path);

struct SimulationOptions {
  /// Write a checkpoint to `checkpoint_path` every this many steps (0: never).
  std::int64_t checkpoint_every = 0;
  std::string checkpoint_path;
  /// Continue from this checkpoint instead of the scenario's initial state.
  const Checkpoint* resume = nullptr;
  /// Stop at the next step boundary when *stop_flag != 0 (a signal handler's flag).
  const volatile std::sig_atomic_t* stop_flag = nullptr;
  /// Called every `progress_every` steps with (k, t).
  std::function<void(std::int64_t, double)> progress;
  std::int64_t progress_every = 16384;
};

struct SimulationResult {
  bool completed = false;
  bool interrupted = false;  ///< stopped on request (stop_flag)
  std::string error;         ///< why it failed or stopped; empty if completed
  RunStatistics stats;
  RigidBodyState final_state;
  double wall_seconds = 0.0;  ///< integration loop with diagnostics and row output, all legs
};

/// Runs the scenario, handing rows (every `output_every` steps, the first and
/// the last) to `sink`. Integration failures are reported in the result, not
/// thrown; the sink then holds the trajectory up to the last good step.
SimulationResult simulate(const Scenario& scenario, TrajectorySink& sink, const SimulationOptions& options = {});

/// The same with a user's potential (e.g. written in Python) in place of the
/// scenario's [potential].
SimulationResult simulate(const Scenario& scenario, const CallablePotential& potential, TrajectorySink& sink,
                          const SimulationOptions& options = {});

/// The summary of a run as JSON text (the CLI's summary.json).
std::string summary_json(const Scenario& scenario, const SimulationResult& result);

}  // namespace lgvi::app
