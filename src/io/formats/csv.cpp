// [output] format = "csv" (the default): one text line per row, the
// trajectory's columns with a header line; the scenario and the summary are
// the run folder's side files (scenario.toml, summary.json).
#include "io/formats/registry.hpp"

#include <cerrno>
#include <charconv>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

namespace lgvi::io {

namespace {

/// CSV: rows printed with 17 significant digits (%.17g: every double
/// round-trips exactly). Formatting 17 digits costs as much as the
/// integration itself on the paper's run (docs/tuning.md), so rows are
/// collected in blocks and a second thread formats and writes each block
/// while the integration goes on (double buffering). The bytes do not depend
/// on timing.
class CsvTrajectory final : public TrajectorySink {
 public:
  CsvTrajectory(const std::string& path, const TrajectoryLayout& layout, const SinkPosition* resume)
      : path_(path), columns_(static_cast<std::size_t>(layout.columns)) {
    file_ = open_appendable_file(path, resume);
    if (resume) rows_ = resume->rows;
    if (!resume && std::fputs((layout.header + "\n").c_str(), file_) < 0)
      throw std::runtime_error("cannot write " + path);
    filling_.reserve(rows_per_block * columns_);
    writing_.reserve(filling_.capacity());
    thread_ = std::thread([this] { writer_loop(); });
  }

  ~CsvTrajectory() override {
    try {
      finish();
    } catch (...) {  // errors reach callers through close(); a destructor must not throw
    }
  }

  void row(const double* values) override {
    filling_.insert(filling_.end(), values, values + columns_);
    ++rows_;
    if (filling_.size() >= rows_per_block * columns_) hand_over();
  }

  SinkPosition sync() override {
    if (!filling_.empty()) hand_over();
    std::unique_lock lock(mutex_);
    cv_.wait(lock, [this] { return !block_ready_ && !busy_; });  // the writer is idle: all handed rows are written
    if (!error_.empty()) throw std::runtime_error(error_);
    if (std::fflush(file_) != 0) throw std::runtime_error("writing " + path_ + " failed: " + std::strerror(errno));
    SinkPosition p;
    p.rows = rows_;
    p.bytes = static_cast<std::int64_t>(std::ftell(file_));
    return p;
  }

  void close(const std::string&, const std::string&) override { finish(); }

 private:
  static constexpr std::size_t rows_per_block = 2048;

  void finish() {
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

  void hand_over() {
    std::unique_lock lock(mutex_);
    cv_.wait(lock, [this] { return !block_ready_; });  // the writer has taken the previous block
    std::swap(filling_, writing_);
    filling_.clear();
    block_ready_ = true;
    cv_.notify_all();
  }

  void writer_loop() {
    std::vector<double> block;
    for (;;) {
      {
        std::unique_lock lock(mutex_);
        cv_.wait(lock, [this] { return block_ready_ || stop_; });
        if (!block_ready_) return;  // stopped with nothing left
        std::swap(block, writing_);
        block_ready_ = false;
        busy_ = true;
        cv_.notify_all();
      }
      if (error_.empty()) write_block(block);
      block.clear();
      {
        std::lock_guard lock(mutex_);
        busy_ = false;
        cv_.notify_all();
      }
    }
  }

  void write_block(const std::vector<double>& block) {
    std::string text;
    text.reserve(block.size() * 24);
    char number[32];
    for (std::size_t i = 0; i < block.size(); ++i) {
      const auto res = std::to_chars(number, number + sizeof number, block[i], std::chars_format::general, 17);
      text.append(number, res.ptr);
      text.push_back((i + 1) % columns_ == 0 ? '\n' : ',');
    }
    if (std::fwrite(text.data(), 1, text.size(), file_) != text.size())
      error_ = "writing " + path_ + " failed: " + std::strerror(errno);
  }

  std::string path_;
  std::size_t columns_;
  std::FILE* file_ = nullptr;
  std::int64_t rows_ = 0;
  std::vector<double> filling_, writing_;
  std::thread thread_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool block_ready_ = false, busy_ = false, stop_ = false;
  std::string error_;  // set by the writer thread; read after sync() waits or after join
};

std::unique_ptr<TrajectorySink> open_csv(const std::string& path, const TrajectoryLayout& layout,
                                         const SinkPosition* resume) {
  return std::make_unique<CsvTrajectory>(path, layout, resume);
}

}  // namespace

extern const FormatDescriptor csv_format;  // listed in formats/registry.cpp
const FormatDescriptor csv_format{
    .name = "csv", .file_name = "trajectory.csv", .holds_columns = true, .open = open_csv};

}  // namespace lgvi::io
