#!/usr/bin/env bash
# The whole test suite, in this order:
#   1. set up and build (scripts/setup.sh);
#   2. clang-tidy over the project's sources, clean (scripts/tidy.sh);
#   3. the libFuzzer target, bounded to LGVI_FUZZ_SECONDS (default 60) (scripts/fuzz.sh);
#   4. the C++ and command-line tests again under AddressSanitizer +
#      UndefinedBehaviorSanitizer (build-asan/, clang), with zero reports allowed;
#   5. every test through ctest (GoogleTest, command-line, pytest with
#      /usr/bin/python3, downstream find_package, the view and the documentation site
#      (scripts/docs.sh, -W) in headless chromium).
# LGVI_QUICK=1 skips 2-4.
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc 2>/dev/null || echo 2)
# Each stage's wall time, printed as it ends (docs/benchmarks.md, "The test suite's time").
stage_start=$SECONDS
stage_done() {
  echo "lgvi: $1: $((SECONDS - stage_start)) s"
  stage_start=$SECONDS
}
scripts/setup.sh
stage_done "setup and build"
if [[ "${LGVI_QUICK:-0}" != 1 ]]; then
  scripts/tidy.sh
  stage_done "clang-tidy"
  scripts/fuzz.sh "${LGVI_FUZZ_SECONDS:-60}"
  stage_done "fuzz build and run"
  echo "lgvi: building and running the tests under ASan + UBSan (build-asan/, clang)"
  # clang, as the fuzz stage: it compiles this code under the sanitizers in about 0.6 of g++'s time
  # (docs/benchmarks.md, "The test suite's time"). A build-asan/ configured with another compiler is
  # started afresh.
  if [[ -f build-asan/CMakeCache.txt ]] && ! grep -q '^CMAKE_CXX_COMPILER:[A-Z]*=.*clang++' build-asan/CMakeCache.txt; then
    rm -rf build-asan
  fi
  # A unity build (each target's files compiled in batches of 6, the tests in 7): about half the
  # CPU time of compiling them one by one (docs/benchmarks.md, "The test suite's time"). The
  # Release build in build/ keeps one object per source of the library and the program (for
  # clang-tidy's compilation database, and the shipped binary as it was).
  cmake -S . -B build-asan -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=None \
    "-DCMAKE_CXX_FLAGS=-O1 -g1" -DCMAKE_UNITY_BUILD=ON -DCMAKE_UNITY_BUILD_BATCH_SIZE=6 -DLGVI_SANITIZE=ON -DLGVI_BUILD_BENCHMARKS=OFF -DLGVI_MPI=OFF -DLGVI_BUILD_PYTHON=OFF >/dev/null
  cmake --build build-asan -j"$jobs" >build-asan.log 2>&1 || { tail -40 build-asan.log; exit 1; }
  stage_done "sanitized build"
  # Not under the sanitizers: the Python extension and the downstream build (outside what they
  # instrument), and the view's browser tests (their time is chromium's: lgvi view's C++ side only
  # assembles the arguments of `python3 -m lgvi.viewer` and runs it through run_python, which the
  # paper run's figures exercise here). The command-line paths that the pytest files drive run
  # against the sanitized binaries as the ctest test sanitized.cli_pytest (tests/CMakeLists.txt),
  # beside the C++ tests.
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 \
    LSAN_OPTIONS="suppressions=$(pwd)/scripts/lsan-suppressions.txt:print_suppressions=0"
  # Nor TimeTransformed.SecondOrderThroughTheClosestPass...: its time under the sanitizers is nearly
  # all its reference (about 10^6 RK4 steps of the continuous equations,
  # ContinuousEquations::rk4_time_transformed), a code path the stage's other TimeTransformed and
  # ExactFlow tests run (its share of the stage: docs/benchmarks.md, "The test suite's time"); it
  # runs with the rest in the Release ctest below.
  (cd build-asan && ctest -j"$jobs" -E "^(python|downstream|view)\.|^TimeTransformed\.SecondOrderThroughTheClosestPass" \
    --output-on-failure)
  unset ASAN_OPTIONS UBSAN_OPTIONS LSAN_OPTIONS
  stage_done "sanitized tests"
fi
cd build
ctest --output-on-failure -j"$jobs"
stage_done "tests"
