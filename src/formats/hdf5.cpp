// Placeholder until the hdf5 writer lands (being written now).
#include "formats/formats.hpp"

#include <stdexcept>

namespace lgvi::app {
std::unique_ptr<TrajectorySink> open_hdf5(const std::string&, const SinkPosition*) {
  throw std::runtime_error("the hdf5 trajectory format is not available yet");
}
}  // namespace lgvi::app
