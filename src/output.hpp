// Summary files of a run: a small JSON writer and atomic file replacement.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <fmt/format.h>

namespace lgvi::app {

/// A minimal JSON object writer (the summary is small and flat-ish).
class JsonObject {
 public:
  JsonObject& number(const std::string& key, double v);
  JsonObject& integer(const std::string& key, std::int64_t v);
  JsonObject& boolean(const std::string& key, bool v);
  JsonObject& string(const std::string& key, const std::string& v);
  JsonObject& array(const std::string& key, const std::vector<double>& v);
  JsonObject& object(const std::string& key, const JsonObject& o);
  JsonObject& raw(const std::string& key, const std::string& json);
  std::string str(int indent = 0) const;

 private:
  std::vector<std::pair<std::string, std::string>> items_;
};

std::string json_number(double v);
std::string json_string(const std::string& s);

/// Writes `text` to `path` atomically: a temporary file in the same folder,
/// then a rename, so a reader never sees a half-written file.
void write_file_atomically(const std::string& path, const std::string& text);

}  // namespace lgvi::app
