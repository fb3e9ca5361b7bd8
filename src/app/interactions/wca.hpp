// [interaction] kind = "wca": Weeks-Chandler-Andersen (forces/wca.hpp),
// epsilon and sigma, cutoff fixed at 2^(1/6) sigma, Verlet list skin
// (default 0.3 sigma).
#pragma once

#include "app/interactions/registry.hpp"

#include <lgvi/forces/wca.hpp>

namespace lgvi::app {

inline constexpr std::string_view wca_keys[] = {"epsilon", "sigma", "skin"};

inline constinit const InteractionDescriptor wca_interaction{
    .kind = "wca",
    .title = "Weeks-Chandler-Andersen",
    .keys = wca_keys,
    .read =
        [](const InteractionReader& r, InteractionSpec& spec) {
          const double epsilon = r.positive("epsilon", "the depth of the potential well");
          const double sigma = r.positive("sigma", "where the potential is zero");
          const double skin = r.nonnegative_or("skin", 0.3 * sigma, "0.3 sigma is usual");
          spec.numbers = {{"epsilon", epsilon}, {"sigma", sigma}, {"skin", skin}};
        },
    .build = [](const System& system, const InteractionSpec& spec, Parallelism par) -> AnyMutualInteraction {
      return WeeksChandlerAndersen(system, spec.number("epsilon"), spec.number("sigma"), par, spec.number("skin"));
    },
    .describe =
        [](const InteractionSpec& spec, Json& out) {
          out["epsilon"] = spec.number("epsilon");
          out["sigma"] = spec.number("sigma");
          out["cutoff"] = WcaKernel(spec.number("epsilon"), spec.number("sigma")).cutoff();  // 2^(1/6) sigma
          out["skin"] = spec.number("skin");
        },
    .keeps_bodies_apart = true,
    .reach =
        [](const InteractionSpec& spec) {
          return WcaKernel(spec.number("epsilon"), spec.number("sigma")).cutoff() + spec.number("skin");
        },
};

}  // namespace lgvi::app
