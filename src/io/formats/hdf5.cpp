// HDF5 trajectory through the HDF5 C API (Debian's libhdf5, 1.10 or later).
//
// File layout:
//   /trajectory          dataset, H5T_IEEE_F64LE, shape (rows, 21), maximum
//                        shape (unlimited, 21), chunks of 4096 x 21 (688 KiB),
//                        no filters. Rows are collected 4096 at a time and
//                        appended by extending the dataset and writing a
//                        hyperslab, so memory does not grow with the rows.
//   /trajectory@columns  the 21 column names, a 1-d attribute of
//                        variable-length UTF-8 strings (h5py 3 reads str).
//   /@scenario, /@summary  scalar variable-length UTF-8 strings (the
//                        scenario's TOML, the summary's JSON; h5py reads str),
//                        written at close.
// The file uses HDF5's default (earliest) format versions, readable by any
// HDF5 1.8 or later.
//
// SinkPosition: rows only. Resume opens the file read-write, sets the
// dataset's extent back to the position's rows (dropping rows written after
// it) and removes the root attributes of a previous close, then appends.
// sync() writes the buffered rows and flushes the file (H5Fflush). Unlike the
// CSV and npz files, an HDF5 file is not append-only: HDF5 1.10 updates its
// metadata (chunk index, extent) in place, so a process killed between two
// syncs can leave a file that HDF5 cannot open. Resume then fails with an
// error naming the file; a run stopped by an exception (the sink destroyed
// without close) leaves a consistent file.
//
// Every HDF5 failure becomes a std::runtime_error naming the file, the
// operation and HDF5's innermost error message; HDF5's own error printing is
// switched off.
#include "io/formats/registry.hpp"

#include <hdf5.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace lgvi::io {

namespace {

/// An HDF5 identifier closed by its close function when it goes out of scope.
class Handle {
 public:
  using Closer = herr_t (*)(hid_t);
  Handle() = default;
  Handle(hid_t id, Closer closer) : id_(id), closer_(closer) {}
  Handle(Handle&& o) noexcept : id_(std::exchange(o.id_, H5I_INVALID_HID)), closer_(o.closer_) {}
  Handle& operator=(Handle&& o) noexcept {
    if (this != &o) {
      reset();
      id_ = std::exchange(o.id_, H5I_INVALID_HID);
      closer_ = o.closer_;
    }
    return *this;
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle() { reset(); }

  hid_t get() const { return id_; }
  /// Closes now; returns the close function's status (negative on failure).
  herr_t reset() {
    herr_t rc = 0;
    if (id_ >= 0 && closer_) rc = closer_(id_);
    id_ = H5I_INVALID_HID;
    return rc;
  }

 private:
  hid_t id_ = H5I_INVALID_HID;
  Closer closer_ = nullptr;
};

/// HDF5's innermost error message on this thread's error stack, or "".
std::string hdf5_error() {
  std::string message;
  H5Ewalk2(
      H5E_DEFAULT, H5E_WALK_UPWARD,
      [](unsigned, const H5E_error2_t* e, void* out) -> herr_t {
        auto& m = *static_cast<std::string*>(out);
        if (m.empty() && e && e->desc && *e->desc) m = e->desc;
        return 0;
      },
      &message);
  H5Eclear2(H5E_DEFAULT);
  for (char& c : message)
    if (c == '\n') c = ' ';
  return message;
}

constexpr hsize_t chunk_rows = 4096;
constexpr const char* dataset_name = "trajectory";

class Hdf5Trajectory final : public TrajectorySink {
 public:
  Hdf5Trajectory(const std::string& path, const TrajectoryLayout& layout, const SinkPosition* resume)
      : path_(path),
        layout_(layout),
        columns_(static_cast<hsize_t>(layout.columns)),
        per_step_(static_cast<hsize_t>(layout.rows_per_step())),
        rank_(layout.bodies > 0 ? 3 : 2) {
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    if (resume) reopen(*resume);
    else create();
    buffer_.reserve(chunk_rows * columns_);
  }

