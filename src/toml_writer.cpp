// TOML text in toml::toml_formatter's layout, without its undefined
// line-wrapping estimate; see toml_writer.hpp for why.
#include "toml_writer.hpp"

#include <cmath>
#include <cstdint>
#include <sstream>
#include <string_view>
#include <vector>

namespace lgvi::app {

namespace {

/// toml_formatter breaks an array over lines when its estimated inline width
/// plus the indentation reaches this many columns.
constexpr std::size_t wrap_columns = 120;
constexpr std::string_view indent_unit = "    ";

/// Decimal digits before the point of a magnitude (1 for magnitudes below 10,
/// including those below 1, where toml_formatter's cast of a negative log10 to
/// size_t is undefined; it means the "0" of "0.05").
std::size_t integer_digits(double magnitude) {
  const double l = std::log10(magnitude);
  return l >= 1.0 ? static_cast<std::size_t>(l) + 1u : 1u;
}

/// toml_formatter_count_inline_columns with every case defined: stops early
/// once the wrap width is reached, as the original does.
std::size_t inline_columns(const toml::node& node) {
  switch (node.type()) {
    case toml::node_type::table: {
      const toml::table& t = *node.as_table();
      if (t.empty()) return 2u;  // "{}"
      std::size_t weight = 3u;   // "{ }"
      for (auto&& [k, v] : t) {
        weight += k.length() + inline_columns(v) + 2u;  // ", "
        if (weight >= wrap_columns) break;
      }
      return weight;
    }
    case toml::node_type::array: {
      const toml::array& a = *node.as_array();
      if (a.empty()) return 2u;  // "[]"
      std::size_t weight = 3u;   // "[ ]"
      for (const toml::node& e : a) {
        weight += inline_columns(e) + 2u;
        if (weight >= wrap_columns) break;
      }
      return weight;
    }
    case toml::node_type::string: return node.as_string()->get().length() + 2u;  // quotes
    case toml::node_type::integer: {
      const std::int64_t v = node.as_integer()->get();
      if (v == 0) return 1u;
      // |v| as unsigned: defined for INT64_MIN too.
      const std::uint64_t magnitude = v < 0 ? 0u - static_cast<std::uint64_t>(v) : static_cast<std::uint64_t>(v);
      return (v < 0 ? 1u : 0u) + integer_digits(static_cast<double>(magnitude));
    }
    case toml::node_type::floating_point: {
      const double v = node.as_floating_point()->get();
      if (v == 0.0) return 3u;  // "0.0"
      const std::size_t sign = std::signbit(v) ? 1u : 0u;
      if (!std::isfinite(v)) return sign + 3u;  // "inf", "nan"
      return sign + 2u + integer_digits(std::fabs(v));  // ".0"
    }
    case toml::node_type::boolean: return 5u;
    case toml::node_type::date:
    case toml::node_type::time: return 10u;
    case toml::node_type::date_time: return 30u;
    case toml::node_type::none: break;
  }
  return 0u;
}

bool is_bare_key(std::string_view k) {
  if (k.empty()) return false;
  for (const char c : k)
    if (!((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-'))
      return false;
  return true;
}

bool is_non_inline_array_of_tables(const toml::node& n) {
  const toml::array* a = n.as_array();
  return a && a->is_array_of_tables() && !(*a)[0].as_table()->is_inline();
}

/// The state machine of toml::formatter / toml_formatter: the indentation
/// level (-1 at the root), whether the last character written was a newline,
/// and whether a blank line is owed before the next table header.
class Writer {
 public:
  explicit Writer(std::ostream& out) : out_(out) {}

  void root(const toml::table& t) {
    indent_ = -1;  // root keys and top-level tables at the same indentation
    table(t);
  }

  void inline_table(const toml::table& t) {
    if (t.empty()) {
      raw("{}");
      return;
    }
    raw("{ ");
    bool first = true;
    for (auto&& [k, v] : t) {
      if (!first) raw(", ");
      first = false;
      key(k.str());
      raw(" = ");
      any_value(v);
    }
    raw(" }");
  }

 private:
  void raw(std::string_view s) {
    out_ << s;
    naked_newline_ = false;
  }
  void newline(bool force) {
    if (!naked_newline_ || force) {
      out_ << '\n';
      naked_newline_ = true;
    }
  }
  void indentation() {
    for (int i = 0; i < indent_; ++i) raw(indent_unit);
  }
  void pending_separator() {
    if (pending_separator_) {
      newline(true);
      newline(true);
      pending_separator_ = false;
    }
  }

  /// A scalar, printed by toml++ (strings quoted and escaped as it chooses,
  /// floats to round-trip).
  void scalar(const toml::node& v) {
    std::ostringstream os;
    os << toml::toml_formatter(v);
    raw(os.str());
  }

  void key(std::string_view k) {
    if (is_bare_key(k)) {
      raw(k);
      return;
    }
    // A key that must be quoted: toml++ quotes it as it would a single-line
    // string value.
    std::ostringstream os;
    os << toml::toml_formatter(toml::value<std::string>(std::string(k)),
                               toml::toml_formatter::default_flags & ~toml::format_flags::allow_multi_line_strings);
    raw(os.str());
  }

  void any_value(const toml::node& v) {
    if (const toml::table* t = v.as_table())
      inline_table(*t);
    else if (const toml::array* a = v.as_array())
      array(*a);
    else
      scalar(v);
  }

  void array(const toml::array& a) {
    if (a.empty()) {
      raw("[]");
      return;
    }
    const int original_indent = indent_;
    const bool multiline =
        inline_columns(a) + indent_unit.size() * static_cast<std::size_t>(original_indent < 0 ? 0 : original_indent) >=
        wrap_columns;
    raw("[");
    if (multiline) {
      if (original_indent < 0) indent_ = 0;
      ++indent_;
    } else {
      raw(" ");
    }
    for (std::size_t i = 0; i < a.size(); ++i) {
      if (i > 0) {
        raw(",");
        if (!multiline) raw(" ");
      }
      if (multiline) {
        newline(true);
        indentation();
      }
      any_value(a[i]);
    }
    if (multiline) {
      indent_ = original_indent;
      newline(true);
      indentation();
    } else {
      raw(" ");
    }
    raw("]");
  }

  void key_path() {
    for (std::size_t i = 0; i < path_.size(); ++i) {
      if (i > 0) raw(".");
      key(path_[i]);
    }
  }

  void table(const toml::table& t) {
    // Values, arrays and inline tables first.
    for (auto&& [k, v] : t) {
      const toml::table* sub = v.as_table();
      if ((sub && !sub->is_inline()) || is_non_inline_array_of_tables(v)) continue;
      pending_separator_ = true;
      newline(false);
      indentation();
      key(k.str());
      raw(" = ");
      any_value(v);
    }
    // Then [tables]; one holding only tables gets no header of its own.
    for (auto&& [k, v] : t) {
      const toml::table* sub = v.as_table();
      if (!sub || sub->is_inline()) continue;
      std::size_t values = 0, tables = 0;
      for (auto&& [ck, cv] : *sub) {
        const toml::table* ct = cv.as_table();
        if ((ct && !ct->is_inline()) || is_non_inline_array_of_tables(cv))
          ++tables;
        else
          ++values;
      }
      const bool skip_header = values == 0 && tables > 0;
      path_.push_back(k.str());
      if (!skip_header) {
        pending_separator();
        ++indent_;
        indentation();
        raw("[");
        key_path();
        raw("]");
        pending_separator_ = true;
      }
      table(*sub);
      path_.pop_back();
      if (!skip_header) --indent_;
    }
    // Then [[arrays of tables]].
    for (auto&& [k, v] : t) {
      if (!is_non_inline_array_of_tables(v)) continue;
      const toml::array& a = *v.as_array();
      ++indent_;
      path_.push_back(k.str());
      for (const toml::node& element : a) {
        pending_separator();
        indentation();
        raw("[[");
        key_path();
        raw("]]");
        pending_separator_ = true;
        table(*element.as_table());
      }
      path_.pop_back();
      --indent_;
    }
  }

  std::ostream& out_;
  int indent_ = 0;
  bool naked_newline_ = true;
  bool pending_separator_ = false;
  std::vector<std::string_view> path_;
};

}  // namespace

std::string write_toml(const toml::table& document) {
  std::ostringstream os;
  Writer(os).root(document);
  return os.str();
}

std::string write_inline_toml(const toml::table& table) {
  std::ostringstream os;
  Writer(os).inline_table(table);
  return os.str();
}

}  // namespace lgvi::app
