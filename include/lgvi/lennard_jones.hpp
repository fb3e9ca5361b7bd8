// Lennard-Jones interaction between the balls (sites) of different bodies:
// rigid molecules and granular models.
//
//   V = sum over pairs of sites i, j of different bodies with r_ij < r_c of
//       4 eps ((sigma/r)^12 - (sigma/r)^6) - V_c,   V_c = 4 eps ((sigma/r_c)^12 - (sigma/r_c)^6),
//
// the energy shifted to zero at the cutoff (forces unchanged; LAMMPS's
// pair_modify shift yes). Sites of the same body do not interact (their
// distances are fixed). With d = X_j - X_i, the force on site i is
//   f_i = -24 eps (2 (sigma/r)^12 - (sigma/r)^6) d / r^2.
//
// Neighbours by Verlet lists, as in LAMMPS and HOOMD: each site keeps the
// sites of other bodies within r_c + skin, found with a cell list (cubic cells
// of side >= r_c + skin over the sites' bounding box, at most ~2 per site, so
// a dilute system gets larger cells instead of a huge empty grid; counting
// sort, O(S)). The lists are rebuilt when some site has moved more than
// skin/2 since the last build (then no pair can have crossed into r_c
// unseen), so the cost grows like the number of sites, not its square.
//
// Each pair is computed once (a half list, as LAMMPS's newton on): the force
// of j on i, f_ij, is kept per pair, and j takes -f_ij, exactly. Then every
// body sums its sites' pair forces.
//
// Determinism: each site's list is sorted by site index, so the sum over a
// site's neighbours runs in an order that depends on the current positions
// only, not on when the lists were built; each body's force and torque are
// summed by one thread. Results are bit-identical for any number of threads
// and after a checkpoint and resume (which rebuilds the lists).
#pragma once

#include <lgvi/interaction.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

namespace lgvi {

class LennardJones {
 public:
  /// `skin`: the Verlet lists hold pairs within cutoff + skin (LAMMPS's
  /// default 0.3 sigma).
  LennardJones(const System& sys, double epsilon, double sigma, double cutoff, Parallelism par = {},
               double skin = -1.0)
      : sys_(sys), sites_(sys), eps_(epsilon), sigma2_(sigma * sigma), cutoff_(cutoff),
        skin_(skin < 0.0 ? 0.3 * sigma : skin), par_(par) {
    if (!(std::isfinite(epsilon) && epsilon > 0.0))
      throw InvalidInput("interaction.epsilon: must be a finite number > 0");
    if (!(std::isfinite(sigma) && sigma > 0.0)) throw InvalidInput("interaction.sigma: must be a finite number > 0");
    if (!(std::isfinite(cutoff) && cutoff > 0.0))
      throw InvalidInput("interaction.cutoff: must be a finite number > 0 (typically 2.5 sigma)");
    const double sr6 = std::pow(sigma2_ / (cutoff * cutoff), 3);
    shift_ = 4.0 * eps_ * (sr6 * sr6 - sr6);
  }

  void add(const SystemState& s, SystemEvaluation& e) const {
    const std::size_t n = s.size();
    sites_.place(s, par_, position_, arm_);
    if (needs_rebuild()) build_lists();
    // Pass 1, once per pair of sites (i < j) within r_c + skin: the force on
    // i, f_ij = coef d with d = X_j - X_i; the force on j is -f_ij exactly.
    const double rc2 = cutoff_ * cutoff_;
    pair_force_.resize(pairs_.size());
    pair_energy_.resize(pairs_.size());
    parallel_ranges(pair_ranges_, [&](std::size_t k) {
      const auto [i, j] = pairs_[k];
      const Vector3<double> d = position_[j] - position_[i];
      const double r2 = d.squaredNorm();
      if (r2 >= rc2) {
        pair_force_[k].setZero();
        pair_energy_[k] = 0.0;
        return;
      }
      const double sr2 = sigma2_ / r2;
      const double sr6 = sr2 * sr2 * sr2;
      const double sr12 = sr6 * sr6;
      const double coef = -24.0 * eps_ * (2.0 * sr12 - sr6) / r2;
      if (!std::isfinite(coef)) detail::close_approach(sys_, sites_, i, j, std::sqrt(r2));
      pair_force_[k] = coef * d;
      pair_energy_[k] = 4.0 * eps_ * (sr12 - sr6) - shift_;
    });
    // Pass 2, per body on one thread: each site's neighbours in the list's
    // order (by site index), so the sums do not depend on the threads.
    energy_.assign(n, 0.0);
    parallel_ranges(body_ranges_, [&](std::size_t a) {
      Vector3<double> force = Vector3<double>::Zero(), torque = Vector3<double>::Zero();
      double energy = 0.0;
      for (std::size_t i = sites_.begin(a); i < sites_.end(a); ++i) {
        Vector3<double> fi = Vector3<double>::Zero();
        for (std::size_t k = list_start_[i]; k < list_start_[i + 1]; ++k) {
          const std::size_t pair = pair_of_[k];
          if (pairs_[pair].first == i) {
            fi += pair_force_[pair];
          } else {
            fi -= pair_force_[pair];
          }
          if (sites_.body_of(neighbours_[k]) > a) energy += pair_energy_[pair];
        }
        force += fi;
        torque += arm_[i].cross(fi);
      }
      e.force[a] += force;
      e.torque[a] += s.q[a].inverse().act(torque);
      energy_[a] = energy;
    });
    for (std::size_t a = 0; a < n; ++a) e.energy += energy_[a];
  }

