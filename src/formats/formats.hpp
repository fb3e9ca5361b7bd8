// Binary trajectory formats: numpy's .npz (written without numpy) and HDF5.
#pragma once

#include "trajectory_sink.hpp"

namespace lgvi::app {

/// `path`.npz with entries trajectory.npy (float64, shape (rows, columns), or
/// (steps, bodies, columns) for the long layout, C order), columns.npy (the
/// column names), scenario.npy and summary.npy (0-d unicode arrays holding
/// the scenario's TOML and the summary's JSON).
std::unique_ptr<TrajectorySink> open_npz(const std::string& path, const TrajectoryLayout& layout,
                                         const SinkPosition* resume);

/// `path`.h5 with a chunked, extendible dataset /trajectory (float64,
/// (rows, columns), or (steps, bodies, columns) for the long layout), its
/// attribute `columns`, and root attributes `scenario` and `summary` (strings).
std::unique_ptr<TrajectorySink> open_hdf5(const std::string& path, const TrajectoryLayout& layout,
                                          const SinkPosition* resume);

}  // namespace lgvi::app
