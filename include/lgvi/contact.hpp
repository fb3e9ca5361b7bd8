// Contact between the bodies of a system: which pairs overlap at a state.
//
// The integrators have no contact forces: bodies pass through each other, and
// from the first overlap on the model (rigid bodies that interact only through
// their potentials) no longer describes what it simulates. This finds those
// overlaps; it only reads the state.
//
// Each body is known by its extent (rigid_body.hpp): its balls, a sphere, an
// ellipsoid, or nothing, in which case it is its centre of mass (a point: it
// overlaps a body only by lying inside it, another point only by coinciding
// with it).
//
// The broad phase holds every body in one or more spheres, its proxies: its
// bounding sphere about the centre of mass (RigidBody::bounding_radius), or,
// for a body of balls that fill less than an eighth of that sphere's volume
// (a long chain, balls far apart), each of its balls. Two bodies can overlap
// only where proxies of both meet. The proxies are binned in a hierarchy of
// grids: cubic cells of side 2 r_max (r_max the largest proxy radius), and
// finer levels of half the side, each proxy in the finest level whose side is
// at least its diameter. Two proxies that meet then lie in the same or
// adjacent cells of the coarser one's level, so each proxy looks in 27 cells
// of its own and of each coarser level in use: a broad phase of O(P log P +
// K) per call, P the proxies and K the pairs of meeting proxies, whatever
// the spread of sizes (small bodies are not binned in a large one's cells)
// and however far apart one body's balls lie. Only pairs of bodies with
// meeting proxies are tested exactly, piece by piece (ball by ball for
// bodies of balls, the balls of one swept along x against those of the
// other; each such test places every ball of both bodies, O(S_a + S_b)):
//
//  * two spheres (balls, spheres, points as spheres of radius 0) overlap when
//    the distance d of their centres is below r_a + r_b (or is 0);
//  * where an ellipsoid is involved, by the Perram-Wertheim contact function
//    (J. W. Perram and M. S. Wertheim, J. Comput. Phys. 58, 409 (1985)): with
//    M = R diag(a^2, b^2, c^2) R^T for an ellipsoid (r^2 I for a sphere) and
//    r the vector between the centres,
//      F(lambda) = lambda (1 - lambda) r^T [(1 - lambda) M_a + lambda M_b]^-1 r,
//    concave on [0, 1]; mu^2 = max F is the factor by which both pieces,
//    scaled about their centres, just touch (mu < 1: they overlap). F is
//    quadratic in r, so along the line of centres they would just touch at
//    the centre distance D = d / mu: the "reach" of the pair (r_a + r_b for
//    two spheres, exactly). The maximum is found by bisection on the sign of
//    F' (decreasing, F concave) down to adjacent doubles: mu to round-off.
//    A point against an ellipsoid is the limit M_b = 0: mu^2 = r^T M_a^-1 r.
//
// What a contact reports: the pieces' centre distance d and the depth D - d,
// how far they would have to move apart along their line of centres to just
// touch (r_a + r_b - d for two spheres); of all overlapping pieces of a pair,
// the deepest.
#pragma once

#include <lgvi/rigid_body.hpp>
#include <lgvi/s3.hpp>
#include <lgvi/system.hpp>

#include <Eigen/Cholesky>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <utility>
#include <vector>

