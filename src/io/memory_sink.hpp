// A TrajectorySink that keeps the rows in memory, for the Python package:
// lgvi.simulate() hands them to numpy without a copy.
#pragma once

#include "io/trajectory_sink.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace lgvi::io {

class MemorySink final : public TrajectorySink {
 public:
  /// Reserves room for `rows_hint` rows (the rows a run will write).
  explicit MemorySink(std::int64_t rows_hint = 0, const TrajectoryLayout& layout = {}) : layout_(layout) {
    if (rows_hint > 0 && rows_hint < (std::int64_t{1} << 26))
      data_.reserve(static_cast<std::size_t>(rows_hint) * static_cast<std::size_t>(layout.columns));
  }

  void row(const double* values) override {
    data_.insert(data_.end(), values, values + layout_.columns);
    ++rows_;
  }

  /// Nothing to flush; the position is the number of rows.
  SinkPosition sync() override {
    SinkPosition p;
    p.rows = rows_;
    return p;
  }

  /// Keeps the scenario and summary texts, like the npz and HDF5 files do.
  bool stores_summary() const override { return true; }
  void close(const std::string& scenario_toml, const std::string& summary_json) override {
    scenario_ = scenario_toml;
    summary_ = summary_json;
  }

  std::int64_t rows() const { return rows_; }
  const TrajectoryLayout& layout() const { return layout_; }
  /// The rows, row-major (rows() x layout().columns); leaves the sink empty.
  std::vector<double> take() {
    rows_ = 0;
    return std::move(data_);
  }

 private:
  TrajectoryLayout layout_;
  std::vector<double> data_;
  std::int64_t rows_ = 0;
  std::string scenario_, summary_;
};

}  // namespace lgvi::io
