// A pair interaction between the interaction sites (balls) of different
// bodies, over a pair kernel: the kernel says what a pair does (its
// parameters, its cutoff r_c, and a function of the pair's squared distance
// giving the force coefficient and the energy); this class finds the pairs,
// sums the forces and reduces them to each body's force and torque.
//
//   V = sum over pairs of sites i, j of different bodies with r_ij < r_c of u(r_ij^2),
//   f_i = coef(r_ij^2) d,  d = X_j - X_i   (the force on site i; coef = u'(r) / r),
//
// Sites of the same body do not interact (their distances are fixed).
//
// A kernel (the PairKernel concept) is a small copyable struct with
//   double cutoff() const;            r_c
//   double cutoff2() const;           r_c^2, the bound of `inside` below
//   PairTerms operator()(double r2) const;   {coef, energy} at r^2 = r2 < r_c^2
// or, for a kernel of typed sites (TypedPairKernel: LAMMPS's atom types),
//   std::uint32_t types() const;      the number of site types T
//   PairTerms operator()(double r2, std::uint32_t pair) const;   pair = T t_i + t_j
// (t the sites' types, 0-based: Ball::type - 1), one cutoff for every pair.
// The call is made for every list entry, inside r_c or not, without a branch
// (the result beyond r_c is discarded, by a select, below), so that the loop
// over entries vectorizes; it must therefore be branch-free itself and
// marked always_inline (GCC does not inline a function into the loop's
// no-trapping-math clones otherwise). Its values may be anything at r2 >= r_c^2,
// including infinities and NaN. Forces and energies are the kernel's IEEE
// operations in the kernel's order: a kernel that does not fuse or reorder
// gives results independent of the processor (below).
//
// Neighbours by Verlet lists, as in LAMMPS and HOOMD (neighbour_lists.hpp:
// each site's list holds the sites of higher bodies within r_c + skin,
// rebuilt and pruned as the sites move). Results do not depend on when the
// lists were built or pruned: pairs beyond r_c add exact zeros (below).
//
// Half lists (as LAMMPS with newton on): each pair is in the list of its
// lower site only (the sites of higher bodies within r_c + skin). One pass
// over the bodies in order computes the pair terms of consecutive bodies in
// batches, vectorized (detail::pair_terms), and adds each pair's force to its
// lower site's running sum and, negated, to its partner's: the negated force
// is exactly what that site would have computed itself (d = X_j - X_i on one
// side, X_i - X_j = -d exactly on the other, the same r^2, so the same coef,
// and (-coef d) is exact). On several threads each takes a range of bodies;
// the terms of every body with a pair that crosses from its range into a
// higher one are computed first, so that every site's sum takes the same
// terms in the same order on any number of threads (PairInteraction::ranged_pass).
//
// Determinism: each site's lists are sorted by site index, so the sum over a
// site's neighbours (in index order: its lower partners, then its own list)
// runs in an order that depends on the current positions only, not on when
// or how the lists were built (pairs beyond r_c add exact zeros); each body's
// force, torque and energy are summed by one thread (SiteWrench).
// Results are bit-identical for any number of threads and after a checkpoint
// and resume (which rebuilds the lists).
//
// A concrete interaction is a kernel plus a class or alias naming it
// (forces/lennard_jones.hpp, for example).
#pragma once

#include <lgvi/forces/neighbour_lists.hpp>
#include <lgvi/interaction.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <concepts>
#include <cstdint>
#include <limits>
#include <memory>
#include <type_traits>
#include <utility>
#include <vector>

