// `lgvi ensemble` (ensemble.hpp): the sweep file, the members' scenarios and
// draws, one member's run and row, the journal, and the threads runner.
#include "app/ensemble.hpp"

#include "io/formats/registry.hpp"
#include "io/json_io.hpp"

#include "io/output.hpp"
#include "app/run.hpp"
#include "app/simulation.hpp"
#include "app/summary.hpp"
#include "io/toml_reader.hpp"
#include "io/toml_writer.hpp"
#include "io/trajectory_sink.hpp"

#include <lgvi/counter_random.hpp>
#include <lgvi/error.hpp>

#include <fmt/format.h>
#include <fmt/printf.h>
#include <toml++/toml.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <iostream>
#include <map>
#include <mutex>
#include <numbers>
#include <optional>
#include <sstream>
#include <thread>
#include <unistd.h>

namespace lgvi::app {

namespace fs = std::filesystem;

namespace {

// Draws: (seed, member, vary, component) -> a number (lgvi/counter_random.hpp), so that they do not
// depend on the order in which members run or on where.
using counter_random::normal01;
using counter_random::uniform01;

/// Appends ",v" to a CSV row (fmt::format_to: no temporary strings).
void append_number(std::string& row, double v) { fmt::format_to(std::back_inserter(row), ",{:.17g}", v); }

/// The fields of one CSV line (RFC 4180 quoting, as csv_field writes it).
std::vector<std::string> csv_fields(const std::string& line) {
  std::vector<std::string> out(1);
  bool quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        out.back() += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        out.back() += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      out.emplace_back();
    } else {
      out.back() += c;
    }
  }
  return out;
}

/// A CSV field: quoted (with quotes doubled) when it holds a comma, quote or line break.
std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string out = "\"";
  for (char c : s) {
    if (c == '"') out += '"';
    out += c == '\n' || c == '\r' ? ' ' : c;
  }
  return out + "\"";
}

// ---------------------------------------------------------------------------
// The sweep file

/// A key's parts between its dots; an entry of an array of tables may also be written NAME[I] before the
/// last part ("body.wheel[0].inertia", as the reader's messages name it, is "body.wheel.0.inertia"), but
/// for a [[bodies]] entry's name, which may hold brackets ("bodies.sat[1].omega"). In the last part,
/// brackets index an array's elements (Leaf).
std::vector<std::string> split_key(const std::string& key) {
  std::vector<std::string> parts;
  std::stringstream ss(key);
  for (std::string p; std::getline(ss, p, '.');) parts.push_back(p);
  std::vector<std::string> split;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const std::string& p = parts[i];
    const std::size_t open = p.find('[');
    const bool body_name = i == 1 && parts[0] == "bodies";
    if (!body_name && i + 1 < parts.size() && open != std::string::npos && open > 0 && p.back() == ']' &&
        p.find_first_of("[]", open + 1) == p.size() - 1) {
      split.push_back(p.substr(0, open));
      split.push_back(p.substr(open + 1, p.size() - open - 2));
    } else {
      split.push_back(p);
    }
  }
  return split;
}

/// The table holding the key's last part, in a scenario's document: tables by
/// name ("initial", "integrator", ...), a [[bodies]] entry by its name
/// ("bodies.primary.omega"; unnamed entries are body0, body1, ...), an entry
/// of another array of tables by its index from 0 ("forcing.0.k_p"). nullptr
/// if there is none; `leaf` gets the last part.
toml::table* key_table(toml::table& root, const std::vector<std::string>& parts, std::string& leaf) {
  if (parts.size() < 2) return nullptr;
  toml::table* t = &root;
  std::size_t i = 0;
  if (parts[0] == "bodies") {
    toml::array* bodies = root["bodies"].as_array();
    if (!bodies || parts.size() < 3) return nullptr;
    t = nullptr;
    for (std::size_t a = 0; a < bodies->size(); ++a) {
      toml::table* b = bodies->get(a)->as_table();
      if (!b) continue;
      const std::string name = (*b)["name"].value_or(std::string("body") + std::to_string(a));
      if (name == parts[1]) t = b;
    }
    if (!t) return nullptr;
    i = 2;
  }
  for (; i + 1 < parts.size(); ++i) {
    if (toml::array* entries = (*t)[parts[i]].as_array()) {  // [[forcing]]: the next part is an index
      const std::string& index = parts[i + 1];
      // One spelling per index (0, 1, ..., no leading zero); NAME[I] and NAME.I are the same entry, which
      // the plan refuses to vary twice (parse_ensemble_with).
      if (i + 2 >= parts.size() || index.empty() || index.size() > 6 || (index.size() > 1 && index[0] == '0') ||
          index.find_first_not_of("0123456789") != std::string::npos)
        return nullptr;
      const std::size_t a = std::stoul(index);
      t = a < entries->size() ? entries->get(a)->as_table() : nullptr;
      ++i;
    } else {
      t = (*t)[parts[i]].as_table();
    }
    if (!t) return nullptr;
  }
  leaf = parts.back();
  return t;
}

VarySpec read_vary(const TomlReader& r, const toml::table& v, std::size_t index, bool& random) {
  const std::string p = "vary[" + std::to_string(index) + "]";
  r.only_keys(v, p, {"key", "normal", "uniform", "values", "rotation", "attitude_error_deg"});
  VarySpec s;
  const auto key = v["key"].value<std::string>();
  if (!key || key->empty()) r.fail(p + ".key", "missing: the dotted scenario key to vary, e.g. \"initial.omega\"");
  s.key = *key;
  const int given = static_cast<int>(v.contains("normal")) + static_cast<int>(v.contains("uniform")) +
                    static_cast<int>(v.contains("values")) + static_cast<int>(v.contains("rotation")) +
                    static_cast<int>(v.contains("attitude_error_deg"));
  if (given != 1)
    r.fail(p, "give exactly one of normal = {mean, std}, uniform = {low, high}, values = [...] (a grid), "
              "rotation = \"uniform\" (random attitudes) or attitude_error_deg = SIGMA (attitude errors)");
  auto pair = [&](const char* what, const char* first, const char* second) {
    const toml::table* t = v[what].as_table();
    const std::string q = p + "." + what;
    if (!t) r.fail(q, std::string("must be a table {") + first + " = ..., " + second + " = ...}");
    r.only_keys(*t, q, {first, second});
    if (!t->contains(first) || !t->contains(second)) r.fail(q, std::string("needs ") + first + " and " + second);
    bool s1 = false, s2 = false;
    s.a = r.numbers(*t->get(first), q + "." + first, s1);
    s.b = r.numbers(*t->get(second), q + "." + second, s2);
    if (s1 != s2 || s.a.size() != s.b.size())
      r.fail(q, std::string(first) + " and " + second + " must both be numbers or arrays of the same length");
    s.scalar = s1;
  };
  if (v.contains("normal")) {
    s.kind = VarySpec::Kind::Normal;
    pair("normal", "mean", "std");
    for (std::size_t c = 0; c < s.b.size(); ++c)
      if (s.b[c] < 0.0) r.fail(p + ".normal.std", "must be >= 0");
    random = true;
  } else if (v.contains("uniform")) {
    s.kind = VarySpec::Kind::Uniform;
    pair("uniform", "low", "high");
    for (std::size_t c = 0; c < s.a.size(); ++c)
      if (!(s.a[c] <= s.b[c])) r.fail(p + ".uniform", "needs low <= high in every component");
    random = true;
  } else if (v.contains("rotation")) {
    if (v["rotation"].value<std::string>() != "uniform")
      r.fail(p + ".rotation", "must be \"uniform\" (attitudes drawn uniformly over SO(3))");
    s.kind = VarySpec::Kind::RandomRotation;
    random = true;
  } else if (v.contains("attitude_error_deg")) {
    const double sigma = r.number(v, p, "attitude_error_deg");
    if (!(sigma >= 0.0 && sigma <= 180.0))
      r.fail(p + ".attitude_error_deg", "must be in [0, 180]: the standard deviation of the error angle, in degrees");
    s.kind = VarySpec::Kind::AttitudeError;
    s.a = {sigma};
    random = true;
  } else {
    s.kind = VarySpec::Kind::Values;
    const toml::array* a = v["values"].as_array();
    if (!a || a->empty()) r.fail(p + ".values", "must be a non-empty array of values (numbers, or arrays of numbers)");
    s.integer = true;
    for (std::size_t i = 0; i < a->size(); ++i) {
      const toml::node& n = *a->get(i);
      if (const toml::array* inner = n.as_array()) {
        for (std::size_t k = 0; k < inner->size(); ++k) s.integer = s.integer && inner->get(k)->is_integer();
      } else {
        s.integer = s.integer && n.is_integer();
      }
      bool scalar = false;
      s.values.push_back(r.numbers(*a->get(i), p + ".values[" + std::to_string(i) + "]", scalar));
      if (i == 0) s.scalar = scalar;
      if (scalar != s.scalar || s.values[i].size() != s.values[0].size())
        r.fail(p + ".values", "every value must have the shape of the first");
    }
  }
  return s;
}

