// The adaptive LGVI: the quaternion LGVI in a time-transformed (extended)
// phase space, so that the physical step shrinks where the dynamics is fast
// (a close pass) while |q| = 1, the momentum map and reversibility stay exact.
//
// Time transformation (Preto & Tremaine 1999; Mikkola & Tanikawa 1999). With
// H = K + V (K = sum_a |p_a|^2/(2 m_a) + w_a^T J_a^{-1} w_a / 8), U = -V and
// E0 = H at the start, the extended Hamiltonian in a fictitious time s
//   Gamma = f(K + p_t) - f(U),   p_t = -E0 (the momentum conjugate to t),
// has dt/ds = f'(K - E0), dx/ds = f'(K - E0) dK/dp and dp/ds = f'(U) F: on the
// shell Gamma = 0 (K - E0 = U) it is the physical flow with dt/ds = g(U),
// g = f'. The monitor
//   g(u) = (1 + (u/c)^4)^(-3/8)
// tends to 1 far from the sources (u << c) and to (c/u)^(3/2) ~ d^(3/2) near a
// point mass (u ~ 1/d): the local dynamical time. (The logarithmic
// Hamiltonian's g = 1/u gives ~ d, too little for balls fixed in a rotating
// body.)
//
// Gamma = A(p, w) + B(x, q) splits into two pieces that lgvi already solves:
// A = f(K - E0) is a free motion at the rate g(K - E0), which K keeps
// constant, and B = -f(U) a kick at the rate g(U), which V keeps constant.
// One step of fictitious size eps is drift-kick-drift:
//   dt1 = (eps/2) g(K - E0):  drift(dt1);
//   one evaluation of the system at (x, q);  tau = eps g(-V):  p += tau F,  w += 2 tau M;
//   dt2 = (eps/2) g(K - E0):  drift(dt2);  t += dt1 + dt2;
// where drift(dt) is every body's free motion by the LGVI over dt:
//   x += dt p/m;  solve g(f) = (dt/4) w (rotation_solver.hpp);  q <- q f;  w <- pi(f)^T w.
// The drift keeps each body's w^T J^{-1} w exactly (w before and after differ
// only in the sign of f_v x J f_v, which is J^{-1}-orthogonal to f_s J f_v),
// so dt1 and dt2 are explicit; every piece keeps the spatial angular momentum
// of each body (the drift) or of the whole system (a kick by a
// rotation-invariant potential); the step is symmetric, hence second order
// in eps, and exactly reversible with the same E0 (flip p and w, step again:
// back to the start with flipped momenta). The energy is not kept exactly:
// Gamma is (to O(eps^2)), so the error rises during a close pass and returns
// after it.
//
// Drift-kick-drift rather than kick-drift-kick (which would reuse the end
// evaluation as the next step's first kick): through the paper's close pass
// (p0 = (1, 0, 0), c = 0.4) kick-drift-kick's energy error peaks 30 times
// higher at eps = 0.02 (1.9e-3 against 6.4e-5) and needs eps = 0.01, with
// twice the steps, to come near (drift-kick-drift's runs: docs/benchmarks.md).
// Its cost per step: two rotation solves per body and two evaluations, one at
// the midpoint for the kick and one at the new state for its V, F and M
// (evaluation(), the stepper contract: the energy of the reported state). No
// implicit equation for the step size. Forcing is not taken (it would need the
// work in the extended Hamiltonian); the caller refuses fields whose V can be
// positive, where U = -V does not measure closeness.
//
// Compositions: the step is a symmetric one-step map of the extended phase
// space, so a symmetric composition (composition.hpp) of sub-steps gamma_i eps
// raises its order in eps (to 4, 6, 8: Yoshida's triple jump gives errors
// falling by 16.0 per halving of eps through the paper's close pass). A
// negative gamma_i steps back in t as well; the whole step advances it.
//
// Finishing at a given time (TimeTransformOptions::finish_time): the step
// that would pass it is taken again from its start with a smaller eps' in
// (0, eps), found by the Illinois variant of regula falsi on dt(eps') = the
// time left (bracketed by 0 and eps, where the full step passed it), so the
// run ends at that time exactly (to 4 eps of t) with a step of the same method
// (same order in eps; each trial costs a step's evaluations). Only steps that can reach it
// (t + eps sum |gamma_i| >= finish time, as g <= 1) keep a copy of their start.
#pragma once

