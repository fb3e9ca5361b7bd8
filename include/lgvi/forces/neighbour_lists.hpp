// Verlet lists of the interaction sites of different bodies, the one
// neighbour structure of the pair forces (PairInteraction's kernels,
// PairDamping): each site keeps the sites of higher bodies within a reach
// r_c + skin (half lists, as LAMMPS with newton on), found with a cell list
// (cubic cells of side >= (r_c + skin) / 2 over the sites' bounding box, at
// most ~2 per site, so a dilute system gets larger cells instead of a huge
// empty grid; counting sort, O(S) for S sites). The lists are rebuilt when
// some site has moved more than skin/2 since the last build (then no pair can
// have crossed into r_c unseen; a little sooner, as the places it moved from
// are kept in floats: SitePlaces), so the cost grows like the number of
// sites, not its square.
//
// Pruned lists (GROMACS's dynamic pruning): the lists a user reads hold only
// the pairs within r_c + delta (delta = skin/3), pruned from the built ones
// (the outer lists, kept compressed: detail::encode_partners) again when
// some site has moved more than delta/2 since the last pruning. A pair
// within r_c now is in the lists (the skin's argument) and was within
// r_c + delta at the pruning (each site has moved at most delta/2 since), so
// no pair within r_c is missed; a user tests r < r_c itself. The measured
// fractions of pairs and costs are in docs/benchmarks.md ("Against LAMMPS":
// how lgvi computes the pairs) and in docs/tuning.md.
//
// Determinism: each site's list is sorted by site index. Which pairs beyond
// r_c it holds depends on when the lists were built; the pairs within r_c,
// in list order, depend on the current positions only, not on the lists'
// history or the number of threads. A sum that skips the pairs beyond r_c,
// or adds them as exact zeros, therefore gives the same bits on any thread
// count and after a checkpoint and resume (which rebuilds the lists).
//
// In a periodic box the separations are minimum images (box.hpp), and the
// reach must be below half the shortest periodic length (checked), so that a
// pair has one image within reach. The sites are placed about their bodies'
// centres of mass wrapped into the box, so that a pair's plain separation
// is its minimum image unless it straddles a face: a separation of which
// each component is within Box::plain_bound() (just below half a period) is taken
// as it is, the reduction paid only beyond. Each pruned entry says whether
// its pair was across a period at the pruning (across()), so that a user can
// take the plain separations of a site none of whose pairs were, checking
// them against Box::plain_bound() (a body that has crossed a face since is
// placed a period away from its partners).
#pragma once

#include <lgvi/box.hpp>
#include <lgvi/error.hpp>
#include <lgvi/interaction.hpp>
#include <lgvi/parallel.hpp>
#include <lgvi/system.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <new>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace lgvi {

