#!/usr/bin/python3
"""Does composition make lgvi the cheapest way to small energy errors? (issue 9's goal)

    /usr/bin/python3 scripts/compare_orders.py [--lgvi build/lgvi] [--repeat 3] [--out docs/compare/orders]

For the paper's orbit and the heavy top: `lgvi compare` with lgvi at orders 2, 4, 6, 8 and
rk4-normalized, the ladder starting at a step 8 times the scenario's (higher orders pay off at
larger steps) over 8 halvings. The compare is run --repeat times; each (method, step)'s wall time
is the median over the repeats (single runs of a few ms are noisy). For each energy target
1e-6 ... 1e-12: the least wall time at which some lgvi order keeps max |E - E0| over [0, T] below
the target, against rk4-normalized's; and, from the equal-cost runs of 10^6 steps, each method's
max energy error (bounded, or drifting). Writes PROBLEM.md per problem and prints them.
"""

import argparse
import csv
import pathlib
import statistics
import subprocess
import tempfile

REPO = pathlib.Path(__file__).resolve().parent.parent
PROBLEMS = {"paper-orbit": 0.08, "heavy-top": 0.008}
METHODS = "lgvi,lgvi:4,lgvi:6,lgvi:8,rk4-normalized"
TARGETS = (1e-6, 1e-8, 1e-10, 1e-12)


def run_compare(lgvi, problem, ladder_from, out, long_steps):
    subprocess.run([lgvi, "compare", str(REPO / "scenarios" / f"{problem}.toml"), "--methods", METHODS,
                    "--ladder", "8", "--ladder-from", str(ladder_from), "--long-steps", str(long_steps),
                    "--out", str(out), "--force", "--no-figures", "-q"], check=True, capture_output=True)
    with open(out / "work_precision.csv") as f:
        ladder = list(csv.DictReader(f))
    with open(out / "comparison.csv") as f:
        summary = list(csv.DictReader(f))
    return ladder, summary


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--lgvi", default=str(REPO / "build" / "lgvi"))
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    work = pathlib.Path(tempfile.mkdtemp(prefix="lgvi-orders-"))
    for problem, ladder_from in PROBLEMS.items():
        walls, points, long_summary = {}, {}, None
        for r in range(args.repeat):
            ladder, summary = run_compare(args.lgvi, problem, ladder_from, work / f"{problem}-{r}",
                                          1000000 if r == 0 else 1)
            if r == 0:
                long_summary = summary
            for p in ladder:
                key = (p["method"], float(p["h"]))
                walls.setdefault(key, []).append(float(p["wall_seconds"]))
                points[key] = p
        lines = [f"# Orders on `{problem}`", "",
                 f"Ladder: h = {ladder_from} / 2^j, j = 0..7; wall time: median of {args.repeat} runs of "
                 f"`lgvi compare` ({' '.join(METHODS.split(','))}).", "",
                 "| target max abs(E - E0) | best lgvi (order, h, wall) | rk4-normalized (h, wall) | "
                 "rk4 / best lgvi |", "|---:|---|---|---:|"]
        for target in TARGETS:
            best = {}
            for (method, h), p in points.items():
                if p["completed"] != "true" or not float(p["max_abs_energy_error"]) <= target:
                    continue
                family = "rk4" if method.startswith("rk4") else "lgvi"
                wall = statistics.median(walls[(method, h)])
                if family not in best or wall < best[family][2]:
                    best[family] = (method, h, wall)
            def cell(b):
                return f"{b[0]}, h = {b[1]:g}, {1e3 * b[2]:.2f} ms" if b else "none reached it"
            ratio = f"{best['rk4'][2] / best['lgvi'][2]:.2f}" if "rk4" in best and "lgvi" in best else "-"
            lines.append(f"| {target:.0e} | {cell(best.get('lgvi'))} | {cell(best.get('rk4'))} | {ratio} |")
        lines += ["", "Equal cost, 10^6 evaluations' worth (a method of e evaluations per step runs e h):", "",
                  "| method | long: max abs energy error | long: final energy error | long: max abs(abs(q) - 1) |",
                  "|---|---:|---:|---:|"]
        for s in long_summary:
            lines.append(f"| {s['method']} | {float(s['long_max_abs_energy_error']):.3e} | "
                         f"{float(s['long_final_energy_error']):.3e} | {float(s['long_max_abs_quat_norm_error']):.3e} |")
        text = "\n".join(lines) + "\n"
        print(text)
        if args.out:
            out = pathlib.Path(args.out)
            out.mkdir(parents=True, exist_ok=True)
            (out / f"{problem}.md").write_text(text)


if __name__ == "__main__":
    main()