namespace lgvi {

/// What a pair kernel returns for one pair at squared distance r^2: the force
/// on the list's site is coef * d (d from it to its partner), the pair's
/// energy `energy`.
struct PairTerms {
  double coef, energy;
};

/// The contract of a pair kernel of typed sites (the comment at the top of this file).
template <class K>
concept TypedPairKernel = std::copyable<K> && requires(const K& k, double r2, std::uint32_t pair) {
  { k.cutoff() } -> std::convertible_to<double>;
  { k.cutoff2() } -> std::convertible_to<double>;
  { k.types() } -> std::convertible_to<std::uint32_t>;
  { k(r2, pair) } -> std::same_as<PairTerms>;
};

/// The contract of a pair kernel (the comment at the top of this file): one
/// function of r^2 for every pair, or one per pair of site types.
template <class K>
concept PairKernel = TypedPairKernel<K> || (std::copyable<K> && requires(const K& k, double r2) {
  { k.cutoff() } -> std::convertible_to<double>;
  { k.cutoff2() } -> std::convertible_to<double>;
  { k(r2) } -> std::same_as<PairTerms>;
});

namespace detail {

/// What detail::pair_terms reports of a batch besides its terms.
struct PairTermsCheck {
  bool finite;  ///< every force finite
  bool plain;   ///< every r^2 < plain_radius2
};

/// The pair terms of `count` list entries with separations d = (dx, dy, dz):
/// r^2 = (dx^2 + dy^2) + dz^2, the force on the list's site f = coef d into
/// (fx, fy, fz), and the pair's energy into `energy`, from the kernel for
/// r^2 < r_c^2; all 0 for r >= r_c. `pair`: each entry's pair of site types
/// for a TypedPairKernel (ignored, and may be null, otherwise). Returns
/// whether every force is finite (false may also mean a sum of components
/// overflowed: the caller looks) and whether every r^2 is below
/// `plain_radius2` (Box::plain_radius2: then each separation taken plain is
/// its minimum image; false also for a NaN r^2).
/// Branch-free, so that the compiler vectorizes it (GCC does only without
/// trapping math, which changes no result: it only stops treating the
/// compare as a possible floating-point trap); a clone for AVX2 (4 doubles at
/// a time) is picked at run time where the processor has it. Every term is
/// the same IEEE operation in the same order in either clone (no fused
/// multiply-add: AVX2 does not include FMA), so the results are bit-identical
/// on any x86-64 processor (in a build that does not itself target FMA, as
/// the project's does not). The AVX2 clone is GCC's: Clang does not take
/// target_clones on a function template (it compiles the default one only,
/// with the same results).
template <PairKernel Kernel>
#if defined(__GNUC__) && !defined(__clang__)
__attribute__((optimize("no-trapping-math")))
#if defined(__x86_64__)
__attribute__((target_clones("avx2", "default")))
#endif
#endif
PairTermsCheck pair_terms(std::size_t count, const Kernel& kernel, double plain_radius2, const double* __restrict dx,
                          const double* __restrict dy, const double* __restrict dz,
                          const std::uint32_t* __restrict pair, double* __restrict fx, double* __restrict fy,
                          double* __restrict fz, double* __restrict energy) {
  // A local copy of a trivially copyable kernel (its constants stay in
  // registers); a kernel that shares a table (TypedPairKernel's) by reference.
  std::conditional_t<std::is_trivially_copyable_v<Kernel>, const Kernel, const Kernel&> k = kernel;
  const double cutoff2 = k.cutoff2();
  double bad = 0.0, far = 0.0;  // (doubles, not bools: this form GCC vectorizes)
  for (std::size_t i = 0; i < count; ++i) {
    const double r2 = (dx[i] * dx[i] + dy[i] * dy[i]) + dz[i] * dz[i];
    const bool inside = r2 < cutoff2;
    far = r2 < plain_radius2 ? far : 1.0;
    PairTerms t;  // computed for every entry: no branch
    if constexpr (TypedPairKernel<Kernel>) t = k(r2, pair[i]);
    else t = k(r2);
    const double coef = inside ? t.coef : 0.0;
    fx[i] = coef * dx[i];
    fy[i] = coef * dy[i];
    fz[i] = coef * dz[i];
    energy[i] = inside ? t.energy : 0.0;
    const double sum = (fx[i] + fy[i]) + fz[i];  // not finite if a component is not (or, rarely, if it overflows)
    bad = sum - sum == 0.0 ? bad : 1.0;          // x - x is NaN for an infinite or NaN x
  }
  return {bad == 0.0, far == 0.0};
}

}  // namespace detail

/// A pair interaction over `Kernel` between the sites of different bodies
/// (the comment at the top of this file): a MutualInteraction, its model
/// (the bodies, the kernel) shared by copies, its workspace (the neighbour
/// lists, the pass's arrays) each copy's own (interaction.hpp).
template <PairKernel Kernel>
class PairInteraction {
 public:
  /// `skin`: the Verlet lists hold pairs within cutoff + skin (>= 0; LAMMPS's
  /// default is 0.3 sigma for Lennard-Jones).
  PairInteraction(const System& sys, const Kernel& kernel, Parallelism par, double skin)
      : model_(std::make_shared<const Model>(Model{sys, kernel})),
        par_(par),
        lists_(sys, kernel.cutoff(), skin, par, "interaction") {
    if constexpr (TypedPairKernel<Kernel>) {
      for (std::size_t i = 0; i < sites().size(); ++i)
        if (sites().type(i) >= kernel.types())
          throw InvalidInput("interaction: a site of type " + std::to_string(sites().type(i) + 1) +
                             " has no coefficients (the interaction's types are 1.." +
                             std::to_string(kernel.types()) + ")");
    }
  }

  void add(const SystemState& s, SystemEvaluation& e) {
    prepare(s);
    const std::size_t n = s.size();
    energy_.resize(n);  // (every body's entries written by the pass: no fill)
    finite_.resize(n);
    ranged_pass(s, e);
    for (std::size_t a = 0; a < n; ++a) e.energy += energy_[a];
  }

