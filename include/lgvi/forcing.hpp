// Forcing: forces and torques that no potential gives (control laws, damping,
// thrust), depending on time, configuration and velocity.
//
// Discretization (discrete Lagrange-d'Alembert principle, Marsden & West,
// "Discrete mechanics and variational integrators", Acta Numerica 2001,
// section 3.2): the virtual work of the forcing over a step is approximated
// by the trapezoidal rule, so the discrete forces are
//   f_d^-(k) = (h/2) (F_k, M_k),   f_d^+(k) = (h/2) (F_{k+1}, M_{k+1}),
// half of the impulse at each end of the step, and they enter the step
// exactly where the potential's force -dV/dx and body torque M enter
// (lgvi.hpp): the step keeps its symmetry and second order, and composes.
// The end-of-step part is evaluated at the new state; when the forcing
// depends on the momenta (damping, a derivative gain) the momenta of the
// new state are solved for by fixed-point iteration (StepperBase in
// stepper.hpp). Then the discrete momentum balance holds exactly:
//   P_{k+1} - P_k = (h/2)(F_k + F_{k+1}),  L_{k+1} - L_k = (h/2)(tau_k + tau_{k+1}),
// with tau = x cross F + R(q) M the inertial torque about the origin.
//
// Conventions, those of the potentials (potential.hpp): F is an inertial
// force at the centre of mass, M a torque in the body frame. The work done
// by the forcing is accumulated with the same trapezoidal rule,
//   W_{k+1} = W_k + (h/2)(P_k + P_{k+1}),  P = sum_a F_a . v_a + M_a . Omega_a,
// so that E - E0 - W is the integrator's own energy error, bounded and of
// second order (tests/test_forcing.cpp).
#pragma once

#include <lgvi/checkpoint_fields.hpp>
#include <lgvi/error.hpp>
#include <lgvi/pair_damping.hpp>
#include <lgvi/rigid_body.hpp>
#include <lgvi/s3.hpp>
#include <lgvi/state.hpp>
#include <lgvi/system.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <concepts>
#include <cstdint>
#include <functional>
#include <limits>
#include <string>
#include <type_traits>
#include <utility>
#include <variant>
#include <vector>

namespace lgvi {

/// A force F (inertial frame, at the centre of mass) and a torque M (body
/// frame) on one body.
struct Wrench {
  Vector3<double> force = Vector3<double>::Zero();
  Vector3<double> torque = Vector3<double>::Zero();
};

/// The frame a prescribed vector is given in.
enum class ForcingFrame { Body, Inertial };

/// A vector-valued function of time: a constant, or the piecewise linear
/// interpolation of a table (t_i, v_i) with t_i strictly increasing. Outside
/// the table's span the end values are held: the scenario reader requires
/// the table to cover [0, T], and only the sub-steps of a composed step
/// reach a little beyond (the order-8 table's sub-step times run from
/// t - 0.05 h to t + 1.05 h).
class Profile {
 public:
  Profile() = default;
  static Profile constant(const Vector3<double>& v) {
    Profile p;
    p.values_.push_back(v);
    return p;
  }
  /// Throws InvalidInput unless the times are finite and strictly increasing
  /// and there are at least two rows.
  static Profile table(std::vector<double> t, std::vector<Vector3<double>> v) {
    if (t.size() != v.size()) throw InvalidInput("table: as many times as values are needed");
    if (t.size() < 2) throw InvalidInput("table: needs at least two rows (t and three components)");
    for (std::size_t i = 0; i < t.size(); ++i) {
      if (!std::isfinite(t[i]) || !v[i].allFinite()) throw InvalidInput("table: row " + std::to_string(i + 1) + " is not finite");
      if (i > 0 && !(t[i] > t[i - 1]))
        throw InvalidInput("table: the times must increase strictly (row " + std::to_string(i + 1) + ")");
    }
    Profile p;
    p.times_ = std::move(t);
    p.values_ = std::move(v);
    return p;
  }

