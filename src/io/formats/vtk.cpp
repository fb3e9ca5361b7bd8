// VTK XML for ParaView: one PolyData file (.vtp) per output step, its points
// the sites (balls) of every body, and a ParaView data collection (.pvd)
// listing them with their times, which ParaView opens as one time series.
//
// Streaming: each .vtp is written whole (a temporary file, then a rename) when
// its step's rows are in, then its <DataSet> line is appended to the .pvd.
// The .pvd's closing tags are written by close() only, so a run that dies
// leaves an unclosed index (and complete frames); `lgvi run --resume`
// truncates the index back to the checkpoint and goes on, and a completed run
// is byte-identical to an uninterrupted one.
//
// ASCII, with 17 significant digits: every double round-trips exactly (the
// tests compare with the CSV bit for bit), the files can be read and diffed
// as text, and ParaView reads them as it reads binary ones. The cost is size
// and speed (about 2.5 times the bytes of raw Float64 and a formatting cost
// per number like the CSV's): these files are for watching a run, which
// rarely needs more than some thousands of frames; npz or HDF5 are for bulk.
#include "io/formats/registry.hpp"
#include "io/formats/particles.hpp"
#include "io/output.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <stdexcept>

namespace lgvi::io {

namespace {

namespace fs = std::filesystem;

constexpr const char* pvd_head =
    "<?xml version=\"1.0\"?>\n"
    "<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
    "  <Collection>\n";
constexpr const char* pvd_tail = "  </Collection>\n</VTKFile>\n";

/// frame_000042.vtp: six digits at least, so that a folder listing sorts them
/// for runs of up to a million frames (the .pvd lists them in order anyway).
std::string frame_file_name(std::int64_t index) {
  char name[48];
  std::snprintf(name, sizeof name, "frame_%06lld.vtp", static_cast<long long>(index));
  return name;
}

/// The number of a frame file's name, or -1 for other files.
std::int64_t frame_number(const std::string& name) {
  long long n = -1;
  char tail[8] = {};
  if (std::sscanf(name.c_str(), "frame_%lld.%4s", &n, tail) == 2 && std::strcmp(tail, "vtp") == 0) return n;
  return -1;
}

class VtkTrajectory final : public TrajectorySink {
 public:
  VtkTrajectory(const std::string& path, const TrajectoryLayout& layout, const SinkPosition* resume)
      : path_(path), frames_(layout) {
    const fs::path p(path);
    folder_ = p.parent_path() / p.stem();
    folder_name_ = p.stem().string();
    std::error_code ec;
    fs::create_directories(folder_, ec);
    if (ec) throw std::runtime_error("cannot create the frame folder " + folder_.string() + ": " + ec.message());
    if (resume) {
      frames_.resume_at(resume->rows);
      fs::resize_file(path, static_cast<std::uintmax_t>(resume->bytes), ec);
      if (ec) throw std::runtime_error("cannot truncate " + path + " to resume: " + ec.message());
      file_ = std::fopen(path.c_str(), "ab");
    } else {
      file_ = std::fopen(path.c_str(), "wb");
    }
    if (!file_) throw std::runtime_error("cannot write " + path + ": " + std::strerror(errno));
    // Frames after the checkpoint (or all, for a new run) are another run's.
    remove_frames_from(frames_.frames());
    if (!resume && std::fputs(pvd_head, file_) < 0) throw std::runtime_error("cannot write " + path);
  }

  ~VtkTrajectory() override {
    if (file_) std::fclose(file_);  // not closed: a crash; resume completes the index
  }

  void row(const double* values) override {
    const ParticleFrame* frame = frames_.row(values);
    if (!frame || !error_.empty()) return;
    try {
      write_frame(*frame);
    } catch (const std::exception& e) {  // reported by sync() and close()
      error_ = e.what();
    }
  }

  SinkPosition sync() override { return particle_file_position("vtk", frames_, file_, path_, error_); }

  void close(const std::string&, const std::string&) override {
    if (!file_) return;
    const bool tail_ok = error_.empty() && std::fputs(pvd_tail, file_) >= 0;
    const int rc = std::fclose(file_);
    file_ = nullptr;
    if (!error_.empty()) throw std::runtime_error(error_);
    if (!tail_ok || rc != 0) throw std::runtime_error("closing " + path_ + " failed: " + std::strerror(errno));
  }

 private:
  void remove_frames_from(std::int64_t first) {
    std::error_code ec;
    for (const fs::directory_entry& e : fs::directory_iterator(folder_, ec))
      if (frame_number(e.path().filename().string()) >= first) fs::remove(e.path(), ec);
  }

