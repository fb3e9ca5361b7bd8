#include "io/json_io.hpp"

#include "io/output.hpp"

#include <lgvi/error.hpp>

#include <algorithm>

namespace lgvi::io {

namespace {

bool named(const std::vector<std::string_view>& names, const std::string& key) {
  return std::find(names.begin(), names.end(), key) != names.end();
}

/// A number, string, boolean or null. nlohmann's dump would write a double
/// as its shortest round-trip text ("0.1") and NaN as null; lgvi's files
/// have json_number's 17 digits ("0.10000000000000001").
std::string leaf_text(const Json& j) {
  if (j.is_number_float()) return json_number(j.get<double>());
  return j.dump(-1, ' ', false, Json::error_handler_t::replace);
}

std::string key_text(const std::string& key) { return leaf_text(Json(key)); }

/// `j` on one line: ", " between elements and members, ": " after keys.
void append_one_line(std::string& out, const Json& j) {
  if (j.is_object()) {
    out += '{';
    for (auto it = j.begin(); it != j.end(); ++it) {
      if (it != j.begin()) out += ", ";
      out += key_text(it.key()) + ": ";
      append_one_line(out, it.value());
    }
    out += '}';
  } else if (j.is_array()) {
    out += '[';
    for (std::size_t i = 0; i < j.size(); ++i) {
      if (i > 0) out += ", ";
      append_one_line(out, j[i]);
    }
    out += ']';
  } else {
    out += leaf_text(j);
  }
}

/// Where the text goes: appended to `out`, which is emptied into `file` (if
/// any) once it is longer than a buffer, between a generated array's elements.
struct Drain {
  std::FILE* file = nullptr;
  bool ok = true;
  void operator()(std::string& out) {
    if (file == nullptr || out.size() < (std::size_t{1} << 16)) return;
    ok = ok && std::fwrite(out.data(), 1, out.size(), file) == out.size();
    out.clear();
  }
};

/// `j` at nesting `depth` (0: the document), laid out by `layout`: an object
/// one member a line, its members indented by 2 (depth + 1) spaces.
void append(std::string& out, const Json& j, int depth, const JsonLayout& layout, Drain& drain) {
  if (!j.is_object()) {
    append_one_line(out, j);
    return;
  }
  const std::string pad(static_cast<std::size_t>(2 * depth), ' ');
  const std::string member_pad = pad + "  ";
  out += "{\n";
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (it != j.begin()) out += ",\n";
    out += member_pad + key_text(it.key()) + ": ";
    const Json& value = it.value();
    const auto generated = std::find_if(layout.generated.begin(), layout.generated.end(),
                                        [&](const JsonLayout::Generated& g) { return g.placeholder == &value; });
    if (generated != layout.generated.end() && generated->count > 0) {
      out += '[';
      for (std::size_t i = 0; i < generated->count; ++i) {
        out += i > 0 ? ",\n" : "\n";
        out += member_pad + "  ";
        append_one_line(out, generated->element(i));
        drain(out);
      }
      out += "\n" + member_pad + ']';
    } else if (generated != layout.generated.end()) {
      out += "[]";
    } else if (value.is_object() && !named(layout.one_line, it.key())) {
      append(out, value, depth + 1, layout, drain);
    } else if (value.is_array() && !value.empty() && named(layout.one_element_a_line, it.key())) {
      out += '[';
      for (std::size_t i = 0; i < value.size(); ++i) {
        out += i > 0 ? ",\n" : "\n";
        out += member_pad + "  ";
        append_one_line(out, value[i]);
      }
      out += "\n" + member_pad + ']';
    } else {
      append_one_line(out, value);
    }
  }
  if (!j.empty()) out += '\n';
  out += pad + '}';
}

}  // namespace

std::string json_text(const Json& doc, const JsonLayout& layout) {
  std::string out;
  Drain none;
  append(out, doc, 0, layout, none);
  return out;
}

bool write_json(std::FILE* file, const Json& doc, const JsonLayout& layout) {
  std::string out;
  Drain drain{file};
  append(out, doc, 0, layout, drain);
  return drain.ok && std::fwrite(out.data(), 1, out.size(), file) == out.size();
}

bool write_json_lines(std::FILE* file, std::size_t count, const std::function<Json(std::size_t)>& element) {
  std::string out;
  Drain drain{file};
  for (std::size_t i = 0; i < count; ++i) {
    append_one_line(out, element(i));
    out += '\n';
    drain(out);
  }
  return drain.ok && std::fwrite(out.data(), 1, out.size(), file) == out.size();
}

namespace {

/// Parses with `parse`; a parse error as parse_json_file_text's message.
template <class Parse>
Json parsed_or_one_line(const std::string& file, Parse&& parse) {
  try {
    return parse();
  } catch (const Json::exception& e) {
    // e.what() is "[json.exception.parse_error.101] parse error at line 4,
    // column 3: ..." (nlohmann writes the control characters it quotes as
    // <U+000A>, so it is one line); the tag means nothing to a user.
    std::string what = e.what();
    const std::size_t tag_end = what.find("] ");
    if (what.rfind("[json.exception.", 0) == 0 && tag_end != std::string::npos) what.erase(0, tag_end + 2);
    throw InvalidInput(file + ": not valid JSON (" + what + ")");
  }
}

}  // namespace

Json parse_json_file_text(const std::string& text, const std::string& file) {
  return parsed_or_one_line(file, [&] { return Json::parse(text); });
}

Json parse_json_file_stream(std::istream& in, const std::string& file, const Json::parser_callback_t& keep) {
  return parsed_or_one_line(file, [&] { return Json::parse(in, keep); });
}

}  // namespace lgvi::io
