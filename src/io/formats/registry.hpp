// The trajectory formats `[output] format` can name: each one a descriptor
// (its name, its file in a run folder, whether it holds the trajectory's
// columns, how its file is opened, and the ensemble's members table in it if
// it has one), defined in the file that writes the format (formats/csv.cpp,
// npz.cpp, ...) and listed once in formats/registry.cpp. The scenario reader,
// the run, the ensemble and the Python module's FORMATS go through this table
// only: a new format is its file and its line in registry.cpp.
#pragma once

#include "io/formats/format.hpp"
#include "io/trajectory_sink.hpp"

#include <cstdint>
#include <cstdio>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace lgvi::io {

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

/// One trajectory format.
struct FormatDescriptor {
  std::string_view name;       ///< [output] format = "..."
  std::string_view file_name;  ///< the trajectory's file in a run folder
  /// Whether the file holds the trajectory's columns, which lgvi.load and the
  /// figures read; the others are exports of the bodies' sites for viewers.
  bool holds_columns = true;
  /// Whether the file writes a data file's atom and molecule IDs
  /// (TrajectoryLayout::ids, an imported system's): only then are they copied
  /// into the layout.
  bool writes_file_ids = false;
  /// Opens a new file (truncating), or, with `resume`, reopens one and
  /// truncates it back to that position to append. Throws std::runtime_error
  /// naming the file on failure.
  std::unique_ptr<TrajectorySink> (*open)(const std::string& path, const TrajectoryLayout& layout,
                                          const SinkPosition* resume) = nullptr;
  /// The ensemble's members table in this format, written beside members.csv
  /// as `table_file_name` (whole, to a temporary name and renamed), or null
  /// if members.csv is all the format asks for.
  void (*write_table)(const std::string& path, const ColumnTable& table) = nullptr;
  std::string_view table_file_name = {};
};

/// The scenario name of a format ("csv", ...).
inline const char* to_string(TrajectoryFormat f) { return f.descriptor().name.data(); }

/// The file name of the trajectory in a run folder.
inline const char* trajectory_file_name(TrajectoryFormat f) { return f.descriptor().file_name.data(); }

/// Whether the format holds the trajectory's columns (FormatDescriptor::holds_columns).
inline bool holds_columns(TrajectoryFormat f) { return f.descriptor().holds_columns; }
/// Whether the format writes an imported system's IDs (FormatDescriptor::writes_file_ids).
inline bool writes_file_ids(TrajectoryFormat f) { return f.descriptor().writes_file_ids; }

/// FormatDescriptor::open of the format.
std::unique_ptr<TrajectorySink> open_trajectory(TrajectoryFormat format, const std::string& path,
                                                const TrajectoryLayout& layout = {},
                                                const SinkPosition* resume = nullptr);
/// The single-body layout.
inline std::unique_ptr<TrajectorySink> open_trajectory(TrajectoryFormat format, const std::string& path,
                                                       const SinkPosition* resume) {
  return open_trajectory(format, path, TrajectoryLayout::single_body(), resume);
}

/// The file of a format that appends to one file (csv, xyz, lammps-dump):
/// new and empty, or on resume truncated back to the checkpoint's
/// `resume->bytes` and opened for appending. Throws std::runtime_error
/// naming the file when it cannot be truncated or opened, or is missing or
/// shorter than `resume->bytes`.
std::FILE* open_appendable_file(const std::string& path, const SinkPosition* resume);

}  // namespace lgvi::io
