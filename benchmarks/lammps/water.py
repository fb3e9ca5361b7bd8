#!/usr/bin/python3
"""A LAMMPS data file of rigid SPC/E water (Berendsen, Grigera & Straatsma 1987: O-H 1 Angstrom, H-O-H 109.47
degrees, charges -0.8476 and +0.4238 e, O-O Lennard-Jones epsilon 0.1553 kcal/mol, sigma 3.166 Angstrom) for
in.water (LAMMPS `units real`, atom_style full: each molecule's two bonds and one angle, so that
special_bonds excludes the intramolecular pairs, Ewald/PPPM part included):

    /usr/bin/python3 benchmarks/lammps/water.py OUT.data [--side 10] [--density 0.997] [--seed 1]

side^3 molecules on a cubic lattice filling a periodic cube at the density (g/cm^3), each turned by a random
rotation drawn until no atom comes within 1.9 Angstrom of another molecule's atom. No velocities: in.water
draws them (velocity create, loop geom: the same for any rank count).
"""
import argparse
import pathlib

import numpy as np

from lgvi.plot import rotation_matrix  # R = pi(q), q scalar-first

MASS_O, MASS_H = 15.9994, 1.008
CHARGE_O, CHARGE_H = -0.8476, 0.4238
AVOGADRO = 6.02214076e23


def molecule():
    """The three atoms (O, H, H) relative to the centre of mass, Angstrom."""
    half = np.radians(109.47) / 2
    atoms = np.array([[0.0, 0.0, 0.0], [np.sin(half), np.cos(half), 0.0], [-np.sin(half), np.cos(half), 0.0]])
    masses = np.array([MASS_O, MASS_H, MASS_H])
    return atoms - masses @ atoms / masses.sum()


def random_rotation(rng):
    """A uniformly random rotation: pi(q) of a normal 4-vector normalised."""
    q = rng.normal(size=4)
    return rotation_matrix(q / np.linalg.norm(q))


def place(side, length, rng, closest=1.9):
    """The molecules' atoms (side^3 arrays of 3 x 3), each turned until it keeps `closest` from the atoms of
    the molecules placed before it within two lattice spacings (periodic distances)."""
    spacing = length / side
    body = molecule()
    centres, placed = [], []
    for i in range(side):
        for j in range(side):
            for k in range(side):
                centre = (np.array([i, j, k]) + 0.5) * spacing
                near = []
                if centres:
                    d = np.array(centres) - centre
                    d -= length * np.round(d / length)
                    near = [placed[n] for n in np.flatnonzero((d ** 2).sum(axis=1) < (2 * spacing) ** 2)]
                for _ in range(1000):
                    atoms = centre + body @ random_rotation(rng).T
                    if not near:
                        break
                    d = atoms[None, :, None, :] - np.array(near)[:, None, :, :]
                    d -= length * np.round(d / length)
                    if (d ** 2).sum(axis=3).min() >= closest ** 2:
                        break
                else:
                    raise SystemExit("water.py: no orientation without overlap; lower --density")
                centres.append(centre)
                placed.append(atoms)
    return placed


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", type=pathlib.Path)
    parser.add_argument("--side", type=int, default=10)
    parser.add_argument("--density", type=float, default=0.997)
    parser.add_argument("--seed", type=int, default=1)
    a = parser.parse_args()
    n = a.side ** 3
    grams = n * (MASS_O + 2 * MASS_H) / AVOGADRO
    length = (grams / a.density * 1e24) ** (1 / 3)  # cm^3 -> Angstrom^3
    molecules = place(a.side, length, np.random.default_rng(a.seed))
    lines = [f"SPC/E water, {n} rigid molecules at {a.density} g/cm^3 (benchmarks/lammps/water.py)", "",
             f"{3 * n} atoms", f"{2 * n} bonds", f"{n} angles", "2 atom types", "1 bond types", "1 angle types", "",
             f"0.0 {length!r} xlo xhi", f"0.0 {length!r} ylo yhi", f"0.0 {length!r} zlo zhi", "",
             "Masses", "", f"1 {MASS_O}", f"2 {MASS_H}", "", "Atoms # full", ""]
    for m, atoms in enumerate(molecules):
        for a_index, (kind, charge) in enumerate(((1, CHARGE_O), (2, CHARGE_H), (2, CHARGE_H))):
            x = atoms[a_index] % length
            image = np.floor_divide(atoms[a_index], length).astype(int)
            lines.append(f"{3 * m + a_index + 1} {m + 1} {kind} {charge} {x[0]!r} {x[1]!r} {x[2]!r} "
                         f"{image[0]} {image[1]} {image[2]}")
    lines += ["", "Bonds", ""]
    for m in range(n):
        lines += [f"{2 * m + 1} 1 {3 * m + 1} {3 * m + 2}", f"{2 * m + 2} 1 {3 * m + 1} {3 * m + 3}"]
    lines += ["", "Angles", ""]
    lines += [f"{m + 1} 1 {3 * m + 2} {3 * m + 1} {3 * m + 3}" for m in range(n)]
    a.out.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