  void write_frame(const ParticleFrame& f) {
    const std::string name = frame_file_name(f.index);
    write_file_atomically((folder_ / name).string(), vtp_text(f));
    std::string line = "    <DataSet timestep=\"";
    append_number(line, f.t);
    line += "\" group=\"\" part=\"0\" file=\"" + folder_name_ + "/" + name + "\"/>\n";
    // Flushed line by line: the stdio buffer is empty before each line, so the
    // line (about 100 bytes) reaches the file in one write() and a killed run
    // leaves whole <DataSet> lines only (a buffer flushed when full would cut
    // one, listing a truncated file name). One more system call per frame,
    // beside the frame file's own write and rename.
    if (std::fwrite(line.data(), 1, line.size(), file_) != line.size() || std::fflush(file_) != 0)
      throw std::runtime_error("writing " + path_ + " failed: " + std::strerror(errno));
  }

  static std::string vtp_text(const ParticleFrame& f) {
    const std::string n = std::to_string(f.particles.size());
    std::string s;
    s.reserve(f.particles.size() * 400 + 2048);
    s += "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"0.1\" byte_order=\"LittleEndian\">\n";
    s += "  <PolyData>\n    <FieldData>\n";
    auto field = [&](const char* name, double v) {
      s += "      <DataArray type=\"Float64\" Name=\"";
      s += name;
      s += "\" NumberOfTuples=\"1\" format=\"ascii\">";
      append_number(s, v);
      s += "</DataArray>\n";
    };
    field("TimeValue", f.t);  // the name ParaView and VTK readers take as the time of a data set
    field("energy", f.energy);
    field("energy_error", f.energy_error);
    field("momentum_error", f.momentum_error);
    s += "    </FieldData>\n";
    s += "    <Piece NumberOfPoints=\"" + n + "\" NumberOfVerts=\"" + n +
         "\" NumberOfLines=\"0\" NumberOfStrips=\"0\" NumberOfPolys=\"0\">\n";
    s += "      <PointData Scalars=\"radius\">\n";
    auto array = [&](const char* type, const char* name, int components, auto&& value) {
      s += "        <DataArray type=\"";
      s += type;
      s += "\" Name=\"";
      s += name;
      s += "\" NumberOfComponents=\"" + std::to_string(components) + "\" format=\"ascii\">\n";
      for (const Particle& p : f.particles) {
        s += "         ";
        for (int c = 0; c < components; ++c) {
          s.push_back(' ');
          value(p, c);
        }
        s.push_back('\n');
      }
      s += "        </DataArray>\n";
    };
    auto number = [&](double v) { append_number(s, v); };
    array("Float64", "radius", 1, [&](const Particle& p, int) { number(p.radius); });
    array("Int64", "body", 1, [&](const Particle& p, int) { s += std::to_string(p.body); });
    array("Float64", "quaternion_wxyz", 4, [&](const Particle& p, int c) { number(p.q[static_cast<std::size_t>(c)]); });
    array("Float64", "velocity", 3, [&](const Particle& p, int c) { number(p.velocity[static_cast<std::size_t>(c)]); });
    array("Float64", "angular_velocity", 3,
          [&](const Particle& p, int c) { number(p.omega[static_cast<std::size_t>(c)]); });
    s += "      </PointData>\n      <Points>\n";
    array("Float64", "position", 3, [&](const Particle& p, int c) { number(p.position[static_cast<std::size_t>(c)]); });
    s += "      </Points>\n      <Verts>\n";
    // One vertex cell per point, so that ParaView draws the points as they are.
    array("Int64", "connectivity", 1, [&](const Particle& p, int) { s += std::to_string(p.site); });
    array("Int64", "offsets", 1, [&](const Particle& p, int) { s += std::to_string(p.site + 1); });
    s += "      </Verts>\n    </Piece>\n  </PolyData>\n</VTKFile>\n";
    return s;
  }

  std::string path_;
  ParticleFrames frames_;
  fs::path folder_;
  std::string folder_name_;
  std::FILE* file_ = nullptr;
  std::string error_;
};

std::unique_ptr<TrajectorySink> open_vtk(const std::string& path, const TrajectoryLayout& layout,
                                         const SinkPosition* resume) {
  return std::make_unique<VtkTrajectory>(path, layout, resume);
}

}  // namespace

extern const FormatDescriptor vtk_format;  // listed in formats/registry.cpp
const FormatDescriptor vtk_format{.name = "vtk", .file_name = "trajectory.pvd", .holds_columns = false, .open = open_vtk};

}  // namespace lgvi::io
