#include "io/formats/particles.hpp"
#include "io/formats/registry.hpp"

#include <lgvi/s3.hpp>
#include <lgvi/system.hpp>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <stdexcept>

namespace lgvi::io {

std::vector<BodyShape> body_shapes(const System& system) {
  std::vector<BodyShape> shapes;
  shapes.reserve(system.size());
  for (std::size_t a = 0; a < system.size(); ++a) {
    const RigidBody& body = system.body(a);
    BodyShape s;
    s.name = system.name(a);
    s.mass = body.mass();
    const Matrix3<double>& j_inv = body.inertia_inverse();
    for (std::size_t i = 0; i < 3; ++i)
      for (std::size_t k = 0; k < 3; ++k)
        s.inertia_inverse[3 * i + k] = j_inv(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(k));
    for (const Ball& b : body.balls())
      s.sites.push_back({{b.position.x(), b.position.y(), b.position.z()}, b.radius, b.type});
    if (s.sites.empty()) {
      // A uniform sphere has every moment 2/5 m r^2: the one of the mean moment tr J / 3.
      const double r = std::sqrt(5.0 * body.inertia().trace() / (6.0 * body.mass()));
      s.sites.push_back({{0.0, 0.0, 0.0}, r});
    }
    shapes.push_back(std::move(s));
  }
  return shapes;
}

namespace {

/// The position of `name` in a comma-separated header; throws if absent.
int column_of(const char* header, const char* name) {
  int index = 0;
  const std::size_t n = std::strlen(name);
  for (const char* p = header;; ++index) {
    const char* end = std::strchr(p, ',');
    const std::size_t len = end ? static_cast<std::size_t>(end - p) : std::strlen(p);
    if (len == n && std::strncmp(p, name, n) == 0) return index;
    if (!end) break;
    p = end + 1;
  }
  throw std::runtime_error(std::string("trajectory layout: no column '") + name + "'");
}

}  // namespace

ParticleFrames::ParticleFrames(const TrajectoryLayout& layout)
    : shapes_(layout.shapes), box_(layout.box), columns_(static_cast<std::size_t>(layout.columns)) {
  if (static_cast<std::int64_t>(shapes_.size()) != layout.rows_per_step())
    throw std::runtime_error("the particle exports (xyz, vtk, lammps-dump) need the shape of each of the " +
                             std::to_string(layout.rows_per_step()) + " bodies, got " +
                             std::to_string(shapes_.size()));
  const char* h = layout.header.c_str();
  col_ = {column_of(h, "t"),      column_of(h, "x"),           column_of(h, "qw"),
          column_of(h, "px"),     column_of(h, "wx"),          column_of(h, "energy"),
          column_of(h, "energy_error"), column_of(h, "momentum_error")};
  step_rows_.resize(shapes_.size() * columns_);
  std::int64_t sites = 0;
  for (const BodyShape& s : shapes_) sites += static_cast<std::int64_t>(s.sites.size());
  frame_.particles.resize(static_cast<std::size_t>(sites));
}

void ParticleFrames::resume_at(std::int64_t rows) {
  const auto per_step = static_cast<std::int64_t>(shapes_.size());
  if (rows < 0 || rows % per_step != 0)
    throw std::runtime_error("cannot resume a particle export after " + std::to_string(rows) +
                             " rows: not a whole number of steps of " + std::to_string(per_step) + " rows");
  rows_ = rows;
  pending_ = 0;
  frames_ = rows / per_step;
}

std::array<double, 3> site_position(const double* x, const double* q_wxyz, const std::array<double, 3>& rho) {
  const Matrix3<double> r = S3d(q_wxyz[0], q_wxyz[1], q_wxyz[2], q_wxyz[3]).matrix();
  std::array<double, 3> p{};
  for (int i = 0; i < 3; ++i) {
    const double rotated = (r(i, 0) * rho[0] + r(i, 1) * rho[1]) + r(i, 2) * rho[2];
    p[static_cast<std::size_t>(i)] = x[i] + rotated;
  }
  return p;
}

const ParticleFrame* ParticleFrames::row(const double* values) {
  std::memcpy(step_rows_.data() + pending_ * columns_, values, columns_ * sizeof(double));
  ++rows_;
  if (++pending_ < shapes_.size()) return nullptr;
  pending_ = 0;
  const double* first = step_rows_.data();
  frame_.t = first[col_.t];
  frame_.energy = first[col_.energy];
  frame_.energy_error = first[col_.energy_error];
  frame_.momentum_error = first[col_.momentum_error];
  std::size_t k = 0;
  for (std::size_t a = 0; a < shapes_.size(); ++a) {
    const BodyShape& shape = shapes_[a];
    const double* v = step_rows_.data() + a * columns_;
    const double *x = v + col_.x, *q = v + col_.qw, *p = v + col_.px, *w = v + col_.wx;
    // Omega = J^-1 w / 2 in the body frame, R Omega in the inertial frame.
    std::array<double, 3> body_omega{};
    for (std::size_t i = 0; i < 3; ++i) {
      const double* j = shape.inertia_inverse.data() + 3 * i;
      body_omega[i] = 0.5 * (j[0] * w[0] + j[1] * w[1] + j[2] * w[2]);
    }
    const double zero[3] = {0.0, 0.0, 0.0};
    const std::array<double, 3> omega = site_position(zero, q, body_omega);
    for (const Site& site : shape.sites) {
      Particle& out = frame_.particles[k];
      out.body = static_cast<std::int64_t>(a);
      out.site = static_cast<std::int64_t>(k);
      out.position = site_position(x, q, site.rho);
      if (box_.any_periodic()) {
        const Box::Wrapped w = box_.wrap({out.position[0], out.position[1], out.position[2]});
        out.position = {w.x(0), w.x(1), w.x(2)};
        out.image = w.image;
      }
      out.q = {q[0], q[1], q[2], q[3]};
      out.velocity = {p[0] / shape.mass, p[1] / shape.mass, p[2] / shape.mass};
      out.omega = omega;
      out.radius = site.radius;
      ++k;
    }
  }
  frame_.index = frames_++;
  return &frame_;
}

void append_number(std::string& text, double v) {
  char number[32];
  const auto res = std::to_chars(number, number + sizeof number, v, std::chars_format::general, 17);
  text.append(number, res.ptr);
}

SinkPosition particle_file_position(const char* format, const ParticleFrames& frames, std::FILE* file,
                                    const std::string& path, const std::string& error) {
  if (frames.mid_step()) throw std::logic_error(std::string(format) + ": sync() in the middle of an output step");
  if (!error.empty()) throw std::runtime_error(error);
  if (std::fflush(file) != 0) throw std::runtime_error("writing " + path + " failed: " + std::strerror(errno));
  SinkPosition p;
  p.rows = frames.rows();
  p.bytes = static_cast<std::int64_t>(std::ftell(file));
  return p;
}

ParticleTextFile::ParticleTextFile(const char* format, const std::string& path, const TrajectoryLayout& layout,
                                   const SinkPosition* resume)
    : format_(format), path_(path), frames_(layout) {
  // The sites' own types where the scenario gives any (a ball's type, a data
  // file's atom types); else one type per radius.
  bool typed = false;
  for (const BodyShape& shape : frames_.shapes())
    for (const Site& site : shape.sites) typed = typed || site.type != 1;
  std::map<double, std::int64_t> type_of_radius;  // O(sites log types)
  for (const BodyShape& shape : frames_.shapes())
    for (const Site& site : shape.sites) {
      const std::int64_t next = static_cast<std::int64_t>(type_of_radius.size()) + 1;
      site_types_.push_back(typed ? site.type : type_of_radius.emplace(site.radius, next).first->second);
    }
  if (resume) frames_.resume_at(resume->rows);
  file_ = open_appendable_file(path, resume);
}

ParticleTextFile::~ParticleTextFile() {
  if (file_) std::fclose(file_);  // not closed: a crash; the file is valid up to its last whole frame
}

void ParticleTextFile::row(const double* values) {
  const ParticleFrame* frame = frames_.row(values);
  if (!frame || !error_.empty()) return;
  text_.clear();
  format_frame(*frame, text_);
  if (std::fwrite(text_.data(), 1, text_.size(), file_) != text_.size())
    error_ = "writing " + path_ + " failed: " + std::strerror(errno);
}

SinkPosition ParticleTextFile::sync() { return particle_file_position(format_, frames_, file_, path_, error_); }

void ParticleTextFile::close(const std::string&, const std::string&) {
  if (!file_) return;
  const int rc = std::fclose(file_);
  file_ = nullptr;
  if (!error_.empty()) throw std::runtime_error(error_);
  if (rc != 0) throw std::runtime_error("closing " + path_ + " failed: " + std::strerror(errno));
}

}  // namespace lgvi::io
