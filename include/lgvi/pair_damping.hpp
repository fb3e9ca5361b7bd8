// Pair damping: a dissipative force between the sites of different bodies
// that depends on their relative velocity, the dissipative part of
// dissipative particle dynamics (P. Espanol and P. Warren, Europhys. Lett.
// 30, 191 (1995); R. D. Groot and P. B. Warren, J. Chem. Phys. 107, 4423
// (1997)). On site i of body a from site j of body b != a,
//
//   F_ij = -gamma w(r)^2 (e . v_ij) e,   e = r_ij / r,  r = |r_ij| < r_c,
//   w(r) = 1 - r / r_c,
//
// r_ij = c_i - c_j (the minimum image in a periodic box), v_ij = u_i - u_j,
// and u_i = v_a + omega_a x (c_i - x_a) the velocity of the point of body a
// at site i (omega_a = R_a Omega_a, inertial). The sites are a body's balls,
// or its centre of mass for a body without balls; sites of one body do not
// act on each other, and coincident sites (r = 0, no direction) not either.
//
// What it keeps and what it takes:
//  * F_ji = -F_ij along the line of the sites: the total force and the total
//    torque about any point vanish, so a step under the discrete
//    Lagrange-d'Alembert forcing (forcing.hpp) keeps the total linear
//    momentum and, in free space, the total angular momentum to round-off.
//  * Its power is -gamma sum_pairs w^2 (e . v_ij)^2 <= 0: it only removes
//    energy, and only from the relative motion along the lines of the sites
//    (a rigid motion of the whole system is not damped).
//  * It has no random force: it is not a DPD thermostat (whose noise is not
//    a function of the time and state, which lgvi's forcing must be).
//
// It is a forcing term on the whole system (ForcingSet's system terms): it
// writes every body's force and body torque at once. It depends on the
// velocities, so the end of each step iterates on the new momenta
// (StepperBase::end_step); it converges when h gamma / m is small. The
// pairs are taken once per configuration from its own Verlet lists, kept by
// the pair interactions' code (forces/neighbour_lists.hpp; a skin of r_c / 5,
// less in a periodic box too small for it); the forces are summed on one
// thread in the order of the pairs (i, j), which depends on the
// configuration only: the same bits on any thread count and after a resume.
#pragma once

#include <lgvi/box.hpp>
#include <lgvi/error.hpp>
#include <lgvi/forces/neighbour_lists.hpp>
#include <lgvi/parallel.hpp>
#include <lgvi/rigid_body.hpp>
#include <lgvi/s3.hpp>
#include <lgvi/state.hpp>
#include <lgvi/system.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace lgvi {

class PairDamping {
 public:
  static constexpr bool depends_on_velocity = true;

  /// gamma > 0 (force per relative speed), r_c > 0 (the cutoff); in a
  /// periodic box r_c must be below half its shortest periodic length, so
  /// that a site meets at most one image of another (InvalidInput otherwise).
  PairDamping(double gamma, double cutoff, const Box& box) : gamma_(gamma), cutoff_(cutoff) {
    if (!(gamma > 0.0 && std::isfinite(gamma))) throw InvalidInput("pair damping: gamma must be finite and > 0");
    if (!(cutoff > 0.0 && std::isfinite(cutoff))) throw InvalidInput("pair damping: cutoff must be finite and > 0");
    require_cutoff_fits(box);
  }

  double gamma() const { return gamma_; }
  double cutoff() const { return cutoff_; }
  /// How many times the neighbour lists have been built (for tests of their reuse).
  std::int64_t list_builds() const { return earlier_builds_ + (lists_ ? lists_->builds() : 0); }

  /// Adds the damping's force (inertial) and body torque on every body at
  /// state s to `force` and `torque` (sized to the system). The pairs within
  /// reach are found again only when the configuration (x, q) or the system
  /// differs from the last call's: the end of a step iterates on the momenta
  /// alone.
  void add(const SystemState& s, const System& sys, std::vector<Vector3<double>>& force,
           std::vector<Vector3<double>>& torque) {
    if (&sys != system_ || lists_->sites().bodies() != sys.size()) {
      // Another system (a copy of the forcing given to another stepper): its
      // box must allow the cutoff too, and nothing found for the last holds.
      // (The system is recorded last: an exception leaves none.)
      system_ = nullptr;
      x_.clear();
      require_cutoff_fits(sys.box());
      if (lists_) earlier_builds_ += lists_->builds();
      lists_.reset();
      lists_.emplace(sys, cutoff_, skin(sys.box()), Parallelism{}, "forcing");
      system_ = &sys;
    }
    if (!same_configuration(s)) find_pairs(s, sys);
    // The sites' velocities u_i = v_a + omega_a x arm_i.
    const NeighbourLists& lists = *lists_;
    const InteractionSites& sites = lists.sites();
    velocity_.resize(sites.size());
    for (std::size_t a = 0; a < sys.size(); ++a) {
      const Vector3<double> v = s.p[a] / sys.body(a).mass();
      const Vector3<double> omega = sys.body(a).extent() == Extent::Balls
                                        ? Vector3<double>(rotation_[a] * body_angular_velocity(s, sys, a))
                                        : Vector3<double>::Zero();
      for (std::size_t i = sites.begin(a); i < sites.end(a); ++i)
        velocity_[i] = v + omega.cross(sites.arm(rotation_[a], i));
    }
    arm_torque_.assign(sys.size(), Vector3<double>::Zero());
    for (const Pair& p : pairs_) {
      const std::size_t a = sites.body_of(p.i), b = sites.body_of(p.j);
      const Vector3<double> f = (-p.coefficient * p.unit.dot(velocity_[p.i] - velocity_[p.j])) * p.unit;
      force[a] += f;
      force[b] -= f;
      arm_torque_[a] += sites.arm(rotation_[a], p.i).cross(f);
      arm_torque_[b] -= sites.arm(rotation_[b], p.j).cross(f);
    }
    for (std::size_t a = 0; a < sys.size(); ++a)
      if (!arm_torque_[a].isZero(0.0)) torque[a] += rotation_[a].transpose() * arm_torque_[a];
  }

