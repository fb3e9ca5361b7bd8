// The integrate loop, kept apart from the system (potential), the stepper
// and the observer, in the manner of Boost.Odeint. Time is t0 + k h, never
// accumulated.
#pragma once

#include <lgvi/error.hpp>
#include <lgvi/lgvi.hpp>
#include <lgvi/state.hpp>

#include <concepts>
#include <cstdint>

namespace lgvi {

/// What the observer sees at each step k = 0..n.
struct StepInfo {
  std::int64_t k;
  double t;
  const RigidBodyState& state;
  const PotentialEvaluation& evaluation;  ///< V, F, M at `state`
  const SolveReport& solve;               ///< the solve that produced `state` (empty at k = 0)
};

template <class O>
concept Observer = std::invocable<O&, const StepInfo&>;

/// Runs n steps of `stepper` from `state` (updated in place), calling
/// `observer` at k = 0 (after initialize) and after every step. A failed step
/// is rethrown as IntegrationFailure naming the step and time; `state` then
/// holds the last good state, which the observer has seen.
template <Stepper S, Observer O>
void integrate_n_steps(S& stepper, RigidBodyState& state, double t0, std::int64_t n, O&& observer) {
  const double h = stepper.step_size();
  try {
    stepper.initialize(state);
  } catch (const StepFailure& f) {
    throw IntegrationFailure(0, t0, f);
  }
  const SolveReport none{};
  observer(StepInfo{0, t0, state, stepper.evaluation(), none});
  for (std::int64_t k = 0; k < n; ++k) {
    RigidBodyState next = state;
    try {
      stepper.step(next);
    } catch (const StepFailure& f) {
      throw IntegrationFailure(k, t0 + static_cast<double>(k) * h, f);
    }
    state = next;
    observer(StepInfo{k + 1, t0 + static_cast<double>(k + 1) * h, state, stepper.evaluation(), stepper.last_solve()});
  }
}

}  // namespace lgvi
