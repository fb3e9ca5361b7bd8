// lgvi's JSON files (summary.json): nlohmann::ordered_json documents, written
// in lgvi's layout and with its number text (json_number's), and read back
// with one-line errors.
#pragma once

#include <cstdio>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

namespace lgvi::io {

/// A JSON document; objects keep the order their keys were added in.
using Json = nlohmann::ordered_json;

/// Where json_text breaks lines. By default an object is written one member a
/// line (indented by two spaces a level) and an array on one line, with
/// everything inside it on one line too ("[1, 2]", "[{\"a\": 1, \"b\": 2}]").
/// The members named here, at any depth, are written otherwise.
struct JsonLayout {
  /// Objects written on one line ({"a": 1, "b": 2}).
  std::vector<std::string_view> one_line;
  /// Arrays written one element a line (the lists of bodies).
  std::vector<std::string_view> one_element_a_line;
  /// Arrays written one element a line whose elements are made as they are
  /// written, one at a time (the lists of bodies: one body's JSON object in
  /// memory, not N of them): where the document holds the array (an empty
  /// placeholder, found by address), its length and its element i.
  struct Generated {
    const Json* placeholder = nullptr;
    std::size_t count = 0;
    std::function<Json(std::size_t)> element;
  };
  std::vector<Generated> generated = {};
};

/// `doc` as JSON text laid out by `layout`. Floating-point numbers are
/// json_number's text (17 significant digits, null for NaN and inf), so that
/// a file reads back to the same doubles; integers, booleans and strings are
/// nlohmann's (UTF-8 written as it is, invalid UTF-8 replaced by U+FFFD).
std::string json_text(const Json& doc, const JsonLayout& layout = {});

/// The same text written to `file` as it is made (a generated array's
/// elements a buffer at a time, not the whole text in memory); false if a
/// write failed.
bool write_json(std::FILE* file, const Json& doc, const JsonLayout& layout = {});

/// JSON Lines: elements 0 ... count - 1 written to `file` one a line, each on
/// one line as json_text lays out an array's elements, made one at a time as
/// they are written; false if a write failed.
bool write_json_lines(std::FILE* file, std::size_t count, const std::function<Json(std::size_t)>& element);
/// Parses the JSON text read from `file`; throws InvalidInput "FILE: not
/// valid JSON (parse error at line L, column C: WHAT)", on one line, if it is
/// not JSON.
Json parse_json_file_text(const std::string& text, const std::string& file);

/// The same, read from a stream as it is parsed, with nlohmann's parser
/// callback (return false to drop an element as soon as it is parsed).
Json parse_json_file_stream(std::istream& in, const std::string& file, const Json::parser_callback_t& keep);

}  // namespace lgvi::io
