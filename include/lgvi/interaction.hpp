// The potential of a system of bodies: what one evaluation returns, the
// external fields that act on each body alone, and the mutual interactions
// between bodies, put together.
//
// A system potential V(x_1, q_1, ..., x_N, q_N) returns, in one evaluation,
// V, and per body the inertial force F_a = -dV/dx_a and the body torque M_a
// with F(q_a) dV/dq_a = -2 M_a (potential.hpp explains the factor). It is
// what the N-body steppers call once per step.
//
//  * ExternalField<P>: a single-body potential P (none, central, uniform,
//    a user's) acting on every body by itself, V = sum_a V_a(x_a, q_a).
//  * Mutual interactions (mutual_gravity.hpp, forces/): V depends on
//    pairs of bodies. Their `add` adds energy, forces and torques to an
//    evaluation; they act between the interaction sites of different bodies.
//  * Coupled<E, M>: an external field plus a mutual interaction.
//
// Model and workspace (as Pinocchio's Model and Data): a force provider keeps
// what it is (its parameters, the bodies' sites: the model, immutable after
// construction; shared by the provider's copies where it holds the bodies)
// apart from what an evaluation writes (caches, neighbour lists, scratch: the
// workspace, each copy its own, so that copies may evaluate on different
// threads at once).
// Evaluating is therefore a non-const call; it writes the workspace only,
// and its results depend on the model and the state alone, not on what the
// workspace held before (a resumed run, whose workspace is new, continues
// bit for bit).
#pragma once

#include <lgvi/error.hpp>
#include <lgvi/parallel.hpp>
#include <lgvi/potential.hpp>
#include <lgvi/rigid_body.hpp>
#include <lgvi/system.hpp>

#include <algorithm>
#include <cmath>
#include <concepts>
#include <limits>
#include <cstddef>
#include <cstdint>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace lgvi {

/// The contract of a system potential: evaluate(state, e) overwrites e with
/// V and every body's force and torque at `state` (writing its workspace:
/// the comment at the top of this file).
template <class I>
concept SystemPotential = requires(I& i, const SystemState& s, SystemEvaluation& e) {
  { i.evaluate(s, e) };
};

/// The contract of a mutual interaction: add(state, e) adds its energy,
/// forces and torques to e (sized for the system).
template <class M>
concept MutualInteraction = requires(M& m, const SystemState& s, SystemEvaluation& e) {
  { m.add(s, e) };
};

/// A single-body potential applied to each body separately: body a feels
/// P_a(x_a, q_a), where P_a is built for body a (its balls, its mass). The
/// energy is summed in body order after the (parallel) per-body loop. The
/// model: the bodies' potentials; the workspace: their energies.
template <Potential P>
class ExternalField {
 public:
  explicit ExternalField(std::vector<P> per_body, Parallelism par = {})
      : per_body_(std::move(per_body)), par_(par) {}
  /// The same potential for every body (e.g. NoPotential).
  static ExternalField uniform(const P& p, std::size_t n, Parallelism par = {}) {
    return ExternalField(std::vector<P>(n, p), par);
  }

  void evaluate(const SystemState& s, SystemEvaluation& e) {
    const std::vector<P>& per_body = per_body_;
    const std::size_t n = s.size();
    if (e.size() != n) e.reset(n);
    if (n == 1) {  // one body: no loop, no per-body energies to sum
      const PotentialEvaluation pe = per_body[0].evaluate(s.x[0], s.q[0]);
      e.energy = pe.energy;
      e.force[0] = pe.force;
      e.torque[0] = pe.torque;
      return;
    }
    if constexpr (std::is_same_v<P, NoPotential>) {
      // No field: zeros (the same values as the loop below: every term is
      // 0), each body's written by the thread that computed its forces last
      // (a many-body run without a field, such as a Lennard-Jones gas, goes
      // through this every step), so that the arrays' cache lines stay on
      // the core that uses them (docs/tuning.md).
      parallel_for(n, par_, [&](std::size_t a) {
        e.force[a] = Vector3<double>::Zero();
        e.torque[a] = Vector3<double>::Zero();
      });
      e.energy = 0.0;
      return;
    }
    std::vector<double>& energies = energies_;
    energies.resize(n);
    parallel_for(n, par_, [&](std::size_t a) {
      const PotentialEvaluation pe = per_body[a].evaluate(s.x[a], s.q[a]);
      energies[a] = pe.energy;
      e.force[a] = pe.force;
      e.torque[a] = pe.torque;
    });
    // Body 0's term first (not 0 + V_0): N = 1 gives the single-body value bit for bit.
    e.energy = energies[0];
    for (std::size_t a = 1; a < n; ++a) e.energy += energies[a];
  }

