"""Peak memory and wall time of a run that reads its molecules from a LAMMPS data file ([import]), for two
lgvi binaries in one session (e.g. before and after a change to the import).

    /usr/bin/python3 benchmarks/import_memory.py OLD_LGVI NEW_LGVI [--molecules 100000] [--repeat 2]

Writes a data file of triangle molecules (3 atoms of type 1, mass 1) on a cubic lattice of spacing 2.2,
each turned by a random rotation, with random velocities, and a scenario reading it with a Lennard-Jones
interaction (cutoff 2.5, periodic box); runs 20 steps of h = 0.002 on one thread with each binary in turn,
`--repeat` times, and prints the peak resident memory and wall time of each run from /usr/bin/time.
"""

import argparse
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

TRIANGLE = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 0.8660254037844386, 0.0]])


def rotation(q):
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def write_case(folder, n):
    side = int(round(n ** (1 / 3))) + 1
    length = side * 2.2
    rng = np.random.default_rng(3)
    atoms, velocities = [], []
    centred = TRIANGLE - TRIANGLE.mean(axis=0)
    for m in range(n):
        cell = np.array([m % side, (m // side) % side, m // (side * side)])
        turn = rotation(rng.normal(size=4))
        for p in centred:
            r = cell * 2.2 + 0.7 + turn @ p
            atoms.append(f"{len(atoms) + 1} {m + 1} 1 {r[0]!r} {r[1]!r} {r[2]!r}")
            v = 0.1 * rng.normal(size=3)
            velocities.append(f"{len(velocities) + 1} {v[0]!r} {v[1]!r} {v[2]!r}")
    header = ["triangles", "", f"{len(atoms)} atoms", "1 atom types"] + \
             [f"0.0 {length!r} {a}lo {a}hi" for a in "xyz"] + ["", "Masses", "", "1 1.0", "", "Atoms # molecular", ""]
    (folder / "triangles.data").write_text("\n".join(header + atoms + ["", "Velocities", ""] + velocities) + "\n")
    (folder / "import.toml").write_text(
        '[import]\nlammps_data = "triangles.data"\n\n[interaction]\nkind = "lennard-jones"\nepsilon = 1.0\n'
        'sigma = 1.0\ncutoff = 2.5\n\n[potential]\nkind = "none"\n\n[integrator]\nstep = 0.002\nduration = 0.04\n\n'
        '[output]\nevery = 1000\n')


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("binaries", nargs="+", help="lgvi executables to compare")
    parser.add_argument("--molecules", type=int, default=100000)
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(tmp)
        write_case(folder, args.molecules)
        print(f"{args.molecules} imported triangle molecules, 20 steps, one thread")
        for k in range(args.repeat):
            for binary in args.binaries:
                out = folder / f"out-{k}"
                proc = subprocess.run(["/usr/bin/time", "-f", "%M %e", binary, "run", str(folder / "import.toml"),
                                       "--out", str(out), "--force", "-q", "--no-figures", "--threads", "1"],
                                      capture_output=True, text=True)
                if proc.returncode != 0:
                    print(f"{binary}: failed: {proc.stderr.strip()}", file=sys.stderr)
                    return 1
                kb, seconds = proc.stderr.strip().splitlines()[-1].split()
                print(f"{binary}: peak {int(kb) / 1024:.0f} MB, {float(seconds):.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
