// The quaternion Lie group variational integrator of Shen & Leok, in its
// Hamiltonian form (the default) and its Lagrangian (position-position) form,
// for a system of N bodies (system.hpp). Each body takes the paper's step with
// the force and torque of the whole system's potential; the N rotation solves
// are independent and run on the stepper's threads, and the potential is
// evaluated once per step at the new configuration of all bodies:
//   per body a: x_a1 = x_a0 + (h/m_a)(p_a0 + (h/2) F_a0); solve g_a(f_a) = (h/4)(w_a0 + h M_a0);
//               q_a1 = q_a0 f_a (formed as q_a0 + q_a0 (f_a - e): S3::times_near_identity);
//   one evaluation of the system at (x_1, q_1);
//   per body a: p_a1 = p_a0 + (h/2)(F_a0 + F_a1); w_a1 = pi(f_a)^T (w_a0 + h M_a0) + h M_a1.
// Linear bodies and points (rigid_body.hpp) take the same step: their
// rotation equation is solved in closed form (rotation_solver.hpp), which
// sees only the part of w_a0 + h M_a0 across the axis; w_a1 is formed from
// that part (the axial part of a torque does nothing to a body without
// inertia about its axis; rotated by f it would leak across the axis, an
// O(h) error) and keeps no axial component (RigidBody::admissible_momentum).
// A single body is N = 1 (single_body.hpp: SingleBody<Method, P>).
// A body with reaction wheels (a gyrostat, wheels.hpp) takes the same step
// with its rotation equation P(J_s f_v + (h/2) h_w) = (h/4)(w0 + h M0) and
// the same update of w; its wheels' momenta take half of each step's motor
// impulse before the solve and half after (set_wheel_torques, gyrostat.hpp).
//
// Discrete Lagrangian (paper eq. "discrtelag", from Wendlandt & Marsden):
//   L_d = h( m|x1 - x0|^2/(2h^2) + (2/h^2) Im(q0^* q1)^T J Im(q0^* q1) - (V0 + V1)/2 ).
// With force F = -dV/dx and body torque M (F(q) dV/dq = -2 M, potential.hpp)
// and f = q0^* q1 = exp(xi0), the paper's Hamiltonian system "eqhamilton" is
//   p0 = m (x1 - x0)/h - (h/2) F0                   -> x1 = x0 + (h/m)(p0 + (h/2) F0)
//   w0 = (4/h)(f_s J f_v + f_v x J f_v) - h M0      -> solve for xi0 (rotation_solver.hpp)
//   p1 = m (x1 - x0)/h + (h/2) F1                   =  p0 + (h/2)(F0 + F1)
//   w1 = (4/h) G(f) J Im(f) + h M1                  =  (4/h)(f_s J f_v - f_v x J f_v) + h M1
// p1 and w1 are computed in their second, algebraically equal forms:
//  * m (x1 - x0)/h loses about log10(|x|/|x1 - x0|) digits to cancellation
//    (two orders on the paper's orbit), which shows directly in x cross p;
//  * (4/h)(f_s J f_v - f_v x J f_v) = pi(f)^T (4/h)(f_s J f_v + f_v x J f_v)
//    = pi(f)^T (w0 + h M0) holds for |f| = 1 exactly; evaluated as the paper
//    writes it, the solver's residual and the rounding of |f| (the same each
//    step for a steady spin) enter w1 as a systematic error, which makes the
//    angular momentum drift linearly (4e-12 over 1e5 steps on the paper's
//    orbit, against 3e-13 with the rotated form; see tests/test_lgvi.cpp).
#pragma once

#include <lgvi/methods/method_traits.hpp>
#include <lgvi/error.hpp>
#include <lgvi/interaction.hpp>
#include <lgvi/methods/implicit_stepper.hpp>
#include <lgvi/gyrostat.hpp>
#include <lgvi/potential.hpp>
#include <lgvi/rigid_body.hpp>
#include <lgvi/rotation_solver.hpp>
#include <lgvi/s3.hpp>
#include <lgvi/state.hpp>
#include <lgvi/stepper.hpp>
#include <lgvi/system.hpp>

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

namespace lgvi {

/// The Hamiltonian-side quaternion LGVI on (x, q, p, w) for a system
/// potential I (N bodies; one body: SingleBody<LieGroupVariationalIntegrator, P>).
template <SystemPotential I>
class LieGroupVariationalIntegrator : public detail::ImplicitStepperBase<I, RotationPredictor> {
  using Base = detail::ImplicitStepperBase<I, RotationPredictor>;

