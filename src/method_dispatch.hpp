// The one place that maps a scenario's `[integrator] method` to a stepper
// class, for the run loop (simulation.cpp) and the Python package alike.
#pragma once

#include "scenario.hpp"

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
#include <type_traits>

namespace lgvi::app {

/// Builds the stepper of `sc.integrator.method` for potential `pot` and
/// returns f(stepper). "exact" needs the free body: `is_free` says whether
/// `pot` is (a wrapper of) NoPotential, and the exact stepper then gets a
/// NoPotential.
template <bool is_free, class P, class F>
decltype(auto) with_stepper(const Scenario& sc, const P& pot, F&& f) {
  const IntegratorSpec& i = sc.integrator;
  auto make = [&]<template <class> class S>() -> decltype(auto) {
    S<P> stepper(sc.body, pot, i.step, i.solver);
    return f(stepper);
  };
  switch (i.method) {
    case Method::Hamiltonian: return make.template operator()<LieGroupVariationalIntegrator>();
    case Method::Lagrangian: return make.template operator()<LagrangianLieGroupVariationalIntegrator>();
    case Method::So3Lgvi: return make.template operator()<So3LieGroupVariationalIntegrator>();
    case Method::RattleQuaternion: return make.template operator()<RattleQuaternionIntegrator>();
    case Method::Rk4Normalized: return make.template operator()<Rk4NormalizedIntegrator>();
    case Method::EulerExp: return make.template operator()<EulerExpIntegrator>();
    case Method::NoSquish: return make.template operator()<NoSquishIntegrator>();
    case Method::SplittingDlm: return make.template operator()<SplittingDlmIntegrator>();
    case Method::Exact:
      if constexpr (is_free) {
        ExactFreeBodyStepper<NoPotential> stepper(sc.body, NoPotential{}, i.step, i.solver);
        return f(stepper);
      }
      break;
  }
  throw InvalidInput("integrator.method: \"" + std::string(to_string(i.method)) +
                     "\" is the free body's exact flow; it needs [potential] kind = \"none\"");
}

}  // namespace lgvi::app
