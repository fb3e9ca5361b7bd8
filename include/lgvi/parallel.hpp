// Per-body loops on several threads (OpenMP), with results that do not
// depend on the number of threads.
//
// Determinism: every iteration writes only its own body's entries, in an
// order fixed by the iteration alone, and every sum over bodies is taken
// afterwards on one thread in body order. So the floating-point results are
// bit-identical for 1, 2 or any number of threads (tests/test_system.cpp).
//
// Exceptions: an exception may not leave an OpenMP region. Each iteration's
// exception is caught; after the loop the one of the lowest index is
// rethrown, the same one a serial loop would have thrown first.
//
// Without OpenMP (a compiler without -fopenmp) the pragmas are ignored and
// the loops run serially, with the same results.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <limits>
#include <thread>

namespace lgvi {

/// How many threads per-body loops use. Loops over fewer than
/// `min_bodies_per_thread` bodies per thread run serially: below that the
/// cost of waking threads (a few microseconds) exceeds the work.
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

}  // namespace lgvi
