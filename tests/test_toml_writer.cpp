// Tests of the TOML writer (src/toml_writer.cpp): toml++'s own toml_formatter
// is the independent reference for the layout wherever its line-wrapping
// estimate is defined (floats of magnitude >= 0.1), and every document parses
// back to equal values.
#include <gtest/gtest.h>

#include "toml_writer.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <filesystem>
#include <sstream>
#include <string>

namespace {

using lgvi::app::write_inline_toml;
using lgvi::app::write_toml;

std::string toml_formatter_text(const toml::table& t) {
  std::ostringstream os;
  os << toml::toml_formatter(t);
  return os.str();
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
    EXPECT_EQ(write_toml(doc), toml_formatter_text(doc)) << entry.path();
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
  EXPECT_EQ(write_toml(doc), toml_formatter_text(doc));
  EXPECT_NE(write_toml(doc).find("[\n"), std::string::npos) << "the 40-element array is broken over lines";
}

TEST(TomlWriter, SmallFloatsAreDefinedAndRoundTrip) {
  // toml_formatter is undefined here (it casts log10(0.05) < 0 to size_t);
  // the writer counts such a float as "0.x" and keeps a 3-vector on one line.
  toml::table doc{{"initial", toml::table{{"w", toml::array{0.05, -1.0e-20, 3.0e-310}}}}};
  const std::string text = write_toml(doc);
  // One header line and the vector on one line; toml++ prints the numbers
  // (17 significant digits), the round trip below checks them.
  EXPECT_EQ(text.rfind("[initial]\nw = [ ", 0), 0u) << text;
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

TEST(TomlWriter, InlineTableQuotesTheUsersInput) {
  const toml::table orbit{{"radius", 8.0e6}, {"eccentricity", 0.01}, {"inclination", 30.0}};
  EXPECT_EQ(write_inline_toml(orbit), "{ eccentricity = 0.01, inclination = 30.0, radius = 8000000.0 }");
  EXPECT_EQ(write_inline_toml(toml::table{}), "{}");
}

}  // namespace
