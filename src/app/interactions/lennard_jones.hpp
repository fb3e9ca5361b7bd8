// [interaction] kind = "lennard-jones" (forces/lennard_jones.hpp): epsilon,
// sigma, cutoff (default 2.5 sigma), Verlet list skin (default 0.3 sigma);
// with site types (Ball::type, a data file's atom types), per pair of types
// [[interaction.pair]] types = [i, j], epsilon, sigma, and `mixing` for the
// pairs not given.
//
// Coefficients per pair of types, as LAMMPS's lj/cut with pair_modify mix:
// epsilon and sigma at the top are every type's own (i, i) unless a
// [[interaction.pair]] gives it; a pair (i, j), i != j, not given is mixed
// from (i, i) and (j, j): eps_ij = sqrt(eps_i eps_j) and sigma_ij =
// sqrt(sigma_i sigma_j) ("geometric", the default) or (sigma_i + sigma_j) / 2
// ("arithmetic", Lorentz-Berthelot). One cutoff for every pair, each pair's
// energy shifted to zero there.
#pragma once

#include "app/interactions/registry.hpp"

#include <lgvi/forces/lennard_jones.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <optional>

namespace lgvi::app {

inline constexpr std::string_view lennard_jones_keys[] = {"epsilon", "sigma", "cutoff", "skin", "mixing", "pair"};

namespace lennard_jones_detail {

/// The coefficients of every pair of the scenario's site types into
/// spec.type_pairs (first <= second), given or mixed; empty if the scenario
/// has one type and no [[interaction.pair]].
inline void read_type_pairs(const InteractionReader& r, InteractionSpec& spec, std::optional<double> epsilon,
                            std::optional<double> sigma) {
  const int types = r.site_types();
  const auto tables = r.tables("pair", {"types", "epsilon", "sigma"});
  if (types == 1 && tables.empty()) return;
  const std::string mixing = r.has("mixing") ? r.choice("mixing", {"geometric", "arithmetic"}) : "geometric";
  spec.words["mixing"] = mixing;
  const auto n = static_cast<std::size_t>(types);
  std::vector<std::optional<std::pair<double, double>>> given(n * n);  // (eps, sigma) per (i, j), 0-based
  for (const auto& t : tables) {
    std::vector<std::int64_t> ij = t->integers("types", 2);
    for (std::int64_t v : ij)
      if (v < 1 || v > types)
        t->fail("types", fmt::format("type {} is not a site type of this scenario's bodies (1..{}: the balls' "
                                     "`type`, or a data file's atom types)",
                                     v, types));
    std::sort(ij.begin(), ij.end());
    const auto at = static_cast<std::size_t>(ij[0] - 1) * n + static_cast<std::size_t>(ij[1] - 1);
    if (given[at]) t->fail("types", fmt::format("the pair ({}, {}) is given twice", ij[0], ij[1]));
    given[at] = std::pair(t->positive("epsilon", "the depth of the pair's well"),
                          t->positive("sigma", "where the pair's potential is zero"));
  }
  std::vector<std::pair<double, double>> own(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (given[i * n + i]) own[i] = *given[i * n + i];
    else if (epsilon && sigma) own[i] = {*epsilon, *sigma};
    else
      r.fail("pair", fmt::format("site type {} has no coefficients: give [[interaction.pair]] types = [{}, {}] with "
                                 "epsilon and sigma, or epsilon and sigma in [interaction] for every type",
                                 i + 1, i + 1, i + 1));
  }
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = i; j < n; ++j) {
      TypePairSpec p;
      p.first = static_cast<int>(i + 1);
      p.second = static_cast<int>(j + 1);
      std::pair<double, double> c;
      if (given[i * n + j]) c = *given[i * n + j];
      else if (i == j) c = own[i];
      else {
        p.mixed = true;
        c.first = std::sqrt(own[i].first * own[j].first);
        c.second = mixing == "geometric" ? std::sqrt(own[i].second * own[j].second)
                                         : 0.5 * (own[i].second + own[j].second);
      }
      p.numbers = {{"epsilon", c.first}, {"sigma", c.second}};
      spec.type_pairs.push_back(std::move(p));
    }
}

/// The largest sigma of the pairs (or the one sigma).
inline double largest_sigma(const InteractionSpec& spec) {
  double s = spec.numbers.contains("sigma") ? spec.number("sigma") : 0.0;
  for (const TypePairSpec& p : spec.type_pairs) s = std::max(s, p.numbers.at("sigma"));
  return s;
}

/// Whether every pair has the same coefficients (then one kernel serves all).
inline bool uniform(const InteractionSpec& spec) {
  return std::all_of(spec.type_pairs.begin(), spec.type_pairs.end(),
                     [&](const TypePairSpec& p) { return p.numbers == spec.type_pairs.front().numbers; });
}

}  // namespace lennard_jones_detail

