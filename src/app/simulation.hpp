// One run of a scenario: the integrator, the diagnostics at every step, the
// rows handed to a TrajectorySink, checkpoints, and stopping on request.
// Shared by the command line (run.cpp) and the Python package, so both give
// the same numbers to the last bit.
#pragma once

#include "app/checkpoint.hpp"
#include "app/interactions/any_mutual.hpp"
#include "app/scenario.hpp"
#include "io/trajectory_sink.hpp"

#include <lgvi/interaction.hpp>
#include <lgvi/parallel.hpp>
#include <lgvi/potential.hpp>
#include <lgvi/state.hpp>
#include <lgvi/system.hpp>

#include <algorithm>
#include <csignal>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <variant>
#include <string>
#include <vector>

namespace lgvi::app {

/// The built-in potentials a scenario can name.
using ScenarioPotential = std::variant<NoPotential, CentralGravity, UniformGravity, HeavyTop>;

/// The scenario's [potential] for its first body (single-body tools: the
/// continuous equations of `lgvi compare`'s reference).
ScenarioPotential scenario_potential(const Scenario& s);

/// The potential of a scenario's whole system: its external field on every
/// body plus its mutual interaction. One type for every scenario (the field
/// and the interaction are variants, visited once per evaluation), so that
/// each method is compiled once. Counts its evaluations (the cost measure of
/// `lgvi compare`).
class ScenarioSystemPotential {
 public:
  using External = std::variant<ExternalField<NoPotential>, ExternalField<CentralGravity>,
                                ExternalField<UniformGravity>, ExternalField<HeavyTop>,
                                ExternalField<CallablePotential>>;
  using Mutual = AnyMutualInteraction;  ///< empty: none

  ScenarioSystemPotential(External external, Mutual mutual, std::int64_t* evaluations)
      : external_(std::move(external)), mutual_(std::move(mutual)), evaluations_(evaluations) {}

  void evaluate(const SystemState& s, SystemEvaluation& e) {
    std::visit([&](auto& field) { field.evaluate(s, e); }, external_);
    mutual_.add(s, e);
    ++*evaluations_;
  }
  /// The mutual interaction's molecular virial at `s` (the pressure's;
  /// PairInteraction::virial), if it has one (it updates the interaction's
  /// lists: a non-const call, as an evaluation).
  std::optional<double> virial(const SystemState& s) { return mutual_.virial(s); }
  /// No field and no interaction: the free body (for method "exact").
  bool is_free() const {
    return std::holds_alternative<ExternalField<NoPotential>>(external_) &&
           mutual_.empty();
  }

