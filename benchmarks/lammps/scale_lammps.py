#!/usr/bin/python3
"""The periodic Lennard-Jones gas of rigid triangle molecules at growing N, in
lgvi and in LAMMPS (fix rigid/nve/small) from the same initial state: set-up
time, time per step, peak memory and energy error of each, on T threads (lgvi)
and T MPI ranks (LAMMPS):

    /usr/bin/python3 benchmarks/lammps/scale_lammps.py LGVI_BINARY LMP_BINARY [--sizes 22 46 100] [--steps 100] [--threads 1 2]

A size n is n^3 molecules on a cubic lattice of spacing 2.2 filling a periodic
cube of side 2.2 n (scenarios/lj-gas.toml's molecules, kT = 0.5, point masses
as in compare_lammps.py, whose conversion to a LAMMPS data file this uses).
Each program runs `--steps` steps of h = 0.002 writing the first and last
only, under /usr/bin/time -v: its wall time and maximum resident set size. The
time per step is the run loop's (lgvi's summary wall_seconds; LAMMPS's "Loop
time"), the set-up time the rest of the wall time (reading, building the
bodies, the first neighbour lists, writing the outputs). The peak memory is
lgvi's process's, and the sum of LAMMPS's ranks' (each rank under
/usr/bin/time). The energy error is the largest |E - E0| over the run: lgvi's
over every step (its summary), LAMMPS's over every step too (thermo 1, in a second run: its time and memory are
from a run printing the first and last step only, as lgvi's).

With --marginal, each program also runs 2 x `--steps` steps (timed the same
way), and a second table gives the time per step from the difference of the
two loops, (loop(2 s) - loop(s)) / s: the cost of a step in the middle of a run,
without what both loops hold once. lgvi's loop holds its first evaluation (its
neighbour lists built) and the two frames it writes (at 10^6 molecules two
frames of 10^6 rows, 1 GB of CSV); LAMMPS's "Loop time" holds neither (its first
evaluation is in its set-up, and it writes no frames here, only thermo lines).

With --no-squish, a second table gives the energy errors to five digits, with
those of lgvi's own NO_SQUISH method (`method = "no-squish"`, the rotation
splitting fix rigid/nve/small uses) on the same gas: as far as lgvi's
NO_SQUISH agrees with LAMMPS, a difference between lgvi's LGVI and LAMMPS is
the methods', not the programs'.
Prints a Markdown table.
"""
import argparse
import json
import os
import pathlib
import re
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from compare_lammps import HERE, ROOT, rotation  # noqa: E402


def scenario(n, steps, step):
    text = (ROOT / "scenarios" / "lj-gas.toml").read_text().replace("radius = 0.5", "radius = 0.0")
    text = re.sub(r"count = \d+", f"count = {n ** 3}", text)
    text = re.sub(r"duration = [0-9.]+", f"duration = {steps * step!r}", text)
    text = re.sub(r"step = [0-9.]+", f"step = {step!r}", text)
    text = re.sub(r"every = \d+", f"every = {max(steps, 1)}", text)
    lo, hi = -1.1, -1.1 + 2.2 * n
    return text + f"\n[box]\nlower = [{lo!r}, {lo!r}, {lo!r}]\nupper = [{hi!r}, {hi!r}, {hi!r}]\n", (lo, hi)


def timed(command, ranks=1):
    """Runs command under /usr/bin/time, as `ranks` MPI ranks if more than one:
    (wall seconds, peak RSS in MB summed over the ranks)."""
    with tempfile.TemporaryDirectory() as tmp:
        report = pathlib.Path(tmp) / "time"
        timer = ["/usr/bin/time", "-f", "%e %M", "-o"]
        if ranks > 1:  # each rank timed into its own file (Open MPI sets OMPI_COMM_WORLD_RANK)
            env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
            rank_timer = ["sh", "-c", 'exec /usr/bin/time -f "%e %M" -o "$0.$OMPI_COMM_WORLD_RANK" "$@"', report]
            command = timer + [report, "mpirun", "-n", str(ranks), "--oversubscribe", *rank_timer, *command]
        else:
            env, command = None, timer + [report, *command]
        out = subprocess.run(list(map(str, command)), capture_output=True, text=True, env=env)
        if out.returncode != 0:
            sys.exit(f"{command} failed: {out.stderr[-2000:]}")
        wall = float(report.read_text().split()[-2])
        files = [pathlib.Path(f"{report}.{r}") for r in range(ranks)] if ranks > 1 else [report]
        return wall, sum(int(f.read_text().split()[-1]) for f in files) / 1024