#include <lgvi/checkpoint_fields.hpp>
#include <lgvi/composition.hpp>
#include <lgvi/error.hpp>
#include <lgvi/interaction.hpp>
#include <lgvi/methods/implicit_stepper.hpp>
#include <lgvi/rigid_body.hpp>
#include <lgvi/rotation_solver.hpp>
#include <lgvi/s3.hpp>
#include <lgvi/state.hpp>
#include <lgvi/stepper.hpp>
#include <lgvi/system.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace lgvi {

/// The time transformation's settings ([integrator] time_transform).
struct TimeTransformOptions {
  /// c in g(u) = (1 + (u/c)^4)^(-3/8); 0: |V| at the start.
  double monitor_scale = 0.0;
  /// The physical time at which the run must end exactly (the file comment):
  /// the step that would pass it is shortened to end there. Infinity: none.
  double finish_time = std::numeric_limits<double>::infinity();
};

/// The monitor g(u) = (1 + (u/c)^4)^(-3/8), c > 0: in (0, 1], 1 at u = 0.
inline double time_transform_monitor(double u, double c) {
  const double r = u / c;
  const double r2 = r * r;
  return std::pow(1.0 + r2 * r2, -0.375);
}

/// The adaptive (time-transformed) LGVI of the file comment on N bodies. A
/// SystemStepper whose step(state, s, eps) advances the fictitious time by
/// eps; the physical time is its own (time(), set by initialize(state, t)),
/// and the integrate loop reports it (integrate.hpp: physical_time).
template <SystemPotential I>
class TimeTransformedLieGroupVariationalIntegrator : public detail::ImplicitStepperBase<I, RotationPredictor> {
  using Base = detail::ImplicitStepperBase<I, RotationPredictor>;

 public:
  TimeTransformedLieGroupVariationalIntegrator(System system, I potential, TimeTransformOptions tt = {},
                                               SolverOptions solver = {}, Parallelism par = {},
                                               CompositionTable composition = {})
      : Base(std::move(system), std::move(potential), solver, par), tt_(tt), composition_(std::move(composition)) {
    if (!(tt.monitor_scale >= 0.0 && std::isfinite(tt.monitor_scale)))
      throw InvalidInput("integrator.monitor_scale: must be a finite number > 0 (or 0: |V| at the start), got " +
                         std::to_string(tt.monitor_scale));
    if (std::isnan(tt.finish_time)) throw InvalidInput("integrator.duration: the finish time is not a number");
    this->use_rotation_solvers();
    for (const double g : composition_.gamma()) reach_ += std::abs(g);
    // Each drift of each sub-step extrapolates its own relative rotations.
    this->set_stages(2 * composition_.stages());
  }

  /// Evaluates the potential at s (time t): E0 = H(s), and c = |V(s)| unless
  /// given; InvalidInput if that is 0 (no scale to adapt to).
  void initialize(const SystemState& s, double t) {
    Base::initialize(s, t);
    time_ = t;
    time_carry_ = 0.0;
    last_dt_ = 0.0;
    reference_energy_ = total_energy(s, this->system_, this->eval_);
    scale_ = tt_.monitor_scale > 0.0 ? tt_.monitor_scale : std::abs(this->eval_.energy);
    if (!(scale_ > 0.0 && std::isfinite(scale_)))
      throw InvalidInput(std::string("integrator.monitor_scale: the potential energy at the start is ") +
                         (this->eval_.energy == 0.0 ? "0 (or underflows)" : "not finite") +
                         ", which gives no default scale; give monitor_scale (the size of -V where steps should "
                         "start to shrink)");
  }

