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
// Neighbours by Verlet lists, as in LAMMPS and HOOMD: each site keeps the
// sites of higher bodies within r_c + skin (half lists, below), found with a
// cell list (cubic cells of side >= (r_c + skin) / 2 over the sites' bounding
// box, at most ~2 per site, so a dilute system gets larger cells instead of a
// huge empty grid; counting sort, O(S)). The lists are rebuilt when some site has moved more
// than skin/2 since the last build (then no pair can have crossed into r_c
// unseen), so the cost grows like the number of sites, not its square.
//
// Pruned lists (GROMACS's dynamic pruning): the evaluation passes only the
// pairs of those lists within r_c + delta (delta = skin/3), pruned from them
// again when some site has moved more than delta/2 since the last pruning.
// A pair within r_c now is in the lists (the skin's argument) and was within
// r_c + delta at the pruning (each site has moved at most delta/2 since), so
// no pair within r_c is missed. Results do not depend on it (pairs beyond r_c
// add exact zeros, below). The measured fractions of pairs and costs are in
// docs/benchmarks.md ("Against LAMMPS": how lgvi computes the pairs) and in docs/tuning.md.
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

#include <lgvi/interaction.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <concepts>
#include <cstdint>
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

/// The pair terms of `count` list entries with separations d = (dx, dy, dz):
/// r^2 = (dx^2 + dy^2) + dz^2, the force on the list's site f = coef d into
/// (fx, fy, fz), and the pair's energy into `energy`, from the kernel for
/// r^2 < r_c^2; all 0 for r >= r_c. `pair`: each entry's pair of site types
/// for a TypedPairKernel (ignored, and may be null, otherwise). Returns true if every force is finite
/// (false may also mean a sum of components overflowed: the caller looks).
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
bool pair_terms(std::size_t count, const Kernel& kernel, const double* __restrict dx, const double* __restrict dy,
                const double* __restrict dz, const std::uint32_t* __restrict pair, double* __restrict fx,
                double* __restrict fy, double* __restrict fz, double* __restrict energy) {
  // A local copy of a trivially copyable kernel (its constants stay in
  // registers); a kernel that shares a table (TypedPairKernel's) by reference.
  std::conditional_t<std::is_trivially_copyable_v<Kernel>, const Kernel, const Kernel&> k = kernel;
  const double cutoff2 = k.cutoff2();
  double bad = 0.0;  // (a double, not a bool: this form GCC vectorizes)
  for (std::size_t i = 0; i < count; ++i) {
    const double r2 = (dx[i] * dx[i] + dy[i] * dy[i]) + dz[i] * dz[i];
    const bool inside = r2 < cutoff2;
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
  return bad == 0.0;
}

}  // namespace detail

/// A pair interaction over `Kernel` between the sites of different bodies
/// (the comment at the top of this file): a MutualInteraction.
template <PairKernel Kernel>
class PairInteraction {
 public:
  /// `skin`: the Verlet lists hold pairs within cutoff + skin (>= 0; LAMMPS's
  /// default is 0.3 sigma for Lennard-Jones).
  PairInteraction(const System& sys, const Kernel& kernel, Parallelism par, double skin)
      : sys_(sys), sites_(sys), kernel_(kernel), cutoff_(kernel.cutoff()), skin_(skin),
        prune_margin_(prune_fraction * skin_), par_(par), box_(sys.box()) {
    if (sites_.size() > max_sites)
      throw InvalidInput("interaction: " + std::to_string(sites_.size()) +
                         " interaction sites; the neighbour lists index at most " + std::to_string(max_sites) +
                         " (2^31 - 1); split the system");
    if constexpr (TypedPairKernel<Kernel>) {
      for (std::size_t i = 0; i < sites_.size(); ++i)
        if (sites_.type(i) >= kernel.types())
          throw InvalidInput("interaction: a site of type " + std::to_string(sites_.type(i) + 1) +
                             " has no coefficients (the interaction's types are 1.." +
                             std::to_string(kernel.types()) + ")");
    }
    if (box_.any_periodic() && !(2.0 * (cutoff_ + skin_) < box_.shortest_periodic_length()))
      throw InvalidInput("interaction.cutoff: the cutoff + skin = " + std::to_string(cutoff_ + skin_) +
                         " must be less than half the shortest periodic length of the box (" +
                         std::to_string(box_.shortest_periodic_length()) +
                         "), so that a pair has one image within reach; enlarge the box or shorten the cutoff or skin");
  }

