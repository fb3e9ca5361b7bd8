// Output files of a run: lgvi's number text (JSON and CSV) and atomic file
// replacement.
#pragma once

#include <cstdio>
#include <functional>
#include <string>

namespace lgvi::io {

/// A number as lgvi writes it in JSON and CSV files: 17 significant digits
/// (%.17g, enough to read back the same double), "null" for NaN and inf
/// (JSON has neither).
std::string json_number(double v);

/// Writes `text` to `path` atomically: a temporary file in the same folder,
/// then a rename, so a reader never sees a half-written file.
void write_file_atomically(const std::string& path, const std::string& text);

/// The same for text written by `write` into the open temporary file, as it
/// is made (a large summary is not held in memory whole); `write` returns
/// false on a write error.
void write_file_atomically(const std::string& path, const std::function<bool(std::FILE*)>& write);

}  // namespace lgvi::io