  const P& body_potential(std::size_t a) const { return per_body_[a]; }
  void set_parallelism(Parallelism par) { par_ = par; }

 private:
  /// The model: each body's potential, held by value (read at every evaluation, so not behind a
  /// pointer; a copy copies it).
  std::vector<P> per_body_;
  Parallelism par_;
  std::vector<double> energies_;  ///< the workspace: each body's energy, summed in order
};

/// No mutual interaction (bodies feel only the external field).
struct NoMutualInteraction {
  void add(const SystemState&, SystemEvaluation&) const {}
};

/// An external field plus a mutual interaction.
template <SystemPotential E, MutualInteraction M>
class Coupled {
 public:
  Coupled(E external, M mutual) : external_(std::move(external)), mutual_(std::move(mutual)) {}
  void evaluate(const SystemState& s, SystemEvaluation& e) {
    external_.evaluate(s, e);
    mutual_.add(s, e);
  }
  const E& external() const { return external_; }
  const M& mutual() const { return mutual_; }
  M& mutual() { return mutual_; }

 private:
  E external_;
  M mutual_;
};

/// The interaction sites of a system's bodies, flattened: body a's sites are
/// [begin(a), begin(a + 1)), each with its body-frame position rho (relative
/// to the centre of mass), mass, radius and type. A body made of balls has one site
/// per ball; a body given by mass and inertia has one site at its centre of
/// mass with the whole mass (radius 0). The sites' positions rho and radii
/// are stored once per kind of body (System::kind), their types, masses and
/// bodies per site (read per pair).
class InteractionSites {
 public:
  InteractionSites() = default;
  explicit InteractionSites(const System& sys) : kind_(sys.size()) {
    kind_first_.push_back(0);
    for (std::size_t k = 0; k < sys.kinds(); ++k) {
      const RigidBody& b = sys.kind_body(k);
      if (b.balls().empty()) {
        kind_rho_.emplace_back(Vector3<double>::Zero());
        kind_radius_.push_back(0.0);
        kind_mass_.push_back(b.mass());
      } else {
        for (const Ball& ball : b.balls()) {
          kind_mass_.push_back(ball.mass);
          kind_rho_.push_back(ball.position);
          kind_radius_.push_back(ball.radius);
        }
      }
      kind_first_.push_back(kind_rho_.size());
    }
    std::size_t sites = 0;
    for (std::size_t a = 0; a < sys.size(); ++a) {
      kind_[a] = static_cast<std::uint32_t>(sys.kind(a));
      sites += kind_first_[kind_[a] + 1] - kind_first_[kind_[a]];
    }
    type_.reserve(sites);
    body_.reserve(sites);
    offset_.reserve(sys.size() + 1);
    offset_.push_back(0);
    for (std::size_t a = 0; a < sys.size(); ++a) {
      const RigidBody& b = sys.body(a);
      if (b.balls().empty()) {
        add(a, 1);
      } else {
        for (const Ball& ball : b.balls()) add(a, ball.type);
      }
      offset_.push_back(body_.size());
    }
  }

  std::size_t bodies() const { return offset_.empty() ? 0 : offset_.size() - 1; }
  std::size_t size() const { return body_.size(); }
  std::size_t begin(std::size_t a) const { return offset_[a]; }
  std::size_t end(std::size_t a) const { return offset_[a + 1]; }
  std::size_t body_of(std::size_t i) const { return body_[i]; }
  const Vector3<double>& rho(std::size_t i) const { return kind_rho_[kind_site(i)]; }
  double mass(std::size_t i) const { return kind_mass_[kind_site(i)]; }
  double radius(std::size_t i) const { return kind_radius_[kind_site(i)]; }
  /// The site's type, 0-based (Ball::type - 1; 0 for a body given by mass and inertia).
  std::uint32_t type(std::size_t i) const { return type_[i]; }
  /// The ball's index within its body (for messages).
  std::size_t local_index(std::size_t i) const { return i - offset_[body_[i]]; }