namespace lgvi {

/// The centre distance D at which two convex pieces just touch when moved
/// apart along the unit vector `u` from one centre to the other: both given
/// by M = R diag(s^2) R^T (s their semi-axes; a sphere r^2 I, a point 0). At
/// most one of them may be a point (M = 0); two points never touch (D = 0).
inline double contact_reach(const Vector3<double>& u, const Matrix3<double>& ma, bool a_point,
                            const Matrix3<double>& mb, bool b_point) {
  if (a_point && b_point) return 0.0;
  if (a_point || b_point) {
    // The limit lambda -> 1 (the point's side): F = r^T M^-1 r.
    const Matrix3<double>& m = a_point ? mb : ma;
    return 1.0 / std::sqrt(u.dot(m.llt().solve(u)));
  }
  const Matrix3<double> diff = mb - ma;
  // F'(lambda) = (1 - 2 lambda) r^T x - lambda (1 - lambda) x^T (M_b - M_a) x,
  // x = G^-1 r: positive at 0, negative at 1, decreasing between.
  auto slope = [&](double l, double& f) {
    const Vector3<double> x = ((1.0 - l) * ma + l * mb).llt().solve(u);
    const double rx = u.dot(x);
    f = l * (1.0 - l) * rx;
    return (1.0 - 2.0 * l) * rx - l * (1.0 - l) * x.dot(diff * x);
  };
  double lo = 0.0, hi = 1.0, f = 0.0, best = 0.0;
  for (int i = 0; i < 64; ++i) {
    const double mid = 0.5 * (lo + hi);
    if (mid <= lo || mid >= hi) break;  // adjacent doubles
    const double s = slope(mid, f);
    best = std::max(best, f);
    if (s > 0.0) lo = mid;
    else if (s < 0.0) hi = mid;
    else break;
  }
  return 1.0 / std::sqrt(best);
}

/// An overlap of bodies a < b at a state: of their overlapping pieces (balls,
/// or the body's sphere, ellipsoid or point), the deepest.
struct Contact {
  std::size_t a = 0, b = 0;
  /// The overlapping ball of a (of b) in a body of balls; -1 for other extents.
  std::ptrdiff_t ball_a = -1, ball_b = -1;
  double distance = 0.0;  ///< between the centres of the two pieces
  double reach = 0.0;     ///< the centre distance at which the pieces just touch, along their line (r_a + r_b)
  double depth() const { return reach - distance; }
};

/// Finds the overlapping pairs of a system's bodies at a state (see the top
/// of this file). Its model (interaction.hpp) refers to the system, which
/// must outlive it (not a copy of every body's balls), with the bodies'
/// bounding radii and proxies; its workspace is the scan's buffers, reused
/// from call to call, so a search is a non-const call: one detector per
/// thread.
class ContactDetector {
 public:
  ContactDetector() = default;
  explicit ContactDetector(const System& sys) : sys_(&sys) {
    proxy_begin_.push_back(0);
    for (std::size_t a = 0; a < sys.size(); ++a) {
      const RigidBody& body = sys.body(a);
      radius_.push_back(body.bounding_radius());
      if (proxies_are_balls(body)) {
        for (std::size_t i = 0; i < body.balls().size(); ++i)
          proxies_.push_back({a, static_cast<std::ptrdiff_t>(i), body.balls()[i].radius});
      } else {
        proxies_.push_back({a, -1, radius_[a]});
      }
      proxy_begin_.push_back(proxies_.size());
    }
  }
  explicit ContactDetector(System&&) = delete;  // a temporary would not outlive the detector

  /// Every overlapping pair at `s`, in the order of (a, b). The reference
  /// stays valid until the next call.
  const std::vector<Contact>& find(const SystemState& s) {
    scan(s, false);
    return found_;
  }

  /// The first overlapping pair in the order of (a, b), if any: what find()
  /// would list first, found without looking further (one overlap is enough
  /// to refuse a start).
  std::optional<Contact> first(const SystemState& s) {
    scan(s, true);
    return found_.empty() ? std::nullopt : std::optional<Contact>(found_.front());
  }

  /// The pairs of bodies the last call tested exactly (those whose proxies
  /// meet): the broad phase's yield, for tests of its cost.
  std::size_t pairs_tested() const { return pairs_tested_; }

 private:
  /// A sphere of the broad phase that holds a body (ball -1) or one of its balls.
  struct Proxy {
    std::size_t body = 0;
    std::ptrdiff_t ball = -1;
    double radius = 0.0;
  };

  /// Whether a body is held by its balls rather than by its bounding sphere:
  /// when they fill less than an eighth of its volume (R^3 > 8 sum r_i^3).
  static bool proxies_are_balls(const RigidBody& body) {
    if (body.extent() != Extent::Balls || body.balls().size() < 2) return false;
    double filled = 0.0;
    for (const Ball& b : body.balls()) filled += b.radius * b.radius * b.radius;
    const double r = body.bounding_radius();
    return r * r * r > 8.0 * filled;
  }

  /// A grid cell: the level (0 the coarsest), then the cell's indices.
  using Cell = std::array<std::int64_t, 4>;

