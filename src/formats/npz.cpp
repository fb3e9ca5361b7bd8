// numpy's .npz trajectory, written without numpy or zlib: a ZIP archive of
// uncompressed (stored) .npy entries, streamed row by row.
//
// File layout (offsets in bytes):
//
//   0    local file header of trajectory.npy (30 bytes + the 14-byte name +
//        a 20-byte ZIP64 extra field with the sizes): CRC-32 and sizes are
//        written as zero while rows arrive and patched at close
//   64   .npy header, version 1.0, 128 bytes: "\x93NUMPY", 1, 0, the header
//        length, then {'descr': '<f8', 'fortran_order': False, 'shape': (N, 21), }
//        padded with spaces to end in '\n'. Room is reserved for N of any
//        int64 size, so close() patches N in place. While rows arrive the
//        header says N = 0.
//   192  the rows: 21 little-endian float64 each (168 bytes), C order. 192 is
//        a multiple of 64, so the data can be memory-mapped in place.
//   ...  at close: columns.npy (shape (21,), '<U15': the column names),
//        scenario.npy and summary.npy (0-d '<U{n}' arrays: the scenario's
//        TOML and the summary's JSON as UTF-32LE code points), each a stored
//        entry with its own local header; then the central directory, a
//        ZIP64 end of central directory record and locator, and the end of
//        central directory record.
//
// trajectory.npy always carries ZIP64 sizes (local header and central
// directory), so entries beyond 4 GiB need nothing special; the small entries
// get a ZIP64 extra field in the central directory only when their offset
// does not fit 32 bits; the ZIP64 end records are always written (zipfile
// and numpy read them; every count and offset that fits is also in the
// classic end record). Timestamps are fixed at 1980-01-01 00:00, the DOS
// epoch, so that a file's bytes depend only on its content (a resumed run
// gives the same file as an uninterrupted one).
//
// Until close() the file is not a valid ZIP archive: the central directory is
// written last. A run killed before close() leaves the rows written so far
// at 192 + 168 * rows (the summary says completed: false); resume continues
// it, and close() makes it a valid archive.
//
// SinkPosition: rows; bytes = the file offset of the end of the data
// (192 + 168 * rows); crc32 = the CRC-32 of trajectory.npy's content so far
// as it is in the file at that point, i.e. of bytes [64, bytes) with the
// .npy header saying N = 0. Resume checks these against the file (reading
// its data once) before truncating it back.
#include "formats/formats.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace lgvi::app {

namespace {

// ---- CRC-32 (ZIP's: reflected polynomial 0xEDB88320), slicing by 8 ----------

constexpr std::uint32_t crc_polynomial = 0xEDB88320u;

constexpr std::array<std::array<std::uint32_t, 256>, 8> make_crc_tables() {
  std::array<std::array<std::uint32_t, 256>, 8> t{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1u) ? (c >> 1) ^ crc_polynomial : c >> 1;
    t[0][i] = c;
  }
  for (std::size_t k = 1; k < 8; ++k)
    for (std::size_t i = 0; i < 256; ++i) t[k][i] = (t[k - 1][i] >> 8) ^ t[0][t[k - 1][i] & 0xFFu];
  return t;
}
constexpr auto crc_tables = make_crc_tables();

std::uint32_t load_le32(const unsigned char* p) {
  return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}

/// The CRC-32 of (the bytes behind `crc`) followed by p[0, n).
std::uint32_t crc32_update(std::uint32_t crc, const unsigned char* p, std::size_t n) {
  const auto& t = crc_tables;
  crc = ~crc;
  for (; n >= 8; p += 8, n -= 8) {
    const std::uint32_t a = load_le32(p) ^ crc, b = load_le32(p + 4);
    crc = t[7][a & 0xFFu] ^ t[6][(a >> 8) & 0xFFu] ^ t[5][(a >> 16) & 0xFFu] ^ t[4][a >> 24] ^ t[3][b & 0xFFu] ^
          t[2][(b >> 8) & 0xFFu] ^ t[1][(b >> 16) & 0xFFu] ^ t[0][b >> 24];
  }
  for (; n > 0; ++p, --n) crc = t[0][(crc ^ *p) & 0xFFu] ^ (crc >> 8);
  return ~crc;
}