  /// Inertial positions of every site at `s`, X_i = x_a + R_a rho_i, and the
  /// arms R_a rho_i, computed per body (in parallel); then `after(a)`, on the
  /// thread that placed body a's sites (work on them while they are in its
  /// cache, without a loop of its own).
  template <class AfterBody = void (*)(std::size_t)>
  void place(const SystemState& s, const Parallelism& par, std::vector<Vector3<double>>& position,
             std::vector<Vector3<double>>& arm, AfterBody&& after = [](std::size_t) {}) const {
    arm.resize(size());
    place(s, par, position, arm.data(), after);
  }
  /// The same without the arms (which arm() gives again, bit for bit), each
  /// body's sites placed about its centre of mass wrapped into `box`
  /// (Box::wrap: X_i = wrapped x_a + R_a rho_i, an image of the site).
  template <class AfterBody = void (*)(std::size_t)>
  void place_wrapped(const SystemState& s, const Parallelism& par, const Box& box,
                     std::vector<Vector3<double>>& position, AfterBody&& after = [](std::size_t) {}) const {
    place(s, par, position, nullptr, after, &box);
  }
  /// Site i's arm R_a rho_i for its body's attitude matrix R_a =
  /// s.q[a].matrix(), the same bits as place()'s.
  Vector3<double> arm(const Matrix3<double>& r, std::size_t i) const { return r * rho(i); }
  /// Body a's sites' rho, site begin(a) + l at [l] (as rho(), without its lookups per site).
  const Vector3<double>* body_rho(std::size_t a) const { return kind_rho_.data() + kind_first_[kind_[a]]; }

 private:
  template <class AfterBody>
  void place(const SystemState& s, const Parallelism& par, std::vector<Vector3<double>>& position,
             Vector3<double>* const arms, AfterBody&& after, const Box* box = nullptr) const {
    position.resize(size());
    // (Through local pointers: `after` may store chars, which could alias
    // anything, and the vectors' data would be reloaded for every site.)
    const Vector3<double>* const rho = kind_rho_.data();
    const std::size_t* const kind_first = kind_first_.data();
    const std::uint32_t* const kind = kind_.data();
    const std::size_t* const offset = offset_.data();
    Vector3<double>* const positions = position.data();
    parallel_for(bodies(), par, [&](std::size_t a) {
      const Matrix3<double> r = s.q[a].matrix();
      const Vector3<double> x = box != nullptr && box->any_periodic() ? box->wrap(s.x[a]).x : s.x[a];
      const Vector3<double>* const rho_a = rho + kind_first[kind[a]];  // the kind's sites
      for (std::size_t i = offset[a]; i < offset[a + 1]; ++i) {
        const Vector3<double> arm_i = r * rho_a[i - offset[a]];
        if (arms != nullptr) arms[i] = arm_i;
        positions[i] = x + arm_i;
      }
      after(a);
    });
  }

  void add(std::size_t body, int type) {
    type_.push_back(static_cast<std::uint32_t>(type - 1));
    body_.push_back(static_cast<std::uint32_t>(body));
  }
  /// Site i's index among its kind's sites (kind_rho_, kind_radius_, kind_mass_).
  std::size_t kind_site(std::size_t i) const { return kind_first_[kind_[body_[i]]] + local_index(i); }
  std::vector<Vector3<double>> kind_rho_;  ///< per kind k: its sites [kind_first_[k], kind_first_[k + 1])
  std::vector<double> kind_radius_, kind_mass_;
  std::vector<std::size_t> kind_first_;
  std::vector<std::uint32_t> kind_;  ///< per body
  std::vector<std::uint32_t> type_, body_;  ///< (a body's index in 4 bytes: PairInteraction's limit on sites bounds it)
  std::vector<std::size_t> offset_;
};

