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

/// A stop request checked before each step (a signal flag, a time limit).
template <class F>
concept StopPredicate = std::predicate<F&>;

/// Never stops early.
struct NeverStop {
  constexpr bool operator()() const { return false; }
};

/// Advances an initialized `stepper` from step k_begin (state at
/// t0 + k_begin h) to k_end, calling `observer` after every step. Returns the
/// index reached: k_end, or an earlier one if `stop()` asked for it. A failed
/// step is rethrown as IntegrationFailure naming the step and time; `state`
/// then holds the last good state, which the observer has seen.
template <Stepper S, Observer O, StopPredicate Stop = NeverStop>
std::int64_t integrate_range(S& stepper, RigidBodyState& state, double t0, std::int64_t k_begin, std::int64_t k_end,
                             O&& observer, Stop&& stop = {}) {
  const double h = stepper.step_size();
  for (std::int64_t k = k_begin; k < k_end; ++k) {
    if (stop()) return k;
    RigidBodyState next = state;
    try {
      stepper.step(next);
    } catch (const StepFailure& f) {
      throw IntegrationFailure(k, t0 + static_cast<double>(k) * h, f);
    }
    state = next;
    observer(StepInfo{k + 1, t0 + static_cast<double>(k + 1) * h, state, stepper.evaluation(), stepper.last_solve()});
  }
  return k_end;
}

/// Runs n steps of `stepper` from `state` (updated in place): initializes the
/// stepper there, calls `observer` at k = 0 and after every step. Failures as
/// in integrate_range.
template <Stepper S, Observer O, StopPredicate Stop = NeverStop>
std::int64_t integrate_n_steps(S& stepper, RigidBodyState& state, double t0, std::int64_t n, O&& observer,
                               Stop&& stop = {}) {
  try {
    stepper.initialize(state);
  } catch (const StepFailure& f) {
    throw IntegrationFailure(0, t0, f);
  }
  const SolveReport none{};
  observer(StepInfo{0, t0, state, stepper.evaluation(), none});
  return integrate_range(stepper, state, t0, 0, n, observer, stop);
}

}  // namespace lgvi
