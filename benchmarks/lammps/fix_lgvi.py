#!/usr/bin/python3
"""fix rigid/nve/lgvi against LAMMPS's own rigid integrators on the same input, in one invocation:

    /usr/bin/python3 benchmarks/lammps/fix_lgvi.py LGVI_BINARY LMP_LGVI [--steps 10000] [--repeat 3] [--ranks 1 2]
    /usr/bin/python3 benchmarks/lammps/fix_lgvi.py LGVI_BINARY LMP_LGVI --water --steps 5000 --step 2.0 [--scan 3 4 5 6]

LMP_LGVI is the driver build/lammps/lmp-lgvi (scripts/setup.sh builds it); it is LAMMPS (Debian's liblammps)
with the fix registered, so all three styles run in the same executable. The case is the periodic
Lennard-Jones gas of 1000 rigid triangle molecules (compare_lammps.py --periodic: its data file is written from
lgvi's initial state) with lammps/tests/in.gas: `fix rigid/nve/lgvi` (this project's fix), `rigid/nve/small`
(NO_SQUISH) and `rigid/small` (Richardson iteration), each on 1 and 2 MPI ranks, `--repeat` times. Printed as a
Markdown table: median loop time per step, its ratio to rigid/nve/small's on as many ranks, max |E - E0| over
the run (E = pe + erotate/rigid + ke/rigid, sampled every 100 steps, which every style pays alike) and the
drift, the least-squares slope of E against the step scaled to 10^5 steps. With --scan H1 H2 ... a second
table: each style on one rank over the same simulated time (--steps * --step) at each step H, max |E - E0| and
drift, or where the run failed (a lost atom, a failed rotation solve): the largest stable step.

With --water the case is rigid SPC/E water instead (water.py writes 1000 molecules on a lattice, in.water runs
them: lj/cut/coul/long 9 A + PPPM 1e-5, units real, steps in fs), first --equilibrate steps of
rigid/nvt/small at 300 K, whose final state (write_data) every style then starts from.

With --sizes n1 n2 ... the case is the periodic gas of n^3 molecules (scale_lammps.py's data file) instead, run
--steps steps by rigid/nve/lgvi and rigid/nve/small on each of --ranks under /usr/bin/time: loop time per step
and peak memory (summed over ranks).
"""
import argparse
import os
import pathlib
import re
import statistics
import subprocess
import sys
import tempfile

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent.parent
sys.path.insert(0, str(HERE))
import compare_lammps  # noqa: E402

STYLES = ("rigid/nve/lgvi", "rigid/nve/small", "rigid/small")
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")


def case_input(case, work):
    """The input file and its case-specific variables."""
    if case == "water":
        return HERE / "in.water", {"velocities": 0}
    return ROOT / "lammps" / "tests" / "in.gas", {"boundary": "p", "dump": work / "run.dump"}


def run(lmp, work, case, data, style, ranks, steps, step, allow_failure=False):
    log = work / "run.log"
    path, variables = case_input(case, work)
    variables.update(data=data, style=style, steps=steps, dt=repr(step), thermo=100, log=log)
    args = [lmp, "-in", str(path), "-screen", "none", "-log", "none"]
    for name, value in variables.items():
        args += ["-var", name, str(value)]
    if ranks > 1:
        args = ["mpirun", "-n", str(ranks), "--oversubscribe", *args]
    out = subprocess.run(args, capture_output=True, text=True, cwd=work, env=ENV)
    if out.returncode != 0:
        if allow_failure:  # LAMMPS's error line, from its log (the screen is off)
            text = log.read_text() if log.exists() else ""
            lines = [line for line in text.splitlines() if line.startswith("ERROR")]
            reason = lines[0] if lines else "no error line"
            at = re.search(r"at step (\d+)", reason)
            label = ("rotation solve" if "rotation of the body" in reason else
                     "atoms lost" if "missing" in reason or "Lost atoms" in reason else reason[:60])
            return None, f"failed ({label}{', step ' + at.group(1) if at else ''})", None
        sys.exit(f"{style} on {ranks} ranks failed: {out.stdout[-2000:]}{out.stderr[-2000:]}")
    text = log.read_text()
    loop = float(re.search(r"Loop time of ([0-9.eE+-]+)", text).group(1))
    rows = np.array([[float(m.group(1)), float(m.group(2))]
                     for m in re.finditer(r"^\s*(\d+)\s+([-+0-9.eE]+)(?:\s+[-+0-9.eE]+){3}\s*$", text, re.M)])
    step_index, energy = rows[:, 0], rows[:, 1]
    drift = np.polyfit(step_index, energy, 1)[0] * 1e5
    run.series[(style, ranks, step)] = (step_index * step, energy - energy[0])
    return loop / steps, float(np.abs(energy - energy[0]).max()), float(drift)