 public:
  static constexpr MethodTraits traits{"lgvi", "the quaternion LGVI of Shen & Leok, Hamiltonian form", 2,
                                      /*symmetric=*/true, /*two_step=*/false, /*implicit=*/true,
                                      /*accepts_forcing=*/true, /*needs_principal_axes=*/false,
                                      /*free_body_only=*/false, /*linear_bodies=*/true};

  LieGroupVariationalIntegrator(System system, I potential, SolverOptions solver = {}, Parallelism par = {})
      : Base(std::move(system), std::move(potential), solver, par), w_half_(this->system_.size()), f_(this->system_.size()) {
    this->use_rotation_solvers();
    // In batches from two full ones on; fewer bodies keep the scalar solves
    // (a batch pays for four lanes whatever it holds), as do systems of
    // linear bodies only (none batchable). At the first step a
    // batch seeds all its bodies' predictors before solving: a body after
    // one whose solve fails has its predictor seeded from this attempt,
    // where the loop below would leave it empty.
    batched_ = solver.kind == SolverKind::Newton && this->system_.size() >= 2 * RotationSolveBatch::lanes &&
               this->any_batchable();
    // Gyrostats: their own rotation equation (gyrostat.hpp), solved body by body.
    for (std::size_t a = 0; a < this->system_.size(); ++a)
      if (this->system_.body(a).has_wheels()) {
        if (gyrostats_.empty()) gyrostats_.resize(this->system_.size());
        gyrostats_[a].emplace(this->system_.body(a).wheels().reduced_inertia(), solver);
      }
    if (!gyrostats_.empty()) {
      batched_ = false;
      wheel_impulse_.resize(this->system_.size());
      wheel_speed_.resize(this->system_.size());
      for (std::size_t a = 0; a < this->system_.size(); ++a) {
        wheel_impulse_[a].assign(this->system_.body(a).wheels().size(), 0.0);
        wheel_speed_[a].assign(this->system_.body(a).wheels().size(), 0.0);
      }
    }
  }

  /// Motor torques on the bodies' reaction wheels, each held between its
  /// samples (gyrostat.hpp). Before initialize(). Throws InvalidInput for a
  /// body or wheel that does not exist.
  void set_wheel_torques(std::vector<WheelTorque> torques) {
    for (const WheelTorque& u : torques)
      if (u.body >= this->system_.size() || u.wheel >= this->system_.body(u.body).wheels().size())
        throw InvalidInput("wheel torque: body " + std::to_string(u.body) + " has no wheel " + std::to_string(u.wheel));
    wheel_torques_ = std::move(torques);
  }
  /// Attitude control of body 0 through its wheels (gyrostat.hpp): its sampled, held commands drive
  /// every wheel of that body (with no set_wheel_torques for it). Before initialize().
  void set_wheel_control(WheelAttitudeControl control) {
    if (!gyrostat(0) || control.command().size() != this->system_.body(0).wheels().size())
      throw InvalidInput("wheel control: body 0 has no reaction wheels, or not as many as the controller was built for");
    wheel_control_ = std::move(control);
  }

  /// The work of the motor torques since initialize(): sum over steps and
  /// wheels of impulse x the wheel's mean relative speed at the step's ends.
  double wheel_work() const { return wheel_work_; }
  /// The work of everything besides the potential: the forcing's and the motor torques' (E - E0 - W is
  /// then the integrator's error; integrate.hpp reports it).
  double forcing_work() const { return gyrostats_.empty() ? Base::forcing_work() : Base::forcing_work() + wheel_work_; }
  /// The impulse each wheel received in the last step (body, wheel), after
  /// the limits: its mean applied torque is this / h.
  const std::vector<std::vector<double>>& last_wheel_impulses() const { return wheel_impulse_; }

  void initialize(const SystemState& s, double t) {
    Base::initialize(s, t);
    wheel_work_ = 0.0;
    if (wheel_control_) wheel_control_->reset();
    if (!gyrostats_.empty()) {
      if (s.eta.size() != s.size())
        throw InvalidInput("state: bodies with reaction wheels need their momenta eta (SystemState::eta)");
      for (std::size_t a = 0; a < s.size(); ++a)
        if (s.eta[a].size() != this->system_.body(a).wheels().size())
          throw InvalidInput("state: eta[" + std::to_string(a) + "] has " + std::to_string(s.eta[a].size()) +
                             " momenta; body " + std::to_string(a) + " has " +
                             std::to_string(this->system_.body(a).wheels().size()) + " wheels");
    }
  }


