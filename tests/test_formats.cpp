// Trajectory file formats (src/io/formats/, the sink interface src/io/trajectory_sink.hpp): written by
// the formats' writers, read back independently: the CSV parsed with
// from_chars, the npz by a small ZIP and .npy reader below (with its own
// CRC-32), the HDF5 file with the HDF5 C API.
//
// FormatSamples.Write writes sample files for tests/python/test_formats.py
// (numpy and h5py read them) when LGVI_FORMAT_SAMPLES_DIR is set.
#include "io/formats/registry.hpp"

#include <gtest/gtest.h>

#if __has_include(<hdf5.h>)
#include <hdf5.h>
#define LGVI_TEST_HDF5_API 1
#endif

#include <bit>
#include <cctype>
#include <cfloat>
#include <charconv>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <unistd.h>

namespace test_formats {

namespace {

using lgvi::io::open_trajectory;
using lgvi::io::SinkPosition;
using lgvi::io::TrajectoryFormat;
using lgvi::io::TrajectorySink;
namespace fs = std::filesystem;

// The formats by their registered names (io/formats/registry.cpp).
const TrajectoryFormat Csv = TrajectoryFormat::named("csv"), Npz = TrajectoryFormat::named("npz"),
                       Hdf5 = TrajectoryFormat::named("hdf5");

constexpr int columns = lgvi::io::trajectory_columns;

// ---- sample data ------------------------------------------------------------

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

/// The value of row r, column c: every fifth one awkward (0.1, -0.0,
/// denormals, extremes), the others random finite bit patterns (any exponent).
double sample_value(std::int64_t r, int c) {
  static const double awkward[] = {0.1,     -0.0,     0.0,     1e-300,  1e300,   4.9406564584124654e-324,
                                   -2.5e-320, DBL_MIN, DBL_MAX, -DBL_MAX, 1.0 / 3, 0.30000000000000004,
                                   -123456789.125, 2.2250738585072009e-308};
  const auto i = static_cast<std::uint64_t>(r) * columns + static_cast<std::uint64_t>(c);
  if (i % 5 == 0) return awkward[(i / 5) % std::size(awkward)];
  std::uint64_t bits = splitmix64(i);
  if (((bits >> 52) & 0x7FF) == 0x7FF) bits &= ~(std::uint64_t(1) << 62);  // no inf or NaN
  return std::bit_cast<double>(bits);
}

void write_rows(TrajectorySink& sink, std::int64_t begin, std::int64_t end, double offset = 0.0) {
  double row[columns];
  for (std::int64_t r = begin; r < end; ++r) {
    for (int c = 0; c < columns; ++c) row[c] = offset == 0.0 ? sample_value(r, c) : sample_value(r, c) + offset;  // -0.0 + 0.0 is 0.0
    sink.row(row);
  }
}

const std::string scenario_text =
    "# a scenario with non-ASCII text: \xC3\xA9t\xC3\xA9, \xE5\x90\x8D\xE5\x89\x8D, \xF0\x9F\x9A\x80\n"
    "name = \"formats \\\"test\\\"\"\n[integrator]\ndt = 0.01\nsteps = 10007\n";
const std::string summary_text = "{\n  \"completed\": true,\n  \"steps\": 10007,\n  \"note\": \"\\u00e9\"\n}\n";

std::vector<std::string> header_names() {
  std::vector<std::string> names;
  std::stringstream ss(lgvi::io::trajectory_header);
  for (std::string n; std::getline(ss, n, ',');) names.push_back(n);
  return names;
}

// ---- files ------------------------------------------------------------------

class TempDir {
 public:
  TempDir() {
    static int counter = 0;
    path_ = fs::temp_directory_path() /
            ("lgvi_formats_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  fs::path path_;
};

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  if (!out) throw std::runtime_error("cannot write " + path);
}

// ---- what a reader found ----------------------------------------------------

struct Trajectory {
  std::int64_t rows = 0;
  std::vector<double> values;  // rows x columns, C order
  std::vector<std::string> columns;
  std::string scenario, summary;  // npz and HDF5 only
};

// ---- CSV --------------------------------------------------------------------

Trajectory read_csv(const std::string& path) {
  const std::string text = read_file(path);
  Trajectory t;
  std::size_t line_end = text.find('\n');
  if (line_end == std::string::npos) throw std::runtime_error("no header line in " + path);
  std::stringstream header(text.substr(0, line_end));
  for (std::string n; std::getline(header, n, ',');) t.columns.push_back(n);
  const char* p = text.data() + line_end + 1;
  const char* end = text.data() + text.size();
  while (p < end) {
    for (int c = 0; c < columns; ++c) {
      double v;
      const auto res = std::from_chars(p, end, v);
      if (res.ec != std::errc() || res.ptr == end || *res.ptr != (c + 1 == columns ? '\n' : ','))
        throw std::runtime_error("malformed CSV row " + std::to_string(t.rows) + " in " + path);
      t.values.push_back(v);
      p = res.ptr + 1;
    }
    ++t.rows;
  }
  return t;
}

// ---- ZIP and .npy -----------------------------------------------------------

/// The ZIP CRC-32, bit by bit (independent of the writer's table-driven one).
std::uint32_t crc32_bitwise(std::string_view s) {
  std::uint32_t crc = 0xFFFFFFFFu;
  for (unsigned char ch : s) {
    crc ^= ch;
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  return ~crc;
}

std::uint64_t le(std::string_view s, std::size_t at, int bytes) {
  if (at + static_cast<std::size_t>(bytes) > s.size()) throw std::runtime_error("ZIP structure beyond the end");
  std::uint64_t v = 0;
  for (int i = bytes - 1; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(s[at + static_cast<std::size_t>(i)]);
  return v;
}

struct ZipEntry {
  std::string name;
  std::uint16_t method = 0;
  std::uint32_t crc = 0;
  std::uint64_t size = 0, compressed = 0, local_offset = 0, data_offset = 0;
  bool zip64_in_central = false, zip64_in_local = false;
  std::string_view data;
};

struct Zip {
  std::vector<ZipEntry> entries;
  bool zip64_end = false;
};

/// Reads the sizes/offset that are 0xFFFFFFFF from a ZIP64 extra field.
bool read_zip64_extra(std::string_view extra, std::uint64_t* size, std::uint64_t* compressed,
                      std::uint64_t* offset) {
  for (std::size_t at = 0; at + 4 <= extra.size();) {
    const auto id = le(extra, at, 2), len = le(extra, at + 2, 2);
    if (id == 0x0001) {
      std::size_t f = at + 4;
      for (std::uint64_t* v : {size, compressed, offset})
        if (v && *v == 0xFFFFFFFFu) {
          *v = le(extra, f, 8);
          f += 8;
        }
      if (f > at + 4 + len) throw std::runtime_error("short ZIP64 extra field");
      return true;
    }
    at += 4 + len;
  }
  return false;
}

/// Parses the archive from its end records and central directory, checks
/// each local header against it, and each entry's CRC-32.
Zip read_zip(std::string_view z) {
  if (z.size() < 22) throw std::runtime_error("too short for a ZIP archive");
  std::size_t eocd = z.size() - 22;
  while (le(z, eocd, 4) != 0x06054b50u) {
    if (eocd == 0 || z.size() - eocd > 22 + 0xFFFF) throw std::runtime_error("no end of central directory record");
    --eocd;
  }
  Zip zip;
  std::uint64_t entries = le(z, eocd + 10, 2), cd_size = le(z, eocd + 12, 4), cd_offset = le(z, eocd + 16, 4);
  if (eocd >= 20 && le(z, eocd - 20, 4) == 0x07064b50u) {
    const std::uint64_t at = le(z, eocd - 20 + 8, 8);
    if (le(z, at, 4) != 0x06064b50u) throw std::runtime_error("bad ZIP64 end of central directory record");
    zip.zip64_end = true;
    entries = le(z, at + 32, 8);
    cd_size = le(z, at + 40, 8);
    cd_offset = le(z, at + 48, 8);
  }
  std::size_t at = cd_offset;
  for (std::uint64_t i = 0; i < entries; ++i) {
    if (le(z, at, 4) != 0x02014b50u) throw std::runtime_error("bad central directory header");
    ZipEntry e;
    e.method = static_cast<std::uint16_t>(le(z, at + 10, 2));
    e.crc = static_cast<std::uint32_t>(le(z, at + 16, 4));
    e.compressed = le(z, at + 20, 4);
    e.size = le(z, at + 24, 4);
    const auto name_len = le(z, at + 28, 2), extra_len = le(z, at + 30, 2), comment_len = le(z, at + 32, 2);
    e.local_offset = le(z, at + 42, 4);
    e.name = std::string(z.substr(at + 46, name_len));
    e.zip64_in_central =
        read_zip64_extra(z.substr(at + 46 + name_len, extra_len), &e.size, &e.compressed, &e.local_offset);
    at += 46 + name_len + extra_len + comment_len;

    const std::size_t lh = e.local_offset;
    if (le(z, lh, 4) != 0x04034b50u) throw std::runtime_error("bad local header of " + e.name);
    std::uint64_t local_size = le(z, lh + 22, 4), local_compressed = le(z, lh + 18, 4);
    const auto local_name_len = le(z, lh + 26, 2), local_extra_len = le(z, lh + 28, 2);
    if (z.substr(lh + 30, local_name_len) != e.name) throw std::runtime_error("local name differs for " + e.name);
    e.zip64_in_local =
        read_zip64_extra(z.substr(lh + 30 + local_name_len, local_extra_len), &local_size, &local_compressed, nullptr);
    if (le(z, lh + 8, 2) != e.method || le(z, lh + 14, 4) != e.crc || local_size != e.size ||
        local_compressed != e.compressed)
      throw std::runtime_error("local header differs from the central directory for " + e.name);
    e.data_offset = lh + 30 + local_name_len + local_extra_len;
    e.data = z.substr(e.data_offset, e.compressed);
    if (e.data.size() != e.compressed) throw std::runtime_error("entry beyond the end: " + e.name);
    if (crc32_bitwise(e.data) != e.crc) throw std::runtime_error("CRC-32 differs for " + e.name);
    zip.entries.push_back(e);
  }
  if (at != cd_offset + cd_size) throw std::runtime_error("central directory size differs");
  return zip;
}

struct Npy {
  std::string descr;
  bool fortran_order = true;
  std::vector<std::int64_t> shape;
  std::size_t header_bytes = 0;
  std::string_view data;
};

Npy read_npy(std::string_view s) {
  if (s.substr(0, 6) != "\x93NUMPY") throw std::runtime_error("no .npy magic");
  Npy n;
  const int major = static_cast<unsigned char>(s[6]);
  const std::size_t len_bytes = major == 1 ? 2 : 4;
  const std::size_t header_len = le(s, 8, static_cast<int>(len_bytes));
  n.header_bytes = 8 + len_bytes + header_len;
  const std::string dict(s.substr(8 + len_bytes, header_len));
  if (dict.empty() || dict.back() != '\n') throw std::runtime_error(".npy header does not end in a newline");
  auto value_after = [&](const std::string& key) {
    const auto at = dict.find("'" + key + "': ");
    if (at == std::string::npos) throw std::runtime_error("no " + key + " in .npy header " + dict);
    return at + key.size() + 4;
  };
  const auto d = value_after("descr");
  n.descr = dict.substr(d + 1, dict.find('\'', d + 1) - d - 1);
  n.fortran_order = dict.compare(value_after("fortran_order"), 4, "True") == 0;
  const auto sh = value_after("shape");
  const std::string shape = dict.substr(sh + 1, dict.find(')', sh) - sh - 1);
  for (const char* p = shape.data(); p < shape.data() + shape.size();) {
    while (*p == ' ' || *p == ',') ++p;
    if (p >= shape.data() + shape.size()) break;
    std::int64_t v;
    const auto res = std::from_chars(p, shape.data() + shape.size(), v);
    if (res.ec != std::errc()) throw std::runtime_error("bad shape " + shape);
    n.shape.push_back(v);
    p = res.ptr;
  }
  n.data = s.substr(n.header_bytes);
  return n;
}

std::string utf8(std::uint32_t cp) {
  std::string s;
  if (cp < 0x80) {
    s += static_cast<char>(cp);
  } else if (cp < 0x800) {
    s += static_cast<char>(0xC0 | (cp >> 6));
    s += static_cast<char>(0x80 | (cp & 0x3F));
  } else if (cp < 0x10000) {
    s += static_cast<char>(0xE0 | (cp >> 12));
    s += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
    s += static_cast<char>(0x80 | (cp & 0x3F));
  } else {
    s += static_cast<char>(0xF0 | (cp >> 18));
    s += static_cast<char>(0x80 | ((cp >> 12) & 0x3F));
    s += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
    s += static_cast<char>(0x80 | (cp & 0x3F));
  }
  return s;
}

/// The strings of a '<U{n}' array, as UTF-8 (numpy drops trailing NULs).
std::vector<std::string> unicode_strings(const Npy& n) {
  if (n.descr.substr(0, 2) != "<U") throw std::runtime_error("not a unicode array: " + n.descr);
  const std::size_t width = std::stoul(n.descr.substr(2));
  std::size_t count = 1;
  for (auto d : n.shape) count *= static_cast<std::size_t>(d);
  if (n.data.size() != count * width * 4) throw std::runtime_error("unicode array size differs");
  std::vector<std::string> out;
  for (std::size_t i = 0; i < count; ++i) {
    std::vector<std::uint32_t> cps;
    for (std::size_t k = 0; k < width; ++k) cps.push_back(static_cast<std::uint32_t>(le(n.data, (i * width + k) * 4, 4)));
    while (!cps.empty() && cps.back() == 0) cps.pop_back();
    std::string s;
    for (auto cp : cps) s += utf8(cp);
    out.push_back(s);
  }
  return out;
}

const ZipEntry& entry(const Zip& zip, const std::string& name) {
  for (const auto& e : zip.entries)
    if (e.name == name) return e;
  throw std::runtime_error("no " + name + " in the archive");
}

Trajectory read_npz(const std::string& path) {
  const std::string bytes = read_file(path);
  const Zip zip = read_zip(bytes);
  Trajectory t;
  const Npy traj = read_npy(entry(zip, "trajectory.npy").data);
  if (traj.descr != "<f8" || traj.fortran_order || traj.shape.size() != 2 || traj.shape[1] != columns)
    throw std::runtime_error("trajectory.npy is not a C-order (N, 21) '<f8' array");
  t.rows = traj.shape[0];
  if (traj.data.size() != static_cast<std::size_t>(t.rows) * columns * 8)
    throw std::runtime_error("trajectory.npy's data size differs from its shape");
  t.values.resize(static_cast<std::size_t>(t.rows) * columns);
  for (std::size_t i = 0; i < t.values.size(); ++i) t.values[i] = std::bit_cast<double>(le(traj.data, 8 * i, 8));
  t.columns = unicode_strings(read_npy(entry(zip, "columns.npy").data));
  const Npy scenario = read_npy(entry(zip, "scenario.npy").data), summary = read_npy(entry(zip, "summary.npy").data);
  if (!scenario.shape.empty() || !summary.shape.empty()) throw std::runtime_error("scenario/summary are not 0-d");
  t.scenario = unicode_strings(scenario).at(0);
  t.summary = unicode_strings(summary).at(0);
  return t;
}

// ---- HDF5 -------------------------------------------------------------------

#ifdef LGVI_TEST_HDF5_API
struct H5 {
  hid_t id;
  herr_t (*closer)(hid_t);
  H5(hid_t i, herr_t (*c)(hid_t), const std::string& what) : id(i), closer(c) {
    if (id < 0) throw std::runtime_error("HDF5 test reader: " + what + " failed");
  }
  H5(const H5&) = delete;
  H5& operator=(const H5&) = delete;
  ~H5() { closer(id); }
};

void reclaim(hid_t type, hid_t space, void* buf) {
#if H5_VERSION_GE(1, 12, 0)
  H5Treclaim(type, space, H5P_DEFAULT, buf);
#else
  H5Dvlen_reclaim(type, space, H5P_DEFAULT, buf);
#endif
}

/// Reads a variable-length UTF-8 string attribute (1-d or scalar).
std::vector<std::string> read_string_attribute(hid_t object, const char* name) {
  H5 attr(H5Aopen(object, name, H5P_DEFAULT), H5Aclose, std::string("open attribute ") + name);
  H5 type(H5Aget_type(attr.id), H5Tclose, "attribute type");
  if (H5Tget_class(type.id) != H5T_STRING || H5Tis_variable_str(type.id) <= 0 ||
      H5Tget_cset(type.id) != H5T_CSET_UTF8)
    throw std::runtime_error(std::string("attribute ") + name + " is not a variable-length UTF-8 string");
  H5 space(H5Aget_space(attr.id), H5Sclose, "attribute space");
  const hssize_t n = H5Sget_simple_extent_npoints(space.id);
  H5 mem(H5Tcopy(H5T_C_S1), H5Tclose, "string type");
  H5Tset_size(mem.id, H5T_VARIABLE);
  H5Tset_cset(mem.id, H5T_CSET_UTF8);
  std::vector<char*> p(static_cast<std::size_t>(n), nullptr);
  if (H5Aread(attr.id, mem.id, p.data()) < 0) throw std::runtime_error(std::string("read attribute ") + name);
  std::vector<std::string> out(p.begin(), p.end());
  reclaim(mem.id, space.id, p.data());
  return out;
}

struct Hdf5Layout {
  bool f64le = false;
  hsize_t maxdims[2] = {0, 0}, chunk[2] = {0, 0};
};

Trajectory read_hdf5(const std::string& path, Hdf5Layout* layout = nullptr) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  H5 file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose, "open " + path);
  H5 dset(H5Dopen2(file.id, "/trajectory", H5P_DEFAULT), H5Dclose, "open /trajectory");
  H5 space(H5Dget_space(dset.id), H5Sclose, "dataset space");
  hsize_t dims[2] = {0, 0}, maxdims[2] = {0, 0};
  if (H5Sget_simple_extent_ndims(space.id) != 2 || H5Sget_simple_extent_dims(space.id, dims, maxdims) != 2 ||
      dims[1] != columns)
    throw std::runtime_error("/trajectory is not (N, 21)");
  if (layout) {
    H5 type(H5Dget_type(dset.id), H5Tclose, "dataset type");
    layout->f64le = H5Tequal(type.id, H5T_IEEE_F64LE) > 0;
    layout->maxdims[0] = maxdims[0];
    layout->maxdims[1] = maxdims[1];
    H5 dcpl(H5Dget_create_plist(dset.id), H5Pclose, "dataset creation properties");
    if (H5Pget_layout(dcpl.id) == H5D_CHUNKED) H5Pget_chunk(dcpl.id, 2, layout->chunk);
  }
  Trajectory t;
  t.rows = static_cast<std::int64_t>(dims[0]);
  t.values.resize(dims[0] * dims[1]);
  if (!t.values.empty() && H5Dread(dset.id, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, t.values.data()) < 0)
    throw std::runtime_error("read /trajectory");
  t.columns = read_string_attribute(dset.id, "columns");
  if (H5Aexists(file.id, "scenario") > 0) t.scenario = read_string_attribute(file.id, "scenario").at(0);
  if (H5Aexists(file.id, "summary") > 0) t.summary = read_string_attribute(file.id, "summary").at(0);
  return t;
}
#else
struct Hdf5Layout {
  bool f64le = false;
  unsigned long long maxdims[2] = {0, 0}, chunk[2] = {0, 0};
};
Trajectory read_hdf5(const std::string&, Hdf5Layout* = nullptr) {
  throw std::runtime_error(
      "lgvi_tests was built without HDF5's headers, so it cannot read HDF5 files back: "
      "add HDF5::HDF5 to target_link_libraries(lgvi_tests ...) in tests/CMakeLists.txt");
}
#endif

// ---- all formats ------------------------------------------------------------

Trajectory read_back(TrajectoryFormat f, const std::string& path) {
  if (f == Csv) return read_csv(path);
  if (f == Npz) return read_npz(path);
  if (f == Hdf5) return read_hdf5(path);
  throw std::logic_error("format");  // the particle exports hold sites, not these columns: test_exports.cpp
}

/// "Csv", "Npz", "Hdf5": the test names' suffixes.
std::string format_name(TrajectoryFormat f) {
  std::string name = lgvi::io::to_string(f);
  name[0] = static_cast<char>(std::toupper(static_cast<unsigned char>(name[0])));
  return name;
}

/// Compares bit patterns: -0.0 differs from 0.0.
void expect_sample_rows(const Trajectory& t, std::int64_t rows) {
  ASSERT_EQ(t.rows, rows);
  ASSERT_EQ(t.values.size(), static_cast<std::size_t>(rows) * columns);
  std::int64_t mismatches = 0;
  for (std::int64_t r = 0; r < rows; ++r)
    for (int c = 0; c < columns; ++c) {
      const double got = t.values[static_cast<std::size_t>(r * columns + c)], want = sample_value(r, c);
      if (std::bit_cast<std::uint64_t>(got) != std::bit_cast<std::uint64_t>(want) && mismatches++ < 5)
        ADD_FAILURE() << "row " << r << " column " << c << ": got " << got << ", want " << want;
    }
  EXPECT_EQ(mismatches, 0);
}

bool bitwise_equal(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0);
}

class TrajectoryFormatTest : public ::testing::TestWithParam<TrajectoryFormat> {
 protected:
  std::string path() const { return dir_.file(lgvi::io::trajectory_file_name(GetParam())); }
  bool stores_texts() const { return GetParam() != Csv; }

