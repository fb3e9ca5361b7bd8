// The .npy layer of the npz writer: numpy's array file format (version 1.0)
// for float64 tables and unicode strings, written without numpy.
#pragma once

#include "io/trajectory_sink.hpp"

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace lgvi::io::npy {

/// Bytes reserved for the trajectory's .npy header, so that the number of
/// rows can be patched in place at close (room for any int64) and the data
/// start at a multiple of 64.
inline constexpr std::size_t trajectory_header_bytes = 128;

/// A version 1.0 .npy header for `dict`, padded with spaces so that the
/// whole header is `total` bytes (a multiple of 64) or, with total = 0, the
/// smallest multiple of 64 that holds it.
std::string npy_header(const std::string& dict, std::size_t total = 0);

/// The .npy header of the trajectory after `rows` rows: shape (rows, columns),
/// or (rows / bodies, bodies, columns) for the long layout.
std::string trajectory_npy_header(std::int64_t rows, const TrajectoryLayout& layout);

/// UTF-8 to code points; a malformed sequence becomes U+FFFD.
std::vector<std::uint32_t> code_points(const std::string& s);

/// A .npy of unicode strings ('<U{width}', UTF-32LE, NUL-padded): 0-d when
/// `scalar`, else shape (strings.size(),).
std::string npy_unicode(const std::vector<std::string>& strings, bool scalar);

}  // namespace lgvi::io::npy