  /// How many times the neighbour lists were built (for tests and benchmarks).
  std::int64_t list_builds() const { return builds_; }

  double epsilon() const { return eps_; }
  double sigma() const { return std::sqrt(sigma2_); }
  double cutoff() const { return cutoff_; }

 private:
  /// Whether some site moved more than skin/2 since the lists were built.
  bool needs_rebuild() const {
    if (built_at_.size() != position_.size()) return true;
    const double limit = 0.25 * skin_ * skin_;
    for (std::size_t i = 0; i < position_.size(); ++i)
      if (!((position_[i] - built_at_[i]).squaredNorm() <= limit)) return true;  // also true for NaN
    return false;
  }

  std::array<std::int64_t, 3> cell_of(const Vector3<double>& x) const {
    std::array<std::int64_t, 3> c{};
    for (int k = 0; k < 3; ++k) {
      const auto v = static_cast<std::int64_t>((x(k) - origin_(k)) * inv_cell_(k));
      c[static_cast<std::size_t>(k)] = std::clamp<std::int64_t>(v, 0, dims_[static_cast<std::size_t>(k)] - 1);
    }
    return c;
  }

  /// Sorts the sites into cells of side >= r_c + skin, then lists for every
  /// site the sites of other bodies within r_c + skin, by increasing index.
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
      const double extent = hi(k) - lo(k);
      const double count = std::clamp(std::floor(extent / reach), 1.0, budget);
      dims_[static_cast<std::size_t>(k)] = static_cast<std::int64_t>(count);
      inv_cell_(k) = count / std::max(extent, reach);
      cells *= static_cast<std::size_t>(count);
    }
    cell_index_.resize(m);
    cell_start_.assign(cells + 1, 0);
    for (std::size_t i = 0; i < m; ++i) {
      const std::array<std::int64_t, 3> c = cell_of(position_[i]);
      cell_index_[i] = static_cast<std::size_t>((c[2] * dims_[1] + c[1]) * dims_[0] + c[0]);
      ++cell_start_[cell_index_[i] + 1];
    }
    for (std::size_t c = 0; c < cells; ++c) cell_start_[c + 1] += cell_start_[c];
    fill_.assign(cell_start_.begin(), cell_start_.end() - 1);
    sorted_.resize(m);
    for (std::size_t i = 0; i < m; ++i) sorted_[fill_[cell_index_[i]]++] = i;
    // The lists, one site after the other. Each site's list is its own: the
    // sites of other bodies within r_c + skin in the 27 cells around it, then
    // sorted by index (the cells are visited in space order). So the lists do
    // not depend on who builds them: the sites are cut into fixed chunks, each
    // chunk's lists built on some thread into the chunk's buffer, and the
    // buffers joined in site order.
    const double reach2 = reach * reach;
    const std::size_t chunks = std::min<std::size_t>(m, list_chunks);
    chunk_lists_.resize(chunks);
    list_start_.assign(m + 1, 0);
    parallel_for(chunks, par_, [&](std::size_t chunk) {
      std::vector<std::size_t>& out = chunk_lists_[chunk];
      out.clear();
      for (std::size_t i = chunk * m / chunks; i < (chunk + 1) * m / chunks; ++i) {
        const std::size_t a = sites_.body_of(i);
        const std::array<std::int64_t, 3> c = cell_of(position_[i]);
        const std::size_t first = out.size();
        for (std::int64_t dz = -1; dz <= 1; ++dz) {
          const std::int64_t z = c[2] + dz;
          if (z < 0 || z >= dims_[2]) continue;
          for (std::int64_t dy = -1; dy <= 1; ++dy) {
            const std::int64_t y = c[1] + dy;
            if (y < 0 || y >= dims_[1]) continue;
            for (std::int64_t dx = -1; dx <= 1; ++dx) {
              const std::int64_t x = c[0] + dx;
              if (x < 0 || x >= dims_[0]) continue;
              const auto cell = static_cast<std::size_t>((z * dims_[1] + y) * dims_[0] + x);
              for (std::size_t k = cell_start_[cell]; k < cell_start_[cell + 1]; ++k) {
                const std::size_t j = sorted_[k];
                if (sites_.body_of(j) != a && (position_[j] - position_[i]).squaredNorm() < reach2) out.push_back(j);
              }
            }
          }
        }
        std::sort(out.begin() + static_cast<std::ptrdiff_t>(first), out.end());
        list_start_[i + 1] = out.size() - first;  // the count; summed below
      }
    });
    for (std::size_t i = 0; i < m; ++i) list_start_[i + 1] += list_start_[i];
    neighbours_.resize(list_start_[m]);
    parallel_for(chunks, par_, [&](std::size_t chunk) {
      std::copy(chunk_lists_[chunk].begin(), chunk_lists_[chunk].end(),
                neighbours_.begin() + static_cast<std::ptrdiff_t>(list_start_[chunk * m / chunks]));
    });
    // The unordered pairs (i < j), numbered in the order of i and then of j
    // (the entries j > i are the end of i's sorted list); an entry (i, j)
    // with j < i finds its pair in j's list.
    pair_start_.assign(m + 1, 0);
    parallel_for(m, par_, [&](std::size_t i) {
      const auto end = neighbours_.begin() + static_cast<std::ptrdiff_t>(list_start_[i + 1]);
      pair_start_[i + 1] = static_cast<std::size_t>(
          end - std::upper_bound(neighbours_.begin() + static_cast<std::ptrdiff_t>(list_start_[i]), end, i));
    });
    for (std::size_t i = 0; i < m; ++i) pair_start_[i + 1] += pair_start_[i];
    pairs_.resize(pair_start_[m]);
    pair_of_.resize(neighbours_.size());
    parallel_for(m, par_, [&](std::size_t i) {
      const std::size_t above = list_start_[i + 1] - (pair_start_[i + 1] - pair_start_[i]);
      for (std::size_t k = above; k < list_start_[i + 1]; ++k) {
        pair_of_[k] = pair_start_[i] + (k - above);
        pairs_[pair_of_[k]] = {i, neighbours_[k]};
      }
    });
    parallel_for(m, par_, [&](std::size_t i) {
      for (std::size_t k = list_start_[i]; k < list_start_[i + 1] && neighbours_[k] < i; ++k) {
        const std::size_t j = neighbours_[k];
        const auto begin = neighbours_.begin() + static_cast<std::ptrdiff_t>(list_start_[j]);
        const auto end = neighbours_.begin() + static_cast<std::ptrdiff_t>(list_start_[j + 1]);
        pair_of_[k] = pair_of_[static_cast<std::size_t>(std::lower_bound(begin, end, i) - neighbours_.begin())];
      }
    });
    // How passes 1 and 2 split their work between threads: the bodies into
    // consecutive ranges of about equal list entries (pass 2's cost; a gas
    // that clusters makes halves by count uneven), and the pairs at the same
    // bodies' first sites, so that each thread computes the pair forces its
    // own bodies sum next (they stay in its cache). Results do not depend on it.
    const std::size_t n = sys_.size();
    const int threads = par_.threads_for(n);
    body_ranges_ = balanced_ranges(n, threads, [&](std::size_t a) { return list_start_[a < n ? sites_.begin(a) : m]; });
    pair_ranges_.resize(body_ranges_.size());
    for (std::size_t t = 0; t < body_ranges_.size(); ++t)
      pair_ranges_[t] = pair_start_[body_ranges_[t] < n ? sites_.begin(body_ranges_[t]) : m];
    built_at_ = position_;
  }

  System sys_;
  InteractionSites sites_;
  double eps_, sigma2_, cutoff_, skin_, shift_ = 0.0;
  Parallelism par_;
  mutable std::vector<Vector3<double>> position_, arm_;
  mutable std::vector<double> energy_;
  mutable Vector3<double> origin_ = Vector3<double>::Zero(), inv_cell_ = Vector3<double>::Ones();
  mutable std::array<std::int64_t, 3> dims_{1, 1, 1};
  /// The lists are built in this many chunks of sites (fixed, so that the
  /// work split does not depend on the threads; enough for load balance).
  static constexpr std::size_t list_chunks = 64;
  mutable std::vector<std::size_t> cell_index_, cell_start_, fill_, sorted_, list_start_, neighbours_, pair_of_,
      pair_start_;
  mutable std::vector<std::vector<std::size_t>> chunk_lists_;
  mutable std::vector<std::size_t> body_ranges_, pair_ranges_;  ///< per thread t: [r[t], r[t + 1]) (build_lists)
  mutable std::vector<std::pair<std::size_t, std::size_t>> pairs_;
  mutable std::vector<Vector3<double>> pair_force_;
  mutable std::vector<double> pair_energy_;
  mutable std::vector<Vector3<double>> built_at_;
  mutable std::int64_t builds_ = 0;
};

}  // namespace lgvi