  bool is_constant() const { return times_.empty(); }
  double t_begin() const { return is_constant() ? -std::numeric_limits<double>::infinity() : times_.front(); }
  double t_end() const { return is_constant() ? std::numeric_limits<double>::infinity() : times_.back(); }

  Vector3<double> at(double t) const {
    if (is_constant()) return values_[0];
    if (!(t > times_.front())) return values_.front();
    const auto hi = std::upper_bound(times_.begin(), times_.end(), t);
    if (hi == times_.end()) return values_.back();
    const std::size_t i = static_cast<std::size_t>(hi - times_.begin()) - 1;
    const double s = (t - times_[i]) / (times_[i + 1] - times_[i]);
    return values_[i] + s * (values_[i + 1] - values_[i]);
  }

 private:
  std::vector<double> times_;
  std::vector<Vector3<double>> values_ = {};
};

/// A prescribed torque, constant or tabulated, in the body or inertial frame
/// (an inertial torque tau acts as the body torque R^T tau).
struct AppliedTorque {
  Profile value;
  ForcingFrame frame = ForcingFrame::Body;
  static constexpr bool depends_on_velocity = false;
  Wrench operator()(double t, const RigidBodyState& s, const RigidBody&) const {
    const Vector3<double> v = value.at(t);
    return {Vector3<double>::Zero(), frame == ForcingFrame::Body ? v : s.q.inverse().act(v)};
  }
};

/// A prescribed force at the centre of mass, constant or tabulated, in the
/// inertial or body frame (a body force f acts as the inertial force R f).
struct AppliedForce {
  Profile value;
  ForcingFrame frame = ForcingFrame::Inertial;
  static constexpr bool depends_on_velocity = false;
  Wrench operator()(double t, const RigidBodyState& s, const RigidBody&) const {
    const Vector3<double> v = value.at(t);
    return {frame == ForcingFrame::Inertial ? v : s.q.act(v), Vector3<double>::Zero()};
  }
};

/// Linear damping: the body torque -c Omega and the force -c_linear v, with
/// Omega = J^{-1} w / 2 and v = p / m. For a spherical body (J = j I) the
/// spin decays as Omega(t) = Omega(0) exp(-c t / j).
struct Damping {
  double c = 0.0;
  double c_linear = 0.0;
  static constexpr bool depends_on_velocity = true;
  Wrench operator()(double, const RigidBodyState& s, const RigidBody& body) const {
    return {(-c_linear / body.mass()) * s.p, (-0.5 * c) * (body.inertia_inverse() * s.w)};
  }
};

/// A proportional-derivative attitude controller on the quaternion error
/// e = q_target^* q (body frame):
///   M = -k_p sgn(e_s) e_v - k_d Omega,  scaled down to |M| = max_torque if larger
/// (for a linear body, M's part across its axis: RigidBody::admissible_momentum).
/// sgn(e_s) picks the shorter of the two rotations that q and -q represent.
/// For a spherical body (J = j I) and small errors the error angle obeys
/// j theta'' + k_d theta' + (k_p/2) theta = 0 (e_v ~ theta/2 about the axis).
/// With a `period` > 0 the controller is sampled: computed at the first
/// (sub-)step starting at or after t = n period and held in between
/// (zero-order hold); see ForcingSet::sample.
struct AttitudeControl {
  S3d target;
  double k_p = 0.0;
  double k_d = 0.0;
  double max_torque = std::numeric_limits<double>::infinity();
  double period = 0.0;  ///< 0: continuous
  static constexpr bool depends_on_velocity = true;  // continuous form (k_d Omega)
  Wrench operator()(double, const RigidBodyState& s, const RigidBody& body) const {
    const S3d e = target.inverse() * s.q;
    const double sign = e.w() < 0.0 ? -1.0 : 1.0;
    // A linear body turns only across its axis (a point not at all): the
    // torque's part along the axis would do nothing, and must not count
    // toward max_torque. (m itself for a body with three moments.)
    Vector3<double> m =
        body.admissible_momentum((-k_p * sign) * e.vec() - (0.5 * k_d) * (body.inertia_inverse() * s.w));
    const double n = m.norm();
    if (n > max_torque) m *= max_torque / n;
    return {Vector3<double>::Zero(), m};
  }
  /// The same law for a body whose rate omega is given (a gyrostat's, wheels.hpp: not J^-1 w / 2):
  /// M = -k_p sgn(e_s) e_v - k_d omega, scaled down to max_torque.
  Vector3<double> torque_for(const S3d& q, const Vector3<double>& omega) const {
    const S3d e = target.inverse() * q;
    const double sign = e.w() < 0.0 ? -1.0 : 1.0;
    Vector3<double> m = (-k_p * sign) * e.vec() - k_d * omega;
    const double n = m.norm();
    if (n > max_torque) m *= max_torque / n;
    return m;
  }
};

/// A user's forcing, e.g. written in Python: f(t, body index, state of that
/// body) -> wrench.
struct CallableForcing {
  std::function<Wrench(double, std::size_t, const RigidBodyState&)> f;
  bool velocity_dependent = true;  ///< false lets the step skip the momentum iteration
  static constexpr bool depends_on_velocity = true;  // per instance: velocity_dependent
};

/// A user's C++ forcing term: anything callable as f(t, a, state_a) -> Wrench.
template <class F>
concept BodyForcing = requires(const F& f, double t, std::size_t a, const RigidBodyState& s) {
  { f(t, a, s) } -> std::convertible_to<Wrench>;
};

/// The forcing terms acting on a system. A body term gives one body's
/// wrench from that body's state, and acts on one body or on each; a system
/// term (PairDamping) gives every body's wrench at once from the whole state,
/// as a pair force must. Value type: a stepper owns its copy. Holds the
/// sampled values of zero-order-hold controllers, which a checkpoint keeps
/// (internal_state).
class ForcingSet {
 public:
  using Term = std::variant<AppliedTorque, AppliedForce, Damping, AttitudeControl, CallableForcing, PairDamping>;
  static constexpr std::size_t all_bodies = static_cast<std::size_t>(-1);