  ~Hdf5Trajectory() override {
    // Without close(): the rows so far go to the file, which is left without
    // the scenario and summary attributes (and can be resumed).
    if (file_.get() < 0) return;
    try {
      flush_rows();
    } catch (...) {  // a destructor must not throw; close() reports errors
    }
  }

  void row(const double* values) override {
    if (file_.get() < 0) throw std::runtime_error("row after close of " + path_);
    buffer_.insert(buffer_.end(), values, values + layout_.columns);
    // Whole steps only: the long layout's dataset grows by steps of N rows.
    const hsize_t rows = buffer_.size() / columns_;
    if (rows >= chunk_rows && rows % per_step_ == 0) flush_rows();
  }

  SinkPosition sync() override {
    if (file_.get() < 0) throw std::runtime_error("sync after close of " + path_);
    flush_rows();
    check(H5Fflush(file_.get(), H5F_SCOPE_LOCAL), "flush");
    SinkPosition p;
    p.rows = static_cast<std::int64_t>(rows_);
    return p;
  }

  bool stores_summary() const override { return true; }
  void close(const std::string& scenario_toml, const std::string& summary_json) override {
    if (file_.get() < 0) throw std::runtime_error("close of an already closed " + path_);
    flush_rows();
    write_string_attribute("scenario", scenario_toml);
    write_string_attribute("summary", summary_json);
    check(dataset_.reset(), "close the dataset of");
    check(file_.reset(), "close");
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    const std::string detail = hdf5_error();
    throw std::runtime_error("HDF5: cannot " + what + " " + path_ + (detail.empty() ? "" : ": " + detail));
  }
  template <class T>
  T check(T rc, const std::string& what) const {
    if (rc < 0) fail(what);
    return rc;
  }
  Handle handle(hid_t id, Handle::Closer closer, const std::string& what) const {
    check(id, what);
    return Handle(id, closer);
  }

  static Handle utf8_string_type() {
    const hid_t t = H5Tcopy(H5T_C_S1);
    Handle h(t, H5Tclose);
    if (t < 0 || H5Tset_size(t, H5T_VARIABLE) < 0 || H5Tset_cset(t, H5T_CSET_UTF8) < 0) return Handle();
    return h;
  }

