// Where a run's trajectory rows go: the columns and layout of the rows, and
// the interface every format's sink implements (the formats and their
// registry: formats/; for the Python package, memory). One interface, so that
// the run loop, checkpoints and resume do not depend on the format.
#pragma once

#include "io/formats/format.hpp"

#include <lgvi/box.hpp>

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace lgvi::io {

/// The trajectory's columns of the single-body layout, in order, in every format.
inline constexpr const char* trajectory_header =
    "t,x,y,z,qw,qx,qy,qz,px,py,pz,wx,wy,wz,energy,energy_error,quat_norm_error,Lx,Ly,Lz,momentum_error";
inline constexpr int trajectory_columns = 21;

/// The columns of a [[bodies]] scenario's trajectory, the long format: one
/// row per output step and body, with the body's index and state, its
/// |q| - 1, then the system's energy, energy error, total linear momentum P,
/// its error |P - P0| / sum |p_a0|, total angular momentum L about the origin
/// and its error |L - L0| (the same on every row of a step).
inline constexpr const char* bodies_trajectory_header =
    "t,body,x,y,z,qw,qx,qy,qz,px,py,pz,wx,wy,wz,quat_norm_error,energy,energy_error,Px,Py,Pz,"
    "linear_momentum_error,Lx,Ly,Lz,momentum_error";
inline constexpr int bodies_trajectory_columns = 26;

/// A forced scenario's ([[forcing]]) columns: the above and the work W done
/// by the forcing since t = 0 (energy_error is then E - E0 - W).
inline constexpr const char* forced_trajectory_header =
    "t,x,y,z,qw,qx,qy,qz,px,py,pz,wx,wy,wz,energy,energy_error,quat_norm_error,Lx,Ly,Lz,momentum_error,work";
inline constexpr const char* forced_bodies_trajectory_header =
    "t,body,x,y,z,qw,qx,qy,qz,px,py,pz,wx,wy,wz,quat_norm_error,energy,energy_error,Px,Py,Pz,"
    "linear_momentum_error,Lx,Ly,Lz,momentum_error,work";

/// The thermodynamic columns a molecular run (a short-range pair
/// interaction between the bodies' sites) ends the long layout's rows with,
/// after "work" when forced: the kinetic temperature, and in a box periodic
/// along every axis the pressure (the same on every row of a step).
enum class ThermoColumns { none, temperature, temperature_and_pressure };
inline constexpr const char* temperature_column = "temperature";
inline constexpr const char* pressure_column = "pressure";

/// One sphere of a body as the particle exports (xyz, vtk, lammps-dump) draw it: its
/// centre in the body frame (about the centre of mass), its radius and its
/// site type (Ball::type: 1, 2, ...).
struct Site {
  std::array<double, 3> rho{};
  double radius = 0.0;
  int type = 1;
};

/// What the particle exports need of a body beyond the trajectory's rows:
/// they write sites (balls), not bodies, and the rows hold only each body's
/// centre of mass, quaternion, momentum p and w = 2 J Omega.
struct BodyShape {
  std::string name;  ///< the body's name (the XYZ species)
  double mass = 1.0;
  /// J^-1, row-major: the angular velocity Omega = J^-1 w / 2 (body frame).
  std::array<double, 9> inertia_inverse{};
  /// One per ball; a body given by mass and inertia has one site at its
  /// centre of mass, with the radius of the uniform sphere of its mean
  /// moment (tr J / 3 = 2/5 m r^2).
  std::vector<Site> sites;
};

/// What a trajectory file holds: the column names, and how many rows make
/// one output step (RowLayout: 1 in the single-body layout; N, one per body,
/// in the long layout, whose npz and HDF5 arrays are then shaped
/// (steps, N, columns)).
struct TrajectoryLayout {
  std::string header = trajectory_header;
  int columns = trajectory_columns;
  std::int64_t bodies = 0;  ///< 0: the single-body layout, 2-D arrays; N >= 1: the long layout
  /// The bodies' shapes, one per row of a step: needed by the particle
  /// exports (xyz, vtk, lammps-dump) only; the other formats ignore them.
  std::vector<BodyShape> shapes = {};
  /// The time step h, by which the LAMMPS dump numbers its frames' steps
  /// (round(t / h)); 0 if unknown, then they are numbered by output index.
  double step = 0.0;
  /// The system's box: the particle exports wrap each site into it along
  /// its periodic axes (with image counts) and draw it; the other formats
  /// write the centres of mass unwrapped.
  Box box = {};
  /// The bodies' and sites' IDs in the data file they were read from (empty: none).
  FileIds ids = {};

  static TrajectoryLayout single_body(bool forced = false) {
    if (forced) return {forced_trajectory_header, trajectory_columns + 1, 0};
    return {};
  }
  static TrajectoryLayout long_format(std::int64_t n, bool forced = false, ThermoColumns thermo = ThermoColumns::none) {
    TrajectoryLayout layout{forced ? forced_bodies_trajectory_header : bodies_trajectory_header,
                            bodies_trajectory_columns + (forced ? 1 : 0), n};
    if (thermo != ThermoColumns::none) {
      layout.header += std::string(",") + temperature_column;
      ++layout.columns;
    }
    if (thermo == ThermoColumns::temperature_and_pressure) {
      layout.header += std::string(",") + pressure_column;
      ++layout.columns;
    }
    return layout;
  }
  RowLayout row_layout() const { return bodies > 0 ? RowLayout::long_format : RowLayout::single_body; }
  /// Rows per output step.
  std::int64_t rows_per_step() const { return bodies > 0 ? bodies : 1; }
  /// The column names: `header` split at its commas.
  std::vector<std::string> column_names() const {
    std::vector<std::string> names;
    std::size_t from = 0;
    for (std::size_t comma; (comma = header.find(',', from)) != std::string::npos; from = comma + 1)
      names.push_back(header.substr(from, comma - from));
    names.push_back(header.substr(from));
    return names;
  }
};

/// How far a file has been written, as returned by TrajectorySink::sync() and
/// kept in a checkpoint; a resumed run truncates the file back to it. The
/// meaning of the fields is the format's own (CSV and npz: bytes of the file
/// and the CRC-32 of the data so far; HDF5: rows; xyz: bytes; vtk: bytes of
/// the .pvd index and rows, which number the frame files).
struct SinkPosition {
  std::int64_t rows = 0;
  std::int64_t bytes = 0;
  std::uint32_t crc32 = 0;
};

class TrajectorySink {
 public:
  virtual ~TrajectorySink() = default;
  /// Appends one row of layout.columns values.
  virtual void row(const double* values) = 0;
  /// Makes every row so far durable in the file and says where it ends.
  virtual SinkPosition sync() = 0;
  /// Completes the file. The scenario (TOML text) and the summary (JSON text)
  /// are stored with the trajectory where the format allows (npz entries,
  /// HDF5 attributes); CSV has them as side files (scenario.toml,
  /// summary.json). Throws std::runtime_error on a write error.
  virtual void close(const std::string& scenario_toml, const std::string& summary_json) = 0;
  /// Whether close() stores the summary (else it is given "": a large
  /// system's summary need not be made in memory for it).
  virtual bool stores_summary() const { return false; }
};

}  // namespace lgvi::io