/// Member i's value of vary v (components in order).
std::vector<double> draw(const VarySpec& s, std::uint64_t seed, std::int64_t member, std::size_t v,
                         std::size_t grid_index) {
  std::vector<double> out;
  switch (s.kind) {
    case VarySpec::Kind::Normal:
      for (std::size_t c = 0; c < s.a.size(); ++c) out.push_back(s.a[c] + s.b[c] * normal01(seed, member, v, c));
      break;
    case VarySpec::Kind::Uniform:
      for (std::size_t c = 0; c < s.a.size(); ++c)
        out.push_back(s.a[c] + (s.b[c] - s.a[c]) * uniform01(seed, member, v, c, 0));
      break;
    case VarySpec::Kind::RandomRotation: {
      // Shoemake (Graphics Gems III): uniform on S^3, hence on SO(3); scalar first.
      const double u1 = uniform01(seed, member, v, 0, 0), u2 = uniform01(seed, member, v, 1, 0),
                   u3 = uniform01(seed, member, v, 2, 0);
      const double a = std::sqrt(1.0 - u1), b = std::sqrt(u1), t2 = 2.0 * std::numbers::pi * u2,
                   t3 = 2.0 * std::numbers::pi * u3;
      out = {b * std::cos(t3), a * std::sin(t2), a * std::cos(t2), b * std::sin(t3)};
      break;
    }
    case VarySpec::Kind::AttitudeError: {
      // The axis uniform on the unit sphere (z = cos(polar angle) uniform in [-1, 1], the azimuth
      // uniform), the angle normal with the given standard deviation (Box-Muller on component 2's
      // streams); a negative angle is the positive one about the opposite axis.
      const double z = 2.0 * uniform01(seed, member, v, 0, 0) - 1.0;
      const double phi = 2.0 * std::numbers::pi * uniform01(seed, member, v, 1, 0);
      const double rho = std::sqrt(std::max(0.0, 1.0 - z * z));
      const double angle = s.a[0] * normal01(seed, member, v, 2);
      const double sign = angle < 0.0 ? -1.0 : 1.0;
      out = {std::abs(angle), sign * rho * std::cos(phi), sign * rho * std::sin(phi), sign * z};
      break;
    }
    case VarySpec::Kind::Values: out = s.values[grid_index]; break;
  }
  return out;
}

/// The rotation an AttitudeError's values (angle in degrees, unit axis) stand for, scalar first.
std::array<double, 4> error_quaternion(const std::vector<double>& value) {
  const double half = 0.5 * value[0] * std::numbers::pi / 180.0, s = std::sin(half);
  return {std::cos(half), s * value[1], s * value[2], s * value[3]};
}

/// Hamilton's product a b of quaternions, scalar first.
std::array<double, 4> quaternion_product(const std::array<double, 4>& a, const std::array<double, 4>& b) {
  return {a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3], a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
          a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1], a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]};
}

/// A key's last part: a name and the indices after it ("inertia[0][2]": an element of an array of arrays).
struct Leaf {
  std::string name;
  std::vector<std::size_t> indices;
};

/// Splits "name[i][j]..." (indices of at most 6 digits, no leading zero); nullopt if malformed.
std::optional<Leaf> parse_leaf(const std::string& leaf) {
  Leaf out;
  const std::size_t open = leaf.find('[');
  out.name = leaf.substr(0, open);
  if (out.name.empty()) return std::nullopt;
  for (std::size_t at = open; at != std::string::npos;) {
    const std::size_t close = leaf.find(']', at);
    if (close == std::string::npos || leaf[at] != '[') return std::nullopt;
    const std::string index = leaf.substr(at + 1, close - at - 1);
    if (index.empty() || index.size() > 6 || (index.size() > 1 && index[0] == '0') ||
        index.find_first_not_of("0123456789") != std::string::npos)
      return std::nullopt;
    out.indices.push_back(std::stoul(index));
    at = close + 1 < leaf.size() ? close + 1 : std::string::npos;
  }
  return out;
}

/// The node a leaf names in table t (an array's element for indices); nullptr if there is none. With
/// indices, `parent` gets the array holding it.
toml::node* leaf_node(toml::table& t, const Leaf& leaf, toml::array** parent = nullptr) {
  toml::node* n = t.get(leaf.name);
  for (std::size_t i : leaf.indices) {
    toml::array* a = n ? n->as_array() : nullptr;
    if (!a || i >= a->size()) return nullptr;
    if (parent) *parent = a;
    n = a->get(i);
  }
  return n;
}

