// A method of the registry (method_registry.hpp), as the scenario model
// holds it: which stepper class runs `[integrator] method`, and what that
// class declares about itself (lgvi/methods/method_traits.hpp). Light, so that
// the scenario model does not include the steppers.
#pragma once

#include <lgvi/methods/method_traits.hpp>

#include <cstddef>
#include <span>
#include <string>
#include <vector>

namespace lgvi::app {

/// One registered method: an index into the registry's table, in display
/// order. Default-constructed, the first method ("lgvi", the default of
/// `[integrator] method`).
class Method {
 public:
  constexpr Method() = default;

  /// The method called `name`; throws InvalidInput "key 'WHERE': "NAME" is
  /// not one of "lgvi", ..., "exact"" otherwise.
  static Method named(const std::string& name, const std::string& where = "integrator.method");

  /// Every registered method's traits, in display order.
  static std::span<const MethodTraits> all();

  const MethodTraits& traits() const { return all()[index_]; }
  const char* name() const { return traits().name; }
  std::size_t index() const { return index_; }

  bool operator==(const Method&) const = default;
  /// Registry (display) order.
  bool operator<(const Method& other) const { return index_ < other.index_; }

 private:
  explicit constexpr Method(std::size_t index) : index_(index) {}
  std::size_t index_ = 0;
};

/// The registered methods as `--help` lists them: one line each with the
/// name, the order and what the method declares (method_traits.hpp).
std::string method_table();

/// The names of the registered methods whose traits satisfy `pred`, in
/// display order, joined by `separator` and before the last by `last`
/// (quoted in "..." if `quoted`): the lists in the reader's messages.
template <class Pred>
std::string method_names_where(Pred pred, const char* separator, const char* last, bool quoted) {
  std::vector<const char*> names;
  for (const MethodTraits& t : Method::all())
    if (pred(t)) names.push_back(t.name);
  std::string out;
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (i > 0) out += i + 1 == names.size() ? last : separator;
    if (quoted) out += '"';
    out += names[i];
    if (quoted) out += '"';
  }
  return out;
}

}  // namespace lgvi::app