  /// The molecular virial at `s`, over the pairs within r_c:
  ///
  ///   W = sum over pairs (i of body a, j of body b) of f_i . (X_a - X_b),
  ///
  /// f_i the pair's force on site i and X_a - X_b the centres' separation
  /// of the pair's minimum image (X_i - rho_i - (X_j - rho_j), rho the sites'
  /// arms). It is -dV/d(epsilon) when every centre of mass and the box are
  /// scaled by 1 + epsilon at fixed attitudes, so that the pressure of rigid
  /// molecules in a periodic box of volume V is P = (2 K_trans + W) / (3 V)
  /// (K_trans the bodies' translational kinetic energy; LAMMPS's pressure
  /// with fix rigid, whose constraint virial cancels the rotational kinetic
  /// energy and the sites' arms). Summed per body in list order and then in
  /// body order on this thread, so it does not depend on the thread count.
  /// Costs about one serial evaluation (the runs call it per written frame).
  double virial(const SystemState& s) {
    prepare(s);
    PassScratch scratch;
    double total = 0.0;
    for (std::size_t a = 0; a < s.size(); ++a) {
      const std::size_t first = lists_.list_begin(sites().begin(a));
      scratch.resize(lists_.list_begin(sites().end(a)) - first);
      pair_terms(a, a + 1, scratch, scratch.fx.data(), scratch.fy.data(), scratch.fz.data());
      double w = 0.0;
      const Matrix3<double> r = s.q[a].matrix();
      std::size_t b = s.size();  // the partner's body, whose attitude matrix is rb (a body's sites come in a row)
      Matrix3<double> rb = Matrix3<double>::Zero();
      for (std::size_t i = sites().begin(a); i < sites().end(a); ++i)
        for (std::size_t k = lists_.list_begin(i); k < lists_.list_end(i); ++k) {
          // X_a - X_b = -d - rho_i + rho_j, d = X_j - X_i (minimum image); beyond r_c f = 0 exactly.
          const std::size_t j = lists_.partner(k);
          if (sites().body_of(j) != b) {
            b = sites().body_of(j);
            rb = s.q[b].matrix();
          }
          const Vector3<double> centres = sites().arm(rb, j) - sites().arm(r, i) -
                                          Vector3<double>(scratch.dx[k - first], scratch.dy[k - first],
                                                          scratch.dz[k - first]);
          w += scratch.fx[k - first] * centres.x() + scratch.fy[k - first] * centres.y() +
               scratch.fz[k - first] * centres.z();
        }
      total += w;
    }
    return total;
  }

  /// How many times the neighbour lists were built, and pruned (every build
  /// prunes too), for tests and benchmarks.
  std::int64_t list_builds() const { return lists_.builds(); }
  std::int64_t list_prunes() const { return lists_.prunes(); }

  const Kernel& kernel() const { return model_->kernel; }
  double cutoff() const { return lists_.cutoff(); }
  double skin() const { return lists_.skin(); }

 private:
  const InteractionSites& sites() const { return lists_.sites(); }

  /// Places the sites of `s` and brings the lists, and the threads' share
  /// of them, up to date for it.
  void prepare(const SystemState& s) {
    const NeighbourLists::Change change = lists_.update(s);
    if (change == NeighbourLists::Change::built || !work_ready_) split_work(true);
    else if (change == NeighbourLists::Change::pruned) split_work(false);
  }

  /// One thread's buffers for the list entries of a batch of bodies: the
  /// separations and the pairs' energies.
  struct Scratch {
    std::vector<double> dx, dy, dz, energy;
    std::vector<std::uint32_t> pair;  ///< the entries' pairs of site types (a TypedPairKernel's)
    void resize(std::size_t count) {
      if (dx.size() >= count) return;
      for (std::vector<double>* v : {&dx, &dy, &dz, &energy}) v->resize(count);
      if constexpr (TypedPairKernel<Kernel>) pair.resize(count);
    }
  };
  /// A range pass's buffers: also the pair forces (the crossing bodies' go
  /// into the crossing arrays).
  struct PassScratch : Scratch {
    std::vector<double> fx, fy, fz;
    void resize(std::size_t count) {
      Scratch::resize(count);
      if (fx.size() >= count) return;
      for (std::vector<double>* v : {&fx, &fy, &fz}) v->resize(count);
    }
  };

