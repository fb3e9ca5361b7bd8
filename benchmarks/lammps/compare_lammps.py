#!/usr/bin/python3
"""The Lennard-Jones gas of rigid triangle molecules (scenarios/lj-gas.toml) in
lgvi and in LAMMPS (fix rigid/nve/small, the NO_SQUISH integrator of Miller
et al.), from the same initial state, with the same step, cutoff and
neighbour settings, timed in one invocation:

    /usr/bin/python3 benchmarks/lammps/compare_lammps.py LGVI_BINARY LMP_BINARY [--steps 2000] [--repeat 5]
    /usr/bin/python3 benchmarks/lammps/compare_lammps.py LGVI_BINARY LMP_BINARY --periodic
    /usr/bin/python3 benchmarks/lammps/compare_lammps.py LGVI_BINARY LMP_BINARY --periodic --scenario S.toml

--scenario takes another gas or liquid of the same molecules (three Lennard-Jones sites of mass 1, the
same eps, sigma, cutoff 2.5 and skin 0.3: scenarios/lj-fluid-periodic.toml, say) instead of
scenarios/lj-gas.toml; with --periodic its own [box] is used when it has one.

With --periodic the same gas fills a periodic cube of side 22 (the lattice of
spacing 2.2 continued across the faces: [box] in lgvi, boundary p p p in
LAMMPS), and the script compares the start only (in.lj-triangles-thermo):
LAMMPS's step-0 potential energy `pe`, kinetic energy of the atoms
(translational + rotational of the rigid molecules, thermo_modify norm no),
temperature `temp` (fix rigid's 6 N - 3 degrees of freedom) and the pressure
of the rigid molecules computed from LAMMPS's per-atom data against lgvi's V,
T, temperature and pressure, where lgvi's T is computed here from its state
(p^2 / 2m + w . J^-1 w / 8 per molecule), V = E0 - T, and the temperature and
pressure are the summary's. It exits with status 1 unless all agree to 1e-10
relative.

(LMP_BINARY: Debian's `lmp`, package lammps.) It writes a scratch folder with
the LAMMPS data file and input (in.lj-triangles, next to this script, is the
input it uses), runs each program `--repeat` times on one thread (lgvi
--threads 1; LAMMPS serial), and prints a Markdown table: median time per
step, the ratio, and each program's max |E - E0| over the run.

The initial state comes from lgvi itself (a run of zero steps writes every
body's x, q, p, w), converted to atoms: positions x + R rho_i and velocities
p/m + (R Omega) x (R rho_i), Omega = J^{-1} w / 2, so that LAMMPS's rigid
bodies start with exactly lgvi's momenta. The balls are point masses in both
(radius 0: LAMMPS atoms have no inertia of their own), the LJ sites interact
only between molecules (neigh_modify exclude molecule/intra), the energy is
shifted at the cutoff 2.5 (pair_modify shift yes), Verlet lists with skin 0.3.
"""
import argparse
import json
import pathlib
import re
import statistics
import subprocess
import sys
import tempfile
import tomllib

import numpy as np

from lgvi.plot import rotation_matrix as rotation  # R = pi(q), q scalar-first

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent.parent


# --periodic: the cube [-1.1, 20.9)^3, so that the lattice of 10 x 10 x 10
# molecules at spacing 2.2 from the origin continues across its faces.
BOX = (-1.1, 20.9)


GAS = ROOT / "scenarios" / "lj-gas.toml"


def box_of(text):
    """((lower, upper) of the scenario's [box] as arrays) or None."""
    box = tomllib.loads(text).get("box")
    return (np.array(box["lower"], dtype=float), np.array(box["upper"], dtype=float)) if box else None


def scenario_text(steps, step, every, periodic=False, base=GAS):
    text = pathlib.Path(base).read_text()
    if periodic and box_of(text) is None:
        lo, hi = BOX
        text += f"\n[box]\nlower = [{lo!r}, {lo!r}, {lo!r}]\nupper = [{hi!r}, {hi!r}, {hi!r}]\n"
    text = text.replace("radius = 0.5", "radius = 0.0")  # point masses, as LAMMPS atoms
    text = re.sub(r"duration = [0-9.]+", f"duration = {steps * step!r}", text)
    text = re.sub(r"step = [0-9.]+", f"step = {step!r}", text)
    text = re.sub(r"every = \d+", f"every = {every}", text)
    return text


