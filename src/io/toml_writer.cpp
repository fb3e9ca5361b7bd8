// TOML text in toml::toml_formatter's layout, without its undefined
// line-wrapping estimate; see toml_writer.hpp for why.
#include "io/toml_writer.hpp"

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <sstream>
#include <string_view>
#include <vector>

namespace lgvi::io {

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

/// A finite or non-finite double as Python's repr spells it (the shortest
/// digits that read back to the same double; positional when the decimal
/// exponent e of d.ddd x 10^e is in [-4, 15], with ".0" added to a whole
/// number, else d.ddde+XX with two exponent digits at least), so a scenario
/// written by lgvi reads "0.1" where the user wrote 0.1, from C++ and from
/// Python alike; "nan", "inf", "-inf" as TOML spells them.
std::string float_text(double x) {
  if (std::isnan(x)) return "nan";
  if (std::isinf(x)) return x > 0 ? "inf" : "-inf";
  std::string out;
  if (std::signbit(x)) out += '-';
  if (x == 0.0) {
    out += "0.0";
    return out;
  }
  char buffer[40];
  const auto [end, ec] = std::to_chars(buffer, buffer + sizeof buffer, std::fabs(x), std::chars_format::scientific);
  (void)ec;  // 40 characters hold any double's shortest scientific form (at most 24)
  const std::string_view text(buffer, static_cast<std::size_t>(end - buffer));
  const std::size_t e_at = text.find('e');
  std::string digits;  // d1 d2 ... without the point
  for (const char c : text.substr(0, e_at))
    if (c != '.') digits += c;
  const int exponent = std::atoi(std::string(text.substr(e_at + 1)).c_str());
  if (exponent < -4 || exponent >= 16) {
    out += digits[0];
    if (digits.size() > 1) {
      out += '.';
      out.append(digits, 1, std::string::npos);
    }
    out += exponent < 0 ? "e-" : "e+";
    const int magnitude = std::abs(exponent);
    if (magnitude < 10) out += '0';
    out += std::to_string(magnitude);
  } else if (exponent < 0) {
    out += "0.";
    out.append(static_cast<std::size_t>(-exponent - 1), '0');
    out += digits;
  } else {
    const auto whole = static_cast<std::size_t>(exponent) + 1;  // digits before the point
    if (digits.size() <= whole) {
      out += digits;
      out.append(whole - digits.size(), '0');
      out += ".0";
    } else {
      out.append(digits, 0, whole);
      out += '.';
      out.append(digits, whole, std::string::npos);
    }
  }
  return out;
}

/// A string as a TOML basic string, "...", in ASCII (the scenario reader
/// takes no other character outside a comment): the escapes TOML and JSON
/// share (\" \\ \b \t \n \f \r, other control characters and DEL as
/// \u00XX), and every character beyond ASCII as its code point, \uXXXX or
/// \UXXXXXXXX (an invalid UTF-8 byte as U+FFFD).
std::string basic_string_text(std::string_view text) {
  constexpr char hex[] = "0123456789abcdef";
  std::string out = "\"";
  auto code_point = [&](char32_t cp) {
    const int digits = cp <= 0xffff ? 4 : 8;
    out += digits == 4 ? "\\u" : "\\U";
    for (int shift = 4 * (digits - 1); shift >= 0; shift -= 4) out += hex[(cp >> shift) & 15];
  };
  for (std::size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c >= 0x80) {
      const std::size_t length = c >= 0xf0 ? 4 : c >= 0xe0 ? 3 : c >= 0xc0 ? 2 : 1;
      char32_t cp = length == 4 ? c & 0x07u : length == 3 ? c & 0x0fu : c & 0x1fu;
      bool valid = length > 1 && i + length <= text.size();
      for (std::size_t j = 1; valid && j < length; ++j) {
        const auto next = static_cast<unsigned char>(text[i + j]);
        valid = (next & 0xc0u) == 0x80u;
        cp = (cp << 6) | (next & 0x3fu);
      }
      if (!valid || cp > 0x10ffff || (cp >= 0xd800 && cp <= 0xdfff)) {
        code_point(0xfffd);
        ++i;
      } else {
        code_point(cp);
        i += length;
      }
      continue;
    }
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\b': out += "\\b"; break;
      case '\t': out += "\\t"; break;
      case '\n': out += "\\n"; break;
      case '\f': out += "\\f"; break;
      case '\r': out += "\\r"; break;
      default:
        if (c < 0x20 || c == 0x7f)
          code_point(c);
        else
          out += static_cast<char>(c);
    }
    ++i;
  }
  out += '"';
  return out;
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

  /// A scalar: a float as float_text spells it, a string as
  /// basic_string_text, others printed by toml++.
  void scalar(const toml::node& v) {
    if (const toml::value<double>* f = v.as_floating_point()) {
      raw(float_text(f->get()));
      return;
    }
    if (const toml::value<std::string>* t = v.as_string()) {
      raw(basic_string_text(t->get()));
      return;
    }
    std::ostringstream os;
    os << toml::toml_formatter(v);
    raw(os.str());
  }

  void key(std::string_view k) {
    if (is_bare_key(k)) {
      raw(k);
      return;
    }
    raw(basic_string_text(k));  // a key that must be quoted
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

}  // namespace lgvi::io
