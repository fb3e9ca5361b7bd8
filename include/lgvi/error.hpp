// Errors raised by the library. Every failure is an exception with a message
// that names the cause (and the step, for integration failures); nothing is
// reported through NaN values or silently clamped.
#pragma once

#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace lgvi {

/// Invalid input: a body, a state, a scenario field. The message names the
/// field and how to fix it.
class InvalidInput : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// A step could not be taken (solver did not converge, the rotation in one
/// step reached pi, a value became non-finite). `hint` suggests the cure.
class StepFailure : public std::runtime_error {
 public:
  StepFailure(const std::string& reason, std::string hint = {})
      : std::runtime_error(reason), hint_(std::move(hint)) {}
  const std::string& hint() const { return hint_; }

 private:
  std::string hint_;
};

/// A StepFailure located in a run: which step (the step from t_k to t_{k+1}
/// failed, k = `step`) and at what time t_k.
class IntegrationFailure : public std::runtime_error {
 public:
  IntegrationFailure(std::int64_t step, double time, const StepFailure& cause)
      : std::runtime_error(format(step, time, cause)), step_(step), time_(time) {}
  std::int64_t step() const { return step_; }
  double time() const { return time_; }

 private:
  static std::string format(std::int64_t step, double time, const StepFailure& cause) {
    char t[32];
    std::snprintf(t, sizeof t, "%.10g", time);
    std::string m = "step " + std::to_string(step) + " (from t = " + t + ") failed: " + cause.what();
    if (!cause.hint().empty()) m += "; " + cause.hint();
    return m;
  }
  std::int64_t step_;
  double time_;
};

}  // namespace lgvi
