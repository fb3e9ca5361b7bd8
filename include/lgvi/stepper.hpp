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

#include <lgvi/checkpoint_fields.hpp>
#include <lgvi/error.hpp>
#include <lgvi/forcing.hpp>
#include <lgvi/interaction.hpp>
#include <lgvi/parallel.hpp>
#include <lgvi/rotation_solver.hpp>
#include <lgvi/system.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <concepts>
#include <string>
#include <vector>

namespace lgvi {

/// A stepper for N bodies.
///  * initialize(state, t): evaluate the potential at `state` (time t);
///  * step(state, t, h): advance `state` from t to t + h in place; h is not
///    checked here, since a composition's sub-steps gamma_i h can be negative
///    (composition.hpp); the run loop (integrate.hpp) refuses a step size that
///    is not finite and > 0;
///  * evaluation(): V, forces and torques at the current state, no extra cost;
///  * last_solve(): the implicit solves of the last step (zero if explicit);
///  * save(fields) / load(state, t, fields): what a checkpoint keeps besides
///    the state for a bit-identical continuation, as named fields under
///    "stepper." (checkpoint_fields.hpp); load() evaluates the potential at
///    `state` and also reads a checkpoint of versions 2 to 4, whose numbers
///    are the field "stepper.internal" in the layout of internal_state();
///  * internal_state() / resume(state, t, internal): those numbers.
template <class S>
concept SystemStepper = requires(S& s, const S& cs, SystemState& state, double t, double h,
                                 const std::vector<double>& internal, CheckpointFields& out,
                                 const CheckpointFields& in) {
  { s.initialize(state, t) };
  { s.step(state, t, h) };
  { cs.evaluation() } -> std::convertible_to<const SystemEvaluation&>;
  { cs.last_solve() } -> std::convertible_to<SolveReport>;
  { cs.internal_state() } -> std::convertible_to<std::vector<double>>;
  { s.resume(state, t, internal) };
  { cs.save(out) };
  { s.load(state, t, in) };
  { cs.system() } -> std::convertible_to<const System&>;
};

namespace detail {

/// to = from before a step (the run loop's, integrate.hpp, or a
/// step_from that steps in place). A system without wheels (eta empty), copied
/// into one of its size, is copied body by body on the stepper's threads
/// where the stepper has more than one: a many-body step's copy (104 B per
/// body) is otherwise a serial part of every step. The same values either
/// way.
template <class S>
void copy_state(const S& s, SystemState& to, const SystemState& from) {
  if constexpr (requires { s.parallelism(); }) {
    if (to.size() == from.size() && from.eta.empty() && to.eta.empty() && s.parallelism().threads > 1) {
      parallel_for(from.size(), s.parallelism(), [&](std::size_t a) {
        to.x[a] = from.x[a];
        to.q[a] = from.q[a];
        to.p[a] = from.p[a];
        to.w[a] = from.w[a];
      });
      return;
    }
  }
  to = from;
}

/// Throws InvalidInput unless every body has three principal moments > 0.
/// The methods whose equations divide by the moments (all but the LGVI's two
/// forms, MethodTraits::linear_bodies) call it on construction: a linear body
/// or a point (RigidBody::rotational_dof) would give them no error, only
/// infinities or a wrong motion.
inline void require_three_moments(const System& system, const char* method) {
  for (std::size_t a = 0; a < system.size(); ++a) {
    if (system.body(a).rotational_dof() == 3) continue;
    throw InvalidInput(std::string(method) + " needs three principal moments > 0; body " + std::to_string(a) +
                       " (\"" + system.name(a) + "\") is " + system.body(a).rotation_description() +
                       "; integrate it with the LGVI (lgvi or lgvi-lagrangian)");
  }
}

inline void require_valid_step(double h) {
  if (!(std::isfinite(h) && h > 0.0))
    throw InvalidInput("integrator.step: must be a finite number > 0, got " + std::to_string(h));
}

/// "body a ("name"): " for systems of more than one body, "" for one body
/// (whose messages need not name it).
inline std::string body_prefix(const System& sys, std::size_t a) {
  if (sys.size() == 1) return {};
  return "body " + std::to_string(a) + " (\"" + sys.name(a) + "\"): ";
}

/// Runs f() for body a: a StepFailure is reported with the body named
/// (systems of more than one body).
template <class F>
void for_body(const System& sys, std::size_t a, F&& f) {
  try {
    f();
  } catch (const StepFailure& e) {
    if (sys.size() == 1) throw;
    throw StepFailure(body_prefix(sys, a) + e.what(), e.hint());
  }
}

/// Runs f(a) for every body on the stepper's threads; a StepFailure of a
/// body is reported with the body named (systems of more than one body).
template <class F>
void for_each_body(const System& sys, const Parallelism& par, F&& f) {
  parallel_for(sys.size(), par, [&](std::size_t a) { for_body(sys, a, [&] { f(a); }); });
}

/// Runs f(first, count) for the bodies in consecutive batches of `lanes`
/// (the last one may be shorter) on the stepper's threads, each batch's
/// bodies on one thread, in order; threads as for as many bodies (each
/// thread at least par.min_bodies_per_thread). f names a failing body
/// itself (for_body).
template <class F>
void for_each_body_batch(const System& sys, const Parallelism& par, std::size_t lanes, F&& f) {
  const std::size_t n = sys.size(), batches = (n + lanes - 1) / lanes;
  Parallelism per_batch = par;
  per_batch.min_bodies_per_thread = std::max<std::size_t>(1, par.min_bodies_per_thread / lanes);
  parallel_for(batches, per_batch, [&](std::size_t k) { f(k * lanes, std::min(lanes, n - k * lanes)); });
}

/// Whether body a's state and evaluation are finite. One test on a sum: a
/// NaN or infinity anywhere makes it non-finite (inf - inf is NaN), so the
/// common case costs one branch.
inline bool body_finite(const SystemState& s, const SystemEvaluation& e, std::size_t a) {
  const double sum = s.x[a].sum() + s.q[a].coefficient_sum() + s.p[a].sum() + s.w[a].sum() + e.energy +
                     e.force[a].sum() + e.torque[a].sum();
  return std::isfinite(sum);
}

/// Throws StepFailure if the state or the evaluation is not finite, naming
/// the first body that is not (systems of more than one body).
inline void require_finite(const System& sys, const SystemState& s, const SystemEvaluation& e) {
  for (std::size_t a = 0; a < s.size(); ++a) {
    if (body_finite(s, e, a)) continue;
    // Cause-neutral: the potential may be the user's. At a finite configuration (x, q) a non-finite
    // evaluation is the cause (the momenta it fed are non-finite too); name what was not finite (the
    // caller adds the step and its time).
    const bool evaluation_finite = std::isfinite(e.energy) && e.force[a].allFinite() && e.torque[a].allFinite();
    if (!evaluation_finite && s.x[a].allFinite() && s.q[a].all_finite()) {
      const char* what = !std::isfinite(e.energy) ? "energy" : !e.force[a].allFinite() ? "force" : "torque";
      throw StepFailure(body_prefix(sys, a) + "the potential returned a non-finite " + what,
                        "check the potential at this state (where is it not defined?); a smaller step resolves "
                        "close encounters better");
    }
    if (!s.body(a).all_finite())
      throw StepFailure(body_prefix(sys, a) + "the state became non-finite", "try a smaller step");
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
  /// For what the potential computes besides the evaluation (a pair
  /// interaction's virial), which writes its workspace (interaction.hpp).
  I& potential() { return potential_; }
  const SystemEvaluation& evaluation() const { return eval_; }
  const SolveReport& last_solve() const { return report_; }
  void set_parallelism(Parallelism par) { par_ = par; }
  const Parallelism& parallelism() const { return par_; }
  /// The forcing acting besides the potential (forcing.hpp); empty if none.
  const ForcingSet& forcing() const { return forcing_; }
  /// The work done by the forcing since initialize() (trapezoidal rule,
  /// forcing.hpp), 0 without forcing.
  double forcing_work() const { return work_; }

  /// Evaluates the potential at s, and the forcing at (t, s) (sampled
  /// controllers sample there; the work starts from 0).
  void initialize(const SystemState& s, double t) {
    if (s.size() != system_.size())
      throw InvalidInput("state: " + std::to_string(s.size()) + " bodies, the system has " +
                         std::to_string(system_.size()));
    potential_.evaluate(s, eval_);
    require_finite(system_, s, eval_);
    if (forcing_.empty()) return;
    forcing_.reset();
    forcing_.sample(t, s, system_);
    work_ = 0.0;
    evaluate_forcing(t, s);
    if (forcing_.has_callable()) require_repeatable_forcing(t, s, ext_force_, ext_torque_);
  }

 protected:
  StepperBase(System system, I potential, Parallelism par)
      : system_(std::move(system)), potential_(std::move(potential)), par_(par), eval_(system_.size()) {}

  /// The potential at the new state s, which becomes the current evaluation.
  void evaluate_at(const SystemState& s) {
    potential_.evaluate(s, eval_);
  }

  /// Installs a forcing (steppers that implement the discrete
  /// Lagrange-d'Alembert step expose this as set_forcing).
  void install_forcing(ForcingSet f) {
    forcing_ = std::move(f);
    const std::size_t n = system_.size();
    ext_force_.assign(n, Vector3<double>::Zero());
    ext_torque_.assign(n, Vector3<double>::Zero());
    total_force_ = eval_.force;
    total_torque_ = eval_.torque;
  }

  /// The force on body a at the current state: the potential's plus the
  /// forcing's (inertial frame).
  const Vector3<double>& force(std::size_t a) const { return forcing_.empty() ? eval_.force[a] : total_force_[a]; }
  /// The body torque on body a at the current state, potential plus forcing.
  const Vector3<double>& torque(std::size_t a) const { return forcing_.empty() ? eval_.torque[a] : total_torque_[a]; }

  /// At the start of a step from (t, s): sampled controllers sample, and the
  /// forcing's power there is kept for the work of the step. The forcing at
  /// (t, s) is the end-of-step value of the step before (or initialize's).
  void begin_step(const SystemState& s, double t) {
    if (forcing_.empty()) return;
    if (forcing_.sample(t, s, system_)) evaluate_forcing(t, s);
    power0_ = ForcingSet::power(s, system_, ext_force_, ext_torque_);
  }

  /// Ends a step of size h whose new configuration is in s (the potential
  /// evaluated there by evaluate_at): evaluates the forcing at (t1, s) and
  /// calls kick(a), which sets body a's new momenta from force(a) and
  /// torque(a), for every body. When the forcing reads the momenta, the new
  /// momenta are a fixed point of (evaluate, kick): iterated until they
  /// change by less than 4 eps relative (or stagnate at round-off), at most
  /// 50 times; a StepFailure otherwise. Then `finish()` completes the state
  /// (a gyrostat's wheels take the second half of their impulse, lgvi.hpp),
  /// and the step's work is added at the completed state.
  template <class Kick, class Finish = void (*)()>
  void end_step(SystemState& s, double t1, double h, Kick&& kick, Finish&& finish = [] {}) {
    if (forcing_.empty()) {
      for_each_body(system_, par_, kick);
      finish();
      return;
    }
    evaluate_forcing(t1, s);
    for_each_body(system_, par_, kick);
    if (forcing_.depends_on_velocity()) {
      constexpr int max_iterations = 50;
      constexpr double eps = std::numeric_limits<double>::epsilon();
      double previous = std::numeric_limits<double>::infinity();
      for (int it = 1;; ++it) {
        p_iterate_ = s.p;
        w_iterate_ = s.w;
        evaluate_forcing(t1, s);
        for_each_body(system_, par_, kick);
        double change = 0.0, scale = 0.0;
        for (std::size_t a = 0; a < s.size(); ++a) {
          change = std::max({change, (s.p[a] - p_iterate_[a]).norm(), (s.w[a] - w_iterate_[a]).norm()});
          scale = std::max({scale, s.p[a].norm(), s.w[a].norm()});
        }
        if (change <= 4 * eps * scale) break;
        // Round-off stagnation: the iteration stopped contracting a few ulps away.
        if (change >= previous && change <= 1e3 * eps * scale) break;
        if (it == max_iterations || !std::isfinite(change)) {
          // A user's function that draws new values on every call (noise) has no fixed point to
          // converge to: say that rather than blame the step.
          if (forcing_.has_callable()) {
            forcing_.evaluate(t1, s, system_, p_iterate_, w_iterate_);
            require_repeatable_forcing(t1, s, p_iterate_, w_iterate_);
          }
          throw StepFailure("the forcing depends on the momenta and the end-of-step momenta did not converge in " +
                                std::to_string(max_iterations) + " iterations (relative change " +
                                std::to_string(scale > 0.0 ? change / scale : change) + ")",
                            "the forcing is too stiff for this step (e.g. h c / j not small for damping): "
                            "use a smaller step");
        }
        previous = change;
      }
    }
    finish();
    work_ += 0.5 * h * (power0_ + ForcingSet::power(s, system_, ext_force_, ext_torque_));
  }

  /// What a checkpoint keeps of the forcing: the work, the forcing at the
  /// current state (the next step starts from it, so that a resumed run
  /// continues bit for bit) and the sampled controllers' values. Empty
  /// without forcing.
  void forcing_internal(std::vector<double>& v) const {
    if (forcing_.empty()) return;
    v.push_back(work_);
    for (const auto* arr : {&ext_force_, &ext_torque_})
      for (const Vector3<double>& x : *arr) v.insert(v.end(), {x.x(), x.y(), x.z()});
    const std::vector<double> sampled = forcing_.internal_state(system_.size());
    v.insert(v.end(), sampled.begin(), sampled.end());
  }
  std::size_t forcing_internal_size() const {
    return forcing_.empty() ? 0 : 1 + 6 * system_.size() + forcing_.internal_size(system_.size());
  }
  /// The forcing's fields (checkpoint_fields.hpp), nothing without forcing:
  /// "stepper.forcing.work", "stepper.forcing.force" and
  /// "stepper.forcing.torque" (the forcing at the current state, 3 numbers
  /// per body: the next step starts from it) and the sampled controllers'
  /// (ForcingSet::save).
  void save_forcing(CheckpointFields& out) const {
    if (forcing_.empty()) return;
    out.put_f64("stepper.forcing.work", {work_});
    for (const auto& [name, arr] : {std::pair{"stepper.forcing.force", &ext_force_},
                                    std::pair{"stepper.forcing.torque", &ext_torque_}}) {
      std::vector<double> v;
      for (const Vector3<double>& x : *arr) v.insert(v.end(), {x.x(), x.y(), x.z()});
      out.put_f64(name, std::move(v));
    }
    forcing_.save(out, system_.size());
  }
  /// Restores what save_forcing wrote (after initialize()).
  void load_forcing(const CheckpointFields& in) {
    if (forcing_.empty()) return;
    const std::size_t n = system_.size();
    work_ = in.f64_value("stepper.forcing.work");
    for (const auto& [name, arr] : {std::pair{"stepper.forcing.force", &ext_force_},
                                    std::pair{"stepper.forcing.torque", &ext_torque_}}) {
      const std::vector<double>& v = in.f64(name, 3 * n);
      for (std::size_t a = 0; a < n; ++a) (*arr)[a] = Vector3<double>(v[3 * a], v[3 * a + 1], v[3 * a + 2]);
    }
    forcing_.load(in, n);
    sum_wrenches();
  }
  /// Restores what forcing_internal wrote (after initialize()).
  void restore_forcing(const double* d) {
    if (forcing_.empty()) return;
    const std::size_t n = system_.size();
    work_ = *d++;
    for (auto* arr : {&ext_force_, &ext_torque_})
      for (Vector3<double>& x : *arr) {
        x = Vector3<double>(d[0], d[1], d[2]);
        d += 3;
      }
    forcing_.restore(d, n);
    sum_wrenches();
  }

  System system_;
  I potential_;
  Parallelism par_;
  SystemEvaluation eval_;
  SolveReport report_;

 private:
  /// Evaluates the forcing at (t, s) once more and requires the same values as
  /// `force` and `torque` from an evaluation there, to 1e3 eps relative (a
  /// deterministic function whose last bits vary, as a threaded reduction, is
  /// not refused; noise differs at its own scale). lgvi evaluates a forcing
  /// more than once at the same time and state (here at the start, in the
  /// end-of-step momentum iteration, at a resume), so it must be a function of
  /// (t, state): a function that draws fresh noise on every call gives the
  /// iteration nothing to converge to and the run results that depend on how
  /// often it was called. Non-finite values are left to the callers' checks.
  void require_repeatable_forcing(double t, const SystemState& s, const std::vector<Vector3<double>>& force,
                                  const std::vector<Vector3<double>>& torque) {
    constexpr double tolerance = 1e3 * std::numeric_limits<double>::epsilon();
    std::vector<Vector3<double>> again_force, again_torque;
    forcing_.evaluate(t, s, system_, again_force, again_torque);
    auto differ = [&](const Vector3<double>& a, const Vector3<double>& b) {
      return a.allFinite() && b.allFinite() && (a - b).norm() > tolerance * std::max(a.norm(), b.norm());
    };
    for (std::size_t a = 0; a < s.size(); ++a)
      if (differ(again_force[a], force[a]) || differ(again_torque[a], torque[a]))
        throw StepFailure(body_prefix(system_, a) +
                              "the forcing returned different values for the same time and state (t = " +
                              std::to_string(t) +
                              "); lgvi evaluates a forcing more than once at the same time and state (at the "
                              "start, in each step's momentum iteration) and needs it to be a function of them",
                          "draw noise once per control sample (a generator seeded by the sample number, e.g. "
                          "numpy.random.default_rng([seed, int(numpy.floor(t / period + 1e-9))])), see "
                          "docs/guide/forcing.md and examples/gyro_noise.py");
  }

  /// The forcing at (t, s) into ext_*, and the totals potential + forcing.
  void evaluate_forcing(double t, const SystemState& s) {
    forcing_.evaluate(t, s, system_, ext_force_, ext_torque_);
    sum_wrenches();
    for (std::size_t a = 0; a < s.size(); ++a)
      if (!(ext_force_[a].allFinite() && ext_torque_[a].allFinite()))
        throw StepFailure(body_prefix(system_, a) + "the forcing returned a non-finite force or torque at t = " +
                              std::to_string(t),
                          "check the forcing's inputs (a table, a callable)");
  }
  void sum_wrenches() {
    const std::size_t n = system_.size();
    total_force_.resize(n);
    total_torque_.resize(n);
    for (std::size_t a = 0; a < n; ++a) {
      total_force_[a] = eval_.force[a] + ext_force_[a];
      total_torque_[a] = eval_.torque[a] + ext_torque_[a];
    }
  }

  ForcingSet forcing_;
  std::vector<Vector3<double>> ext_force_, ext_torque_;      ///< the forcing at the current state
  std::vector<Vector3<double>> total_force_, total_torque_;  ///< potential + forcing
  std::vector<Vector3<double>> p_iterate_, w_iterate_;
  double work_ = 0.0, power0_ = 0.0;
};

}  // namespace detail
}  // namespace lgvi