  /// How gather<How>() takes the separations d = X_j - X_i of the list
  /// entries of bodies [a, b) into the scratch (entry k - first, first the
  /// bodies' first entry; for a TypedPairKernel also each entry's pair of
  /// site types), returning their count: `plain`, as they are (an open box);
  /// `reduced`, their minimum images (Box::reduce); `unmarked`, as they are
  /// + 0.0, which is their minimum images' bits where each component is
  /// within Box::plain_bound(); `marked`, per site: reduced if one of its
  /// entries is marked across a period (NeighbourLists::across), else
  /// unmarked. So a periodic box pays for the reduction only at sites with a
  /// pair across a period. Whether an unmarked separation is within the
  /// bound is the caller's test, on r^2 (pair_terms: a body whose centre has
  /// crossed a face since the pruning is placed a period away from its
  /// partners, and the bodies are then gathered again, reduced).
  enum class Separation { plain, reduced, unmarked, marked };
  template <Separation How, class Buffers>
  std::size_t gather(std::size_t a, std::size_t b, Buffers& scratch) const {
    const std::size_t first = lists_.list_begin(sites().begin(a)),
                      count = lists_.list_begin(sites().end(b - 1)) - first;
    scratch.resize(count);
    const Box& box = lists_.box();
    // Site i's entries [k0, k1), taken as `how` says (plain, reduced or unmarked).
    auto separations = [&](const Vector3<double>& xi, std::size_t k0, std::size_t k1, auto how) {
      for (std::size_t k = k0; k < k1; ++k) {
        const NeighbourLists::Entry e = lists_.entry(k);
        const Vector3<double>& xj = lists_.position(NeighbourLists::partner_of(e));
        double dx = xj(0) - xi(0), dy = xj(1) - xi(1), dz = xj(2) - xi(2);
        if (how == Separation::reduced) {
          dx = box.reduce(dx, 0);
          dy = box.reduce(dy, 1);
          dz = box.reduce(dz, 2);
        } else if (how != Separation::plain) {
          dx += 0.0;
          dy += 0.0;
          dz += 0.0;
        }
        scratch.dx[k - first] = dx;
        scratch.dy[k - first] = dy;
        scratch.dz[k - first] = dz;
      }
    };
    for (std::size_t i = sites().begin(a); i < sites().end(b - 1); ++i) {
      const Vector3<double> xi = lists_.position(i);
      const std::size_t k0 = lists_.list_begin(i), k1 = lists_.list_end(i);
      if constexpr (How == Separation::marked) {
        // (Per site, not per entry: the loop over a site's entries has no branch.)
        NeighbourLists::Entry any = 0;
        for (std::size_t k = k0; k < k1; ++k) any |= lists_.entry(k);
        if (NeighbourLists::across(any))
          separations(xi, k0, k1, std::integral_constant<Separation, Separation::reduced>{});
        else
          separations(xi, k0, k1, std::integral_constant<Separation, Separation::unmarked>{});
      } else {
        separations(xi, k0, k1, std::integral_constant<Separation, How>{});
      }
      if constexpr (TypedPairKernel<Kernel>) {
        const std::uint32_t row = model_->kernel.types() * sites().type(i);
        for (std::size_t k = lists_.list_begin(i); k < lists_.list_end(i); ++k)
          scratch.pair[k - first] = row + sites().type(lists_.partner(k));
      }
    }
    return count;
  }

  /// The pair terms of bodies [a, b): the separations gathered into the
  /// scratch, the forces on their sites into fx, fy, fz and the pairs'
  /// energies into the scratch's `energy` (entry k - first of their list
  /// entries). Each entry's terms depend on its separation only, so they are
  /// the same computed for one body or several at once. Returns false if a
  /// force may not be finite (as detail::pair_terms). In a periodic box the
  /// separations are first taken `marked`; if some r^2 is not below
  /// Box::plain_radius2() (an unmarked one may then be beyond the plain
  /// bound), the bodies are gathered again, reduced, and their terms
  /// computed again (a superset of the separations beyond the bound, so the
  /// same bits either way: within it, reduced is unmarked's bits).
  template <class Buffers>
  bool pair_terms(std::size_t a, std::size_t b, Buffers& scratch, double* fx, double* fy, double* fz) const {
    auto terms = [&](std::size_t count, double plain_radius2) {
      return detail::pair_terms(count, model_->kernel, plain_radius2, scratch.dx.data(), scratch.dy.data(),
                                scratch.dz.data(), scratch.pair.data(), fx, fy, fz, scratch.energy.data());
    };
    constexpr double unbounded = std::numeric_limits<double>::infinity();
    const Box& box = lists_.box();
    if (!box.any_periodic()) return terms(gather<Separation::plain>(a, b, scratch), unbounded).finite;
    const detail::PairTermsCheck marked = terms(gather<Separation::marked>(a, b, scratch), box.plain_radius2());
    if (marked.plain) return marked.finite;
    return terms(gather<Separation::reduced>(a, b, scratch), unbounded).finite;
  }

