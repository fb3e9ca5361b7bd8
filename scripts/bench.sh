#!/usr/bin/env bash
# Benchmarks (Google Benchmark), medians of 9 repetitions, ratios within the same run:
#  1. bench_step: the quaternion LGVI and its solvers on the paper-orbit problem, against
#     one force-and-torque evaluation (the floor: the method needs one per step);
#  2. bench_methods: every method on each standard problem (scenarios/), ns per step and
#     the ratio against the quaternion LGVI on the same problem.
# Usage: scripts/bench.sh [extra google-benchmark flags]
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh >/dev/null
step=$(mktemp) methods=$(mktemp)
build/benchmarks/bench_step --benchmark_repetitions=9 --benchmark_report_aggregates_only=true \
  --benchmark_format=json "$@" >"$step"
build/benchmarks/bench_methods --benchmark_repetitions=9 --benchmark_report_aggregates_only=true \
  --benchmark_min_time=0.1 --benchmark_format=json "$@" >"$methods"
/usr/bin/python3 - "$step" "$methods" <<'PY'
import json, sys
def medians(path):
    return {b["run_name"]: b for b in json.load(open(path))["benchmarks"] if b.get("aggregate_name") == "median"}
rows = medians(sys.argv[1])
floor = rows["BM_PotentialEvaluation"]["real_time"]
print("| benchmark (median of 9) | ns per step | / one potential evaluation | solver iterations per step | residual evaluations per step |")
print("|---|---:|---:|---:|---:|")
fmt = lambda v: "" if v is None else f"{v:.2f}"
for name, b in rows.items():
    print(f"| {name} | {b['real_time']:.1f} | {b['real_time'] / floor:.2f} | {fmt(b.get('solver_iterations'))} | "
          f"{fmt(b.get('residual_evaluations'))} |")
m = medians(sys.argv[2])
problems = []
for name in m:
    p = name.split("/", 1)[1]
    if p not in problems:
        problems.append(p)
methods = []
for name in m:
    meth = name.split("/", 1)[0]
    if meth != "potential" and meth not in methods:
        methods.append(meth)
print()
print("| ns per step (median of 9); in brackets: / lgvi | " + " | ".join(problems) + " |")
print("|---|" + "---:|" * len(problems))
print("| one potential evaluation | " + " | ".join(f"{m['potential/' + p]['real_time']:.1f}" for p in problems) + " |")
for meth in methods:
    cells = []
    for p in problems:
        b = m.get(f"{meth}/{p}")
        cells.append("-" if b is None else f"{b['real_time']:.0f} ({b['real_time'] / m['lgvi/' + p]['real_time']:.2f})")
    print(f"| {meth} | " + " | ".join(cells) + " |")
PY
rm -f "$step" "$methods"
