#include "json_reader.hpp"

#include <cctype>
#include <charconv>
#include <stdexcept>

namespace lgvi::app {

const JsonValue* JsonValue::find(const std::string& key) const {
  if (!is_object()) return nullptr;
  for (const auto& [k, value] : *std::get<std::shared_ptr<JsonMembers>>(v))
    if (k == key) return &value;
  return nullptr;
}

namespace {

class Parser {
 public:
  explicit Parser(const std::string& t) : t_(t) {}

  JsonValue document() {
    JsonValue v = value(0);
    skip();
    if (i_ != t_.size()) fail("trailing characters");
    return v;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw std::runtime_error("invalid JSON at offset " + std::to_string(i_) + ": " + what);
  }
  void skip() {
    while (i_ < t_.size() && std::isspace(static_cast<unsigned char>(t_[i_]))) ++i_;
  }
  bool eat(char c) {
    skip();
    if (i_ < t_.size() && t_[i_] == c) {
      ++i_;
      return true;
    }
    return false;
  }
  bool word(const char* w) {
    const std::string s(w);
    if (t_.compare(i_, s.size(), s) != 0) return false;
    i_ += s.size();
    return true;
  }

  JsonValue value(int depth) {
    if (depth > 64) fail("nested too deeply");
    skip();
    if (i_ >= t_.size()) fail("unexpected end");
    const char c = t_[i_];
    if (c == '{') {
      ++i_;
      auto members = std::make_shared<JsonMembers>();
      if (!eat('}')) {
        do {
          skip();
          std::string key = string();
          if (!eat(':')) fail("expected ':'");
          members->emplace_back(std::move(key), value(depth + 1));
        } while (eat(','));
        if (!eat('}')) fail("expected '}'");
      }
      return {members};
    }
    if (c == '[') {
      ++i_;
      auto items = std::make_shared<JsonArray>();
      if (!eat(']')) {
        do items->push_back(value(depth + 1));
        while (eat(','));
        if (!eat(']')) fail("expected ']'");
      }
      return {items};
    }
    if (c == '"') return {string()};
    if (word("true")) return {true};
    if (word("false")) return {false};
    if (word("null")) return {nullptr};
    double d = 0;
    const auto res = std::from_chars(t_.data() + i_, t_.data() + t_.size(), d);
    if (res.ec != std::errc()) fail("expected a value");
    i_ = static_cast<std::size_t>(res.ptr - t_.data());
    return {d};
  }

  std::string string() {
    if (i_ >= t_.size() || t_[i_] != '"') fail("expected a string");
    ++i_;
    std::string s;
    while (i_ < t_.size() && t_[i_] != '"') {
      char c = t_[i_++];
      if (c == '\\') {
        if (i_ >= t_.size()) fail("unterminated escape");
        const char e = t_[i_++];
        switch (e) {
          case 'n': c = '\n'; break;
          case 't': c = '\t'; break;
          case 'r': c = '\r'; break;
          case 'b': c = '\b'; break;
          case 'f': c = '\f'; break;
          case 'u':  // lgvi writes \u00XX only
            if (i_ + 4 > t_.size()) fail("short \\u escape");
            c = static_cast<char>(std::stoi(t_.substr(i_, 4), nullptr, 16));
            i_ += 4;
            break;
          default: c = e;
        }
      }
      s += c;
    }
    if (i_ >= t_.size()) fail("unterminated string");
    ++i_;
    return s;
  }

  const std::string& t_;
  std::size_t i_ = 0;
};

}  // namespace

JsonValue parse_json(const std::string& text) { return Parser(text).document(); }

}  // namespace lgvi::app