  /// Adds a term acting on body `body` (default: every body; a system term
  /// acts on every body).
  void add(Term term, std::size_t body = all_bodies) {
    if (const auto* c = std::get_if<AttitudeControl>(&term); c && !(c->period >= 0.0 && std::isfinite(c->period)))
      throw InvalidInput("forcing: attitude-control period must be >= 0");
    if (is_system_term(term) && body != all_bodies)
      throw InvalidInput("forcing: pair damping acts between the bodies and on each; it takes no body");
    terms_.push_back({std::move(term), body, {}, 0});
  }
  /// Adds a user's C++ forcing (see BodyForcing).
  template <BodyForcing F>
  void add_callable(F f, bool velocity_dependent = true, std::size_t body = all_bodies) {
    add(CallableForcing{std::move(f), velocity_dependent}, body);
  }

  bool empty() const { return terms_.empty(); }
  std::size_t size() const { return terms_.size(); }
  /// Whether a term is a user's function (CallableForcing), whose values
  /// lgvi cannot know to be a function of (t, state) alone.
  bool has_callable() const {
    for (const Entry& e : terms_)
      if (std::holds_alternative<CallableForcing>(e.term)) return true;
    return false;
  }

  /// Whether there are terms and every one is internal to the system: equal
  /// and opposite forces along the line of the points they act on (pair
  /// damping), so that the total force and torque vanish and both momenta
  /// are kept.
  bool internal_only() const {
    if (terms_.empty()) return false;
    for (const Entry& e : terms_)
      if (!is_system_term(e.term)) return false;
    return true;
  }

  /// Whether any term reads the momenta (then the end of a step iterates).
  bool depends_on_velocity() const {
    for (const Entry& e : terms_) {
      if (const auto* c = std::get_if<CallableForcing>(&e.term); c && !c->velocity_dependent) continue;
      if (const auto* a = std::get_if<AttitudeControl>(&e.term); a && a->period > 0.0) continue;
      if (std::visit([](const auto& t) { return std::decay_t<decltype(t)>::depends_on_velocity; }, e.term)) return true;
    }
    return false;
  }

