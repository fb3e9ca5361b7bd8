#!/usr/bin/env bash
# The whole test suite: set up and build (scripts/setup.sh), then every test
# through ctest (GoogleTest, command-line checks, pytest, the downstream
# find_package check).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
cd build
ctest --output-on-failure -j"$(nproc 2>/dev/null || echo 2)"
