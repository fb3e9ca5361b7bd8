// Placeholder until the npz writer lands (being written now).
#include "formats/formats.hpp"

#include <stdexcept>

namespace lgvi::app {
std::unique_ptr<TrajectorySink> open_npz(const std::string&, const SinkPosition*) {
  throw std::runtime_error("the npz trajectory format is not available yet");
}
}  // namespace lgvi::app
