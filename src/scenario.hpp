// A scenario file (TOML) describes one run: body, potential, initial state,
// integrator and output. The reader rejects unknown keys, missing keys, wrong
// types and invalid values with an InvalidInput naming the key.
#pragma once

#include <lgvi/rigid_body.hpp>
#include <lgvi/rotation_solver.hpp>
#include <lgvi/state.hpp>

#include "trajectory_sink.hpp"

#include <cstdint>
#include <optional>
#include <string>

namespace lgvi::app {

enum class PotentialKind { None, Central, Uniform };
enum class Method { Hamiltonian, Lagrangian };

struct PotentialSpec {
  PotentialKind kind = PotentialKind::None;
  double mu = 0.0;                                   // central
  Vector3<double> g = Vector3<double>::Zero();     // uniform
};

struct IntegratorSpec {
  Method method = Method::Hamiltonian;
  SolverOptions solver;
  double step = 0.0;
  double duration = 0.0;
  std::int64_t steps = 0;  ///< ceil(duration / step), computed on reading
};

struct Scenario {
  std::string name;  ///< the file's stem
  RigidBody body;
  PotentialSpec potential;
  RigidBodyState initial;
  IntegratorSpec integrator;
  std::int64_t output_every = 1;
  TrajectoryFormat output_format = TrajectoryFormat::Csv;
  std::string source_text;  ///< the TOML text it was read from
};

/// Reads and validates a scenario file. Throws InvalidInput with a message
/// "FILE: KEY: what is wrong; how to fix it".
Scenario read_scenario(const std::string& path);

/// The same, from TOML text (`name` is used in messages and as the name).
Scenario parse_scenario(const std::string& toml_text, const std::string& name);

const char* to_string(PotentialKind k);
const char* to_string(Method m);

}  // namespace lgvi::app
