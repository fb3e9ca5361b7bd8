// `lgvi ensemble`: many runs of one scenario with some of its numbers varied
// (parameter sweeps and Monte Carlo), on the threads of one process or the
// ranks of an MPI job, with results that do not depend on either.
//
// A sweep file names a base scenario and [[vary]] entries: a dotted key of
// the scenario ("initial.omega", "integrator.step", "bodies.primary.omega")
// and either random draws (normal, uniform, a uniformly random rotation) or
// a grid of values. Member i's scenario is the base with the drawn or grid
// values written in; every member's scenario is read by the reader of
// `lgvi run` before any member starts. Random draws come from (seed, member
// index, vary index, component) through a counter-based generator, so a
// member's numbers do not depend on which thread or rank runs it, or when.
//
// Results: one CSV row per member (members.csv, in member order): the index,
// the varied values, completed, error, steps and the run's error maxima, and
// the final state of every body. Rows are appended to a journal as members
// finish (in any order); members.csv is written sorted from it, at the end
// and when stopped, and `--resume` runs only the members without a row.
#pragma once

#include "app/progress_line.hpp"
#include "app/scenario.hpp"
#include "app/stop_signals.hpp"

#include <chrono>
#include <cstdint>
#include <limits>
#include <utility>
#include <ostream>
#include <string>
#include <vector>

namespace lgvi::app {

/// One [[vary]] entry.
struct VarySpec {
  /// AttitudeError: a rotation about a uniformly random axis by a normally distributed angle (standard
  /// deviation a[0] degrees), composed with the base's attitude; its values are the angle (deg, >= 0)
  /// and the axis (body frame).
  enum class Kind { Normal, Uniform, Values, RandomRotation, AttitudeError };
  std::string key;  ///< dotted key of the scenario
  Kind kind = Kind::Values;
  std::vector<double> a, b;                 ///< normal: mean, std; uniform: low, high (one per component)
  std::vector<std::vector<double>> values;  ///< a grid: each value's components
  bool scalar = false;                      ///< a number rather than an array
  bool integer = false;                     ///< a grid of TOML integers: written as integers (e.g. an order)
  std::size_t components() const;
};

/// [ensemble] metrics: what each member's row records for guidance, navigation and control, after its
/// error columns, in the order given (docs/guide/ensembles.md):
///   pointing_error_deg  the angle of q_target^* q at the end (the attitude controller's target), deg
///   settling_time       the first time from which the pointing error stays within settle_band_deg
///                       to the end, checked at every step (NaN if it ends outside the band)
///   max_wheel_torque    the largest |motor torque| applied to any wheel (N m)
///   max_wheel_speed     the largest |speed| of any wheel relative to the body (rad/s)
///   saturation_time     the time during which at least one wheel was at a limit (s)
///   control_effort      the motors' total torque impulse sum_i int |u_i| dt (N m s)
/// A member that did not complete has NaN in them. With a pointing metric, each member's pointing error
/// at the base scenario's output frames goes to pointing_error.csv.
struct MemberMetrics {
  std::vector<std::string> names;
  double settle_band_deg = std::numeric_limits<double>::quiet_NaN();
  /// Whether the pointing error is measured (pointing_error_deg or settling_time).
  bool pointing() const;
};

/// A sweep file, read and checked, with every member's varied values.
struct EnsemblePlan {
  std::string name;           ///< the sweep file's stem
  std::string sweep_text;     ///< the sweep file, as read (kept in the output folder for --resume)
  std::string scenario_text;  ///< the base scenario's text
  std::string scenario_name;  ///< the base scenario's stem
  std::uint64_t seed = 0;
  bool keep_trajectories = false;
  std::vector<VarySpec> vary;
  std::vector<std::string> varied_columns;  ///< header names of the varied values (key or key[i])
  std::vector<std::vector<double>> varied;  ///< per member, the varied values in column order
  std::string header;                       ///< members.csv's header line (no newline)
  /// The members.csv columns named "..._error" that measure a change, not an
  /// error of the method: a momentum that some member's dynamics does not
  /// conserve (a forcing or an external field; conservation_laws), as
  /// summary.json's conserved.changes_not_errors says for one run.
  std::vector<std::string> changes_not_errors;
  /// The members run a [[forcing]]: their max_abs_energy_error is of E - E0 - W (W the forcing's work).
  bool forced = false;
  TrajectoryFormat output_format;  ///< the base scenario's: its members table (members.npz, .h5) beside the CSV
  MemberMetrics metrics;           ///< [ensemble] metrics (none: the rows have none)
  /// [ensemble] sensor_noise = "per-member" (default): each member's [[sensor]] seeds are drawn from its
  /// index and the base's seeds (member_toml writes them), so members see independent noise; "shared":
  /// every member keeps the base's seeds (the same noise: paired comparisons of, e.g., gains).
  bool shared_sensor_noise = false;
  /// With pointing metrics: the times of the base's output frames, at which each row carries its
  /// member's pointing error (deg) after the members.csv columns (split_row); every member has them.
  std::vector<double> series_times;
  std::size_t header_fields = 0;  ///< the fields of `header` (members.csv's columns), for split_row
  /// A row (journal.csv, run_member) as its members.csv row and the pointing errors after it (empty
  /// without series_times).
  std::pair<std::string, std::string> split_row(const std::string& row) const;

