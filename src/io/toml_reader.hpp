#pragma once
// The one reader of TOML documents (scenarios and sweep files): typed values
// out of a parsed document, every error one InvalidInput naming the file and
// the full dotted key ("integrator.step", "vary[0].normal.std") and what is
// expected there.

#include <lgvi/error.hpp>
#include <lgvi/s3.hpp>

#include <toml++/toml.h>

#include <Eigen/Core>

#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace lgvi::io {

/// User text echoed in a message, with control characters escaped so that
/// every message stays one line.
std::string printable(std::string_view text);

/// Reads typed values out of a parsed TOML document, naming the full key
/// ("integrator.step") in every error.
class TomlReader {
 public:
  explicit TomlReader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw InvalidInput(file_ + ": " + (key.empty() ? "" : "key '" + key + "': ") + what);
  }

  /// Rejects keys of `t` not in `allowed`.
  void only_keys(const toml::table& t, const std::string& prefix, std::initializer_list<std::string_view> allowed) const {
    only_keys(t, prefix, std::span<const std::string_view>(allowed.begin(), allowed.size()));
  }

  void only_keys(const toml::table& t, const std::string& prefix, std::span<const std::string_view> allowed) const {
    for (const auto& [k, v] : t) {
      bool ok = false;
      for (auto a : allowed) ok = ok || k.str() == a;
      if (!ok) {
        std::string list;
        for (auto a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
        fail(join(prefix, printable(k.str())), "unknown key; allowed here: " + list);
      }
    }
  }

  const toml::table& table(const toml::table& t, const std::string& prefix, const std::string& name) const {
    const toml::node* n = t.get(name);
    if (!n) fail(join(prefix, name), "missing table [" + join(prefix, name) + "]");
    if (!n->is_table()) fail(join(prefix, name), "must be a table [" + join(prefix, name) + "]");
    return *n->as_table();
  }

  const toml::table* optional_table(const toml::table& t, const std::string& prefix, const std::string& name) const {
    const toml::node* n = t.get(name);
    if (n && !n->is_table()) fail(join(prefix, name), "must be a table");
    return n ? n->as_table() : nullptr;
  }

  double number(const toml::node& n, const std::string& key) const {
    if (!n.is_number()) fail(key, std::string("must be a number, got a ") + type_name(n));
    const double v = n.is_integer() ? static_cast<double>(n.as_integer()->get()) : n.as_floating_point()->get();
    if (!std::isfinite(v)) fail(key, "must be finite, got " + std::to_string(v));
    return v;
  }

  /// A number or a non-empty array of numbers; `scalar` says which it was.
  std::vector<double> numbers(const toml::node& n, const std::string& key, bool& scalar) const {
    scalar = n.is_number();
    if (scalar) return {number(n, key)};
    const toml::array* a = n.as_array();
    if (!a || a->empty()) fail(key, std::string("must be a number or a non-empty array of numbers, got ") +
                                        (a ? "an empty array" : std::string("a ") + type_name(n)));
    std::vector<double> v;
    for (std::size_t i = 0; i < a->size(); ++i) v.push_back(number(*a->get(i), key + "[" + std::to_string(i) + "]"));
    return v;
  }

  double number(const toml::table& t, const std::string& prefix, const std::string& name) const {
    const toml::node* n = t.get(name);
    if (!n) fail(join(prefix, name), "missing (a number)");
    return number(*n, join(prefix, name));
  }

  std::int64_t integer(const toml::table& t, const std::string& prefix, const std::string& name) const {
    const toml::node* n = t.get(name);
    const std::string key = join(prefix, name);
    if (!n) fail(key, "missing (an integer)");
    if (!n->is_integer()) fail(key, std::string("must be an integer, got a ") + type_name(*n));
    return n->value<std::int64_t>().value();
  }

  std::string string(const toml::table& t, const std::string& prefix, const std::string& name,
                     std::initializer_list<std::string_view> allowed) const {
    return string(t, prefix, name, std::span<const std::string_view>(allowed.begin(), allowed.size()));
  }

  std::string string(const toml::table& t, const std::string& prefix, const std::string& name,
                     std::span<const std::string_view> allowed) const {
    const toml::node* n = t.get(name);
    const std::string key = join(prefix, name);
    std::string list;
    for (auto a : allowed) list += (list.empty() ? "\"" : ", \"") + std::string(a) + "\"";
    if (!n) fail(key, "missing; one of " + list);
    if (!n->is_string()) fail(key, std::string("must be a string, one of ") + list + ", got a " + type_name(*n));
    std::string v = n->value<std::string>().value();
    for (auto a : allowed)
      if (v == a) return v;
    fail(key, "\"" + printable(v) + "\" is not one of " + list);
  }

  template <int N>
  Eigen::Matrix<double, N, 1> vector(const toml::node& n, const std::string& key) const {
    const toml::array* a = n.as_array();
    if (!a) fail(key, "must be an array of " + std::to_string(N) + " numbers, got a " + type_name(n));
    if (static_cast<int>(a->size()) != N)
      fail(key, "must have " + std::to_string(N) + " numbers, got " + std::to_string(a->size()));
    Eigen::Matrix<double, N, 1> v;
    for (int i = 0; i < N; ++i) v(i) = number(*a->get(static_cast<std::size_t>(i)), key + "[" + std::to_string(i) + "]");
    return v;
  }

  template <int N>
  Eigen::Matrix<double, N, 1> vector(const toml::table& t, const std::string& prefix, const std::string& name) const {
    const toml::node* n = t.get(name);
    if (!n) fail(join(prefix, name), "missing (an array of " + std::to_string(N) + " numbers)");
    return vector<N>(*n, join(prefix, name));
  }

  Matrix3<double> matrix3(const toml::table& t, const std::string& prefix, const std::string& name) const {
    const toml::node* n = t.get(name);
    const std::string key = join(prefix, name);
    if (!n) fail(key, "missing (a 3x3 array of arrays)");
    const toml::array* a = n->as_array();
    if (!a || a->size() != 3) fail(key, "must be 3 rows of 3 numbers, e.g. [[1,0,0],[0,2,0],[0,0,3]]");
    Matrix3<double> m;
    for (int i = 0; i < 3; ++i)
      m.row(i) = vector<3>(*a->get(static_cast<std::size_t>(i)), key + "[" + std::to_string(i) + "]").transpose();
    return m;
  }

  static std::string join(const std::string& prefix, const std::string& name) {
    return prefix.empty() ? name : prefix + "." + name;
  }

 private:
  static const char* type_name(const toml::node& n) {
    switch (n.type()) {
      case toml::node_type::string: return "string";
      case toml::node_type::integer: return "integer";
      case toml::node_type::floating_point: return "number";
      case toml::node_type::boolean: return "boolean";
      case toml::node_type::array: return "array";
      case toml::node_type::table: return "table";
      default: return "date or time";
    }
  }

  std::string file_;
};

}  // namespace lgvi::io
