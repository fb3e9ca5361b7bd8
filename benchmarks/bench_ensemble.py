#!/usr/bin/python3
"""Overhead and scaling of `lgvi ensemble`.

    /usr/bin/python3 benchmarks/bench_ensemble.py [--lgvi build/lgvi] [--members 32] [--repeat 5]

Members: the paper's orbit for 10^4 steps (h = 0.01, t = 100) from random attitudes and
spins. All timings are medians of --repeat runs, interleaved in one process so that the
machine's load falls on all of them alike:

1. Overhead: the ensemble's wall time per member on 1 thread, against the same member run
   alone by `lgvi run --no-figures -q` (its integration loop: summary.json's wall_seconds).
   Per member = the slope between an ensemble of M and of 8 M members, so that the
   process's fixed start-up (loading its libraries, ~50 ms, and MPI's, ~0.5 s) is not
   charged to the members; the start-ups are reported apart.
2. Scaling: 1 thread against 2 threads, 1 process against `mpirun -n 2` (rank 0 hands
   out members and runs them on a second thread; rank 1 runs them), and against one rank
   running members on 2 threads (`mpirun -n 1 --bind-to none --threads 2`), as the same slopes.

Prints a Markdown table.
"""

import argparse
import json
import os
import pathlib
import shutil
import statistics
import subprocess
import tempfile
import time

REPO = pathlib.Path(__file__).resolve().parent.parent
SWEEP = """[ensemble]
scenario = "base.toml"
members = {members}
seed = 1
[[vary]]
key = "initial.quaternion"
rotation = "uniform"
[[vary]]
key = "initial.w"
normal = {{ mean = [1.0, 2.0, 3.0], std = [0.1, 0.1, 0.1] }}
"""
MPI_ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")


def timed(cmd, env=None):
    start = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True, env=env)
    return time.perf_counter() - start


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--lgvi", default=str(REPO / "build" / "lgvi"))
    parser.add_argument("--members", type=int, default=32)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    work = pathlib.Path(tempfile.mkdtemp(prefix="lgvi-bench-ensemble-"))
    base = (REPO / "scenarios" / "paper-orbit.toml").read_text().replace("duration = 1000.0", "duration = 100.0")
    base = base.replace("every = 10", f"every = {10**4}")
    (work / "base.toml").write_text(base)
    small, large = args.members, 8 * args.members
    for m in (small, large):
        (work / f"sweep{m}.toml").write_text(SWEEP.format(members=m))
    mpirun = shutil.which("mpirun")
    configs = [("t1", ["--threads", "1"], None, []), ("t2", ["--threads", "2"], None, [])]
    if mpirun:
        configs.append(("mpi2", [], MPI_ENV, [mpirun, "-n", "2", "--oversubscribe"]))
        # Open MPI binds each of up to 2 ranks to one core by default: threads within a rank need --bind-to none.
        configs.append(("mpi1t2", ["--threads", "2"], MPI_ENV, [mpirun, "-n", "1", "--bind-to", "none"]))
    runs = {"alone_loop": [], "alone_process": []}
    for r in range(args.repeat):
        out = work / f"alone{r}"
        runs["alone_process"].append(timed([args.lgvi, "run", str(work / "base.toml"), "--out", str(out), "--force",
                                            "--no-figures", "-q"]))
        runs["alone_loop"].append(json.loads((out / "summary.json").read_text())["wall_seconds"])
        for name, extra, env, launcher in configs:
            for m in (small, large):
                runs.setdefault((name, m), []).append(timed(
                    launcher + [args.lgvi, "ensemble", str(work / f"sweep{m}.toml"), "--out",
                                str(work / f"{name}-{m}-{r}"), "-q", "--no-figures", *extra], env))
    med = {k: statistics.median(v) for k, v in runs.items() if v}
    slope = {name: (med[(name, large)] - med[(name, small)]) / (large - small) for name, *_ in configs}
    start = {name: med[(name, small)] - small * slope[name] for name, *_ in configs}
    # Speed-ups: the median over the rounds of each round's ratio of slopes. This machine's
    # speed drifts between rounds (by 20 % here); a round's runs follow each other closely,
    # so the ratio within a round is steadier than a ratio of medians taken across rounds.
    def round_slope(name, r):
        return (runs[(name, large)][r] - runs[(name, small)][r]) / (large - small)

    def speedup(a, b):
        return statistics.median(round_slope(a, r) / round_slope(b, r) for r in range(args.repeat))
    print(f"Members: the paper orbit, 10^4 steps each; ensembles of {small} and {large} members; "
          f"medians of {args.repeat} interleaved runs.\n")
    print("| measure | value |")
    print("|---|---:|")
    print(f"| one member run alone: integration loop (ms) | {1e3 * med['alone_loop']:.3f} |")
    print(f"| one member run alone: whole `lgvi run` process (ms) | {1e3 * med['alone_process']:.1f} |")
    print(f"| ensemble, 1 thread: time per member (ms) | {1e3 * slope['t1']:.3f} |")
    print(f"| overhead per member against the loop alone | {100 * (slope['t1'] / med['alone_loop'] - 1):+.1f} % |")
    print(f"| ensemble start-up, 1 process (ms) | {1e3 * start['t1']:.0f} |")
    print(f"| speed-up per member, 1 -> 2 threads | {speedup('t1', 't2'):.2f} |")
    if "mpi2" in slope:
        print(f"| speed-up per member, 1 process -> `mpirun -n 2` | {speedup('t1', 'mpi2'):.2f} |")
        print(f"| time per member, `mpirun -n 2` / 2 threads | {1 / speedup('t2', 'mpi2'):.3f} |")
        print(f"| start-up of `mpirun -n 2` (ms) | {1e3 * start['mpi2']:.0f} |")
        print(f"| speed-up per member, 1 process -> `mpirun -n 1 --bind-to none --threads 2` (threads within a rank) | "
              f"{speedup('t1', 'mpi1t2'):.2f} |")
    shutil.rmtree(work)


if __name__ == "__main__":
    main()