run.series = {}  # (style, ranks, step) -> (time, E - E0) of the last such run, for --figures


def figures(a, out, scan):
    """E - E0 against time for each style on one rank at --step, and max |E - E0| against the step (--scan)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    out.mkdir(parents=True, exist_ok=True)
    name = "water" if a.water else "gas"
    unit = " (kcal/mol)" if a.water else ""
    fig, ax = plt.subplots(figsize=(7, 3.6))
    for s in a.styles:
        if (s, 1, a.step) in run.series:
            t, de = run.series[(s, 1, a.step)]
            ax.plot(t, de, label=s, lw=1)
    ax.set_xlabel("time (fs)" if a.water else "time")
    ax.set_ylabel("E - E0" + unit)
    ax.set_title(f"{'SPC/E water' if a.water else 'LJ gas'}, 1000 rigid molecules, step {a.step:g}, one rank")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / f"lammps-fix-{name}-energy.png", dpi=110)
    plt.close(fig)
    if scan:
        fig, ax = plt.subplots(figsize=(7, 3.6))
        steps = sorted({h for _, h in scan} | ({a.step} if (a.styles[0], 1, a.step) in run.series else set()))
        for s in a.styles:
            xs, ys = [], []
            for h in steps:
                if (s, 1, h) in run.series:
                    xs.append(h)
                    ys.append(np.abs(run.series[(s, 1, h)][1]).max())
            ax.loglog(xs, ys, "o-", label=s)
        ax.set_xlabel("step (fs)" if a.water else "step")
        ax.set_ylabel("max |E - E0|" + unit)
        ax.set_title(f"over t = {a.steps * a.step:g}; a missing point: the run failed")
        ax.legend()
        fig.tight_layout()
        fig.savefig(out / f"lammps-fix-{name}-steps.png", dpi=110)
        plt.close(fig)


def scale(a):
    import scale_lammps
    print(f"Periodic LJ gas of rigid triangle molecules, {a.steps} steps of {a.step}, time per step and peak memory:\n")
    print("| molecules | ranks | rigid/nve/lgvi ms/step | rigid/nve/small ms/step | ratio | rigid/nve/lgvi MB "
          "| rigid/nve/small MB |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for n in a.sizes:
        with tempfile.TemporaryDirectory() as tmp:
            work = pathlib.Path(tmp)
            _, box = scale_lammps.scenario(n, 0, a.step)
            scale_lammps.data_file(a.lgvi, work, n, box)
            for ranks in a.ranks:
                cells = {}
                for style in ("rigid/nve/lgvi", "rigid/nve/small"):
                    log = work / "run.log"
                    _, rss = scale_lammps.timed(
                        [a.lmp_lgvi, "-in", ROOT / "lammps" / "tests" / "in.gas", "-screen", "none", "-log", "none",
                         "-var", "data", work / "lj-triangles.data", "-var", "style", style, "-var", "boundary", "p",
                         "-var", "steps", a.steps, "-var", "dt", repr(a.step), "-var", "log", log,
                         "-var", "dumps", 0], ranks=ranks)
                    loop = float(re.search(r"Loop time of ([0-9.eE+-]+)", log.read_text()).group(1))
                    cells[style] = (loop / a.steps * 1e3, rss)
                (tl, ml), (tn, mn) = cells["rigid/nve/lgvi"], cells["rigid/nve/small"]
                print(f"| {n ** 3} | {ranks} | {tl:.2f} | {tn:.2f} | {tl / tn:.3f} | {ml:.0f} | {mn:.0f} |", flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("lgvi")
    parser.add_argument("lmp_lgvi")
    parser.add_argument("--steps", type=int, default=10000)
    parser.add_argument("--step", type=float, default=0.002)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--scan", type=float, nargs="*", default=[])
    parser.add_argument("--scan-only", action="store_true", help="only the --scan table")
    parser.add_argument("--figures", type=pathlib.Path, help="write the energy figures into this folder")
    parser.add_argument("--styles", nargs="+", default=list(STYLES), choices=STYLES,
                        help="the fixes to run (default all three; rigid/nve/small is the reference of the ratios)")
    parser.add_argument("--water", action="store_true", help="the SPC/E water case (units real: steps in fs)")
    parser.add_argument("--equilibrate", type=int, default=5000, help="water: steps of rigid/nvt/small at 300 K first")
    parser.add_argument("--sizes", type=int, nargs="*", default=[], help="the gas of n^3 molecules: time and memory")
    a = parser.parse_args()
    a.lgvi, a.lmp_lgvi = (str(pathlib.Path(x).resolve()) for x in (a.lgvi, a.lmp_lgvi))
    if a.sizes:
        return scale(a)
    with tempfile.TemporaryDirectory() as tmp:
        work = pathlib.Path(tmp)
        case = "water" if a.water else "gas"
        if a.water:
            subprocess.run([sys.executable, str(HERE / "water.py"), str(work / "lattice.data")], check=True)
            data = work / "water.data"
            out = subprocess.run([a.lmp_lgvi, "-in", str(HERE / "in.water"), "-screen", "none", "-log", "none",
                                  "-var", "data", str(work / "lattice.data"), "-var", "style", "rigid/nvt/small",
                                  "-var", "keywords", "temp 300.0 300.0 100.0", "-var", "steps", str(a.equilibrate),
                                  "-var", "dt", "2.0", "-var", "thermo", "1000", "-var", "log", str(work / "eq.log"),
                                  "-var", "to_data", "1", "-var", "data_out", str(data)], capture_output=True,
                                 text=True, cwd=work)
            if out.returncode != 0:
                sys.exit(f"equilibration failed: {out.stdout[-2000:]}")
        else:
            data = compare_lammps.lammps_data(a.lgvi, work, periodic=True)
        times = {(s, r): [] for s in a.styles for r in a.ranks}
        errors = {}
        for _ in range(0 if a.scan_only else a.repeat):  # interleaved, so that a slow spell of the machine hits every style alike
            for r in a.ranks:
                for s in a.styles:
                    t, e, d = run(a.lmp_lgvi, work, case, data, s, r, a.steps, a.step)
                    times[(s, r)].append(t)
                    errors[(s, r)] = (e, d)
        scan = {(s, h): run(a.lmp_lgvi, work, case, data, s, 1, round(a.steps * a.step / h), h,
                                  allow_failure=True)
                for h in a.scan for s in a.styles}
    what = (f"SPC/E water, 1000 rigid molecules (PPPM 1e-5, cutoff 9 A), from {a.equilibrate} steps at 300 K"
            if a.water else "Periodic LJ gas of 1000 rigid triangle molecules")
    print(f"{what}, {a.steps} steps of {a.step}, median of {a.repeat}:\n")
    if not a.scan_only:
        print("| fix | ranks | ms per step | / rigid/nve/small | max abs(E - E0) | drift per 10^5 steps |")
        print("|---|---:|---:|---:|---:|---:|")
    for r in [] if a.scan_only else a.ranks:
        base = statistics.median(times[("rigid/nve/small", r)])
        for s in a.styles:
            m = statistics.median(times[(s, r)])
            e, d = errors[(s, r)]
            print(f"| {s} | {r} | {1e3 * m:.3f} | {m / base:.3f} | {e:.3g} | {d:.3g} |")
    if a.scan:
        print(f"\nThe same system over t = {a.steps * a.step:g} at other steps, one rank: max abs(E - E0) (drift per 10^5 "
              "steps)\n")
        print("| step | " + " | ".join(a.styles) + " |")
        print("|---:|" + "---:|" * len(a.styles))
        for h in a.scan:
            cells = []
            for s in a.styles:
                _, e, d = scan[(s, h)]
                cells.append(e if d is None else f"{e:.3g} ({d:.2g})")
            print(f"| {h:g} | " + " | ".join(cells) + " |")
    if a.figures:
        figures(a, a.figures.resolve(), scan)


if __name__ == "__main__":
    main()
