// `lgvi show DIR`: the summary of a run as a readable table.
#pragma once

#include <ostream>
#include <string>

namespace lgvi::app {

/// Prints the summary of the run in `dir` to `out`; throws InvalidInput if
/// DIR has no readable summary.json.
void show_run(const std::string& dir, std::ostream& out);

}  // namespace lgvi::app
