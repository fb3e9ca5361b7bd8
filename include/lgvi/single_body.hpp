// One rigid body in a potential V(x, q): the single-body face of the N-body
// steppers, for code that integrates one body (the library's original API).
//
// SingleBodyStepper<Method, P> is Method<ExternalField<P>> on the system of
// one body: the same code and the same arithmetic as every system, with the
// state copied in and out as a RigidBodyState. Time is k h, k counted by the
// adapter (t0 + k h in the integrate loop).
#pragma once

#include <lgvi/interaction.hpp>
#include <lgvi/potential.hpp>
#include <lgvi/rotation_solver.hpp>
#include <lgvi/state.hpp>
#include <lgvi/stepper.hpp>
#include <lgvi/system.hpp>

#include <concepts>
#include <cstdint>
#include <vector>

namespace lgvi {

/// The contract of a single-body one-step method: initialize at a state
/// (evaluating the potential there), then advance by step() in place.
/// evaluation() is the potential at the current state, for diagnostics,
/// with no extra cost.
template <class S>
concept Stepper = requires(S& s, const S& cs, RigidBodyState& state) {
  { s.initialize(state) };
  { s.step(state) };
  { cs.step_size() } -> std::convertible_to<double>;
  { cs.evaluation() } -> std::convertible_to<PotentialEvaluation>;
  { cs.last_solve() } -> std::convertible_to<SolveReport>;
};

template <template <class> class Method, Potential P>
class SingleBodyStepper {
 public:
  using SystemMethod = Method<ExternalField<P>>;

  SingleBodyStepper(const RigidBody& body, P potential, double h, SolverOptions solver = {})
      : inner_(System(body), ExternalField<P>(std::vector<P>{std::move(potential)}), solver), h_(h) {
    detail::require_valid_step(h);
  }

  void initialize(const RigidBodyState& s) {
    state_ = SystemState(s);
    k_ = 0;
    inner_.initialize(state_, 0.0);
    refresh();
  }
  void step(RigidBodyState& s) {
    state_.set_body(0, s);
    inner_.step(state_, static_cast<double>(k_) * h_, h_);
    ++k_;
    s = state_.body(0);
    refresh();
  }

  double step_size() const { return h_; }
  const PotentialEvaluation& evaluation() const { return eval_; }
  const SolveReport& last_solve() const { return inner_.last_solve(); }
  const RigidBody& body() const { return inner_.system().body(0); }
  const P& potential() const { return inner_.potential().body_potential(0); }
  /// The N-body stepper behind (method-specific accessors).
  const SystemMethod& system_stepper() const { return inner_; }

  std::vector<double> internal_state() const { return inner_.internal_state(); }
  void resume(const RigidBodyState& s, const std::vector<double>& internal) {
    state_ = SystemState(s);
    inner_.resume(state_, 0.0, internal);
    refresh();
  }

 private:
  void refresh() { eval_ = inner_.evaluation().body(0); }

  SystemMethod inner_;
  double h_;
  std::int64_t k_ = 0;
  SystemState state_;
  PotentialEvaluation eval_;
};

}  // namespace lgvi
