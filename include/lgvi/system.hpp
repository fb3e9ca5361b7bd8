// A system of N rigid bodies and its state, stored as arrays.
//
// The paper's configuration space for one body is R^3 x S^3; N bodies live on
// (R^3 x S^3)^N, with the product structure: each body keeps its own
// (x_a, q_a, p_a, w_a) in the paper's symbols (state.hpp), and bodies couple
// only through the potential, whose one evaluation per step returns the
// energy, the inertial force F_a and the body-frame torque M_a on every body
// (interaction.hpp). A single body is N = 1 of the same code.
//
// Layout (as in LAMMPS and HOOMD): a structure of arrays, one array per
// quantity, so that a loop over bodies is a loop over contiguous memory and
// per-body work can be split across threads. Per body the state costs
// 3 + 4 + 3 + 3 = 13 doubles (104 bytes); with a rotation matrix in place of
// the quaternion it would be 3 + 9 + 3 + 3 = 18 (144 bytes), the paper's
// "4 versus 9" (benchmarks/bench_system.cpp measures it).
#pragma once

#include <lgvi/box.hpp>
#include <lgvi/error.hpp>
#include <lgvi/rigid_body.hpp>
#include <lgvi/s3.hpp>
#include <lgvi/state.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <iterator>
#include <memory>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

namespace lgvi {

/// The bodies of a system: mass, inertia and interaction sites of each, and
/// a unique name; and the box they move in (box.hpp: free space unless
/// given). Bodies alike may share one RigidBody, their kind (LAMMPS's
/// "types": a gas of 10^6 identical molecules stores one); names numbered
/// in order (molecule0, molecule1, ...) are likewise kept as one prefix and
/// a first number (NameRun), not a string per body. Immutable after
/// construction, so that its copies share one storage: a copy (each
/// interaction, stepper and run keeps one) costs a pointer, not the N bodies
/// again.
class System {
 public:
  System() = default;
  /// Bodies with names (default body0, body1, ...) in `box`. Throws
  /// InvalidInput on an empty system, a size mismatch or a repeated name.
  explicit System(std::vector<RigidBody> bodies, std::vector<std::string> names = {}, const Box& box = {})
      : System(std::move(bodies), {}, std::move(names), box) {}
  /// Bodies of given kinds: body a is kinds[kind[a]] (kind empty: body a is
  /// kinds[a]). Throws InvalidInput as above, or on a kind out of range.
  System(std::vector<RigidBody> kinds, std::vector<std::uint32_t> kind, std::vector<std::string> names,
         const Box& box = {}) {
    auto data = std::make_shared<Data>(Data{std::move(kinds), std::move(kind), 0, {}, box});
    const std::size_t size = data->kind.empty() ? data->kinds.size() : data->kind.size();
    std::vector<std::string>& n = names;
    if (size == 0) throw InvalidInput("bodies: a system needs at least one body");
    for (const std::uint32_t k : data->kind)
      if (k >= data->kinds.size()) throw InvalidInput("bodies: a body's kind is out of range");
    if (n.empty())
      for (std::size_t a = 0; a < size; ++a) n.push_back("body" + std::to_string(a));
    if (n.size() != size) throw InvalidInput("bodies: one name per body is needed");
    // The first body whose name an earlier body has, named with that earlier
    // body's index: one hash look-up per body (O(N), not the O(N^2) of
    // comparing every pair; measured: docs/tuning.md).
    std::unordered_map<std::string_view, std::size_t> first;
    first.reserve(n.size());
    for (std::size_t a = 0; a < n.size(); ++a) {
      const auto [at, inserted] = first.try_emplace(n[a], a);
      if (!inserted)
        throw InvalidInput("bodies[" + std::to_string(a) + "].name: \"" + n[a] + "\" is already the name of bodies[" +
                           std::to_string(at->second) + "]; names must be unique");
    }
    data->size = size;
    data->name_runs = name_runs(n);
    data_ = std::move(data);
  }
  /// The system of one body.
  explicit System(const RigidBody& body) : System(std::vector<RigidBody>{body}) {}

