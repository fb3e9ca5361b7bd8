// lgvi's JSON files through nlohmann::ordered_json (src/io/json_io.hpp): the
// summary's text byte for byte as the hand-written writer it replaced wrote
// it (tests/reference/summary_*.json were written by that writer), \u
// escapes read as UTF-8, and one error naming the file for a file that is
// not JSON.
#include "io/json_io.hpp"
#include "io/output.hpp"
#include "app/scenario.hpp"
#include "app/show.hpp"
#include "app/simulation.hpp"
#include "app/summary.hpp"

#include <lgvi/error.hpp>

#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace test_json {

namespace {

namespace fs = std::filesystem;
using lgvi::InvalidInput;
using lgvi::app::Json;
using lgvi::app::json_text;
using lgvi::app::JsonLayout;
using lgvi::app::parse_json_file_text;
using lgvi::app::parse_scenario;

const fs::path reference_dir = fs::path(LGVI_SCENARIO_DIR).parent_path() / "tests" / "reference";

std::string file_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// A fresh folder of this test process under the system's temporary folder.
fs::path fresh_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("lgvi-test-json-" + name + "-" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// Two scenarios that between them hold every member summary.json can have:
// one body with balls in a J2 field, composed to order 4, under a forcing,
// named with a non-ASCII character; and two named bodies with gravity.
const char* const single_body_toml = R"(
[body]
[[body.ball]]
position = [1.0, 0.0, 0.0]
mass = 0.1
radius = 0.2
[[body.ball]]
position = [-1.0, 0.0, 0.0]
mass = 0.3
radius = 0.2
[[body.ball]]
position = [0.0, 0.5, 0.25]
mass = 0.7
radius = 0.2
[potential]
kind = "central"
mu = 3.986004418e14
j2 = 1.08262668e-3
reference_radius = 6378137.0
pole = [0.0, 0.0, 1.0]
[initial]
position = [7.0e6, 0.0, 0.0]
quaternion = [1.0, 0.0, 0.0, 0.0]
momentum = [0.0, 7546.0, 0.0]
w = [0.1, -0.2, 0.3]
[integrator]
method = "lgvi"
order = 4
step = 0.1
duration = 1.0
[[forcing]]
kind = "torque"
frame = "inertial"
value = [0.001, 0.0, -0.002]
)";

const char* const two_bodies_toml = R"(
[[bodies]]
name = "primary"
position = [-0.1, 0.0, 0.0]
quaternion = [1.0, 0.0, 0.0, 0.0]
momentum = [0.0, -0.01, 0.0]
omega = [0.0, 0.0, 0.6]
[[bodies.ball]]
position = [0, 0, 0]
mass = 0.4
radius = 0.4
[[bodies.ball]]
position = [0.6, 0, 0]
mass = 0.1
radius = 0.3
[[bodies]]
name = "moon"
position = [1.5, 0.0, 0.0]
quaternion = [1.0, 0.0, 0.0, 0.0]
momentum = [0.0, 0.01, 0.0]
omega = [0.0, 0.0, 0.1]
[[bodies.ball]]
position = [0, 0, 0]
mass = 0.05
radius = 0.1
[interaction]
kind = "gravity"
G = 1.0
model = "balls"
[potential]
kind = "none"
[integrator]
method = "lgvi"
step = 0.01
duration = 1.0
)";

/// A result of `sc` with every statistic set, in numbers whose text shows how
/// they are written: thirds (17 digits), a tiny and a huge one, an integral
/// double, a negative zero and a NaN (null).
lgvi::app::SimulationResult fixed_result(const lgvi::app::Scenario& sc) {
  lgvi::app::SimulationResult r;
  r.completed = false;
  r.error = "stopped at step 7: \"why\" \\ on\ttwo\nlines";
  r.final_state = sc.initial_state;
  r.wall_seconds = 0.125;
  lgvi::app::RunStatistics& st = r.stats;
  st.observed = true;
  st.energy0 = -1.0 / 3.0;
  st.momentum0 = {0.1, -0.0, 2.0 / 3.0};
  st.max_energy_error = 1e-300;
  st.max_quat_error = 2.220446049250313e-16;
  st.max_momentum_error = 1.5e300;
  st.max_linear_momentum_error = 4.0;
  st.iterations_total = 70;
  st.steps_solved = 7;
  st.potential_evaluations = 36;
  st.iterations_max = 12;
  st.last_k = 7;
  st.last_t = 0.7000000000000001;
  st.rot_energy0 = 0.25;
  st.min_rot_energy = 0.2;
  st.max_rot_energy = 0.3;
  st.spin0 = {1.0, 2.0, 3.0};
  st.min_spin = 3.7;
  st.max_spin = 3.75;
  st.max_spin_change = 1e-9;
  st.work = std::nan("");
  // A contact episode (written for [[bodies]] scenarios checked for contact).
  st.contacts = {{0, 1, 5, 7, 0.05, 0.07, 1.0 / 3.0, 0.5}};
  st.contact_episodes = 1;
  return r;
}

