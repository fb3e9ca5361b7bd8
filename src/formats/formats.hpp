// Trajectory formats beside CSV: numpy's .npz (written without numpy), HDF5,
// and the particle exports for viewers, extended XYZ (OVITO) and VTK XML
// (ParaView).
#pragma once

#include "trajectory_sink.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace lgvi::app {

/// `path`.npz with entries trajectory.npy (float64, shape (rows, columns), or
/// (steps, bodies, columns) for the long layout, C order), columns.npy (the
/// column names), scenario.npy and summary.npy (0-d unicode arrays holding
/// the scenario's TOML and the summary's JSON).
std::unique_ptr<TrajectorySink> open_npz(const std::string& path, const TrajectoryLayout& layout,
                                         const SinkPosition* resume);

/// `path`.h5 with a chunked, extendible dataset /trajectory (float64,
/// (rows, columns), or (steps, bodies, columns) for the long layout), its
/// attribute `columns`, and root attributes `scenario` and `summary` (strings).
std::unique_ptr<TrajectorySink> open_hdf5(const std::string& path, const TrajectoryLayout& layout,
                                          const SinkPosition* resume);

/// The `Properties=` of the extended XYZ frames: the columns of each line.
/// orientation is (qx, qy, qz, qw), OVITO's order (formats/xyz.cpp).
inline constexpr const char* xyz_properties =
    "Properties=species:S:1:pos:R:3:orientation:R:4:radius:R:1:body:I:1:id:I:1:velo:R:3:omega:R:3";

/// `path` (.xyz): extended XYZ, one frame per output step, one line per site
/// (ball) of every body; needs layout.shapes. Resumes by truncation, like CSV.
std::unique_ptr<TrajectorySink> open_xyz(const std::string& path, const TrajectoryLayout& layout,
                                         const SinkPosition* resume);

/// `path` (.pvd): a ParaView collection indexing one VTK XML PolyData file per
/// output step in the folder named like `path` without its extension; needs
/// layout.shapes. The .pvd's closing tags are written by close().
std::unique_ptr<TrajectorySink> open_vtk(const std::string& path, const TrajectoryLayout& layout,
                                         const SinkPosition* resume);

/// A table of named columns of equal length, each of numbers (float64),
/// integers (int64) or strings: the ensemble's members table.
struct ColumnTable {
  struct Column {
    enum class Kind { Number, Integer, String };
    std::string name;
    Kind kind = Kind::Number;
    std::vector<double> numbers;        ///< Kind::Number
    std::vector<std::int64_t> integers;  ///< Kind::Integer
    std::vector<std::string> strings;   ///< Kind::String (UTF-8)
    std::size_t size() const {
      return kind == Kind::Number ? numbers.size() : kind == Kind::Integer ? integers.size() : strings.size();
    }
  };
  std::vector<Column> columns;
};

/// `path` (.npz): one 1-D array per column, named by it ('<f8', '<i8' or
/// '<U', numpy's loader gives float64, int64 and str arrays), stored
/// uncompressed in column order. Written whole to a temporary name and
/// renamed: never half-written. The bytes depend on the table alone.
void write_npz_table(const std::string& path, const ColumnTable& table);

/// `path` (.h5): one 1-D dataset per column at the root (IEEE float64 LE,
/// int64 LE, variable-length UTF-8 strings), no timestamps, written to a
/// temporary name and renamed.
void write_hdf5_table(const std::string& path, const ColumnTable& table);

}  // namespace lgvi::app