  /// Writes rows [0, rows) without interruption and closes.
  void write_reference(const std::string& file, std::int64_t rows) const {
    auto sink = open_trajectory(GetParam(), file);
    write_rows(*sink, 0, rows);
    sink->close(scenario_text, summary_text);
  }

  /// After a resume from `resume`, the result is the same as an uninterrupted write.
  void expect_same_as_reference(const std::string& reference) const {
    if (GetParam() == Hdf5) {
      const Trajectory a = read_back(GetParam(), path()), b = read_back(GetParam(), reference);
      EXPECT_EQ(a.rows, b.rows);
      EXPECT_TRUE(bitwise_equal(a.values, b.values));
      EXPECT_EQ(a.columns, b.columns);
      EXPECT_EQ(a.scenario, b.scenario);
      EXPECT_EQ(a.summary, b.summary);
    } else {
      EXPECT_TRUE(read_file(path()) == read_file(reference)) << "the resumed file differs from " << reference;
    }
  }

  TempDir dir_;
};

TEST_P(TrajectoryFormatTest, RoundTripsEveryDoubleBitExactly) {
  const std::int64_t rows = 10007;  // not a multiple of any block size
  write_reference(path(), rows);
  const Trajectory t = read_back(GetParam(), path());
  expect_sample_rows(t, rows);
  EXPECT_EQ(t.columns, header_names());
  if (stores_texts()) {
    EXPECT_EQ(t.scenario, scenario_text);
    EXPECT_EQ(t.summary, summary_text);
  }
}

TEST_P(TrajectoryFormatTest, EmptyTrajectoryIsValid) {
  auto sink = open_trajectory(GetParam(), path());
  sink->close("", "{}");
  const Trajectory t = read_back(GetParam(), path());
  EXPECT_EQ(t.rows, 0);
  EXPECT_EQ(t.columns, header_names());
  if (stores_texts()) {
    EXPECT_EQ(t.scenario, "");
    EXPECT_EQ(t.summary, "{}");
  }
}

TEST_P(TrajectoryFormatTest, ResumeAfterCrashGivesTheUninterruptedResult) {
  const std::int64_t rows = 10007, synced = 5000;
  const std::string reference = dir_.file("reference_" + std::string(lgvi::io::trajectory_file_name(GetParam())));
  write_reference(reference, rows);

  SinkPosition position;
  {
    auto sink = open_trajectory(GetParam(), path());
    write_rows(*sink, 0, synced);
    position = sink->sync();
    EXPECT_EQ(position.rows, synced);
    write_rows(*sink, synced, synced + 1000, 7.0);  // different values, discarded by the resume
    // Destroyed without close(), as when a run dies: the file stays mid-way.
  }
  if (GetParam() == Npz) {
    EXPECT_ANY_THROW(read_npz(path())) << "not a ZIP archive before close(): no central directory yet";
  }

  auto sink = open_trajectory(GetParam(), path(), &position);
  write_rows(*sink, synced, rows);
  sink->close(scenario_text, summary_text);
  sink.reset();
  expect_same_as_reference(reference);
  expect_sample_rows(read_back(GetParam(), path()), rows);
}

TEST_P(TrajectoryFormatTest, ResumeAfterCloseGivesTheUninterruptedResult) {
  // A run resumed from a checkpoint taken before its trajectory was closed
  // (e.g. a completed run re-run from its last checkpoint).
  const std::int64_t rows = 9001, synced = 4097;
  const std::string reference = dir_.file("reference_" + std::string(lgvi::io::trajectory_file_name(GetParam())));
  write_reference(reference, rows);

  SinkPosition position;
  {
    auto sink = open_trajectory(GetParam(), path());
    write_rows(*sink, 0, synced);
    position = sink->sync();
    write_rows(*sink, synced, rows + 10, -3.0);
    sink->close("old scenario", "old summary");
  }
  auto sink = open_trajectory(GetParam(), path(), &position);
  write_rows(*sink, synced, rows);
  sink->close(scenario_text, summary_text);
  sink.reset();
  expect_same_as_reference(reference);
}

TEST_P(TrajectoryFormatTest, SyncTwiceAndResumeAtTheStart) {
  SinkPosition empty;
  {
    auto sink = open_trajectory(GetParam(), path());
    empty = sink->sync();
    EXPECT_EQ(empty.rows, 0);
    write_rows(*sink, 0, 10);
    EXPECT_EQ(sink->sync().rows, 10);
    EXPECT_EQ(sink->sync().rows, 10);
  }
  auto sink = open_trajectory(GetParam(), path(), &empty);
  write_rows(*sink, 0, 3);
  sink->close(scenario_text, summary_text);
  expect_sample_rows(read_back(GetParam(), path()), 3);
}

TEST_P(TrajectoryFormatTest, UnwritablePathThrowsNamingIt) {
  const std::string bad = dir_.file("no-such-folder/" + std::string(lgvi::io::trajectory_file_name(GetParam())));
  try {
    open_trajectory(GetParam(), bad);
    FAIL() << "no exception for " << bad;
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
  }
  SinkPosition p;
  p.rows = 1;
  p.bytes = 192 + 168;
  try {
    open_trajectory(GetParam(), bad, &p);
    FAIL() << "no exception resuming " << bad;
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
  }
}

INSTANTIATE_TEST_SUITE_P(Formats, TrajectoryFormatTest,
                         ::testing::Values(Csv, Npz, Hdf5),
                         [](const ::testing::TestParamInfo<TrajectoryFormat>& info) { return format_name(info.param); });

// ---- npz specifics ----------------------------------------------------------

TEST(NpzFormat, LayoutIsStoredZip64WithAlignedData) {
  TempDir dir;
  const std::string path = dir.file("trajectory.npz");
  const std::int64_t rows = 4321;
  SinkPosition position;
  {
    auto sink = open_trajectory(Npz, path);
    write_rows(*sink, 0, 1234);
    position = sink->sync();
    // The position's CRC-32 is that of trajectory.npy's bytes so far, as they are in the file.
    const std::string partial = read_file(path);
    ASSERT_EQ(partial.size(), static_cast<std::size_t>(position.bytes));
    EXPECT_EQ(position.bytes, 192 + 1234 * 168);
    EXPECT_EQ(position.crc32, crc32_bitwise(std::string_view(partial).substr(64)));
    EXPECT_EQ(read_npy(std::string_view(partial).substr(64)).shape, (std::vector<std::int64_t>{0, columns}));
    write_rows(*sink, 1234, rows);
    sink->close(scenario_text, summary_text);
  }
  const std::string bytes = read_file(path);
  const Zip zip = read_zip(bytes);
  EXPECT_TRUE(zip.zip64_end);
  ASSERT_EQ(zip.entries.size(), 4u);
  const char* names[] = {"trajectory.npy", "columns.npy", "scenario.npy", "summary.npy"};
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(zip.entries[i].name, names[i]);
    EXPECT_EQ(zip.entries[i].method, 0) << "stored, uncompressed";
    EXPECT_EQ(zip.entries[i].size, zip.entries[i].compressed);
  }
  const ZipEntry& t = zip.entries[0];
  EXPECT_EQ(t.local_offset, 0u);
  EXPECT_TRUE(t.zip64_in_local);
  EXPECT_TRUE(t.zip64_in_central);
  EXPECT_EQ(t.data_offset, 64u);
  const Npy traj = read_npy(t.data);
  EXPECT_EQ(traj.header_bytes, 128u);
  EXPECT_EQ((t.data_offset + traj.header_bytes) % 64, 0u) << "the rows can be memory-mapped";
  EXPECT_EQ(traj.descr, "<f8");
  EXPECT_FALSE(traj.fortran_order);
  EXPECT_EQ(traj.shape, (std::vector<std::int64_t>{rows, columns}));
  EXPECT_EQ(t.size, 128u + static_cast<std::uint64_t>(rows) * 168);

