// Writing a TOML document back to text (the run's copy of a scenario whose
// file tables were inlined or whose orbit / attitude was converted, and each
// ensemble member's scenario).
//
// Why not toml++'s own toml_formatter: its line-wrapping estimate
// (toml_formatter_count_inline_columns in toml++ 3.3, Debian 12) casts
// log10(|x|) to size_t, which is undefined behaviour for every float with
// 0 < |x| < 0.1 in an array or inline table (upstream marzer/tomlplusplus
// pull request 276); the fuzzer's UBSan build stops on it. This writer lays
// the document out exactly as toml_formatter does (same order, indentation,
// table separators, the same 120-column rule for breaking an array over
// lines) with that estimate defined, and prints every scalar and key through
// toml++ itself, so the text is toml_formatter's wherever toml_formatter is
// defined, and it parses back to the same values.
#pragma once

#include <string>

#include <toml++/toml.h>

namespace lgvi::app {

/// The document as TOML text: top-level keys, then [tables], then [[arrays
/// of tables]], laid out like toml::toml_formatter's default flags.
std::string write_toml(const toml::table& document);

/// One inline table, `{ key = value, ... }` (for a comment line quoting a
/// table of the user's input).
std::string write_inline_toml(const toml::table& table);

}  // namespace lgvi::app