std::uint32_t crc32_of(const std::string& s) {
  return crc32_update(0, reinterpret_cast<const unsigned char*>(s.data()), s.size());
}

// crc32_combine as in zlib: the CRC of A followed by B from crc(A), crc(B) and
// the length of B, by multiplying crc(A) by x^(8 len) modulo the polynomial.
// It lets close() put the final .npy header (with N) in front of data whose
// CRC was computed as the rows arrived, without reading the data again.
std::uint32_t multmodp(std::uint32_t a, std::uint32_t b) {
  std::uint32_t m = 1u << 31, p = 0;
  for (;;) {
    if (a & m) {
      p ^= b;
      if ((a & (m - 1)) == 0) break;
    }
    m >>= 1;
    b = (b & 1u) ? (b >> 1) ^ crc_polynomial : b >> 1;
  }
  return p;
}

constexpr std::array<std::uint32_t, 32> make_x2n_table() {
  std::array<std::uint32_t, 32> t{};
  std::uint32_t p = 1u << 30;  // x^1
  t[0] = p;
  for (std::size_t n = 1; n < 32; ++n) {
    // p = multmodp(p, p), spelled out so that it is constexpr
    std::uint32_t a = p, b = p, m = 1u << 31, r = 0;
    for (;;) {
      if (a & m) {
        r ^= b;
        if ((a & (m - 1)) == 0) break;
      }
      m >>= 1;
      b = (b & 1u) ? (b >> 1) ^ crc_polynomial : b >> 1;
    }
    t[n] = p = r;
  }
  return t;
}
constexpr auto x2n_table = make_x2n_table();

std::uint32_t crc32_combine(std::uint32_t crc_a, std::uint32_t crc_b, std::uint64_t length_b) {
  std::uint32_t p = 1u << 31;  // x^0
  for (unsigned k = 3; length_b != 0; length_b >>= 1, ++k)
    if (length_b & 1u) p = multmodp(x2n_table[k & 31u], p);
  return multmodp(p, crc_a) ^ crc_b;
}

// ---- little-endian byte strings ---------------------------------------------

void put16(std::string& s, std::uint32_t v) {
  s.push_back(static_cast<char>(v & 0xFFu));
  s.push_back(static_cast<char>((v >> 8) & 0xFFu));
}
void put32(std::string& s, std::uint32_t v) {
  put16(s, v & 0xFFFFu);
  put16(s, v >> 16);
}
void put64(std::string& s, std::uint64_t v) {
  put32(s, static_cast<std::uint32_t>(v & 0xFFFFFFFFu));
  put32(s, static_cast<std::uint32_t>(v >> 32));
}

constexpr std::uint32_t u32_max = 0xFFFFFFFFu;
constexpr std::uint32_t dos_time = 0;                        // 00:00:00
constexpr std::uint32_t dos_date = (0u << 9) | (1u << 5) | 1u;  // 1980-01-01

// ---- .npy -------------------------------------------------------------------

/// A version 1.0 .npy header for `dict`, padded with spaces so that the
/// whole header is `total` bytes (a multiple of 64) or, with total = 0, the
/// smallest multiple of 64 that holds it.
std::string npy_header(const std::string& dict, std::size_t total = 0) {
  const std::size_t needed = 10 + dict.size() + 1;
  if (total == 0) total = (needed + 63) / 64 * 64;
  if (needed > total || total - 10 > 0xFFFFu) throw std::logic_error("npy header does not fit");
  std::string h = "\x93NUMPY";
  h.push_back('\x01');
  h.push_back('\x00');
  put16(h, static_cast<std::uint32_t>(total - 10));
  h += dict;
  h.append(total - needed, ' ');
  h.push_back('\n');
  return h;
}

constexpr std::size_t trajectory_header_bytes = 128;

/// The .npy header of the trajectory after `rows` rows: shape (rows, columns),
/// or (rows / bodies, bodies, columns) for the long layout.
std::string trajectory_npy_header(std::int64_t rows, const TrajectoryLayout& layout) {
  const std::string shape = layout.bodies > 0 ? std::to_string(rows / layout.bodies) + ", " +
                                                    std::to_string(layout.bodies) + ", " + std::to_string(layout.columns)
                                              : std::to_string(rows) + ", " + std::to_string(layout.columns);
  return npy_header("{'descr': '<f8', 'fortran_order': False, 'shape': (" + shape + "), }", trajectory_header_bytes);
}

