// The integrate loop, kept apart from the system (potential), the stepper
// and the observer, in the manner of Boost.Odeint. Time is t0 + k h, never
// accumulated; a stepper with a clock of its own (a time-transformed one,
// time_transformed.hpp, whose h is a fictitious step) reports the physical
// time through time(), and the observer sees that.
#pragma once

#include <lgvi/error.hpp>
#include <lgvi/lgvi.hpp>
#include <lgvi/parallel.hpp>
#include <lgvi/single_body.hpp>  // not used here: for programs of one body, which include this header
#include <lgvi/state.hpp>
#include <lgvi/stepper.hpp>
#include <lgvi/system.hpp>

#include <concepts>
#include <cstdint>
#include <utility>

namespace lgvi {

/// What the observer of a run sees at each step k = 0..n (one body:
/// state.body(0), evaluation.body(0)).
struct SystemStepInfo {
  std::int64_t k;
  double t;
  const SystemState& state;
  const SystemEvaluation& evaluation;  ///< V and every body's F, M at `state`
  const SolveReport& solve;            ///< the solves that produced `state` (empty at k = 0)
  double work = 0.0;  ///< the work done by the stepper's forcing since it was initialized (forcing.hpp)
};

/// A stop request checked before each step (a signal flag, a time limit).
template <class F>
concept StopPredicate = std::predicate<F&>;

/// Never stops early.
struct NeverStop {
  constexpr bool operator()() const { return false; }
};

namespace detail {
/// The forcing's work of a stepper that has a forcing, 0 otherwise.
template <class S>
double forcing_work(const S& s) {
  if constexpr (requires { s.forcing_work(); }) return s.forcing_work();
  else return 0.0;
}
/// The time the observer sees after a step: the stepper's own physical
/// time where it keeps one (time_transformed.hpp), else t0 + k h.
template <class S>
double physical_time(const S& s, double t) {
  if constexpr (requires { { s.time() } -> std::convertible_to<double>; }) return s.time();
  else return t;
}
/// One step from `state` into `next` (whose contents before are not read):
/// the stepper's step_from where it has one (it writes the new state from
/// the old without a copy first), else a copy (copy_state, stepper.hpp) and
/// an in-place step.
template <class S>
void step_into_next(S& s, const SystemState& state, SystemState& next, double t, double h) {
  if constexpr (requires { s.step_from(state, next, t, h); }) {
    s.step_from(state, next, t, h);
  } else {
    copy_state(s, next, state);
    s.step(next, t, h);
  }
}
}  // namespace detail

/// Advances an initialized `stepper` from step k_begin (state at
/// t0 + k_begin h) to k_end, calling `observer` after every step. Returns the
/// index reached: k_end, or an earlier one if `stop()` asked for it. A failed
/// step is rethrown as IntegrationFailure naming the step and time; `state`
/// then holds the last good state, which the observer has seen. h must be
/// finite and > 0 (InvalidInput otherwise, before any step).
template <SystemStepper S, class O, StopPredicate Stop = NeverStop>
std::int64_t integrate_range(S& stepper, SystemState& state, double t0, double h, std::int64_t k_begin,
                             std::int64_t k_end, O&& observer, Stop&& stop = {}) {
  detail::require_valid_step(h);
  SystemState next = state;  // assigned, not constructed, in the loop: no allocation per step
  for (std::int64_t k = k_begin; k < k_end; ++k) {
    if (stop()) return k;
    const double t = t0 + static_cast<double>(k) * h;
    try {
      detail::step_into_next(stepper, state, next, t, h);
    } catch (const StepFailure& f) {
      throw IntegrationFailure(k, detail::physical_time(stepper, t), f);
    }
    std::swap(state, next);
    observer(SystemStepInfo{k + 1, detail::physical_time(stepper, t0 + static_cast<double>(k + 1) * h), state,
                            stepper.evaluation(), stepper.last_solve(), detail::forcing_work(stepper)});
  }
  return k_end;
}

/// Runs n steps of size h from `state` (updated in place): initializes the
/// stepper there, calls `observer` at k = 0 and after every step. Failures as
/// in integrate_range.
template <SystemStepper S, class O, StopPredicate Stop = NeverStop>
std::int64_t integrate_n_steps(S& stepper, SystemState& state, double t0, double h, std::int64_t n, O&& observer,
                               Stop&& stop = {}) {
  detail::require_valid_step(h);
  try {
    stepper.initialize(state, t0);
  } catch (const StepFailure& f) {
    throw IntegrationFailure(0, t0, f);
  }
  const SolveReport none{};
  observer(SystemStepInfo{0, t0, state, stepper.evaluation(), none});
  return integrate_range(stepper, state, t0, h, 0, n, observer, stop);
}

}  // namespace lgvi