  /// One step of fictitious size eps: drift-kick-drift (the file comment),
  /// or the composition's sub-steps gamma_i eps. The `s` argument (the loop's
  /// fictitious time) is not used: the physical time advances by the sum of
  /// the drifts' dt. A step that would pass the finish time is shortened to
  /// end there (the file comment), and time() is then the finish time; its
  /// solve report is its last trial's (the evaluations of every trial count);
  /// a step from the finish time has length 0.
  void step(SystemState& state, double /*s*/, double eps) {
    if (!(time_ + eps * reach_ >= tt_.finish_time)) {
      advance(state, eps);
      return;
    }
    const SystemState start = state;
    const auto predictors = this->predictors_;
    const auto x_carry = this->x_carry_;
    const double time0 = time_, carry0 = time_carry_;
    advance(state, eps);
    if (time_ <= tt_.finish_time) return;
    // The time left, as the compensated sum holds it (time_ - carry is the sum).
    const double left = (tt_.finish_time - time0) + carry0;
    const auto miss = [&](double e) {
      this->predictors_ = predictors;
      this->x_carry_ = x_carry;
      time_ = time0;
      time_carry_ = carry0;
      state = start;
      advance(state, e);
      return last_dt_ - left;
    };
    // Illinois: f(0) = -left < 0 < f(eps); a trial replaces the end of its
    // sign, and halves the other end's f when it keeps the same end twice.
    // Converged at a dt within 4 eps of the size of t: the state's offset
    // from the finish time is round-off.
    const double tolerance =
        4.0 * std::numeric_limits<double>::epsilon() * std::max(std::abs(tt_.finish_time), std::abs(time0));
    double a = 0.0, fa = -left, b = eps, fb = last_dt_ - left, f = fb;
    for (int it = 0; it < 100 && std::abs(f) > tolerance; ++it) {
      const double e = b - fb * (b - a) / (fb - fa);
      f = miss(e);
      if ((f > 0) == (fb > 0)) {
        fa *= 0.5;
      } else {
        a = b;
        fa = fb;
      }
      b = e;
      fb = f;
    }
    if (std::abs(f) > tolerance)
      throw StepFailure("the last step could not be fitted to end at t = " + std::to_string(tt_.finish_time) +
                        " (its physical step misses it by " + std::to_string(f) + ")");
    time_ = tt_.finish_time;
    time_carry_ = 0.0;
    last_dt_ = left;
  }

  /// The physical time of the current state.
  double time() const { return time_; }
  /// The physical step dt of the last step (0 before the first).
  double last_time_step() const { return last_dt_; }
  /// E0, the energy at initialize() (the extended Hamiltonian's p_t = -E0).
  double reference_energy() const { return reference_energy_; }
  /// Sets E0 after initialize(): a run that continues another in the same
  /// extended phase space (the same Gamma), such as the reversed run of a
  /// reversibility check, whose own K + V differs from E0 by the energy error.
  void set_reference_energy(double e0) { reference_energy_ = e0; }
  /// c of the monitor in use.
  double monitor_scale() const { return scale_; }
  /// g(u) with this stepper's c.
  double monitor(double u) const { return time_transform_monitor(u, scale_); }

  /// The base's numbers (ImplicitStepperBase::internal_state), then t, its
  /// carry, E0 and c.
  std::vector<double> internal_state() const {
    std::vector<double> v = Base::internal_state();
    v.insert(v.end(), {time_, time_carry_, reference_energy_, scale_});
    return v;
  }
  void resume(const SystemState& s, double t, const std::vector<double>& internal) {
    initialize(s, t);
    if (internal.size() < 4) throw InvalidInput("checkpoint: time-transformed integrator data too short");
    const auto own = internal.end() - 4;
    this->restore(std::vector<double>(internal.begin(), own), "the time-transformed integrator");
    time_ = own[0];
    time_carry_ = own[1];
    reference_energy_ = own[2];
    scale_ = own[3];
  }
  /// Checkpoint fields: the base's (ImplicitStepperBase::save) and
  /// "stepper.time" (the physical time t and the carry of its compensated
  /// sum), "stepper.reference_energy" (E0), "stepper.monitor_scale" (c): a
  /// resumed run continues bit for bit.
  void save(CheckpointFields& out) const {
    Base::save(out);
    out.put_f64("stepper.time", {time_, time_carry_});
    out.put_f64("stepper.reference_energy", {reference_energy_});
    out.put_f64("stepper.monitor_scale", {scale_});
  }
  void load(const SystemState& s, double t, const CheckpointFields& in) {
    initialize(s, t);
    this->load_fields(in, "the time-transformed integrator");
    const std::vector<double>& time = in.f64("stepper.time", 2);
    time_ = time[0];
    time_carry_ = time[1];
    reference_energy_ = in.f64_value("stepper.reference_energy");
    scale_ = in.f64_value("stepper.monitor_scale");
  }

