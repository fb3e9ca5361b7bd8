// The format registry's table (formats/registry.hpp): one line per format,
// its descriptor defined in the format's own file.
#include "formats/registry.hpp"

#include "toml_reader.hpp"  // printable

#include <lgvi/error.hpp>

#include <array>

namespace lgvi::app {

extern const FormatDescriptor csv_format, npz_format, hdf5_format, xyz_format, vtk_format, lammps_dump_format;

namespace {
// The order of [output] format's list, --help and lgvi.FORMATS; the first is the default.
const std::array<const FormatDescriptor*, 6> registered_formats{&csv_format, &npz_format, &hdf5_format,
                                                                &xyz_format, &vtk_format, &lammps_dump_format};
}  // namespace

std::span<const FormatDescriptor* const> trajectory_formats() { return registered_formats; }

TrajectoryFormat TrajectoryFormat::named(std::string_view name, const std::string& where) {
  std::string list;
  for (const FormatDescriptor* d : registered_formats) {
    if (d->name == name) return TrajectoryFormat(d);
    list += (list.empty() ? "\"" : ", \"") + std::string(d->name) + "\"";
  }
  throw InvalidInput("key '" + where + "': \"" + printable(name) + "\" is not one of " + list);
}

std::unique_ptr<TrajectorySink> open_trajectory(TrajectoryFormat format, const std::string& path,
                                                const TrajectoryLayout& layout, const SinkPosition* resume) {
  return format.descriptor().open(path, layout, resume);
}

}  // namespace lgvi::app
