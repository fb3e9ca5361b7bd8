#!/usr/bin/env bash
# clang-tidy over the project's own sources with the checked-in .clang-tidy;
# any finding fails. Needs a configured build/ (scripts/setup.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
files=$(git ls-files 'src/*.cpp' 'src/**/*.cpp' 'fuzz/*.cpp' 'examples/*.cpp' 'lammps/*.cpp' | grep -v '^src/python/' || true)
run-clang-tidy -quiet -p build -j "$(nproc 2>/dev/null || echo 2)" $files >build/tidy.log 2>&1 || {
  grep -E "error:|warning:" build/tidy.log | sort -u | head -50; echo "lgvi tidy: findings above (full log: build/tidy.log)"; exit 1; }
echo "lgvi tidy: clean ($(echo $files | wc -w) files)"