/// UTF-8 to code points; a malformed sequence becomes U+FFFD.
std::vector<std::uint32_t> code_points(const std::string& s) {
  std::vector<std::uint32_t> out;
  out.reserve(s.size());
  const auto* p = reinterpret_cast<const unsigned char*>(s.data());
  const std::size_t n = s.size();
  for (std::size_t i = 0; i < n;) {
    const unsigned c = p[i];
    int len = 0;
    std::uint32_t cp = 0, min = 0;
    if (c < 0x80) { len = 1; cp = c; }
    else if ((c & 0xE0) == 0xC0) { len = 2; cp = c & 0x1F; min = 0x80; }
    else if ((c & 0xF0) == 0xE0) { len = 3; cp = c & 0x0F; min = 0x800; }
    else if ((c & 0xF8) == 0xF0) { len = 4; cp = c & 0x07; min = 0x10000; }
    bool ok = len > 0 && i + static_cast<std::size_t>(len) <= n;
    for (int k = 1; ok && k < len; ++k) {
      if ((p[i + static_cast<std::size_t>(k)] & 0xC0) != 0x80) ok = false;
      else cp = (cp << 6) | (p[i + static_cast<std::size_t>(k)] & 0x3Fu);
    }
    if (ok && (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF))) ok = false;
    if (ok) {
      out.push_back(cp);
      i += static_cast<std::size_t>(len);
    } else {
      out.push_back(0xFFFD);
      ++i;
    }
  }
  return out;
}

/// A .npy of unicode strings ('<U{width}', UTF-32LE, NUL-padded): 0-d when
/// `scalar`, else shape (strings.size(),).
std::string npy_unicode(const std::vector<std::string>& strings, bool scalar) {
  std::vector<std::vector<std::uint32_t>> cps;
  std::size_t width = 1;  // numpy has no '<U0' array of one empty string: np.array('') is '<U1'
  for (const auto& s : strings) {
    cps.push_back(code_points(s));
    width = std::max(width, cps.back().size());
  }
  // Appended piece by piece: "literal" + std::string&& trips GCC 12's -Wrestrict (GCC bug 105651).
  std::string dict = "{'descr': '<U";
  dict += std::to_string(width);
  dict += "', 'fortran_order': False, 'shape': ";
  if (scalar) {
    dict += "()";
  } else {
    dict += '(';
    dict += std::to_string(strings.size());
    dict += ",)";
  }
  dict += ", }";
  std::string out = npy_header(dict);
  for (const auto& s : cps) {
    for (std::uint32_t cp : s) put32(out, cp);
    out.append(4 * (width - s.size()), '\0');
  }
  return out;
}

// ---- ZIP --------------------------------------------------------------------

const std::string trajectory_entry = "trajectory.npy";
constexpr std::int64_t local_header_bytes = 30 + 14 + 20;  // fixed part, name, ZIP64 extra
constexpr std::int64_t data_offset = local_header_bytes + static_cast<std::int64_t>(trajectory_header_bytes);
static_assert(data_offset % 64 == 0);

struct Entry {
  std::string name;
  std::uint32_t crc = 0;
  std::uint64_t size = 0;    // stored: compressed size = uncompressed size
  std::uint64_t offset = 0;  // of the local header
  bool zip64_sizes = false;  // sizes in a ZIP64 extra field (trajectory.npy: always)
};

std::string local_header(const Entry& e) {
  std::string h;
  put32(h, 0x04034b50u);
  put16(h, e.zip64_sizes ? 45 : 20);  // version needed to extract (4.5: ZIP64)
  put16(h, 0);                        // flags
  put16(h, 0);                        // method: stored
  put16(h, dos_time);
  put16(h, dos_date);
  put32(h, e.crc);
  put32(h, e.zip64_sizes ? u32_max : static_cast<std::uint32_t>(e.size));
  put32(h, e.zip64_sizes ? u32_max : static_cast<std::uint32_t>(e.size));
  put16(h, static_cast<std::uint32_t>(e.name.size()));
  put16(h, e.zip64_sizes ? 20 : 0);
  h += e.name;
  if (e.zip64_sizes) {
    put16(h, 0x0001);  // ZIP64 extended information
    put16(h, 16);
    put64(h, e.size);  // uncompressed
    put64(h, e.size);  // compressed
  }
  return h;
}