  /// One step of the paper's system "eqhamilton" (forms above). Each solve
  /// starts from its RotationPredictor's extrapolation of the last steps' f.
  /// With a forcing, F and M are the potential's plus the forcing's, at the
  /// start and at the end of the step (forcing.hpp).
  void step(SystemState& s, double t, double h) { step_into(s, s, t, h); }

  /// The step from `from` into `to`: the same bits as `to = from; step(to,
  /// t, h)` (to's contents before are not read), without the copy where the
  /// step writes every part of the new state itself, from `from`'s (no
  /// forcing, no wheels, and `to` of from's size): the run loop's form
  /// (integrate.hpp), where `from` stays the last good state if the step
  /// fails. At 10^6 bodies the copy is a pass over 104 MB each way per step.
  void step_from(const SystemState& from, SystemState& to, double t, double h) {
    const std::size_t n = from.size();
    const bool same_size = to.x.size() == n && to.q.size() == n && to.p.size() == n && to.w.size() == n;
    if (!this->forcing().empty() || !gyrostats_.empty() || !from.eta.empty() || !to.eta.empty() || !same_size) {
      detail::copy_state(*this, to, from);
      step_into(to, to, t, h);
      return;
    }
    step_into(from, to, t, h);
  }

 private:
  /// The step from `in` into `s` (the same state for step(); for
  /// step_from's other case no forcing and no wheels, which read and write s
  /// before the solves): the solves' pass reads x, q, p and w from `in` and
  /// writes x and q to s; the last pass writes p and w.
  void step_into(const SystemState& in, SystemState& s, double t, double h) {
    const System& sys = this->system_;
    this->begin_step(s, t);
    if (!gyrostats_.empty()) kick_wheels(s, t, h);
    // Body a's right side b = (h/4)(w0 + h M0) of g(xi0) = b (w_half_[a] =
    // w0 + h M0), and the initial guess of its solve: the first-order
    // estimate xi0 ~ J^{-1} b (a gyrostat's J_s^{-1} (b - c)) at the first step.
    auto right_side = [&](std::size_t a) {
      w_half_[a] = in.w[a] + h * this->torque(a);
      RotationPredictor& predictor = this->predictor(a);
      if (predictor.empty()) {
        const Vector3<double> b = (0.25 * h) * w_half_[a];
        predictor.reset(gyrostat(a) ? S3d::exp(sys.body(a).wheels().reduced_inertia().inverse() *
                                               (b - wheel_offset(s, a, h)))
                                    : S3d::exp(sys.body(a).inertia_inverse() * b));
      }
      return predictor.predict();
    };
    // Body a after its solve gave f.
    auto advance = [&](std::size_t a, const S3d& f) {
      this->predictor(a).push(f);
      this->drift(in, s, a, h);
      s.q[a] = in.q[a].times_near_identity(f);
      f_[a] = f;
    };
    if (batched_) {
      // The solves of consecutive bodies side by side (RotationSolveBatch):
      // each the same bits as alone. A body the batch leaves unsolved is
      // solved alone, which reports its failure as the loop below would.
      constexpr int lanes = RotationSolveBatch::lanes;
      detail::for_each_body_batch(sys, this->par_, lanes, [&](std::size_t first, std::size_t count) {
        RotationSolveBatch batch;
        S3d guess[lanes];
        for (std::size_t l = 0; l < count; ++l) {
          guess[l] = right_side(first + l);
          this->solver(first + l).load(batch, static_cast<int>(l), (0.25 * h) * w_half_[first + l], guess[l]);
        }
        detail::newton_cayley_lanes(batch, static_cast<int>(count), this->opt_.tolerance, this->opt_.max_iterations);
        for (std::size_t l = 0; l < count; ++l) {
          const std::size_t a = first + l;
          const auto lane = static_cast<int>(l);
          if (batch.solved[lane] && this->solver(a).batchable()) {
            this->reports_[a] = {batch.iterations[lane], batch.residual_evaluations[lane], 0};
            advance(a, S3d(batch.f[0][lane], batch.f[1][lane], batch.f[2][lane], batch.f[3][lane]));
            continue;
          }
          detail::for_body(sys, a, [&] { this->solver(a).solve((0.25 * h) * w_half_[a], guess[l], this->reports_[a]); });
          advance(a, guess[l]);
        }
      });
    } else {
      detail::for_each_body(sys, this->par_, [&](std::size_t a) {
        S3d f = right_side(a);
        if (gyrostat(a))
          detail::for_body(sys, a, [&] {
            gyrostats_[a]->solve((0.25 * h) * w_half_[a], wheel_offset(s, a, h), f, this->reports_[a]);
          });
        else
          this->solver(a).solve((0.25 * h) * w_half_[a], f, this->reports_[a]);
        advance(a, f);
      });
    }
    this->evaluate_at(s);
    // Without a forcing the momenta are updated in one pass over the bodies,
    // after which each body's state is final: whether it is finite is noted
    // there, on the threads, rather than tested in a serial loop after it;
    // only a failure is examined again, serially, for the same message (the
    // lowest failing body) as a serial test gives. Every body is updated
    // either way.
    const bool checked = this->forcing().empty();
    this->end_step(
        s, t + h, h,
        [&](std::size_t a) {
          this->kick(s, a, h);
          const RigidBody& body = sys.body(a);
          s.w[a] =
              body.admissible_momentum(f_[a].inverse().act(body.admissible_momentum(w_half_[a])) + h * this->torque(a));
          if (checked) this->note_finite(s, a);
        },
        // The wheels' second half-impulse once w is final (not in the kick: a forcing that reads the
        // momenta calls it more than once), before the forcing's work, whose power reads their rate.
        [&] {
          if (!gyrostats_.empty())
            for (std::size_t a = 0; a < sys.size(); ++a) finish_wheels(s, a);
        });
    this->finish_step(s, checked);
  }

