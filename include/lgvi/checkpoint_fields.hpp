// The content of a checkpoint: named, typed, sized fields. Each object that
// takes part in a resume (the run, its statistics, the trajectory sink, the
// stepper and what it owns) writes its own fields under names it owns and
// reads them back; the file format (src/app/checkpoint.cpp) only stores them.
//
// Contract: a name is dot-separated, owner first ("stepper.predictors"); a
// field is written at most once; reading a field marks it read, so that what
// nobody read (a field written by a newer lgvi) can be reported. Accessors
// throw InvalidInput naming the field ("checkpoint field 'stepper.predictors':
// ..."); the caller adds the file's name.
#pragma once

#include <lgvi/error.hpp>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace lgvi {

class CheckpointFields {
 public:
  /// The element type of a field (stored in the file: the values are fixed).
  enum class Type : std::uint8_t { F64 = 1, I64 = 2, Text = 3 };

  struct Field {
    std::string name;
    Type type = Type::F64;
    std::vector<double> f64;
    std::vector<std::int64_t> i64;
    std::string text;
    mutable bool read = false;

    /// The number of elements (characters for text).
    std::size_t count() const {
      return type == Type::F64 ? f64.size() : type == Type::I64 ? i64.size() : text.size();
    }
  };

  void put_f64(std::string name, std::vector<double> values) {
    Field& f = add(std::move(name), Type::F64);
    f.f64 = std::move(values);
  }
  void put_i64(std::string name, std::vector<std::int64_t> values) {
    Field& f = add(std::move(name), Type::I64);
    f.i64 = std::move(values);
  }
  void put_text(std::string name, std::string text) {
    Field& f = add(std::move(name), Type::Text);
    f.text = std::move(text);
  }

  /// Adds a copy of a field (e.g. of another set), not yet read.
  void put(const Field& field) {
    Field& f = add(field.name, field.type);
    f.f64 = field.f64;
    f.i64 = field.i64;
    f.text = field.text;
  }

  bool has(const std::string& name) const { return find(name) != nullptr; }

  /// The values of a field of doubles, `count` of them unless count is
  /// any_count; throws if it is missing, of another type or size.
  static constexpr std::size_t any_count = static_cast<std::size_t>(-1);
  const std::vector<double>& f64(const std::string& name, std::size_t count = any_count) const {
    return get(name, Type::F64, count).f64;
  }
  const std::vector<std::int64_t>& i64(const std::string& name, std::size_t count = any_count) const {
    return get(name, Type::I64, count).i64;
  }
  const std::string& text(const std::string& name) const { return get(name, Type::Text, any_count).text; }
  /// A single number.
  double f64_value(const std::string& name) const { return f64(name, 1)[0]; }
  std::int64_t i64_value(const std::string& name) const { return i64(name, 1)[0]; }

  /// The fields in the order they were written.
  const std::vector<Field>& fields() const { return fields_; }
  /// The names of the fields not read yet whose name starts with `prefix`.
  std::vector<std::string> unread(const std::string& prefix = "") const {
    std::vector<std::string> names;
    for (const Field& f : fields_)
      if (!f.read && f.name.compare(0, prefix.size(), prefix) == 0) names.push_back(f.name);
    return names;
  }
  /// Throws InvalidInput naming the fields under `prefix` that nobody read:
  /// they hold state this lgvi does not know (a newer lgvi wrote them), and
  /// continuing without it would not be the run that was checkpointed.
  void require_all_read(const std::string& prefix = "") const {
    const std::vector<std::string> names = unread(prefix);
    if (!names.empty()) throw InvalidInput(unknown_fields_message(names));
  }
  /// The message for fields nobody read.
  static std::string unknown_fields_message(const std::vector<std::string>& names) {
    std::string list;
    for (const std::string& n : names) list += (list.empty() ? "'" : ", '") + n + "'";
    return "unknown checkpoint field" + std::string(names.size() > 1 ? "s " : " ") + list +
           " (written by a newer lgvi, or by another method?); this lgvi cannot continue the run bit for bit "
           "without what it holds: resume with the lgvi that wrote the checkpoint";
  }

  static const char* type_name(Type t) {
    switch (t) {
      case Type::F64: return "f64";
      case Type::I64: return "i64";
      case Type::Text: return "text";
    }
    return "?";
  }

 private:
  Field& add(std::string name, Type type) {
    if (has(name)) throw InvalidInput("checkpoint field '" + name + "' written twice");
    fields_.push_back(Field{std::move(name), type, {}, {}, {}, false});
    return fields_.back();
  }
  const Field* find(const std::string& name) const {
    const auto it = std::find_if(fields_.begin(), fields_.end(), [&](const Field& f) { return f.name == name; });
    return it == fields_.end() ? nullptr : &*it;
  }
  const Field& get(const std::string& name, Type type, std::size_t count) const {
    const Field* f = find(name);
    if (!f) throw InvalidInput("checkpoint field '" + name + "' is missing");
    if (f->type != type)
      throw InvalidInput("checkpoint field '" + name + "' holds " + type_name(f->type) + " values, expected " +
                         type_name(type));
    if (count != any_count && f->count() != count)
      throw InvalidInput("checkpoint field '" + name + "' holds " + std::to_string(f->count()) + " values, expected " +
                         std::to_string(count));
    f->read = true;
    return *f;
  }

  std::vector<Field> fields_;
};

}  // namespace lgvi

namespace lgvi::detail {

/// Runs f, which reads a stepper's numbers in a checkpoint of versions 2 to 4
/// (the field "stepper.internal"), naming that field in its InvalidInput.
template <class F>
void reading_stepper_internal(F&& f) {
  try {
    f();
  } catch (const InvalidInput& e) {
    std::string what = e.what();
    if (what.rfind("checkpoint: ", 0) == 0) what.erase(0, 12);
    throw InvalidInput("checkpoint field 'stepper.internal': " + what);
  }
}

}  // namespace lgvi::detail
