#include "io/formats/zip_stream.hpp"

#include <zlib.h>

#include <algorithm>
#include <limits>

namespace lgvi::io::zip {

namespace {
/// The fields the local and the central header share, from "version needed
/// to extract" to the file name's length.
void common_fields(std::string& h, const Entry& e, bool zip64) {
  put16(h, zip64 ? 45 : 20);  // version needed to extract (4.5: ZIP64)
  put16(h, 0);                // flags
  put16(h, 0);                // method: stored
  put16(h, dos_time);
  put16(h, dos_date);
  put32(h, e.crc);
  put32(h, e.zip64_sizes ? u32_max : static_cast<std::uint32_t>(e.size));
  put32(h, e.zip64_sizes ? u32_max : static_cast<std::uint32_t>(e.size));
  put16(h, static_cast<std::uint32_t>(e.name.size()));
}
}  // namespace

std::string local_header(const Entry& e) {
  std::string h;
  put32(h, 0x04034b50u);
  common_fields(h, e, e.zip64_sizes);
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
  put16(h, 45);  // version made by: 4.5, MS-DOS attributes
  common_fields(h, e, zip64);
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

std::uint32_t crc32_update(std::uint32_t crc, const unsigned char* p, std::size_t n) {
  // zlib takes lengths as uInt: feed it in pieces.
  uLong c = crc;
  while (n > 0) {
    const auto piece = static_cast<uInt>(std::min<std::size_t>(n, std::numeric_limits<uInt>::max()));
    c = ::crc32(c, p, piece);
    p += piece;
    n -= piece;
  }
  return static_cast<std::uint32_t>(c);
}

std::uint32_t crc32_of(const std::string& s) {
  return crc32_update(0, reinterpret_cast<const unsigned char*>(s.data()), s.size());
}

std::uint32_t crc32_combine(std::uint32_t crc_a, std::uint32_t crc_b, std::uint64_t length_b) {
  return static_cast<std::uint32_t>(::crc32_combine64(crc_a, crc_b, static_cast<z_off64_t>(length_b)));
}

}  // namespace lgvi::io::zip
