// [output] format = "lammps-dump": the sites of every body as a LAMMPS text
// dump (the layout of LAMMPS's `dump custom`), which OVITO, VMD and LAMMPS's
// own read_dump and rerun read. One block per output step:
//
//   ITEM: TIMESTEP               the step k = round(t / h)
//   <k>
//   ITEM: NUMBER OF ATOMS
//   <sites>
//   ITEM: BOX BOUNDS ss ss ss    per axis: "pp" along a periodic axis of the
//   <xlo> <xhi>                  [box], its lower and upper bounds; "ss"
//   <ylo> <yhi>                  (shrink-wrapped) along an open one: the extent
//   <zlo> <zhi>                  of the sites' spheres (c -+ radius), widened by
//                                0.5 each way where it is flat (LAMMPS refuses
//                                lo = hi)
//   ITEM: ATOMS id mol type x y z ix iy iz
//   <id> <mol> <type> <x> <y> <z> <ix> <iy> <iz>    one line per site
//
// id numbers the sites of a frame from 1, mol the bodies from 1 (the bodies'
// order in the scenario); for bodies read from a LAMMPS data file ([import]),
// id and mol are the file's atom and molecule IDs (mol 0 for its atoms of
// molecule 0, as there). type the site's type (Ball::type, a data
// file's atom type) where the scenario gives any; else the site radii from 1
// in order of first appearance, so that a viewer's per-type radius draws
// every site at its size (one type for a gas of identical molecules). Coordinates
// are x + R(q) rho with 17 significant digits, exactly the extended XYZ
// export's positions: each site wrapped into the box along its periodic axes
// with its image counts (LAMMPS's convention: unwrapped = x + ix (xhi - xlo)),
// as it is with image 0 along open axes.
// Resumes by truncation, as the XYZ export.
#include "io/formats/particles.hpp"
#include "io/formats/registry.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace lgvi::io {

namespace {

class LammpsDump final : public ParticleTextFile {
 public:
  LammpsDump(const std::string& path, const TrajectoryLayout& layout, const SinkPosition* resume)
      : ParticleTextFile("lammps-dump", path, layout, resume), step_(layout.step), ids_(layout.ids) {
    std::size_t sites = 0;
    for (const BodyShape& shape : layout.shapes) sites += shape.sites.size();
    if (!ids_.empty() && (ids_.molecule.size() != layout.shapes.size() || ids_.atom.size() != sites))
      throw std::logic_error("lammps-dump: the data file's IDs do not match the bodies and sites");
  }

 private:
  void format_frame(const ParticleFrame& f, std::string& text) override {
    const long long k = step_ > 0.0 ? std::llround(f.t / step_) : static_cast<long long>(f.index);
    text += "ITEM: TIMESTEP\n" + std::to_string(k) + "\nITEM: NUMBER OF ATOMS\n" +
            std::to_string(f.particles.size()) + "\nITEM: BOX BOUNDS";
    const Box& box = frames().box();
    for (int axis = 0; axis < 3; ++axis) text += box.periodic(axis) ? " pp" : " ss";
    text.push_back('\n');
    for (std::size_t axis = 0; axis < 3; ++axis) {
      if (box.periodic(static_cast<int>(axis))) {
        append_number(text, box.lower()(static_cast<int>(axis)));
        text.push_back(' ');
        append_number(text, box.upper()(static_cast<int>(axis)));
        text.push_back('\n');
        continue;
      }
      double lo = 0.0, hi = 0.0;
      for (std::size_t i = 0; i < f.particles.size(); ++i) {
        const Particle& p = f.particles[i];
        lo = i == 0 ? p.position[axis] - p.radius : std::min(lo, p.position[axis] - p.radius);
        hi = i == 0 ? p.position[axis] + p.radius : std::max(hi, p.position[axis] + p.radius);
      }
      if (!(hi > lo)) {  // points in a plane (or no sites): a box of width 1 about them
        lo -= 0.5;
        hi += 0.5;
      }
      append_number(text, lo);
      text.push_back(' ');
      append_number(text, hi);
      text.push_back('\n');
    }
    text += "ITEM: ATOMS id mol type x y z ix iy iz\n";
    for (const Particle& p : f.particles) {
      const auto site = static_cast<std::size_t>(p.site), body = static_cast<std::size_t>(p.body);
      text += ids_.empty() ? std::to_string(p.site + 1) + ' ' + std::to_string(p.body + 1)
                           : std::to_string(ids_.atom[site]) + ' ' + std::to_string(ids_.molecule[body]);
      text += ' ' + std::to_string(site_types()[site]);
      for (const double c : p.position) {
        text.push_back(' ');
        append_number(text, c);
      }
      for (const std::int64_t n : p.image) {
        text.push_back(' ');
        text += std::to_string(n);
      }
      text.push_back('\n');
    }
  }

  double step_;
  FileIds ids_;  ///< a data file's atom and molecule IDs (empty: sites and bodies numbered from 1)
};

std::unique_ptr<TrajectorySink> open_lammps_dump(const std::string& path, const TrajectoryLayout& layout,
                                                 const SinkPosition* resume) {
  return std::make_unique<LammpsDump>(path, layout, resume);
}

}  // namespace

extern const FormatDescriptor lammps_dump_format;  // listed in formats/registry.cpp
const FormatDescriptor lammps_dump_format{
    .name = "lammps-dump", .file_name = "trajectory.lammpstrj", .holds_columns = false, .writes_file_ids = true,
    .open = open_lammps_dump};

}  // namespace lgvi::io