/// Writes value into the document at the vary's key.
void write_value(toml::table& root, const VarySpec& s, const std::vector<double>& value) {
  std::string leaf_text;
  toml::table* t = key_table(root, split_key(s.key), leaf_text);
  const std::optional<Leaf> leaf = parse_leaf(leaf_text);
  if (!t || !leaf) throw std::logic_error("key checked before: " + s.key);
  if (s.kind == VarySpec::Kind::AttitudeError) {
    // Composed with the base's quaternion (q0 (x) dq: an error in body axes), or, where the base sets the
    // attitude by initial.attitude, given to it as its error.
    const std::array<double, 4> dq = error_quaternion(value);
    toml::array q;
    if (const toml::array* base = leaf_node(*t, *leaf) ? leaf_node(*t, *leaf)->as_array() : nullptr) {
      std::array<double, 4> q0{};
      for (std::size_t c = 0; c < 4; ++c) q0[c] = base->get(c)->value<double>().value();
      for (double x : quaternion_product(q0, dq)) q.push_back(x);
      t->insert_or_assign(leaf->name, std::move(q));
    } else {
      for (double x : dq) q.push_back(x);
      t->get_as<toml::table>("attitude")->insert_or_assign("error", std::move(q));
    }
    return;
  }
  if (!leaf->indices.empty()) {  // an element of an array (checked to exist): a number
    toml::array* parent = nullptr;
    leaf_node(*t, *leaf, &parent);
    const auto at = parent->cbegin() + static_cast<std::ptrdiff_t>(leaf->indices.back());
    if (s.integer) {
      parent->replace(at, static_cast<std::int64_t>(value[0]));
    } else {
      parent->replace(at, value[0]);
    }
    return;
  }
  const std::string& name = leaf->name;
  // Integers stay integers (exact: a grid's integers are read as doubles
  // below 2^53 and converted back).
  if (s.scalar) {
    if (s.integer) {
      t->insert_or_assign(name, static_cast<std::int64_t>(value[0]));
    } else {
      t->insert_or_assign(name, value[0]);
    }
  } else {
    toml::array a;
    for (double x : value) {
      if (s.integer) {
        a.push_back(static_cast<std::int64_t>(x));
      } else {
        a.push_back(x);
      }
    }
    t->insert_or_assign(name, std::move(a));
  }
}

std::string read_text(const fs::path& path, const std::string& what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InvalidInput(path.string() + ": cannot read the " + what);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// The final-state columns of a scenario's bodies.
std::vector<std::string> state_columns(const Scenario& sc) {
  static const char* names[] = {"x", "y", "z", "qw", "qx", "qy", "qz", "px", "py", "pz", "wx", "wy", "wz"};
  std::vector<std::string> cols;
  for (std::size_t a = 0; a < sc.bodies(); ++a) {
    const std::string body = sc.many_body_form ? sc.system.name(a) + "." : std::string();
    for (const char* n : names) cols.push_back(body + n);
  }
  return cols;
}

/// Rows go nowhere: a member's diagnostics come from the run's statistics.
class DiscardSink final : public TrajectorySink {
 public:
  void row(const double*) override {}
  SinkPosition sync() override { return {}; }
  void close(const std::string&, const std::string&) override {}
};

/// How many output frames a fixed-step scenario writes: every output.every steps from 0, and the last.
std::int64_t pointing_frame_count(const Scenario& sc) {
  const std::int64_t n = sc.integrator.steps, every = sc.output_every;
  return n / every + 1 + (n % every != 0 ? 1 : 0);
}

/// The times of those frames, k h.
std::vector<double> pointing_frames(const Scenario& sc) {
  const std::int64_t n = sc.integrator.steps, every = sc.output_every;
  std::vector<double> t;
  t.reserve(static_cast<std::size_t>(pointing_frame_count(sc)));
  for (std::int64_t k = 0; k <= n; k += every) t.push_back(static_cast<double>(k) * sc.integrator.step);
  if (n % every != 0) t.push_back(static_cast<double>(n) * sc.integrator.step);
  return t;
}

/// Whether member 0's scenario can give the plan's metrics; the frames of its pointing-error curves.
void check_metrics(const TomlReader& r, EnsemblePlan& plan, const Scenario& sc) {
  for (const std::string& name : plan.metrics.names) {
    if (name == "pointing_error_deg" || name == "settling_time") {
      if (sc.many_body_form || sc.attitude_targets.size() != 1)
        r.fail("ensemble.metrics", "\"" + name + "\" is measured from the target of the base scenario's attitude "
                                   "controller: it needs a [body] with one [[forcing]] kind = \"attitude-control\"");
    } else if (sc.many_body_form || !sc.body().has_wheels()) {
      r.fail("ensemble.metrics", "\"" + name + "\" measures reaction wheels: the base scenario's [body] needs "
                                 "[[body.wheel]] tables");
    }
  }
  if (!plan.metrics.pointing()) return;
  if (sc.integrator.adaptive())
    r.fail("ensemble.metrics", "the pointing-error curves need a fixed step; the base scenario has "
                               "integrator.time_transform");
  if (const std::int64_t frames = pointing_frame_count(sc); frames > 10001)
    r.fail("ensemble.metrics", fmt::format("the pointing-error curves would hold {} frames per member (at most "
                                           "10001): give the base scenario a larger [output] every",
                                           frames));
  plan.series_times = pointing_frames(sc);
}

}  // namespace

bool MemberMetrics::pointing() const {
  return std::find(names.begin(), names.end(), "pointing_error_deg") != names.end() ||
         std::find(names.begin(), names.end(), "settling_time") != names.end();
}

std::pair<std::string, std::string> EnsemblePlan::split_row(const std::string& row) const {
  if (series_times.empty()) return {row, {}};
  const std::size_t fields = header_fields;
  bool quoted = false;
  std::size_t commas = 0;
  for (std::size_t i = 0; i < row.size(); ++i) {
    if (row[i] == '"') {
      quoted = !quoted;  // a doubled quote inside a field toggles twice
    } else if (row[i] == ',' && !quoted && ++commas == fields) {
      return {row.substr(0, i), row.substr(i + 1)};
    }
  }
  return {row, {}};
}

std::size_t VarySpec::components() const {
  if (kind == Kind::RandomRotation || kind == Kind::AttitudeError) return 4;
  if (kind == Kind::Values) return values.front().size();
  return a.size();
}

std::string EnsemblePlan::member_toml(std::int64_t i) const {
  toml::table doc = toml::parse(scenario_text);
  std::size_t column = 0;
  for (const VarySpec& v : vary) {
    const std::vector<double> value(varied[static_cast<std::size_t>(i)].begin() + static_cast<std::ptrdiff_t>(column),
                                    varied[static_cast<std::size_t>(i)].begin() +
                                        static_cast<std::ptrdiff_t>(column + v.components()));
    write_value(doc, v, value);
    column += v.components();
  }
  if (!shared_sensor_noise) {
    // Each member's own noise: seed = a function of (the ensemble's seed, the base sensor's seed, the
    // member's index), 63 bits, under a tag of its own (not one of the draws' keys). A base seed that is
    // not an integer >= 0 stays as it is, for the member's reader to refuse.
    constexpr std::uint64_t sensor_tag = 0x53454e534f52ULL;  // "SENSOR"
    if (toml::array* sensors = doc["sensor"].as_array()) {
      for (std::size_t s = 0; s < sensors->size(); ++s) {
        toml::table* t = sensors->get(s)->as_table();
        if (!t) continue;  // the member's reader names it
        const toml::node* given = t->get("seed");
        if (given && !(given->is_integer() && given->value<std::int64_t>().value() >= 0)) continue;
        const auto base = static_cast<std::uint64_t>(given ? given->value<std::int64_t>().value() : 0);
        using counter_random::mix;
        const std::uint64_t drawn = mix(mix(seed ^ sensor_tag) ^ mix(base) ^ static_cast<std::uint64_t>(i)) >> 1;
        t->insert_or_assign("seed", static_cast<std::int64_t>(drawn));
      }
    }
  }
  return write_toml(doc);
}

