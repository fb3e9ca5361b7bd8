// The method registry's table (method.hpp, method_registry.hpp).
#include "app/method_registry.hpp"

#include <lgvi/error.hpp>

#include <algorithm>
#include <string>
#include <string_view>

#include "io/toml_reader.hpp"

namespace lgvi::app {

namespace {

constexpr bool unique_names() {
  for (std::size_t a = 0; a < registered_method_traits.size(); ++a)
    for (std::size_t b = a + 1; b < registered_method_traits.size(); ++b)
      if (std::string_view(registered_method_traits[a].name) == registered_method_traits[b].name) return false;
  return true;
}
static_assert(unique_names(), "two registered methods have the same name");
static_assert(std::string_view(registered_method_traits[0].name) == "lgvi",
              "the first registered method is the default of [integrator] method");

}  // namespace

std::span<const MethodTraits> Method::all() { return registered_method_traits; }

Method Method::named(const std::string& name, const std::string& where) {
  std::string list;
  for (std::size_t k = 0; k < registered_method_traits.size(); ++k) {
    if (name == registered_method_traits[k].name) return Method(k);
    list += (list.empty() ? "\"" : ", \"") + std::string(registered_method_traits[k].name) + "\"";
  }
  throw InvalidInput("key '" + where + "': \"" + printable(name) + "\" is not one of " + list);
}

std::string method_table() {
  std::string out = "Methods ([integrator] method, --methods NAME or NAME:ORDER):\n";
  std::size_t width = 0;
  for (const MethodTraits& t : Method::all()) width = std::max(width, std::string_view(t.name).size() + 2);
  for (const MethodTraits& t : Method::all()) {
    std::string props = t.order == 0 ? "exact" : "order " + std::to_string(t.order);
    if (t.two_step) props += ", two-step";
    props += t.implicit ? ", implicit" : ", explicit";
    if (t.composable()) props += ", composable to 4/6/8";
    if (t.accepts_forcing) props += ", [[forcing]]";
    if (t.needs_principal_axes) props += ", principal axes only";
    if (t.free_body_only) props += ", one free body only";
    const std::string name(t.name);
    out.append("  ").append(name).append(width - name.size(), ' ').append(props).append("\n");
    out.append(2 + width, ' ').append(t.summary).append("\n");
  }
  return out + "\n";
}

}  // namespace lgvi::app
