// numpy's .npz trajectory, written without numpy: a ZIP archive of
// uncompressed (stored) .npy entries, streamed row by row. The .npy layer is
// formats/npy.hpp, the ZIP layer (and zlib's CRC-32) formats/zip_stream.hpp;
// this file is the sink that streams the rows and patches the headers.
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
#include "io/formats/registry.hpp"
#include "io/formats/npy.hpp"
#include "io/formats/zip_stream.hpp"
#include "io/output.hpp"

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

namespace lgvi::io {

namespace {
using namespace zip;
using npy::npy_unicode;
using npy::npy_header;
using npy::trajectory_header_bytes;
using npy::trajectory_npy_header;

const std::string trajectory_entry = "trajectory.npy";
constexpr std::int64_t local_header_bytes = 30 + 14 + 20;  // fixed part, name, ZIP64 extra
constexpr std::int64_t data_offset = local_header_bytes + static_cast<std::int64_t>(trajectory_header_bytes);
static_assert(data_offset % 64 == 0);

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

  bool stores_summary() const override { return true; }
  void close(const std::string& scenario_toml, const std::string& summary_json) override {
    if (!file_) throw std::runtime_error("close of an already closed " + path_);
    flush_rows();
    const std::string header = trajectory_npy_header(rows_, layout_);
    const std::uint64_t data_bytes = static_cast<std::uint64_t>(end_ - data_offset);
    std::vector<Entry> entries;
    entries.push_back(trajectory_local_entry(crc32_combine(crc32_of(header), data_crc_, data_bytes),
                                             header.size() + data_bytes));

    const std::pair<const char*, std::string> small[] = {{"columns.npy", npy_unicode(layout_.column_names(), false)},
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

std::unique_ptr<TrajectorySink> open_npz(const std::string& path, const TrajectoryLayout& layout,
                                         const SinkPosition* resume) {
  return std::make_unique<NpzTrajectory>(path, layout, resume);
}

/// Little-endian bytes of 64-bit values (float64 or int64), as .npy stores them.
template <class T>
void append_le64(std::string& out, const std::vector<T>& values) {
  static_assert(sizeof(T) == 8);
  for (const T& v : values) {
    std::uint64_t bits;
    std::memcpy(&bits, &v, 8);
    for (int b = 0; b < 8; ++b) out.push_back(static_cast<char>((bits >> (8 * b)) & 0xFFu));
  }
}

/// A 1-D .npy of `column`.
std::string npy_column(const ColumnTable::Column& column) {
  using Kind = ColumnTable::Column::Kind;
  if (column.kind == Kind::String) return npy_unicode(column.strings, false);
  const std::string dict = "{'descr': '" + std::string(column.kind == Kind::Number ? "<f8" : "<i8") +
                           "', 'fortran_order': False, 'shape': (" + std::to_string(column.size()) + ",), }";
  std::string out = npy_header(dict);
  if (column.kind == Kind::Number)
    append_le64(out, column.numbers);
  else
    append_le64(out, column.integers);
  return out;
}

/// One 1-D array per column, named by it ('<f8', '<i8' or '<U': numpy's
/// loader gives float64, int64 and str arrays), stored uncompressed in column
/// order. Written whole to a temporary name and renamed: never half-written.
/// The bytes depend on the table alone.
void write_npz_table(const std::string& path, const ColumnTable& table) {
  std::string archive;
  std::vector<Entry> entries;
  for (const ColumnTable::Column& column : table.columns) {
    const std::string content = npy_column(column);
    Entry e;
    e.name = column.name + ".npy";
    e.crc = crc32_of(content);
    e.size = content.size();
    e.offset = archive.size();
    archive += local_header(e);
    archive += content;
    entries.push_back(std::move(e));
  }
  std::string cd;
  for (const Entry& e : entries) cd += central_header(e);
  archive += cd + end_records(entries.size(), archive.size(), cd.size());
  write_file_atomically(path, archive);
}

}  // namespace

extern const FormatDescriptor npz_format;  // listed in formats/registry.cpp
const FormatDescriptor npz_format{.name = "npz", .file_name = "trajectory.npz", .holds_columns = true, .open = open_npz, .write_table = write_npz_table, .table_file_name = "members.npz"};

}  // namespace lgvi::io