 private:
  /// The step of fictitious size eps of step(), without the finish time.
  void advance(SystemState& state, double eps) {
    const System& sys = this->system_;
    for (SolveReport& r : this->reports_) r = {};
    double dt = 0.0;
    const std::vector<double>& gamma = composition_.gamma();
    for (std::size_t i = 0; i < gamma.size(); ++i) {
      const double e = gamma.size() == 1 ? eps : gamma[i] * eps;
      const double dt1 = 0.5 * e * monitor(kinetic_energy(state, sys) - reference_energy_);
      drift(state, dt1, 2 * i);
      this->evaluate_at(state);
      const double tau = e * monitor(-this->eval_.energy);
      detail::for_each_body(sys, this->par_, [&](std::size_t a) { kick(state, a, tau); });
      const double dt2 = 0.5 * e * monitor(kinetic_energy(state, sys) - reference_energy_);
      drift(state, dt2, 2 * i + 1);
      dt += dt1 + dt2;
    }
    this->evaluate_at(state);
    detail::for_each_body(sys, this->par_, [&](std::size_t a) { this->note_finite(state, a); });
    this->finish_step(state, /*checked=*/true);
    // t += dt as a compensated sum: the steps are not all the same, and
    // 10^5 of them rounded at the size of t would cost the trajectory rows
    // digits of t (the loop's t0 + k h has no such sum to make).
    const double y = dt - time_carry_;
    const double t1 = time_ + y;
    time_carry_ = (t1 - time_) - y;
    time_ = t1;
    last_dt_ = dt;
  }

  /// Every body's free motion over dt by the LGVI (the file comment), with
  /// the predictors of `stage` (2 i: sub-step i's first drift, 2 i + 1 its
  /// second); each body's solve report added to the step's.
  void drift(SystemState& state, double dt, std::size_t stage) {
    const System& sys = this->system_;
    this->select_stage(stage);
    detail::for_each_body(sys, this->par_, [&](std::size_t a) {
      const RigidBody& body = sys.body(a);
      this->add_to_position(state.x[a], a, (dt / body.mass()) * state.p[a]);
      RotationPredictor& predictor = this->predictor(a);
      const Vector3<double> w = body.admissible_momentum(state.w[a]);
      if (predictor.empty()) predictor.reset(S3d::exp(body.inertia_inverse() * ((0.25 * dt) * w)));
      S3d f = predictor.predict();
      SolveReport report;
      this->solver(a).solve((0.25 * dt) * w, f, report);
      predictor.push(f);
      state.q[a] = state.q[a].times_near_identity(f);
      state.w[a] = body.admissible_momentum(f.inverse().act(w));
      this->reports_[a].iterations += report.iterations;
      this->reports_[a].residual_evaluations += report.residual_evaluations;
    });
    this->select_stage(0);
  }

  /// p += tau F, w += 2 tau M for body a (w kept admissible: no axial
  /// momentum for a linear body).
  void kick(SystemState& state, std::size_t a, double tau) {
    state.p[a] += tau * this->force(a);
    state.w[a] = this->system_.body(a).admissible_momentum(state.w[a] + (2.0 * tau) * this->torque(a));
  }

  TimeTransformOptions tt_;
  CompositionTable composition_;  ///< the sub-steps gamma_i of a step (plain: one, gamma = 1)
  double reach_ = 0.0;  ///< sum |gamma_i|: a step advances t by at most eps reach_ (g <= 1)
  double time_ = 0.0, time_carry_ = 0.0, last_dt_ = 0.0, reference_energy_ = 0.0, scale_ = 1.0;
};

}  // namespace lgvi
