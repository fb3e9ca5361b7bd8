// The checkpoint of a run: everything needed to continue it bit-identically
// (the step index, the state of every body, the stepper's internals, the
// diagnostics so far and where the trajectory file ended), and its binary
// file format: named, typed, sized fields (lgvi/checkpoint_fields.hpp), each
// object writing and reading its own.
#pragma once

#include "io/trajectory_sink.hpp"

#include <lgvi/checkpoint_fields.hpp>
#include <lgvi/error.hpp>
#include <lgvi/s3.hpp>
#include <lgvi/system.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace lgvi::app {

// The application is built on the I/O layer (src/io, namespace lgvi::io, below it:
// io names nothing of app, tests/check_library_layers.py) and names its types unqualified.
using namespace lgvi::io;

/// A contact episode of two bodies a < b: the steps first_k..last_k, one
/// after the other, at which they overlap (contact.hpp), and the deepest
/// overlap over them.
struct ContactEpisode {
  std::int64_t a = 0, b = 0;
  std::int64_t first_k = 0, last_k = 0;
  double first_t = 0.0, last_t = 0.0;
  double max_depth = 0.0;
  double distance = 0.0;  ///< the pieces' centre distance at the deepest overlap
};

/// The thermodynamic columns' values over the written frames (thermo_columns):
/// the first and the last, their sums (the mean is sum / frames) and how many
/// frames. The pressure is NaN without a periodic box.
struct ThermoStatistics {
  double temperature0 = 0.0, pressure0 = 0.0, temperature = 0.0, pressure = 0.0;
  double temperature_sum = 0.0, pressure_sum = 0.0;
  std::int64_t frames = 0;
};

/// Diagnostics over every step, written or not.
struct RunStatistics {
  double energy0 = 0.0;
  Vector3<double> momentum0 = Vector3<double>::Zero();  ///< total angular momentum about the origin
  double max_energy_error = 0.0, max_quat_error = 0.0, max_momentum_error = 0.0;
  Vector3<double> linear_momentum0 = Vector3<double>::Zero();  ///< total linear momentum P0
  double linear_momentum_scale = 0.0;                           ///< sum_a |p_a0|
  double max_linear_momentum_error = 0.0;                       ///< max |P - P0| / sum_a |p_a0|
  std::int64_t iterations_total = 0, steps_solved = 0;
  std::int64_t potential_evaluations = 0;  ///< the cost measure of method comparisons
  std::int64_t iterations_max = 0;
  std::int64_t last_k = 0;  ///< the last step reached (and observed)
  double last_t = 0.0;
  bool observed = false;          ///< the initial state was evaluated
  double wall_seconds_before = 0.0;  ///< integration time of earlier legs of a resumed run
  // Rotation (summed over the bodies): kinetic energy T = sum Pi.J^-1 Pi / 2
  // and spin angular momentum S = sum R Pi (Pi = w / 2, the body angular
  // momentum), their initial values and ranges, and max |S - S0|.
  double rot_energy0 = 0.0, min_rot_energy = 0.0, max_rot_energy = 0.0;
  Vector3<double> spin0 = Vector3<double>::Zero();
  double min_spin = 0.0, max_spin = 0.0, max_spin_change = 0.0;
  double work = 0.0;  ///< [[forcing]]: the work done up to last_k (not checkpointed: the stepper keeps it)
  /// An adaptive run's (time_transform): the smallest and largest physical
  /// step, as differences of consecutive steps' t; 0 for a fixed step.
  double min_time_step = 0.0, max_time_step = 0.0;
  /// Contact episodes (on_contact "warn", or the one that stopped a run), in
  /// the order they began; at most max_listed_contacts of them,
  /// contact_episodes counts them all.
  std::vector<ContactEpisode> contacts;
  ThermoStatistics thermo;  ///< a molecular run's temperature and pressure (written frames only)
  /// Per reaction wheel of the body (in its order): the largest |speed| relative to the body and |torque|
  /// applied, and the time it spent at a limit (its torque clipped to max_torque, or held at max_speed).
  struct WheelStatistics {
    double max_speed = 0.0, max_torque = 0.0, time_limited = 0.0;
  };
  std::vector<WheelStatistics> wheels;
  /// Over the wheels and the steps: the motors' total torque impulse sum_i int |u_i| dt (N m s, the
  /// control effort), and the time during which at least one wheel was at a limit.
  double wheel_effort = 0.0, wheels_saturated_time = 0.0;
  std::int64_t contact_episodes = 0;
  static constexpr std::size_t max_listed_contacts = 10000;
};

/// Everything needed to continue a run bit-identically: the step index, the
/// state, the integrator's internals (e.g. the solver's warm start), the
/// statistics, and where the trajectory file ended.
struct Checkpoint {
  std::int64_t k = 0;
  SystemState state;
  /// The stepper's fields, all named "stepper.*" (SystemStepper's save, load);
  /// read from a file of versions 2 to 4: its numbers as "stepper.internal".
  CheckpointFields stepper;
  /// The observer's fields, all named "recorder.*" (e.g. its copy of a wheel controller, how far each
  /// side table was written): written and read by the run loop (simulation.cpp).
  CheckpointFields recorder;
  RunStatistics stats;
  SinkPosition sink;
  std::int64_t checkpoint_every = 0;
  std::string scenario_name;  ///< the original file's stem (the copy in the run folder is scenario.toml)
  std::int64_t version = 0;   ///< the file's format version (read_checkpoint sets it; written: the current)
  std::string path;           ///< the file it was read from (read_checkpoint), for messages
};

/// A checkpoint that cannot be resumed: a field missing, unknown, truncated
/// or of the wrong size. The message names the file and the field.
class CheckpointError : public InvalidInput {
 public:
  using InvalidInput::InvalidInput;
};

/// Writes `path` atomically (temporary file + rename). Binary, native
/// byte order, with a magic header and version (checkpoint.cpp: the layout).
void write_checkpoint(const std::string& path, const Checkpoint& c);
/// Reads a checkpoint of this lgvi's format or an older one (versions 2 to 4,
/// mapped onto the fields); throws InvalidInput naming the file (and the
/// field) if it is missing, truncated, not a checkpoint, or has a field
/// missing or unknown to this lgvi. The stepper's fields are checked when the
/// stepper reads them (SystemStepper's load).
Checkpoint read_checkpoint(const std::string& path);

}  // namespace lgvi::app