TEST(Json, SummaryOfOneBodyIsByteIdenticalToTheOldWriter) {
  const lgvi::app::Scenario sc = parse_scenario(single_body_toml, "caf\xc3\xa9");
  EXPECT_EQ(lgvi::app::summary_json(sc, fixed_result(sc)), file_text(reference_dir / "summary_single_body.json"));
}

TEST(Json, SummaryOfTwoBodiesIsByteIdenticalToTheOldWriter) {
  const lgvi::app::Scenario sc = parse_scenario(two_bodies_toml, "two-bodies");
  EXPECT_EQ(lgvi::app::summary_json(sc, fixed_result(sc)), file_text(reference_dir / "summary_two_bodies.json"));
}

TEST(Json, LayoutByMemberName) {
  Json doc;
  doc["x"] = 0.1;
  doc["n"] = std::int64_t{-3};
  doc["nan"] = std::nan("");
  doc["empty"] = Json::object();
  doc["inner"] = {{"ok", true}, {"m", Json::array({Json::array({1.0, 0.0}), Json::array()})}};
  doc["short"] = {{"a", 1.5}, {"b", nullptr}};
  doc["list"] = Json::array({{{"k", 1.0}}, {{"k", 2.0}}});
  doc["empty_list"] = Json::array();
  EXPECT_EQ(json_text(doc, {{"short"}, {"list", "empty_list"}}),
            "{\n"
            "  \"x\": 0.10000000000000001,\n"
            "  \"n\": -3,\n"
            "  \"nan\": null,\n"
            "  \"empty\": {\n"
            "  },\n"
            "  \"inner\": {\n"
            "    \"ok\": true,\n"
            "    \"m\": [[1, 0], []]\n"
            "  },\n"
            "  \"short\": {\"a\": 1.5, \"b\": null},\n"
            "  \"list\": [\n"
            "    {\"k\": 1},\n"
            "    {\"k\": 2}\n"
            "  ],\n"
            "  \"empty_list\": []\n"
            "}");
}

TEST(Json, GeneratedArraysAreWrittenAsTheArraysTheyStandFor) {
  // An array made element by element as it is written (the summary's lists
  // of bodies) must be the text of the same array held whole, one element a
  // line; nested (inside "setup") and empty too. The placeholders are found
  // by address, so a member of another name stays as it is.
  auto element = [](std::size_t i) { return Json{{"name", "b" + std::to_string(i)}, {"x", 0.1 * static_cast<double>(i)}}; };
  Json whole, lazy;
  for (Json* doc : {&whole, &lazy}) {
    (*doc)["n"] = 3;
    (*doc)["setup"] = {{"bodies", Json::array()}, {"kind", "gas"}};
    (*doc)["final_bodies"] = Json::array();
    (*doc)["none"] = Json::array();
  }
  for (std::size_t i = 0; i < 3; ++i) {
    whole["final_bodies"].push_back(element(i));
    whole["setup"]["bodies"].push_back(element(i + 10));
  }
  JsonLayout layout{{}, {"bodies", "final_bodies", "none"}};
  const std::string expected = json_text(whole, layout);
  layout.generated.push_back({&lazy["final_bodies"], 3, element});
  layout.generated.push_back({&lazy["setup"]["bodies"], 3, [&](std::size_t i) { return element(i + 10); }});
  layout.generated.push_back({&lazy["none"], 0, element});
  EXPECT_EQ(json_text(lazy, layout), expected);
  EXPECT_NE(expected.find("\"final_bodies\": [\n    {\"name\": \"b0\", \"x\": 0},"), std::string::npos);
}

