#!/usr/bin/env bash
# Benchmarks: ns per step of each integrator and solver on the paper-orbit
# problem, and that figure divided by one force-and-torque evaluation measured
# in the same run (the floor: the method needs one per step). Medians of 9
# repetitions. Usage: scripts/bench.sh [extra google-benchmark flags]
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh >/dev/null
out=$(mktemp)
build/benchmarks/bench_step --benchmark_repetitions=9 --benchmark_report_aggregates_only=true \
  --benchmark_format=json "$@" >"$out"
/usr/bin/python3 - "$out" <<'PY'
import json, sys
rows = {b["run_name"]: b for b in json.load(open(sys.argv[1]))["benchmarks"] if b.get("aggregate_name") == "median"}
floor = rows["BM_PotentialEvaluation"]["real_time"]
print("| benchmark (median of 9) | ns per step | / one potential evaluation | solver iterations per step | residual evaluations per step |")
print("|---|---:|---:|---:|---:|")
fmt = lambda v: "" if v is None else f"{v:.2f}"
for name, b in rows.items():
    print(f"| {name} | {b['real_time']:.1f} | {b['real_time'] / floor:.2f} | {fmt(b.get('solver_iterations'))} | "
          f"{fmt(b.get('residual_evaluations'))} |")
PY
rm -f "$out"