/// With check_members false, only member 0's scenario is read (for the
/// columns and the format): for a plan whose members were checked already.
static EnsemblePlan parse_ensemble_with(const std::string& sweep_text, const std::string& name, const std::string& base_dir,
                                 const std::string* scenario_text, bool check_members = true) {
  const TomlReader r(name);
  toml::table root;
  try {
    root = toml::parse(sweep_text, name);
  } catch (const toml::parse_error& e) {
    r.fail("", std::string(e.description()) + " (line " + std::to_string(e.source().begin.line) + ")");
  }
  r.only_keys(root, "", {"ensemble", "vary"});
  const toml::table* ens = root["ensemble"].as_table();
  if (!ens) r.fail("ensemble", "missing table [ensemble] (scenario = \"base.toml\", members, seed)");
  r.only_keys(*ens, "ensemble",
              {"scenario", "members", "seed", "trajectories", "metrics", "settle_band_deg", "sensor_noise"});
  EnsemblePlan plan;
  plan.name = name;
  plan.sweep_text = sweep_text;
  const auto scenario_path = (*ens)["scenario"].value<std::string>();
  if (!scenario_path) r.fail("ensemble.scenario", "missing: the base scenario file, relative to this file");
  const fs::path path = fs::path(base_dir) / *scenario_path;
  plan.scenario_name = path.stem().string();
  plan.scenario_text = scenario_text ? *scenario_text : read_text(path, "base scenario (ensemble.scenario)");
  if (!scenario_text) {
    // An [import]'s data file is relative to the base scenario: the members (parsed by the scenario's stem
    // alone) and the ensemble's copy take the base's run copy, with the file's absolute path and checksum.
    const Scenario base = parse_scenario(plan.scenario_text, path.string());
    if (base.imported) plan.scenario_text = base.source_text;
  }
  if (ens->contains("trajectories")) {
    const auto t = (*ens)["trajectories"].value<std::string>();
    if (t != "none" && t != "all") r.fail("ensemble.trajectories", "must be \"none\" (default) or \"all\"");
    plan.keep_trajectories = *t == "all";
  }
  if (const toml::node* m = ens->get("metrics")) {
    static const std::vector<std::string> known{"pointing_error_deg", "max_wheel_torque", "max_wheel_speed",
                                                "settling_time",      "saturation_time",  "control_effort"};
    std::string list;
    for (const std::string& k : known) list += (list.empty() ? "\"" : ", \"") + k + "\"";
    const toml::array* a = m->as_array();
    if (!a || a->empty()) r.fail("ensemble.metrics", "must be a non-empty array of names, from " + list);
    for (std::size_t i = 0; i < a->size(); ++i) {
      const std::string key = "ensemble.metrics[" + std::to_string(i) + "]";
      const auto name = a->get(i)->value<std::string>();
      if (!name || std::find(known.begin(), known.end(), *name) == known.end())
        r.fail(key, "must be one of " + list);
      if (std::find(plan.metrics.names.begin(), plan.metrics.names.end(), *name) != plan.metrics.names.end())
        r.fail(key, "\"" + *name + "\" is given twice");
      plan.metrics.names.push_back(*name);
    }
  }
  if (ens->contains("sensor_noise"))
    plan.shared_sensor_noise = r.string(*ens, "ensemble", "sensor_noise", {"per-member", "shared"}) == "shared";
  if (ens->contains("settle_band_deg")) {
    plan.metrics.settle_band_deg = r.number(*ens, "ensemble", "settle_band_deg");
    if (!(plan.metrics.settle_band_deg > 0.0 && plan.metrics.settle_band_deg < 180.0))
      r.fail("ensemble.settle_band_deg", "must be in (0, 180): the pointing error (deg) within which a member has settled");
  }
  const auto& metric_names = plan.metrics.names;
  if (std::find(metric_names.begin(), metric_names.end(), "settling_time") != metric_names.end() &&
      std::isnan(plan.metrics.settle_band_deg))
    r.fail("ensemble.settle_band_deg", "missing: settling_time needs the band (deg) it measures to, e.g. "
                                       "settle_band_deg = 0.1");
  const toml::array* varies = root["vary"].as_array();
  if (!varies || varies->empty()) r.fail("vary", "missing: at least one [[vary]] table (key and its values)");
  bool random = false, grid = false;
  for (std::size_t i = 0; i < varies->size(); ++i) {
    const toml::table* v = varies->get(i)->as_table();
    if (!v) r.fail("vary", "must be [[vary]] tables");
    bool is_random = false;
    plan.vary.push_back(read_vary(r, *v, i, is_random));
    (is_random ? random : grid) = true;
  }
  if (random && grid)
    r.fail("vary", "give either random draws (normal, uniform, rotation) with ensemble.members, or grids "
                   "(values) whose product is the ensemble, not both");
  // The keys exist in the base scenario (or their table does) with the drawn shape.
  toml::table base;
  try {
    base = toml::parse(plan.scenario_text, plan.scenario_name);
  } catch (const toml::parse_error& e) {
    r.fail("ensemble.scenario", std::string("the base scenario does not parse: ") + std::string(e.description()));
  }
  for (std::size_t i = 0; i < plan.vary.size(); ++i) {
    VarySpec& v = plan.vary[i];
    const std::string p = "vary[" + std::to_string(i) + "].key";
    for (std::size_t j = 0; j < i; ++j)
      if (split_key(plan.vary[j].key) == split_key(v.key))
        r.fail(p, "\"" + v.key + "\" varies the same value as vary[" + std::to_string(j) + "] (\"" +
                      plan.vary[j].key + "\"); give each key once");
    std::string leaf_text;
    toml::table* t = key_table(base, split_key(v.key), leaf_text);
    if (!t)
      r.fail(p, "\"" + v.key + "\" names no table of the base scenario (e.g. \"initial.omega\", \"integrator.step\", "
                "\"bodies.NAME.omega\", \"forcing.0.k_p\" or \"forcing[0].k_p\" for the first [[forcing]], "
                "\"body.wheel[0].inertia\", \"body.inertia[0][0]\" for an element)");
    const std::optional<Leaf> leaf = parse_leaf(leaf_text);
    if (!leaf)
      r.fail(p, "\"" + v.key + "\": its last part must be a name, or a name and indices from 0 such as inertia[0][2]");
    if (!leaf->indices.empty() && !leaf_node(*t, *leaf))
      r.fail(p, "\"" + v.key + "\" names no element of the base scenario (an element is varied where the base gives "
                "its array, e.g. body.inertia[0][0] for inertia = [[...], [...], [...]])");
    if (!leaf->indices.empty() && v.kind == VarySpec::Kind::AttitudeError)
      r.fail(p, "attitude_error_deg varies a quaternion key such as \"initial.quaternion\", not an element");
    if (v.kind == VarySpec::Kind::AttitudeError && !leaf_node(*t, *leaf)) {
      const toml::table* attitude = t->get_as<toml::table>("attitude");
      if (leaf->name != "quaternion" || !attitude)
        r.fail(p, "attitude_error_deg draws an error of the base's attitude: the base must give \"" + v.key +
                      "\" (a quaternion), or set it by initial.attitude");
      if (attitude->contains("error"))
        r.fail(p, "the base's initial.attitude has an error already; the draws would replace it: remove it");
    }
    if (v.kind == VarySpec::Kind::RandomRotation || v.kind == VarySpec::Kind::AttitudeError) v.scalar = false;
    if (const toml::node* n = leaf_node(*t, *leaf)) {
      bool scalar = false;
      const std::vector<double> now = r.numbers(*n, p + " (its value in the base scenario)", scalar);
      if (scalar != v.scalar || now.size() != v.components())
        r.fail(p, "\"" + v.key + "\" holds " + (scalar ? "a number" : std::to_string(now.size()) + " numbers") +
                      " in the base scenario; the values given have another shape");
    }
    const std::size_t c = v.components();
    if (v.kind == VarySpec::Kind::AttitudeError) {
      plan.varied_columns.push_back(v.key + ".error_deg");
      for (std::size_t k = 0; k < 3; ++k) plan.varied_columns.push_back(v.key + ".error_axis[" + std::to_string(k) + "]");
      continue;
    }
    for (std::size_t k = 0; k < c; ++k)
      plan.varied_columns.push_back(v.scalar ? v.key : v.key + "[" + std::to_string(k) + "]");
  }
  // Members: random draws, or the product of the grids (the last varies fastest).
  std::int64_t members = 1;
  if (random) {
    if (!ens->contains("members")) r.fail("ensemble.members", "missing: how many members to draw");
    const auto m = (*ens)["members"].value<std::int64_t>();
    if (!m || *m < 1 || *m > 100000000) r.fail("ensemble.members", "must be an integer in [1, 1e8]");
    members = *m;
    if (!ens->contains("seed")) r.fail("ensemble.seed", "missing: the seed of the draws (an integer >= 0)");
    const auto s = (*ens)["seed"].value<std::int64_t>();
    if (!s || *s < 0) r.fail("ensemble.seed", "must be an integer >= 0");
    plan.seed = static_cast<std::uint64_t>(*s);
  } else {
    if (ens->contains("members"))
      r.fail("ensemble.members", "only with random draws; a grid ensemble has the product of its grids' sizes");
    for (const VarySpec& v : plan.vary) members *= static_cast<std::int64_t>(v.values.size());
    if (members > 100000000) r.fail("vary", "the grids' product exceeds 1e8 members");
  }
  for (std::int64_t m = 0; m < members; ++m) {
    std::vector<double> row;
    std::int64_t rest = m;
    std::vector<std::size_t> grid_index(plan.vary.size(), 0);
    for (std::size_t v = plan.vary.size(); v-- > 0;) {
      if (plan.vary[v].kind != VarySpec::Kind::Values) continue;
      const auto n = static_cast<std::int64_t>(plan.vary[v].values.size());
      grid_index[v] = static_cast<std::size_t>(rest % n);
      rest /= n;
    }
    for (std::size_t v = 0; v < plan.vary.size(); ++v) {
      const std::vector<double> value = draw(plan.vary[v], plan.seed, m, v, grid_index[v]);
      row.insert(row.end(), value.begin(), value.end());
    }
    plan.varied.push_back(std::move(row));
  }
  // Every member's scenario, read as `lgvi run` reads it, before any runs.
  std::size_t bodies = 0;
  bool adaptive = false;  // member 0's time_transform (not a number: every member has the same)
  std::vector<std::string> state_cols;
  for (std::int64_t m = 0; m < (check_members ? members : 1); ++m) {
    Scenario sc;
    try {
      sc = parse_scenario(plan.member_toml(m), plan.scenario_name);
    } catch (const InvalidInput& e) {
      std::string values;
      for (std::size_t c = 0; c < plan.varied_columns.size(); ++c)
        fmt::format_to(std::back_inserter(values), "{}{} = {:.6g}", c ? ", " : "", plan.varied_columns[c],
                       plan.varied[static_cast<std::size_t>(m)][c]);
      throw InvalidInput(fmt::format("{}: member {} ({}): {}", name, m, values, e.what()));
    }
    const ConservationLaws laws = conservation_laws(sc);
    auto change = [&](const char* column) {
      if (std::find(plan.changes_not_errors.begin(), plan.changes_not_errors.end(), column) ==
          plan.changes_not_errors.end())
        plan.changes_not_errors.emplace_back(column);
    };
    if (laws.angular_momentum != ConservationLaws::Angular::Conserved) change("max_momentum_error");
    if (!laws.linear_momentum) change("max_linear_momentum_error");
    plan.forced = plan.forced || laws.forced;
    if (m == 0) {
      plan.output_format = sc.output_format;
      adaptive = sc.integrator.adaptive();
      bodies = sc.bodies();
      state_cols = state_columns(sc);
      check_metrics(r, plan, sc);
    } else if (sc.bodies() != bodies) {
      r.fail("vary", "member " + std::to_string(m) + " has " + std::to_string(sc.bodies()) +
                         " bodies and member 0 " + std::to_string(bodies) + "; every member needs the same bodies");
    } else if (plan.metrics.pointing() &&
               (pointing_frame_count(sc) != static_cast<std::int64_t>(plan.series_times.size()) ||
                pointing_frames(sc) != plan.series_times)) {
      r.fail("vary", "member " + std::to_string(m) + " writes its frames at other times than member 0 (its step, "
                     "duration or output.every differ); the pointing-error curves need the same times in every "
                     "member");
    }
  }
  std::string header = "index";
  for (const std::string& c : plan.varied_columns) header += "," + c;
  // An adaptive run (time_transform) ends past its duration, each member at its own time: last_time says where.
  header += adaptive ? ",completed,error,steps,last_time" : ",completed,error,steps";
  header += ",max_abs_energy_error,max_abs_quat_norm_error,max_momentum_error,max_linear_momentum_error";
  for (const std::string& c : plan.metrics.names) header += "," + c;
  for (const std::string& c : state_cols) header += "," + c;
  plan.header = header;
  plan.header_fields = csv_fields(header).size();
  return plan;
}