def lammps_data(lgvi, work, periodic=False, base=GAS):
    """Writes the LAMMPS data file of lgvi's initial state; returns its path."""
    scen = work / "initial.toml"
    scen.write_text(scenario_text(0, 0.002, 1, periodic, base))
    subprocess.run([lgvi, "run", scen, "--out", work / "initial", "--force", "--no-figures", "-q"], check=True)
    rows = np.loadtxt(work / "initial" / "trajectory.csv", delimiter=",", skiprows=1, ndmin=2)
    summary = json.loads((work / "initial" / "summary.json").read_text())
    body = summary["setup"]["bodies"][0]
    rho = np.array([b["position"] for b in body["balls"]])
    inertia = np.array(body["inertia"])
    mass = body["mass"]
    atoms, velocities = [], []
    for row in rows:
        x, q, p, w = row[2:5], row[5:9], row[9:12], row[12:15]
        r = rotation(q)
        omega = r @ np.linalg.solve(inertia, 0.5 * w)  # inertial angular velocity
        for k, rk in enumerate(rho):
            arm = r @ rk
            atoms.append((int(row[1]) + 1, x + arm))
            velocities.append(p / mass + np.cross(omega, arm))
    pos = np.array([a[1] for a in atoms])
    lo, hi = pos.min(axis=0) - 50.0, pos.max(axis=0) + 50.0
    if periodic:  # atoms outside a periodic box are wrapped in by read_data, with their image flags
        lo, hi = box_of(scen.read_text())
    lines = ["LAMMPS data: lgvi's lj-gas initial state (benchmarks/lammps/compare_lammps.py)", "",
             f"{len(atoms)} atoms", "1 atom types", ""]
    lines += [f"{lo[i]!r} {hi[i]!r} {c}lo {c}hi" for i, c in enumerate("xyz")]
    lines += ["", "Masses", "", "1 1.0", "", "Atoms # molecular", ""]
    lines += [f"{i + 1} {mol} 1 {x[0]!r} {x[1]!r} {x[2]!r}" for i, (mol, x) in enumerate(atoms)]
    lines += ["", "Velocities", ""]
    lines += [f"{i + 1} {v[0]!r} {v[1]!r} {v[2]!r}" for i, v in enumerate(velocities)]
    path = work / "lj-triangles.data"
    path.write_text("\n".join(lines) + "\n")
    return path


def run_lammps(lmp, work, steps, step, thermo, periodic=False):
    boundary = ["-var", "boundary", "p" if periodic else "s"]
    out = subprocess.run([lmp, "-in", str(HERE / "in.lj-triangles"), "-log", "none", "-screen", "none", *boundary,
                          "-var", "data", str(work / "lj-triangles.data"), "-var", "steps", str(steps),
                          "-var", "dt", repr(step), "-var", "thermo", str(thermo),
                          "-var", "log", str(work / "lammps.log")],
                         capture_output=True, text=True, cwd=work)
    if out.returncode != 0:
        sys.exit(f"LAMMPS failed: {out.stderr or out.stdout}")
    log = (work / "lammps.log").read_text()
    loop = float(re.search(r"Loop time of ([0-9.eE+-]+)", log).group(1))
    rows = [[float(v) for v in m.group(1, 2, 3)]
            for m in re.finditer(r"^\s*\d+\s+([-0-9.eE+]+)\s+([-0-9.eE+]+)\s+([-0-9.eE+]+)\s*$", log, re.M)]
    energies = [r[0] for r in rows]
    if periodic:
        return rows[0]  # E, pe, ke at step 0
    return loop / steps, max(abs(e - energies[0]) for e in energies), energies[0]