std::string central_header(const Entry& e) {
  const bool zip64_offset = e.offset >= u32_max;
  const bool zip64 = e.zip64_sizes || zip64_offset;
  std::string extra;
  if (zip64) {
    std::string fields;
    if (e.zip64_sizes) {
      put64(fields, e.size);
      put64(fields, e.size);
    }
    if (zip64_offset) put64(fields, e.offset);
    put16(extra, 0x0001);
    put16(extra, static_cast<std::uint32_t>(fields.size()));
    extra += fields;
  }
  std::string h;
  put32(h, 0x02014b50u);
  put16(h, 45);                       // version made by: 4.5, MS-DOS attributes
  put16(h, zip64 ? 45 : 20);          // version needed to extract
  put16(h, 0);                        // flags
  put16(h, 0);                        // method: stored
  put16(h, dos_time);
  put16(h, dos_date);
  put32(h, e.crc);
  put32(h, e.zip64_sizes ? u32_max : static_cast<std::uint32_t>(e.size));
  put32(h, e.zip64_sizes ? u32_max : static_cast<std::uint32_t>(e.size));
  put16(h, static_cast<std::uint32_t>(e.name.size()));
  put16(h, static_cast<std::uint32_t>(extra.size()));
  put16(h, 0);  // comment length
  put16(h, 0);  // disk number
  put16(h, 0);  // internal attributes
  put32(h, 0);  // external attributes
  put32(h, zip64_offset ? u32_max : static_cast<std::uint32_t>(e.offset));
  h += e.name;
  h += extra;
  return h;
}

/// ZIP64 end of central directory record and locator, then the classic end record.
std::string end_records(std::uint64_t entries, std::uint64_t cd_offset, std::uint64_t cd_size) {
  const std::uint64_t zip64_end_offset = cd_offset + cd_size;
  std::string h;
  put32(h, 0x06064b50u);
  put64(h, 44);  // size of the rest of the record
  put16(h, 45);  // version made by
  put16(h, 45);  // version needed
  put32(h, 0);   // this disk
  put32(h, 0);   // disk of the central directory
  put64(h, entries);
  put64(h, entries);
  put64(h, cd_size);
  put64(h, cd_offset);
  put32(h, 0x07064b50u);  // locator
  put32(h, 0);            // disk of the ZIP64 end record
  put64(h, zip64_end_offset);
  put32(h, 1);  // disks
  put32(h, 0x06054b50u);
  put16(h, 0);
  put16(h, 0);
  put16(h, static_cast<std::uint32_t>(std::min<std::uint64_t>(entries, 0xFFFFu)));
  put16(h, static_cast<std::uint32_t>(std::min<std::uint64_t>(entries, 0xFFFFu)));
  put32(h, static_cast<std::uint32_t>(std::min<std::uint64_t>(cd_size, u32_max)));
  put32(h, static_cast<std::uint32_t>(std::min<std::uint64_t>(cd_offset, u32_max)));
  put16(h, 0);  // comment length
  return h;
}

// ---- the sink ---------------------------------------------------------------

class NpzTrajectory final : public TrajectorySink {
 public:
  NpzTrajectory(const std::string& path, const TrajectoryLayout& layout, const SinkPosition* resume)
      : path_(path), layout_(layout), row_bytes(std::int64_t{8} * layout.columns) {
    try {
      if (resume) {
        reopen(*resume);
      } else {
        file_ = std::fopen(path.c_str(), "wb");
        if (!file_) fail("cannot write");
        write_at(0, local_header(trajectory_local_entry(0, 0)));
        write_at(local_header_bytes, trajectory_npy_header(0, layout_));
      }
      buffer_.reserve(static_cast<std::size_t>(rows_per_block * row_bytes));
    } catch (...) {
      if (file_) std::fclose(file_);
      file_ = nullptr;
      throw;
    }
  }

  ~NpzTrajectory() override {
    // Without close() (an exception in the run, or a crash test): the rows go
    // to the file, which stays a partial archive that resume can continue.
    if (!file_) return;
    try {
      flush_rows();
    } catch (...) {  // a destructor must not throw; close() reports errors
    }
    std::fclose(file_);
  }

