// The particle exports (src/io/formats/xyz.cpp, vtk.cpp, lammps_dump.cpp) at the sink level:
// resume after a crash or after close is byte-identical to an uninterrupted
// write, the shapes must match the layout, errors name the file. Their
// contents against a real run are checked by tests/python/test_exports.py
// (with VTK's own reader).
#include "io/formats/particles.hpp"
#include "io/formats/registry.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <unistd.h>

namespace test_exports {

namespace {

using lgvi::io::BodyShape;
using lgvi::io::open_trajectory;
using lgvi::io::SinkPosition;
using lgvi::io::TrajectoryFormat;
using lgvi::io::TrajectoryLayout;
using lgvi::io::TrajectorySink;
namespace fs = std::filesystem;

// The one export that writes a file per step (io/formats/vtk.cpp).
const TrajectoryFormat Vtk = TrajectoryFormat::named("vtk");

/// Every registered format that is an export for viewers (holds no columns):
/// each one passes the tests below.
std::vector<TrajectoryFormat> export_formats() {
  std::vector<TrajectoryFormat> out;
  for (const lgvi::io::FormatDescriptor* d : lgvi::io::trajectory_formats())
    if (!d->holds_columns) out.push_back(TrajectoryFormat::named(d->name));
  return out;
}

/// Two bodies: three balls, and one body given by mass and inertia.
TrajectoryLayout two_bodies() {
  TrajectoryLayout layout = TrajectoryLayout::long_format(2);
  BodyShape pile;
  pile.name = "pile";
  pile.mass = 1.75;
  pile.inertia_inverse = {1.0, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.25};
  pile.sites = {{{0.1, 0.2, 0.3}, 0.3}, {{-0.5, 0.0, 0.1}, 0.2}, {{0.0, 0.4, -0.2}, 0.15}};
  BodyShape top;
  top.name = "top";
  top.mass = 2.0;
  top.inertia_inverse = {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
  top.sites = {{{0.0, 0.0, 0.0}, 0.7}};
  layout.shapes = {pile, top};
  return layout;
}

/// Row r of the long layout: body r % 2 at step r / 2, a unit quaternion,
/// values that differ in every row (`offset` makes another run's rows).
void write_rows(TrajectorySink& sink, std::int64_t begin, std::int64_t end, double offset = 0.0) {
  double row[lgvi::io::bodies_trajectory_columns] = {};
  for (std::int64_t r = begin; r < end; ++r) {
    const std::int64_t step = r / 2;
    const double k = static_cast<double>(step) + offset;
    for (int c = 0; c < lgvi::io::bodies_trajectory_columns; ++c) row[c] = 0.001 * k * (c + 1) + 0.1 / (c + 1);
    row[0] = 0.01 * k;                       // t
    row[1] = static_cast<double>(r % 2);     // body
    const double angle = 0.05 * k + static_cast<double>(r % 2);
    row[5] = std::cos(angle);                // qw
    row[6] = std::sin(angle) * 0.6;          // qx
    row[7] = 0.0;                            // qy
    row[8] = std::sin(angle) * 0.8;          // qz
    sink.row(row);
  }
}

std::string read_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path.string());
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

class ExportFormatTest : public ::testing::TestWithParam<TrajectoryFormat> {
 protected:
  ExportFormatTest() {
    static int counter = 0;
    dir_ = fs::temp_directory_path() / ("lgvi_exports_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "a");
    fs::create_directories(dir_ / "b");
  }
  ~ExportFormatTest() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  fs::path file(const char* sub) const { return dir_ / sub / lgvi::io::trajectory_file_name(GetParam()); }

  /// Every file of the export in folder `sub`, by name relative to it.
  std::map<std::string, std::string> contents(const char* sub) const {
    std::map<std::string, std::string> files;
    for (const auto& e : fs::recursive_directory_iterator(dir_ / sub))
      if (e.is_regular_file()) files[fs::relative(e.path(), dir_ / sub).string()] = read_file(e.path());
    return files;
  }

  /// Writes `steps` steps without interruption into folder a/.
  void write_reference(std::int64_t steps) const {
    auto sink = open_trajectory(GetParam(), file("a").string(), two_bodies());
    write_rows(*sink, 0, 2 * steps);
    sink->close("scenario", "{}");
  }

  fs::path dir_;
};

TEST_P(ExportFormatTest, ResumeAfterCrashIsByteIdentical) {
  const std::int64_t steps = 41, synced = 17;
  write_reference(steps);
  SinkPosition position;
  {
    auto sink = open_trajectory(GetParam(), file("b").string(), two_bodies());
    write_rows(*sink, 0, 2 * synced);
    position = sink->sync();
    EXPECT_EQ(position.rows, 2 * synced);
    write_rows(*sink, 2 * synced, 2 * synced + 11, 5.0);  // another run's steps and half a step, then the crash
  }
  EXPECT_NE(contents("a"), contents("b"));
  auto sink = open_trajectory(GetParam(), file("b").string(), two_bodies(), &position);
  write_rows(*sink, 2 * synced, 2 * steps);
  sink->close("scenario", "{}");
  sink.reset();
  const auto a = contents("a"), b = contents("b");
  EXPECT_EQ(a.size(), GetParam() == Vtk ? 1u + steps : 1u);  // vtk: the .pvd and one .vtp a step
  EXPECT_TRUE(a == b) << "the resumed export differs from the uninterrupted one";
}

TEST_P(ExportFormatTest, ResumeAfterCloseIsByteIdentical) {
  const std::int64_t steps = 23, synced = 9;
  write_reference(steps);
  SinkPosition position;
  {
    auto sink = open_trajectory(GetParam(), file("b").string(), two_bodies());
    write_rows(*sink, 0, 2 * synced);
    position = sink->sync();
    write_rows(*sink, 2 * synced, 2 * (steps + 4), -1.0);  // more steps than the reference
    sink->close("old", "{}");
  }
  auto sink = open_trajectory(GetParam(), file("b").string(), two_bodies(), &position);
  write_rows(*sink, 2 * synced, 2 * steps);
  sink->close("scenario", "{}");
  sink.reset();
  EXPECT_TRUE(contents("a") == contents("b")) << "the resumed export differs from the uninterrupted one";
}

TEST_P(ExportFormatTest, ResumeMidStepIsRefused) {
  SinkPosition p;
  p.rows = 3;  // one and a half steps of two bodies
  try {
    open_trajectory(GetParam(), file("b").string(), two_bodies(), &p);
    FAIL() << "resumed after half a step";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("not a whole number of steps"), std::string::npos) << e.what();
  }
}

TEST_P(ExportFormatTest, ShapesMustMatchTheBodies) {
  TrajectoryLayout layout = two_bodies();
  layout.shapes.pop_back();
  try {
    open_trajectory(GetParam(), file("b").string(), layout);
    FAIL() << "opened with one shape for two bodies";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("need the shape of each of the 2 bodies, got 1"), std::string::npos)
        << e.what();
  }
}

TEST_P(ExportFormatTest, UnwritablePathThrowsNamingIt) {
  const std::string bad = "/proc/lgvi-no-such-folder/" + std::string(lgvi::io::trajectory_file_name(GetParam()));
  try {
    open_trajectory(GetParam(), bad, two_bodies());
    FAIL() << "no exception for " << bad;
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/proc/lgvi-no-such-folder/"), std::string::npos) << e.what();
  }
}

INSTANTIATE_TEST_SUITE_P(Formats, ExportFormatTest, ::testing::ValuesIn(export_formats()),
                         [](const ::testing::TestParamInfo<TrajectoryFormat>& info) {
                           std::string name = lgvi::io::to_string(info.param);  // xyz, vtk, lammps_dump
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

TEST(ExportFormat, SitePositionIsXPlusRRho) {
  // A quarter turn about z: R e_x = e_y.
  const double x[3] = {1.0, 2.0, 3.0};
  const double s = std::sqrt(0.5);
  const double q[4] = {s, 0.0, 0.0, s};
  const auto p = lgvi::io::site_position(x, q, {2.0, 0.0, 0.0});
  // R is formed from s^2 = 0.5 (1 ulp from sqrt(0.5)^2): within 4 ulp of 2.
  EXPECT_NEAR(p[0], 1.0, 1e-15);
  EXPECT_NEAR(p[1], 4.0, 4e-15);
  EXPECT_NEAR(p[2], 3.0, 1e-15);
}

}  // namespace

}  // namespace test_exports
