#include "output.hpp"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <stdexcept>

namespace lgvi::app {

std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";  // JSON has no NaN/inf
  return fmt::format("{:.17g}", v);
}

std::string json_string(const std::string& s) {
  std::string o = "\"";
  for (char c : s) {
    switch (c) {
      case '"': o += "\\\""; break;
      case '\\': o += "\\\\"; break;
      case '\n': o += "\\n"; break;
      case '\t': o += "\\t"; break;
      case '\r': o += "\\r"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20)
          o += fmt::format("\\u{:04x}", static_cast<int>(c));
        else
          o += c;
    }
  }
  return o + "\"";
}

JsonObject& JsonObject::number(const std::string& k, double v) { return raw(k, json_number(v)); }
JsonObject& JsonObject::integer(const std::string& k, std::int64_t v) { return raw(k, std::to_string(v)); }
JsonObject& JsonObject::boolean(const std::string& k, bool v) { return raw(k, v ? "true" : "false"); }
JsonObject& JsonObject::string(const std::string& k, const std::string& v) { return raw(k, json_string(v)); }
JsonObject& JsonObject::array(const std::string& k, const std::vector<double>& v) {
  std::string s = "[";
  for (std::size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + json_number(v[i]);
  return raw(k, s + "]");
}
JsonObject& JsonObject::object(const std::string& k, const JsonObject& o) { return raw(k, o.str()); }
JsonObject& JsonObject::raw(const std::string& k, const std::string& json) {
  items_.emplace_back(k, json);
  return *this;
}

std::string JsonObject::str(int indent) const {
  const std::string pad(static_cast<std::size_t>(indent + 2), ' ');
  std::string s = "{\n";
  for (std::size_t i = 0; i < items_.size(); ++i) {
    // Nested objects are re-indented by one level.
    std::string v = items_[i].second;
    std::string nested;
    for (char c : v) {
      nested += c;
      if (c == '\n') nested += std::string(static_cast<std::size_t>(indent + 2), ' ');
    }
    s += pad;
    s += json_string(items_[i].first);
    s += ": ";
    s += nested;
    s += i + 1 < items_.size() ? ",\n" : "\n";
  }
  return s + std::string(static_cast<std::size_t>(indent), ' ') + "}";
}

void write_file_atomically(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (!f) throw std::runtime_error("cannot write " + tmp + ": " + std::strerror(errno));
  const bool ok = std::fwrite(text.data(), 1, text.size(), f) == text.size();
  if (std::fclose(f) != 0 || !ok) {
    std::remove(tmp.c_str());
    throw std::runtime_error("writing " + path + " failed: " + std::strerror(errno));
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw std::runtime_error("renaming " + tmp + " to " + path + " failed: " + ec.message());
}

}  // namespace lgvi::app
