#include "output.hpp"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <stdexcept>

namespace lgvi::app {

namespace {
constexpr std::size_t rows_per_block = 2048;
}

CsvWriter::CsvWriter(const std::string& path, const std::string& header, int columns)
    : path_(path), columns_(columns) {
  file_ = std::fopen(path.c_str(), "wb");
  if (!file_) throw std::runtime_error("cannot write " + path + ": " + std::strerror(errno));
  if (std::fputs((header + "\n").c_str(), file_) < 0) throw std::runtime_error("cannot write " + path);
  filling_.reserve(rows_per_block * static_cast<std::size_t>(columns));
  writing_.reserve(filling_.capacity());
  thread_ = std::thread([this] { writer_loop(); });
}

CsvWriter::~CsvWriter() {
  try {
    close();
  } catch (...) {  // a destructor must not throw; close() reports errors to callers that call it
  }
}

void CsvWriter::row(const double* values) {
  filling_.insert(filling_.end(), values, values + columns_);
  if (filling_.size() >= rows_per_block * static_cast<std::size_t>(columns_)) hand_over();
}

void CsvWriter::hand_over() {
  std::unique_lock lock(mutex_);
  cv_.wait(lock, [this] { return !block_ready_; });  // the writer has taken the previous block
  std::swap(filling_, writing_);
  filling_.clear();
  block_ready_ = true;
  cv_.notify_all();
}

void CsvWriter::writer_loop() {
  std::vector<double> block;
  for (;;) {
    {
      std::unique_lock lock(mutex_);
      cv_.wait(lock, [this] { return block_ready_ || stop_; });
      if (!block_ready_) return;  // stop_ and nothing left
      std::swap(block, writing_);
      block_ready_ = false;
      cv_.notify_all();
    }
    if (error_.empty()) write_block(block);
    block.clear();
  }
}

void CsvWriter::write_block(const std::vector<double>& block) {
  // 17 significant digits (%.17g) with std::to_chars: exact text, several
  // times faster than printf.
  std::string text;
  text.reserve(block.size() * 24);
  char number[32];
  for (std::size_t i = 0; i < block.size(); ++i) {
    const auto res = std::to_chars(number, number + sizeof number, block[i], std::chars_format::general, 17);
    text.append(number, res.ptr);
    text.push_back((i + 1) % static_cast<std::size_t>(columns_) == 0 ? '\n' : ',');
  }
  if (std::fwrite(text.data(), 1, text.size(), file_) != text.size())
    error_ = "writing " + path_ + " failed: " + std::strerror(errno);
}

void CsvWriter::close() {
  if (!file_) return;
  if (!filling_.empty()) hand_over();
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
    cv_.notify_all();
  }
  if (thread_.joinable()) thread_.join();
  const int rc = std::fclose(file_);
  file_ = nullptr;
  if (!error_.empty()) throw std::runtime_error(error_);
  if (rc != 0) throw std::runtime_error("closing " + path_ + " failed: " + std::strerror(errno));
}

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
    s += pad + json_string(items_[i].first) + ": " + nested + (i + 1 < items_.size() ? ",\n" : "\n");
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