  /// The energy of body a's pairs, summed in list order into energy_[a], from
  /// their energies u (entry k - first, first the body's first entry).
  /// Beyond r_c a pair's energy is 0 and adds nothing: x + 0 = x (no sum here
  /// is ever -0).
  void sum_body_energy(std::size_t a, const double* u) {
    const std::size_t count = lists_.list_begin(sites().end(a)) - lists_.list_begin(sites().begin(a));
    double energy = 0.0;
    for (std::size_t q = 0; q < count; ++q) energy += u[q];
    energy_[a] = energy;
  }

  /// Stops the run at the first pair of body a's lists, in list order, whose
  /// force is not finite, naming both bodies; returns if there is none (only
  /// a sum of components overflowed). Computes the body's pair terms again:
  /// the pass has not kept them (a run ends here, so the cost is no matter).
  void report_collision(std::size_t a) const {
    PassScratch scratch;
    const std::size_t first = lists_.list_begin(sites().begin(a));
    scratch.resize(lists_.list_begin(sites().end(a)) - first);
    pair_terms(a, a + 1, scratch, scratch.fx.data(), scratch.fy.data(), scratch.fz.data());
    for (std::size_t i = sites().begin(a); i < sites().end(a); ++i)
      for (std::size_t k = lists_.list_begin(i); k < lists_.list_end(i); ++k)
        if (!(std::isfinite(scratch.fx[k - first]) && std::isfinite(scratch.fy[k - first]) &&
              std::isfinite(scratch.fz[k - first]))) {
          const std::size_t j = lists_.partner(k);
          detail::close_approach(model_->sys, sites(), i, j,
                                 lists_.box().minimum_image(lists_.position(j) - lists_.position(i)).norm());
        }
  }

  /// Body a's force and torque from its sites' forces f_i (summed over each
  /// site's whole neighbourhood), in site order (SiteWrench).
  template <class SiteForce>
  void add_body_wrench(const SystemState& s, SystemEvaluation& e, std::size_t a, SiteForce&& site_force) const {
    SiteWrench wrench;
    const Matrix3<double> r = s.q[a].matrix();
    const Vector3<double>* const rho = sites().body_rho(a);
    for (std::size_t i = sites().begin(a); i < sites().end(a); ++i)
      wrench.add(r * rho[i - sites().begin(a)], site_force(i));  // (the arm, sites().arm(r, i))
    wrench.add_to(s, a, e);
  }

