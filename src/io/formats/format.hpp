// The trajectory format a scenario names (`[output] format`) as a value, and
// the IDs a data file gave its bodies: what the scenario model holds of the
// output layer, without it (the descriptors, the sinks and the layouts are
// formats/registry.hpp's and trajectory_sink.hpp's).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace lgvi::app {

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

/// The IDs a data file gave the bodies and their sites (an [import]'s:
/// app/lammps_data.hpp), which the LAMMPS dump writes in place of its own
/// numbering.
struct FileIds {
  std::vector<std::int64_t> molecule;  ///< per body
  std::vector<std::int64_t> atom;      ///< per site, the bodies' balls in order
  bool empty() const { return molecule.empty(); }
};

}  // namespace lgvi::app
