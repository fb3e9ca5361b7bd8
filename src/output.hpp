// Trajectory and summary files of a run.
#pragma once

#include <cstdint>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <thread>
#include <string>
#include <vector>

#include <fmt/format.h>

namespace lgvi::app {

/// The columns of trajectory.csv, in order.
inline constexpr const char* trajectory_header =
    "t,x,y,z,qw,qx,qy,qz,px,py,pz,wx,wy,wz,energy,energy_error,quat_norm_error,Lx,Ly,Lz,momentum_error";
inline constexpr int trajectory_columns = 21;

/// CSV writer: rows of doubles printed with 17 significant digits (%.17g:
/// every double round-trips exactly). Formatting 17 digits costs ~60 ns a
/// number, as much as the integration itself on the paper's run, so rows are
/// collected in blocks and a second thread formats and writes each block
/// while the integration goes on (double buffering). The file's bytes do not
/// depend on the timing.
class CsvWriter {
 public:
  /// Opens (truncates) `path` and writes `header`; throws std::runtime_error
  /// naming the file on failure.
  CsvWriter(const std::string& path, const std::string& header, int columns);
  ~CsvWriter();
  CsvWriter(const CsvWriter&) = delete;
  CsvWriter& operator=(const CsvWriter&) = delete;

  void row(const double* values);
  /// Writes out every row and closes; throws on a write error (disk full).
  void close();

 private:
  void hand_over();
  void writer_loop();
  void write_block(const std::vector<double>& block);

  std::string path_;
  int columns_;
  std::FILE* file_ = nullptr;
  std::vector<double> filling_, writing_;
  std::thread thread_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool block_ready_ = false, stop_ = false;
  std::string error_;
};

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