  /// The sites' forces in one pass over the bodies in order, LAMMPS's newton
  /// on: the pair terms of a batch of consecutive bodies (vectorized), then,
  /// body by body, per site i its own pairs' forces added to its running
  /// sum, each negated into its partner's. A site j's sum thus receives its lower partners' terms as the
  /// bodies below it are passed, by increasing partner index, and then its
  /// own in list order, from 0: the sum over its whole neighbourhood in index
  /// order (pairs beyond r_c add exact zeros, so it depends on the positions
  /// only). Each body's energy is summed in list order in the same loop (its
  /// chain of additions runs beside the forces').
  ///
  /// On T threads the bodies are cut into T consecutive ranges, one pass per
  /// range, and each site's sum is still that one, term by term: a site's
  /// lower partners in ranges below its own come first in index order, so
  /// they are added first, before the range's pass, from the terms of the
  /// pairs that cross into a higher range. Those are computed beforehand by
  /// all threads (the bodies with such pairs, split evenly); then, after a
  /// barrier, each range's pass starts its sites' sums with the crossing
  /// pairs' terms (x - y and x + (-y) are the same IEEE operation), by
  /// increasing partner, and adds a crossing pair only to its lower site.
  /// So results are bit-identical on any number of threads. Bodies numbered
  /// in space (a lattice) cross little; in the worst case, every body, this
  /// is two passes: all terms, then the sums.
  void ranged_pass(const SystemState& s, SystemEvaluation& e) {
    const std::size_t m = sites().size();
    site_force_.resize(4 * m);
    double* const site_force = site_force_.data();
    // Before the barrier: the terms of the bodies with crossing pairs, into
    // the crossing arrays, and their energies.
    auto crossing_terms = [&](std::size_t index) {
      thread_local Scratch scratch;
      const auto [a, b] = crossing_batches_[index];
      const std::size_t at = crossing_first_[a], first = lists_.list_begin(sites().begin(a));
      const bool finite =
          pair_terms(a, b, scratch, crossing_fx_.data() + at, crossing_fy_.data() + at, crossing_fz_.data() + at);
      for (std::size_t body = a; body < b; ++body) {
        finite_[body] = finite ? 1 : 0;
        sum_body_energy(body, scratch.energy.data() + (lists_.list_begin(sites().begin(body)) - first));
      }
    };
    auto range_pass = [&](std::size_t t) {
      thread_local PassScratch scratch;
      const std::size_t begin = range_bounds_[t], end = range_bounds_[t + 1];
      const std::size_t site_end = sites().begin(end);  // (begin(N) is the number of sites)
      // Each site's sum starts with its crossing pairs' terms, by increasing partner.
      const bool incoming = !incoming_start_.empty();
      for (std::size_t j = sites().begin(begin); j < site_end; ++j) {
        double fx = 0.0, fy = 0.0, fz = 0.0;
        const std::size_t l0 = incoming ? incoming_start_[j] : 0, l1 = incoming ? incoming_start_[j + 1] : 0;
        for (std::size_t l = l0; l < l1; ++l) {
          const std::size_t k = incoming_pair_[l];
          fx -= crossing_fx_[k];
          fy -= crossing_fy_[k];
          fz -= crossing_fz_[k];
        }
        site_force[4 * j] = fx;
        site_force[4 * j + 1] = fy;
        site_force[4 * j + 2] = fz;
      }
      // Body a's pass, its pair forces g and energies u at entry k - first;
      // `crossing`: its terms were computed before the barrier (energy too),
      // and its pairs with sites beyond the range are added to its own sites
      // only.
      auto scatter = [&](std::size_t a, std::size_t first, const double* gx, const double* gy, const double* gz,
                         const double* u, auto crossing) {
        double energy = 0.0;
        for (std::size_t i = sites().begin(a); i < sites().end(a); ++i) {
          double fx = site_force[4 * i], fy = site_force[4 * i + 1], fz = site_force[4 * i + 2];
          for (std::size_t k = lists_.list_begin(i); k < lists_.list_end(i); ++k) {
            const std::size_t j = lists_.partner(k);
            const double x = gx[k - first], y = gy[k - first], z = gz[k - first];
            fx += x;
            fy += y;
            fz += z;
            if constexpr (!decltype(crossing)::value) energy += u[k - first];
            if (decltype(crossing)::value && j >= site_end) continue;  // its partner has it already
            double* const fj = site_force + 4 * j;
            fj[0] -= x;
            fj[1] -= y;
            fj[2] -= z;
          }
          site_force[4 * i] = fx;
          site_force[4 * i + 1] = fy;
          site_force[4 * i + 2] = fz;
        }
        if constexpr (!decltype(crossing)::value) energy_[a] = energy;
      };
      auto wrench = [&](std::size_t a) {
        add_body_wrench(s, e, a, [&](std::size_t i) {
          return Vector3<double>(site_force[4 * i], site_force[4 * i + 1], site_force[4 * i + 2]);
        });
      };
      for (std::size_t a = begin; a < end;) {
        if (const std::size_t at = crossing_first_[a]; at != no_crossing) {
          scatter(a, lists_.list_begin(sites().begin(a)), crossing_fx_.data() + at, crossing_fy_.data() + at,
                  crossing_fz_.data() + at, nullptr, std::true_type{});
          wrench(a);
          ++a;
          continue;
        }
        // A batch of bodies [a, b) that do not cross, of about batch_entries
        // list entries: their pair terms in one call (the vectorized loop's
        // set-up and remainder shared), then each body's sums in order.
        const std::size_t first = lists_.list_begin(sites().begin(a));
        std::size_t b = a + 1;
        while (b < end && crossing_first_[b] == no_crossing &&
               lists_.list_begin(sites().begin(b)) - first < batch_entries)
          ++b;
        scratch.resize(lists_.list_begin(sites().end(b - 1)) - first);  // before taking the force buffers' addresses
        const bool finite = pair_terms(a, b, scratch, scratch.fx.data(), scratch.fy.data(), scratch.fz.data());
        for (; a < b; ++a) {
          // (A batch that may not be finite marks each of its bodies: the
          // report below looks at each again.)
          finite_[a] = finite ? 1 : 0;
          const std::size_t at = lists_.list_begin(sites().begin(a)) - first;
          scatter(a, first + at, scratch.fx.data() + at, scratch.fy.data() + at, scratch.fz.data() + at,
                  scratch.energy.data() + at, std::false_type{});
          wrench(a);
        }
      }
    };
    parallel_ranges(crossing_ranges_, crossing_terms, range_ids_, range_pass);
    // A force that is not finite (two sites on top of each other) stops the
    // run, naming the first such pair of the lowest body in list order, as a
    // serial pass would; report_collision returns for a body without one (a
    // batch that may not be finite marks each of its bodies). A pair is in
    // the list of its lower site, so the lowest body with a non-finite pair
    // in its sites' whole neighbourhoods is the lowest with one in its own
    // lists.
    for (std::size_t a = 0; a < s.size(); ++a)
      if (finite_[a] == 0) report_collision(a);
  }