  void row(const double* values) override {
    if (!file_) throw std::runtime_error("row after close of " + path_);
    if constexpr (std::endian::native == std::endian::little) {
      const auto* bytes = reinterpret_cast<const unsigned char*>(values);
      buffer_.insert(buffer_.end(), bytes, bytes + row_bytes);
    } else {
      for (int c = 0; c < layout_.columns; ++c) {
        std::uint64_t bits;
        std::memcpy(&bits, values + c, 8);
        for (int b = 0; b < 8; ++b) buffer_.push_back(static_cast<unsigned char>(bits >> (8 * b)));
      }
    }
    ++rows_;
    if (buffer_.size() >= static_cast<std::size_t>(rows_per_block * row_bytes)) flush_rows();
  }

  SinkPosition sync() override {
    if (!file_) throw std::runtime_error("sync after close of " + path_);
    flush_rows();
    if (std::fflush(file_) != 0) fail("writing", " failed");
    SinkPosition p;
    p.rows = rows_;
    p.bytes = end_;
    p.crc32 = crc32_combine(placeholder_crc(), data_crc_, static_cast<std::uint64_t>(end_ - data_offset));
    return p;
  }

  void close(const std::string& scenario_toml, const std::string& summary_json) override {
    if (!file_) throw std::runtime_error("close of an already closed " + path_);
    flush_rows();
    const std::string header = trajectory_npy_header(rows_, layout_);
    const std::uint64_t data_bytes = static_cast<std::uint64_t>(end_ - data_offset);
    std::vector<Entry> entries;
    entries.push_back(trajectory_local_entry(crc32_combine(crc32_of(header), data_crc_, data_bytes),
                                             header.size() + data_bytes));

    std::vector<std::string> names;
    for (const char *p = layout_.header, *q = p;; ++q)
      if (*q == ',' || *q == '\0') {
        names.emplace_back(p, q);
        if (*q == '\0') break;
        p = q + 1;
      }
    const std::pair<const char*, std::string> small[] = {{"columns.npy", npy_unicode(names, false)},
                                                        {"scenario.npy", npy_unicode({scenario_toml}, true)},
                                                        {"summary.npy", npy_unicode({summary_json}, true)}};
    std::int64_t at = end_;
    for (const auto& [name, content] : small) {
      Entry e;
      e.name = name;
      e.crc = crc32_of(content);
      e.size = content.size();
      e.offset = static_cast<std::uint64_t>(at);
      const std::string h = local_header(e);
      write_at(at, h);
      write_at(at + static_cast<std::int64_t>(h.size()), content);
      at += static_cast<std::int64_t>(h.size() + content.size());
      entries.push_back(e);
    }
    std::string cd;
    for (const auto& e : entries) cd += central_header(e);
    write_at(at, cd + end_records(entries.size(), static_cast<std::uint64_t>(at), cd.size()));

    // Patch the trajectory's sizes, CRC and shape in place.
    write_at(0, local_header(entries.front()));
    write_at(local_header_bytes, header);

    std::FILE* f = file_;
    file_ = nullptr;
    if (std::fclose(f) != 0) fail("closing", " failed");
  }

 private:
  static constexpr std::int64_t rows_per_block = 4096;  // 688 KiB

  static Entry trajectory_local_entry(std::uint32_t crc, std::uint64_t size) {
    Entry e;
    e.name = trajectory_entry;
    e.crc = crc;
    e.size = size;
    e.offset = 0;
    e.zip64_sizes = true;
    return e;
  }

  std::uint32_t placeholder_crc() const { return crc32_of(trajectory_npy_header(0, layout_)); }

  /// Throws "<what> <path><after>: <errno's message>".
  [[noreturn]] void fail(const std::string& what, const char* after = "") const {
    const int e = errno;
    throw std::runtime_error(what + " " + path_ + after + (e ? std::string(": ") + std::strerror(e) : std::string()));
  }

  /// Writes at `offset`, seeking only when not already there (streaming rows never seeks).
  void write_at(std::int64_t offset, const void* bytes, std::size_t n) {
    errno = 0;
    if (offset != at_ && fseeko(file_, static_cast<off_t>(offset), SEEK_SET) != 0) {
      at_ = -1;
      fail("writing", " failed");  // a seek flushes stdio's buffer: the error is usually the write's
    }
    at_ = offset;
    if (std::fwrite(bytes, 1, n, file_) != n) {
      at_ = -1;
      fail("writing", " failed");
    }
    at_ += static_cast<std::int64_t>(n);
  }
  void write_at(std::int64_t offset, const std::string& bytes) { write_at(offset, bytes.data(), bytes.size()); }