  std::int64_t members() const { return static_cast<std::int64_t>(varied.size()); }
  /// Member i's scenario as TOML text (the base with the varied values written in).
  std::string member_toml(std::int64_t i) const;
};

/// Reads the sweep file at `path` (its scenario relative to it); checks every
/// member's scenario with the reader of `lgvi run`. Throws InvalidInput with
/// one line naming the key (and the member's index for a member's scenario).
EnsemblePlan read_ensemble(const std::string& path);

/// The same from the sweep's text; `base_dir` resolves its scenario path.
EnsemblePlan parse_ensemble(const std::string& sweep_text, const std::string& name, const std::string& base_dir);

/// The same with the base scenario's text given (the sweep's `scenario`
/// key then only names it): the Python package's entry.
EnsemblePlan parse_ensemble_text(const std::string& sweep_text, const std::string& name,
                                 const std::string& scenario_text);

/// Runs member i of the plan (its scenario with per-body threads `threads`)
/// and returns its members.csv row (no newline). A failed run is a row with
/// completed = 0 and its message; with `trajectory_dir` non-empty the
/// member's trajectory, summary and scenario copy go there.
std::string run_member(const EnsemblePlan& plan, std::int64_t i, int threads = 1,
                       const std::string& trajectory_dir = {});

/// The same from the member's index, varied values and scenario text alone
/// (what a worker process of the Python package receives).
std::string run_member_scenario(std::int64_t index, const std::vector<double>& varied, const std::string& scenario_toml,
                                const std::string& scenario_name, int threads = 1,
                                const std::string& trajectory_dir = {}, const MemberMetrics& metrics = {});

struct EnsembleOptions {
  std::string out_dir;
  int threads = 0;  ///< members run at once in this process (0: all cores)
  bool resume = false;
  bool quiet = false;
  bool figures = true;  ///< draw the figures (lgvi.plot) when the ensemble is complete
  /// Show the progress line even when stderr is not a terminal (under
  /// mpirun, a rank's stderr is a pipe to mpirun, which passes it on).
  bool progress = false;
};

/// `lgvi ensemble SWEEP --out DIR` / `lgvi ensemble --resume DIR`: runs the
/// members on threads, or on the ranks of an MPI job when started by mpirun
/// (rank 0 hands out members and writes). Returns the exit status.
int run_ensemble(const std::string& sweep_path, const EnsembleOptions& options);

/// `lgvi show DIR` of an ensemble folder: counts, failures, quantiles.
void show_ensemble(const std::string& dir, std::ostream& out);

// The parts the MPI runner (ensemble_mpi.cpp) shares with the threads.
namespace ensemble_detail {

/// A plan with its output folder and the rows already done.
struct Prepared {
  EnsemblePlan plan;
  std::string dir;
  std::vector<std::string> rows;  ///< per member, its row or "" (not run yet)
};

/// Reads the sweep (or, resuming, the folder's copies of it and its base
/// scenario), checks every member, creates the folder (refusing one that
/// already holds an ensemble) and reads its journal.
Prepared prepare(const std::string& sweep_path, const EnsembleOptions& options);
/// The plan from an ensemble folder's copies (--resume; ranks other than 0).
/// check_members false reads member 0's scenario only: ranks other than 0
/// use the plan rank 0 has checked, so their start-up does not grow with the
/// number of members.
EnsemblePlan plan_of_folder(const std::string& dir, bool check_members = true);
/// Appends a row to the journal and flushes it (what rank 0 has is on disk).
void append_journal(const std::string& dir, const std::string& row);
/// Appends member `index`'s wall time (seconds: reading its scenario and
/// running it) and the rank that ran it (0 on threads) to DIR/timings.csv,
/// in the order members finish; writes its header first if the file is new.
/// Kept apart from members.csv, which must not depend on the run's timing.
void append_timing(const std::string& dir, std::int64_t index, double seconds, int rank);
/// Cuts the journal's last line if it is torn (no newline: the process died
/// while writing it), so that the next row appended starts a line of its own.
/// The same for timings.csv.
void cut_torn_line(const std::string& dir);
/// The progress line on a terminal (stderr): members done / total, failures,
/// rate and time left. Shown unless quiet, when stderr is a terminal or when
/// asked for (--progress).
class EnsembleProgress {
 public:
  EnsembleProgress(const EnsembleOptions& options, std::int64_t total, std::int64_t done);
  void operator()(std::int64_t done, std::int64_t failed);

