// The summary of a run (the CLI's summary.json, also stored in npz and HDF5
// trajectories and returned by the Python package): what was run, whether it
// completed, and the diagnostics' maxima over every step.
#pragma once

#include "app/scenario.hpp"
#include "app/simulation.hpp"

#include <string>

namespace lgvi::app {

/// The file beside summary.json holding a system's lists of bodies, one body a
/// line, where the scenario's body_lists says so (BodyLists::file).
inline constexpr const char* kBodyListsFile = "bodies.jsonl";

/// The summary of a run as JSON text (the CLI's summary.json).
std::string summary_json(const Scenario& scenario, const SimulationResult& result);

/// The same text written to `path` atomically as it is made: a system's
/// lists of bodies are not held in memory whole (summary.json of a run).
/// With BodyLists::file, the lists go to kBodyListsFile in the same folder,
/// written before the summary that names it.
void write_summary_file(const std::string& path, const Scenario& scenario, const SimulationResult& result);

}  // namespace lgvi::app
