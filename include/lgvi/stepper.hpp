// The contract of a one-step method on a system of bodies, Odeint-style: the
// stepper receives the state, the time and the step size on every call, so a
// composition method can call it with sub-steps gamma h and a forcing can read
// t. The system and its potential are the stepper's; the integrate loop
// (integrate.hpp) and the observer are kept apart.
//
// Evaluations: a stepper evaluates the potential once at initialize() and
// then once per step, at the new state; that evaluation serves the next step
// (it depends on the state alone, not on h, so it stays valid when the next
// call has another h).
#pragma once

#include <lgvi/error.hpp>
#include <lgvi/interaction.hpp>
#include <lgvi/parallel.hpp>
#include <lgvi/rotation_solver.hpp>
#include <lgvi/system.hpp>

#include <cmath>
#include <concepts>
#include <string>
#include <vector>

namespace lgvi {

/// A stepper for N bodies.
///  * initialize(state, t): evaluate the potential at `state` (time t);
///  * step(state, t, h): advance `state` from t to t + h in place;
///  * evaluation(): V, forces and torques at the current state, no extra cost;
///  * last_solve(): the implicit solves of the last step (zero if explicit);
///  * internal_state() / resume(state, t, internal): what a checkpoint keeps
///    besides the state for a bit-identical continuation.
template <class S>
concept SystemStepper = requires(S& s, const S& cs, SystemState& state, double t, double h,
                                 const std::vector<double>& internal) {
  { s.initialize(state, t) };
  { s.step(state, t, h) };
  { cs.evaluation() } -> std::convertible_to<const SystemEvaluation&>;
  { cs.last_solve() } -> std::convertible_to<SolveReport>;
  { cs.internal_state() } -> std::convertible_to<std::vector<double>>;
  { s.resume(state, t, internal) };
  { cs.system() } -> std::convertible_to<const System&>;
};

namespace detail {

inline void require_valid_step(double h) {
  if (!(std::isfinite(h) && h > 0.0))
    throw InvalidInput("integrator.step: must be a finite number > 0, got " + std::to_string(h));
}

/// "body a ("name"): " for systems of more than one body, "" for one body
/// (whose messages stay as they were).
inline std::string body_prefix(const System& sys, std::size_t a) {
  if (sys.size() == 1) return {};
  return "body " + std::to_string(a) + " (\"" + sys.name(a) + "\"): ";
}

/// Runs f(a) for every body on the stepper's threads; a StepFailure of a
/// body is reported with the body named (systems of more than one body).
template <class F>
void for_each_body(const System& sys, const Parallelism& par, F&& f) {
  parallel_for(sys.size(), par, [&](std::size_t a) {
    try {
      f(a);
    } catch (const StepFailure& e) {
      if (sys.size() == 1) throw;
      throw StepFailure(body_prefix(sys, a) + e.what(), e.hint());
    }
  });
}

/// Throws StepFailure if the state or the evaluation is not finite. One test
/// on a sum per body: a NaN or infinity anywhere makes it non-finite
/// (inf - inf is NaN), so the common case costs one branch per body.
inline void require_finite(const System& sys, const SystemState& s, const SystemEvaluation& e) {
  for (std::size_t a = 0; a < s.size(); ++a) {
    const double sum = s.x[a].sum() + s.q[a].coefficient_sum() + s.p[a].sum() + s.w[a].sum() + e.energy +
                       e.force[a].sum() + e.torque[a].sum();
    if (std::isfinite(sum)) continue;
    if (!s.body(a).all_finite())
      throw StepFailure(body_prefix(sys, a) + "the state became non-finite", "try a smaller step");
    if (!(std::isfinite(e.energy) && e.force[a].allFinite() && e.torque[a].allFinite()))
      throw StepFailure(body_prefix(sys, a) +
                            "the potential returned a non-finite energy, force or torque (a ball at the field's "
                            "centre?)",
                        "check the initial state; a smaller step resolves close encounters better");
  }
}

/// Sums the per-body solve reports: iterations and residual evaluations in
/// all, and the most iterations one body needed.
inline SolveReport combine(const std::vector<SolveReport>& reports) {
  if (reports.size() == 1) {
    SolveReport r = reports[0];
    r.worst_iterations = r.iterations;
    return r;
  }
  SolveReport r;
  for (const SolveReport& b : reports) {
    r.iterations += b.iterations;
    r.residual_evaluations += b.residual_evaluations;
    r.worst_iterations = std::max(r.worst_iterations, b.iterations);
  }
  return r;
}

/// What every N-body stepper holds: the system, its potential, the
/// evaluation at the current state and the threads for per-body loops.
template <SystemPotential I>
class StepperBase {
 public:
  const System& system() const { return system_; }
  const I& potential() const { return potential_; }
  const SystemEvaluation& evaluation() const { return eval_; }
  const SolveReport& last_solve() const { return report_; }
  void set_parallelism(Parallelism par) { par_ = par; }

  /// Evaluates the potential at s.
  void initialize(const SystemState& s, double /*t*/) {
    if (s.size() != system_.size())
      throw InvalidInput("state: " + std::to_string(s.size()) + " bodies, the system has " +
                         std::to_string(system_.size()));
    potential_.evaluate(s, eval_);
    require_finite(system_, s, eval_);
  }

 protected:
  StepperBase(System system, I potential, Parallelism par)
      : system_(std::move(system)), potential_(std::move(potential)), par_(par), eval_(system_.size()) {}

  /// The potential at the new state s, which becomes the current evaluation.
  void evaluate_at(const SystemState& s) {
    potential_.evaluate(s, eval_);
  }

  System system_;
  I potential_;
  Parallelism par_;
  SystemEvaluation eval_;
  SolveReport report_;
};

}  // namespace detail
}  // namespace lgvi
