// The format registry's table (formats/registry.hpp): one line per format,
// its descriptor defined in the format's own file.
#include "io/formats/registry.hpp"

#include "io/toml_reader.hpp"  // printable

#include <lgvi/error.hpp>

#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <stdexcept>

namespace lgvi::io {

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

std::FILE* open_appendable_file(const std::string& path, const SinkPosition* resume) {
  std::FILE* file = nullptr;
  if (resume) {
    std::error_code ec;
    // Shorter than the checkpoint recorded: not the file the run wrote (resizing would pad it with zeros).
    const std::uintmax_t size = std::filesystem::file_size(path, ec);
    if (ec) throw std::runtime_error("cannot resume " + path + ": " + ec.message());
    if (size < static_cast<std::uintmax_t>(resume->bytes))
      throw std::runtime_error("cannot resume " + path + ": it holds " + std::to_string(size) +
                               " bytes, fewer than the " + std::to_string(resume->bytes) +
                               " the checkpoint recorded; it was cut or replaced since");
    std::filesystem::resize_file(path, static_cast<std::uintmax_t>(resume->bytes), ec);
    if (ec) throw std::runtime_error("cannot truncate " + path + " to resume: " + ec.message());
    file = std::fopen(path.c_str(), "ab");
  } else {
    file = std::fopen(path.c_str(), "wb");
  }
  if (!file) throw std::runtime_error("cannot write " + path + ": " + std::strerror(errno));
  return file;
}

}  // namespace lgvi::io
