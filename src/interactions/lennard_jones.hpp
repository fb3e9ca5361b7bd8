// [interaction] kind = "lennard-jones" (forces/lennard_jones.hpp): epsilon,
// sigma, cutoff (default 2.5 sigma), Verlet list skin (default 0.3 sigma).
#pragma once

#include "interactions/registry.hpp"

#include <lgvi/forces/lennard_jones.hpp>

namespace lgvi::app {

inline constexpr std::string_view lennard_jones_keys[] = {"epsilon", "sigma", "cutoff", "skin"};

inline constinit const InteractionDescriptor lennard_jones_interaction{
    .kind = "lennard-jones",
    .title = "Lennard-Jones",
    .keys = lennard_jones_keys,
    .read =
        [](const InteractionReader& r, InteractionSpec& spec) {
          const double epsilon = r.positive("epsilon", "the depth of the potential well");
          const double sigma = r.positive("sigma", "where the potential is zero");
          const double cutoff = r.has("cutoff") ? r.number("cutoff") : 2.5 * sigma;
          if (!(cutoff > sigma))
            r.fail("cutoff", "must be > sigma (2.5 sigma is usual); the energy is shifted to 0 there");
          const double skin = r.nonnegative_or("skin", 0.3 * sigma, "0.3 sigma is usual");
          spec.numbers = {{"epsilon", epsilon}, {"sigma", sigma}, {"cutoff", cutoff}, {"skin", skin}};
        },
    .build = [](const System& system, const InteractionSpec& spec, Parallelism par) -> AnyMutualInteraction {
      return LennardJones(system, spec.number("epsilon"), spec.number("sigma"), spec.number("cutoff"), par,
                          spec.number("skin"));
    },
    .describe =
        [](const InteractionSpec& spec, Json& out) {
          for (const char* key : {"epsilon", "sigma", "cutoff", "skin"}) out[key] = spec.number(key);
        },
    .keeps_bodies_apart = true,
    .reach = [](const InteractionSpec& spec) { return spec.number("cutoff") + spec.number("skin"); },
};

}  // namespace lgvi::app
