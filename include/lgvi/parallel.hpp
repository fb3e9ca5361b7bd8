// Per-body loops on several threads (OpenMP), with results that do not
// depend on the number of threads.
//
// Determinism: every iteration writes only its own body's entries, in an
// order fixed by the iteration alone, and every sum over bodies is taken
// afterwards on one thread in body order. So the floating-point results are
// bit-identical for 1, 2 or any number of threads (tests/test_nbody.cpp,
// Threads.ResultsAreBitIdenticalForOneAndTwoThreads).
//
// Exceptions: an exception may not leave an OpenMP region. Each iteration's
// exception is caught; after the loop the one of the lowest index is
// rethrown, the same one a serial loop would have thrown first.
//
// Without OpenMP (a compiler without -fopenmp) the pragmas are ignored and
// the loops run serially, with the same results.
#pragma once

#include <algorithm>
#include <cassert>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <limits>
#include <thread>
#include <utility>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace lgvi {

/// How many threads per-body loops use. Loops over fewer than
/// `min_bodies_per_thread` bodies per thread run serially: below that the
/// cost of waking threads exceeds the work (docs/tuning.md).
struct Parallelism {
  int threads = 1;
  std::size_t min_bodies_per_thread = 16;

  /// All cores of the machine (at least 1).
  static Parallelism all_cores() {
    const unsigned n = std::thread::hardware_concurrency();
    return {n == 0 ? 1 : static_cast<int>(n)};
  }
  /// The number of threads a loop over n bodies uses.
  int threads_for(std::size_t n) const {
    if (threads <= 1 || n < 2 * min_bodies_per_thread) return 1;
    const std::size_t most = n / min_bodies_per_thread;
    return static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(threads), most));
  }
};

/// Calls f(i) for i = 0..n-1, on up to `par.threads` threads (static
/// schedule). f must write only what belongs to i.
template <class F>
void parallel_for(std::size_t n, const Parallelism& par, F&& f) {
  const int threads = par.threads_for(n);
  if (threads <= 1) {
    for (std::size_t i = 0; i < n; ++i) f(i);
    return;
  }
  std::exception_ptr first;
  std::int64_t first_index = std::numeric_limits<std::int64_t>::max();
  const auto count = static_cast<std::int64_t>(n);
#pragma omp parallel for schedule(static) num_threads(threads)
  for (std::int64_t i = 0; i < count; ++i) {
    try {
      f(static_cast<std::size_t>(i));
    } catch (...) {
#pragma omp critical(lgvi_parallel_for_exception)
      if (i < first_index) {
        first_index = i;
        first = std::current_exception();
      }
    }
  }
  if (first) std::rethrow_exception(first);
}

/// Splits 0..n-1 into `threads` consecutive ranges of about equal cost:
/// `prefix(i)` is the running cost (prefix(0) = 0, prefix(i + 1) - prefix(i)
/// the cost of item i, for i up to n). Range t is [bounds[t], bounds[t + 1]),
/// its first item the first whose running cost reaches t / threads of the
/// total. Depends on the costs only.
template <class Prefix>
std::vector<std::size_t> balanced_ranges(std::size_t n, int threads, const Prefix& prefix) {
  std::vector<std::size_t> bounds(static_cast<std::size_t>(threads) + 1, n);
  bounds[0] = 0;
  const double total = static_cast<double>(prefix(n));
  std::size_t i = 0;
  for (int t = 1; t < threads; ++t) {
    const double target = total * t / threads;
    while (i < n && static_cast<double>(prefix(i)) < target) ++i;
    bounds[static_cast<std::size_t>(t)] = i;
  }
  return bounds;
}

namespace detail {
/// This thread's place in the current OpenMP team and the team's size (0 and
/// 1 outside a parallel region or without OpenMP).
inline std::pair<int, int> team_place() {
#ifdef _OPENMP
  return {omp_get_thread_num(), omp_get_num_threads()};
#else
  return {0, 1};
#endif
}

/// Runs body(i) for i in ranges t, t + team size, ... of `bounds` for this
/// thread of the team (range t on thread t when the team has as many threads
/// as ranges; every range still runs when it has fewer: OpenMP may give
/// fewer threads than asked, e.g. under OMP_THREAD_LIMIT or nesting, and
/// without OpenMP one thread runs them all in order). The first exception
/// is recorded (lowest index of all threads) and ends this thread's pass.
template <class Body>
void run_ranges(const std::vector<std::size_t>& bounds, Body& body, std::exception_ptr& failure,
                std::size_t& failure_index) {
  const auto [place, team] = team_place();
  const int ranges = static_cast<int>(bounds.size()) - 1;
  for (int t = place; t < ranges; t += team) {
    for (std::size_t i = bounds[static_cast<std::size_t>(t)]; i < bounds[static_cast<std::size_t>(t) + 1]; ++i) {
      try {
        body(i);
      } catch (...) {
#pragma omp critical(lgvi_parallel_for_exception)
        if (i < failure_index) {
          failure_index = i;
          failure = std::current_exception();
        }
        return;
      }
    }
  }
}
}  // namespace detail

/// Two passes over 0..n-1 in one parallel region: f(i) for i in thread t's
/// range [first[t], first[t + 1]) (each thread its own consecutive range, so
/// that loops split alike touch the same data on the same thread, its cache),
/// then, once every thread has finished its
/// first pass, g(i) for i in [second[t], second[t + 1]) (both bounds from
/// balanced_ranges, for the same number of threads). For a second pass that
/// reads what the first wrote for other items, without the cost of a second
/// region. f and g must write only what belongs to i. Exceptions as in
/// parallel_for: the one of the lowest index of the first pass, else of the
/// second; after an exception in the first pass no thread starts the second.
template <class F, class G>
void parallel_ranges(const std::vector<std::size_t>& first, F&& f, const std::vector<std::size_t>& second, G&& g) {
  assert(first.size() == second.size());
  const int threads = static_cast<int>(first.size()) - 1;
  if (threads <= 1) {
    for (std::size_t i = first.front(); i < first.back(); ++i) f(i);
    for (std::size_t i = second.front(); i < second.back(); ++i) g(i);
    return;
  }
  std::exception_ptr failure[2];
  std::size_t failure_index[2] = {std::numeric_limits<std::size_t>::max(), std::numeric_limits<std::size_t>::max()};
#pragma omp parallel num_threads(threads)
  {
    detail::run_ranges(first, f, failure[0], failure_index[0]);
#pragma omp barrier
    if (!failure[0]) detail::run_ranges(second, g, failure[1], failure_index[1]);
  }
  for (const std::exception_ptr& e : failure)
    if (e) std::rethrow_exception(e);
}

}  // namespace lgvi