  /// Places and bins the proxies (cells_, sorted by level, cell, then
  /// proxy), then tests body a = 0, 1, ... against the bodies b > a whose
  /// proxies meet one of its own, in the order of b: contacts come out in the
  /// order of (a, b). A proxy looks for those of b > a in its own level and
  /// the coarser ones; the pairs where b's proxy is the finer are gathered
  /// first (cross_). With `first_only`, stops after the first body a that
  /// has a contact.
  void scan(const SystemState& s, bool first_only) {
    const std::size_t n = radius_.size();
    found_.clear();
    pairs_tested_ = 0;
    if (n < 2) return;
    const Box& box = sys_->box();
    const std::size_t m = proxies_.size();
    centre_.resize(m);
    for (std::size_t a = 0; a < n; ++a) {
      const std::size_t begin = proxy_begin_[a], end = proxy_begin_[a + 1];
      if (proxies_[begin].ball < 0) {
        centre_[begin] = s.x[a];
        continue;
      }
      // As pieces() places the balls (the same rotation and sums).
      const Matrix3<double> r = s.q[a].matrix();
      const std::vector<Ball>& balls = sys_->body(a).balls();
      for (std::size_t p = begin; p < end; ++p)
        centre_[p] = s.x[a] + r * balls[static_cast<std::size_t>(proxies_[p].ball)].position;
    }
    // In a periodic box the exact test places b at the image of its centre
    // of mass nearest a's, the broad phase each proxy at its own nearest
    // image: both radii are widened by what rounding may part them.
    // (Both round at the positions' size: the state is not wrapped.)
    double spread = 0.0;
    for (std::size_t p = 0; p < m; ++p) spread = std::max(spread, centre_[p].cwiseAbs().maxCoeff());
    const double slack =
        box.any_periodic() ? 0x1p-40 * std::max(box.periodic_length().cwiseAbs().maxCoeff(), spread) : 0.0;
    double r_max = 0.0;
    for (std::size_t p = 0; p < m; ++p) r_max = std::max(r_max, proxies_[p].radius + slack);
    // Level l has cells of side coarsest / 2^l: at least the diameter of its
    // proxies, so that |c_u - c_v| <= r_u + r_v <= side for proxies that meet
    // (v of this level, u of this level or a finer one). Coarser where the
    // proxies spread over more than 2^40 cells, so that every cell index is
    // an exact integer; at most 61 levels.
    const double floor_side = std::max(0x1p-40 * spread, std::numeric_limits<double>::min());
    const double coarsest = std::max(2.0 * r_max, floor_side);
    int finest = 0;
    while (finest < 60 && std::ldexp(coarsest, -(finest + 1)) >= floor_side) ++finest;
    level_.resize(m);
    std::vector<bool> in_use(static_cast<std::size_t>(finest) + 1, false);
    for (std::size_t p = 0; p < m; ++p) {
      const double diameter = 2.0 * (proxies_[p].radius + slack);
      int l = 0;
      while (l < finest && std::ldexp(coarsest, -(l + 1)) >= diameter) ++l;
      level_[p] = l;
      in_use[static_cast<std::size_t>(l)] = true;
    }
    levels_.clear();
    for (int l = 0; l <= finest; ++l)
      if (in_use[static_cast<std::size_t>(l)]) levels_.push_back(l);
    // Along a periodic axis, a whole number of cells over the box (each at
    // least the level's side wide), numbered by the wrapped fractional
    // coordinate; the neighbours of the last cell are the first (below).
    periodic_cells_.assign(static_cast<std::size_t>(finest) + 1, {});
    for (const int l : levels_)
      for (int i = 0; i < 3; ++i)
        if (box.periodic(i))
          periodic_cells_[static_cast<std::size_t>(l)][static_cast<std::size_t>(i)] = std::max<std::int64_t>(
              1, static_cast<std::int64_t>(std::min(box.periodic_length()(i) / std::ldexp(coarsest, -l), 0x1p40)));
    auto cell_of = [&](const Vector3<double>& x, int l) {
      Cell c{l, 0, 0, 0};
      const double side = std::ldexp(coarsest, -l);
      for (int i = 0; i < 3; ++i) {
        const std::int64_t dims = periodic_cells_[static_cast<std::size_t>(l)][static_cast<std::size_t>(i)];
        std::int64_t& k = c[static_cast<std::size_t>(i) + 1];
        if (dims > 0) {
          const double f = std::floor(box.fraction(x[i], i) * static_cast<double>(dims));
          k = std::isfinite(f) ? std::clamp<std::int64_t>(static_cast<std::int64_t>(f), 0, dims - 1) : 0;
          continue;
        }
        const double f = std::floor(x[i] / side);
        k = std::isfinite(f) ? static_cast<std::int64_t>(f) : 0;  // not finite: one cell
      }
      return c;
    };
    auto neighbour = [&](const Cell& home, std::int64_t d, int i) {
      const std::int64_t dims =
          periodic_cells_[static_cast<std::size_t>(home[0])][static_cast<std::size_t>(i)];
      const std::int64_t c = home[static_cast<std::size_t>(i) + 1];
      return dims > 0 ? ((c + d) % dims + dims) % dims : c + d;
    };
    cells_.resize(m);
    for (std::size_t p = 0; p < m; ++p) cells_[p] = {cell_of(centre_[p], level_[p]), p};
    std::sort(cells_.begin(), cells_.end());
    auto by_cell = [](const std::pair<Cell, std::size_t>& e, const Cell& c) { return e.first < c; };
    // Calls visit(v) for every proxy v of level l that may meet proxy u (in
    // the 27 cells about u's own cell of that level), cell by cell in the
    // order dx, dy, dz = -1, 0, 1. The three cells of a column (dz) are
    // consecutive in cells_ where their z indices are (no wrap): one search
    // finds the column, whose proxies then come in that order.
    auto near = [&](std::size_t u, int l, auto&& visit) {
      const Cell home = cell_of(centre_[u], l);
      const std::int64_t z0 = neighbour(home, -1, 2), z1 = neighbour(home, 1, 2);
      const bool column = z1 == z0 + 2;
      for (std::int64_t dx = -1; dx <= 1; ++dx)
        for (std::int64_t dy = -1; dy <= 1; ++dy) {
          const std::int64_t x = neighbour(home, dx, 0), y = neighbour(home, dy, 1);
          if (column) {
            const Cell last{l, x, y, z1};
            for (auto e = std::lower_bound(cells_.begin(), cells_.end(), Cell{l, x, y, z0}, by_cell);
                 e != cells_.end() && e->first <= last; ++e)
              visit(e->second);
            continue;
          }
          for (std::int64_t dz = -1; dz <= 1; ++dz) {
            const Cell c{l, x, y, neighbour(home, dz, 2)};
            for (auto e = std::lower_bound(cells_.begin(), cells_.end(), c, by_cell);
                 e != cells_.end() && e->first == c; ++e)
              visit(e->second);
          }
        }
    };
    auto meet = [&](std::size_t u, std::size_t v) {
      return box.minimum_image(centre_[v] - centre_[u]).norm() <= proxies_[u].radius + proxies_[v].radius + 2.0 * slack;
    };
    // The pairs (b, a), b < a, where a proxy of b meets a finer one of a.
    cross_.clear();
    for (std::size_t u = 0; u < m; ++u) {
      const std::size_t a = proxies_[u].body;
      for (const int l : levels_) {
        if (l >= level_[u]) break;
        near(u, l, [&](std::size_t v) {
          if (proxies_[v].body < a && meet(u, v)) cross_.emplace_back(proxies_[v].body, a);
        });
      }
    }
    std::sort(cross_.begin(), cross_.end());
    std::size_t next_cross = 0;
    for (std::size_t a = 0; a < n; ++a) {
      candidates_.clear();
      for (std::size_t u = proxy_begin_[a]; u < proxy_begin_[a + 1]; ++u)
        for (const int l : levels_) {
          if (l > level_[u]) break;
          near(u, l, [&](std::size_t v) {
            if (proxies_[v].body > a && meet(u, v)) candidates_.push_back(proxies_[v].body);
          });
        }
      for (; next_cross < cross_.size() && cross_[next_cross].first == a; ++next_cross)
        candidates_.push_back(cross_[next_cross].second);
      // (Several proxies of a pair may meet; with fewer than 3 cells along a
      // periodic axis, a cell is its own neighbour twice.)
      std::sort(candidates_.begin(), candidates_.end());
      candidates_.erase(std::unique(candidates_.begin(), candidates_.end()), candidates_.end());
      pairs_tested_ += candidates_.size();
      for (const std::size_t b : candidates_) {
        Contact c;
        if (pair(s, a, b, c)) found_.push_back(c);
      }
      if (first_only && !found_.empty()) return;
    }
  }

