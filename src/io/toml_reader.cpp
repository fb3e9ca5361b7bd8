#include "io/toml_reader.hpp"

namespace lgvi::io {

std::string printable(std::string_view text) {
  std::string o;
  for (char c : text) {
    if (c == '\n') o += "\\n";
    else if (c == '\t') o += "\\t";
    else if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) o += "?";
    else o += c;
  }
  return o;
}

}  // namespace lgvi::io