namespace detail {

/// The outer lists' code: site i's partners j_0 < j_1 < ... (all above i)
/// as the differences j_0 - i, j_1 - j_0, ... (each at least 1), each in
/// LEB128 (7 bits a byte, the lowest first, the high bit set on every byte
/// but a number's last: at most max_coded_bytes). The sites of a gas
/// numbered along its lattice have their neighbours a few indices or a
/// row or a plane away, so an entry takes a byte or two instead of 4
/// (docs/benchmarks.md). Returns the end of what was written.
inline std::uint8_t* encode_partners(std::size_t i, const std::uint32_t* partner, std::size_t count,
                                     std::uint8_t* out) {
  auto previous = static_cast<std::uint32_t>(i);
  for (std::size_t k = 0; k < count; ++k) {
    std::uint32_t d = partner[k] - previous;
    previous = partner[k];
    for (; d >= 0x80; d >>= 7) *out++ = static_cast<std::uint8_t>(d | 0x80);
    *out++ = static_cast<std::uint8_t>(d);
  }
  return out;
}
/// At most this many bytes per entry (a difference below 2^32).
inline constexpr std::size_t max_coded_bytes = 5;
/// Site i's partners from their code [in, end) into partner (room for
/// end - in); returns how many.
inline std::size_t decode_partners(std::size_t i, const std::uint8_t* in, const std::uint8_t* end,
                                   std::uint32_t* partner) {
  auto previous = static_cast<std::uint32_t>(i);
  std::size_t count = 0;
  while (in < end) {
    std::uint32_t d = 0;
    int shift = 0;
    for (std::uint8_t byte = 0x80; byte >= 0x80; shift += 7) {
      byte = *in++;
      d |= static_cast<std::uint32_t>(byte & 0x7f) << shift;
    }
    previous += d;
    partner[count++] = previous;
  }
  return count;
}

/// One buffer for arrays of trivial types that are used one set at a time
/// (the neighbour lists' cell arrays during a build, then the pruned lists):
/// begin_arrays(bytes) starts a set of that many bytes (bytes_for's sum),
/// growing the buffer if needed, which discards its contents; array<T>(count)
/// places the set's next array after the previous one, each on a 64-byte
/// line. The buffer is kept between sets, not freed: its pages are taken
/// from the system once rather than at every build, and the memory one set
/// frees does not stay in the heap apart from the next (glibc's malloc, on
/// two threads, would keep it if it were freed; measured: docs/benchmarks.md).
/// Copies copy the bytes in use.
class ArrayWorkspace {
 public:
  ArrayWorkspace() = default;
  ArrayWorkspace(const ArrayWorkspace& other) { *this = other; }
  ArrayWorkspace& operator=(const ArrayWorkspace& other) {
    if (this == &other) return *this;
    ArrayWorkspace copy;  // (this one unchanged if the allocation fails)
    if (other.base_ != nullptr) {
      copy.grow(other.used_);
      std::copy(other.base_, other.base_ + other.used_, copy.base_);
    }
    copy.used_ = copy.set_ = other.used_;
    return *this = std::move(copy);
  }
  ArrayWorkspace(ArrayWorkspace&& other) noexcept
      : bytes_(std::move(other.bytes_)), base_(other.base_), size_(other.size_), used_(other.used_), set_(other.set_) {
    other.base_ = nullptr;
    other.size_ = other.used_ = other.set_ = 0;
  }
  ArrayWorkspace& operator=(ArrayWorkspace&& other) noexcept {
    bytes_ = std::move(other.bytes_);
    base_ = std::exchange(other.base_, nullptr);
    size_ = std::exchange(other.size_, 0);
    used_ = std::exchange(other.used_, 0);
    set_ = std::exchange(other.set_, 0);
    return *this;
  }
  ~ArrayWorkspace() = default;

  /// The bytes an array of count T's takes.
  template <class T>
  static constexpr std::size_t bytes_for(std::size_t count) {
    static_assert(std::is_trivially_default_constructible_v<T> && std::is_trivially_destructible_v<T> &&
                  alignof(T) <= line);
    return (count * sizeof(T) + line - 1) / line * line;
  }

  void begin_arrays(std::size_t bytes) {
    if (bytes > capacity()) grow(bytes);
    used_ = 0;
    set_ = bytes;
  }

  /// Room for count T's after the set's arrays so far; their values are
  /// unspecified (not initialized).
  template <class T>
  T* array(std::size_t count) {
    const std::size_t at = used_, end = at + bytes_for<T>(count);
    if (end > set_) throw std::logic_error("ArrayWorkspace: an array beyond its set's bytes");
    used_ = end;
    // Begins the array's lifetime in the buffer (no initialization, no
    // overhead for a trivial type).
    return ::new (static_cast<void*>(base_ + at)) T[count];
  }

  /// The set's first array, as placed by array<T>.
  template <class T>
  T* first() const {
    return std::launder(reinterpret_cast<T*>(base_));
  }

 private:
  static constexpr std::size_t line = 64;
  std::size_t capacity() const { return size_ == 0 ? 0 : size_ - line; }
  void grow(std::size_t bytes) {
    // Freed before the larger one is taken (the contents are not kept):
    // never both at once. An eighth more, as the lists grow with the
    // system's density; not initialized, so that what is never written
    // takes no memory (a large block's pages are the system's until
    // touched).
    release();
    size_ = bytes + bytes / 8 + line;
    bytes_ = std::make_unique_for_overwrite<std::byte[]>(size_);
    base_ = bytes_.get() + (line - reinterpret_cast<std::uintptr_t>(bytes_.get()) % line) % line;
  }
  void release() {
    bytes_.reset();
    base_ = nullptr;
    size_ = used_ = set_ = 0;
  }
  std::unique_ptr<std::byte[]> bytes_;
  std::byte* base_ = nullptr;  ///< the buffer's first 64-byte line (it has a line more than its capacity())
  std::size_t size_ = 0, used_ = 0, set_ = 0;
};

}  // namespace detail