  void add(const SystemState& s, SystemEvaluation& e) const {
    prepare(s);
    const std::size_t n = s.size();
    energy_.assign(n, 0.0);
    finite_.assign(n, 1);
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
  double virial(const SystemState& s) const {
    prepare(s);
    PassScratch scratch;
    double total = 0.0;
    for (std::size_t a = 0; a < s.size(); ++a) {
      const std::size_t first = list_start_[sites_.begin(a)];
      scratch.resize(list_start_[sites_.end(a)] - first);
      pair_terms(a, a + 1, scratch, scratch.fx.data(), scratch.fy.data(), scratch.fz.data());
      double w = 0.0;
      for (std::size_t i = sites_.begin(a); i < sites_.end(a); ++i)
        for (std::size_t k = list_start_[i]; k < list_start_[i + 1]; ++k) {
          // X_a - X_b = -d - rho_i + rho_j, d = X_j - X_i (minimum image); beyond r_c f = 0 exactly.
          const Vector3<double> centres = arm_[neighbours_[k]] - arm_[i] -
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
  std::int64_t list_builds() const { return builds_; }
  std::int64_t list_prunes() const { return prunes_; }

  const Kernel& kernel() const { return kernel_; }
  double cutoff() const { return cutoff_; }
  double skin() const { return skin_; }

 private:
  /// Places the sites of `s` and brings the lists up to date for it.
  void prepare(const SystemState& s) const {
    const std::size_t n = s.size();
    // The sites, and whether any moved more than skin/2 since the lists were
    // built (then no pair can have crossed into r_c unseen), or else more
    // than delta/2 since they were pruned, per body on the thread that
    // placed it.
    const bool have_lists = lists_ready_ && built_at_.size() == sites_.size();
    const double limit = 0.25 * skin_ * skin_, prune_limit = 0.25 * prune_margin_ * prune_margin_;
    moved_.resize(n);
    sites_.place(s, par_, position_, arm_, [&](std::size_t a) {
      char moved = have_lists ? no_move : beyond_skin;
      for (std::size_t i = sites_.begin(a); i < sites_.end(a) && moved != beyond_skin; ++i) {
        // (Both also true for NaN.)
        if (!((position_[i] - built_at_[i]).squaredNorm() <= limit)) moved = beyond_skin;
        else if (!((position_[i] - pruned_at_[i]).squaredNorm() <= prune_limit)) moved = beyond_margin;
      }
      moved_[a] = moved;
    });
    const char most = *std::max_element(moved_.begin(), moved_.end());
    if (most == beyond_skin) build_lists();
    else if (most == beyond_margin) prune_lists();
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

  /// The separations d = X_j - X_i of the list entries of bodies [a, b) into
  /// the scratch (entry k - first, first the bodies' first entry); their count.
  /// In a periodic box, each separation's minimum image (box.hpp). For a
  /// TypedPairKernel also each entry's pair of site types.
  template <class Buffers>
  std::size_t gather(std::size_t a, std::size_t b, Buffers& scratch) const {
    return box_.any_periodic() ? gather<true>(a, b, scratch) : gather<false>(a, b, scratch);
  }
  template <bool Periodic, class Buffers>
  std::size_t gather(std::size_t a, std::size_t b, Buffers& scratch) const {
    const std::size_t first = list_start_[sites_.begin(a)], count = list_start_[sites_.end(b - 1)] - first;
    scratch.resize(count);
    for (std::size_t i = sites_.begin(a); i < sites_.end(b - 1); ++i) {
      const Vector3<double> xi = position_[i];
      for (std::size_t k = list_start_[i]; k < list_start_[i + 1]; ++k) {
        const Vector3<double>& xj = position_[neighbours_[k]];
        scratch.dx[k - first] = separation<Periodic>(xj(0) - xi(0), 0);
        scratch.dy[k - first] = separation<Periodic>(xj(1) - xi(1), 1);
        scratch.dz[k - first] = separation<Periodic>(xj(2) - xi(2), 2);
      }
      if constexpr (TypedPairKernel<Kernel>) {
        const std::uint32_t row = kernel_.types() * sites_.type(i);
        for (std::size_t k = list_start_[i]; k < list_start_[i + 1]; ++k)
          scratch.pair[k - first] = row + sites_.type(neighbours_[k]);
      }
    }
    return count;
  }

  /// A site's index in the lists (4 bytes: the lists are most of the
  /// interaction's memory); at most max_sites sites.
  using SiteIndex = std::uint32_t;
  static constexpr std::size_t max_sites = 0x7fffffff;

  /// A separation's component along axis k: its minimum image in a periodic
  /// box (the identity along an open axis), as it is.
  template <bool Periodic>
  double separation(double d, int k) const {
    if constexpr (Periodic) return box_.reduce(d, k);
    else return d;
  }

  /// The candidates[0, n) within r^2 < reach2 of position x, in their order,
  /// into list (which has room for n); returns how many. Branch-free: each
  /// candidate is written, and kept by advancing the count (the lists'
  /// build and pruning both filter so).
  template <bool Periodic>
  std::size_t within(const Vector3<double>* position, const Vector3<double>& x, const SiteIndex* candidates,
                     std::size_t n, double reach2, SiteIndex* list) const {
    const double xi = x(0), yi = x(1), zi = x(2);
    std::size_t count = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const SiteIndex j = candidates[k];
      const double dx = separation<Periodic>(position[j](0) - xi, 0),
                   dy = separation<Periodic>(position[j](1) - yi, 1),
                   dz = separation<Periodic>(position[j](2) - zi, 2);
      list[count] = j;
      count += static_cast<std::size_t>(dx * dx + dy * dy + dz * dz < reach2);
    }
    return count;
  }

  /// The pair terms of bodies [a, b): the separations gathered into the
  /// scratch, the forces on their sites into fx, fy, fz and the pairs'
  /// energies into the scratch's `energy` (entry k - first of their list
  /// entries). Each entry's terms depend on its separation only, so they are
  /// the same computed for one body or several at once. Returns false if a
  /// force may not be finite (as detail::pair_terms).
  template <class Buffers>
  bool pair_terms(std::size_t a, std::size_t b, Buffers& scratch, double* fx, double* fy, double* fz) const {
    const std::size_t count = gather(a, b, scratch);
    return detail::pair_terms(count, kernel_, scratch.dx.data(), scratch.dy.data(), scratch.dz.data(),
                              scratch.pair.data(), fx, fy, fz, scratch.energy.data());
  }

  /// The energy of body a's pairs, summed in list order into energy_[a], from
  /// their energies u (entry k - first, first the body's first entry).
  /// Beyond r_c a pair's energy is 0 and adds nothing: x + 0 = x (no sum here
  /// is ever -0).
  void sum_body_energy(std::size_t a, const double* u) const {
    const std::size_t count = list_start_[sites_.end(a)] - list_start_[sites_.begin(a)];
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
    const std::size_t first = list_start_[sites_.begin(a)];
    scratch.resize(list_start_[sites_.end(a)] - first);
    pair_terms(a, a + 1, scratch, scratch.fx.data(), scratch.fy.data(), scratch.fz.data());
    for (std::size_t i = sites_.begin(a); i < sites_.end(a); ++i)
      for (std::size_t k = list_start_[i]; k < list_start_[i + 1]; ++k)
        if (!(std::isfinite(scratch.fx[k - first]) && std::isfinite(scratch.fy[k - first]) &&
              std::isfinite(scratch.fz[k - first]))) {
          const std::size_t j = neighbours_[k];
          detail::close_approach(sys_, sites_, i, j, box_.minimum_image(position_[j] - position_[i]).norm());
        }
  }

  /// Body a's force and torque from its sites' forces f_i (summed over each
  /// site's whole neighbourhood), in site order (SiteWrench).
  template <class SiteForce>
  void add_body_wrench(const SystemState& s, SystemEvaluation& e, std::size_t a, SiteForce&& site_force) const {
    SiteWrench wrench;
    for (std::size_t i = sites_.begin(a); i < sites_.end(a); ++i) wrench.add(arm_[i], site_force(i));
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
  void ranged_pass(const SystemState& s, SystemEvaluation& e) const {
    const std::size_t m = position_.size();
    site_force_.resize(4 * m);
    double* const site_force = site_force_.data();
    // Before the barrier: the terms of the bodies with crossing pairs, into
    // the crossing arrays, and their energies.
    auto crossing_terms = [&](std::size_t index) {
      thread_local Scratch scratch;
      const auto [a, b] = crossing_batches_[index];
      const std::size_t at = crossing_first_[a], first = list_start_[sites_.begin(a)];
      const bool finite =
          pair_terms(a, b, scratch, crossing_fx_.data() + at, crossing_fy_.data() + at, crossing_fz_.data() + at);
      for (std::size_t body = a; body < b; ++body) {
        finite_[body] = finite ? 1 : 0;
        sum_body_energy(body, scratch.energy.data() + (list_start_[sites_.begin(body)] - first));
      }
    };
    auto range_pass = [&](std::size_t t) {
      thread_local PassScratch scratch;
      const std::size_t begin = range_bounds_[t], end = range_bounds_[t + 1];
      const std::size_t site_end = sites_.begin(end);  // (begin(N) is the number of sites)
      // Each site's sum starts with its crossing pairs' terms, by increasing partner.
      for (std::size_t j = sites_.begin(begin); j < site_end; ++j) {
        double fx = 0.0, fy = 0.0, fz = 0.0;
        for (std::size_t l = incoming_start_[j]; l < incoming_start_[j + 1]; ++l) {
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
        for (std::size_t i = sites_.begin(a); i < sites_.end(a); ++i) {
          double fx = site_force[4 * i], fy = site_force[4 * i + 1], fz = site_force[4 * i + 2];
          for (std::size_t k = list_start_[i]; k < list_start_[i + 1]; ++k) {
            const std::size_t j = neighbours_[k];
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
          scatter(a, list_start_[sites_.begin(a)], crossing_fx_.data() + at, crossing_fy_.data() + at,
                  crossing_fz_.data() + at, nullptr, std::true_type{});
          wrench(a);
          ++a;
          continue;
        }
        // A batch of bodies [a, b) that do not cross, of about batch_entries
        // list entries: their pair terms in one call (the vectorized loop's
        // set-up and remainder shared), then each body's sums in order.
        const std::size_t first = list_start_[sites_.begin(a)];
        std::size_t b = a + 1;
        while (b < end && crossing_first_[b] == no_crossing && list_start_[sites_.begin(b)] - first < batch_entries)
          ++b;
        scratch.resize(list_start_[sites_.end(b - 1)] - first);  // before taking the force buffers' addresses
        const bool finite = pair_terms(a, b, scratch, scratch.fx.data(), scratch.fy.data(), scratch.fz.data());
        for (; a < b; ++a) {
          // (A batch that may not be finite marks each of its bodies: the
          // report below looks at each again.)
          finite_[a] = finite ? 1 : 0;
          const std::size_t at = list_start_[sites_.begin(a)] - first;
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

  /// The cell of a site at x: along an open axis from the sites' bounding
  /// box (clamped to it); along a periodic one from x's fractional
  /// coordinate in the box, wrapped into [0, 1).
  std::array<std::int64_t, 3> cell_of(const Vector3<double>& x) const {
    std::array<std::int64_t, 3> c{};
    for (int k = 0; k < 3; ++k) {
      const std::int64_t dims = dims_[static_cast<std::size_t>(k)];
      std::int64_t v = 0;
      if (box_.periodic(k)) {  // (origin_(k) is the box's lower face there)
        v = static_cast<std::int64_t>(box_.fraction(x(k), k) * static_cast<double>(dims));
      } else {
        v = static_cast<std::int64_t>((x(k) - origin_(k)) * inv_cell_(k));
      }
      c[static_cast<std::size_t>(k)] = std::clamp<std::int64_t>(v, 0, dims - 1);
    }
    return c;
  }

  /// The cells along axis k that meet [from, to]: one run of consecutive
  /// cells, or two where a periodic axis wraps around (every cell once if the
  /// interval is as long as the box).
  struct CellRuns {
    int count = 1;
    std::array<std::array<std::int64_t, 2>, 2> run{};
  };
  CellRuns cells_between(int k, double from, double to) const {
    CellRuns r;
    const std::int64_t dims = dims_[static_cast<std::size_t>(k)];
    if (!box_.periodic(k)) {
      Vector3<double> a = Vector3<double>::Constant(origin_(k)), b = a;
      a(k) = from;
      b(k) = to;
      r.run[0] = {cell_of(a)[static_cast<std::size_t>(k)], cell_of(b)[static_cast<std::size_t>(k)]};
      return r;
    }
    // Unwrapped cell numbers, widened by the rounding of the fractional
    // coordinates (cell_of wraps them before scaling, this does not).
    const double scale = box_.inverse_periodic_length()(k) * static_cast<double>(dims);
    const double slack = 1e-12 * (std::abs(from - origin_(k)) + std::abs(to - origin_(k)) + box_.periodic_length()(k));
    const double u0 = std::floor((from - slack - origin_(k)) * scale), u1 = std::floor((to + slack - origin_(k)) * scale);
    const auto d = static_cast<double>(dims);
    if (!(u1 - u0 + 1.0 < d)) {  // (also where far sites have lost their place in the box to rounding)
      r.run[0] = {0, dims - 1};
      return r;
    }
    // The cells modulo dims, in double (u0 may be beyond any integer type).
    auto wrapped = [&](double u) {
      return std::clamp<std::int64_t>(static_cast<std::int64_t>(std::clamp(u - d * std::floor(u / d), 0.0, d - 1.0)), 0,
                                      dims - 1);
    };
    const std::int64_t a = wrapped(u0), b = wrapped(u1);
    if (a <= b) {
      r.run[0] = {a, b};
    } else {
      r.count = 2;
      r.run[0] = {a, dims - 1};
      r.run[1] = {0, b};
    }
    return r;
  }

  /// Sorts the sites into cells of side >= (r_c + skin) / 2, then lists for
  /// every site the sites of higher bodies within r_c + skin, by increasing
  /// index (the outer lists); then prunes them (prune_lists).
  void build_lists() const { box_.any_periodic() ? build_lists<true>() : build_lists<false>(); }
  template <bool Periodic>
  void build_lists() const {
    ++builds_;
    const std::size_t m = position_.size();
    Vector3<double> lo = position_[0], hi = position_[0];
    for (const Vector3<double>& x : position_) {
      lo = lo.cwiseMin(x);
      hi = hi.cwiseMax(x);
    }
    if (!(lo.allFinite() && hi.allFinite())) throw StepFailure("the state became non-finite", "try a smaller step");
    const double reach = cutoff_ + skin_;
    origin_ = lo;
    const double budget = std::max(1.0, std::floor(std::cbrt(2.0 * static_cast<double>(m) + 1.0)));
    std::size_t cells = 1;
    for (int k = 0; k < 3; ++k) {
      // A periodic axis: cells over the box, a whole number of them (each
      // at least reach / cells_per_reach wide), whatever the sites' spread.
      const bool periodic = box_.periodic(k);
      if (periodic) origin_(k) = box_.lower()(k);
      const double extent = periodic ? box_.periodic_length()(k) : hi(k) - lo(k);
      const double count = std::clamp(std::floor(extent * cells_per_reach / reach), 1.0, budget);
      dims_[static_cast<std::size_t>(k)] = static_cast<std::int64_t>(count);
      inv_cell_(k) = count / std::max(extent, reach / cells_per_reach);
      cells *= static_cast<std::size_t>(count);
    }
    cell_index_.resize(m);
    cell_start_.assign(cells + 1, 0);
    for (std::size_t i = 0; i < m; ++i) {
      const std::array<std::int64_t, 3> c = cell_of(position_[i]);
      cell_index_[i] = static_cast<SiteIndex>((c[2] * dims_[1] + c[1]) * dims_[0] + c[0]);
      ++cell_start_[cell_index_[i] + 1];
    }
    for (std::size_t c = 0; c < cells; ++c) cell_start_[c + 1] += cell_start_[c];
    fill_.assign(cell_start_.begin(), cell_start_.end() - 1);
    sorted_.resize(m);
    for (std::size_t i = 0; i < m; ++i) sorted_[fill_[cell_index_[i]]++] = static_cast<SiteIndex>(i);
    // The sites' positions and bodies in cell order: a row of neighbouring
    // cells along x is one contiguous run of these arrays.
    cell_x_.resize(m);
    cell_y_.resize(m);
    cell_z_.resize(m);
    cell_body_.resize(m);
    for (std::size_t k = 0; k < m; ++k) {
      const Vector3<double>& x = position_[sorted_[k]];
      cell_x_[k] = x(0);
      cell_y_[k] = x(1);
      cell_z_[k] = x(2);
      cell_body_[k] = static_cast<SiteIndex>(sites_.body_of(sorted_[k]));
    }
    // The lists, one body after the other. Each site's list is its own: the
    // sites of higher bodies within r_c + skin, by index. Per body (per site
    // for a body of more than group_sites sites), first the sites of higher
    // bodies near it: those in the cells around its sites' bounding box
    // (extended by r_c + skin) within r_c + skin + R of the box's centre (R:
    // the farthest of its sites from it), sorted by index; then each site's
    // list is the sites of those within r_c + skin of it, in that order.
    // (Per body rather than per site: the body's sites share their
    // surroundings, so each cell is visited and each candidate is sorted
    // once for all of them.) So the lists do not depend on who
    // builds them: the bodies are cut into fixed chunks, each chunk's lists
    // built on some thread into the chunk's buffer (where they stay: the
    // outer lists, outer_lists_).
    lists_ready_ = false;  // (until the pruning below completes: a build cut short by an exception is redone)
    const std::size_t n = sys_.size();
    const double reach2 = reach * reach;
    const std::size_t chunks = std::min<std::size_t>(n, list_chunks);
    outer_lists_.resize(chunks);
    chunk_used_.resize(chunks);
    outer_start_.assign(m + 1, 0);
    built_at_.resize(m);
    parallel_for(chunks, par_, [&](std::size_t chunk) {
      std::vector<SiteIndex>& out = outer_lists_[chunk];
      std::size_t& used = chunk_used_[chunk];  // out's entries in use (out only grows: no zero fill per site)
      used = 0;
      // Where the chunk's sites are now (the skin's reference).
      std::copy(position_.begin() + static_cast<std::ptrdiff_t>(sites_.begin(chunk * n / chunks)),
                position_.begin() + static_cast<std::ptrdiff_t>(sites_.begin((chunk + 1) * n / chunks)),
                built_at_.begin() + static_cast<std::ptrdiff_t>(sites_.begin(chunk * n / chunks)));
      thread_local std::vector<SiteIndex> near;
      for (std::size_t a = chunk * n / chunks; a < (chunk + 1) * n / chunks; ++a) {
        // A body of many sites (a wall, a long chain) goes site by site: its
        // box would hold candidates for all of them, each site scanning all.
        const std::size_t group = sites_.end(a) - sites_.begin(a) <= group_sites ? group_sites : 1;
        for (std::size_t g0 = sites_.begin(a); g0 < sites_.end(a); g0 += group) {
          const std::size_t g1 = std::min(g0 + group, sites_.end(a));
          Vector3<double> lo = position_[g0], hi = lo;
          for (std::size_t i = g0 + 1; i < g1; ++i) {
            lo = lo.cwiseMin(position_[i]);
            hi = hi.cwiseMax(position_[i]);
          }
          const Vector3<double> centre = 0.5 * (lo + hi);
          double radius2 = 0.0;
          for (std::size_t i = g0; i < g1; ++i) radius2 = std::max(radius2, (position_[i] - centre).squaredNorm());
          // Generous by a relative 1e-9: only a filter, the test below is exact.
          const double around = (reach + std::sqrt(radius2)) * (1.0 + 1e-9), around2 = around * around;
          const CellRuns xs = cells_between(0, lo(0) - reach, hi(0) + reach),
                         ys = cells_between(1, lo(1) - reach, hi(1) + reach),
                         zs = cells_between(2, lo(2) - reach, hi(2) + reach);
          const double cx = centre(0), cy = centre(1), cz = centre(2);
          std::size_t kept = 0;
          for (int zr = 0; zr < zs.count; ++zr)
            for (std::int64_t z = zs.run[zr][0]; z <= zs.run[zr][1]; ++z)
              for (int yr = 0; yr < ys.count; ++yr)
                for (std::int64_t y = ys.run[yr][0]; y <= ys.run[yr][1]; ++y)
                  for (int xr = 0; xr < xs.count; ++xr) {
                    const auto row = static_cast<std::size_t>((z * dims_[1] + y) * dims_[0]);
                    const std::size_t run_first = cell_start_[row + static_cast<std::size_t>(xs.run[xr][0])],
                                      run_end = cell_start_[row + static_cast<std::size_t>(xs.run[xr][1]) + 1];
                    if (near.size() < kept + (run_end - run_first)) near.resize(2 * (kept + (run_end - run_first)));
                    SiteIndex* const list = near.data();
                    // Every candidate written, the count advanced only for those kept:
                    // no branch to mispredict on the distance test.
                    for (std::size_t k = run_first; k < run_end; ++k) {
                      const double dx = separation<Periodic>(cell_x_[k] - cx, 0),
                                   dy = separation<Periodic>(cell_y_[k] - cy, 1),
                                   dz = separation<Periodic>(cell_z_[k] - cz, 2);
                      list[kept] = sorted_[k];
                      kept += static_cast<std::size_t>((dx * dx + dy * dy + dz * dz < around2) & (cell_body_[k] > a));
                    }
                  }
          // By index; insertion sort for tens of sites, where it is fastest
          // (and the candidates, in cell order, come nearly sorted in a gas
          // numbered along its lattice).
          if (kept > 64) {
            std::sort(near.begin(), near.begin() + static_cast<std::ptrdiff_t>(kept));
          } else {
            for (std::size_t k = 1; k < kept; ++k) {
              const SiteIndex j = near[k];
              std::size_t slot = k;
              for (; slot > 0 && near[slot - 1] > j; --slot) near[slot] = near[slot - 1];
              near[slot] = j;
            }
          }
          for (std::size_t i = g0; i < g1; ++i) {
            const std::size_t first = used;
            if (out.size() < first + kept) {
              // Grown by a quarter (a vector's resize would double it): the
              // chunks' buffers are the outer lists, kept between builds.
              out.reserve(first + kept + (first + kept) / 4);
              out.resize(out.capacity());
            }
            const std::size_t count =
                within<Periodic>(position_.data(), position_[i], near.data(), kept, reach2, out.data() + first);
            used = first + count;
            outer_start_[i + 1] = count;  // summed below
          }
        }
      }
    });
    for (std::size_t i = 0; i < m; ++i) outer_start_[i + 1] += outer_start_[i];
    // Room for the pruned lists in place of the outer ones (prune_lists).
    neighbours_.resize(outer_start_[m]);
    prune_lists<Periodic>(true);
  }

  /// The outer lists' entries within r_c + prune_margin_ now, per site in
  /// the same order: the lists the evaluation passes (neighbours_,
  /// list_start_). Then the threads' ranges (`new_ranges`: split anew, at a
  /// build; else kept) and the pairs that cross between them (ranged_pass).
  void prune_lists() const { box_.any_periodic() ? prune_lists<true>(false) : prune_lists<false>(false); }
  template <bool Periodic>
  void prune_lists(bool new_ranges) const {
    ++prunes_;
    lists_ready_ = false;
    const std::size_t n = sys_.size(), m = position_.size();
    // Generous by a relative 1e-9, as the build's filter: no pair within the
    // margin is lost to the rounding of r^2.
    const double reach = (cutoff_ + prune_margin_) * (1.0 + 1e-9), reach2 = reach * reach;
    const std::size_t chunks = std::min<std::size_t>(n, list_chunks);
    chunk_used_.resize(chunks);
    list_start_.assign(m + 1, 0);
    pruned_at_.resize(m);
    // Each chunk's pruned lists first where its outer lists' entries would
    // be in one array (neighbours_[outer_start_[i0] ...), then moved down in
    // chunk order to follow the previous chunk's.
    parallel_for(chunks, par_, [&](std::size_t chunk) {
      const std::size_t i0 = sites_.begin(chunk * n / chunks), i1 = sites_.begin((chunk + 1) * n / chunks);
      std::copy(position_.begin() + static_cast<std::ptrdiff_t>(i0), position_.begin() + static_cast<std::ptrdiff_t>(i1),
                pruned_at_.begin() + static_cast<std::ptrdiff_t>(i0));  // the margin's reference
      const Vector3<double>* const position = position_.data();
      const SiteIndex* const outer = outer_lists_[chunk].data();  // site i's: outer[outer_start_[i] - base ...]
      const std::size_t base = outer_start_[i0];
      SiteIndex* const list = neighbours_.data() + base;
      std::size_t count = 0;
      for (std::size_t i = i0; i < i1; ++i) {
        const std::size_t k0 = outer_start_[i] - base, k1 = outer_start_[i + 1] - base;
        const std::size_t kept = within<Periodic>(position, position[i], outer + k0, k1 - k0, reach2, list + count);
        count += kept;
        list_start_[i + 1] = kept;  // summed below
      }
      chunk_used_[chunk] = count;
    });
    for (std::size_t i = 0; i < m; ++i) list_start_[i + 1] += list_start_[i];
    for (std::size_t chunk = 0; chunk < chunks; ++chunk) {  // (to lower or equal offsets: in order, nothing unread is overwritten)
      const std::size_t i0 = sites_.begin(chunk * n / chunks);
      if (list_start_[i0] == outer_start_[i0]) continue;  // (in place already)
      const auto from = neighbours_.begin() + static_cast<std::ptrdiff_t>(outer_start_[i0]);
      std::copy(from, from + static_cast<std::ptrdiff_t>(chunk_used_[chunk]),
                neighbours_.begin() + static_cast<std::ptrdiff_t>(list_start_[i0]));
    }
    // How the evaluation splits its work between threads (results do not
    // depend on it): the bodies into consecutive ranges of about equal pairs
    // (a gas that clusters makes halves by count uneven), the bodies with
    // pairs that cross into a higher range, and the crossing pairs' terms
    // by their higher site (ranged_pass).
    const int threads = par_.threads_for(n);
    auto entries = [&](std::size_t a) { return list_start_[sites_.end(a)] - list_start_[sites_.begin(a)]; };
    // The bodies with pairs into a higher range than theirs: each range's
    // on a thread (the one that pruned its lists, whose cache holds them),
    // then their offsets in order.
    auto find_crossing = [&] {
      const std::size_t ranges = range_bounds_.size() - 1;
      crossing_first_.resize(n);
      range_crossing_.resize(ranges);
      parallel_for(ranges, Parallelism{par_.threads, 1}, [&](std::size_t t) {
        std::vector<std::size_t>& found = range_crossing_[t];
        found.clear();
        const std::size_t site_end = sites_.begin(range_bounds_[t + 1]);
        for (std::size_t a = range_bounds_[t]; a < range_bounds_[t + 1]; ++a) {
          bool crosses = false;  // each list is sorted: its last partner is its highest
          for (std::size_t i = sites_.begin(a); i < sites_.end(a); ++i)
            crosses =
                crosses || (list_start_[i + 1] > list_start_[i] && neighbours_[list_start_[i + 1] - 1] >= site_end);
          crossing_first_[a] = no_crossing;
          if (crosses) found.push_back(a);
        }
      });
      crossing_bodies_.clear();
      std::size_t pairs = 0;
      for (const std::vector<std::size_t>& found : range_crossing_)
        for (const std::size_t a : found) {
          crossing_first_[a] = pairs;
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
      range_bounds_ = balanced_ranges(n, threads, [&](std::size_t a) { return list_start_[sites_.begin(a)]; });
      if (threads > 1) {
        find_crossing();
        std::vector<std::size_t> work(n + 1, 0);
        for (std::size_t a = 0; a < n; ++a)
          work[a + 1] = work[a] + entries(a) * (crossing_first_[a] == no_crossing ? 3 : 1);
        range_bounds_ = balanced_ranges(n, threads, [&](std::size_t a) { return work[a]; });
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
    // counting sort by j of the crossing bodies' pairs in list order.
    incoming_start_.assign(m + 1, 0);
    // (A site's list is sorted, so its crossing pairs are its list's tail.)
    auto for_each_crossing_pair = [&](auto&& visit) {
      for (const std::size_t a : crossing_bodies_) {
        std::size_t t = 0;
        while (range_bounds_[t + 1] <= a) ++t;
        const std::size_t site_end = sites_.begin(range_bounds_[t + 1]), first = list_start_[sites_.begin(a)];
        for (std::size_t i = sites_.begin(a); i < sites_.end(a); ++i) {
          std::size_t k = list_start_[i + 1];
          while (k > list_start_[i] && neighbours_[k - 1] >= site_end) --k;
          for (; k < list_start_[i + 1]; ++k) visit(neighbours_[k], crossing_first_[a] + (k - first));
        }
      }
    };
    for_each_crossing_pair([&](std::size_t j, std::size_t) { ++incoming_start_[j + 1]; });
    for (std::size_t i = 0; i < m; ++i) incoming_start_[i + 1] += incoming_start_[i];
    fill_.assign(incoming_start_.begin(), incoming_start_.end() - 1);
    incoming_pair_.resize(incoming_start_[m]);
    for_each_crossing_pair([&](std::size_t j, std::size_t k) { incoming_pair_[fill_[j]++] = k; });
    lists_ready_ = true;
  }

  System sys_;
  InteractionSites sites_;
  Kernel kernel_;
  double cutoff_, skin_, prune_margin_;
  Parallelism par_;
  Box box_;  ///< the system's: separations are minimum images along its periodic axes
  mutable std::vector<Vector3<double>> position_, arm_;
  mutable std::vector<double> energy_;
  mutable std::vector<char> finite_;  ///< per body: its pairs' forces are finite
  mutable std::vector<char> moved_;  ///< per body: a site moved more than skin/2 since the build
  mutable Vector3<double> origin_ = Vector3<double>::Zero(), inv_cell_ = Vector3<double>::Ones();
  mutable std::array<std::int64_t, 3> dims_{1, 1, 1};
  /// The pruned lists hold the pairs within r_c + delta, delta =
  /// prune_fraction * skin (any fraction in (0, 1] gives the same results;
  /// this one was the fastest measured, docs/tuning.md).
  static constexpr double prune_fraction = 1.0 / 3.0;
  /// The lists are built in this many chunks of bodies (fixed, so that the
  /// work split does not depend on the threads; enough for load balance).
  static constexpr std::size_t list_chunks = 64;
  /// Cells are at least reach / cells_per_reach wide (reach = r_c + skin): a
  /// body's candidates are in the cells that meet its sites' bounding box
  /// extended by reach, a volume closer to that box's than with cells of
  /// side reach (docs/tuning.md).
  static constexpr double cells_per_reach = 2.0;
  mutable std::vector<std::size_t> cell_start_, fill_, list_start_;
  mutable std::vector<SiteIndex> cell_index_, sorted_;
  mutable std::vector<double> cell_x_, cell_y_, cell_z_;  ///< the sites' positions in cell order
  mutable std::vector<SiteIndex> cell_body_;              ///< and their bodies
  /// The pruned lists: site i's partners neighbours_[list_start_[i] ...
  /// list_start_[i + 1]) (the array as long as the outer lists, which it
  /// holds while they are pruned).
  mutable std::vector<SiteIndex> neighbours_;
  mutable std::vector<std::size_t> chunk_used_;  ///< per chunk: its list's entries in use
  /// ranged_pass: each site's running force sum (x, y, z and a pad: one
  /// cache line holds two sites, a partner's three components are one access).
  mutable std::vector<double> site_force_;
  /// Range t: bodies [range_bounds_[t], range_bounds_[t + 1]); range_ids_ = 0, 1, ..., T.
  mutable std::vector<std::size_t> range_bounds_, range_ids_;
  static constexpr std::size_t no_crossing = static_cast<std::size_t>(-1);
  /// A range pass computes the pair terms of consecutive bodies in batches
  /// of about this many list entries (7 arrays of it stay in a core's L1).
  static constexpr std::size_t batch_entries = 256;
  /// Lists are built per body for bodies of up to this many sites (molecules,
  /// rubble), site by site for larger ones (build_lists).
  static constexpr std::size_t group_sites = 16;
  /// The bodies with pairs into a higher range, in order; per body, where
  /// its list entries' terms start in the crossing arrays (or no_crossing);
  /// the split of those bodies between threads.
  mutable std::vector<std::size_t> crossing_bodies_, crossing_first_, crossing_ranges_;
  mutable std::vector<std::vector<std::size_t>> range_crossing_;  ///< find_crossing's, per range
  mutable std::vector<double> crossing_fx_, crossing_fy_, crossing_fz_;  ///< per entry: the force on its list's site
  /// The crossing bodies in batches [first, end) of consecutive bodies.
  mutable std::vector<std::pair<std::size_t, std::size_t>> crossing_batches_;
  /// Site j's crossing pairs: incoming_pair_[incoming_start_[j] ...
  /// incoming_start_[j + 1]) index the crossing arrays, by increasing lower site.
  mutable std::vector<std::size_t> incoming_start_, incoming_pair_;
  /// Per site: where it was at the last build and at the last pruning.
  mutable std::vector<Vector3<double>> built_at_, pruned_at_;
  /// The outer lists: per site i, the sites of higher bodies within r_c +
  /// skin at the last build, by index, in its chunk c's buffer:
  /// outer_lists_[c][outer_start_[i] - outer_start_[i0] ... outer_start_[i +
  /// 1] - outer_start_[i0]), i0 the chunk's first site (not joined into one
  /// array: only the pruning reads them, chunk by chunk); neighbours_ and
  /// list_start_ are their pruned form.
  mutable std::vector<std::size_t> outer_start_;
  mutable std::vector<std::vector<SiteIndex>> outer_lists_;
  mutable std::int64_t builds_ = 0, prunes_ = 0;
  mutable bool lists_ready_ = false;  ///< the lists are whole (a build and its pruning completed)
  /// moved_: how far a body's sites moved.
  static constexpr char no_move = 0, beyond_margin = 1, beyond_skin = 2;
};

}  // namespace lgvi