 public:
  /// Adds a forcing (forcing.hpp) to the potential's force and torque, by the
  /// discrete Lagrange-d'Alembert principle. Before initialize().
  void set_forcing(ForcingSet forcing) { this->install_forcing(std::move(forcing)); }

  /// Resumes at `s` (evaluating the potential there) with saved internals.
  void resume(const SystemState& s, double t, const std::vector<double>& internal) {
    initialize(s, t);
    this->restore(internal, "the predictor");
  }
  /// Resumes at `s` from a checkpoint's fields (ImplicitStepperBase::save).
  void load(const SystemState& s, double t, const CheckpointFields& in) {
    initialize(s, t);
    load_time_ = t;
    this->load_fields(in, "the predictor");
  }

 private:
  bool gyrostat(std::size_t a) const { return !gyrostats_.empty() && gyrostats_[a].has_value(); }

  /// With reaction wheels, a checkpoint's fields (nothing otherwise): "stepper.wheels.work", the motor
  /// torques' work so far, and the wheel controller's ("stepper.wheel_control.*", gyrostat.hpp). The
  /// wheels' momenta are the state's (SystemState::eta); the torque tables are functions of t.
  void save_extra(CheckpointFields& out) const override {
    if (gyrostats_.empty()) return;
    out.put_f64("stepper.wheels.work", {wheel_work_});
    if (wheel_control_) wheel_control_->save(out, "stepper.wheel_control");
  }
  void load_extra(const CheckpointFields& in) override {
    if (gyrostats_.empty()) return;
    wheel_work_ = in.f64_value("stepper.wheels.work");
    if (wheel_control_) wheel_control_->load(in, "stepper.wheel_control", load_time_, false);
  }

  /// c = (h/2) h_w(eta_half): the wheels' momentum at the middle of the step (s.eta holds eta_half
  /// between kick_wheels and finish_wheels).
  Vector3<double> wheel_offset(const SystemState& s, std::size_t a, double h) const {
    return (0.5 * h) * this->system_.body(a).wheels().momentum(s.eta[a].data());
  }

