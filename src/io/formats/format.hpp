// The trajectory format a scenario names (`[output] format`) as a value, the
// layout of its rows (`[output] layout`), and the IDs a data file gave its
// bodies: what the scenario model holds of the output layer, without it (the
// descriptors, the sinks and the columns are formats/registry.hpp's and
// trajectory_sink.hpp's).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace lgvi::io {

struct FormatDescriptor;  // formats/registry.hpp

/// Every format, in registration order (formats/registry.cpp); the first is the default.
std::span<const FormatDescriptor* const> trajectory_formats();

/// A registered format (a value: compares by which format it is). Default:
/// the first registered, CSV.
class TrajectoryFormat {
 public:
  TrajectoryFormat() : descriptor_(trajectory_formats().front()) {}
  /// The format of that name; throws InvalidInput naming `where` (e.g.
  /// "output.format") and the registered names if there is none.
  static TrajectoryFormat named(std::string_view name, const std::string& where = "output.format");
  const FormatDescriptor& descriptor() const { return *descriptor_; }
  bool operator==(const TrajectoryFormat& o) const { return descriptor_ == o.descriptor_; }

 private:
  explicit TrajectoryFormat(const FormatDescriptor* d) : descriptor_(d) {}
  const FormatDescriptor* descriptor_;
};

/// How a trajectory's rows are laid out ([output] layout), in every format.
enum class RowLayout {
  /// "single-body": one row a written step with one body's state and the
  /// run's diagnostics (trajectory_sink.hpp's trajectory_header); 2-D arrays
  /// in npz and HDF5. The default of a [body] scenario; one body only.
  single_body,
  /// "long": one row a written step and body, the body's index and state,
  /// then the system's diagnostics (bodies_trajectory_header); arrays shaped
  /// (steps, N, columns) in npz and HDF5. The default of [[bodies]].
  long_format,
};
/// The scenario key's values, as RowLayout orders them.
inline constexpr const char* row_layout_names[] = {"single-body", "long"};
inline const char* to_string(RowLayout l) { return row_layout_names[static_cast<int>(l)]; }

/// The IDs a data file gave the bodies and their sites (an [import]'s:
/// app/lammps_data.hpp), which the LAMMPS dump writes in place of its own
/// numbering.
struct FileIds {
  std::vector<std::int64_t> molecule;  ///< per body
  std::vector<std::int64_t> atom;      ///< per site, the bodies' balls in order
  bool empty() const { return molecule.empty(); }
};

}  // namespace lgvi::io
