#include "app/interactions/registry.hpp"

#include "app/interactions/gravity.hpp"
#include "app/interactions/lennard_jones.hpp"
#include "app/interactions/wca.hpp"

#include <algorithm>
#include <stdexcept>

namespace lgvi::app {

namespace {
/// Every interaction kind a scenario can name, in the order the reader's
/// messages list them (after "none"). A new one: its descriptor's file
/// included above and one line here.
const InteractionDescriptor* const registered[] = {
    &gravity_interaction,
    &lennard_jones_interaction,
    &wca_interaction,
};
}  // namespace

std::span<const InteractionDescriptor* const> interaction_kinds() { return registered; }

const InteractionDescriptor* find_interaction(std::string_view kind) {
  const auto* found = std::find_if(std::begin(registered), std::end(registered),
                                   [&](const InteractionDescriptor* d) { return d->kind == kind; });
  return found == std::end(registered) ? nullptr : *found;
}

double InteractionSpec::number(std::string_view key) const {
  const auto found = numbers.find(key);
  if (found == numbers.end()) throw std::logic_error("interaction." + std::string(key) + ": not read");
  return found->second;
}

const std::string& InteractionSpec::word(std::string_view key) const {
  const auto found = words.find(key);
  if (found == words.end()) throw std::logic_error("interaction." + std::string(key) + ": not read");
  return found->second;
}

std::string interaction_kind(const InteractionSpec& spec) {
  return spec.descriptor ? std::string(spec.descriptor->kind) : "none";
}

}  // namespace lgvi::app