TEST(Json, TextWrittenToAFileAsItIsMadeIsTheSameText) {
  // write_json empties its buffer into the file between a generated array's
  // elements once it holds 64 kB: 5000 elements of ~30 bytes cross that
  // boundary about twice, and the file must still be json_text's bytes.
  // And the text is in the file before the document ends: at element 4000 (of 10000) the file holds some of it.
  std::FILE* file = nullptr;
  long written_by_element_4000 = -1;
  auto element = [&](std::size_t i) {
    if (i == 4000 && file != nullptr) written_by_element_4000 = std::ftell(file);
    return Json{{"name", "body" + std::to_string(i)}, {"x", 0.1 * static_cast<double>(i)}};
  };
  Json doc;
  doc["n"] = 5000;
  doc["setup"] = {{"bodies", Json::array()}};
  doc["final_bodies"] = Json::array();
  JsonLayout layout{{}, {}};
  layout.generated.push_back({&doc["final_bodies"], 5000, element});
  layout.generated.push_back({&doc["setup"]["bodies"], 5000, [&](std::size_t i) { return element(i + 7); }});
  const fs::path dir = fresh_dir("streamed");
  const std::string path = (dir / "doc.json").string();
  lgvi::app::write_file_atomically(path, [&](std::FILE* f) {
    file = f;
    const bool ok = lgvi::app::write_json(f, doc, layout);
    file = nullptr;
    return ok;
  });
  EXPECT_GT(written_by_element_4000, 0);
  const std::string expected = json_text(doc, layout);
  ASSERT_GT(expected.size(), std::size_t{2} << 16);
  EXPECT_EQ(file_text(path), expected);
  // The summary written to its file as it is made, and held whole (npz, HDF5, Python).
  const lgvi::app::Scenario sc = parse_scenario(two_bodies_toml, "two-bodies");
  lgvi::app::write_summary_file((dir / "summary.json").string(), sc, fixed_result(sc));
  EXPECT_EQ(file_text(dir / "summary.json"), lgvi::app::summary_json(sc, fixed_result(sc)));
  fs::remove_all(dir);
}

TEST(Json, UnicodeEscapesReadAsUtf8) {
  // e with acute accent (U+00E9), and a rocket (U+1F680) as a surrogate pair.
  const Json doc = parse_json_file_text(R"({"name": "caf\u00e9 \ud83d\ude80"})", "name.json");
  EXPECT_EQ(doc["name"].get<std::string>(), "caf\xc3\xa9 \xf0\x9f\x9a\x80");
}

TEST(Json, ShowReadsUnicodeEscapes) {
  const lgvi::app::Scenario sc = parse_scenario(two_bodies_toml, "placeholder");
  std::string text = lgvi::app::summary_json(sc, fixed_result(sc));
  const std::string plain = "\"scenario\": \"placeholder\"";
  ASSERT_NE(text.find(plain), std::string::npos);
  // The name as another JSON writer (Python's json.dumps) would write it.
  text.replace(text.find(plain), plain.size(), "\"scenario\": \"caf\\u00e9 \\ud83d\\ude80\"");
  const fs::path dir = fresh_dir("unicode");
  std::ofstream(dir / "summary.json", std::ios::binary) << text;
  std::ostringstream out;
  lgvi::app::show_run(dir.string(), out);
  EXPECT_NE(out.str().find("run                    caf\xc3\xa9 \xf0\x9f\x9a\x80  (NOT completed)\n"), std::string::npos)
      << out.str();
  fs::remove_all(dir);
}

TEST(Json, MalformedFileIsOneErrorNamingTheFileAndLine) {
  const fs::path dir = fresh_dir("malformed");
  const std::string file = (dir / "summary.json").string();
  std::ofstream(file, std::ios::binary) << "{\n  \"scenario\": \"x\",\n  \"steps\": 12\n  \"completed\": true\n}\n";
  std::ostringstream out;
  try {
    lgvi::app::show_run(dir.string(), out);
    ADD_FAILURE() << "no error";
  } catch (const InvalidInput& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind(file + ": not valid JSON (parse error at line 4, column 13: ", 0), 0u) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << "one line: " << what;
  }
  fs::remove_all(dir);
}

}  // namespace

}  // namespace test_json
