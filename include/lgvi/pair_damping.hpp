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
// pairs are taken once per configuration from a list of candidates within
// r_c plus a skin, made in cells (O(S log S) for S sites) when a site has
// moved more than half the skin; the forces are summed on one thread in the
// order of the pairs (i, j): the same bits on any thread count and after a
// resume.
#pragma once

#include <lgvi/box.hpp>
#include <lgvi/error.hpp>
#include <lgvi/rigid_body.hpp>
#include <lgvi/s3.hpp>
#include <lgvi/state.hpp>
#include <lgvi/system.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
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
  /// How many times the candidate list has been made (for tests of its reuse).
  std::size_t candidate_lists_made() const { return lists_made_; }

  /// Adds the damping's force (inertial) and body torque on every body at
  /// state s to `force` and `torque` (sized to the system). The pairs within
  /// reach are found again only when the configuration (x, q) or the system
  /// differs from the last call's: the end of a step iterates on the momenta
  /// alone.
  void add(const SystemState& s, const System& sys, std::vector<Vector3<double>>& force,
           std::vector<Vector3<double>>& torque) const {
    if (&sys != system_) {
      // Another system (a copy of the forcing given to another stepper): its
      // box must allow the cutoff too, and nothing found for the last holds.
      require_cutoff_fits(sys.box());
      system_ = &sys;
      x_.clear();
      made_at_.clear();
    }
    if (!same_configuration(s)) find_pairs(s, sys);
    // The sites' velocities u_i = v_a + omega_a x arm_i.
    velocity_.resize(sites_.size());
    for (std::size_t a = 0, i = 0; a < sys.size(); ++a) {
      const Vector3<double> v = s.p[a] / sys.body(a).mass();
      const Vector3<double> omega = sys.body(a).extent() == Extent::Balls
                                        ? Vector3<double>(rotation_[a] * body_angular_velocity(s, sys, a))
                                        : Vector3<double>::Zero();
      for (; i < sites_.size() && sites_[i].body == a; ++i) velocity_[i] = v + omega.cross(sites_[i].arm);
    }
    arm_torque_.assign(sys.size(), Vector3<double>::Zero());
    for (const Pair& p : pairs_) {
      const Site& u = sites_[p.i];
      const Site& v = sites_[p.j];
      const Vector3<double> f = (-p.coefficient * p.unit.dot(velocity_[p.i] - velocity_[p.j])) * p.unit;
      force[u.body] += f;
      force[v.body] -= f;
      arm_torque_[u.body] += u.arm.cross(f);
      arm_torque_[v.body] -= v.arm.cross(f);
    }
    for (std::size_t a = 0; a < sys.size(); ++a)
      if (!arm_torque_[a].isZero(0.0)) torque[a] += rotation_[a].transpose() * arm_torque_[a];
  }

 private:
  using Cell = std::array<std::int64_t, 3>;
  struct Site {
    Vector3<double> centre;  ///< c_i, inertial
    Vector3<double> arm;     ///< c_i - x_a, inertial
    std::size_t body = 0;
  };
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

  /// The skin of the candidate list, a fraction of r_c: candidates are the
  /// pairs closer than r_c + skin when the list was made, which hold every
  /// pair closer than r_c until a site has moved skin / 2.
  static constexpr double skin_fraction = 0.2;

  bool same_configuration(const SystemState& s) const {
    if (x_.size() != s.size()) return false;
    for (std::size_t a = 0; a < s.size(); ++a)
      if (x_[a] != s.x[a] || q_[a].w() != s.q[a].w() || q_[a].vec() != s.q[a].vec()) return false;
    return true;
  }

  /// The sites at state s (in the order of the bodies and their balls) and
  /// the pairs closer than r_c, in the order of (i, j): taken from the
  /// candidates, which are made again when a site has moved more than half
  /// the skin since they were made. The pairs are the same, in the same
  /// order, whenever the candidates were made: a run's forces do not depend
  /// on its history (a resumed run continues bit for bit).
  void find_pairs(const SystemState& s, const System& sys) const {
    x_ = s.x;
    q_ = s.q;
    sites_.clear();
    rotation_.resize(sys.size());
    for (std::size_t a = 0; a < sys.size(); ++a) {
      const RigidBody& body = sys.body(a);
      rotation_[a] = s.q[a].matrix();
      if (body.extent() != Extent::Balls) {
        sites_.push_back({s.x[a], Vector3<double>::Zero(), a});
        continue;
      }
      for (const Ball& ball : body.balls()) {
        const Vector3<double> arm = rotation_[a] * ball.position;
        sites_.push_back({s.x[a] + arm, arm, a});
      }
    }
    const Box& box = sys.box();
    const bool periodic = box.any_periodic();
    auto separation = [&](const Vector3<double>& a, const Vector3<double>& b) {
      return periodic ? box.minimum_image(a - b) : Vector3<double>(a - b);
    };
    const double skin = skin_fraction * cutoff_;
    bool fresh = made_at_.size() == sites_.size();
    for (std::size_t i = 0; fresh && i < sites_.size(); ++i)
      fresh = separation(sites_[i].centre, made_at_[i]).squaredNorm() <= 0.25 * skin * skin;
    if (!fresh) {
      make_candidates(sys, cutoff_ + skin);
      ++lists_made_;
    }
    const double inverse_cutoff = 1.0 / cutoff_, cutoff2 = cutoff_ * cutoff_;
    pairs_.clear();
    for (const auto& [i, j] : candidates_) {
      const Vector3<double> r = separation(sites_[i].centre, sites_[j].centre);
      const double d2 = r.squaredNorm();
      if (!(d2 < cutoff2) || d2 == 0.0) continue;
      const double d = std::sqrt(d2);
      if (!(d < cutoff_)) continue;  // (d2 rounded below r_c^2)
      const double w = 1.0 - d * inverse_cutoff;
      pairs_.push_back({i, j, r / d, gamma_ * w * w});
    }
  }

  /// The pairs of sites i < j of different bodies closer than `reach`, in
  /// the order of (i, j), found in cells of side at least `reach`.
  void make_candidates(const System& sys, double reach) const {
    const std::size_t m = sites_.size();
    const Box& box = sys.box();
    const bool periodic = box.any_periodic();
    made_at_.resize(m);
    for (std::size_t i = 0; i < m; ++i) made_at_[i] = sites_[i].centre;
    candidates_.clear();
    // Sites closer than `reach` lie in the same or adjacent cells. Coarser
    // where the sites spread over more than 2^40 cells, so that every index
    // is an exact integer; along a periodic axis a whole number of cells over
    // the box, by the wrapped fraction.
    double spread = 0.0;
    for (const Site& site : sites_) spread = std::max(spread, site.centre.cwiseAbs().maxCoeff());
    const double side = std::max({reach, 0x1p-40 * spread, std::numeric_limits<double>::min()});
    std::array<std::int64_t, 3> dims{};
    for (int i = 0; i < 3; ++i)
      if (box.periodic(i))
        dims[static_cast<std::size_t>(i)] =
            std::max<std::int64_t>(1, static_cast<std::int64_t>(std::min(box.periodic_length()(i) / side, 0x1p40)));
    auto cell_of = [&](const Vector3<double>& x) {
      Cell c{};
      for (int i = 0; i < 3; ++i) {
        const std::int64_t d = dims[static_cast<std::size_t>(i)];
        const double f = d > 0 ? std::floor(box.fraction(x[i], i) * static_cast<double>(d)) : std::floor(x[i] / side);
        const std::int64_t k = std::isfinite(f) ? static_cast<std::int64_t>(f) : 0;  // not finite: one cell
        c[static_cast<std::size_t>(i)] = d > 0 ? std::clamp<std::int64_t>(k, 0, d - 1) : k;
      }
      return c;
    };
    cells_.resize(m);
    for (std::size_t i = 0; i < m; ++i) cells_[i] = {cell_of(sites_[i].centre), i};
    std::sort(cells_.begin(), cells_.end());
    auto by_cell = [](const std::pair<Cell, std::size_t>& e, const Cell& c) { return e.first < c; };
    const double reach2 = reach * reach;
    // Cell by cell (runs of cells_), each pair once: from the earlier of the
    // two in cells_ order.
    for (std::size_t begin = 0; begin < m;) {
      const Cell home = cells_[begin].first;
      std::size_t end = begin + 1;
      while (end < m && cells_[end].first == home) ++end;
      // The distinct cells about this one (with fewer than 3 cells along a
      // periodic axis, a cell is its own neighbour more than once), and the
      // run of sites in each.
      near_.clear();
      for (std::int64_t dx = -1; dx <= 1; ++dx)
        for (std::int64_t dy = -1; dy <= 1; ++dy)
          for (std::int64_t dz = -1; dz <= 1; ++dz) {
            Cell c{};
            const std::array<std::int64_t, 3> d{dx, dy, dz};
            for (std::size_t k = 0; k < 3; ++k)
              c[k] = dims[k] > 0 ? ((home[k] + d[k]) % dims[k] + dims[k]) % dims[k] : home[k] + d[k];
            near_.push_back(c);
          }
      std::sort(near_.begin(), near_.end());
      near_.erase(std::unique(near_.begin(), near_.end()), near_.end());
      runs_.clear();
      for (const Cell& c : near_) {
        auto first = std::lower_bound(cells_.begin(), cells_.end(), c, by_cell);
        auto last = first;
        while (last != cells_.end() && last->first == c) ++last;
        if (first != last)
          runs_.emplace_back(static_cast<std::size_t>(first - cells_.begin()),
                             static_cast<std::size_t>(last - cells_.begin()));
      }
      for (std::size_t e = begin; e < end; ++e)
        for (const auto& [from, to] : runs_)
          for (std::size_t f = std::max(from, e + 1); f < to; ++f) {
            std::size_t i = cells_[e].second, j = cells_[f].second;
            if (sites_[i].body == sites_[j].body) continue;
            const Vector3<double> r = periodic ? box.minimum_image(sites_[i].centre - sites_[j].centre)
                                               : Vector3<double>(sites_[i].centre - sites_[j].centre);
            if (!(r.squaredNorm() < reach2)) continue;
            if (j < i) std::swap(i, j);
            candidates_.emplace_back(i, j);
          }
      begin = end;
    }
    std::sort(candidates_.begin(), candidates_.end());
  }

  double gamma_ = 0.0;
  double cutoff_ = 0.0;
  // The system and configuration the pairs were found at, and what was found.
  mutable const System* system_ = nullptr;
  mutable std::size_t lists_made_ = 0;
  mutable std::vector<Vector3<double>> x_;
  mutable std::vector<S3d> q_;
  mutable std::vector<Matrix3<double>> rotation_;
  mutable std::vector<Site> sites_;
  mutable std::vector<Pair> pairs_;
  // The candidates and the sites' centres when they were made.
  mutable std::vector<std::pair<std::size_t, std::size_t>> candidates_;
  mutable std::vector<Vector3<double>> made_at_;
  // Scratch.
  mutable std::vector<Vector3<double>> velocity_;
  mutable std::vector<std::pair<Cell, std::size_t>> cells_;
  mutable std::vector<Cell> near_;
  mutable std::vector<std::pair<std::size_t, std::size_t>> runs_;
  mutable std::vector<Vector3<double>> arm_torque_;
};

}  // namespace lgvi