  /// Forgets what the sampled controllers hold: the next sample() samples.
  void reset() {
    for (Entry& e : terms_) {
      e.held.clear();
      e.next_sample = 0;
    }
  }

  /// Called at the start of every (sub-)step at time t with its state: a
  /// sampled controller whose next sampling time n period has come (to a
  /// relative 1e-9 of the period, the round-off of t = k h) computes its
  /// torque from `s` and holds it until the next. Returns whether a held
  /// value changed.
  bool sample(double t, const SystemState& s, const System& sys) {
    bool changed = false;
    for (Entry& e : terms_) {
      const auto* c = std::get_if<AttitudeControl>(&e.term);
      if (!c || c->period <= 0.0) continue;
      const double slot = t / c->period + 1e-9;
      if (!e.held.empty() && slot < static_cast<double>(e.next_sample)) continue;
      e.held.resize(sys.size());
      for (std::size_t a = 0; a < sys.size(); ++a)
        if (applies(e, a)) e.held[a] = (*c)(t, s.body(a), sys.body(a));
      e.next_sample = static_cast<std::int64_t>(std::floor(slot)) + 1;
      changed = true;
    }
    return changed;
  }

  /// The forcing's wrench on every body at time t and state s (F inertial, M
  /// body). Not const: a system term writes its workspace (its pairs, kept
  /// between calls; interaction.hpp), so a set is evaluated by one stepper
  /// (each has its own copy).
  void evaluate(double t, const SystemState& s, const System& sys, std::vector<Vector3<double>>& force,
                std::vector<Vector3<double>>& torque) {
    const std::size_t n = sys.size();
    force.assign(n, Vector3<double>::Zero());
    torque.assign(n, Vector3<double>::Zero());
    for (Entry& e : terms_) {
      if (auto* pairs = std::get_if<PairDamping>(&e.term)) {
        pairs->add(s, sys, force, torque);
        continue;
      }
      for (std::size_t a = 0; a < n; ++a) {
        if (!applies(e, a)) continue;
        const Wrench w = wrench(e, t, a, s.body(a), sys.body(a));
        force[a] += w.force;
        torque[a] += w.torque;
      }
    }
  }

  /// The power of a wrench at a state: sum_a F_a . v_a + M_a . Omega_a (Omega_a a gyrostat's rate for a
  /// body with reaction wheels: body_angular_velocity).
  static double power(const SystemState& s, const System& sys, const std::vector<Vector3<double>>& force,
                      const std::vector<Vector3<double>>& torque) {
    double p = 0.0;
    for (std::size_t a = 0; a < sys.size(); ++a)
      p += force[a].dot(s.p[a]) / sys.body(a).mass() + torque[a].dot(body_angular_velocity(s, sys, a));
    return p;
  }

