// The method registry: every stepper class that `[integrator] method` can
// name, and the one place that builds the stepper of a scenario's method for
// the run loop (simulation.cpp), lgvi compare and the Python package alike.
// A new method is its file in include/lgvi/methods/ (the class, with its
// `static constexpr MethodTraits traits`) and one entry in RegisteredMethods.
#pragma once

#include "app/method.hpp"
#include "app/scenario.hpp"
#include "app/simulation.hpp"

#include <lgvi/composition.hpp>
#include <lgvi/error.hpp>
#include <lgvi/exact_free_body.hpp>
#include <lgvi/lgvi.hpp>
#include <lgvi/methods/euler_exp.hpp>
#include <lgvi/methods/no_squish.hpp>
#include <lgvi/methods/rattle_quaternion.hpp>
#include <lgvi/methods/rk4_normalized.hpp>
#include <lgvi/methods/so3_lgvi.hpp>
#include <lgvi/methods/splitting_dlm.hpp>
#include <lgvi/time_transformed.hpp>

#include <array>
#include <cstddef>
#include <limits>
#include <string>
#include <string_view>
#include <utility>

namespace lgvi::app {

template <template <class> class... S>
struct StepperList {};

/// Every method, in display order; the first is the default.
using RegisteredMethods =
    StepperList<LieGroupVariationalIntegrator, LagrangianLieGroupVariationalIntegrator, So3LieGroupVariationalIntegrator,
                RattleQuaternionIntegrator, Rk4NormalizedIntegrator, EulerExpIntegrator, NoSquishIntegrator,
                SplittingDlmIntegrator, ExactFreeBodyStepper>;

namespace detail {

template <template <class> class... S>
constexpr std::array<MethodTraits, sizeof...(S)> traits_of(StepperList<S...> /*list*/) {
  return {S<ScenarioSystemPotential>::traits...};
}

/// make.template operator()<S>() for the index-th class S of the list.
template <std::size_t K, template <class> class S, template <class> class... Rest, class Make>
decltype(auto) dispatch_at(std::size_t index, Make& make) {
  if constexpr (sizeof...(Rest) > 0) {
    if (index != K) return dispatch_at<K + 1, Rest...>(index, make);
  }
  return make.template operator()<S>();
}

template <template <class> class... S, class Make>
decltype(auto) dispatch(StepperList<S...> /*list*/, std::size_t index, Make& make) {
  return dispatch_at<0, S...>(index, make);
}

}  // namespace detail

/// The registered methods' traits, in the order of RegisteredMethods.
inline constexpr auto registered_method_traits = detail::traits_of(RegisteredMethods{});

/// Builds the N-body stepper of `sc.integrator.method` for the system
/// potential `pot` (moved into it; on `par` threads), composed if [integrator] asks for it,
/// or the adaptive LGVI if it asks for a time transformation, and returns
/// f(stepper). The reader refuses what a method's traits exclude (forcing,
/// composition, a free-body-only method on another system) and what the
/// time transformation does not take; this says so again for other callers.
template <class F>
decltype(auto) with_stepper(const Scenario& sc, ScenarioSystemPotential pot, const Parallelism& par, F&& f) {
  const IntegratorSpec& i = sc.integrator;
  if (i.adaptive()) {
    if (!sc.forcing.empty() || i.method.index() != 0)
      throw InvalidInput("integrator.time_transform: the adaptive LGVI takes no forcing and is method \"lgvi\"");
    TimeTransformedLieGroupVariationalIntegrator<ScenarioSystemPotential> stepper(
        sc.system, std::move(pot),
        TimeTransformOptions{i.monitor_scale, i.exact_finish ? i.duration : std::numeric_limits<double>::infinity()},
        i.solver, par, i.composition);
    return f(stepper);
  }
  auto make = [&]<template <class> class S>() -> decltype(auto) {
    using Stepper = S<ScenarioSystemPotential>;
    constexpr MethodTraits traits = Stepper::traits;
    static_assert(traits.accepts_forcing == requires(Stepper& s, const ForcingSet& forcing) { s.set_forcing(forcing); },
                  "a method's traits.accepts_forcing says whether it has set_forcing");
    if (traits.free_body_only && !pot.is_free())
      throw InvalidInput("integrator.method: \"" + std::string(traits.name) +
                         "\" is the free body's exact flow; it needs [potential] kind = \"none\" and no [interaction]");
    Stepper stepper(sc.system, std::move(pot), i.solver, par);  // (one method is made: pot moves once)
    if (!sc.forcing.empty()) {
      if constexpr (traits.accepts_forcing)
        stepper.set_forcing(sc.forcing);
      else
        throw InvalidInput("forcing: integrator.method \"" + std::string(traits.name) +
                           "\" does not take [[forcing]] (" +
                           method_names_where([](const MethodTraits& t) { return t.accepts_forcing; }, ", ",
                                              " and ", false) +
                           " do)");
    }
    if (!sc.wheel_torques.empty() || sc.wheel_control) {  // the reader allows them with "lgvi" only
      if constexpr (requires(Stepper& s, std::vector<WheelTorque> u) { s.set_wheel_torques(std::move(u)); }) {
        stepper.set_wheel_torques(sc.wheel_torques);
        if (sc.wheel_control) stepper.set_wheel_control(*sc.wheel_control);
      } else {
        throw InvalidInput("forcing: integrator.method \"" + std::string(traits.name) + "\" turns no reaction wheels");
      }
    }
    if constexpr (traits.composable()) {
      if (!i.composition.is_plain()) {
        ComposedStepper<Stepper> composed(std::move(stepper), i.composition);
        return f(composed);
      }
    }
    return f(stepper);
  };
  return detail::dispatch(RegisteredMethods{}, i.method.index(), make);
}

}  // namespace lgvi::app