  /// How the evaluation splits its work between threads (results do not
  /// depend on it), after the lists changed: the threads' ranges of bodies
  /// (`new_ranges`: split anew, at a build; else kept) and the pairs that
  /// cross between them (ranged_pass).
  void split_work(bool new_ranges) {
    work_ready_ = false;
    const std::size_t n = model_->sys.size(), m = sites().size();
    // The bodies into consecutive ranges of about equal pairs
    // (a gas that clusters makes halves by count uneven), the bodies with
    // pairs that cross into a higher range, and the crossing pairs' terms
    // by their higher site (ranged_pass).
    const int threads = par_.threads_for(n);
    auto entries = [&](std::size_t a) {
      return lists_.list_begin(sites().end(a)) - lists_.list_begin(sites().begin(a));
    };
    // The bodies with pairs into a higher range than theirs: each range's
    // on a thread, then their offsets in order.
    auto find_crossing = [&] {
      const std::size_t ranges = range_bounds_.size() - 1;
      crossing_first_.resize(n);
      range_crossing_.resize(ranges);
      parallel_for(ranges, Parallelism{par_.threads, 1}, [&](std::size_t t) {
        std::vector<std::size_t>& found = range_crossing_[t];
        found.clear();
        const std::size_t site_end = sites().begin(range_bounds_[t + 1]);
        for (std::size_t a = range_bounds_[t]; a < range_bounds_[t + 1]; ++a) {
          bool crosses = false;  // each list is sorted: its last partner is its highest
          for (std::size_t i = sites().begin(a); i < sites().end(a); ++i)
            crosses =
                crosses ||
                (lists_.list_end(i) > lists_.list_begin(i) && lists_.partner(lists_.list_end(i) - 1) >= site_end);
          crossing_first_[a] = no_crossing;
          if (crosses) found.push_back(a);
        }
      });
      crossing_bodies_.clear();
      std::size_t pairs = 0;
      for (const std::vector<std::size_t>& found : range_crossing_)
        for (const std::size_t a : found) {
          crossing_first_[a] = static_cast<CrossingOffset>(pairs);
          crossing_bodies_.push_back(a);
          pairs += entries(a);
        }
      return pairs;
    };
    // First ranges of about equal pairs; then, as a crossing body's terms
    // are computed before the barrier by all threads, ranges of about equal
    // work after it: a pair costs 1 for its sum, and 2 more for its terms if
    // its body does not cross (the weights' measurement: docs/tuning.md). Which
    // bodies cross is taken from the first split; the second moves its
    // bounds a little, and the crossing bodies are then found again for it
    // (an estimate: results do not depend on the split).
    // Split at a build, kept at the prunings in between (the lists shrink
    // about alike everywhere), which saves their serial cost.
    if (new_ranges || range_bounds_.size() != static_cast<std::size_t>(threads) + 1) {
      range_bounds_ = balanced_ranges(n, threads, [&](std::size_t a) { return lists_.list_begin(sites().begin(a)); });
      if (threads > 1) {
        const std::size_t pairs = find_crossing();
        // The work before body a: 3 per entry before it, less 2 per entry of
        // the crossing bodies before it (crossing_first_ of the first crossing
        // body from a on, the entries of those before it). (`next`: that
        // body's place in crossing_bodies_, found again only where a goes
        // back: balanced_ranges asks for the total, then scans up.)
        std::size_t next = 0;
        range_bounds_ = balanced_ranges(n, threads, [&](std::size_t a) {
          if (next > 0 && crossing_bodies_[next - 1] >= a)
            next = static_cast<std::size_t>(std::lower_bound(crossing_bodies_.begin(), crossing_bodies_.end(), a) -
                                            crossing_bodies_.begin());
          while (next < crossing_bodies_.size() && crossing_bodies_[next] < a) ++next;
          const std::size_t crossing = next == crossing_bodies_.size() ? pairs : crossing_first_[crossing_bodies_[next]];
          return 3 * lists_.list_begin(sites().begin(a)) - 2 * crossing;
        });
      }
    }
    range_ids_.resize(static_cast<std::size_t>(threads) + 1);
    for (std::size_t t = 0; t < range_ids_.size(); ++t) range_ids_[t] = t;
    const std::size_t crossing_pairs = find_crossing();
    crossing_fx_.resize(crossing_pairs);
    crossing_fy_.resize(crossing_pairs);
    crossing_fz_.resize(crossing_pairs);
    // The crossing bodies in batches of consecutive bodies (their entries
    // consecutive in the lists and in the crossing arrays), as a range pass
    // batches its others; the batches split between threads by entries.
    crossing_batches_.clear();
    for (std::size_t index = 0; index < crossing_bodies_.size(); ++index) {
      const std::size_t a = crossing_bodies_[index];
      if (!crossing_batches_.empty() && crossing_batches_.back().second == a &&
          crossing_first_[a] - crossing_first_[crossing_batches_.back().first] < batch_entries)
        crossing_batches_.back().second = a + 1;
      else
        crossing_batches_.emplace_back(a, a + 1);
    }
    crossing_ranges_ = balanced_ranges(crossing_batches_.size(), threads, [&](std::size_t index) {
      return index < crossing_batches_.size() ? crossing_first_[crossing_batches_[index].first] : crossing_pairs;
    });
    // Each site's crossing pairs (i, j), j this site, by increasing i: a
    // counting sort by j of the crossing bodies' pairs in list order. (A
    // site's list is sorted, so its crossing pairs are its list's tail.)
    auto for_each_crossing_pair = [&](auto&& visit) {
      for (const std::size_t a : crossing_bodies_) {
        std::size_t t = 0;
        while (range_bounds_[t + 1] <= a) ++t;
        const std::size_t site_end = sites().begin(range_bounds_[t + 1]), first = lists_.list_begin(sites().begin(a));
        for (std::size_t i = sites().begin(a); i < sites().end(a); ++i) {
          std::size_t k = lists_.list_end(i);
          while (k > lists_.list_begin(i) && lists_.partner(k - 1) >= site_end) --k;
          for (; k < lists_.list_end(i); ++k) visit(lists_.partner(k), crossing_first_[a] + (k - first));
        }
      }
    };
    if (crossing_pairs == 0) {
      // (One thread, or no pair across ranges: no offsets per site.)
      incoming_start_ = {};
      incoming_pair_ = {};
    } else {
      incoming_start_.assign(m + 1, 0);
      for_each_crossing_pair([&](std::size_t j, std::size_t) { ++incoming_start_[j + 1]; });
      for (std::size_t i = 0; i < m; ++i) incoming_start_[i + 1] += incoming_start_[i];
      incoming_pair_.resize(incoming_start_[m]);
      // Each pair placed at incoming_start_[j]++, which then holds site j's
      // end, the next one's start: the starts are moved back up one place.
      for_each_crossing_pair([&](std::size_t j, std::size_t k) {
        incoming_pair_[incoming_start_[j]++] = static_cast<CrossingOffset>(k);
      });
      for (std::size_t j = m; j > 0; --j) incoming_start_[j] = incoming_start_[j - 1];
      incoming_start_[0] = 0;
    }
    work_ready_ = true;
  }

