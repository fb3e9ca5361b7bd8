"""Peak memory and time per step of two lgvi binaries on the periodic gas of scale_lammps.py, run
alternately in one session (e.g. before and after a change to the data layout):

    /usr/bin/python3 benchmarks/lammps/scale_memory.py OLD_LGVI NEW_LGVI [--sizes 100] [--threads 1 2] [--rounds 2]

A size n is n^3 triangle molecules (scale_lammps.py's scenario: 100 steps of h = 0.002, the first and
last written). Each round runs both binaries on each thread count, in alternating order, under
/usr/bin/time; prints each run's set-up time (wall less the run loop), time per step, peak resident
memory, whether the two trajectories are byte-identical, and per size and thread count the median
ratios new/old. Exits with status 1 if a pair of trajectories differs.
"""

import argparse
import filecmp
import json
import pathlib
import statistics
import sys
import tempfile

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from scale_lammps import scenario, timed  # noqa: E402  (the same gas and the same timer)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("old")
    ap.add_argument("new")
    ap.add_argument("--sizes", type=int, nargs="+", default=[100])
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--steps", type=int, default=100)
    args = ap.parse_args()
    binaries = {"old": args.old, "new": args.new}
    identical = True
    print("| molecules | threads | round | binary | set-up s | ms/step | MB |")
    print("|---:|---:|---:|---|---:|---:|---:|")
    ratios = {}
    for n in args.sizes:
        with tempfile.TemporaryDirectory() as tmp:
            work = pathlib.Path(tmp)
            text, _ = scenario(n, args.steps, 0.002)
            (work / "gas.toml").write_text(text)
            for r in range(args.rounds):
                for threads in args.threads:
                    order = ["old", "new"] if r % 2 == 0 else ["new", "old"]
                    seen = {}
                    for name in order:
                        out = work / f"{name}-{threads}"
                        wall, rss = timed([binaries[name], "run", work / "gas.toml", "--out", out, "--force",
                                           "--no-figures", "-q", "--threads", threads])
                        with open(out / "summary.json") as f:
                            loop = json.load(f)["wall_seconds"]
                        seen[name] = (loop / args.steps, rss)
                        print(f"| {n ** 3} | {threads} | {r + 1} | {name} | {wall - loop:.2f} | "
                              f"{1e3 * loop / args.steps:.2f} | {rss:.0f} |", flush=True)
                    same = filecmp.cmp(work / f"old-{threads}" / "trajectory.csv",
                                       work / f"new-{threads}" / "trajectory.csv", shallow=False)
                    identical = identical and same
                    key = (n ** 3, threads)
                    ratios.setdefault(key, []).append((seen["new"][0] / seen["old"][0], seen["new"][1] / seen["old"][1]))
                    if not same:
                        print(f"trajectories differ: {n ** 3} molecules, {threads} threads, round {r + 1}")
    print("\n| molecules | threads | time per step new/old (median) | peak memory new/old (median) |")
    print("|---:|---:|---:|---:|")
    for (molecules, threads), values in ratios.items():
        print(f"| {molecules} | {threads} | {statistics.median(v[0] for v in values):.3f} | "
              f"{statistics.median(v[1] for v in values):.3f} |")
    print("\ntrajectories byte-identical:", "yes" if identical else "NO")
    return 0 if identical else 1


if __name__ == "__main__":
    sys.exit(main())