 private:
  /// Sites i < j of different bodies closer than r_c: e = r_ij / r and gamma w(r)^2.
  struct Pair {
    std::size_t i = 0, j = 0;
    Vector3<double> unit;
    double coefficient = 0.0;
  };

  void require_cutoff_fits(const Box& box) const {
    if (box.any_periodic() && !(2.0 * cutoff_ < box.shortest_periodic_length()))
      throw InvalidInput("pair damping: cutoff " + std::to_string(cutoff_) +
                         " must be less than half the shortest periodic length of the box (" +
                         std::to_string(box.shortest_periodic_length()) + ")");
  }

  /// The neighbour lists' skin: r_c / 5, or less in a periodic box where
  /// r_c + skin must stay below half the shortest periodic length (r_c is,
  /// require_cutoff_fits); 0 where r_c is so close to it that rounding
  /// leaves no room (then the lists are built for every new configuration).
  double skin(const Box& box) const {
    if (!box.any_periodic()) return 0.2 * cutoff_;
    const double length = box.shortest_periodic_length();
    const double skin = std::min(0.2 * cutoff_, 0.5 * (0.5 * length - cutoff_));
    return 2.0 * (cutoff_ + skin) < length ? skin : 0.0;
  }

  bool same_configuration(const SystemState& s) const {
    if (x_.size() != s.size()) return false;
    for (std::size_t a = 0; a < s.size(); ++a)
      if (x_[a] != s.x[a] || q_[a].w() != s.q[a].w() || q_[a].vec() != s.q[a].vec()) return false;
    return true;
  }

  /// The sites at state s and the pairs closer than r_c, in the order of
  /// (i, j), from the neighbour lists (whose entries of site i are the sites
  /// of higher bodies by increasing index): the same pairs in the same order
  /// whenever the lists were built, so a run's forces do not depend on its
  /// history (a resumed run continues bit for bit).
  /// StepFailure if a site's position is not finite.
  void find_pairs(const SystemState& s, const System& sys) {
    x_.clear();  // (until the pairs are found: an exception leaves no configuration)
    rotation_.resize(sys.size());
    for (std::size_t a = 0; a < sys.size(); ++a) rotation_[a] = s.q[a].matrix();
    NeighbourLists& lists = *lists_;
    lists.update(s);
    const Box& box = lists.box();
    const bool periodic = box.any_periodic();
    const double inverse_cutoff = 1.0 / cutoff_, cutoff2 = cutoff_ * cutoff_;
    pairs_.clear();
    for (std::size_t i = 0; i < lists.sites().size(); ++i)
      for (std::size_t k = lists.list_begin(i); k < lists.list_end(i); ++k) {
        const std::size_t j = lists.partner(k);
        const Vector3<double> d = lists.position(i) - lists.position(j);
        const Vector3<double> r = periodic ? box.minimum_image(d) : d;
        const double d2 = r.squaredNorm();
        if (!(d2 < cutoff2) || d2 == 0.0) continue;
        const double distance = std::sqrt(d2);
        if (!(distance < cutoff_)) continue;  // (d2 rounded below r_c^2)
        const double w = 1.0 - distance * inverse_cutoff;
        pairs_.push_back({i, j, r / distance, gamma_ * w * w});
      }
    x_ = s.x;
    q_ = s.q;
  }

  // The model (interaction.hpp): gamma and r_c, fixed at construction.
  double gamma_ = 0.0;
  double cutoff_ = 0.0;
  // The workspace, which add() writes: the system and configuration the pairs were found at, its lists,
  // and the pairs.
  const System* system_ = nullptr;
  std::optional<NeighbourLists> lists_;
  std::int64_t earlier_builds_ = 0;  ///< the lists' builds for systems before this one
  std::vector<Vector3<double>> x_;
  std::vector<S3d> q_;
  std::vector<Matrix3<double>> rotation_;
  std::vector<Pair> pairs_;
  // Scratch.
  std::vector<Vector3<double>> velocity_;
  std::vector<Vector3<double>> arm_torque_;
};

}  // namespace lgvi