  /// Before the solves: each wheel's impulse over [t, t + h] after its limits, its relative speed at
  /// t, and half of the impulse given (s.eta becomes eta_half). A torque is clipped to +-max_torque;
  /// a wheel at or beyond max_speed gets no impulse that would speed it up further.
  void kick_wheels(SystemState& s, double t, double h) {
    const System& sys = this->system_;
    for (std::size_t a = 0; a < sys.size(); ++a) {
      std::fill(wheel_impulse_[a].begin(), wheel_impulse_[a].end(), 0.0);
      if (!gyrostat(a)) continue;
      const Wheels& wheels = sys.body(a).wheels();
      const Vector3<double> omega = wheels.body_rate(s.w[a], s.eta[a].data());
      for (std::size_t i = 0; i < wheels.size(); ++i) wheel_speed_[a][i] = wheels.relative_speed(i, s.eta[a].data(), omega);
    }
    for (const WheelTorque& u : wheel_torques_) {
      const Wheel& wheel = sys.body(u.body).wheels()[u.wheel];
      wheel_impulse_[u.body][u.wheel] +=
          wheel.speed_limited(u.torque.impulse(t, t + h, wheel.max_torque), wheel_speed_[u.body][u.wheel]);
    }
    if (wheel_control_) {
      const Wheels& wheels = sys.body(0).wheels();
      wheel_control_->sample(t, s.q[0], wheels.body_rate(s.w[0], s.eta[0].data()), wheel_speed_[0]);
      for (std::size_t i = 0; i < wheels.size(); ++i)
        wheel_impulse_[0][i] += wheels[i].applied_torque(wheel_control_->command()[i], wheel_speed_[0][i]) * h;
    }
    for (std::size_t a = 0; a < sys.size(); ++a)
      for (std::size_t i = 0; i < wheel_impulse_[a].size(); ++i) s.eta[a][i] += 0.5 * wheel_impulse_[a][i];
  }

  /// After body a's w is final (serially, in body order): the other half of its wheels' impulses, and
  /// their work (impulse x the mean of the relative speeds at the step's ends).
  void finish_wheels(SystemState& s, std::size_t a) {
    if (!gyrostat(a)) return;
    const Wheels& wheels = this->system_.body(a).wheels();
    std::vector<double>& eta = s.eta[a];
    for (std::size_t i = 0; i < wheels.size(); ++i) eta[i] += 0.5 * wheel_impulse_[a][i];
    for (const double e : eta)
      if (!std::isfinite(e)) throw StepFailure("a reaction wheel's momentum is not finite", "check the motor commands");
    const Vector3<double> omega = wheels.body_rate(s.w[a], eta.data());
    double work = 0.0;
    for (std::size_t i = 0; i < wheels.size(); ++i)
      work += wheel_impulse_[a][i] * 0.5 * (wheel_speed_[a][i] + wheels.relative_speed(i, eta.data(), omega));
    wheel_work_ += work;
  }

  std::vector<Vector3<double>> w_half_;
  std::vector<S3d> f_;
  bool batched_ = false;  ///< the rotation solves in RotationSolveBatch (step)
  std::vector<std::optional<GyrostatRotationSolver>> gyrostats_;  ///< per body (empty: no body has wheels)
  std::vector<WheelTorque> wheel_torques_;
  std::optional<WheelAttitudeControl> wheel_control_;
  std::vector<std::vector<double>> wheel_impulse_, wheel_speed_;  ///< per body and wheel, this step's
  double wheel_work_ = 0.0;
  double load_time_ = 0.0;  ///< the t of load(), for load_extra's checks
};

/// The Lagrangian-side (position-position) form: the paper's discrete
/// Euler-Lagrange equations
///   m (x2 - 2 x1 + x0)/h^2 = F1,
///   G(q0^* q1) J Im(q0^* q1) + G(q2^* q1) J Im(q2^* q1) = (h^2/4) F(q1) dV/dq(x1, q1) = -(h^2/2) M1,
/// i.e. with f0 = q0^* q1, f1 = q1^* q2 (G(f1^*) J Im(f1^*) = -g(f1)):
///   g(f1) = f0_s J f0_v - f0_v x J f0_v + (h^2/2) M1.
/// The first step from (x0, q0, p0, w0) comes from the discrete Legendre
/// transform p0 = -D1 L_d, the same equation as the Hamiltonian step; the
/// momenta reported along the way are p_k = D2 L_d(k-1, k):
///   p_k = m (x_k - x_{k-1})/h + (h/2) F_k,  w_k = (4/h)(f_s J f_v - f_v x J f_v) + h M_k.
/// A two-step method: the step size must stay the same from call to call.
///
/// The positions in summed form (Stormer's recurrence as a sum of
/// increments, algebraically the same): with d_k = x_{k+1} - x_k kept as a
/// number of its own,
///   d_{k+1} = d_k + (h^2/m) F_{k+1},  x_{k+2} = x_{k+1} + d_{k+1} (a compensated sum),
///   p_{k+1} = (m/h) d_k + (h/2) F_{k+1}.
/// Written as 2 x1 - x0 + (h^2/m) F1, the recurrence rounds at the size of x
/// every step, and that rounding enters the implied velocity (x1 - x0)/h
/// with a factor 1/h: in the radial free flight of scenarios/paper.toml at
/// h = 1e-4 the angular momentum error grows like t^2, to 4.7e-7 by t = 200
/// (scripts/roundoff_figures.sh; 1.0e-10 in summed form). In summed form the
/// increment carries its own rounding only (as the Hamiltonian form's
/// momentum does), x keeps what its sums lose in the base's carry (drift),
/// and p_k no longer pays the cancellation in x_k - x_{k-1}.
template <SystemPotential I>
class LagrangianLieGroupVariationalIntegrator : public detail::ImplicitStepperBase<I, RotationPredictor> {
  using Base = detail::ImplicitStepperBase<I, RotationPredictor>;

