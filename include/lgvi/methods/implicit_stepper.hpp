// The base of the implicit steppers (lgvi.hpp's two forms of the paper's
// method, methods/so3_lgvi.hpp, methods/rattle_quaternion.hpp): their shared
// translational half-steps, per-body predictors and solve reports, and the
// predictors' history as a checkpoint's internal state. A method file derives
// from it and adds its rotation solve only.
#pragma once

#include <lgvi/checkpoint_fields.hpp>
#include <lgvi/error.hpp>
#include <lgvi/interaction.hpp>
#include <lgvi/rotation_solver.hpp>
#include <lgvi/state.hpp>
#include <lgvi/stepper.hpp>
#include <lgvi/system.hpp>

#include <algorithm>
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace lgvi {

namespace detail {

/// What the implicit steppers (lgvi.hpp, methods/so3_lgvi.hpp,
/// methods/rattle_quaternion.hpp) share: per body a predictor of the next
/// relative rotation and a solve report; the translational half-steps of the
/// paper's scheme, which are the same in all of them,
///   p_half = p0 + (h/2) F0,  x1 = x0 + (h/m) p_half,  ...,  p1 = p_half + (h/2) F1;
/// and the predictors' history as the checkpoint's internal state.
///
/// Stages (composition.hpp): a composed step calls step() with sub-steps
/// gamma_1 h, ..., gamma_s h of different sizes and signs. Each stage i keeps
/// its own predictors, extrapolating stage i's relative rotations of the
/// previous steps (a smooth sequence with a fixed sub-step), so the predictor
/// stays good whatever the neighbouring sub-steps are.
template <SystemPotential I, class Predictor>
class ImplicitStepperBase : public StepperBase<I> {
 public:
  /// Evaluates the potential at s and forgets the predictors' history: the
  /// first step seeds each from its first-order estimate.
  void initialize(const SystemState& s, double t) {
    StepperBase<I>::initialize(s, t);
    for (Predictor& p : predictors_) p = Predictor(opt_.predictor_order);
    std::fill(x_carry_.begin(), x_carry_.end(), Vector3<double>::Zero());
  }

  /// Keeps predictors for `stages` sub-steps per step (1 for a plain step);
  /// forgets their history. Stage 0 is selected.
  void set_stages(std::size_t stages) {
    if (stages == 0) throw InvalidInput("a composition needs at least one stage");
    predictors_.assign(stages * this->system_.size(), Predictor(opt_.predictor_order));
    stage_ = 0;
  }
  std::size_t stages() const { return predictors_.size() / this->system_.size(); }
  /// The stage whose predictors the next step() uses.
  void select_stage(std::size_t i) { stage_ = i; }

  /// Per body, the predictors' history (Predictor::serialized_size numbers
  /// per stage) after `extra` numbers of the method's own (see
  /// serialize_extra); then the forcing's; then, per body, the carry of the
  /// compensated position sum (drift), 3 numbers.
  std::vector<double> internal_state() const {
    std::vector<double> v;
    const std::size_t n = this->system_.size();
    for (std::size_t a = 0; a < n; ++a) {
      serialize_extra(a, v);
      for (std::size_t i = 0; i < stages(); ++i) {
        const std::vector<double> p = predictors_[i * n + a].serialize();
        v.insert(v.end(), p.begin(), p.end());
      }
    }
    this->forcing_internal(v);  // nothing without forcing: the layout above is unchanged
    for (const Vector3<double>& c : x_carry_) v.insert(v.end(), {c.x(), c.y(), c.z()});
    return v;
  }

  /// A checkpoint's fields (checkpoint_fields.hpp): the method's own
  /// (save_extra); "stepper.predictors", the predictors' history
  /// (Predictor::serialized_size numbers each, stage by stage, body by body
  /// within a stage); the forcing's; "stepper.position_carry", per body the
  /// carry of the compensated position sum (drift), 3 numbers.
  void save(CheckpointFields& out) const {
    save_extra(out);
    std::vector<double> p;
    p.reserve(predictors_.size() * Predictor::serialized_size);
    for (const Predictor& predictor : predictors_) {
      const std::vector<double> v = predictor.serialize();
      p.insert(p.end(), v.begin(), v.end());
    }
    out.put_f64("stepper.predictors", std::move(p));
    this->save_forcing(out);
    std::vector<double> carry;
    for (const Vector3<double>& c : x_carry_) carry.insert(carry.end(), {c.x(), c.y(), c.z()});
    out.put_f64("stepper.position_carry", std::move(carry));
  }

 protected:
  ImplicitStepperBase(System system, I potential, SolverOptions solver, Parallelism par)
      : StepperBase<I>(std::move(system), std::move(potential), par),
        opt_(solver),
        predictors_(this->system_.size(), Predictor(solver.predictor_order)),
        reports_(this->system_.size()),
        p_half_(this->system_.size()), x_carry_(this->system_.size(), Vector3<double>::Zero()),
        body_finite_(this->system_.size(), 1) {}

  virtual ~ImplicitStepperBase() = default;
  ImplicitStepperBase(const ImplicitStepperBase&) = default;
  ImplicitStepperBase(ImplicitStepperBase&&) noexcept = default;
  ImplicitStepperBase& operator=(const ImplicitStepperBase&) = default;
  ImplicitStepperBase& operator=(ImplicitStepperBase&&) noexcept = default;

  /// A method's own numbers per body before the predictor (none by default).
  virtual void serialize_extra(std::size_t, std::vector<double>&) const {}
  virtual std::size_t extra_size() const { return 0; }
  virtual void deserialize_extra(std::size_t, const double*) {}

  /// A method's own checkpoint fields (none by default).
  virtual void save_extra(CheckpointFields&) const {}
  virtual void load_extra(const CheckpointFields&) {}

  /// Restores what save() wrote, after initialize(); or, from a checkpoint
  /// of versions 2 to 4, the numbers of internal_state() held in the field
  /// "stepper.internal" (restore).
  void load_fields(const CheckpointFields& in, const char* what) {
    if (in.has("stepper.internal")) {
      detail::reading_stepper_internal([&] { restore(in.f64("stepper.internal"), what); });
      return;
    }
    const std::size_t n = this->system_.size();
    load_extra(in);
    const std::vector<double>& p = in.f64("stepper.predictors", predictors_.size() * Predictor::serialized_size);
    for (std::size_t i = 0; i < predictors_.size(); ++i) {
      const auto first = p.begin() + static_cast<std::ptrdiff_t>(i * Predictor::serialized_size);
      predictors_[i].deserialize(std::vector<double>(first, first + Predictor::serialized_size));
    }
    this->load_forcing(in);
    const std::vector<double>& carry = in.f64("stepper.position_carry", 3 * n);
    for (std::size_t a = 0; a < n; ++a) x_carry_[a] = Vector3<double>(carry[3 * a], carry[3 * a + 1], carry[3 * a + 2]);
  }

  /// Restores the state written by internal_state(), after initialize().
  /// A checkpoint written before the positions' carry was kept has none: it
  /// resumes with a zero carry (a difference of round-off in x).
  void restore(const std::vector<double>& internal, const char* what) {
    const std::size_t n = this->system_.size();
    const std::size_t per_body = extra_size() + stages() * Predictor::serialized_size;
    const std::size_t without_carry = per_body * n + this->forcing_internal_size();
    if (internal.size() != without_carry && internal.size() != without_carry + 3 * n)
      throw InvalidInput(std::string("checkpoint: ") + what + " data has the wrong size");
    if (internal.size() > without_carry)
      for (std::size_t a = 0; a < n; ++a) {
        const double* c = internal.data() + without_carry + 3 * a;
        x_carry_[a] = Vector3<double>(c[0], c[1], c[2]);
      }
    this->restore_forcing(internal.data() + per_body * n);
    for (std::size_t a = 0; a < n; ++a) {
      const double* d = internal.data() + a * per_body + extra_size();
      deserialize_extra(a, internal.data() + a * per_body);
      for (std::size_t i = 0; i < stages(); ++i, d += Predictor::serialized_size)
        predictors_[i * n + a].deserialize(std::vector<double>(d, d + Predictor::serialized_size));
    }
  }

  /// Body a's predictor for the selected stage.
  Predictor& predictor(std::size_t a) { return predictors_[stage_ * this->system_.size() + a]; }

  /// p_half = p0 + (h/2) F0 and x1 = x0 + (h/m) p_half for body a, x1 as a
  /// compensated (Kahan) sum: in free flight the increment is the same every
  /// step, and so is the rounding of a plain x0 + increment (within a binade
  /// the sum has the same fraction of an ulp each time), so x would drift
  /// linearly and x x p with it: the angular momentum of a Lennard-Jones gas
  /// would grow to 1e-11 of its terms over 1e5 steps. The carry holds what the
  /// last sum lost and is added back to the next increment (checkpointed:
  /// internal_state).
  void drift(SystemState& s, std::size_t a, double h) { drift(s, s, a, h); }
  /// The same from `in`'s p and x into s's x (s may be in).
  void drift(const SystemState& in, SystemState& s, std::size_t a, double h) {
    p_half_[a] = in.p[a] + (0.5 * h) * this->force(a);
    Vector3<double> x = in.x[a];
    add_to_position(x, a, (h / this->system_.body(a).mass()) * p_half_[a]);
    s.x[a] = x;
  }
  /// x += increment for body a's position x, as a compensated (Kahan) sum
  /// with its carry (see drift).
  void add_to_position(Vector3<double>& x, std::size_t a, const Vector3<double>& increment) {
    const Vector3<double> dx = increment - x_carry_[a];
    const Vector3<double> x1 = x + dx;
    x_carry_[a] = (x1 - x) - dx;
    x = x1;
  }
  /// p1 = p_half + (h/2) F1 for body a (after the evaluation at the new state).
  void kick(SystemState& s, std::size_t a, double h) { s.p[a] = p_half_[a] + (0.5 * h) * this->force(a); }

  /// Combines the bodies' reports and checks the new state. `checked`: the
  /// step's last per-body loop has recorded, on its threads, whether each
  /// body is finite (note_finite); then only a failure is looked at again,
  /// on this thread, for the message.
  void finish_step(const SystemState& s, bool checked = false) {
    this->report_ = combine(reports_);
    if (!checked || std::find(body_finite_.begin(), body_finite_.end(), 0) != body_finite_.end())
      require_finite(this->system_, s, this->eval_);
  }
  /// Records whether body a's new state and the evaluation are finite (for
  /// finish_step; in a per-body loop, where the body's data are in cache).
  void note_finite(const SystemState& s, std::size_t a) {
    body_finite_[a] = body_finite(s, this->eval_, a) ? 1 : 0;
  }

  /// For the steppers that turn each body by the paper's rotation solve
  /// (lgvi.hpp's two forms, time_transformed.hpp): one RotationSolver per
  /// kind of body (System::kind; it holds the kind's inertia), made by
  /// use_rotation_solvers() in their constructors.
  void use_rotation_solvers() {
    for (std::size_t k = 0; k < this->system_.kinds(); ++k)
      rotation_solvers_.emplace_back(this->system_.kind_body(k), opt_);
  }
  /// Body a's rotation solver (use_rotation_solvers).
  const RotationSolver& solver(std::size_t a) const { return rotation_solvers_[this->system_.kind(a)]; }
  /// Whether any body's solve can run in a RotationSolveBatch.
  bool any_batchable() const {
    return std::any_of(rotation_solvers_.begin(), rotation_solvers_.end(),
                       [](const RotationSolver& s) { return s.batchable(); });
  }

  SolverOptions opt_;
  std::vector<RotationSolver> rotation_solvers_;  ///< per kind (use_rotation_solvers)
  std::vector<Predictor> predictors_;  ///< stage-major: stage i, body a at i N + a
  std::size_t stage_ = 0;
  std::vector<SolveReport> reports_;
  std::vector<Vector3<double>> p_half_;
  std::vector<Vector3<double>> x_carry_;  ///< per body: what the last compensated position sum lost
  std::vector<char> body_finite_;  ///< per body: finite after the step (note_finite)
};

}  // namespace detail

}  // namespace lgvi