  void create() {
    file_ = handle(H5Fcreate(path_.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose, "create");
    // (rows, columns), or (steps, bodies, columns) for the long layout.
    const hsize_t dims[3] = {0, rank_ == 3 ? per_step_ : columns_, columns_};
    const hsize_t maxdims[3] = {H5S_UNLIMITED, dims[1], columns_};
    const hsize_t chunk[3] = {rank_ == 3 ? std::max<hsize_t>(1, chunk_rows / per_step_) : chunk_rows, dims[1], columns_};
    Handle space = handle(H5Screate_simple(rank_, dims, maxdims), H5Sclose, "create the dataspace of");
    Handle dcpl = handle(H5Pcreate(H5P_DATASET_CREATE), H5Pclose, "create the dataset properties of");
    check(H5Pset_chunk(dcpl.get(), rank_, chunk), "set the chunk size of");
    // Every element is written before it is read: no fill values.
    check(H5Pset_fill_time(dcpl.get(), H5D_FILL_TIME_NEVER), "set the fill time of");
    dataset_ = handle(H5Dcreate2(file_.get(), dataset_name, H5T_IEEE_F64LE, space.get(), H5P_DEFAULT, dcpl.get(),
                                 H5P_DEFAULT),
                      H5Dclose, "create /trajectory in");

    const std::vector<std::string> names = layout_.column_names();
    std::vector<const char*> pointers;
    pointers.reserve(names.size());
    for (const auto& n : names) pointers.push_back(n.c_str());
    const hsize_t count = pointers.size();
    Handle type = utf8_string_type();
    check(type.get(), "create a string type for");
    Handle aspace = handle(H5Screate_simple(1, &count, nullptr), H5Sclose, "create the dataspace of columns in");
    Handle attr = handle(H5Acreate2(dataset_.get(), "columns", type.get(), aspace.get(), H5P_DEFAULT, H5P_DEFAULT),
                         H5Aclose, "create /trajectory@columns in");
    check(H5Awrite(attr.get(), type.get(), pointers.data()), "write /trajectory@columns in");
  }

  void reopen(const SinkPosition& p) {
    file_ = handle(H5Fopen(path_.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose, "open to resume");
    dataset_ = handle(H5Dopen2(file_.get(), dataset_name, H5P_DEFAULT), H5Dclose, "open /trajectory in");
    Handle space = handle(H5Dget_space(dataset_.get()), H5Sclose, "get the dataspace of /trajectory in");
    hsize_t dims[3] = {0, 0, 0};
    if (H5Sget_simple_extent_ndims(space.get()) != rank_ ||
        H5Sget_simple_extent_dims(space.get(), dims, nullptr) != rank_ || dims[rank_ - 1] != columns_ ||
        (rank_ == 3 && dims[1] != per_step_))
      throw std::runtime_error("cannot resume " + path_ + ": /trajectory is not an array of " +
                               std::to_string(columns_) + " columns" +
                               (rank_ == 3 ? " for " + std::to_string(per_step_) + " bodies" : std::string()));
    const hsize_t rows_in_file = rank_ == 3 ? dims[0] * per_step_ : dims[0];
    if (p.rows < 0 || rows_in_file < static_cast<hsize_t>(p.rows) || static_cast<hsize_t>(p.rows) % per_step_ != 0)
      throw std::runtime_error("cannot resume " + path_ + ": it has " + std::to_string(rows_in_file) +
                               " rows, fewer than the checkpoint's " + std::to_string(p.rows));
    rows_ = static_cast<hsize_t>(p.rows);
    const hsize_t extent[3] = {rank_ == 3 ? rows_ / per_step_ : rows_, rank_ == 3 ? per_step_ : columns_, columns_};
    check(H5Dset_extent(dataset_.get(), extent), "set the extent of /trajectory to resume");
    for (const char* name : {"scenario", "summary"})
      if (check(H5Aexists(file_.get(), name), std::string("look for /@") + name + " in") > 0)
        check(H5Adelete(file_.get(), name), std::string("delete /@") + name + " in");
  }

  void flush_rows() {
    if (buffer_.empty()) return;
    const hsize_t n = buffer_.size() / columns_;
    // In steps for the long layout (rows_ and n are whole steps there).
    const hsize_t first = rank_ == 3 ? rows_ / per_step_ : rows_, count0 = rank_ == 3 ? n / per_step_ : n;
    const hsize_t middle = rank_ == 3 ? per_step_ : columns_;
    const hsize_t extent[3] = {first + count0, middle, columns_};
    check(H5Dset_extent(dataset_.get(), extent), "extend /trajectory in");
    Handle fspace = handle(H5Dget_space(dataset_.get()), H5Sclose, "get the dataspace of /trajectory in");
    const hsize_t start[3] = {first, 0, 0};
    const hsize_t count[3] = {count0, middle, columns_};
    check(H5Sselect_hyperslab(fspace.get(), H5S_SELECT_SET, start, nullptr, count, nullptr),
          "select rows of /trajectory in");
    Handle mspace = handle(H5Screate_simple(rank_, count, nullptr), H5Sclose, "create a memory dataspace for");
    check(H5Dwrite(dataset_.get(), H5T_NATIVE_DOUBLE, mspace.get(), fspace.get(), H5P_DEFAULT, buffer_.data()),
          "write rows to");
    rows_ += n;
    buffer_.clear();
  }

  void write_string_attribute(const char* name, const std::string& text) {
    const std::string what = std::string("write /@") + name + " in";
    if (check(H5Aexists(file_.get(), name), what) > 0) check(H5Adelete(file_.get(), name), what);
    Handle type = utf8_string_type();
    check(type.get(), what);
    Handle space = handle(H5Screate(H5S_SCALAR), H5Sclose, what);
    Handle attr = handle(H5Acreate2(file_.get(), name, type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose,
                         what);
    const char* p = text.c_str();
    check(H5Awrite(attr.get(), type.get(), &p), what);
  }

  std::string path_;
  TrajectoryLayout layout_;
  hsize_t columns_, per_step_;
  int rank_;  // 2: (rows, columns); 3: (steps, bodies, columns)
  // Members are destroyed in reverse order: the dataset closes before the file.
  Handle file_;
  Handle dataset_;
  hsize_t rows_ = 0;  // rows in the dataset
  std::vector<double> buffer_;
};

std::unique_ptr<TrajectorySink> open_hdf5(const std::string& path, const TrajectoryLayout& layout,
                                          const SinkPosition* resume) {
  return std::make_unique<Hdf5Trajectory>(path, layout, resume);
}

/// One 1-D dataset per column at the root (IEEE float64 LE, int64 LE,
/// variable-length UTF-8 strings), no timestamps, written to a temporary name
/// and renamed.
void write_hdf5_table(const std::string& path, const ColumnTable& table) {
  using Kind = ColumnTable::Column::Kind;
  const std::string tmp = path + ".tmp";
  auto fail = [&](const std::string& what) {
    const std::string detail = hdf5_error();
    std::remove(tmp.c_str());
    throw std::runtime_error("HDF5: cannot " + what + " " + tmp + (detail.empty() ? "" : ": " + detail));
  };
  auto handle = [&](hid_t id, Handle::Closer closer, const std::string& what) {
    if (id < 0) fail(what);
    return Handle(id, closer);
  };
  {
    Handle file = handle(H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose, "create");
    // No modification times in the object headers: the bytes depend on the table alone.
    Handle dcpl = handle(H5Pcreate(H5P_DATASET_CREATE), H5Pclose, "create the dataset properties of");
    if (H5Pset_obj_track_times(dcpl.get(), false) < 0) fail("switch off the timestamps of");
    for (const ColumnTable::Column& column : table.columns) {
      const hsize_t n = column.size();
      Handle space = handle(H5Screate_simple(1, &n, nullptr), H5Sclose, "create the dataspace of " + column.name + " in");
      Handle string_type;
      hid_t file_type = H5T_IEEE_F64LE, memory_type = H5T_NATIVE_DOUBLE;
      const void* data = column.numbers.data();
      std::vector<const char*> pointers;
      if (column.kind == Kind::Integer) {
        file_type = H5T_STD_I64LE;
        memory_type = H5T_NATIVE_INT64;
        data = column.integers.data();
      } else if (column.kind == Kind::String) {
        string_type = handle(H5Tcopy(H5T_C_S1), H5Tclose, "create a string type for");
        if (H5Tset_size(string_type.get(), H5T_VARIABLE) < 0 || H5Tset_cset(string_type.get(), H5T_CSET_UTF8) < 0)
          fail("set up a UTF-8 string type for");
        file_type = memory_type = string_type.get();
        for (const std::string& s : column.strings) pointers.push_back(s.c_str());
        data = pointers.data();
      }
      Handle dataset = handle(H5Dcreate2(file.get(), column.name.c_str(), file_type, space.get(), H5P_DEFAULT,
                                         dcpl.get(), H5P_DEFAULT),
                              H5Dclose, "create /" + column.name + " in");
      if (n > 0 && H5Dwrite(dataset.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0)
        fail("write /" + column.name + " in");
    }
    if (file.reset() < 0) fail("close");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw std::runtime_error("renaming " + tmp + " to " + path + " failed: " + ec.message());
}

}  // namespace

extern const FormatDescriptor hdf5_format;  // listed in formats/registry.cpp
const FormatDescriptor hdf5_format{.name = "hdf5", .file_name = "trajectory.h5", .holds_columns = true, .open = open_hdf5, .write_table = write_hdf5_table, .table_file_name = "members.h5"};

}  // namespace lgvi::io
