// The interactions a scenario's [interaction] table can name: each one a
// descriptor (its kind, the keys it takes, how they are read and checked, how
// it is built, what it writes to the summary), defined in the file of that
// interaction (gravity.hpp, lennard_jones.hpp, ... here) and listed once
// in registry.cpp. The reader, the run and the summary go through this table
// only: a new pair potential is its kernel (include/lgvi/forces/), its
// descriptor here, and its entry in registry.cpp (an include and a line).
#pragma once

#include "app/interactions/any_mutual.hpp"
#include "io/json_io.hpp"
#include "app/scenario.hpp"

#include <lgvi/parallel.hpp>
#include <lgvi/system.hpp>

#include <cstdint>
#include <initializer_list>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace lgvi::app {

/// The [interaction] table as a descriptor reads it: each method names a key
/// of the table (e.g. "epsilon") and fails with the scenario reader's message
/// naming "interaction.<key>" (a sub-table's: "interaction.pair[0].<key>").
class InteractionReader {
 public:
  virtual ~InteractionReader() = default;
  virtual bool has(std::string_view key) const = 0;
  /// The key's number (finite); fails if missing or not a number.
  virtual double number(std::string_view key) const = 0;
  /// The key's array of `count` integers; fails otherwise.
  virtual std::vector<std::int64_t> integers(std::string_view key, std::size_t count) const = 0;
  /// The tables [[interaction.<key>]] (none if absent), each taking only `keys`.
  virtual std::vector<std::unique_ptr<InteractionReader>> tables(std::string_view key,
                                                                 std::initializer_list<std::string_view> keys) const = 0;
  /// The number of site types of the scenario's bodies (the largest
  /// Ball::type; 1 where no ball has a type).
  virtual int site_types() const = 0;
  /// The key's string, one of `allowed`; fails otherwise.
  virtual std::string choice(std::string_view key, std::initializer_list<std::string_view> allowed) const = 0;
  [[noreturn]] virtual void fail(std::string_view key, const std::string& what) const = 0;

  /// The key's number, which must be > 0; `meaning` (what it is) ends the message otherwise.
  double positive(std::string_view key, const std::string& meaning) const {
    const double v = number(key);
    if (!(v > 0.0)) fail(key, "must be > 0 (" + meaning + ")");
    return v;
  }
  /// The key's number, `fallback` if it is absent, which must be >= 0; `usual` (its usual value) ends the message.
  double nonnegative_or(std::string_view key, double fallback, const std::string& usual) const {
    const double v = has(key) ? number(key) : fallback;
    if (!(v >= 0.0)) fail(key, "must be >= 0 (" + usual + ")");
    return v;
  }
};

/// One interaction kind.
struct InteractionDescriptor {
  std::string_view kind;   ///< [interaction] kind = "..."
  std::string_view title;  ///< its name in words, e.g. "Lennard-Jones" (the summary's notes)
  /// The keys it takes besides kind, in the order the reader lists them
  /// (a static array of the descriptor's file: every descriptor is
  /// constinit, built before any code runs, so no static-initialisation
  /// order can find it empty).
  std::span<const std::string_view> keys;
  /// Reads and checks the keys into spec.numbers / spec.words (defaults
  /// filled in: the summary writes what the run used).
  void (*read)(const InteractionReader& r, InteractionSpec& spec);
  /// The interaction of a scenario's system (spec as read).
  AnyMutualInteraction (*build)(const System& system, const InteractionSpec& spec, Parallelism par);
  /// Its keys in the summary's "interaction" object, after "kind".
  void (*describe)(const InteractionSpec& spec, Json& out);
  /// The potential keeps bodies apart (a repulsive core): contact is not
  /// checked during a run unless [run] on_contact says so.
  bool keeps_bodies_apart = false;
  /// Its energy is negative in every configuration (an attraction, such as
  /// gravity): U = -V grows as bodies close in, the measure of closeness
  /// that the adaptive LGVI's time transformation needs (time_transformed.hpp).
  bool attractive = false;
  /// A short-range pair interaction's reach, cutoff + Verlet skin (spec as
  /// read): a periodic box must be more than twice as long. Null for a
  /// long-range one, which a periodic box refuses.
  double (*reach)(const InteractionSpec& spec) = nullptr;
};

/// Every interaction kind, in registration order (registry.cpp).
std::span<const InteractionDescriptor* const> interaction_kinds();

/// The descriptor of `kind`, or null if there is none (also for "none").
const InteractionDescriptor* find_interaction(std::string_view kind);

}  // namespace lgvi::app
