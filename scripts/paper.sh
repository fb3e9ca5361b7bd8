#!/usr/bin/env bash
# The paper's experiment: set up and build (scripts/setup.sh), then run the
# paper's scenario as stated (radial p0) and on the orbit its captions speak
# of. Outputs and figures land in results/paper/ and results/paper-orbit/.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
for s in paper paper-orbit; do
  build/lgvi run "scenarios/$s.toml" --out "results/$s" --force
done
echo "lgvi: the paper's experiment is in results/paper/ and results/paper-orbit/ (trajectory.csv, summary.json, *.png)"