def periodic_start(lgvi, lmp, work, base=GAS):
    """The periodic gas's step-0 energies, temperature and pressure in both programs; exits 1 unless they agree to
    1e-10 relative."""
    lammps_data(lgvi, work, periodic=True, base=base)
    out = subprocess.run([lmp, "-in", str(HERE / "in.lj-triangles-thermo"), "-log", "none", "-screen", "none",
                          "-var", "data", str(work / "lj-triangles.data"), "-var", "log", str(work / "thermo.log")],
                         capture_output=True, text=True, cwd=work)
    if out.returncode != 0:
        sys.exit(f"LAMMPS failed: {out.stderr or out.stdout}")
    row = re.search(r"^\s*0\s+(\S+)\s+(\S+)\s+(\S+)\s+(\S+)\s+(\S+)\s*$", (work / "thermo.log").read_text(), re.M)
    pe, ke, temp, pressure, press = (float(v) for v in row.groups())
    summary = json.loads((work / "initial" / "summary.json").read_text())
    rows = np.loadtxt(work / "initial" / "trajectory.csv", delimiter=",", skiprows=1, ndmin=2)
    body = summary["setup"]["bodies"][0]
    inertia, mass = np.array(body["inertia"]), body["mass"]
    t = sum(row[9:12] @ row[9:12] / (2 * mass) + row[12:15] @ np.linalg.solve(inertia, row[12:15]) / 8 for row in rows)
    v = summary["initial_energy"] - t
    thermo = summary["thermodynamics"]
    lo, hi = box_of((work / "initial.toml").read_text())
    sides = " x ".join(f"{side:g}" for side in hi - lo)
    print(f"{pathlib.Path(base).name}: {len(rows)} rigid triangle molecules in a periodic box of {sides}, step 0:\n")
    print("| quantity | lgvi | LAMMPS | relative difference |")
    print("|---|---:|---:|---:|")
    worst = 0.0
    for name, a, b in (("potential energy", v, pe), ("kinetic energy", t, ke),
                       ("temperature", thermo["temperature"]["initial"], temp),
                       ("pressure of the rigid molecules", thermo["pressure"]["initial"], pressure)):
        rel = abs(a - b) / abs(b)
        worst = max(worst, rel)
        print(f"| {name} | {a:.15g} | {b:.15g} | {rel:.2e} |")
    print(f"\n(LAMMPS's own `press` at step 0, its set-up estimate of fix rigid's constraint virial: {press:.15g})")
    sys.exit(0 if worst <= 1e-10 else 1)


def run_lgvi(lgvi, work, steps, step, every):
    scen = work / "gas.toml"
    scen.write_text(scenario_text(steps, step, every))
    subprocess.run([lgvi, "run", scen, "--out", work / "lgvi", "--force", "--no-figures", "-q", "--threads", "1"], check=True)
    s = json.loads((work / "lgvi" / "summary.json").read_text())
    return s["wall_seconds"] / steps, s["max_abs_energy_error"], s["initial_energy"]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("lgvi")
    ap.add_argument("lmp")
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--step", type=float, default=0.002)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--periodic", action="store_true", help="compare the start of the periodic gas")
    ap.add_argument("--scenario", default=str(GAS), help="the gas or liquid (default scenarios/lj-gas.toml)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = pathlib.Path(tmp)
        if args.periodic:
            periodic_start(args.lgvi, args.lmp, work, args.scenario)
        if args.scenario != str(GAS):
            sys.exit("compare_lammps.py: --scenario is for --periodic (the timed run is scenarios/lj-gas.toml's)")
        lammps_data(args.lgvi, work)
        # Energy errors: every 10th step written (LAMMPS thermo output costs time, so timed runs write rarely).
        _, lmp_de, lmp_e0 = run_lammps(args.lmp, work, args.steps, args.step, 10)
        _, lgvi_de, lgvi_e0 = run_lgvi(args.lgvi, work, args.steps, args.step, 10)
        times = {"lgvi": [], "lammps": []}
        for _ in range(args.repeat):  # interleaved, so that both see the same machine load
            times["lgvi"].append(run_lgvi(args.lgvi, work, args.steps, args.step, args.steps)[0])
            times["lammps"].append(run_lammps(args.lmp, work, args.steps, args.step, args.steps)[0])
    t_lgvi, t_lmp = statistics.median(times["lgvi"]), statistics.median(times["lammps"])
    print(f"Lennard-Jones gas of 1000 rigid triangle molecules, h = {args.step}, {args.steps} steps, one thread, "
          f"medians of {args.repeat}:\n")
    print("| program | ms per step | / LAMMPS | E0 | max abs(E - E0) (every 10th step) |")
    print("|---|---:|---:|---:|---:|")
    print(f"| lgvi (quaternion LGVI) | {t_lgvi * 1e3:.3f} | {t_lgvi / t_lmp:.2f} | {lgvi_e0:.6f} | {lgvi_de:.3e} |")
    print(f"| LAMMPS (fix rigid/nve/small) | {t_lmp * 1e3:.3f} | 1.00 | {lmp_e0:.6f} | {lmp_de:.3e} |")
    print(f"\nall timings (s per step): {json.dumps(times)}")


if __name__ == "__main__":
    main()
