// What the explicit methods (rk4-normalized, euler-exp, no-squish,
// splitting-dlm) share behind the Stepper interface of lgvi.hpp: the body,
// the potential, the step, the potential evaluation at the current state
// (reused by the next step), an empty solve report, and no internal state
// for a checkpoint besides the state itself.
#pragma once

#include <lgvi/error.hpp>
#include <lgvi/lgvi.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace lgvi::detail {

/// The principal moments (J_11, J_22, J_33) of a body whose frame is
/// principal; throws InvalidInput otherwise (message names `method`).
inline Vector3<double> require_principal_axes(const RigidBody& body, const std::string& method) {
  const Matrix3<double>& j = body.inertia();
  const double scale = j.diagonal().cwiseAbs().maxCoeff();
  const double off = std::max({std::abs(j(0, 1)), std::abs(j(0, 2)), std::abs(j(1, 2)), std::abs(j(1, 0)),
                               std::abs(j(2, 0)), std::abs(j(2, 1))});
  if (off > 8 * std::numeric_limits<double>::epsilon() * scale)
    throw InvalidInput(method + ": body.inertia must be diagonal in body axes (diagonalize the body first)");
  return j.diagonal();
}

template <Potential P>
class ExplicitStepperBase {
 public:
  /// Evaluates the potential at s (reused by the first step).
  void initialize(const RigidBodyState& s) {
    eval_ = potential_.evaluate(s.x, s.q);
    require_finite(s, eval_);
  }

  double step_size() const { return h_; }
  const PotentialEvaluation& evaluation() const { return eval_; }
  const SolveReport& last_solve() const { return report_; }
  const RigidBody& body() const { return body_; }

  /// Nothing besides the state: a resume re-evaluates the potential there.
  std::vector<double> internal_state() const { return {}; }
  void resume(const RigidBodyState& s, const std::vector<double>& internal) {
    if (!internal.empty()) throw InvalidInput(std::string("checkpoint: ") + name_ + " has no internal state");
    initialize(s);
  }

 protected:
  ExplicitStepperBase(const RigidBody& body, P potential, double h, const char* name)
      : body_(body), potential_(std::move(potential)), h_(h), name_(name) {
    require_valid_step(h);
  }

  RigidBody body_;
  P potential_;
  double h_;
  PotentialEvaluation eval_;
  SolveReport report_;

 private:
  const char* name_;
};

}  // namespace lgvi::detail