  /// The model: the bodies and the kernel, fixed at construction and shared
  /// by copies. Everything below but the threads is the workspace, each
  /// copy its own: the lists, and what an evaluation writes.
  struct Model {
    System sys;
    Kernel kernel;
  };
  std::shared_ptr<const Model> model_;
  Parallelism par_;
  NeighbourLists lists_;
  std::vector<double> energy_;
  std::vector<char> finite_;  ///< per body: its pairs' forces are finite
  /// ranged_pass: each site's running force sum (x, y, z and a pad: one
  /// cache line holds two sites, a partner's three components are one access).
  std::vector<double> site_force_;
  /// Range t: bodies [range_bounds_[t], range_bounds_[t + 1]); range_ids_ = 0, 1, ..., T.
  std::vector<std::size_t> range_bounds_, range_ids_;
  /// An offset into the crossing arrays: they hold list entries, fewer than
  /// 2^32 (the lists' own offsets are 4 bytes, checked at each build).
  using CrossingOffset = std::uint32_t;
  static constexpr CrossingOffset no_crossing = std::numeric_limits<CrossingOffset>::max();
  /// A range pass computes the pair terms of consecutive bodies in batches
  /// of about this many list entries (7 arrays of it stay in a core's L1).
  static constexpr std::size_t batch_entries = 256;
  /// The bodies with pairs into a higher range, in order; per body, where
  /// its list entries' terms start in the crossing arrays (or no_crossing);
  /// the split of those bodies between threads.
  std::vector<std::size_t> crossing_bodies_, crossing_ranges_;
  std::vector<CrossingOffset> crossing_first_;
  std::vector<std::vector<std::size_t>> range_crossing_;  ///< find_crossing's, per range
  std::vector<double> crossing_fx_, crossing_fy_, crossing_fz_;  ///< per entry: the force on its list's site
  /// The crossing bodies in batches [first, end) of consecutive bodies.
  std::vector<std::pair<std::size_t, std::size_t>> crossing_batches_;
  /// Site j's crossing pairs: incoming_pair_[incoming_start_[j] ...
  /// incoming_start_[j + 1]) index the crossing arrays, by increasing lower
  /// site (both empty where no pair crosses).
  std::vector<CrossingOffset> incoming_start_, incoming_pair_;
  bool work_ready_ = false;  ///< the ranges and crossing pairs are those of the current lists
};

}  // namespace lgvi
