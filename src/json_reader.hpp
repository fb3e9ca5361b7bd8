// A small JSON reader for the files lgvi writes itself (summary.json), used by
// `lgvi show`. Objects keep their key order.
#pragma once

#include <map>
#include <memory>
#include <string>
#include <utility>
#include <variant>
#include <vector>

namespace lgvi::app {

struct JsonValue;
using JsonArray = std::vector<JsonValue>;
using JsonMembers = std::vector<std::pair<std::string, JsonValue>>;

struct JsonValue {
  std::variant<std::nullptr_t, bool, double, std::string, std::shared_ptr<JsonArray>, std::shared_ptr<JsonMembers>> v;

  bool is_object() const { return std::holds_alternative<std::shared_ptr<JsonMembers>>(v); }
  bool is_array() const { return std::holds_alternative<std::shared_ptr<JsonArray>>(v); }
  bool is_number() const { return std::holds_alternative<double>(v); }
  /// The member `key` of an object, or nullptr.
  const JsonValue* find(const std::string& key) const;
};

/// Parses JSON text; throws std::runtime_error with the offset on bad input.
JsonValue parse_json(const std::string& text);

}  // namespace lgvi::app
