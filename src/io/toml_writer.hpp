// Writing a TOML document back to text: the run's copy of a scenario whose
// file tables were inlined or whose orbit / attitude was converted, each
// ensemble member's scenario, and every scenario and sweep the Python package
// builds (lgvi._core.toml_text): the one TOML writer.
//
// Why not toml++'s own toml_formatter: its line-wrapping estimate
// (toml_formatter_count_inline_columns in toml++ 3.3, Debian 12) casts
// log10(|x|) to size_t, which is undefined behaviour for every float with
// 0 < |x| < 0.1 in an array or inline table (upstream marzer/tomlplusplus
// pull request 276); the fuzzer's UBSan build stops on it. This writer lays
// the document out exactly as toml_formatter does (same order, indentation,
// table separators, the same 120-column rule for breaking an array over
// lines) with that estimate defined. Floats are spelled as Python's repr
// spells them (the shortest text that reads back to the same double: 0.1, not
// toml++'s 0.10000000000000001), strings and quoted keys as "..." basic
// strings (not toml++'s '...'), other scalars by toml++. The text parses back
// to the same values.
#pragma once

#include <string>

#include <toml++/toml.h>

namespace lgvi::io {

/// The document as TOML text: top-level keys, then [tables], then [[arrays
/// of tables]], laid out like toml::toml_formatter's default flags.
std::string write_toml(const toml::table& document);

/// One inline table, `{ key = value, ... }` (for a comment line quoting a
/// table of the user's input).
std::string write_inline_toml(const toml::table& table);

}  // namespace lgvi::io