EnsemblePlan parse_ensemble(const std::string& sweep_text, const std::string& name, const std::string& base_dir) {
  return parse_ensemble_with(sweep_text, name, base_dir, nullptr);
}

EnsemblePlan parse_ensemble_text(const std::string& sweep_text, const std::string& name,
                                 const std::string& scenario_text) {
  return parse_ensemble_with(sweep_text, name, ".", &scenario_text);
}

EnsemblePlan read_ensemble(const std::string& path) {
  const fs::path p(path);
  if (!fs::exists(p)) throw InvalidInput(path + ": no such sweep file");
  return parse_ensemble(read_text(p, "sweep file"), path, p.parent_path().string());
}

std::string run_member(const EnsemblePlan& plan, std::int64_t i, int threads, const std::string& trajectory_dir) {
  return run_member_scenario(i, plan.varied[static_cast<std::size_t>(i)], plan.member_toml(i), plan.scenario_name,
                             threads, trajectory_dir, plan.metrics);
}

std::string run_member_scenario(std::int64_t i, const std::vector<double>& varied, const std::string& scenario_toml,
                                const std::string& scenario_name, int threads, const std::string& trajectory_dir,
                                const MemberMetrics& metrics) {
  Scenario sc = parse_scenario(scenario_toml, scenario_name);
  sc.threads = threads;
  SimulationOptions so;
  so.stop_flag = stop_flag();
  const double nan = std::nan("");
  // The pointing error (deg, the angle of q_target^* q) at every step: its last value, the time from
  // which it stays within the band, and its values at the output frames (the plan's series_times).
  const bool pointing = metrics.pointing();
  const std::size_t frames = pointing ? static_cast<std::size_t>(pointing_frame_count(sc)) : 0;
  double last_error = nan, settled_at = nan;
  std::vector<double> series;
  if (pointing) {
    const S3d target = sc.attitude_targets.at(0);
    const std::int64_t every = sc.output_every;
    so.observe_step = [&sc, &last_error, &settled_at, &series, &metrics, target, every](std::int64_t k, double t,
                                                                                       const SystemState& s) {
      const S3d e = target.inverse() * s.q[0];
      last_error = 2.0 * std::atan2(e.vec().norm(), std::abs(e.w())) * (180.0 / std::numbers::pi);
      if (!(last_error <= metrics.settle_band_deg)) {
        settled_at = std::nan("");
      } else if (std::isnan(settled_at)) {
        settled_at = t;
      }
      if (k % every == 0 || sc.integrator.ends(k, t)) series.push_back(last_error);
    };
  }
  SimulationResult r;
  if (trajectory_dir.empty()) {
    sc.output_every = sc.integrator.steps + 1;
    DiscardSink sink;
    so.open_side_table = [](const std::string&, const TrajectoryLayout&,
                            const SinkPosition*) -> std::unique_ptr<TrajectorySink> {
      return std::make_unique<DiscardSink>();
    };
    r = simulate(sc, sink, so);
  } else {
    fs::create_directories(trajectory_dir);
    write_file_atomically((fs::path(trajectory_dir) / "scenario.toml").string(), sc.source_text);
    auto sink = open_trajectory(sc.output_format,
                                (fs::path(trajectory_dir) / trajectory_file_name(sc.output_format)).string(),
                                scenario_layout(sc));
    so.open_side_table = side_tables_in(trajectory_dir);
    r = simulate(sc, *sink, so);
    sink->close(sc.source_text, sink->stores_summary() ? summary_json(sc, r) : std::string());
    write_summary_file((fs::path(trajectory_dir) / "summary.json").string(), sc, r);
  }
  if (r.interrupted) return {};  // not a result: --resume runs it again
  const RunStatistics& st = r.stats;
  std::string row = std::to_string(i);
  for (double v : varied) append_number(row, v);
  fmt::format_to(std::back_inserter(row), ",{},{},{}", r.completed ? 1 : 0, csv_field(r.error), st.last_k);
  if (sc.integrator.adaptive()) append_number(row, st.observed ? st.last_t : nan);
  for (double v : {st.observed ? st.max_energy_error : nan, st.observed ? st.max_quat_error : nan,
                   st.observed ? st.max_momentum_error : nan, st.observed ? st.max_linear_momentum_error : nan})
    append_number(row, v);
  for (const std::string& name : metrics.names) {
    double v = nan;  // a member that did not complete: no final values
    if (r.completed) {
      if (name == "pointing_error_deg") v = last_error;
      if (name == "settling_time") v = settled_at;
      if (name == "saturation_time") v = st.wheels_saturated_time;
      if (name == "control_effort") v = st.wheel_effort;
      if (name == "max_wheel_torque" || name == "max_wheel_speed") {
        v = 0.0;
        for (const RunStatistics::WheelStatistics& w : st.wheels)
          v = std::max(v, name == "max_wheel_torque" ? w.max_torque : w.max_speed);
      }
    }
    append_number(row, v);
  }
  for (std::size_t a = 0; a < sc.bodies(); ++a) {
    const RigidBodyState s = r.final_state.size() == sc.bodies() ? r.final_state.body(a) : sc.initial_state.body(a);
    const Vector4<double> q = s.q.scalar_first();
    for (double v : {s.x.x(), s.x.y(), s.x.z(), q(0), q(1), q(2), q(3), s.p.x(), s.p.y(), s.p.z(), s.w.x(), s.w.y(),
                     s.w.z()})
      append_number(row, st.observed ? v : nan);
  }
  // The pointing-error curve after the members.csv columns (EnsemblePlan::split_row); NaN past a failure.
  series.resize(frames, nan);
  for (double e : series) append_number(row, e);
  return row;
}