  std::size_t size() const { return data().size; }
  const RigidBody& body(std::size_t a) const {
    const Data& d = data();
    return d.kinds[d.kind.empty() ? a : d.kind[a]];
  }
  /// The bodies' kinds: body a is kind_body(kind(a)), one of kinds() (per-kind
  /// data, such as a rotation solver or a body's sites, is kept once per kind).
  std::size_t kinds() const { return data().kinds.size(); }
  std::size_t kind(std::size_t a) const {
    const Data& d = data();
    return d.kind.empty() ? a : d.kind[a];
  }
  const RigidBody& kind_body(std::size_t k) const { return data().kinds[k]; }
  /// Whether any body has reaction wheels (then the state carries their momenta, SystemState::eta).
  bool has_wheels() const {
    for (const RigidBody& b : data().kinds)
      if (b.has_wheels()) return true;
    return false;
  }
  std::string name(std::size_t a) const {
    const std::vector<NameRun>& runs = data().name_runs;
    const NameRun& r = *std::prev(std::upper_bound(runs.begin(), runs.end(), a,
                                                   [](std::size_t b, const NameRun& run) { return b < run.first; }));
    return r.numbered ? r.prefix + std::to_string(r.number + (a - r.first)) : r.prefix;
  }
  /// The index of the body named `name`, or size() if none is.
  std::size_t index_of(const std::string& name) const {
    const std::vector<NameRun>& runs = data().name_runs;
    for (std::size_t k = 0; k < runs.size(); ++k) {
      const NameRun& r = runs[k];
      const std::size_t end = k + 1 < runs.size() ? runs[k + 1].first : size();
      if (!r.numbered) {
        if (name == r.prefix) return r.first;
        continue;
      }
      std::size_t number = 0;
      if (name.compare(0, r.prefix.size(), r.prefix) == 0 &&
          numbered_suffix(std::string_view(name).substr(r.prefix.size()), number) && number >= r.number &&
          number - r.number < end - r.first)
        return r.first + (number - r.number);
    }
    return size();
  }
  const Box& box() const { return data().box; }
  double total_mass() const {
    double m = 0.0;
    for (std::size_t a = 0; a < size(); ++a) m += body(a).mass();
    return m;
  }

 private:
  /// The names of bodies [first, the next run's first): prefix + (number +
  /// a - first) for body a if numbered, else prefix (one body). (A name in
  /// no run takes 56 B, a string alone 32: the runs pay off for generated
  /// names, a block's, the defaults, an import's consecutive mol<ID>s.)
  struct NameRun {
    std::size_t first = 0, number = 0;
    bool numbered = false;
    std::string prefix;
  };
  struct Data {
    std::vector<RigidBody> kinds;
    std::vector<std::uint32_t> kind;  ///< per body (empty: one kind per body)
    std::size_t size = 0;
    std::vector<NameRun> name_runs;  ///< by first body
    Box box;
  };
  /// Whether `digits` is a number as std::to_string writes it (1 to 18
  /// decimal digits, no leading zero but in "0"), and which.
  static bool numbered_suffix(std::string_view digits, std::size_t& number) {
    if (digits.empty() || digits.size() > 18 || (digits.size() > 1 && digits[0] == '0')) return false;
    number = 0;
    for (const char c : digits) {
      if (c < '0' || c > '9') return false;
      number = 10 * number + static_cast<std::size_t>(c - '0');
    }
    return true;
  }
  /// The runs of `names`: consecutive names that are one prefix and
  /// consecutive numbers make one run.
  static std::vector<NameRun> name_runs(const std::vector<std::string>& names) {
    std::vector<NameRun> runs;
    for (std::size_t a = 0; a < names.size(); ++a) {
      const std::string& n = names[a];
      std::size_t digits = n.size();
      while (digits > 0 && n[digits - 1] >= '0' && n[digits - 1] <= '9') --digits;
      std::size_t number = 0;
      const bool numbered = numbered_suffix(std::string_view(n).substr(digits), number);
      if (numbered && !runs.empty() && runs.back().numbered && runs.back().number + (a - runs.back().first) == number &&
          n.compare(0, digits, runs.back().prefix) == 0 && runs.back().prefix.size() == digits)
        continue;
      runs.push_back(numbered ? NameRun{a, number, true, n.substr(0, digits)} : NameRun{a, 0, false, n});
    }
    return runs;
  }
  /// A default System (no bodies) reads as this.
  static const Data& empty() {
    static const Data none{};
    return none;
  }
  const Data& data() const { return data_ ? *data_ : empty(); }
  std::shared_ptr<const Data> data_;
};

/// The bodies of `sys` in order, as a range: for (const RigidBody& b :
/// system_bodies(sys)) (sys must outlive the loop).
class SystemBodies {
 public:
  class Iterator {
   public:
    Iterator(const System* sys, std::size_t a) : sys_(sys), a_(a) {}
    const RigidBody& operator*() const { return sys_->body(a_); }
    Iterator& operator++() {
      ++a_;
      return *this;
    }
    bool operator==(const Iterator& other) const { return a_ == other.a_; }

   private:
    const System* sys_;
    std::size_t a_;
  };
  explicit SystemBodies(const System& sys) : sys_(&sys) {}
  Iterator begin() const { return {sys_, 0}; }
  Iterator end() const { return {sys_, sys_->size()}; }

 private:
  const System* sys_;
};
inline SystemBodies system_bodies(const System& sys) { return SystemBodies(sys); }

/// The state of N bodies, (x_a, q_a, p_a, w_a) for a = 0..N-1, one array per
/// quantity (paper symbols: x centre of mass, q attitude, p = m xdot, and
/// w = 2 J Omega, so that the body angular momentum is w/2).
struct SystemState {
  std::vector<Vector3<double>> x, p, w;
  std::vector<S3d> q;
  /// The reaction wheels' axial momenta eta_i = j_i (a_i.omega + Omega_i) (wheels.hpp), per body in the
  /// order of its wheels: empty when no body has wheels, else one (possibly empty) list per body. Then
  /// w = 2 Pi is the total angular momentum of body and wheels in body axes.
  std::vector<std::vector<double>> eta;

