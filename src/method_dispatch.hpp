// The one place that maps a scenario's `[integrator] method` to a stepper
// class, for the run loop (simulation.cpp) and the Python package alike.
#pragma once

#include "scenario.hpp"
#include "simulation.hpp"

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

#include <string>
#include <utility>
#include <type_traits>

namespace lgvi::app {

/// Builds the N-body stepper of `sc.integrator.method` for the system
/// potential `pot` (on `par` threads) and returns f(stepper). "exact" needs
/// one free body (the reader checks; this says so again for other callers).
template <class F>
decltype(auto) with_stepper(const Scenario& sc, const ScenarioSystemPotential& pot, const Parallelism& par, F&& f) {
  const IntegratorSpec& i = sc.integrator;
  // [[forcing]] goes to the methods that discretize it (the reader refuses
  // it for the others; this says so again for other callers).
  auto add_forcing = [&](auto& stepper) {
    if (sc.forcing.empty()) return;
    if constexpr (requires { stepper.set_forcing(sc.forcing); })
      stepper.set_forcing(sc.forcing);
    else
      throw InvalidInput("forcing: integrator.method \"" + std::string(to_string(i.method)) +
                         "\" does not take [[forcing]] (lgvi and so3-lgvi do)");
  };
  auto make = [&]<template <class> class S>() -> decltype(auto) {
    S<ScenarioSystemPotential> stepper(sc.system, pot, i.solver, par);
    add_forcing(stepper);
    return f(stepper);
  };
  // The symmetric one-step methods, composed when [integrator] asks for it
  // (the reader refuses order/composition for the others).
  auto make_composable = [&]<template <class> class S>() -> decltype(auto) {
    S<ScenarioSystemPotential> stepper(sc.system, pot, i.solver, par);
    add_forcing(stepper);
    if (i.composition.is_plain()) return f(stepper);
    ComposedStepper<S<ScenarioSystemPotential>> composed(std::move(stepper), i.composition);
    return f(composed);
  };
  switch (i.method) {
    case Method::Hamiltonian: return make_composable.template operator()<LieGroupVariationalIntegrator>();
    case Method::Lagrangian: return make.template operator()<LagrangianLieGroupVariationalIntegrator>();
    case Method::So3Lgvi: return make_composable.template operator()<So3LieGroupVariationalIntegrator>();
    case Method::RattleQuaternion: return make_composable.template operator()<RattleQuaternionIntegrator>();
    case Method::Rk4Normalized: return make.template operator()<Rk4NormalizedIntegrator>();
    case Method::EulerExp: return make.template operator()<EulerExpIntegrator>();
    case Method::NoSquish: return make_composable.template operator()<NoSquishIntegrator>();
    case Method::SplittingDlm: return make_composable.template operator()<SplittingDlmIntegrator>();
    case Method::Exact:
      if (pot.is_free()) return make.template operator()<ExactFreeBodySystemStepper>();
      break;
  }
  throw InvalidInput("integrator.method: \"" + std::string(to_string(i.method)) +
                     "\" is the free body's exact flow; it needs [potential] kind = \"none\" and no [interaction]");
}

}  // namespace lgvi::app
