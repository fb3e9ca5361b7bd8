// Counter-based random numbers: a draw is a function of its indices alone (a seed, a counter such as an
// ensemble member or a sensor's sample number, a stream, a component), not of the order in which draws
// are made or of the thread or rank that makes them; so runs that draw them are repeatable and the same
// on any number of threads, ranks, and across a resume. The mixing function is SplitMix64's finalizer
// (Steele, Lea & Flood 2014).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <numbers>

namespace lgvi::counter_random {

inline std::uint64_t mix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

/// Uniform in (0, 1) from (seed, counter, stream, component, sub): 53 random bits, offset by half an ulp
/// so that neither end occurs.
inline double uniform01(std::uint64_t seed, std::int64_t counter, std::size_t stream, std::size_t component,
                        int sub) {
  const std::uint64_t key = (static_cast<std::uint64_t>(stream) << 40) ^
                            (static_cast<std::uint64_t>(component) << 8) ^ static_cast<std::uint64_t>(sub);
  const std::uint64_t h = mix(seed ^ mix(static_cast<std::uint64_t>(counter) ^ mix(key)));
  return (static_cast<double>(h >> 11) + 0.5) * 0x1p-53;
}

/// Standard normal by Box-Muller from the uniforms of sub 0 and 1.
inline double normal01(std::uint64_t seed, std::int64_t counter, std::size_t stream, std::size_t component) {
  const double u1 = uniform01(seed, counter, stream, component, 0), u2 = uniform01(seed, counter, stream, component, 1);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
}

}  // namespace lgvi::counter_random