namespace ensemble_detail {

std::vector<std::string> read_journal(const std::string& dir, std::int64_t members) {
  std::vector<std::string> rows(static_cast<std::size_t>(members));
  std::ifstream in(fs::path(dir) / "journal.csv", std::ios::binary);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::size_t start = 0;
  while (start < text.size()) {
    const std::size_t end = text.find('\n', start);
    if (end == std::string::npos) break;  // a torn last line (the process died mid-write): run it again
    const std::string line = text.substr(start, end - start);
    start = end + 1;
    char* stop = nullptr;
    const long long index = std::strtoll(line.c_str(), &stop, 10);
    if (stop == line.c_str() || *stop != ',' || index < 0 || index >= members) continue;
    rows[static_cast<std::size_t>(index)] = line;
  }
  return rows;
}

void cut_torn_line(const std::string& dir) {
  for (const char* name : {"journal.csv", "timings.csv"}) {
    const fs::path path = fs::path(dir) / name;
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (!in || in.tellg() <= 0) continue;
    in.seekg(-1, std::ios::end);
    if (in.get() == '\n') continue;  // whole lines: the usual case, read no further
    in.seekg(0);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    in.close();
    const std::size_t keep = text.rfind('\n') == std::string::npos ? 0 : text.rfind('\n') + 1;
    std::error_code ec;
    fs::resize_file(path, keep, ec);
    if (ec) throw InvalidInput(path.string() + ": cannot cut its torn last line (" + ec.message() + ")");
  }
}

namespace {
void append_line(const std::string& path, const std::string& line) {
  std::FILE* f = std::fopen(path.c_str(), "ab");
  if (!f) throw std::runtime_error(path + ": cannot append");
  const bool ok = std::fwrite(line.data(), 1, line.size(), f) == line.size();
  if (std::fclose(f) != 0 || !ok) throw std::runtime_error(path + ": write failed");
}
}  // namespace

void append_journal(const std::string& dir, const std::string& row) {
  append_line((fs::path(dir) / "journal.csv").string(), row + "\n");
}

void append_timing(const std::string& dir, std::int64_t index, double seconds, int rank) {
  const fs::path path = fs::path(dir) / "timings.csv";
  std::string line;
  std::error_code ec;
  if (!fs::exists(path, ec) || fs::file_size(path, ec) == 0) line = "index,wall_seconds,rank\n";
  line += fmt::format("{},{:.6g},{}\n", index, seconds, rank);
  append_line(path.string(), line);
}

void write_members(const std::string& dir, const EnsemblePlan& plan, const std::vector<std::string>& full_rows) {
  std::vector<std::string> rows;  // the members.csv part of each row
  std::string curves = "index,t,pointing_error_deg\n";
  for (const std::string& r : full_rows) {
    if (r.empty()) {
      rows.emplace_back();
      continue;
    }
    auto [members_row, series] = plan.split_row(r);
    rows.push_back(std::move(members_row));
    if (plan.series_times.empty()) continue;
    const std::string index = r.substr(0, r.find(','));
    std::size_t j = 0;
    for (std::size_t at = 0; at <= series.size() && j < plan.series_times.size(); ++j) {
      const std::size_t end = std::min(series.find(',', at), series.size());
      fmt::format_to(std::back_inserter(curves), "{},{:.17g},{}\n", index, plan.series_times[j],
                     series.substr(at, end - at));
      at = end + 1;
    }
  }
  if (!plan.series_times.empty()) write_file_atomically((fs::path(dir) / "pointing_error.csv").string(), curves);
  std::string text = plan.header + "\n";
  for (const std::string& r : rows)
    if (!r.empty()) text += r + "\n";
  write_file_atomically((fs::path(dir) / "members.csv").string(), text);
  const FormatDescriptor& format = plan.output_format.descriptor();
  if (!format.write_table) return;
  // The same table as arrays, parsed from the rows just written.
  using Kind = ColumnTable::Column::Kind;
  ColumnTable table;
  for (const std::string& name : csv_fields(plan.header)) {
    ColumnTable::Column c;
    c.name = name;
    c.kind = name == "error" ? Kind::String : name == "index" || name == "completed" || name == "steps" ? Kind::Integer
                                                                                                        : Kind::Number;
    table.columns.push_back(std::move(c));
  }
  for (const std::string& r : rows) {
    if (r.empty()) continue;
    const std::vector<std::string> f = csv_fields(r);
    if (f.size() != table.columns.size())
      throw std::runtime_error(fmt::format("members table: a row of {} fields under {} columns", f.size(),
                                           table.columns.size()));
    for (std::size_t k = 0; k < f.size(); ++k) {
      ColumnTable::Column& c = table.columns[k];
      if (c.kind == Kind::String)
        c.strings.push_back(f[k]);
      else if (c.kind == Kind::Integer)
        c.integers.push_back(std::strtoll(f[k].c_str(), nullptr, 10));
      else
        c.numbers.push_back(std::strtod(f[k].c_str(), nullptr));  // {:.17g}: the same double; "nan" is NaN
    }
  }
  format.write_table((fs::path(dir) / format.table_file_name).string(), table);
}

bool row_failed(const std::string& row, const EnsemblePlan& plan) {
  // The field after the index and the varied values is `completed`.
  std::size_t at = 0;
  for (std::size_t c = 0; c < plan.varied_columns.size() + 1; ++c) at = row.find(',', at) + 1;
  return row.compare(at, 2, "0,") == 0;
}

std::string trajectory_dir(const std::string& dir, const EnsemblePlan& plan, std::int64_t i) {
  return plan.keep_trajectories ? (fs::path(dir) / "members" / fmt::format("{:06d}", i)).string() : std::string();
}

TimedRow run_member_timed(const EnsemblePlan& plan, std::int64_t i, const std::string& dir) {
  const auto start = std::chrono::steady_clock::now();
  TimedRow r;
  r.row = run_member(plan, i, 1, trajectory_dir(dir, plan, i));
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return r;
}

EnsemblePlan plan_of_folder(const std::string& dir, bool check_members) {
  const fs::path d(dir);
  if (!fs::exists(d / "sweep.toml"))
    throw InvalidInput(dir + ": not an ensemble folder (no sweep.toml); give the folder written by lgvi ensemble");
  const std::string base = read_text(d / "scenario.toml", "base scenario copy");
  return parse_ensemble_with(read_text(d / "sweep.toml", "sweep copy"), (d / "sweep.toml").string(), dir, &base,
                             check_members);
}

Prepared prepare(const std::string& sweep_path, const EnsembleOptions& opt) {
  Prepared p;
  p.dir = opt.out_dir;
  // Read once p.dir is known (a new ensemble's default folder is the sweep's stem).
  auto changes_file = [&p] { return fs::path(p.dir) / "changes_not_errors.json"; };
  if (opt.resume) {
    p.plan = plan_of_folder(p.dir);
    if (!fs::exists(changes_file())) {
      // A folder begun by an lgvi before changes_not_errors.json, which ran a body given by mass +
      // inertia in a central field as a point mass: its members must not continue with the
      // gravity-gradient model (members.csv would mix the two physics).
      if (has_gravity_gradient_body(parse_scenario(p.plan.member_toml(0), p.plan.scenario_name)))
        throw InvalidInput("--resume: '" + p.dir + "' was begun by an lgvi that ran a body given by mass + inertia "
                           "as a point mass in the central field; this one gives it the gravity-gradient torque. Add "
                           "model = \"point\" to [potential] in " + (fs::path(p.dir) / "scenario.toml").string() +
                           " to continue as it began, or run the ensemble again");
      write_file_atomically(changes_file().string(), json_text(Json(p.plan.changes_not_errors)) + "\n");
    }
    cut_torn_line(p.dir);
  } else {
    p.plan = read_ensemble(sweep_path);
    if (p.dir.empty()) p.dir = fs::path(sweep_path).stem().string();
    if (fs::exists(fs::path(p.dir) / "journal.csv") || fs::exists(fs::path(p.dir) / "members.csv"))
      throw InvalidInput("--out: '" + p.dir + "' already holds an ensemble; continue it with lgvi ensemble --resume " +
                         p.dir + ", or choose another folder");
    try {
      fs::create_directories(p.dir);
      write_file_atomically((fs::path(p.dir) / "sweep.toml").string(), p.plan.sweep_text);
      write_file_atomically((fs::path(p.dir) / "scenario.toml").string(), p.plan.scenario_text);
      // Which members.csv columns are changes, not errors, for the figures (drawn by Python
      // from the folder, without the compiled module that reads the sweep).
      write_file_atomically(changes_file().string(), json_text(Json(p.plan.changes_not_errors)) + "\n");
      std::ofstream(fs::path(p.dir) / "journal.csv", std::ios::binary | std::ios::trunc);
    } catch (const std::exception& e) {
      throw InvalidInput("--out: '" + p.dir + "' cannot be written: " + e.what());
    }
  }
  p.rows = read_journal(p.dir, p.plan.members());
  return p;
}

EnsembleProgress::EnsembleProgress(const EnsembleOptions& options, std::int64_t total, std::int64_t done)
    : line_(!options.quiet && (options.progress || isatty(2) != 0)), total_(total), start_done_(done) {}

void EnsembleProgress::operator()(std::int64_t done, std::int64_t failed) {
  if (!line_.enabled()) return;
  const double s = line_.elapsed();
  const double rate = s > 0 ? static_cast<double>(done - start_done_) / s : 0.0;
  const double left = rate > 0 ? static_cast<double>(total_ - done) / rate : 0.0;
  line_.show(fmt::sprintf("lgvi ensemble: %lld/%lld members, %lld failed, %.3g members/s, ~%.0f s left",
                          static_cast<long long>(done), static_cast<long long>(total_), static_cast<long long>(failed),
                          rate, left));
}

int finish(const Prepared& p, std::int64_t done, std::int64_t failed, const EnsembleOptions& opt) {
  write_members(p.dir, p.plan, p.rows);
  if (stop_signal() != 0) {
    std::cerr << fmt::format("lgvi: ensemble stopped by {} with {} of {} members done; continue with: lgvi ensemble "
                             "--resume {}\n",
                             stop_signal_name(), done, p.plan.members(), p.dir);
    return stop_exit_status();
  }
  if (!opt.quiet)
    std::cout << fmt::format("{}: {} members, {} failed; results in {}\n", p.plan.name, p.plan.members(), failed,
                             (fs::path(p.dir) / "members.csv").string());
  if (opt.figures) {
    try {
      draw_figures(p.dir);
    } catch (const std::exception& e) {
      std::cerr << "lgvi: error: the ensemble completed and members.csv is written, but " << e.what() << "\n";
      return 1;
    }
  }
  return 0;
}

}  // namespace ensemble_detail

