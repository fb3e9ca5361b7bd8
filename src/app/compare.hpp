// `lgvi compare`: the methods side by side on one scenario, honestly measured.
//
//  * Work-precision: each method over a ladder of steps h, h/2, ... to a time
//    T; the error of the final state against a reference (the exact flow for
//    a free body, else RK4 of the continuous equations with a step 8 times
//    below the finest), against wall time (median and quartiles of repeated runs after an untimed
//    warm-up) and against potential evaluations (for a free body: wall time only; the exact flow is
//    the reference and not ranked). The error is split into position, attitude angle, momentum and
//    angular velocity, each relative to the problem's size.
//  * A system ([[bodies]], several bodies or an [interaction]) is compared against lgvi composed to
//    order 8 at a step found by halving until the final state stops changing (the change reached is
//    reported, DIR/reference.json); its errors are per-body maxima, with the system's energy and
//    momentum errors beside them; a method that cannot run the system (exact: one free body only;
//    no-squish, splitting-dlm: principal axes; only lgvi and so3-lgvi take a forcing) is a table row
//    saying why, not a failed comparison.
//  * The adaptive LGVI ("lgvi+tt", "lgvi:4+tt"; the default when the scenario has time_transform):
//    its ladder is in epsilon, each run ending at T exactly (exact_finish), so fixed and adaptive
//    steps meet on the same error-against-evaluations axes. Where it is compared, or the scenario
//    is adaptive, the references are time-transformed too: RK4 of the continuous equations in the
//    fictitious time (ContinuousEquations::rk4_time_transformed, the runs' monitor) for one body,
//    lgvi:8+tt for a system: a fixed-step reference cannot follow a close pass.
//  * Long-time behaviour at equal cost: every method given the same number of
//    potential evaluations per unit time (a method needing e evaluations per
//    step runs with step e h), out to `long_steps` steps of h; energy error,
//    |q| - 1 and momentum error against time.
//  * Tables (CSV and Markdown) and PNG figures (matplotlib, lgvi.compare_plot).
//
// Every run goes through simulate(), the code `lgvi run` uses.
#pragma once

#include "app/scenario.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace lgvi::app {

/// A method as `--methods` names it: "lgvi", or "lgvi:4" for the method
/// composed to order 4 (composition.hpp; symmetric one-step methods only);
/// "lgvi+tt" or "lgvi:4+tt" for the adaptive LGVI (time_transform =
/// "potential", time_transformed.hpp), whose step in the ladder is epsilon.
struct MethodChoice {
  Method method;  ///< default: "lgvi"
  int order = 2;
  bool time_transformed = false;  ///< the adaptive LGVI ("+tt")
  std::string name() const;
  bool operator<(const MethodChoice& o) const {
    if (method != o.method) return method < o.method;
    return order != o.order ? order < o.order : time_transformed < o.time_transformed;
  }
  bool operator==(const MethodChoice& o) const {
    return method == o.method && order == o.order && time_transformed == o.time_transformed;
  }
};

/// "NAME", "NAME:ORDER", "lgvi+tt" or "lgvi:ORDER+tt"; throws InvalidInput naming `--methods`.
MethodChoice method_choice_from_string(const std::string& text);

/// The methods compared when `--methods` is not given: lgvi and lgvi-lagrangian; for an adaptive
/// scenario (time_transform), its adaptive step and the fixed step at its order (e.g. lgvi:4+tt, lgvi:4).
std::vector<MethodChoice> default_method_choices(const Scenario& scenario);

struct CompareOptions {
  std::vector<MethodChoice> methods;
  std::string out_dir;
  int ladder = 5;                     ///< steps h0, h0/2, ..., h0/2^(ladder-1)
  double ladder_from = 0.0;           ///< h0 (0: the scenario's step h); the long runs keep h
  double error_time = 0.0;            ///< T of the work-precision runs (0: min(duration, 1e4 h))
  std::int64_t long_steps = 1000000;  ///< length of the long runs, in steps of h
  double timing_budget = 0.2;         ///< seconds of repeated runs per timed ladder point (at least 3 runs)
  bool figures = true;
  bool quiet = false;
  bool force = false;                 ///< write into an existing non-empty out_dir
};

/// Runs the comparison and writes DIR/{work_precision.csv, long_time.csv,
/// comparison.csv, comparison.md, *.png} and, for a system, DIR/reference.json.
/// Returns the exit status; throws InvalidInput on bad options and
/// std::runtime_error when a system's reference does not converge.
int compare_methods(const Scenario& scenario, const CompareOptions& options);

}  // namespace lgvi::app
