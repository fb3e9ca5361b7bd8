// The body and initial states of the paper's numerical experiment, for tests,
// benchmarks and examples (the scenario files scenarios/paper*.toml hold the
// same values for the command line).
//
// The paper's figure of the body is missing; its text says three unit-mass
// balls of radius 0.1 joined by massless rods. We place them at the corners
// of an equilateral triangle with side 1 in the body's x-y plane.
#pragma once

#include <lgvi/rigid_body.hpp>
#include <lgvi/state.hpp>

#include <cmath>

namespace lgvi::paper {

inline RigidBody three_ball_body() {
  const double s = std::sqrt(3.0) / 2.0;
  return RigidBody::from_balls({{{0.0, 0.0, 0.0}, 1.0, 0.1}, {{1.0, 0.0, 0.0}, 1.0, 0.1}, {{0.5, s, 0.0}, 1.0, 0.1}});
}

/// The paper's stated initial state: x0 = (8,0,0), q0 = e, p0 = (1,0,0)
/// (radial: the body falls through the centre's neighbourhood and leaves),
/// w0 = (1,2,3).
inline RigidBodyState radial_initial_state() {
  RigidBodyState s;
  s.x = {8.0, 0.0, 0.0};
  s.p = {1.0, 0.0, 0.0};
  s.w = {1.0, 2.0, 3.0};
  return s;
}

/// The orbit the paper's captions speak of: p0 = (0,1,0), a bound orbit of
/// period ~121 (semi-major axis ~7.2 for the centre of mass).
inline RigidBodyState orbit_initial_state() {
  RigidBodyState s = radial_initial_state();
  s.p = {0.0, 1.0, 0.0};
  return s;
}

}  // namespace lgvi::paper