  void flush_rows() {
    if (buffer_.empty()) return;
    write_at(end_, buffer_.data(), buffer_.size());
    data_crc_ = crc32_update(data_crc_, buffer_.data(), buffer_.size());
    end_ += static_cast<std::int64_t>(buffer_.size());
    buffer_.clear();
  }

  /// Resume: check the file and the position, read the data once to check
  /// its CRC, truncate the file back to the position and restore the headers
  /// as they were while rows were being written (a closed file had them
  /// patched).
  void reopen(const SinkPosition& p) {
    if (p.rows < 0 || p.bytes != data_offset + p.rows * row_bytes)
      throw std::runtime_error("cannot resume " + path_ + ": the checkpoint's position (" + std::to_string(p.rows) +
                               " rows, " + std::to_string(p.bytes) + " bytes) is not one of an npz trajectory");
    std::error_code ec;
    const auto size = std::filesystem::file_size(path_, ec);
    if (ec) throw std::runtime_error("cannot resume " + path_ + ": " + ec.message());
    if (size < static_cast<std::uintmax_t>(p.bytes))
      throw std::runtime_error("cannot resume " + path_ + ": the file is shorter (" + std::to_string(size) +
                               " bytes) than the checkpoint's position (" + std::to_string(p.bytes) + " bytes)");
    file_ = std::fopen(path_.c_str(), "r+b");
    if (!file_) fail("cannot open to resume");

    std::vector<unsigned char> block(1 << 20);
    if (std::fread(block.data(), 1, static_cast<std::size_t>(data_offset), file_) !=
            static_cast<std::size_t>(data_offset) ||
        load_le32(block.data()) != 0x04034b50u ||
        std::memcmp(block.data() + 30, trajectory_entry.data(), trajectory_entry.size()) != 0 ||
        std::memcmp(block.data() + local_header_bytes, "\x93NUMPY", 6) != 0)
      throw std::runtime_error("cannot resume " + path_ + ": not an npz trajectory written by lgvi");
    std::uint32_t crc = 0;
    for (std::int64_t left = p.bytes - data_offset; left > 0;) {
      const std::size_t n = static_cast<std::size_t>(std::min<std::int64_t>(left, std::int64_t(block.size())));
      errno = 0;
      if (std::fread(block.data(), 1, n, file_) != n) fail("reading", " failed");
      crc = crc32_update(crc, block.data(), n);
      left -= static_cast<std::int64_t>(n);
    }
    if (crc32_combine(placeholder_crc(), crc, static_cast<std::uint64_t>(p.bytes - data_offset)) != p.crc32)
      throw std::runtime_error("cannot resume " + path_ +
                               ": its rows do not match the checkpoint (CRC-32 differs); was the file changed?");
    std::fclose(file_);
    file_ = nullptr;

    std::filesystem::resize_file(path_, static_cast<std::uintmax_t>(p.bytes), ec);
    if (ec) throw std::runtime_error("cannot truncate " + path_ + " to resume: " + ec.message());
    file_ = std::fopen(path_.c_str(), "r+b");
    if (!file_) fail("cannot open to resume");
    at_ = 0;
    write_at(0, local_header(trajectory_local_entry(0, 0)));
    write_at(local_header_bytes, trajectory_npy_header(0, layout_));
    rows_ = p.rows;
    end_ = p.bytes;
    data_crc_ = crc;
  }

  std::string path_;
  TrajectoryLayout layout_;
  std::int64_t row_bytes;  // 8 bytes per column
  std::FILE* file_ = nullptr;
  std::int64_t rows_ = 0;
  std::int64_t end_ = data_offset;  // file offset of the end of the rows written to the file
  std::uint32_t data_crc_ = 0;      // CRC-32 of the rows written to the file
  std::int64_t at_ = 0;             // the stream's file offset; -1: unknown
  std::vector<unsigned char> buffer_;
};

}  // namespace

std::unique_ptr<TrajectorySink> open_npz(const std::string& path, const TrajectoryLayout& layout,
                                         const SinkPosition* resume) {
  return std::make_unique<NpzTrajectory>(path, layout, resume);
}

}  // namespace lgvi::app