inline constinit const InteractionDescriptor lennard_jones_interaction{
    .kind = "lennard-jones",
    .title = "Lennard-Jones",
    .keys = lennard_jones_keys,
    .read =
        [](const InteractionReader& r, InteractionSpec& spec) {
          namespace lj = lennard_jones_detail;
          std::optional<double> epsilon, sigma;
          // One set of coefficients for all (required without [[interaction.pair]]), or every type's own.
          if (!r.has("pair") || r.has("epsilon") || r.has("sigma")) {
            epsilon = r.positive("epsilon", "the depth of the potential well");
            sigma = r.positive("sigma", "where the potential is zero");
            spec.numbers = {{"epsilon", *epsilon}, {"sigma", *sigma}};
          }
          if (r.has("mixing") && !r.has("pair") && r.site_types() == 1)
            r.fail("mixing", "mixes the coefficients of different site types; this scenario has one type and no "
                             "[[interaction.pair]]");
          lj::read_type_pairs(r, spec, epsilon, sigma);
          if (!sigma && !r.has("cutoff"))
            r.fail("cutoff", "missing: with coefficients per pair of types, give the one cutoff of every pair "
                             "(2.5 times the largest sigma is usual)");
          const double cutoff = r.has("cutoff") ? r.number("cutoff") : 2.5 * *sigma;
          const double largest = lj::largest_sigma(spec);
          if (!(cutoff > largest))
            r.fail("cutoff", spec.type_pairs.empty()
                                 ? std::string("must be > sigma (2.5 sigma is usual); the energy is shifted to 0 there")
                                 : fmt::format("must be > the sigma of every pair (the largest is {}; 2.5 sigma is "
                                               "usual); the energy is shifted to 0 there",
                                               largest));
          const double skin = r.nonnegative_or("skin", 0.3 * largest, "0.3 sigma is usual");
          spec.numbers["cutoff"] = cutoff;
          spec.numbers["skin"] = skin;
        },
    .build = [](const System& system, const InteractionSpec& spec, Parallelism par) -> AnyMutualInteraction {
      namespace lj = lennard_jones_detail;
      if (spec.type_pairs.empty() || lj::uniform(spec)) {
        const auto& c = spec.type_pairs.empty() ? spec.numbers : spec.type_pairs.front().numbers;
        return LennardJones(system, c.at("epsilon"), c.at("sigma"), spec.number("cutoff"), par, spec.number("skin"));
      }
      const auto types = static_cast<std::uint32_t>(spec.type_pairs.back().second);
      std::vector<double> epsilon(std::size_t{types} * types), sigma(epsilon.size());
      for (const TypePairSpec& p : spec.type_pairs) {
        const auto i = static_cast<std::size_t>(p.first - 1), j = static_cast<std::size_t>(p.second - 1);
        epsilon[i * types + j] = epsilon[j * types + i] = p.numbers.at("epsilon");
        sigma[i * types + j] = sigma[j * types + i] = p.numbers.at("sigma");
      }
      return LennardJonesTypes(system, LennardJonesTypesKernel(types, epsilon, sigma, spec.number("cutoff")),
                               spec.number("skin"), par);
    },
    .describe =
        [](const InteractionSpec& spec, Json& out) {
          for (const char* key : {"epsilon", "sigma", "cutoff", "skin"})
            if (spec.numbers.contains(key)) out[key] = spec.number(key);
          if (spec.type_pairs.empty()) return;
          out["mixing"] = spec.word("mixing");
          Json pairs = Json::array();
          for (const TypePairSpec& p : spec.type_pairs)
            pairs.push_back({{"types", {p.first, p.second}},
                             {"epsilon", p.numbers.at("epsilon")},
                             {"sigma", p.numbers.at("sigma")},
                             {"mixed", p.mixed}});
          out["pairs"] = std::move(pairs);
        },
    .keeps_bodies_apart = true,
    .reach = [](const InteractionSpec& spec) { return spec.number("cutoff") + spec.number("skin"); },
};

}  // namespace lgvi::app