  SystemState() = default;
  explicit SystemState(std::size_t n)
      : x(n, Vector3<double>::Zero()), p(n, Vector3<double>::Zero()), w(n, Vector3<double>::Zero()), q(n) {}
  /// N = 1.
  explicit SystemState(const RigidBodyState& s) : x{s.x}, p{s.p}, w{s.w}, q{s.q} {}

  std::size_t size() const { return x.size(); }
  RigidBodyState body(std::size_t a) const { return {x[a], q[a], p[a], w[a]}; }
  void set_body(std::size_t a, const RigidBodyState& s) {
    x[a] = s.x;
    q[a] = s.q;
    p[a] = s.p;
    w[a] = s.w;
  }
  bool all_finite() const {
    for (std::size_t a = 0; a < size(); ++a)
      if (!body(a).all_finite()) return false;
    for (const std::vector<double>& e : eta)
      for (const double v : e)
        if (!std::isfinite(v)) return false;
    return true;
  }
};

/// One evaluation of the system's potential: the energy V, and per body the
/// inertial force F_a = -dV/dx_a and the body torque M_a (F(q_a) dV/dq_a =
/// -2 M_a, potential.hpp).
struct SystemEvaluation {
  double energy = 0.0;
  std::vector<Vector3<double>> force, torque;

  SystemEvaluation() = default;
  explicit SystemEvaluation(std::size_t n) : force(n, Vector3<double>::Zero()), torque(n, Vector3<double>::Zero()) {}

  std::size_t size() const { return force.size(); }
  /// Zero energy, forces and torques for n bodies (reusing the storage).
  void reset(std::size_t n) {
    energy = 0.0;
    force.assign(n, Vector3<double>::Zero());
    torque.assign(n, Vector3<double>::Zero());
  }
  PotentialEvaluation body(std::size_t a) const { return {energy, force[a], torque[a]}; }
  bool all_finite() const {
    if (!std::isfinite(energy)) return false;
    for (std::size_t a = 0; a < size(); ++a)
      if (!(force[a].allFinite() && torque[a].allFinite())) return false;
    return true;
  }
};

// Sums over bodies start from body 0's term, not from zero, so that N = 1
// gives the single-body value bit for bit (0 + -0 would turn a -0 into +0).

/// Body a's kinetic energy: a rigid body's (state.hpp), or with reaction wheels
/// |p|^2/(2m) + the gyrostat's rotational energy (Wheels::kinetic_energy).
inline double kinetic_energy(const SystemState& s, const System& sys, std::size_t a) {
  const RigidBody& body = sys.body(a);
  if (!body.has_wheels() || s.eta.empty()) return kinetic_energy(s.body(a), body);
  return s.p[a].squaredNorm() / (2.0 * body.mass()) + body.wheels().kinetic_energy(s.w[a], s.eta[a].data());
}

/// Body a's angular velocity Omega in body axes: a rigid body's J^-1 w / 2, or with reaction wheels the
/// gyrostat's (Wheels::body_rate; with the wheels' momenta in s.eta).
inline Vector3<double> body_angular_velocity(const SystemState& s, const System& sys, std::size_t a) {
  const RigidBody& body = sys.body(a);
  if (!body.has_wheels() || s.eta.empty()) return 0.5 * (body.inertia_inverse() * s.w[a]);
  return body.wheels().body_rate(s.w[a], s.eta[a].data());
}

/// Kinetic energy of the system, summed over bodies in order.
inline double kinetic_energy(const SystemState& s, const System& sys) {
  double t = kinetic_energy(s, sys, 0);
  for (std::size_t a = 1; a < s.size(); ++a) t += kinetic_energy(s, sys, a);
  return t;
}

/// Total energy T + V, with V from an evaluation at the same state.
inline double total_energy(const SystemState& s, const System& sys, const SystemEvaluation& e) {
  return kinetic_energy(s, sys) + e.energy;
}

/// Total angular momentum about the origin, sum_a x_a x p_a + pi(q_a) w_a / 2:
/// the momentum map of the diagonal S^3 action, conserved by discrete
/// Noether's theorem when the potential is invariant under a common rotation
/// (mutual interactions, central fields).
inline Vector3<double> angular_momentum(const SystemState& s) {
  Vector3<double> l = angular_momentum(s.body(0));
  for (std::size_t a = 1; a < s.size(); ++a) l += angular_momentum(s.body(a));
  return l;
}

/// Total linear momentum sum_a p_a (conserved when no external field acts).
inline Vector3<double> linear_momentum(const SystemState& s) {
  Vector3<double> p = s.p[0];
  for (std::size_t a = 1; a < s.size(); ++a) p += s.p[a];
  return p;
}

}  // namespace lgvi
