#!/usr/bin/env bash
# The methods side by side on each standard problem: `lgvi compare` with every
# method (and the exact flow on free bodies), 1e6-step equal-cost long runs.
# Results: results/compare/PROBLEM/ (comparison.md, CSVs, figures).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh >/dev/null
all=lgvi,lgvi-lagrangian,so3-lgvi,rattle-quaternion,rk4-normalized,euler-exp,no-squish,splitting-dlm
for problem in paper-orbit free-body-manchester-peck free-body-hairer dzhanibekov heavy-top; do
  methods=$all
  grep -q 'kind = "none"' "scenarios/$problem.toml" && methods=$all,exact
  build/lgvi compare "scenarios/$problem.toml" --methods "$methods" --out "results/compare/$problem" --force \
    --long-steps 1000000 -q
  echo "lgvi compare: results/compare/$problem/comparison.md"
done