bool launched_as_mpi_rank() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE", "MPI_LOCALNRANKS"}) {
    const char* s = std::getenv(v);
    if (s && std::atoi(s) > 1) return true;
  }
  return false;
}

namespace {

/// The q-quantile of sorted values (linear interpolation).
double quantile(const std::vector<double>& sorted, double q) {
  if (sorted.empty()) return std::nan("");
  const double at = q * static_cast<double>(sorted.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(at));
  const std::size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (at - static_cast<double>(lo)) * (sorted[hi] - sorted[lo]);
}

}  // namespace

void show_ensemble(const std::string& dir, std::ostream& out) {
  fs::path file = fs::path(dir) / "members.csv";
  std::istringstream in;
  bool from_journal = false;
  if (fs::exists(file)) {
    in.str(read_text(file, "members table"));
  } else {
    // Running, or stopped without a table (kill -9): the journal's whole
    // lines under the header of the folder's plan.
    file = fs::path(dir) / "journal.csv";
    if (!fs::exists(file))
      throw InvalidInput((fs::path(dir) / "members.csv").string() + ": no members here; is '" + dir +
                         "' a folder of lgvi ensemble?");
    const EnsemblePlan plan = ensemble_detail::plan_of_folder(dir, false);
    std::string text = plan.header + "\n";
    for (const std::string& r : ensemble_detail::read_journal(dir, plan.members()))
      if (!r.empty()) text += plan.split_row(r).first + "\n";
    in.str(text);
    from_journal = true;
  }
  std::string line;
  std::getline(in, line);
  const std::vector<std::string> header = csv_fields(line);
  auto column = [&](const std::string& name) {
    const auto it = std::find(header.begin(), header.end(), name);
    if (it == header.end()) throw InvalidInput(file.string() + ": no column " + name + "; not written by lgvi ensemble");
    return static_cast<std::size_t>(it - header.begin());
  };
  const std::size_t completed = column("completed"), error = column("error");
  const std::vector<std::string> errors{"max_abs_energy_error", "max_abs_quat_norm_error", "max_momentum_error"};
  std::vector<std::vector<double>> values(errors.size());
  std::int64_t rows = 0, failed = 0;
  std::map<std::string, std::int64_t> messages;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    const std::vector<std::string> f = csv_fields(line);
    if (f.size() != header.size()) continue;
    ++rows;
    if (f[completed] != "1") {
      ++failed;
      ++messages[f[error]];
      continue;
    }
    for (std::size_t e = 0; e < errors.size(); ++e) values[e].push_back(std::strtod(f[column(errors[e])].c_str(), nullptr));
  }
  // The planned size from the folder's sweep copy (members.csv alone: what it
  // holds), and which columns are changes rather than errors.
  std::int64_t planned = 0;
  std::vector<std::string> changes;
  bool forced = false;
  try {
    const EnsemblePlan plan = ensemble_detail::plan_of_folder(dir, false);
    planned = plan.members();
    changes = plan.changes_not_errors;
    forced = plan.forced;
  } catch (const std::exception&) {
    planned = rows;
  }
  auto row = [&](const std::string& name, const std::string& value) { out << fmt::format("{:<26} {}\n", name, value); };
  row("ensemble", fmt::format("{} ({} of {} members{})", dir, rows, planned, rows < planned ? ", NOT complete" : ""));
  if (from_journal)
    row("", fmt::format("from journal.csv: no members.csv yet (running, or stopped by kill -9); "
                        "lgvi ensemble --resume {} completes it", dir));
  row("failed", fmt::format("{}", failed));
  for (const auto& [message, count] : messages) row("  " + std::to_string(count) + " x", message);
  row("quantiles (completed)", "min / median / 90% / max");
  bool marked = false;
  for (std::size_t e = 0; e < errors.size(); ++e) {
    std::sort(values[e].begin(), values[e].end());
    const bool change = std::find(changes.begin(), changes.end(), errors[e]) != changes.end();
    marked = marked || change;
    const bool balance = forced && errors[e] == "max_abs_energy_error";  // of E - E0 - W, as one run's summary says
    row("  " + errors[e] + (change ? " (a change)" : "") + (balance ? " (E - E0 - W)" : ""), fmt::format("{:.3e} / {:.3e} / {:.3e} / {:.3e}", quantile(values[e], 0.0),
                                      quantile(values[e], 0.5), quantile(values[e], 0.9), quantile(values[e], 1.0)));
  }
  if (marked)
    row("  (a change)", "not conserved by these members' dynamics (a forcing or an external field): the column "
                        "measures how much the quantity changed, not an error of the method");
}

