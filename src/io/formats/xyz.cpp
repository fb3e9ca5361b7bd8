// Extended XYZ for OVITO: one frame per output step, one line per site.
//
// The header follows OVITO's XYZ reader
// (https://www.ovito.org/manual/reference/file_formats/input/xyz.html, the
// extended format): `Properties=` names the columns, and OVITO maps the names
// used here to its standard particle properties: species -> Particle Type,
// pos -> Position, orientation -> Orientation, radius -> Radius, id ->
// Particle Identifier, velo -> Velocity, omega -> Angular Velocity; `body`
// becomes a property of that name. The species is the site's type, "type1",
// "type2", ... (ParticleTextFile::site_types: the balls' types, or by radius
// where none is given, as the LAMMPS dump's types), so that OVITO colours the sites of a gas by kind, not by molecule. OVITO's Orientation is the quaternion
// (X, Y, Z, W), scalar last, in Shoemake's convention (the rotation of the
// body frame into the inertial frame, as lgvi's q): see
// https://www.ovito.org/manual/advanced_topics/aspherical_particles.html.
// So the `orientation` columns are (qx, qy, qz, qw), unlike lgvi's CSV
// (qw first).
//
// In free space, no `Lattice=`: OVITO then takes the particles' bounding box
// as a non-periodic cell, and keeps the comment line's other key=value pairs
// (Time, energy, ...) as the frame's Comment attribute (it splits them into
// attributes only when a Lattice is given); ASE's extxyz reader reads them as
// the frame's info. In a periodic box, `Lattice="Lx 0 0 0 Ly 0 0 0 Lz"`,
// `Origin="xlo ylo zlo"` and `pbc="T T F"` (per axis) give the cell, and the
// sites are wrapped into it along its periodic axes (ParticleFrames).
#include "io/formats/registry.hpp"
#include "io/formats/particles.hpp"

#include <initializer_list>
#include <string>
#include <vector>

namespace lgvi::io {

namespace {

/// The `Properties=` of the frames: the columns of each line; orientation is
/// (qx, qy, qz, qw), OVITO's order.
constexpr const char* xyz_properties =
    "Properties=species:S:1:pos:R:3:orientation:R:4:radius:R:1:body:I:1:id:I:1:velo:R:3:omega:R:3";

class XyzTrajectory final : public ParticleTextFile {
 public:
  XyzTrajectory(const std::string& path, const TrajectoryLayout& layout, const SinkPosition* resume)
      : ParticleTextFile("xyz", path, layout, resume) {}

 private:
  void format_frame(const ParticleFrame& f, std::string& text) override {
    text += std::to_string(f.particles.size());
    text.push_back('\n');
    text += xyz_properties;
    if (const Box& box = frames().box(); box.any_periodic()) {
      const Vector3<double> length = box.upper() - box.lower();
      text += " Lattice=\"";
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
          if (i + j > 0) text.push_back(' ');
          append_number(text, i == j ? length(i) : 0.0);
        }
      text += "\" Origin=\"";
      for (int i = 0; i < 3; ++i) {
        if (i > 0) text.push_back(' ');
        append_number(text, box.lower()(i));
      }
      text += "\" pbc=\"";
      for (int i = 0; i < 3; ++i) text += i > 0 ? (box.periodic(i) ? " T" : " F") : (box.periodic(i) ? "T" : "F");
      text.push_back('"');
    }
    text += " Time=";
    append_number(text, f.t);
    text += " energy=";
    append_number(text, f.energy);
    text += " energy_error=";
    append_number(text, f.energy_error);
    text += " momentum_error=";
    append_number(text, f.momentum_error);
    text += " frame=";
    text += std::to_string(f.index);
    text.push_back('\n');
    for (const Particle& p : f.particles) {
      text += "type";
      text += std::to_string(site_types()[static_cast<std::size_t>(p.site)]);
      auto numbers = [&](std::initializer_list<double> values) {
        for (double v : values) {
          text.push_back(' ');
          append_number(text, v);
        }
      };
      numbers({p.position[0], p.position[1], p.position[2], p.q[1], p.q[2], p.q[3], p.q[0], p.radius});
      text.push_back(' ');
      text += std::to_string(p.body);
      text.push_back(' ');
      text += std::to_string(p.site);
      numbers({p.velocity[0], p.velocity[1], p.velocity[2], p.omega[0], p.omega[1], p.omega[2]});
      text.push_back('\n');
    }
  }
};

std::unique_ptr<TrajectorySink> open_xyz(const std::string& path, const TrajectoryLayout& layout,
                                         const SinkPosition* resume) {
  return std::make_unique<XyzTrajectory>(path, layout, resume);
}

}  // namespace

extern const FormatDescriptor xyz_format;  // listed in formats/registry.cpp
const FormatDescriptor xyz_format{.name = "xyz", .file_name = "trajectory.xyz", .holds_columns = false, .open = open_xyz};

}  // namespace lgvi::io