 public:
  static constexpr MethodTraits traits{"lgvi-lagrangian", "the quaternion LGVI of Shen & Leok, position-position (Lagrangian) form", 2,
                                      /*symmetric=*/true, /*two_step=*/true, /*implicit=*/true,
                                      /*accepts_forcing=*/false, /*needs_principal_axes=*/false,
                                      /*free_body_only=*/false, /*linear_bodies=*/true};

  LagrangianLieGroupVariationalIntegrator(System system, I potential, SolverOptions solver = {},
                                          Parallelism par = {})
      : Base(std::move(system), std::move(potential), solver, par) {
    const std::size_t n = this->system_.size();
    this->use_rotation_solvers();
    x_next_.resize(n);
    d_.resize(n);
    f_.resize(n);
    q_next_.resize(n);
    next_ = SystemState(n);
  }

  /// Evaluates the potential at s; configuration 1 is computed at the first
  /// step, from the Legendre transform p0 = -D1 L_d(0, 1) with that step's h.
  void initialize(const SystemState& s, double t) {
    Base::initialize(s, t);
    phase_ = Phase::Fresh;
  }

  /// Advances from configuration k to k + 1 (computed one step ahead), reports
  /// p_{k+1}, w_{k+1}, and solves the DEL for configuration k + 2.
  void step(SystemState& s, double /*t*/, double h) {
    const System& sys = this->system_;
    if (phase_ == Phase::Fresh) start(s, h);
    if (phase_ == Phase::Resumed) h_ = h;  // the checkpoint does not hold h: the run continues with its own
    phase_ = Phase::Running;
    if (h != h_)
      throw InvalidInput("integrator.step: lgvi-lagrangian is a two-step method and needs the same step size on "
                         "every call (got " + std::to_string(h) + " after " + std::to_string(h_) + ")");
    for (std::size_t a = 0; a < sys.size(); ++a) {
      next_.x[a] = x_next_[a];
      next_.q[a] = q_next_[a];
    }
    this->evaluate_at(next_);
    detail::for_each_body(sys, this->par_, [&](std::size_t a) {
      const RigidBody& body = sys.body(a);
      const Vector3<double>& force = this->eval_.force[a];
      const Vector3<double>& torque = this->eval_.torque[a];
      const S3d& f0 = f_[a];
      const Vector3<double> f0v = f0.vec();
      const Vector3<double> jf0v = body.inertia() * f0v;
      const Vector3<double> g_backward = f0.w() * jf0v - f0v.cross(jf0v);
      s.x[a] = x_next_[a];
      s.q[a] = q_next_[a];
      s.p[a] = (body.mass() / h) * d_[a] + (0.5 * h) * force;
      s.w[a] = body.admissible_momentum((4.0 / h) * g_backward + h * torque);
      // DEL for configuration k + 2.
      S3d f = this->predictor(a).predict();
      this->solver(a).solve(g_backward + (0.5 * h * h) * torque, f, this->reports_[a]);
      this->predictor(a).push(f);
      d_[a] += (h * h / body.mass()) * force;
      this->add_to_position(x_next_[a], a, d_[a]);
      q_next_[a] = q_next_[a].times_near_identity(f);
      f_[a] = f;
    });
    this->finish_step(s);
  }

