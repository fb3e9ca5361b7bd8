#!/usr/bin/python3
"""Writes bent-fluid.data (next to this script): a LAMMPS data file of 1000 rigid
bent triatomic molecules in a periodic cube, the input of scenarios/bent-fluid.toml.

    /usr/bin/python3 scenarios/data/make_bent_fluid.py [OUT]

Each molecule is a site of atom type 1 (mass 1) with two of type 2 (mass 0.5)
at distance 0.8 from it, 104.5 degrees apart (a water-like shape, in
Lennard-Jones units). The molecules sit on a 10 x 10 x 10 lattice of spacing
1.7 filling the cube [0, 17)^3, in random attitudes, each attitude redrawn
while one of its sites comes closer than the pair's sigma to a site of a
molecule placed before (minimum image); every atom gets its own
velocity drawn at kT = 1.2 (m v_k ~ N(0, m kT)), which the importer projects
onto rigid motion as LAMMPS's fix rigid/small does. Atoms whose coordinates
fall outside the cube are wrapped into it with image flags. Deterministic: the
same file on every run (numpy's PCG64 from seed 5).
"""
import pathlib
import sys

import numpy as np

N_SIDE, SPACING, KT, SEED = 10, 1.7, 1.2, 5
SIGMA = {(1, 1): 1.0, (1, 2): 0.7 ** 0.5, (2, 2): 0.7}  # the scenario's sigma per pair of types (geometric mixing)
BOND, ANGLE = 0.8, np.radians(104.5)
MASSES = {1: 1.0, 2: 0.5}


def rotation(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def main():
    out = pathlib.Path(sys.argv[1]) if len(sys.argv) > 1 else pathlib.Path(__file__).with_name("bent-fluid.data")
    rng = np.random.default_rng(SEED)
    half = ANGLE / 2
    shape = [(1, np.zeros(3)), (2, BOND * np.array([np.sin(half), np.cos(half), 0.0])),
             (2, BOND * np.array([-np.sin(half), np.cos(half), 0.0]))]
    side = N_SIDE * SPACING
    atoms, velocities = [], []
    sigma = np.zeros((3, 3))  # by atom type, 1-based
    for (a, b), value in SIGMA.items():
        sigma[a, b] = sigma[b, a] = value
    site_types = np.array([t for t, _ in shape])
    placed, placed_types = np.zeros((0, 3)), np.zeros(0, dtype=int)
    for i in range(N_SIDE ** 3):
        corner = SPACING * np.array([i % N_SIDE, (i // N_SIDE) % N_SIDE, i // N_SIDE ** 2]) + 0.5
        for attempt in range(1000):
            q = rng.normal(size=4)
            r = rotation(q / np.linalg.norm(q))
            sites = np.array([corner + r @ rho for _, rho in shape])
            d = placed[None, :, :] - sites[:, None, :]
            d -= side * np.round(d / side)
            dist = np.linalg.norm(d, axis=2)
            limit = sigma[site_types[:, None], placed_types[None, :]]
            if not (dist < limit).any():
                break
        else:
            sys.exit(f"molecule {i + 1}: no attitude of 1000 keeps its sites a sigma from the others; lower the density")
        placed = np.vstack([placed, sites])
        placed_types = np.concatenate([placed_types, site_types])
        for (atom_type, _), x in zip(shape, sites):
            image = np.floor(x / side).astype(int)
            atoms.append((i + 1, atom_type, x - image * side, image))
            velocities.append(rng.normal(scale=np.sqrt(KT / MASSES[atom_type]), size=3))
    lines = ["LAMMPS data: 1000 rigid bent triatomic molecules (scenarios/data/make_bent_fluid.py)", "",
             f"{len(atoms)} atoms", "2 atom types", "",
             f"0.0 {side!r} xlo xhi", f"0.0 {side!r} ylo yhi", f"0.0 {side!r} zlo zhi", "",
             "Masses", ""] + [f"{t} {m!r}" for t, m in MASSES.items()] + ["", "Atoms # molecular", ""]
    lines += [f"{k + 1} {mol} {t} {x[0]:.12f} {x[1]:.12f} {x[2]:.12f} {n[0]} {n[1]} {n[2]}"
              for k, (mol, t, x, n) in enumerate(atoms)]
    lines += ["", "Velocities", ""]
    lines += [f"{k + 1} {v[0]:.12f} {v[1]:.12f} {v[2]:.12f}" for k, v in enumerate(velocities)]
    out.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