  /// One piece of a body in inertial axes: a sphere (radius 0: a point) or
  /// an ellipsoid (m = R diag(s^2) R^T).
  struct Piece {
    Vector3<double> centre;
    double radius = 0.0;
    bool ellipsoid = false;
    Matrix3<double> m;
    std::ptrdiff_t ball = -1;
    double bound = 0.0;  ///< a radius about the centre that holds the piece (the largest semi-axis)
  };

  /// The pieces of body a at `s`, its centre of mass placed at `x`, within
  /// `range` of `near` (every piece of a body that is not made of balls; its
  /// balls that may reach that far).
  void pieces(const SystemState& s, std::size_t a, const Vector3<double>& x, const Vector3<double>& near, double range,
              std::vector<Piece>& out) const {
    out.clear();
    const RigidBody& body = sys_->body(a);
    switch (body.extent()) {
      case Extent::Point: out.push_back({x, 0.0, false, Matrix3<double>::Zero(), -1, 0.0}); break;
      case Extent::Sphere: {
        const double r = body.semi_axes().x();
        out.push_back({x, r, false, Matrix3<double>::Zero(), -1, r});
        break;
      }
      case Extent::Ellipsoid: {
        const Matrix3<double> r = s.q[a].matrix();
        const Vector3<double> s2 = body.semi_axes().cwiseProduct(body.semi_axes());
        out.push_back({x, 0.0, true, r * s2.asDiagonal() * r.transpose(), -1, body.semi_axes().maxCoeff()});
        break;
      }
      case Extent::Balls: {
        const Matrix3<double> r = s.q[a].matrix();
        const std::vector<Ball>& balls = body.balls();
        for (std::size_t i = 0; i < balls.size(); ++i) {
          const Vector3<double> c = x + r * balls[i].position;
          if ((c - near).norm() <= balls[i].radius + range)
            out.push_back({c, balls[i].radius, false, Matrix3<double>::Zero(), static_cast<std::ptrdiff_t>(i),
                           balls[i].radius});
        }
        break;
      }
    }
  }