  const Npy cols = read_npy(entry(zip, "columns.npy").data);
  EXPECT_EQ(cols.descr, "<U15");  // the longest name, quat_norm_error
  EXPECT_EQ(cols.shape, (std::vector<std::int64_t>{columns}));
  const Npy scenario = read_npy(entry(zip, "scenario.npy").data);
  EXPECT_TRUE(scenario.shape.empty());
  // Code points, not bytes: the text has 2- 3- and 4-byte UTF-8 sequences.
  std::size_t code_points = 0;
  for (unsigned char ch : scenario_text) code_points += (ch & 0xC0) != 0x80;
  EXPECT_EQ(scenario.descr, "<U" + std::to_string(code_points));
  for (const auto& e : zip.entries) EXPECT_EQ(read_npy(e.data).header_bytes % 64, 0u) << e.name;
}

TEST(NpzFormat, ResumeChecksThePositionAgainstTheFile) {
  TempDir dir;
  const std::string path = dir.file("trajectory.npz");
  SinkPosition position;
  {
    auto sink = open_trajectory(Npz, path);
    write_rows(*sink, 0, 100);
    position = sink->sync();
    write_rows(*sink, 100, 150);
  }
  auto expect_refused = [&](SinkPosition p, const std::string& why) {
    try {
      open_trajectory(Npz, path, &p);
      ADD_FAILURE() << "resume accepted: " << why;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
  };
  SinkPosition p = position;
  p.crc32 ^= 1;
  expect_refused(p, "wrong CRC-32");
  p = position;
  p.bytes += 8;
  expect_refused(p, "bytes not at a row boundary");
  p = position;
  p.rows = 10000;
  p.bytes = 192 + 10000 * 168;
  expect_refused(p, "beyond the end of the file");
  {
    // Refusals leave the file as it was: the right position still resumes.
    auto sink = open_trajectory(Npz, path, &position);
    write_rows(*sink, 100, 200);
    sink->close(scenario_text, summary_text);
  }
  expect_sample_rows(read_npz(path), 200);
  write_text(path, "not an npz file, but long enough to hold the headers of one............................"
                   "........................................................................................"
                   "........................................................................................");
  p.rows = 0;
  p.bytes = 192;
  expect_refused(p, "not an npz file");
}

// ---- HDF5 specifics ---------------------------------------------------------

TEST(Hdf5Format, ChunkedExtendibleFloat64WithUtf8Attributes) {
  TempDir dir;
  const std::string path = dir.file("trajectory.h5");
  {
    auto sink = open_trajectory(Hdf5, path);
    write_rows(*sink, 0, 5000);
    sink->close(scenario_text, summary_text);
  }
  Hdf5Layout layout;
  const Trajectory t = read_hdf5(path, &layout);  // checks the string attributes' types
  EXPECT_TRUE(layout.f64le);
  EXPECT_EQ(layout.maxdims[0], ~0ull) << "unlimited rows (H5S_UNLIMITED)";
  EXPECT_EQ(layout.maxdims[1], static_cast<unsigned long long>(columns));
  EXPECT_EQ(layout.chunk[0], 4096ull);
  EXPECT_EQ(layout.chunk[1], static_cast<unsigned long long>(columns));
  expect_sample_rows(t, 5000);
  EXPECT_EQ(t.scenario, scenario_text);
}

TEST(Hdf5Format, ErrorsNameTheFile) {
  TempDir dir;
  const std::string path = dir.file("trajectory.h5");
  write_text(path, "this is not an HDF5 file\n");
  SinkPosition p;
  try {
    open_trajectory(Hdf5, path, &p);
    FAIL() << "opened a text file as HDF5";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("HDF5"), std::string::npos) << e.what();
  }
  {
    auto sink = open_trajectory(Hdf5, path);
    write_rows(*sink, 0, 10);
    sink->close("", "");
  }
  p.rows = 11;  // more rows than the file has
  EXPECT_THROW(open_trajectory(Hdf5, path, &p), std::runtime_error);
}

// ---- samples for tests/python/test_formats.py -------------------------------

/// With LGVI_FORMAT_SAMPLES_DIR set: writes there trajectory.csv,
/// trajectory.npz and trajectory.h5 (or those in LGVI_FORMAT_SAMPLES_FORMATS,
/// e.g. "npz,h5") with LGVI_FORMAT_SAMPLES_ROWS rows (default 1009) of the
/// sample values, and the scenario and summary texts as scenario.toml and
/// summary.json.
TEST(FormatSamples, Write) {
  const char* dir = std::getenv("LGVI_FORMAT_SAMPLES_DIR");
  if (!dir || !*dir) GTEST_SKIP() << "LGVI_FORMAT_SAMPLES_DIR is not set";
  std::int64_t rows = 1009;
  if (const char* r = std::getenv("LGVI_FORMAT_SAMPLES_ROWS")) rows = std::stoll(r);
  std::string formats = "csv,npz,h5";
  if (const char* f = std::getenv("LGVI_FORMAT_SAMPLES_FORMATS")) formats = f;
  fs::create_directories(dir);
  const std::pair<const char*, TrajectoryFormat> all[] = {
      {"csv", Csv}, {"npz", Npz}, {"h5", Hdf5}};
  for (const auto& [name, format] : all) {
    if (("," + formats + ",").find(std::string(",") + name + ",") == std::string::npos) continue;
    auto sink = open_trajectory(format, (fs::path(dir) / lgvi::io::trajectory_file_name(format)).string());
    write_rows(*sink, 0, rows);
    sink->close(scenario_text, summary_text);
  }
  write_text((fs::path(dir) / "scenario.toml").string(), scenario_text);
  write_text((fs::path(dir) / "summary.json").string(), summary_text);
}

}  // namespace

}  // namespace test_formats
