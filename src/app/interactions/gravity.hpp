// [interaction] kind = "gravity": mutual gravity between the bodies
// (mutual_gravity.hpp), model "balls" (default) or "inertia".
#pragma once

#include "app/interactions/registry.hpp"

#include <lgvi/mutual_gravity.hpp>

namespace lgvi::app {

inline constexpr std::string_view gravity_keys[] = {"G", "model"};

inline constinit const InteractionDescriptor gravity_interaction{
    .kind = "gravity",
    .title = "mutual gravity",
    .keys = gravity_keys,
    .read =
        [](const InteractionReader& r, InteractionSpec& spec) {
          spec.words["model"] = r.has("model") ? r.choice("model", {"balls", "inertia"}) : "balls";
          spec.numbers["G"] = r.positive("G", "the gravitational constant in the scenario's units");
        },
    .build = [](const System& system, const InteractionSpec& spec, Parallelism par) -> AnyMutualInteraction {
      if (spec.word("model") == "inertia") return MutualGravityInertia(system, spec.number("G"), par);
      return MutualGravityBalls(system, spec.number("G"), par);
    },
    .describe =
        [](const InteractionSpec& spec, Json& out) {
          out["G"] = spec.number("G");
          out["model"] = spec.word("model");
        },
    .attractive = true,
};

}  // namespace lgvi::app