 private:
  External external_;
  Mutual mutual_;
  std::int64_t* evaluations_;
};

/// The threads a scenario's per-body loops use: [run] threads, else all cores.
Parallelism scenario_parallelism(const Scenario& s);

/// The scenario's system potential, with `field` (e.g. a Python potential)
/// in place of its [potential] when given; evaluations are counted in
/// *evaluations.
ScenarioSystemPotential scenario_system_potential(const Scenario& s, const CallablePotential* field,
                                                  std::int64_t* evaluations);

/// A table of numbers written beside the trajectory, DIR/file: a header of its columns, then its rows
/// (17 significant digits: the same doubles read back), as a CSV trajectory is. The run streams its rows
/// to SimulationOptions::open_side_table's sink; without that opener it keeps them here. No columns: no
/// table.
struct SideTable {
  std::string file;
  std::vector<std::string> columns;
  std::vector<double> values;  ///< the rows, row-major, when kept in memory
  std::size_t rows() const { return columns.empty() ? 0 : values.size() / columns.size(); }
};

/// Opens a side table's sink (SideTable): `file` its name in the run folder, `layout` its columns (the
/// single-body layout's fields, no bodies); `resume` where a checkpoint left it (null: a new file with
/// its header). The run closes the sink at its end.
using SideTableOpener = std::function<std::unique_ptr<TrajectorySink>(
    const std::string& file, const TrajectoryLayout& layout, const SinkPosition* resume)>;

/// The side tables streamed as CSV files into the folder `dir`.
SideTableOpener side_tables_in(const std::string& dir);

/// The file names of every side table a run may write (sensors.csv, wheels.csv): a new run in a folder
/// removes them first, so that none is left from an earlier run that this one does not write.
std::vector<std::string> side_table_files();

struct SimulationOptions {
  /// Write a checkpoint to `checkpoint_path` every this many steps (0: never).
  std::int64_t checkpoint_every = 0;
  std::string checkpoint_path;
  /// Continue from this checkpoint instead of the scenario's initial state.
  const Checkpoint* resume = nullptr;
  /// If given, the state the run starts from, taken (moved from) instead of
  /// a copy of the scenario's initial state: a caller done with that state
  /// saves holding N bodies' state once more.
  SystemState* start = nullptr;
  /// Stop at the next step boundary when *stop_flag != 0 (a signal handler's flag).
  const volatile std::sig_atomic_t* stop_flag = nullptr;
  /// Called every `progress_every` steps with (k, t).
  std::function<void(std::int64_t, double)> progress;
  std::int64_t progress_every = 16384;
  /// Called at every observed step (the initial state's k = 0 too) with (k, t, state), after its
  /// diagnostics: what an ensemble member measures besides them (its pointing error).
  std::function<void(std::int64_t, double, const SystemState&)> observe_step;
  /// Where the side tables (SimulationResult::sensors, wheels) are streamed; empty: kept in memory in the
  /// result (on resume, the rows of the resumed leg only, as a memory trajectory sink holds them). A
  /// checkpoint holds each table's position (SinkPosition), not its rows.
  SideTableOpener open_side_table;
};

struct SimulationResult {
  bool completed = false;
  bool interrupted = false;  ///< stopped on request (stop_flag)
  std::string error;         ///< why it failed or stopped; empty if completed
  RunStatistics stats;
  SystemState final_state;
  double wall_seconds = 0.0;  ///< integration loop with diagnostics and row output, all legs
  /// With [[sensor]]: what the controller read at each of its samples (sensors.csv, sensor_header).
  SideTable sensors;
  /// A system ([[bodies]]) with reaction wheels: per written frame and wheel its speed relative to its
  /// body, its momentum and the torque applied over the step from t (wheels.csv: t, body, wheel, speed,
  /// momentum, torque; body and wheel are indices, named in the summary). A single [body]'s wheels are
  /// trajectory columns instead.
  SideTable wheels;
};

/// The columns of the sensors' readings: t, then gyro.wx, gyro.wy, gyro.wz, gyro.bias_x, gyro.bias_y,
/// gyro.bias_z with a gyro, star_tracker.qw, .qx, .qy, .qz with a star tracker; empty without sensors.
std::vector<std::string> sensor_header(const Scenario& s);

/// The columns of a system's wheels.csv (SimulationResult::wheels); empty without wheels on [[bodies]].
std::vector<std::string> wheel_row_header(const Scenario& s);


/// The diagnostics of one step of one body, as a row of the single-body
/// layout (trajectory_header): t, x, q (scalar first), p, w, energy, its
/// error, |q| - 1, L and |L - L0|, then under a forcing its work W (the
/// column "work"). The one row builder of the run loop and of the Python
/// Stepper.
struct SingleBodyRow {
  double values[trajectory_columns + 1];
  int columns;  ///< trajectory_columns, or one more with the work
  SingleBodyRow(double t, const RigidBodyState& s, double energy, double energy_error, double quat_norm_error,
                const Vector3<double>& L, double momentum_error, std::optional<double> work)
      : values{t,      s.x.x(),      s.x.y(),         s.x.z(), s.q.w(), s.q.vec().x(), s.q.vec().y(),
               s.q.vec().z(), s.p.x(), s.p.y(),         s.p.z(), s.w.x(), s.w.y(),       s.w.z(),
               energy, energy_error, quat_norm_error, L.x(),   L.y(),   L.z(),         momentum_error,
               work.value_or(0.0)},
        columns(trajectory_columns + (work ? 1 : 0)) {}
};

/// The system's totals repeated in each row of the long format: the energy,
/// its error, the total linear momentum P and its error |P - P0| / sum |p_a0|
/// (absolute when every body starts at rest), the total angular momentum L
/// and |L - L0|.
struct SystemRowTotals {
  double energy, energy_error;
  Vector3<double> P;
  double linear_momentum_error;
  Vector3<double> L;
  double momentum_error;
};

/// |P - P0| / sum_a |p_a0|, or |P - P0| when every body starts at rest (scale 0): the long
/// format's linear_momentum_error.
inline double linear_momentum_error(const Vector3<double>& P, const Vector3<double>& P0, double scale) {
  const double change = (P - P0).norm();
  return scale > 0.0 ? change / scale : change;
}

/// Body a's row of the long format (bodies_trajectory_columns: t, a, x, q
/// scalar first, p, w, |q| - 1, then the totals), followed by `tail_size` <= 3
/// optional columns (the work when forced, then the thermodynamic ones), into
/// `row` (room for bodies_trajectory_columns + 3). The one row builder of a
/// system for the run loop and the Python Stepper.
inline void system_row(double t, const SystemState& s, std::size_t a, const SystemRowTotals& c, const double* tail,
                       int tail_size, double* row) {
  const auto& q = s.q[a].quaternion();
  const Vector3<double>&x = s.x[a], &p = s.p[a], &w = s.w[a];
  const double head[bodies_trajectory_columns] = {
      t,     static_cast<double>(a), x.x(),   x.y(),  x.z(),  q.w(), q.x(), q.y(), q.z(),
      p.x(), p.y(),                  p.z(),   w.x(),  w.y(),  w.z(), s.q[a].norm_error(),
      c.energy, c.energy_error, c.P.x(), c.P.y(), c.P.z(), c.linear_momentum_error,
      c.L.x(), c.L.y(), c.L.z(), c.momentum_error};
  std::copy_n(head, bodies_trajectory_columns, row);
  std::copy_n(tail, tail_size, row + bodies_trajectory_columns);
}

/// The thermodynamic columns of a scenario's trajectory (ThermoColumns): a
/// many-body scenario with a short-range pair interaction (one with a reach)
/// has the temperature, and in a box periodic along every axis the pressure.
ThermoColumns thermo_columns(const Scenario& s);

/// The degrees of freedom n_f of the temperature T = 2 K / n_f: 6 per body
/// less the 3 of the total momentum, as LAMMPS counts rigid bodies.
std::int64_t degrees_of_freedom(const Scenario& s);

/// The trajectory layout of a scenario: the single-body columns for a [body]
/// scenario, the long (per body) format for a [[bodies]] one; with the
/// bodies' shapes when the scenario's format is a particle export (xyz, vtk,
/// lammps-dump), and the time step.
TrajectoryLayout scenario_layout(const Scenario& s);

/// Runs the scenario, handing rows (every `output_every` steps, the first and
/// the last) to `sink`. Integration failures are reported in the result, not
/// thrown; the sink then holds the trajectory up to the last good step.
SimulationResult simulate(const Scenario& scenario, TrajectorySink& sink, const SimulationOptions& options = {});

/// Opens the run's trajectory sink; simulate() calls it once, before the
/// first row (for a resume, after the checkpoint has loaded).
using SinkOpener = std::function<TrajectorySink&()>;

/// The same, with the sink opened by `open_sink` only once the run can start:
/// on resume, after the checkpoint's state and stepper fields have loaded.
/// A checkpoint this lgvi cannot read (CheckpointError, naming the file and
/// the field: a body count that differs, a field it does not know or misses)
/// is thrown before open_sink is called, so a refused resume writes nothing.
SimulationResult simulate(const Scenario& scenario, const SinkOpener& open_sink, const SimulationOptions& options);

/// The same with a user's potential (e.g. written in Python) in place of the
/// scenario's [potential].
SimulationResult simulate(const Scenario& scenario, const CallablePotential& potential, TrajectorySink& sink,
                          const SimulationOptions& options = {});



}  // namespace lgvi::app