namespace {
MpiRunner g_mpi_runner = nullptr;
}  // namespace

void set_mpi_runner(MpiRunner runner) { g_mpi_runner = runner; }

int run_ensemble(const std::string& sweep_path, const EnsembleOptions& opt) {
  using namespace ensemble_detail;
  if (launched_as_mpi_rank()) {
    if (!g_mpi_runner)
      throw InvalidInput(
          "lgvi ensemble was started as one of several MPI ranks, but this lgvi was built without MPI: it would run "
          "the whole ensemble once per rank. Build it with Open MPI (apt-get install libopenmpi-dev; cmake finds "
          "it), or run without mpirun: lgvi ensemble SWEEP --threads N");
    return g_mpi_runner(sweep_path, opt);
  }
  Prepared p = prepare(sweep_path, opt);
  std::vector<std::int64_t> pending;
  std::int64_t done = 0, failed = 0;
  for (std::int64_t i = 0; i < p.plan.members(); ++i) {
    const std::string& row = p.rows[static_cast<std::size_t>(i)];
    if (row.empty()) {
      pending.push_back(i);
    } else {
      ++done;
      failed += row_failed(row, p.plan) ? 1 : 0;
    }
  }
  const int cores = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  const int threads =
      std::max(1, std::min<int>(opt.threads > 0 ? opt.threads : cores, static_cast<int>(std::max<std::size_t>(pending.size(), 1))));
  ensemble_detail::EnsembleProgress progress(opt, p.plan.members(), done);
  std::mutex mutex;
  std::size_t next = 0;
  std::exception_ptr error;
  {
    StopSignals signals;
    auto worker = [&] {
      for (;;) {
        std::int64_t i = 0;
        {
          std::lock_guard<std::mutex> lock(mutex);
          if (next >= pending.size() || stop_signal() != 0 || error) return;
          i = pending[next++];
        }
        try {
          const auto [row, seconds] = run_member_timed(p.plan, i, p.dir);
          if (row.empty()) return;  // stopped within the member
          std::lock_guard<std::mutex> lock(mutex);
          append_journal(p.dir, row);
          append_timing(p.dir, i, seconds, 0);
          p.rows[static_cast<std::size_t>(i)] = row;
          ++done;
          failed += row_failed(row, p.plan) ? 1 : 0;
          progress(done, failed);
        } catch (...) {
          std::lock_guard<std::mutex> lock(mutex);
          if (!error) error = std::current_exception();
          return;
        }
      }
    };
    std::vector<std::thread> pool;
    for (int t = 1; t < threads; ++t) pool.emplace_back(worker);
    worker();
    for (std::thread& t : pool) t.join();
  }
  if (error) {
    write_members(p.dir, p.plan, p.rows);
    std::rethrow_exception(error);
  }
  return finish(p, done, failed, opt);
}

}  // namespace lgvi::app
