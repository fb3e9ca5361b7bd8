// Extended XYZ for OVITO: one frame per output step, one line per site.
//
// The header follows OVITO's XYZ reader
// (https://www.ovito.org/manual/reference/file_formats/input/xyz.html, the
// extended format): `Properties=` names the columns, and OVITO maps the names
// used here to its standard particle properties: species -> Particle Type,
// pos -> Position, orientation -> Orientation, radius -> Radius, id ->
// Particle Identifier, velo -> Velocity, omega -> Angular Velocity; `body`
// becomes a property of that name. OVITO's Orientation is the quaternion
// (X, Y, Z, W), scalar last, in Shoemake's convention (the rotation of the
// body frame into the inertial frame, as lgvi's q): see
// https://www.ovito.org/manual/advanced_topics/aspherical_particles.html.
// So the `orientation` columns are (qx, qy, qz, qw), unlike lgvi's CSV
// (qw first).
//
// No `Lattice=`: the runs are not periodic. OVITO then takes the particles'
// bounding box as a non-periodic cell, and keeps the comment line's other
// key=value pairs (Time, energy, ...) as the frame's Comment attribute (it
// splits them into attributes only when a Lattice is given); ASE's extxyz
// reader reads them as the frame's info.
#include "formats/formats.hpp"
#include "formats/particles.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <stdexcept>

namespace lgvi::app {

namespace {

/// Species names: the body's name with anything but letters, digits, '_'
/// and '-' replaced by '_' (a species is one whitespace-free token).
std::string species_of(const std::string& name) {
  std::string s = name.empty() ? std::string("body") : name;
  for (char& c : s) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
    if (!ok) c = '_';
  }
  return s;
}

class XyzTrajectory final : public TrajectorySink {
 public:
  XyzTrajectory(const std::string& path, const TrajectoryLayout& layout, const SinkPosition* resume)
      : path_(path), frames_(layout) {
    for (const BodyShape& s : frames_.shapes()) species_.push_back(species_of(s.name));
    if (resume) {
      frames_.resume_at(resume->rows);
      std::error_code ec;
      std::filesystem::resize_file(path, static_cast<std::uintmax_t>(resume->bytes), ec);
      if (ec) throw std::runtime_error("cannot truncate " + path + " to resume: " + ec.message());
      file_ = std::fopen(path.c_str(), "ab");
    } else {
      file_ = std::fopen(path.c_str(), "wb");
    }
    if (!file_) throw std::runtime_error("cannot write " + path + ": " + std::strerror(errno));
  }

  ~XyzTrajectory() override {
    if (file_) std::fclose(file_);  // not closed: a crash; the file is valid up to its last whole frame
  }

  void row(const double* values) override {
    const ParticleFrame* frame = frames_.row(values);
    if (frame && error_.empty()) write_frame(*frame);
  }

  SinkPosition sync() override { return particle_file_position("xyz", frames_, file_, path_, error_); }

  void close(const std::string&, const std::string&) override {
    if (!file_) return;
    const int rc = std::fclose(file_);
    file_ = nullptr;
    if (!error_.empty()) throw std::runtime_error(error_);
    if (rc != 0) throw std::runtime_error("closing " + path_ + " failed: " + std::strerror(errno));
  }

 private:
  void write_frame(const ParticleFrame& f) {
    text_.clear();
    text_ += std::to_string(f.particles.size());
    text_.push_back('\n');
    text_ += xyz_properties;
    text_ += " Time=";
    append_number(text_, f.t);
    text_ += " energy=";
    append_number(text_, f.energy);
    text_ += " energy_error=";
    append_number(text_, f.energy_error);
    text_ += " momentum_error=";
    append_number(text_, f.momentum_error);
    text_ += " frame=";
    text_ += std::to_string(f.index);
    text_.push_back('\n');
    for (const Particle& p : f.particles) {
      text_ += species_[static_cast<std::size_t>(p.body)];
      auto numbers = [&](std::initializer_list<double> values) {
        for (double v : values) {
          text_.push_back(' ');
          append_number(text_, v);
        }
      };
      numbers({p.position[0], p.position[1], p.position[2], p.q[1], p.q[2], p.q[3], p.q[0], p.radius});
      text_.push_back(' ');
      text_ += std::to_string(p.body);
      text_.push_back(' ');
      text_ += std::to_string(p.site);
      numbers({p.velocity[0], p.velocity[1], p.velocity[2], p.omega[0], p.omega[1], p.omega[2]});
      text_.push_back('\n');
    }
    if (std::fwrite(text_.data(), 1, text_.size(), file_) != text_.size())
      error_ = "writing " + path_ + " failed: " + std::strerror(errno);
  }

  std::string path_;
  ParticleFrames frames_;
  std::vector<std::string> species_;
  std::FILE* file_ = nullptr;
  std::string text_;
  std::string error_;
};

}  // namespace

std::unique_ptr<TrajectorySink> open_xyz(const std::string& path, const TrajectoryLayout& layout,
                                         const SinkPosition* resume) {
  return std::make_unique<XyzTrajectory>(path, layout, resume);
}

}  // namespace lgvi::app