/// The Verlet lists of a system's interaction sites (the comment at the top
/// of this file). Built for one system (its sites, kinds and box); update(s)
/// places the sites at a state and brings the lists up to date for it, then
/// site i's partners (sites of higher bodies, by increasing index) are
/// partner(k) for k in [list_begin(i), list_end(i)), and its position is
/// position(i). A workspace over a model (interaction.hpp): what the lists
/// are of (the sites, the reach, the box: Model) is fixed at construction;
/// the lists are what update() writes.
class NeighbourLists {
 public:
  /// A site's index in the lists (4 bytes: the lists are most of a pair
  /// interaction's memory); at most max_sites sites. (Checked at each
  /// build: at most 2^32 - 1 list entries in all, 4-byte offsets, some 10^8
  /// molecules of the benchmarks' gas; and 4 GiB of coded outer lists for
  /// the bodies of one chunk, 1/64 of them.)
  using SiteIndex = std::uint32_t;
  static constexpr std::size_t max_sites = 0x7fffffff;
  /// A pruned list entry: its partner's SiteIndex, and in the bit above
  /// the highest (max_sites + 1) whether the pair was across a period at the
  /// pruning (across()).
  using Entry = std::uint32_t;
  static constexpr Entry across_bit = 0x80000000u;

  /// What update() did to the lists.
  enum class Change { none, pruned, built };

  /// Lists within `cutoff` + `skin` (skin >= 0) of the sites of `sys`. `owner`
  /// begins the messages of bad input ("interaction" for a scenario's
  /// [interaction] table): more than max_sites sites, or in a periodic box a
  /// reach not below half its shortest periodic length (InvalidInput).
  NeighbourLists(const System& sys, double cutoff, double skin, Parallelism par, const std::string& owner)
      : model_{InteractionSites(sys), cutoff, skin, prune_fraction * skin, par, sys.box()} {
    const Model& m = model_;
    if (m.sites.size() > max_sites)
      throw InvalidInput(owner + ": " + std::to_string(m.sites.size()) +
                         " interaction sites; the neighbour lists index at most " + std::to_string(max_sites) +
                         " (2^31 - 1); split the system");
    if (m.box.any_periodic() && !(2.0 * (m.cutoff + m.skin) < m.box.shortest_periodic_length()))
      throw InvalidInput(owner + ".cutoff: the cutoff + skin = " + std::to_string(m.cutoff + m.skin) +
                         " must be less than half the shortest periodic length of the box (" +
                         std::to_string(m.box.shortest_periodic_length()) +
                         "), so that a pair has one image within reach; enlarge the box or shorten the cutoff or skin");
  }

  /// Places the sites at `s` (per body, on the threads) and brings the lists
  /// up to date for it: rebuilt if a site moved more than skin/2 since the
  /// last build, else pruned again if one moved more than delta/2 since the
  /// last pruning (each limit less the rounding of the places kept,
  /// SitePlaces; a move by a whole period along a periodic axis is no move).
  /// StepFailure if a site's position is not finite.
  Change update(const SystemState& s) {
    const std::size_t n = s.size();
    // The sites, and how far each body's moved, per body on the thread that
    // placed it. (The plain distance first; the minimum image only for a site
    // that seems to have moved: a body whose centre crossed a face is placed
    // a period away, which is no move.)
    const bool have_lists = lists_ready_ && places_.size() == sites().size();
    // Squared: skin/2 and delta/2, less the rounding of the stored places.
    auto squared_less_slack = [&](double half) {
      const double l = std::max(0.0, half - places_.slack());
      return l * l;
    };
    const double limit = squared_less_slack(0.5 * skin());
    const double prune_limit = squared_less_slack(0.5 * model_.prune_margin);
    const bool periodic = box().any_periodic();
    auto within_limit = [&](const Vector3<double>& d, double bound) {
      // (False for NaN.)
      return d.squaredNorm() <= bound || (periodic && box().minimum_image(d).squaredNorm() <= bound);
    };
    moved_.resize(n);
    sites().place_wrapped(s, model_.par, box(), position_, [&](std::size_t a) {
      char moved = have_lists ? no_move : beyond_skin;
      for (std::size_t i = sites().begin(a); i < sites().end(a) && moved != beyond_skin; ++i) {
        if (!within_limit(places_.from_built(i, position_[i]), limit)) moved = beyond_skin;
        else if (!within_limit(places_.from_pruned(i, position_[i]), prune_limit)) moved = beyond_margin;
      }
      moved_[a] = moved;
    });
    const char most = *std::max_element(moved_.begin(), moved_.end());
    if (most == beyond_skin) {
      build_lists();
      return Change::built;
    }
    if (most == beyond_margin) {
      prune_lists();
      return Change::pruned;
    }
    return Change::none;
  }

