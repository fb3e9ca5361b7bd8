// The ZIP layer of the npz writer: little-endian fields, stored (uncompressed)
// entries with ZIP64 sizes, the central directory and end records, and ZIP's
// CRC-32 (zlib's crc32 and crc32_combine). Written for streaming: an entry's
// data can be appended as it comes, its CRC updated on the fly, and its local
// header patched at the end (libzip and minizip rewrite archives at close and
// cannot resume a streamed entry).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace lgvi::io::zip {

inline void put16(std::string& s, std::uint32_t v) {
  s.push_back(static_cast<char>(v & 0xFFu));
  s.push_back(static_cast<char>((v >> 8) & 0xFFu));
}
inline void put32(std::string& s, std::uint32_t v) {
  put16(s, v & 0xFFFFu);
  put16(s, v >> 16);
}
inline void put64(std::string& s, std::uint64_t v) {
  put32(s, static_cast<std::uint32_t>(v & 0xFFFFFFFFu));
  put32(s, static_cast<std::uint32_t>(v >> 32));
}

inline constexpr std::uint32_t u32_max = 0xFFFFFFFFu;
inline constexpr std::uint32_t dos_time = 0;                        // 00:00:00
inline constexpr std::uint32_t dos_date = (0u << 9) | (1u << 5) | 1u;  // 1980-01-01

inline std::uint32_t load_le32(const unsigned char* p) {
  return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}

struct Entry {
  std::string name;
  std::uint32_t crc = 0;
  std::uint64_t size = 0;    // stored: compressed size = uncompressed size
  std::uint64_t offset = 0;  // of the local header
  bool zip64_sizes = false;  // sizes in a ZIP64 extra field (trajectory.npy: always)
};

/// The local file header of `e` (with a ZIP64 extra field of the sizes when e.zip64_sizes).
std::string local_header(const Entry& e);
/// The central directory header of `e`.
std::string central_header(const Entry& e);
/// ZIP64 end of central directory record and locator, then the classic end record.
std::string end_records(std::uint64_t entries, std::uint64_t cd_offset, std::uint64_t cd_size);

/// The CRC-32 of (the bytes behind `crc`) followed by p[0, n) (zlib's crc32).
std::uint32_t crc32_update(std::uint32_t crc, const unsigned char* p, std::size_t n);
/// The CRC-32 of s.
std::uint32_t crc32_of(const std::string& s);
/// The CRC of A followed by B from crc(A), crc(B) and the length of B (zlib's
/// crc32_combine64): it lets the npz writer put the final .npy header in front
/// of data whose CRC was computed as the rows arrived, without reading them again.
std::uint32_t crc32_combine(std::uint32_t crc_a, std::uint32_t crc_b, std::uint64_t length_b);

}  // namespace lgvi::io::zip