 private:
  ProgressLine line_;
  std::int64_t total_, start_done_;
};
/// members.csv: the header and every row present, in member order; and,
/// when the base scenario's [output] format is npz or hdf5, members.npz or
/// members.h5 with the same columns (one array each: int64 index, completed
/// and steps, the error messages as strings, float64 the rest) and the same
/// numbers (the CSV's 17 digits read back are the same doubles).
void write_members(const std::string& dir, const EnsemblePlan& plan, const std::vector<std::string>& rows);
/// Whether a row records a failed run (completed = 0).
bool row_failed(const std::string& row, const EnsemblePlan& plan);
/// Where member i's run folder goes ("" unless trajectories = "all").
std::string trajectory_dir(const std::string& dir, const EnsemblePlan& plan, std::int64_t i);
/// Member i's row (run_member on one thread, its run folder under `dir`)
/// and the wall time of reading its scenario and running it, in seconds
/// (what timings.csv records).
struct TimedRow {
  std::string row;  ///< "" if stopped by a signal within the member
  double seconds = 0.0;
};
TimedRow run_member_timed(const EnsemblePlan& plan, std::int64_t i, const std::string& dir);
/// The final report and exit status (130/143 when stopped by a signal).
int finish(const Prepared& p, std::int64_t done, std::int64_t failed, const EnsembleOptions& options);

}  // namespace ensemble_detail

/// Whether this process was started by mpirun/srun as one of several ranks.
bool launched_as_mpi_rank();

/// The MPI runner (ensemble_mpi.cpp, part of the command-line tool when
/// built with MPI): rank 0 prepares the folder, hands out members to
/// whichever rank asks and writes; every rank runs members.
int run_ensemble_mpi(const std::string& sweep_path, const EnsembleOptions& options);

/// run_ensemble() hands a run started as several MPI ranks to this runner;
/// the `lgvi ensemble` command (cli/ensemble_command.cpp) sets it in a build with MPI. Without one, such a run is refused
/// (one line, status 2) instead of running the ensemble once per rank.
using MpiRunner = int (*)(const std::string& sweep_path, const EnsembleOptions& options);
void set_mpi_runner(MpiRunner runner);

}  // namespace lgvi::app