  /// Besides the state, per body: the configuration one step ahead (x, then
  /// q scalar first), the increment d to it and the predictor; then the
  /// positions' carry. Before the first step: nothing.
  std::vector<double> internal_state() const {
    if (phase_ == Phase::Fresh) return {};
    return Base::internal_state();
  }
  void resume(const SystemState& s, double t, const std::vector<double>& internal) {
    Base::initialize(s, t);
    phase_ = Phase::Fresh;
    if (internal.empty()) return;
    if (internal.size() < 7) throw InvalidInput("checkpoint: Lagrangian integrator data too short");
    this->restore(upgraded(s, internal), "Lagrangian integrator");
    phase_ = Phase::Resumed;
  }
  /// Checkpoint fields: "stepper.started" (0 before the first step, then
  /// nothing else), then the base's (ImplicitStepperBase::save) with this
  /// form's own (save_extra).
  void save(CheckpointFields& out) const {
    out.put_i64("stepper.started", {phase_ == Phase::Fresh ? 0 : 1});
    if (phase_ != Phase::Fresh) Base::save(out);
  }
  void load(const SystemState& s, double t, const CheckpointFields& in) {
    if (in.has("stepper.internal")) {
      const std::vector<double>& internal = in.f64("stepper.internal");
      detail::reading_stepper_internal([&] { resume(s, t, internal); });
      return;
    }
    Base::initialize(s, t);
    phase_ = Phase::Fresh;
    if (in.i64_value("stepper.started") == 0) return;
    this->load_fields(in, "Lagrangian integrator");
    phase_ = Phase::Resumed;
  }

 private:
  /// Configuration 1 from the Legendre transform p0 = -D1 L_d(0, 1).
  void start(const SystemState& s, double h) {
    const System& sys = this->system_;
    detail::for_each_body(sys, this->par_, [&](std::size_t a) {
      const RigidBody& body = sys.body(a);
      const Vector3<double> b = (0.25 * h) * (s.w[a] + h * this->eval_.torque[a]);
      S3d f = S3d::exp(body.inertia_inverse() * b);
      this->solver(a).solve(b, f, this->reports_[a]);
      this->predictor(a).reset(f);
      d_[a] = (h / body.mass()) * (s.p[a] + (0.5 * h) * this->eval_.force[a]);
      x_next_[a] = s.x[a];
      this->add_to_position(x_next_[a], a, d_[a]);
      q_next_[a] = s.q[a].times_near_identity(f);
      f_[a] = f;
    });
    h_ = h;
    phase_ = Phase::Running;
  }

  /// Per body: x_next, q_next (scalar first), the increment d = x_next - x
  /// and the relative rotation f = q^* q_next (scalar first). Checkpoints
  /// written before the summed form hold the first 7 only.
  static constexpr std::size_t extra_numbers = 14, extra_numbers_before_summed_form = 7;
  void serialize_extra(std::size_t a, std::vector<double>& v) const override {
    const Vector4<double> q = q_next_[a].scalar_first(), f = f_[a].scalar_first();
    v.insert(v.end(), {x_next_[a].x(), x_next_[a].y(), x_next_[a].z(), q(0), q(1), q(2), q(3), d_[a].x(), d_[a].y(),
                       d_[a].z(), f(0), f(1), f(2), f(3)});
  }
  std::size_t extra_size() const override { return extra_numbers; }
  /// Per body: "stepper.next_position" x_next (3 numbers),
  /// "stepper.next_quaternion" q_next (4, scalar first),
  /// "stepper.next_increment" d (3), "stepper.relative_rotation" f (4).
  void save_extra(CheckpointFields& out) const override {
    std::vector<double> x, q, d, f;
    for (std::size_t a = 0; a < x_next_.size(); ++a) {
      const Vector4<double> qa = q_next_[a].scalar_first(), fa = f_[a].scalar_first();
      x.insert(x.end(), {x_next_[a].x(), x_next_[a].y(), x_next_[a].z()});
      q.insert(q.end(), {qa(0), qa(1), qa(2), qa(3)});
      d.insert(d.end(), {d_[a].x(), d_[a].y(), d_[a].z()});
      f.insert(f.end(), {fa(0), fa(1), fa(2), fa(3)});
    }
    out.put_f64("stepper.next_position", std::move(x));
    out.put_f64("stepper.next_quaternion", std::move(q));
    out.put_f64("stepper.next_increment", std::move(d));
    out.put_f64("stepper.relative_rotation", std::move(f));
  }
  void load_extra(const CheckpointFields& in) override {
    const std::size_t n = x_next_.size();
    const std::vector<double>& x = in.f64("stepper.next_position", 3 * n);
    const std::vector<double>& q = in.f64("stepper.next_quaternion", 4 * n);
    const std::vector<double>& d = in.f64("stepper.next_increment", 3 * n);
    const std::vector<double>& f = in.f64("stepper.relative_rotation", 4 * n);
    for (std::size_t a = 0; a < n; ++a) {
      x_next_[a] = Vector3<double>(x[3 * a], x[3 * a + 1], x[3 * a + 2]);
      q_next_[a] = S3d(q[4 * a], q[4 * a + 1], q[4 * a + 2], q[4 * a + 3]);
      d_[a] = Vector3<double>(d[3 * a], d[3 * a + 1], d[3 * a + 2]);
      f_[a] = S3d(f[4 * a], f[4 * a + 1], f[4 * a + 2], f[4 * a + 3]);
    }
  }
  void deserialize_extra(std::size_t a, const double* d) override {
    x_next_[a] = Vector3<double>(d[0], d[1], d[2]);
    q_next_[a] = S3d(d[3], d[4], d[5], d[6]);
    d_[a] = Vector3<double>(d[7], d[8], d[9]);
    f_[a] = S3d(d[10], d[11], d[12], d[13]);
  }

