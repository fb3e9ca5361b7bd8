// What the explicit methods (rk4-normalized, euler-exp, no-squish,
// splitting-dlm) share behind the stepper contract of stepper.hpp: the body,
// the potential, the step, the potential evaluation at the current state
// (reused by the next step), an empty solve report, and no internal state
// for a checkpoint besides the state itself.
#pragma once

#include <lgvi/error.hpp>
#include <lgvi/stepper.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace lgvi::detail {

/// The principal moments (J_11, J_22, J_33) of a body whose frame is
/// principal (RigidBody::has_principal_axes); throws InvalidInput otherwise
/// (message names `method`).
inline Vector3<double> require_principal_axes(const RigidBody& body, const std::string& method) {
  if (!body.has_principal_axes())
    throw InvalidInput(method + ": body.inertia must be diagonal in body axes (diagonalize the body first)");
  return body.inertia().diagonal();
}

/// The base of the explicit methods on N bodies: the evaluation at the
/// current state (reused by the next step), no solves, and no internal state
/// besides the state itself (a resume re-evaluates the potential there).
template <SystemPotential I>
class ExplicitStepperBase : public StepperBase<I> {
 public:
  std::vector<double> internal_state() const { return {}; }
  void resume(const SystemState& s, double t, const std::vector<double>& internal) {
    if (!internal.empty()) throw InvalidInput(std::string("checkpoint: ") + name_ + " has no internal state");
    this->initialize(s, t);
  }
  /// No checkpoint fields: the state is all (a checkpoint of versions 2 to 4
  /// holds an empty "stepper.internal").
  void save(CheckpointFields&) const {}
  void load(const SystemState& s, double t, const CheckpointFields& in) {
    if (in.has("stepper.internal"))
      detail::reading_stepper_internal([&] { resume(s, t, in.f64("stepper.internal")); });
    else
      this->initialize(s, t);
  }

 protected:
  ExplicitStepperBase(System system, I potential, Parallelism par, const char* name)
      : StepperBase<I>(std::move(system), std::move(potential), par), name_(name) {
    require_three_moments(this->system_, name);
  }

  /// Checks the state and the evaluation after a step.
  void finish_step(const SystemState& s) { require_finite(this->system_, s, this->eval_); }

 private:
  const char* name_;
};

}  // namespace lgvi::detail
