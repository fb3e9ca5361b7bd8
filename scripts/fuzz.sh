#!/usr/bin/env bash
# Builds the libFuzzer target (clang, ASan + UBSan) and fuzzes the scenario
# reader and run for a bounded time, seeded with the project's scenario files.
# Usage: scripts/fuzz.sh [SECONDS]   (default 60). Fails on any finding; the
# input that caused it is left in build-fuzz/findings/ and should be added to
# fuzz/regressions/ with the fix.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
  -DLGVI_FUZZ=ON -DLGVI_BUILD_CLI=OFF -DLGVI_BUILD_TESTS=OFF -DLGVI_BUILD_BENCHMARKS=OFF -DLGVI_BUILD_PYTHON=OFF >/dev/null
cmake --build build-fuzz -j"$(nproc 2>/dev/null || echo 2)" --target fuzz_scenario
mkdir -p build-fuzz/corpus build-fuzz/findings
# Every past finding must now pass.
if compgen -G "fuzz/regressions/*" >/dev/null; then
  build-fuzz/fuzz/fuzz_scenario fuzz/regressions/* >/dev/null 2>&1 || { build-fuzz/fuzz/fuzz_scenario fuzz/regressions/*; exit 1; }
fi
build-fuzz/fuzz/fuzz_scenario -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=4096 \
  -artifact_prefix=build-fuzz/findings/ -print_final_stats=1 \
  build-fuzz/corpus scenarios tests/cli/bad tests/cli/good fuzz/regressions 2>build-fuzz/fuzz.log || {
  tail -40 build-fuzz/fuzz.log; echo "lgvi fuzz: FINDING, see build-fuzz/findings/"; exit 1; }
grep -E "stat::number_of_executed_units|stat::peak_rss_mb" build-fuzz/fuzz.log | sed 's/^/lgvi fuzz: /'
echo "lgvi fuzz: no findings in ${seconds} s"
