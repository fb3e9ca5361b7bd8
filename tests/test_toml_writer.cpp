// Tests of the TOML writer (src/io/toml_writer.cpp): toml++'s own toml_formatter
// is the independent reference for the layout (with strings and floats masked,
// which the writer spells otherwise) wherever its line-wrapping estimate is
// defined (floats of magnitude >= 0.1); Python's repr is the reference for the
// floats' spelling (here a table of its texts; tests/python/test_toml_text.py
// compares 40000 random doubles against repr itself); and every document
// parses back to equal values.
#include <gtest/gtest.h>

#include "io/toml_writer.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <regex>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace test_toml_writer {

namespace {

using lgvi::io::write_inline_toml;
using lgvi::io::write_toml;

std::string toml_formatter_text(const toml::table& t) {
  std::ostringstream os;
  os << toml::toml_formatter(t);
  return os.str();
}

/// The layout alone: every string ('...' or "...") as S and every float as F.
std::string masked(const std::string& text) {
  static const std::regex strings(R"('[^'\n]*'|"(?:[^"\\\n]|\\.)*")");
  static const std::regex floats(R"(-?(?:\d+\.\d+(?:e[+-]?\d+)?|\d+e[+-]?\d+|nan|inf)\b)");
  return std::regex_replace(std::regex_replace(text, strings, "S"), floats, "F");
}

TEST(TomlWriter, LaysOutEveryShippedScenarioAsTomlFormatterDoes) {
  // The shipped scenarios hold tables, arrays of tables ([[bodies]],
  // [[forcing]]), nested arrays (inertia), strings and integers; none has a
  // float below 0.1 in an array, so toml_formatter is defined on them and
  // must agree byte for byte.
  int files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(LGVI_SCENARIO_DIR)) {
    if (entry.path().extension() != ".toml") continue;
    const toml::table doc = toml::parse_file(entry.path().string());
    const std::string text = write_toml(doc);
    EXPECT_EQ(masked(text), masked(toml_formatter_text(doc))) << entry.path();
    EXPECT_EQ(toml::parse(text), doc) << entry.path();
    ++files;
  }
  EXPECT_GE(files, 10);
}

TEST(TomlWriter, LongArraysBreakOverLinesAndDeepTablesIndentLikeTomlFormatter) {
  toml::table doc;
  toml::array long_array;
  for (int i = 0; i < 40; ++i) long_array.push_back(1.5 + i);  // 40 x "NN.5, " > 120 columns
  doc.insert("composition", long_array);
  doc.insert("name", "a \"quoted\" name");
  toml::table inner{{"x", 1.0}, {"deep", toml::table{{"y", std::int64_t{-7}}}}};
  doc.insert("outer", toml::table{{"k", true}, {"inner", inner}});
  toml::array bodies;
  bodies.push_back(toml::table{{"mass", 2.0}, {"ball", toml::table{{"inline", 1.0}}}});
  bodies.push_back(toml::table{{"mass", 3.0}});
  doc.insert("bodies", bodies);
  const std::string text = write_toml(doc);
  EXPECT_EQ(masked(text), masked(toml_formatter_text(doc)));
  EXPECT_NE(text.find("[\n"), std::string::npos) << "the 40-element array is broken over lines";
  EXPECT_NE(text.find("name = \"a \\\"quoted\\\" name\"\n"), std::string::npos) << text;  // a basic string
  EXPECT_EQ(toml::parse(text), doc);
}

TEST(TomlWriter, SmallFloatsAreDefinedAndRoundTrip) {
  // toml_formatter is undefined here (it casts log10(0.05) < 0 to size_t);
  // the writer counts such a float as "0.x" and keeps a 3-vector on one line.
  toml::table doc{{"initial", toml::table{{"w", toml::array{0.05, -1.0e-20, 3.0e-310}}}}};
  const std::string text = write_toml(doc);
  // One header line and the vector on one line, as repr spells the numbers.
  EXPECT_EQ(text, "[initial]\nw = [ 0.05, -1e-20, 3e-310 ]") << text;
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 1) << text;
  EXPECT_EQ(toml::parse(text), doc);
  toml::array tiny;
  for (int i = 0; i < 40; ++i) tiny.push_back(1.0e-3 * (i + 1));
  toml::table long_doc{{"composition", tiny}};
  const std::string long_text = write_toml(long_doc);
  // 40 elements of at least 5 columns ("0.x, ") exceed 120: broken over lines.
  EXPECT_EQ(long_text.rfind("composition = [\n    0.001,\n", 0), 0u) << long_text;
  EXPECT_EQ(toml::parse(long_text), long_doc);
}

TEST(TomlWriter, FloatsAreSpelledAsPythonsRepr) {
  // The right-hand texts are Python's repr of each double (CPython 3.11).
  const double inf = std::numeric_limits<double>::infinity();
  const std::vector<std::pair<double, std::string>> cases = {
      {0.1, "0.1"},
      {0.1 + 0.2, "0.30000000000000004"},
      {1.0 / 3.0, "0.3333333333333333"},
      {3.0, "3.0"},
      {-0.0, "-0.0"},
      {1e-4, "0.0001"},
      {1e-5, "1e-05"},
      {-2.5e-7, "-2.5e-07"},
      {1e15, "1000000000000000.0"},
      {1e16, "1e+16"},
      {9999999999999998.0, "9999999999999998.0"},
      {123456789012345678.0, "1.2345678901234568e+17"},
      {6.02214076e23, "6.02214076e+23"},
      {5e-324, "5e-324"},
      {std::numeric_limits<double>::max(), "1.7976931348623157e+308"},
      {12345.678, "12345.678"},
      {inf, "inf"},
      {-inf, "-inf"},
      {std::nan(""), "nan"},
  };
  for (const auto& [x, repr] : cases) {
    const toml::table doc{{"x", x}};
    const std::string text = write_toml(doc);
    EXPECT_EQ(text, "x = " + repr) << repr;
    const double back = toml::parse(text)["x"].value<double>().value();
    if (std::isnan(x))
      EXPECT_TRUE(std::isnan(back));
    else
      EXPECT_TRUE(back == x && std::signbit(back) == std::signbit(x)) << repr;
  }
}

TEST(TomlWriter, StringsAreAsciiBasicStringsWithTheEscapesTomlAndJsonShare) {
  // The expected text is json.dumps's (ensure_ascii) of the same string: "é" U+00E9, "𝛀" U+1D6C0 (JSON
  // writes a surrogate pair, TOML \U0001d6c0), DEL, a control character.
  const toml::table doc{{"s", "tab\there \"q\" back\\slash caf\xc3\xa9 \xf0\x9d\x9b\x80 \x7f\x01 end\n"}};
  const std::string text = write_toml(doc);
  EXPECT_EQ(text,
            "s = \"tab\\there \\\"q\\\" back\\\\slash caf\\u00e9 \\U0001d6c0 \\u007f\\u0001 end\\n\"");
  EXPECT_TRUE(std::all_of(text.begin(), text.end(), [](char c) { return static_cast<unsigned char>(c) < 0x80; }));
  EXPECT_EQ(toml::parse(text), doc);
  // A byte that is not UTF-8 is U+FFFD (TOML strings are Unicode).
  EXPECT_EQ(write_toml(toml::table{{"s", std::string("a\xff")}}), "s = \"a\\ufffd\"");
  const toml::table key{{"a key", 1.0}};
  EXPECT_EQ(write_toml(key), "\"a key\" = 1.0");
}

TEST(TomlWriter, InlineTableQuotesTheUsersInput) {
  const toml::table orbit{{"radius", 8.0e6}, {"eccentricity", 0.01}, {"inclination", 30.0}};
  EXPECT_EQ(write_inline_toml(orbit), "{ eccentricity = 0.01, inclination = 30.0, radius = 8000000.0 }");
  EXPECT_EQ(write_inline_toml(toml::table{}), "{}");
}

}  // namespace

}  // namespace test_toml_writer