def data_file(lgvi, work, n, box):
    """The LAMMPS data file of lgvi's initial state (a run of zero steps), vectorized."""
    text, _ = scenario(n, 0, 0.002)
    (work / "initial.toml").write_text(text)
    subprocess.run([lgvi, "run", work / "initial.toml", "--out", work / "initial", "--force", "--no-figures", "-q"],
                   check=True)
    rows = np.loadtxt(work / "initial" / "trajectory.csv", delimiter=",", skiprows=1, ndmin=2)
    with open(work / "initial" / "summary.json") as f:
        summary = json.load(f)
    if "body_lists" in summary:  # beyond 10 000 bodies: their lists a body a line in a file beside it
        with open(work / "initial" / summary["body_lists"]["file"]) as f:
            body = json.loads(f.readline())
    else:
        body = summary["setup"]["bodies"][0]
    rho = np.array([b["position"] for b in body["balls"]])
    inertia, mass = np.array(body["inertia"]), body["mass"]
    x, q, p, w = rows[:, 2:5], rows[:, 5:9], rows[:, 9:12], rows[:, 12:15]
    r = np.array([rotation(qa) for qa in q])                        # (N, 3, 3)
    omega = np.einsum("nij,nj->ni", r, np.linalg.solve(inertia, 0.5 * w.T).T)
    arms = np.einsum("nij,kj->nki", r, rho)                         # (N, 3 sites, 3)
    pos = (x[:, None, :] + arms).reshape(-1, 3)
    vel = (p[:, None, :] / mass + np.cross(omega[:, None, :], arms)).reshape(-1, 3)
    mol = np.repeat(rows[:, 1].astype(int) + 1, len(rho))
    lines = [f"LAMMPS data: lgvi's periodic lj-gas, {len(rows)} molecules (benchmarks/lammps/scale_lammps.py)", "",
             f"{len(pos)} atoms", "1 atom types", ""]
    lines += [f"{box[0]!r} {box[1]!r} {c}lo {c}hi" for c in "xyz"]
    lines += ["", "Masses", "", "1 1.0", "", "Atoms # molecular", ""]
    lines += [f"{i + 1} {m} 1 {a[0]!r} {a[1]!r} {a[2]!r}" for i, (m, a) in enumerate(zip(mol, pos))]
    lines += ["", "Velocities", ""]
    lines += [f"{i + 1} {v[0]!r} {v[1]!r} {v[2]!r}" for i, v in enumerate(vel)]
    (work / "lj-triangles.data").write_text("\n".join(lines) + "\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("lgvi")
    ap.add_argument("lmp")
    ap.add_argument("--sizes", type=int, nargs="+", default=[22, 46, 100])
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--step", type=float, default=0.002)
    ap.add_argument("--threads", type=int, nargs="+", default=[1],
                    help="lgvi's threads and LAMMPS's MPI ranks (default 1)")
    ap.add_argument("--marginal", action="store_true",
                    help="also run 2 x steps: a table of the time per step from the difference of the two loops")
    ap.add_argument("--no-squish", action="store_true",
                    help="also run lgvi's no-squish method: a table of the energy errors to five digits")
    args = ap.parse_args()
    errors = []  # (molecules, lgvi's max |dE|, lgvi no-squish's, LAMMPS's) with --no-squish
    marginal = []  # (molecules, threads, lgvi's and LAMMPS's loops at steps and 2 x steps) with --marginal
    print(f"Periodic Lennard-Jones gas of rigid triangle molecules, {args.steps} steps of h = {args.step}:\n")
    print("| molecules | threads / ranks | lgvi set-up s | LAMMPS set-up s | lgvi ms/step | LAMMPS ms/step | / LAMMPS "
          "| lgvi MB | LAMMPS MB | / LAMMPS | lgvi max abs dE | LAMMPS max abs dE |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for n in args.sizes:
        with tempfile.TemporaryDirectory() as tmp:
            work = pathlib.Path(tmp)
            text, box = scenario(n, args.steps, args.step)
            data_file(args.lgvi, work, n, box)
            (work / "gas.toml").write_text(text)
            (work / "gas-long.toml").write_text(scenario(n, 2 * args.steps, args.step)[0])
            for threads in args.threads:
                def run_lgvi(toml):  # (wall s, peak MB, summary)
                    wall, rss = timed([args.lgvi, "run", toml, "--out", work / "lgvi", "--force", "--no-figures", "-q",
                                       "--threads", threads])
                    with open(work / "lgvi" / "summary.json") as f:
                        return wall, rss, json.load(f)
                lgvi_wall, lgvi_rss, summary = run_lgvi(work / "gas.toml")
                lgvi_loop, lgvi_de = summary["wall_seconds"], summary["max_abs_energy_error"]
                def lammps(thermo, steps=args.steps):
                    return [args.lmp, "-in", HERE / "in.lj-triangles", "-log", "none", "-screen", "none",
                            "-var", "boundary", "p", "-var", "data", work / "lj-triangles.data",
                            "-var", "steps", steps, "-var", "dt", repr(args.step),
                            "-var", "thermo", thermo, "-var", "log", work / "lammps.log"]
                def lammps_loop():
                    return float(re.search(r"Loop time of ([0-9.eE+-]+)", (work / "lammps.log").read_text()).group(1))
                # Timed with thermo output at the first and last step only, as lgvi's; the energy error
                # from a second run printing every step (whose reductions would add to the loop time).
                lmp_wall, lmp_rss = timed(lammps(args.steps), ranks=threads)
                lmp_loop = lammps_loop()
                if args.marginal:
                    lgvi_long = run_lgvi(work / "gas-long.toml")[2]["wall_seconds"]
                    timed(lammps(2 * args.steps, 2 * args.steps), ranks=threads)
                    marginal.append((n ** 3, threads, lgvi_loop, lgvi_long, lmp_loop, lammps_loop()))
                timed(lammps(1), ranks=threads)
                log = (work / "lammps.log").read_text()
                # The thermo rows: step, total energy, pe, ke (in.lj-triangles's thermo_style).
                energy = [float(m.group(1)) for m in re.finditer(r"^\s*\d+\s+(\S+)\s+\S+\s+\S+\s*$", log, re.M)]
                lmp_de = max(abs(e - energy[0]) for e in energy)
                t_lgvi, t_lmp = lgvi_loop / args.steps * 1e3, lmp_loop / args.steps * 1e3
                print(f"| {n ** 3} | {threads} | {lgvi_wall - lgvi_loop:.2f} | {lmp_wall - lmp_loop:.2f} "
                      f"| {t_lgvi:.2f} | {t_lmp:.2f} | {t_lgvi / t_lmp:.2f} | {lgvi_rss:.0f} | {lmp_rss:.0f} "
                      f"| {lgvi_rss / lmp_rss:.2f} | {lgvi_de:.2e} | {lmp_de:.2e} |", flush=True)
            if args.no_squish:  # (its energy does not depend on the threads: one run)
                assert 'method = "lgvi"' in text, "scenarios/lj-gas.toml no longer names its method as expected"
                (work / "no-squish.toml").write_text(text.replace('method = "lgvi"', 'method = "no-squish"', 1))
                subprocess.run([args.lgvi, "run", work / "no-squish.toml", "--out", work / "no-squish", "--force",
                                "--no-figures", "-q"], check=True)
                with open(work / "no-squish" / "summary.json") as f:
                    errors.append((n ** 3, lgvi_de, json.load(f)["max_abs_energy_error"], lmp_de))
    if marginal:
        print(f"\nTime per step from the difference of runs of {args.steps} and {2 * args.steps} steps "
              f"(loop({2 * args.steps}) - loop({args.steps})) / {args.steps}:\n")
        print("| molecules | threads / ranks | lgvi loop s (s, 2 s) | LAMMPS loop s (s, 2 s) | lgvi ms/step "
              "| LAMMPS ms/step | / LAMMPS |")
        print("|---:|---:|---:|---:|---:|---:|---:|")
        for n, threads, lgvi_short, lgvi_long, lmp_short, lmp_long in marginal:
            t_lgvi = (lgvi_long - lgvi_short) / args.steps * 1e3
            t_lmp = (lmp_long - lmp_short) / args.steps * 1e3
            print(f"| {n} | {threads} | {lgvi_short:.2f}, {lgvi_long:.2f} | {lmp_short:.2f}, {lmp_long:.2f} "
                  f"| {t_lgvi:.2f} | {t_lmp:.2f} | {t_lgvi / t_lmp:.2f} |", flush=True)
    if errors:
        print("\n| molecules | lgvi (LGVI) max abs dE | lgvi (NO_SQUISH) max abs dE | LAMMPS max abs dE "
              "| LGVI / LAMMPS | NO_SQUISH / LAMMPS |")
        print("|---:|---:|---:|---:|---:|---:|")
        for n, lgvi_de, no_squish_de, lmp_de in errors:
            print(f"| {n} | {lgvi_de:.5e} | {no_squish_de:.5e} | {lmp_de:.5e} | {lgvi_de / lmp_de:.4f} "
                  f"| {no_squish_de / lmp_de:.4f} |")


if __name__ == "__main__":
    main()
