// Composition methods: higher order from a symmetric second-order one-step
// method Phi_h (lgvi, so3-lgvi, rattle-quaternion, no-squish, splitting-dlm)
// by the symmetric composition
//   Psi_h = Phi_{gamma_s h} o ... o Phi_{gamma_2 h} o Phi_{gamma_1 h},
//   sum_i gamma_i = 1,  gamma_i = gamma_{s+1-i}
// (Hairer, Lubich & Wanner, Geometric Numerical Integration, 2nd ed., II.4
// and V.3). A composition of symplectic maps is symplectic, and each
// sub-step keeps what Phi keeps exactly: |q| = 1 to round-off (no
// normalization anywhere) and the discrete Noether momenta. The order
// conditions on the gamma_i raise the order from 2 to 4, 6 or 8.
//
// The tables (CompositionTable::of_order):
//  * order 4, Suzuki's 5 stages (GNI II.4, eq. (4.6)):
//      gamma_1 = gamma_2 = gamma_4 = gamma_5 = 1/(4 - 4^{1/3}), gamma_3 = 1 - 4 gamma_1;
//  * order 6, Kahan & Li's s9odr6a (GNI V.3, eq. (3.11)), 9 stages;
//  * order 8, Kahan & Li's s15odr8 (GNI V.3, eq. (3.12)), 15 stages;
// and a user's own palindromic table summing to 1 (CompositionTable::custom).
//
// Cost: one potential evaluation per sub-step. Phi's evaluation at the end of
// a sub-step depends on the state alone (stepper.hpp), so it serves the next
// sub-step, across step boundaries too, whatever that sub-step's size and
// sign. The implicit methods keep one set of predictors per stage
// (ImplicitStepperBase::set_stages): stage i's initial guess extrapolates
// stage i's solutions of the previous steps, a smooth sequence with a fixed
// sub-step gamma_i h.
#pragma once

#include <lgvi/checkpoint_fields.hpp>
#include <lgvi/error.hpp>
#include <lgvi/rotation_solver.hpp>
#include <lgvi/stepper.hpp>
#include <lgvi/system.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace lgvi {

/// The sub-step fractions gamma_1..gamma_s of a symmetric composition and
/// its order. Invariant: sum gamma_i = 1 to round-off and gamma_i =
/// gamma_{s+1-i} exactly (checked by the constructors).
class CompositionTable {
 public:
  /// The plain step: one stage, gamma_1 = 1, order 2.
  CompositionTable() : gamma_{1.0}, order_(2) {}

  /// The default table of `order` 2, 4, 6 or 8 (above). Throws InvalidInput
  /// for any other order.
  static CompositionTable of_order(int order) {
    switch (order) {
      case 2: return {};
      case 4: {
        const double g = 1.0 / (4.0 - std::cbrt(4.0));
        return CompositionTable({g, g, 1.0 - 4.0 * g, g, g}, 4);
      }
      case 6:
        return CompositionTable(palindrome({0.39216144400731413927925056, 0.33259913678935943859974864,
                                            -0.70624617255763935980996482, 0.08221359629355080023149045,
                                            0.79854399093482996339895035}),
                                6);
      case 8:
        return CompositionTable(
            palindrome({0.74167036435061295344822780, -0.40910082580003159399730010, 0.19075471029623837995387626,
                        -0.57386247111608226665638773, 0.29906418130365592384446354, 0.33462491824529818378495798,
                        0.31529309239676659663205666, -0.79688793935291635401978884}),
            8);
      default:
        throw InvalidInput("the composition order must be 2, 4, 6 or 8 (got " + std::to_string(order) +
                           "); for another table give the fractions [gamma_1, ..., gamma_s]");
    }
  }

  /// A user's table: at least one stage, finite, palindromic (gamma_i =
  /// gamma_{s+1-i} to 8 eps, then made exact) and summing to 1 within 8 eps
  /// per stage (the rounding of decimal coefficients). Its order is reported
  /// as 2: symmetry and consistency guarantee that much; more depends on
  /// order conditions this does not check.
  static CompositionTable custom(std::vector<double> gamma) {
    if (gamma.empty()) throw InvalidInput("a composition needs at least one sub-step fraction");
    double sum = 0.0, scale = 0.0;
    for (const double g : gamma) {
      if (!std::isfinite(g) || g == 0.0)
        throw InvalidInput("every fraction of a composition must be a finite, non-zero number");
      sum += g;
      scale += std::abs(g);
    }
    const double tol = 8.0 * std::numeric_limits<double>::epsilon() * scale;
    if (std::abs(sum - 1.0) > tol)
      throw InvalidInput("the fractions of a composition must sum to 1 (they sum to " + fmt_number(sum) + ")");
    const std::size_t s = gamma.size();
    for (std::size_t i = 0; i < s / 2; ++i) {
      if (std::abs(gamma[i] - gamma[s - 1 - i]) > tol)
        throw InvalidInput("the composition must be palindromic (gamma_" + std::to_string(i + 1) + " = " +
                           fmt_number(gamma[i]) + " but gamma_" + std::to_string(s - i) + " = " +
                           fmt_number(gamma[s - 1 - i]) + "); a symmetric composition needs gamma_i = gamma_{s+1-i}");
      gamma[s - 1 - i] = gamma[i];
    }
    return CompositionTable(std::move(gamma), 2);
  }

