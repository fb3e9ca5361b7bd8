#include "io/formats/npy.hpp"

#include "io/formats/zip_stream.hpp"

#include <algorithm>
#include <stdexcept>

namespace lgvi::io::npy {

using zip::put16;
using zip::put32;

std::string npy_header(const std::string& dict, std::size_t total) {
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

std::string trajectory_npy_header(std::int64_t rows, const TrajectoryLayout& layout) {
  const std::string shape = layout.bodies > 0 ? std::to_string(rows / layout.bodies) + ", " +
                                                    std::to_string(layout.bodies) + ", " + std::to_string(layout.columns)
                                              : std::to_string(rows) + ", " + std::to_string(layout.columns);
  return npy_header("{'descr': '<f8', 'fortran_order': False, 'shape': (" + shape + "), }", trajectory_header_bytes);
}

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

}  // namespace lgvi::io::npy