  const InteractionSites& sites() const { return model_.sites; }
  const Box& box() const { return model_.box; }
  double cutoff() const { return model_.cutoff; }
  double skin() const { return model_.skin; }
  /// Site i's inertial position X_i = x_a + R_a rho_i at the last update
  /// (its arm R_a rho_i: sites().arm()); in a periodic box its image about
  /// its body's centre of mass wrapped into the box (place_wrapped), which
  /// depends on the state only.
  const Vector3<double>& position(std::size_t i) const { return position_[i]; }
  /// Site i's list entries are [list_begin(i), list_end(i)); the entries of
  /// consecutive sites are consecutive (list_begin(i + 1) = list_end(i);
  /// list_begin(S) is the number of entries).
  std::size_t list_begin(std::size_t i) const { return list_start_[i]; }
  std::size_t list_end(std::size_t i) const { return list_start_[i + 1]; }
  /// Entry k's partner site.
  SiteIndex partner(std::size_t k) const { return partner_of(entries()[k]); }
  /// Entry k as stored: partner_of() and across() take it apart.
  Entry entry(std::size_t k) const { return entries()[k]; }
  static SiteIndex partner_of(Entry e) { return e & ~across_bit; }
  /// Whether the entry's pair was across a period at the last pruning: its
  /// minimum image X_j - X_i - L n with some n_k != 0 (box.hpp). A separation d
  /// whose every component is within Box::plain_bound() is its own minimum
  /// image, d + 0.0 to the bit; beyond (across a period, or a body that has
  /// crossed a face since the pruning), only Box::reduce gives it.
  static bool across(Entry e) { return (e & across_bit) != 0; }

  /// How many times the lists were built, and pruned (every build prunes
  /// too), for tests and benchmarks.
  std::int64_t builds() const { return builds_; }
  std::int64_t prunes() const { return prunes_; }

 private:
  /// Frees the vectors' storage (clear() would keep it).
  template <class... V>
  static void release(V&... v) {
    ((v = V()), ...);
  }

  /// Where each site was at the last build and at the last pruning (the
  /// references of "moved more than skin/2, delta/2 since"). Kept as floats
  /// relative to the sites' bounding-box centre at the build, half the
  /// memory of doubles; slack() bounds the distance between a stored place
  /// and the true one, and the limits are lowered by it, so no move beyond
  /// skin/2 or delta/2 goes unseen. The lists are then rebuilt a little
  /// sooner, which changes no result (the pairs within r_c, in list order,
  /// do not depend on when the lists were built). Where the slack would be
  /// more than an eighth of delta/2 (sites farther than about 3e5 delta
  /// from their bounding box's centre, or no skin, unless all sites are at
  /// the centre and the floats exact) the places are kept as doubles,
  /// exactly (slack 0).
  class SitePlaces {
   public:
    /// Room for m sites, each to stay within `extent` of `origin` along
    /// every axis (as a minimum image in `box`), compared at limits of at
    /// least `limit`.
    void prepare(std::size_t m, const Vector3<double>& origin, double extent, double limit, const Box& box) {
      origin_ = origin;
      box_ = box;
      // float's rounding of a component v = x - origin, |v| <= extent, is
      // at most 2^-24 extent; doubled for the rounding of x - origin and of
      // the separations in double; sqrt(3) for three components.
      const double slack = 2.0 * std::sqrt(3.0) * std::ldexp(extent, -24);
      narrow_ = slack <= limit / 8.0;
      slack_ = narrow_ ? slack : 0.0;
      if (narrow_) {
        release(built_wide_, pruned_wide_);
        built_.resize(m);
        pruned_.resize(m);
      } else {
        release(built_, pruned_);
        built_wide_.resize(m);
        pruned_wide_.resize(m);
      }
    }
    std::size_t size() const { return narrow_ ? built_.size() : built_wide_.size(); }
    double slack() const { return slack_; }
    void store_built(std::size_t i, const Vector3<double>& x) { store(built_, built_wide_, i, x); }
    void store_pruned(std::size_t i, const Vector3<double>& x) { store(pruned_, pruned_wide_, i, x); }
    /// x - site i's stored place at the last build, pruning.
    Vector3<double> from_built(std::size_t i, const Vector3<double>& x) const { return from(built_, built_wide_, i, x); }
    Vector3<double> from_pruned(std::size_t i, const Vector3<double>& x) const {
      return from(pruned_, pruned_wide_, i, x);
    }

