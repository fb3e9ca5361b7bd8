// One rigid body in a potential V(x, q): the system of one body (N = 1).
//
// SingleBody<Method, P> is the N-body stepper Method<ExternalField<P>> on
// System(body), built from the body and its potential: derived from that
// stepper and adding only a constructor and two accessors for the one body
// (the same arithmetic and the same contract: SystemStepper in stepper.hpp,
// step(state, t, h) with the step size on every call). Its state is a SystemState of one body:
// SystemState(RigidBodyState) makes one, state.body(0) reads it back, and an
// observer reads i.state.body(0) and i.evaluation.body(0).
#pragma once

#include <lgvi/interaction.hpp>
#include <lgvi/potential.hpp>
#include <lgvi/rotation_solver.hpp>
#include <lgvi/stepper.hpp>
#include <lgvi/system.hpp>

#include <utility>
#include <vector>

namespace lgvi {

template <template <class> class Method, Potential P>
class SingleBody : public Method<ExternalField<P>> {
 public:
  using SystemMethod = Method<ExternalField<P>>;

  SingleBody(const RigidBody& body, P potential, SolverOptions solver = {})
      : SystemMethod(System(body), ExternalField<P>(std::vector<P>{std::move(potential)}), solver) {}

  const RigidBody& body() const { return this->system().body(0); }
  const P& body_potential() const { return this->potential().body_potential(0); }
};

}  // namespace lgvi
