// The particles of the exports for viewers (extended XYZ for OVITO, VTK XML
// for ParaView, the LAMMPS dump): every sphere of every body placed in the inertial frame, one
// frame per output step. The viewers draw particles, not rigid bodies, so the
// exports carry each body's spheres ("sites") with the body's orientation.
#pragma once

#include "io/trajectory_sink.hpp"

#include <array>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace lgvi {
class System;
}

namespace lgvi::io {

/// The shapes of a system's bodies, for TrajectoryLayout::shapes: a body
/// made of balls has one site per ball (body-frame centre about the centre of
/// mass, radius); a body given by mass and inertia one site at its centre of
/// mass with the radius of the uniform sphere of its mean moment.
std::vector<BodyShape> body_shapes(const System& system);

/// One site of one body at one output step, in the inertial frame.
struct Particle {
  std::int64_t body = 0;
  std::int64_t site = 0;  ///< the site's number in the frame, 0-based
  /// x + R(q) rho (site_position), wrapped into the box along its periodic
  /// axes: the unwrapped position is position + image * L (box.hpp).
  std::array<double, 3> position{};
  std::array<std::int64_t, 3> image{};
  std::array<double, 4> q{};  ///< the body's quaternion, scalar first (w, x, y, z) as in lgvi's files
  std::array<double, 3> velocity{};  ///< of the centre of mass, p / m
  std::array<double, 3> omega{};  ///< angular velocity in the inertial frame, R(q) J^-1 w / 2
  double radius = 0.0;
};

/// One output step as particles, with the system's diagnostics of that step.
struct ParticleFrame {
  std::int64_t index = 0;  ///< the frame's number, 0-based
  double t = 0.0, energy = 0.0, energy_error = 0.0, momentum_error = 0.0;
  std::vector<Particle> particles;
};

/// Collects a step's rows (layout.rows_per_step(), one per body) and turns
/// them into a frame. The rows are the trajectory's own (trajectory_header
/// or bodies_trajectory_header); columns are found by name.
class ParticleFrames {
 public:
  /// Throws std::runtime_error unless layout.shapes has one shape per row of a step.
  explicit ParticleFrames(const TrajectoryLayout& layout);

  /// Takes one row; returns the frame when the row completes a step, else nullptr.
  const ParticleFrame* row(const double* values);

  /// Rows taken so far, and whether a step is partly collected.
  std::int64_t rows() const { return rows_; }
  bool mid_step() const { return pending_ != 0; }
  /// Frames so far (whole steps).
  std::int64_t frames() const { return frames_; }
  /// Particles in every frame.
  std::int64_t particles_per_frame() const { return static_cast<std::int64_t>(frame_.particles.size()); }
  const std::vector<BodyShape>& shapes() const { return shapes_; }
  const Box& box() const { return box_; }

  /// Continues after `rows` rows (a whole number of steps, as in a
  /// checkpoint); throws std::runtime_error otherwise.
  void resume_at(std::int64_t rows);

 private:
  struct Columns {
    int t, x, qw, px, wx, energy, energy_error, momentum_error;
  };
  std::vector<BodyShape> shapes_;
  Box box_;
  Columns col_{};
  std::int64_t rows_ = 0, frames_ = 0;
  std::size_t pending_ = 0;  ///< rows of the current step taken so far
  std::vector<double> step_rows_;
  std::size_t columns_;
  ParticleFrame frame_;
};

/// x + R rho with R = pi(q) of S3::matrix() (the rotation the integrators
/// use), each coordinate summed as (R_i0 rho_0 + R_i1 rho_1) + R_i2 rho_2:
/// the order is fixed so that a reader can reproduce the positions bit for
/// bit from the CSV's x and q (tests/python/test_exports.py does).
std::array<double, 3> site_position(const double* x, const double* q_wxyz, const std::array<double, 3>& rho);

/// Where a particle export written through stdio stands after `frames`'
/// rows (TrajectorySink::sync of the particle exports): the rows taken and the
/// file's length once flushed. Throws std::logic_error in the middle of an
/// output step ("FORMAT: sync() ..."), and std::runtime_error with the
/// sink's recorded write error, if any, or the flush's.
SinkPosition particle_file_position(const char* format, const ParticleFrames& frames, std::FILE* file,
                                    const std::string& path, const std::string& error);

/// A particle export that is one text file, a block of text per frame
/// (extended XYZ, LAMMPS dump): the file opened new, or on resume truncated
/// back to the checkpoint's position and appended to; a write error kept and
/// thrown by sync() or close(). A crash leaves the file valid up to its last
/// whole frame. A format derives from it and writes a frame's text.
class ParticleTextFile : public TrajectorySink {
 public:
  /// `format` names it in messages ("xyz"). Throws std::runtime_error naming
  /// the file if it cannot be opened or truncated.
  ParticleTextFile(const char* format, const std::string& path, const TrajectoryLayout& layout,
                   const SinkPosition* resume);
  ~ParticleTextFile() override;
  ParticleTextFile(const ParticleTextFile&) = delete;
  ParticleTextFile& operator=(const ParticleTextFile&) = delete;

  void row(const double* values) final;
  SinkPosition sync() final;
  void close(const std::string& scenario_toml, const std::string& summary_json) final;

 protected:
  const ParticleFrames& frames() const { return frames_; }
  /// Each site's type, in the frame's site order: the balls' own types
  /// (Ball::type, a data file's atom types) where any is not 1; else the site
  /// radii numbered from 1 in order of first appearance (a radius seen keeps
  /// its type), so that a gas of identical molecules has as many types as its
  /// molecule has radii. The particle exports' species (xyz) and types
  /// (lammps-dump).
  const std::vector<std::int64_t>& site_types() const { return site_types_; }
  /// Appends the frame's text to `text` (empty on entry).
  virtual void format_frame(const ParticleFrame& frame, std::string& text) = 0;

 private:
  const char* format_;
  std::string path_;
  ParticleFrames frames_;
  std::vector<std::int64_t> site_types_;
  std::FILE* file_ = nullptr;
  std::string text_;
  std::string error_;
};

/// Appends v with 17 significant digits (%.17g, as the CSV writer prints
/// them: every double round-trips exactly).
void append_number(std::string& text, double v);

}  // namespace lgvi::io