  const std::vector<double>& gamma() const { return gamma_; }
  std::size_t stages() const { return gamma_.size(); }
  int order() const { return order_; }
  /// A plain step (one stage, gamma = 1): no composition.
  bool is_plain() const { return gamma_.size() == 1 && gamma_[0] == 1.0; }

 private:
  CompositionTable(std::vector<double> gamma, int order) : gamma_(std::move(gamma)), order_(order) {}

  /// gamma_1..gamma_m, the middle one last -> the full palindrome of 2m - 1.
  static std::vector<double> palindrome(std::vector<double> half) {
    for (std::size_t i = half.size() - 1; i-- > 0;) half.push_back(half[i]);
    return half;
  }
  static std::string fmt_number(double x) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.17g", x);
    return buf;
  }

  std::vector<double> gamma_;
  int order_;
};

/// A stepper whose sub-steps keep per-stage predictor state (the implicit
/// steppers of lgvi.hpp and methods/).
template <class S>
concept StagedStepper = requires(S& s, std::size_t i) {
  { s.set_stages(i) };
  { s.select_stage(i) };
};

/// Psi_h = Phi_{gamma_s h} o ... o Phi_{gamma_1 h} over a SystemStepper Phi
/// that must be symmetric and one-step (the caller's choice; the scenario
/// reader refuses the others). A SystemStepper itself.
template <SystemStepper Base>
class ComposedStepper {
 public:
  ComposedStepper(Base base, CompositionTable table) : base_(std::move(base)), table_(std::move(table)) {
    double c = 0.0;
    for (const double g : table_.gamma()) {
      offsets_.push_back(c);
      c += g;
    }
    if constexpr (StagedStepper<Base>) base_.set_stages(table_.stages());
  }

  /// Evaluates the potential at `state` (Phi's initialize: the predictors of
  /// every stage start afresh).
  void initialize(SystemState& state, double t) {
    if constexpr (StagedStepper<Base>) base_.set_stages(table_.stages());
    base_.initialize(state, t);
  }

  /// One composed step: sub-step i starts at t + c_i h, c_i = gamma_1 + ... +
  /// gamma_{i-1}, and has size gamma_i h. The report sums the sub-steps'
  /// iterations; worst_iterations is the most one body needed in one solve.
  void step(SystemState& state, double t, double h) {
    SolveReport total;
    const std::vector<double>& gamma = table_.gamma();
    for (std::size_t i = 0; i < gamma.size(); ++i) {
      if constexpr (StagedStepper<Base>) base_.select_stage(i);
      base_.step(state, t + offsets_[i] * h, gamma[i] * h);
      const SolveReport r = base_.last_solve();
      total.iterations += r.iterations;
      total.residual_evaluations += r.residual_evaluations;
      total.worst_iterations = std::max(total.worst_iterations, r.worst_iterations);
    }
    report_ = total;
  }

  const SystemEvaluation& evaluation() const { return base_.evaluation(); }
  const auto& potential() const { return base_.potential(); }
  auto& potential() { return base_.potential(); }
  const SolveReport& last_solve() const { return report_; }
  std::vector<double> internal_state() const { return base_.internal_state(); }
  void resume(SystemState& state, double t, const std::vector<double>& internal) {
    if constexpr (StagedStepper<Base>) base_.set_stages(table_.stages());
    base_.resume(state, t, internal);
  }
  /// A checkpoint's fields: the composed method's (checkpoint_fields.hpp).
  void save(CheckpointFields& out) const { base_.save(out); }
  void load(SystemState& state, double t, const CheckpointFields& in) {
    if constexpr (StagedStepper<Base>) base_.set_stages(table_.stages());
    base_.load(state, t, in);
  }
  const System& system() const { return base_.system(); }
  /// The forcing's work since initialize() (steppers with a forcing, forcing.hpp).
  double forcing_work() const
    requires requires(const Base& b) { b.forcing_work(); }
  {
    return base_.forcing_work();
  }
  const CompositionTable& table() const { return table_; }
  /// The composed method Phi (method-specific accessors).
  const Base& base() const { return base_; }

 private:
  Base base_;
  CompositionTable table_;
  std::vector<double> offsets_;
  SolveReport report_;
};

}  // namespace lgvi