  /// A checkpoint of the form before the summed positions (7 numbers per body
  /// before the predictor, with or without the carry, which was then always
  /// 0) in today's layout: each body's increment d = x_next - x and relative
  /// rotation f = q^* q_next inserted, computed as the old form computed them
  /// at each step. The resumed run then continues in summed form (not
  /// bit-identical to the old binary's continuation: the arithmetic
  /// changed). (This form takes no forcing and no composition stages,
  /// its traits and scenario.hpp: forcing data is empty and there
  /// is one stage; the layout arithmetic holds either way.)
  std::vector<double> upgraded(const SystemState& s, const std::vector<double>& internal) const {
    const std::size_t n = s.size();
    const std::size_t predictors = this->stages() * RotationPredictor::serialized_size;
    const std::size_t forcing = this->forcing_internal_size();
    const std::size_t current = n * (extra_numbers + predictors) + forcing + 3 * n;
    const std::size_t old = n * (extra_numbers_before_summed_form + predictors) + forcing;
    if (internal.size() == current || (internal.size() != old && internal.size() != old + 3 * n)) return internal;
    std::vector<double> v;
    const std::size_t per_body = extra_numbers_before_summed_form + predictors;
    for (std::size_t a = 0; a < n; ++a) {
      const double* b = internal.data() + a * per_body;
      v.insert(v.end(), b, b + extra_numbers_before_summed_form);
      for (int k = 0; k < 3; ++k) v.push_back(b[k] - s.x[a](k));
      const Vector4<double> f = (s.q[a].inverse() * S3d(b[3], b[4], b[5], b[6])).scalar_first();
      v.insert(v.end(), {f(0), f(1), f(2), f(3)});
      v.insert(v.end(), b + extra_numbers_before_summed_form, b + per_body);
    }
    v.insert(v.end(), internal.begin() + static_cast<std::ptrdiff_t>(n * per_body),
             internal.begin() + static_cast<std::ptrdiff_t>(n * per_body + forcing));
    v.insert(v.end(), 3 * n, 0.0);  // the carry (0 in the old form)
    return v;
  }

  std::vector<Vector3<double>> x_next_;
  std::vector<Vector3<double>> d_;  ///< per body: x_next - x (the reported state's), summed (the class comment)
  std::vector<S3d> q_next_;
  std::vector<S3d> f_;  ///< per body: the relative rotation q^* q_next, as solved (the class comment)
  SystemState next_;
  double h_ = 0.0;
  /// Fresh: configuration 1 is computed at the next step; Resumed: it came
  /// from a checkpoint; Running: h_ is the step size of every call.
  enum class Phase { Fresh, Resumed, Running } phase_ = Phase::Fresh;
};

}  // namespace lgvi