   private:
    void store(std::vector<Vector3<float>>& narrow, std::vector<Vector3<double>>& wide, std::size_t i,
               const Vector3<double>& x) const {
      // (A minimum image, within half a period of the origin: the float's
      // rounding is then bounded by the extent.)
      if (narrow_) narrow[i] = box_.minimum_image(x - origin_).cast<float>();
      else wide[i] = x;
    }
    Vector3<double> from(const std::vector<Vector3<float>>& narrow, const std::vector<Vector3<double>>& wide,
                         std::size_t i, const Vector3<double>& x) const {
      // (A whole number of periods off where the stored place is an image:
      // the caller's minimum image takes them off, as for a wide place.)
      return narrow_ ? Vector3<double>(x - origin_ - narrow[i].cast<double>()) : Vector3<double>(x - wide[i]);
    }
    Vector3<double> origin_ = Vector3<double>::Zero();
    Box box_;  ///< the lists' (separations along its periodic axes are minimum images)
    double slack_ = 0.0;
    bool narrow_ = false;
    std::vector<Vector3<float>> built_, pruned_;
    std::vector<Vector3<double>> built_wide_, pruned_wide_;
  };

  /// The candidates[0, n) within r^2 < reach2 of position x, in their order,
  /// into list (which has room for n); returns how many. Each candidate is
  /// written, and kept by advancing the count (the lists' build and
  /// pruning both filter so). MarkAcross: each as an Entry, across_bit set if
  /// its minimum image is another than its plain separation (else the
  /// partner's SiteIndex alone).
  template <bool Periodic, bool MarkAcross = false>
  std::size_t within(const Vector3<double>* position, const Vector3<double>& x, const SiteIndex* candidates,
                     std::size_t n, double reach2, Entry* list) const {
    const double xi = x(0), yi = x(1), zi = x(2);
    const Box& box = this->box();
    std::size_t count = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const SiteIndex j = candidates[k];
      double dx = position[j](0) - xi, dy = position[j](1) - yi, dz = position[j](2) - zi;
      SiteIndex mark = 0;
      if constexpr (Periodic) {
        [[maybe_unused]] const bool across = box.reduce_beyond_plain(dx, dy, dz);
        if constexpr (MarkAcross) mark = across ? across_bit : 0;
      }
      list[count] = j | mark;
      count += static_cast<std::size_t>(dx * dx + dy * dy + dz * dz < reach2);
    }
    return count;
  }

  /// The cell of a site at x: along an open axis from the sites' bounding
  /// box (clamped to it); along a periodic one from x's fractional
  /// coordinate in the box, wrapped into [0, 1).
  std::array<std::int64_t, 3> cell_of(const Vector3<double>& x) const {
    std::array<std::int64_t, 3> c{};
    for (int k = 0; k < 3; ++k) {
      const std::int64_t dims = dims_[static_cast<std::size_t>(k)];
      std::int64_t v = 0;
      if (box().periodic(k)) {  // (origin_(k) is the box's lower face there)
        v = static_cast<std::int64_t>(box().fraction(x(k), k) * static_cast<double>(dims));
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
    if (!box().periodic(k)) {
      Vector3<double> a = Vector3<double>::Constant(origin_(k)), b = a;
      a(k) = from;
      b(k) = to;
      r.run[0] = {cell_of(a)[static_cast<std::size_t>(k)], cell_of(b)[static_cast<std::size_t>(k)]};
      return r;
    }
    // Unwrapped cell numbers, widened by the rounding of the fractional
    // coordinates (cell_of wraps them before scaling, this does not).
    const double scale = box().inverse_periodic_length()(k) * static_cast<double>(dims);
    const double slack =
        1e-12 * (std::abs(from - origin_(k)) + std::abs(to - origin_(k)) + box().periodic_length()(k));
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
  void build_lists() { box().any_periodic() ? build_lists<true>() : build_lists<false>(); }
  template <bool Periodic>
  void build_lists() {
    ++builds_;
    const std::size_t m = position_.size();
    // Memory: the pruned lists are stale from here on, and the cell arrays
    // are needed only until the outer lists are made, so the two share one
    // buffer (arrays_; they are the largest arrays after the outer
    // lists). (Until the pruning below completes there are no lists: a
    // build cut short by an exception is redone.)
    lists_ready_ = false;
    Vector3<double> lo = position_[0], hi = position_[0];
    bool finite = true;  // (each site's: the bounds pass over a NaN)
    for (const Vector3<double>& x : position_) {
      lo = lo.cwiseMin(x);
      hi = hi.cwiseMax(x);
      finite = finite && x.allFinite();
    }
    if (!finite) throw StepFailure("the state became non-finite", "try a smaller step");
    // The places' origin and extent: until the next build each site stays
    // within skin/2 of its place now, or of an image of it along a periodic
    // axis (there the places are minimum images, within half a period).
    Vector3<double> extent = 0.5 * (hi - lo) + Vector3<double>::Constant(skin());
    for (int k = 0; k < 3; ++k)
      if (box().periodic(k)) extent(k) = 0.5 * box().periodic_length()(k);
    places_.prepare(m, 0.5 * (lo + hi), extent.maxCoeff(), 0.5 * model_.prune_margin, box());
    const double reach = cutoff() + skin();
    origin_ = lo;
    const double budget = std::max(1.0, std::floor(std::cbrt(2.0 * static_cast<double>(m) + 1.0)));
    std::size_t cells = 1;
    for (int k = 0; k < 3; ++k) {
      // A periodic axis: cells over the box, a whole number of them (each
      // at least reach / cells_per_reach wide), whatever the sites' spread.
      const bool periodic = box().periodic(k);
      if (periodic) origin_(k) = box().lower()(k);
      const double extent = periodic ? box().periodic_length()(k) : hi(k) - lo(k);
      const double count = std::clamp(std::floor(extent * cells_per_reach / reach), 1.0, budget);
      dims_[static_cast<std::size_t>(k)] = static_cast<std::int64_t>(count);
      inv_cell_(k) = count / std::max(extent, reach / cells_per_reach);
      cells *= static_cast<std::size_t>(count);
    }
    // The cells, in the workspace: cell c's sites are sorted[cell_start[c]
    // ... cell_start[c + 1]) (site counts: at most max_sites, as the cells'
    // numbers, fewer than 2 max_sites + 2).
    using Arrays = detail::ArrayWorkspace;
    arrays_.begin_arrays(Arrays::bytes_for<SiteIndex>(cells + 1) + Arrays::bytes_for<SiteIndex>(cells) +
                            3 * Arrays::bytes_for<SiteIndex>(m) + 3 * Arrays::bytes_for<double>(m));
    SiteIndex* const cell_start = arrays_.array<SiteIndex>(cells + 1);
    SiteIndex* const cell_fill = arrays_.array<SiteIndex>(cells);
    SiteIndex* const cell_index = arrays_.array<SiteIndex>(m);
    SiteIndex* const sorted = arrays_.array<SiteIndex>(m);
    double* const cell_x = arrays_.array<double>(m);  // the sites' positions in cell order
    double* const cell_y = arrays_.array<double>(m);
    double* const cell_z = arrays_.array<double>(m);
    SiteIndex* const cell_body = arrays_.array<SiteIndex>(m);  // and their bodies
    std::fill(cell_start, cell_start + cells + 1, SiteIndex{0});
    for (std::size_t i = 0; i < m; ++i) {
      const std::array<std::int64_t, 3> c = cell_of(position_[i]);
      cell_index[i] = static_cast<SiteIndex>((c[2] * dims_[1] + c[1]) * dims_[0] + c[0]);
      ++cell_start[cell_index[i] + 1];
    }
    for (std::size_t c = 0; c < cells; ++c) cell_start[c + 1] += cell_start[c];
    std::copy(cell_start, cell_start + cells, cell_fill);
    for (std::size_t i = 0; i < m; ++i) sorted[cell_fill[cell_index[i]]++] = static_cast<SiteIndex>(i);
    // The sites' positions and bodies in cell order: a row of neighbouring
    // cells along x is one contiguous run of these arrays.
    for (std::size_t k = 0; k < m; ++k) {
      const Vector3<double>& x = position_[sorted[k]];
      cell_x[k] = x(0);
      cell_y[k] = x(1);
      cell_z[k] = x(2);
      cell_body[k] = static_cast<SiteIndex>(sites().body_of(sorted[k]));
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
    const std::size_t n = sites().bodies();
    const double reach2 = reach * reach;
    const std::size_t chunks = std::min<std::size_t>(n, list_chunks);
    outer_lists_.resize(chunks);
    outer_end_.resize(m);
    chunk_entries_.assign(chunks + 1, 0);
    parallel_for(chunks, model_.par, [&](std::size_t chunk) {
      std::vector<std::uint8_t>& out = outer_lists_[chunk];
      std::size_t used = 0, entries = 0;  // out's bytes in use (out only grows: no zero fill per site), entries
      // Where the chunk's sites are now (the skin's reference).
      for (std::size_t i = sites().begin(chunk * n / chunks); i < sites().begin((chunk + 1) * n / chunks); ++i)
        places_.store_built(i, position_[i]);
      thread_local std::vector<SiteIndex> near, found;
      for (std::size_t a = chunk * n / chunks; a < (chunk + 1) * n / chunks; ++a) {
        // A body of many sites (a wall, a long chain) goes site by site: its
        // box would hold candidates for all of them, each site scanning all.
        const std::size_t group = sites().end(a) - sites().begin(a) <= group_sites ? group_sites : 1;
        for (std::size_t g0 = sites().begin(a); g0 < sites().end(a); g0 += group) {
          const std::size_t g1 = std::min(g0 + group, sites().end(a));
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
                    const std::size_t run_first = cell_start[row + static_cast<std::size_t>(xs.run[xr][0])],
                                      run_end = cell_start[row + static_cast<std::size_t>(xs.run[xr][1]) + 1];
                    if (near.size() < kept + (run_end - run_first)) near.resize(2 * (kept + (run_end - run_first)));
                    SiteIndex* const list = near.data();
                    // Every candidate written, the count advanced only for those kept:
                    // no branch to mispredict on the distance test (the minimum
                    // image's is taken only across a period).
                    for (std::size_t k = run_first; k < run_end; ++k) {
                      double dx = cell_x[k] - cx, dy = cell_y[k] - cy, dz = cell_z[k] - cz;
                      if constexpr (Periodic) box().reduce_beyond_plain(dx, dy, dz);
                      list[kept] = sorted[k];
                      kept += static_cast<std::size_t>((dx * dx + dy * dy + dz * dz < around2) & (cell_body[k] > a));
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
          if (found.size() < kept) found.resize(kept);
          for (std::size_t i = g0; i < g1; ++i) {
            const std::size_t count =
                within<Periodic>(position_.data(), position_[i], near.data(), kept, reach2, found.data());
            const std::size_t room = used + detail::max_coded_bytes * count;
            if (out.size() < room) {
              // Grown by a quarter (a vector's resize would double it): the
              // chunks' buffers are the outer lists, kept between builds.
              out.reserve(room + room / 4);
              out.resize(out.capacity());
            }
            std::uint8_t* const end = detail::encode_partners(i, found.data(), count, out.data() + used);
            used = static_cast<std::size_t>(end - out.data());
            if (used > std::numeric_limits<std::uint32_t>::max())
              throw StepFailure("the neighbour lists of bodies " + std::to_string(chunk * n / chunks) + " to " +
                                    std::to_string((chunk + 1) * n / chunks - 1) + " take more than 4 GiB",
                                "shorten the cutoff or skin, or split the system");
            outer_end_[i] = static_cast<std::uint32_t>(used);
            entries += count;
          }
        }
      }
      chunk_entries_[chunk + 1] = entries;
    });
    for (std::size_t chunk = 0; chunk < chunks; ++chunk) chunk_entries_[chunk + 1] += chunk_entries_[chunk];
    if (chunk_entries_[chunks] > std::numeric_limits<ListOffset>::max())
      throw StepFailure("the neighbour lists hold " + std::to_string(chunk_entries_[chunks]) +
                            " pairs, more than their 4-byte offsets can index (2^32 - 1)",
                        "shorten the cutoff or skin, or split the system");
    // The cells are done with: the pruned lists in their place, with room
    // for as many entries as the outer lists (prune_lists).
    arrays_.begin_arrays(Arrays::bytes_for<Entry>(chunk_entries_[chunks]));
    arrays_.array<Entry>(chunk_entries_[chunks]);
    prune_lists<Periodic>();
  }

  /// The outer lists' entries within r_c + delta (the pruning margin) now, per site in
  /// the same order: the lists the users read (entries(), list_start_).
  void prune_lists() { box().any_periodic() ? prune_lists<true>() : prune_lists<false>(); }
  template <bool Periodic>
  void prune_lists() {
    ++prunes_;
    lists_ready_ = false;
    const std::size_t n = sites().bodies(), m = position_.size();
    // Generous by a relative 1e-9, as the build's filter: no pair within the
    // margin is lost to the rounding of r^2.
    const double reach = (cutoff() + model_.prune_margin) * (1.0 + 1e-9), reach2 = reach * reach;
    const std::size_t chunks = std::min<std::size_t>(n, list_chunks);
    chunk_used_.resize(chunks);
    list_start_.assign(m + 1, 0);
    // Each chunk's pruned lists first where its outer lists' entries would
    // be in one array (entries()[chunk_entries_[chunk] ...), then moved
    // down in chunk order to follow the previous chunk's.
    parallel_for(chunks, model_.par, [&](std::size_t chunk) {
      const std::size_t i0 = sites().begin(chunk * n / chunks), i1 = sites().begin((chunk + 1) * n / chunks);
      for (std::size_t i = i0; i < i1; ++i) places_.store_pruned(i, position_[i]);  // the margin's reference
      const Vector3<double>* const position = position_.data();
      // Site i's outer list: outer[outer_end_[i - 1] ... outer_end_[i]).
      const std::uint8_t* const outer = outer_lists_[chunk].data();
      Entry* const list = entries() + chunk_entries_[chunk];
      thread_local std::vector<SiteIndex> partners_of_thread;
      std::vector<SiteIndex>& partners = partners_of_thread;
      std::size_t count = 0, from = 0;
      for (std::size_t i = i0; i < i1; ++i) {
        const std::size_t to = outer_end_[i];
        if (partners.size() < to - from) partners.resize(to - from);  // (at least a byte an entry)
        const std::size_t built = detail::decode_partners(i, outer + from, outer + to, partners.data());
        from = to;
        const std::size_t kept = within<Periodic, true>(position, position[i], partners.data(), built, reach2,
                                                         list + count);
        count += kept;
        list_start_[i + 1] = static_cast<ListOffset>(kept);  // summed below
      }
      chunk_used_[chunk] = count;
    });
    for (std::size_t i = 0; i < m; ++i) list_start_[i + 1] += list_start_[i];
    for (std::size_t chunk = 0; chunk < chunks; ++chunk) {  // (to lower or equal offsets: in order, nothing unread is overwritten)
      const std::size_t i0 = sites().begin(chunk * n / chunks);
      if (list_start_[i0] == chunk_entries_[chunk]) continue;  // (in place already)
      Entry* const from = entries() + chunk_entries_[chunk];
      std::copy(from, from + chunk_used_[chunk], entries() + list_start_[i0]);
    }
    lists_ready_ = true;
  }

  /// What the lists are of, written by the constructor only: the sites, the
  /// reach (r_c + skin), the pruning margin delta, the threads and the box.
  /// Held by value, not behind a pointer (the list build and pruning read it
  /// in their loops), and not const (so that the lists move). Everything
  /// below is what update() writes.
  struct Model {
    InteractionSites sites;
    double cutoff, skin, prune_margin;
    Parallelism par;
    Box box;  ///< the system's: separations are minimum images along its periodic axes
  };
  Model model_;
  std::vector<Vector3<double>> position_;
  std::vector<char> moved_;  ///< per body: how far its sites moved (no_move ...)
  Vector3<double> origin_ = Vector3<double>::Zero(), inv_cell_ = Vector3<double>::Ones();
  std::array<std::int64_t, 3> dims_{1, 1, 1};
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
  /// Lists are built per body for bodies of up to this many sites (molecules,
  /// rubble), site by site for larger ones (build_lists).
  static constexpr std::size_t group_sites = 16;
  /// An offset into the lists (4 bytes: checked at each build).
  using ListOffset = std::uint32_t;
  std::vector<ListOffset> list_start_;
  /// A build's cell arrays, then the pruned lists: site i's entries
  /// (partner and across_bit) entries()[list_start_[i] ... list_start_[i +
  /// 1]) (room for as many entries as the outer lists have, as it holds
  /// each chunk's while they are pruned).
  detail::ArrayWorkspace arrays_;
  Entry* entries() const { return arrays_.first<Entry>(); }
  std::vector<std::size_t> chunk_used_;  ///< per chunk: its list's entries in use
  /// Per site: where it was at the last build and at the last pruning.
  SitePlaces places_;
  /// The outer lists: per site i, the sites of higher bodies within r_c +
  /// skin at the last build, by index, coded (detail::encode_partners) in its chunk
  /// c's buffer: outer_lists_[c][outer_end_[i - 1] ... outer_end_[i]) (from
  /// 0 for the chunk's first site; not joined into one array: only the
  /// pruning reads them, chunk by chunk); chunk_entries_[c]: the chunk's
  /// first entry's place in the lists, as many entries before it (the pruned
  /// lists' room). entries() and list_start_ are their pruned form.
  std::vector<std::uint32_t> outer_end_;
  std::vector<std::vector<std::uint8_t>> outer_lists_;
  std::vector<std::size_t> chunk_entries_;
  std::int64_t builds_ = 0, prunes_ = 0;
  bool lists_ready_ = false;  ///< the lists are whole (a build and its pruning completed)
  /// moved_: how far a body's sites moved.
  static constexpr char no_move = 0, beyond_margin = 1, beyond_skin = 2;
};

}  // namespace lgvi