/// The one reduction of forces at interaction sites to a body's force and
/// torque: forces f at the body's sites (arms R_a rho_i, inertial frame) added
/// one by one, in the caller's order, F_a = sum f and M_a = R_a^T sum arm x f,
/// then added to an evaluation. Every mutual interaction between sites
/// (PairInteraction, MutualGravityBalls) sums through it, so the order of the
/// additions, and with it every bit of the result, is the caller's.
struct SiteWrench {
  Vector3<double> force = Vector3<double>::Zero(), torque = Vector3<double>::Zero();
  void add(const Vector3<double>& arm, const Vector3<double>& f) {
    force += f;
    torque += arm.cross(f);
  }
  /// Adds the sums to body a's force and (body-frame) torque in e.
  void add_to(const SystemState& s, std::size_t a, SystemEvaluation& e) const {
    e.force[a] += force;
    e.torque[a] += s.q[a].inverse().act(torque);
  }
};

namespace detail {
/// A mutual force that is not finite: two sites on top of each other.
[[noreturn]] inline void close_approach(const System& sys, const InteractionSites& sites, std::size_t i,
                                        std::size_t j, double distance) {
  auto site = [&](std::size_t k) {
    const std::size_t a = sites.body_of(k);
    const std::string body = "body " + std::to_string(a) + " (\"" + sys.name(a) + "\")";
    return sys.body(a).balls().empty() ? body : "ball " + std::to_string(sites.local_index(k)) + " of " + body;
  };
  throw StepFailure("the mutual interaction between " + site(i) + " and " + site(j) +
                        " is not finite (distance " + std::to_string(distance) + "): a collision",
                    "a smaller step resolves close approaches better; if the bodies really collide, the model "
                    "(point masses, no contact forces) does not hold there");
}
}  // namespace detail

/// Checks every body's force F_a = -dV/dx_a and torque M_a = -dV/dtheta_a
/// (q_a -> q_a exp(theta/2)) of a system potential against fourth-order
/// central differences of its energy, as check_potential_derivatives does for
/// one body (potential.hpp: step eps^(1/5), times max(1, |x_a|) for
/// positions). The errors are the largest over the bodies, each relative to
/// the larger of the two vectors compared (and, in the *_abs_error fields, absolute).
/// (A copy of the potential: it shares the model and evaluates in a workspace of its own.)
template <SystemPotential I>
DerivativeCheck check_system_derivatives(I potential, const SystemState& s) {
  const double h0 = std::pow(std::numeric_limits<double>::epsilon(), 0.2);
  SystemEvaluation e(s.size()), probe(s.size());
  potential.evaluate(s, e);
  auto diff = [](auto&& f, double h) { return (8.0 * (f(h) - f(-h)) - (f(2 * h) - f(-2 * h))) / (12.0 * h); };
  auto relative = [](const Vector3<double>& a, const Vector3<double>& b) {
    const double scale = std::max(a.norm(), b.norm());
    return scale > 0.0 ? (a - b).norm() / scale : 0.0;
  };
  DerivativeCheck worst;
  for (std::size_t a = 0; a < s.size(); ++a) {
    Vector3<double> force_fd, torque_fd;
    for (int i = 0; i < 3; ++i) {
      const Vector3<double> unit = Vector3<double>::Unit(i);
      force_fd(i) = -diff(
          [&](double t) {
            SystemState moved = s;
            moved.x[a] += t * unit;
            potential.evaluate(moved, probe);
            return probe.energy;
          },
          h0 * std::max(1.0, s.x[a].norm()));
      torque_fd(i) = -diff(
          [&](double t) {
            SystemState turned = s;
            turned.q[a] = s.q[a] * S3d::exp((t / 2) * unit);
            potential.evaluate(turned, probe);
            return probe.energy;
          },
          h0);
    }
    worst.force_error = std::max(worst.force_error, relative(e.force[a], force_fd));
    worst.torque_error = std::max(worst.torque_error, relative(e.torque[a], torque_fd));
    worst.force_abs_error = std::max(worst.force_abs_error, (e.force[a] - force_fd).norm());
    worst.torque_abs_error = std::max(worst.torque_abs_error, (e.torque[a] - torque_fd).norm());
  }
  return worst;
}

/// The same for a mutual interaction alone (no external field).
template <MutualInteraction M>
  requires(!SystemPotential<M>)
DerivativeCheck check_system_derivatives(M mutual, const SystemState& s) {
  return check_system_derivatives(Coupled(ExternalField<NoPotential>::uniform(NoPotential{}, s.size()), std::move(mutual)), s);
}

}  // namespace lgvi