  /// The sampled controllers' state for n bodies, for a checkpoint: per
  /// sampled term the next sample's index, whether a value is held, and the
  /// held torque of every body (zeros if none). Empty when no term is sampled.
  std::vector<double> internal_state(std::size_t n) const {
    std::vector<double> v;
    for (const Entry& e : terms_) {
      if (!is_sampled(e)) continue;
      v.push_back(static_cast<double>(e.next_sample));
      v.push_back(e.held.empty() ? 0.0 : 1.0);
      for (std::size_t a = 0; a < n; ++a) {
        const Vector3<double> m = e.held.empty() ? Vector3<double>::Zero() : e.held[a].torque;
        v.insert(v.end(), {m.x(), m.y(), m.z()});
      }
    }
    return v;
  }
  /// The sampled controllers' fields (checkpoint_fields.hpp), nothing when no
  /// term is sampled: "stepper.forcing.samples", per sampled term the next
  /// sample's index and whether a value is held (0 or 1); and
  /// "stepper.forcing.held_torques", per sampled term the held torque of each
  /// of the n bodies (zeros if none).
  void save(CheckpointFields& out, std::size_t n) const {
    std::vector<std::int64_t> samples;
    std::vector<double> torques;
    for (const Entry& e : terms_) {
      if (!is_sampled(e)) continue;
      samples.insert(samples.end(), {e.next_sample, e.held.empty() ? 0 : 1});
      for (std::size_t a = 0; a < n; ++a) {
        const Vector3<double> m = e.held.empty() ? Vector3<double>::Zero() : e.held[a].torque;
        torques.insert(torques.end(), {m.x(), m.y(), m.z()});
      }
    }
    if (samples.empty()) return;
    out.put_i64("stepper.forcing.samples", std::move(samples));
    out.put_f64("stepper.forcing.held_torques", std::move(torques));
  }
  /// Restores what save(out, n) wrote.
  void load(const CheckpointFields& in, std::size_t n) {
    std::size_t sampled = 0;
    for (const Entry& e : terms_) sampled += is_sampled(e) ? 1 : 0;
    if (sampled == 0) return;
    const std::vector<std::int64_t>& samples = in.i64("stepper.forcing.samples", 2 * sampled);
    const std::vector<double>& torques = in.f64("stepper.forcing.held_torques", 3 * n * sampled);
    std::size_t i = 0;
    for (Entry& e : terms_) {
      if (!is_sampled(e)) continue;
      e.next_sample = samples[2 * i];
      e.held.assign(samples[2 * i + 1] != 0 ? n : 0, Wrench{});
      for (std::size_t a = 0; a < e.held.size(); ++a) {
        const double* m = torques.data() + 3 * (n * i + a);
        e.held[a].torque = Vector3<double>(m[0], m[1], m[2]);
      }
      ++i;
    }
  }

  /// How many numbers internal_state(n) holds.
  std::size_t internal_size(std::size_t n) const {
    std::size_t k = 0;
    for (const Entry& e : terms_)
      if (is_sampled(e)) k += 2 + 3 * n;
    return k;
  }
  /// Restores what internal_state(n) wrote (internal_size(n) numbers at d).
  void restore(const double* d, std::size_t n) {
    for (Entry& e : terms_) {
      if (!is_sampled(e)) continue;
      e.next_sample = static_cast<std::int64_t>(d[0]);
      const bool held = d[1] != 0.0;
      d += 2;
      e.held.assign(held ? n : 0, Wrench{});
      for (std::size_t a = 0; a < n; ++a, d += 3)
        if (held) e.held[a].torque = Vector3<double>(d[0], d[1], d[2]);
    }
  }

 private:
  struct Entry {
    Term term;
    std::size_t body;
    std::vector<Wrench> held;  ///< sampled controllers: the held value per body
    std::int64_t next_sample;  ///< sampled controllers: the index n of the next sampling time n period
  };

  static bool applies(const Entry& e, std::size_t a) { return e.body == all_bodies || e.body == a; }
  static bool is_system_term(const Term& term) { return std::holds_alternative<PairDamping>(term); }
  static bool is_sampled(const Entry& e) {
    const auto* c = std::get_if<AttitudeControl>(&e.term);
    return c && c->period > 0.0;
  }

  static Wrench wrench(const Entry& e, double t, std::size_t a, const RigidBodyState& s, const RigidBody& body) {
    if (is_sampled(e)) return e.held.empty() ? Wrench{} : e.held[a];
    if (const auto* c = std::get_if<CallableForcing>(&e.term)) return c->f(t, a, s);
    return std::visit(
        [&](const auto& term) -> Wrench {
          using T = std::decay_t<decltype(term)>;
          if constexpr (std::is_same_v<T, CallableForcing> || std::is_same_v<T, PairDamping>) return {};
          else return term(t, s, body);
        },
        e.term);
  }

  std::vector<Entry> terms_;
};

}  // namespace lgvi