  /// Whether bodies a < b overlap at `s`; if so, their deepest overlap in `c`.
  /// In a periodic box, b is taken at its minimum image about a.
  bool pair(const SystemState& s, std::size_t a, std::size_t b, Contact& c) {
    const Box& box = sys_->box();
    const Vector3<double> xb = box.any_periodic() ? Vector3<double>(s.x[a] + box.minimum_image(s.x[b] - s.x[a])) : s.x[b];
    pieces(s, a, s.x[a], xb, radius_[b], pieces_a_);
    pieces(s, b, xb, s.x[a], radius_[a], pieces_b_);
    // b's pieces sorted along x (ties by ball): each piece of a is tested
    // only against those within reach along x, so that two bodies of many
    // balls cost O(S log S), not O(S_a S_b).
    std::sort(pieces_b_.begin(), pieces_b_.end(), [](const Piece& u, const Piece& v) {
      return u.centre.x() != v.centre.x() ? u.centre.x() < v.centre.x() : u.ball < v.ball;
    });
    double bound_b = 0.0;
    for (const Piece& v : pieces_b_) bound_b = std::max(bound_b, v.bound);
    bool any = false;
    for (const Piece& u : pieces_a_) {
      const double from = u.centre.x() - u.bound - bound_b, to = u.centre.x() + u.bound + bound_b;
      auto v = std::lower_bound(pieces_b_.begin(), pieces_b_.end(), from,
                                [](const Piece& p, double x) { return p.centre.x() < x; });
      for (; v != pieces_b_.end() && v->centre.x() <= to; ++v) {
        const Vector3<double> r = v->centre - u.centre;
        const double d = r.norm();
        double reach = u.radius + v->radius;
        if (u.ellipsoid || v->ellipsoid) {
          // A sphere is M = r^2 I; along the x axis when the centres coincide.
          const Vector3<double> dir = d > 0.0 ? Vector3<double>(r / d) : Vector3<double>::UnitX();
          auto shape = [](const Piece& p) {
            return p.ellipsoid ? p.m : Matrix3<double>(Matrix3<double>::Identity() * (p.radius * p.radius));
          };
          reach = contact_reach(dir, shape(u), !u.ellipsoid && u.radius == 0.0, shape(*v),
                                !v->ellipsoid && v->radius == 0.0);
        }
        if (!(d < reach || d == 0.0)) continue;
        if (!any || reach - d > c.depth()) c = Contact{a, b, u.ball, v->ball, d, reach};
        any = true;
      }
    }
    return any;
  }

  // The model: the system, and per body its bounding radius and proxies.
  const System* sys_ = nullptr;
  std::vector<double> radius_;                ///< each body's bounding radius
  std::vector<Proxy> proxies_;                ///< in the order of the bodies
  std::vector<std::size_t> proxy_begin_;      ///< body a's proxies: [proxy_begin_[a], proxy_begin_[a + 1])
  // The workspace: what a scan writes.
  std::vector<Vector3<double>> centre_;  ///< of each proxy at the state scanned
  std::vector<int> level_;               ///< of each proxy
  std::vector<int> levels_;              ///< the levels in use, coarsest first
  std::vector<std::array<std::int64_t, 3>> periodic_cells_;  ///< per level: cells along each periodic axis (0: open)
  std::vector<std::pair<Cell, std::size_t>> cells_;
  std::vector<std::pair<std::size_t, std::size_t>> cross_;
  std::vector<std::size_t> candidates_;
  std::size_t pairs_tested_ = 0;
  std::vector<Contact> found_;
  std::vector<Piece> pieces_a_, pieces_b_;
};

}  // namespace lgvi
