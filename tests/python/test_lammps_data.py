"""[import] lammps_data: a LAMMPS data file's molecules as rigid bodies
(src/app/lammps_data.hpp). The references are independent of lgvi's reader: the
centre of mass, inertia and rigid projection of the velocities computed here
with numpy from the atoms, lgvi's own [[bodies]] run of the same state, and
LAMMPS (fix rigid/nve/small) reading the same file. Run by ctest with
LGVI_BINARY set."""
import json
import os
import pathlib
import shutil
import subprocess

import numpy as np
import pytest

BINARY = os.environ.get("LGVI_BINARY")
SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
LAMMPS = shutil.which("lmp")
pytestmark = pytest.mark.skipif(BINARY is None, reason="LGVI_BINARY not set (run through ctest)")

LJ = """
[interaction]
kind = "lennard-jones"
epsilon = 1.0
sigma = 1.0
cutoff = 2.5

[potential]
kind = "none"

[integrator]
method = "lgvi"
step = 0.002
duration = {duration}

[output]
every = {every}
"""


def run(*args):
    return subprocess.run([BINARY, "run", *map(str, args), "--no-figures", "-q", "--force"], capture_output=True,
                          text=True)


def scenario(tmp_path, data, duration=0.0, every=1, extra=""):
    path = tmp_path / "imported.toml"
    path.write_text(f'[import]\nlammps_data = "{data}"\n{extra}\n' + LJ.format(duration=duration, every=every))
    return path


# A periodic box of side 12 holding molecules of two atom types (masses 1 and
# 3): triangles, a non-planar four-atom molecule, one molecule whose atoms
# lie on both sides of the x faces (image flags 0 and -1), the atoms given in
# shuffled order with non-rigid velocities (their rigid projection is what
# both codes start from).
LOWER, UPPER = -1.0, 11.0


def random_rotation(rng):
    """The rotation matrix of a uniformly drawn unit quaternion."""
    q = rng.normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def lattice_places():
    """(molecule ID from 1, corner) of the 14 even places (i + j + k even) of a 3 x 3 x 3 lattice of spacing 4."""
    places = [(i, j, k) for i in range(3) for j in range(3) for k in range(3) if (i + j + k) % 2 == 0]
    return [(mol, np.array(p) * 4.0 + 0.6) for mol, p in enumerate(places, start=1)]


def mixed_molecules(seed=3):
    rng = np.random.default_rng(seed)
    shapes = [np.array([[0, 0, 0], [1, 0, 0], [0.5, 0.866, 0]]),
              np.array([[0, 0, 0], [1.1, 0, 0], [0, 1.05, 0], [0.2, 0.3, 0.95]])]
    atoms = []  # (molecule, type, unwrapped position)
    for mol, corner in lattice_places():
        shape = shapes[mol % 2]
        r = random_rotation(rng)
        if mol == 1:
            corner = np.array([LOWER + 0.3, 5.0, 5.0])  # straddles the x faces
        for a, rho in enumerate(shape):
            atoms.append((mol, 1 + (a + mol) % 2, corner + r @ rho))
    n = len(atoms)
    velocities = rng.normal(scale=0.7, size=(n, 3))
    return atoms, velocities


def write_data(path, atoms, velocities, style="molecular", masses=(1.0, 3.0), extra_header="", other_sections=True,
               ids=None):
    """The data file; other_sections: with a bond and Pair Coeffs, which lgvi skips (LAMMPS needs their styles
    defined first); ids: the atoms' IDs (default 1, 2, ... in the order of `atoms`)."""
    ids = np.arange(1, len(atoms) + 1) if ids is None else ids
    length = UPPER - LOWER
    order = np.random.default_rng(7).permutation(len(atoms))  # atom IDs in file order: shuffled
    bonds = ["1 bonds", "1 bond types"] if other_sections else ["", ""]
    lines = ["test data file", "", f"{len(atoms)} atoms", f"{len(masses)} atom types", *bonds, extra_header]
    lines += [f"{LOWER!r} {UPPER!r} {c}lo {c}hi" for c in "xyz"]
    lines += ["", "Masses", ""] + [f"{t + 1} {m!r}" for t, m in enumerate(masses)]
    if other_sections:
        lines += ["", "Pair Coeffs # lj/cut", ""] + [f"{t + 1} 1.0 1.0" for t in range(len(masses))]
    lines += ["", f"Atoms # {style}", ""]
    for i in order:
        mol, typ, x = atoms[i]
        image = np.floor((x - LOWER) / length).astype(int)
        wrapped = x - image * length
        charge = " 0.0" if style == "full" else ""
        lines.append(f"{ids[i]} {mol} {typ}{charge} {wrapped[0]!r} {wrapped[1]!r} {wrapped[2]!r} "
                     f"{image[0]} {image[1]} {image[2]}")
    lines += ["", "Velocities", ""] + [f"{ids[i]} {v[0]!r} {v[1]!r} {v[2]!r}" for i, v in enumerate(velocities)]
    if other_sections:
        lines += ["", "Bonds", "", "1 1 1 2", ""]
    path.write_text("\n".join(lines) + "\n")
    return path


def rigid_reference(atoms, velocities, masses=(1.0, 3.0)):
    """Per molecule, in increasing ID: mass, centre of mass, inertia about it, momentum, angular momentum."""
    out = []
    for mol in sorted({a[0] for a in atoms}):
        idx = [i for i, a in enumerate(atoms) if a[0] == mol]
        m = np.array([masses[atoms[i][1] - 1] for i in idx])
        x = np.array([atoms[i][2] for i in idx])
        v = velocities[idx]
        centre = m @ x / m.sum()
        r = x - centre
        inertia = sum(mi * (ri @ ri * np.eye(3) - np.outer(ri, ri)) for mi, ri in zip(m, r))
        out.append((m.sum(), centre, inertia, m @ v, sum(mi * np.cross(ri, vi) for mi, ri, vi in zip(m, r, v))))
    return out


@pytest.mark.parametrize("style", ["molecular", "full"])
def test_the_bodies_are_the_molecules_rigid_projection(tmp_path, style):
    atoms, velocities = mixed_molecules()
    data = write_data(tmp_path / "mixed.data", atoms, velocities, style=style)
    proc = run(scenario(tmp_path, data.name), "--out", tmp_path / "run")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    rows = np.loadtxt(tmp_path / "run" / "trajectory.csv", delimiter=",", skiprows=1, ndmin=2)
    reference = rigid_reference(atoms, velocities)
    assert len(summary["setup"]["bodies"]) == len(reference) == len(rows)
    assert summary["setup"]["box"]["lower"] == [LOWER] * 3 and summary["setup"]["box"]["periodic"] == [True] * 3
    from lgvi.plot import rotation_matrix
    for body, row, (mass, centre, inertia, p, l) in zip(summary["setup"]["bodies"], rows, reference):
        # Sums of a few products of O(1) numbers, and a 3 x 3 eigen-decomposition: equal to round-off
        # (the file's 17 digits round-trip every coordinate; the wrapped coordinate plus image * 12
        # rounds once, ~1e-15).
        assert body["mass"] == pytest.approx(mass, rel=1e-15)
        j = np.array(body["inertia"])
        # The body axes are principal (J diagonal to round-off: 8 eps of the largest moment is
        # what the splitting methods accept), and R J R^T is the inertia in the space axes.
        assert np.abs(j - np.diag(np.diag(j))).max() <= 8 * 2.2e-16 * np.diag(j).max()
        r = rotation_matrix(row[5:9])
        assert np.allclose(r @ j @ r.T, inertia, rtol=0, atol=1e-13)
        assert abs(np.linalg.det(r) - 1.0) < 1e-14  # right-handed
        # The written centre of mass is wrapped into the box; its image count restores it.
        assert np.allclose(row[2:5], centre - np.floor((centre - LOWER) / (UPPER - LOWER)) * (UPPER - LOWER),
                           rtol=0, atol=1e-13)
        assert np.allclose(row[9:12], p, rtol=0, atol=1e-13)
        assert np.allclose(r @ row[12:15], 2.0 * l, rtol=0, atol=1e-13)  # w = 2 J Omega = 2 R^T L


def test_an_imported_gas_moves_as_the_scenario_it_was_written_from(tmp_path):
    # benchmarks/lammps/compare_lammps.py writes the periodic gas's initial state as a LAMMPS data file (atoms at
    # x + R rho, velocities V + omega x R rho). Imported, each molecule is the same body in its principal axes as
    # LAMMPS picks them, other than the scenario's: the same method in another frame (the LGVI does not depend on
    # the body axes), so the centres of mass agree to round-off growth.
    import sys
    sys.path.insert(0, str(SOURCE / "benchmarks" / "lammps"))
    import compare_lammps
    data = compare_lammps.lammps_data(BINARY, tmp_path, periodic=True)
    original = tmp_path / "original.toml"
    original.write_text(compare_lammps.scenario_text(100, 0.002, 100, periodic=True))
    assert run(original, "--out", tmp_path / "original").returncode == 0
    proc = run(scenario(tmp_path, data.name, duration=0.2, every=100), "--out", tmp_path / "imported")
    assert proc.returncode == 0, proc.stderr
    a = np.loadtxt(tmp_path / "original" / "trajectory.csv", delimiter=",", skiprows=1)
    b = np.loadtxt(tmp_path / "imported" / "trajectory.csv", delimiter=",", skiprows=1)
    assert a.shape == b.shape == (2000, 28)
    # 100 steps of a chaotic gas from states equal to ~1e-15: measured 7e-15 in x, 6e-14 in p.
    assert np.abs(a[:, 2:5] - b[:, 2:5]).max() <= 1e-10 * 22.0
    assert np.abs(a[:, 9:12] - b[:, 9:12]).max() <= 1e-10
    # Energies: the same sums in other axes, ~1e-14 relative.
    assert np.abs(a[:, 16] - b[:, 16]).max() <= 1e-12 * np.abs(a[:, 16]).max()


# Per pair of atom types, lgvi's [[interaction.pair]] tables and LAMMPS's pair_coeff commands for the same
# coefficients: type 1 (eps 1, sigma 1), type 2 (eps 1.7, sigma 1.2), the pair (1, 2) mixed geometrically
# (LAMMPS's default for lj/cut), arithmetically, or given.
TYPES = {
    "one": ("", None),
    "geometric": ('mixing = "geometric"', "pair_modify mix geometric"),
    "arithmetic": ('mixing = "arithmetic"', "pair_modify mix arithmetic"),
    "explicit": ("[[interaction.pair]]\ntypes = [2, 1]\nepsilon = 0.45\nsigma = 1.33",
                 "pair_coeff 1 2 0.45 1.33"),
}


def typed_scenario(tmp_path, data, case):
    lgvi_extra, _ = TYPES[case]
    if case == "one":
        return scenario(tmp_path, data)
    text = scenario(tmp_path, data).read_text()
    text = text.replace("epsilon = 1.0\nsigma = 1.0\n", lgvi_extra.split("[[")[0] + "\n")
    text += ("\n[[interaction.pair]]\ntypes = [1, 1]\nepsilon = 1.0\nsigma = 1.0\n"
             "\n[[interaction.pair]]\ntypes = [2, 2]\nepsilon = 1.7\nsigma = 1.2\n")
    if case == "explicit":
        text += "\n" + lgvi_extra + "\n"
    path = tmp_path / "typed.toml"
    path.write_text(text)
    return path


def expect_lammps_start(tmp_path, data, run_dir, coeffs=None):
    """lgvi's step 0 (the summary and trajectory in run_dir) against LAMMPS reading `data`
    (benchmarks/lammps/in.lj-triangles-thermo: fix rigid/nve/small, the rigid projection of the velocities at
    set-up; `coeffs`: pair_coeff commands per pair of types, else one pair_coeff for all): the potential and
    kinetic energy, the temperature and the pressure of the rigid molecules to 1e-10 relative (sums of the same
    terms in other orders, ~1e-15, and the sites' places rounded through the principal axes). Returns pe."""
    import re
    extra = []
    if coeffs is not None:
        (tmp_path / "coeffs.lammps").write_text(coeffs)
        extra = ["-var", "typed", "1", "-var", "coeffs", str(tmp_path / "coeffs.lammps")]
    out = subprocess.run([LAMMPS, "-in", str(SOURCE / "benchmarks" / "lammps" / "in.lj-triangles-thermo"), "-log",
                          "none", "-screen", "none", "-var", "data", str(data), "-var", "log",
                          str(tmp_path / "thermo.log"), *extra], capture_output=True, text=True, cwd=tmp_path,
                         timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr
    row = re.search(r"^\s*0\s+(\S+)\s+(\S+)\s+(\S+)\s+(\S+)\s+(\S+)\s*$", (tmp_path / "thermo.log").read_text(),
                    re.M)
    pe, ke, temp, pressure, _ = (float(v) for v in row.groups())
    summary = json.loads((run_dir / "summary.json").read_text())
    rows = np.loadtxt(run_dir / "trajectory.csv", delimiter=",", skiprows=1, ndmin=2)
    # (pinv: J's pseudo-inverse for linear molecules and single atoms, which have zero moments)
    kinetic = sum(r[9:12] @ r[9:12] / (2 * b["mass"]) + r[12:15] @ np.linalg.pinv(b["inertia"]) @ r[12:15] / 8
                  for r, b in zip(rows, summary["setup"]["bodies"]))
    thermo = summary["thermodynamics"]
    assert summary["initial_energy"] - kinetic == pytest.approx(pe, rel=1e-10)
    assert kinetic == pytest.approx(ke, rel=1e-10)
    assert thermo["temperature"]["initial"] == pytest.approx(temp, rel=1e-10)
    assert thermo["pressure"]["initial"] == pytest.approx(pressure, rel=1e-10)
    return pe


@pytest.mark.skipif(LAMMPS is None, reason="LAMMPS (lmp, Debian's lammps package) is not installed")
@pytest.mark.parametrize("case", sorted(TYPES))
def test_the_imported_start_equals_lammps(tmp_path, case):
    # The same data file in LAMMPS, with the pair coefficients of each case.
    atoms, velocities = mixed_molecules()
    data = write_data(tmp_path / "mixed.data", atoms, velocities, other_sections=False)
    proc = run(typed_scenario(tmp_path, data.name, case), "--out", tmp_path / "run")
    assert proc.returncode == 0, proc.stderr
    coeffs = None if case == "one" else "pair_coeff 1 1 1.0 1.0\npair_coeff 2 2 1.7 1.2\n" + TYPES[case][1] + "\n"
    pe = expect_lammps_start(tmp_path, data, tmp_path / "run", coeffs)
    assert abs(pe) > 0.1  # molecules within reach of each other: a potential energy to compare
    if case != "one":  # the pairs as the summary states them: (1, 2) mixed or given
        summary = json.loads((tmp_path / "run" / "summary.json").read_text())
        pairs = {tuple(p["types"]): p for p in summary["setup"]["interaction"]["pairs"]}
        assert sorted(pairs) == [(1, 1), (1, 2), (2, 2)]
        mixed = {"geometric": (1.7**0.5, 1.2**0.5), "arithmetic": (1.7**0.5, 1.1), "explicit": (0.45, 1.33)}[case]
        assert pairs[(1, 2)]["epsilon"] == pytest.approx(mixed[0], rel=1e-15)
        assert pairs[(1, 2)]["sigma"] == pytest.approx(mixed[1], rel=1e-15)
        assert pairs[(1, 2)]["mixed"] == (case != "explicit")


def test_balls_make_linear_molecules_and_single_atoms_rigid_bodies(tmp_path):
    # With [import] radius each atom is a uniform ball: a two-atom molecule and an atom of molecule 0 get the
    # inertia 2/5 m r^2 of their balls (the 2-atom molecule's moment about its axis), checked against numpy.
    atoms = [(1, 1, np.array([1.0, 1.0, 1.0])), (1, 2, np.array([2.2, 1.0, 1.0])), (0, 1, np.array([6.0, 6.0, 6.0]))]
    velocities = np.array([[0.1, 0.0, 0.0], [0.0, 0.3, 0.0], [0.0, 0.0, -0.2]])
    data = write_data(tmp_path / "small.data", atoms, velocities)
    proc = run(scenario(tmp_path, data.name, extra="radius = [0.5, 0.25]"), "--out", tmp_path / "balls")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "balls" / "summary.json").read_text())
    rows = np.loadtxt(tmp_path / "balls" / "trajectory.csv", delimiter=",", skiprows=1, ndmin=2)
    (two, single) = summary["setup"]["bodies"]
    assert [b["name"] for b in summary["final_bodies"]] == ["mol1", "atom3"]
    assert "rotational_dof" not in two and "rotational_dof" not in single  # three moments each
    c = (1.0 * 1.0 + 3.0 * 2.2) / 4.0
    axial = 0.4 * (1.0 * 0.5**2 + 3.0 * 0.25**2)
    transverse = axial + 1.0 * (1.0 - c) ** 2 + 3.0 * (2.2 - c) ** 2
    # In principal axes (the eigenvalues ascending: the axial moment first).
    assert np.allclose(two["inertia"], np.diag([axial, transverse, transverse]), rtol=0, atol=1e-15 * transverse)
    assert np.allclose(single["inertia"], 0.4 * 1.0 * 0.25 * np.eye(3), rtol=1e-15, atol=0)
    assert np.allclose(rows[0, 9:12], [0.1, 0.9, 0.0], rtol=0, atol=1e-15)
    assert np.allclose(rows[1, 9:12], [0.0, 0.0, -0.2], rtol=0, atol=1e-15)


def linear_molecules(seed=5):
    """Bent triatomics, CO2-like linear triatomics (types 2-1-2) and N2-like rods on a lattice of side 12, and two
    atoms of molecule ID 0 between them, at least 4 apart (so that LAMMPS's molecule/intra exclusion, which would
    drop the pair of two molecule-0 atoms, does not matter); non-rigid velocities."""
    rng = np.random.default_rng(seed)
    shapes = [(np.array([[0, 0, 0], [1, 0, 0], [0.5, 0.866, 0]]), (1, 2, 1)),
              (np.array([[-1.16, 0, 0], [0, 0, 0], [1.16, 0, 0]]), (2, 1, 2)),
              (np.array([[0, 0, 0], [1.1, 0, 0]]), (1, 1))]
    atoms = []
    for mol, corner in lattice_places():
        shape, types = shapes[mol % 3]
        r = random_rotation(rng)
        for rho, t in zip(shape, types):
            atoms.append((mol, t, corner + r @ rho))
    atoms += [(0, 1, np.array([2.6, 0.6, 0.6])), (0, 2, np.array([2.6, 4.6, 4.6]))]
    return atoms, rng.normal(scale=0.7, size=(len(atoms), 3))


@pytest.mark.skipif(LAMMPS is None, reason="LAMMPS (lmp, Debian's lammps package) is not installed")
def test_linear_molecules_and_single_atoms_start_as_in_lammps(tmp_path):
    # Point masses on a line are a linear body (no moment about the line, two rotational degrees of freedom) and
    # a molecule-0 atom a point body (none), as fix rigid/small and fix nve take them: the bodies against numpy,
    # and step 0 (potential and kinetic energy, the temperature with 5 and 3 degrees of freedom for those, and
    # the pressure) against LAMMPS reading the same file, to 1e-10 relative.
    atoms, velocities = linear_molecules()
    data = write_data(tmp_path / "linear.data", atoms, velocities, other_sections=False)
    proc = run(scenario(tmp_path, data.name), "--out", tmp_path / "run")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    rows = np.loadtxt(tmp_path / "run" / "trajectory.csv", delimiter=",", skiprows=1, ndmin=2)
    bodies = summary["setup"]["bodies"]
    from lgvi.plot import rotation_matrix
    molecules = rigid_reference([a for a in atoms if a[0] > 0], velocities[:-2])
    assert len(bodies) == len(molecules) + 2
    for b, row, (mass, centre, inertia, p, l) in zip(bodies, rows, molecules):
        moments = np.linalg.eigvalsh(inertia)
        r = rotation_matrix(row[5:9])
        # The inertia in space axes and the momenta: sums of a few O(1) products and an eigen-decomposition.
        assert np.allclose(r @ np.array(b["inertia"]) @ r.T, inertia, rtol=0, atol=1e-13)
        assert np.allclose(row[9:12], p, rtol=0, atol=1e-13)
        assert np.allclose(r @ row[12:15], 2.0 * l, rtol=0, atol=1e-13)
        if moments[0] > 1e-7 * moments[2]:
            assert "rotational_dof" not in b
            continue
        # A linear molecule: J = I (1 - n n^T) exactly (its zero moment is zero), its axis along the atoms.
        assert b["rotational_dof"] == 2
        n = np.array(b["linear_axis"])
        assert np.allclose(np.array(b["inertia"]), moments[2] * (np.eye(3) - np.outer(n, n)), rtol=0,
                           atol=1e-14 * moments[2])
        assert abs(row[12:15] @ n) <= 1e-15 * np.linalg.norm(row[12:15])  # no momentum about the axis
    for b, row, (mol, _, x), v in zip(bodies[-2:], rows[-2:], atoms[-2:], velocities[-2:]):
        assert b["rotational_dof"] == 0 and np.all(np.array(b["inertia"]) == 0.0)
        assert np.all(row[12:15] == 0.0) and np.allclose(row[2:5], x, rtol=0, atol=1e-15)
    assert [b["name"] for b in summary["final_bodies"][-2:]] == [f"atom{len(atoms) - 1}", f"atom{len(atoms)}"]
    thermo = summary["thermodynamics"]
    linear = sum(1 for b in bodies if b.get("rotational_dof") == 2)
    assert linear == 10 and thermo["degrees_of_freedom"] == 6 * 4 + 5 * 10 + 3 * 2 - 3  # less the total momentum
    expect_lammps_start(tmp_path, data, tmp_path / "run")


def test_linear_molecules_run_in_the_lgvi_and_other_methods_refuse_them(tmp_path):
    # 0.4 time units of the fluid with linear molecules and single atoms: total momentum conserved to round-off
    # (the box is periodic: angular momentum is not conserved), |q| = 1 to round-off, a linear body's w stays
    # across its axis, and the energy error is second order (halving h divides it by 4, +-15%: the leading term
    # of a smooth 0.4-long run). Methods that need three moments refuse with one line naming the body and the
    # methods that take it.
    atoms, velocities = linear_molecules()
    data = write_data(tmp_path / "linear.data", atoms, velocities, other_sections=False)
    worst = []
    for h in (0.004, 0.002):
        text = scenario(tmp_path, data.name, duration=0.4, every=5).read_text().replace("step = 0.002", f"step = {h}")
        (tmp_path / "s.toml").write_text(text)
        proc = run(tmp_path / "s.toml", "--out", tmp_path / f"h{h}")
        assert proc.returncode == 0, proc.stderr
        summary = json.loads((tmp_path / f"h{h}" / "summary.json").read_text())
        rows = np.loadtxt(tmp_path / f"h{h}" / "trajectory.csv", delimiter=",", skiprows=1, ndmin=2)
        n = len(summary["setup"]["bodies"])
        frames = rows.reshape(-1, n, rows.shape[1])
        p = frames[:, :, 9:12].sum(axis=1)
        assert np.abs(p - p[0]).max() <= 1e-13 * np.abs(frames[0, :, 9:12]).sum()
        assert np.abs(np.linalg.norm(frames[:, :, 5:9], axis=2) - 1.0).max() <= 1e-14
        for a, b in enumerate(summary["setup"]["bodies"]):
            if b.get("rotational_dof") == 2:
                w = frames[:, a, 12:15]
                assert np.abs(w @ np.array(b["linear_axis"])).max() <= 1e-14 * np.abs(w).max()
        energy = frames[:, 0, 16]
        worst.append(np.abs(energy - energy[0]).max())
    assert worst[0] / worst[1] == pytest.approx(4.0, rel=0.15)
    text = scenario(tmp_path, data.name).read_text().replace('method = "lgvi"', 'method = "no-squish"')
    (tmp_path / "ns.toml").write_text(text)
    proc = run(tmp_path / "ns.toml", "--out", tmp_path / "ns")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert '"no-squish" needs three principal moments > 0; bodies[0] ("mol1") is a linear body' in proc.stderr
    assert "use lgvi or lgvi-lagrangian" in proc.stderr


def test_image_flags_along_an_open_axis_and_the_named_style(tmp_path):
    # An open axis has no images: a non-zero flag there is refused (LAMMPS resets it to 0 with a warning, which
    # would move the atom by a box length from where the file's unwrapped place says). Zero tilts are an
    # orthogonal box, and a leading '+' is a number, as in LAMMPS.
    atoms, velocities = mixed_molecules()
    atoms = [(m, t, x - [0.5, 0, 0] if m == 1 else x) for m, t, x in atoms]  # molecule 1 across the lower x face
    data = write_data(tmp_path / "mixed.data", atoms, velocities,
                      extra_header="+0.0 0.0 -0.0 xy xz yz")
    proc = run(scenario(tmp_path, data.name, extra="periodic = [false, true, true]"), "--out", tmp_path / "open")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert "has image flag -1 along x, which [import] periodic makes open" in proc.stderr
    assert run(scenario(tmp_path, data.name), "--out", tmp_path / "periodic").returncode == 0
    # A style given twice must agree; given once in the scenario, it is read so.
    proc = run(scenario(tmp_path, data.name, extra='atom_style = "full"'), "--out", tmp_path / "both")
    assert proc.returncode == 2 and "is of atom_style molecular, [import] atom_style says full" in proc.stderr
    data.write_text(data.read_text().replace("Atoms # molecular", "Atoms"))
    proc = run(scenario(tmp_path, data.name, extra='atom_style = "molecular"'), "--out", tmp_path / "named")
    assert proc.returncode == 0, proc.stderr


def test_an_ensemble_reads_the_data_file_beside_its_scenario(tmp_path, monkeypatch):
    # The base scenario's [import] is relative to it, wherever lgvi ensemble runs from: the members run the base's
    # run copy (absolute path and checksum).
    atoms, velocities = mixed_molecules()
    (tmp_path / "case").mkdir()
    data = write_data(tmp_path / "case" / "mixed.data", atoms, velocities)
    scenario(tmp_path / "case", data.name, duration=0.004, every=1)
    (tmp_path / "sweep.toml").write_text('[ensemble]\nscenario = "case/imported.toml"\n\n'
                                         '[[vary]]\nkey = "integrator.step"\nvalues = [0.001, 0.002]\n')
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    binary = os.path.abspath(BINARY)
    monkeypatch.chdir(elsewhere)
    proc = subprocess.run([binary, "ensemble", str(tmp_path / "sweep.toml"), "--out", str(tmp_path / "ens"), "-q",
                           "--threads", "1"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    copy = (tmp_path / "ens" / "scenario.toml").read_text()
    assert f'lammps_data = "{data}"' in copy and 'checksum = "' in copy


def test_the_run_copy_refuses_a_changed_data_file(tmp_path):
    atoms, velocities = mixed_molecules()
    data = write_data(tmp_path / "mixed.data", atoms, velocities)
    assert run(scenario(tmp_path, data.name), "--out", tmp_path / "run").returncode == 0
    copy = (tmp_path / "run" / "scenario.toml").read_text()
    assert f'lammps_data = "{data}"' in copy and 'checksum = "' in copy  # absolute: the copy runs from anywhere
    assert run(tmp_path / "run" / "scenario.toml", "--out", tmp_path / "again").returncode == 0
    data.write_text(data.read_text().replace("Velocities", "Velocities # changed"))
    proc = run(tmp_path / "run" / "scenario.toml", "--out", tmp_path / "changed")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert "import.checksum" in proc.stderr and "is not the one this run began with" in proc.stderr
    # Changed so that it no longer parses: still the checksum's reason, not the parse error.
    data.write_text(data.read_text().replace("Velocities", "Velocitiez"))
    proc = run(tmp_path / "run" / "scenario.toml", "--out", tmp_path / "broken")
    assert proc.returncode == 2 and "import.checksum" in proc.stderr, proc.stderr


def fnv1a(data):
    """FNV-1a, 64 bits, of bytes: the checksum as its definition gives it (independent of lgvi's reader)."""
    h = 0xcbf29ce484222325
    for b in data:
        h = ((h ^ b) * 0x100000001b3) % 2**64
    return f"{h:016x}"


@pytest.mark.parametrize("ending", ["lf", "crlf", "no final newline"])
def test_the_checksum_is_fnv1a_of_the_files_bytes(tmp_path, ending):
    # The reader checksums the bytes as it parses them (one read of the file): CRLF line ends and a last
    # line without its newline included, exactly as the bytes are.
    atoms, velocities = mixed_molecules()
    data = write_data(tmp_path / "mixed.data", atoms, velocities)
    raw = data.read_bytes()
    if ending == "crlf":
        raw = raw.replace(b"\n", b"\r\n")
    elif ending == "no final newline":
        raw = raw.rstrip(b"\n")
    data.write_bytes(raw)
    assert run(scenario(tmp_path, data.name), "--out", tmp_path / "run").returncode == 0
    copy = (tmp_path / "run" / "scenario.toml").read_text()
    assert f'checksum = "{fnv1a(raw)}"' in copy


BAD = {
    # name: (how the file is changed, the message's expected part); the header's lines are numbered as
    # write_data writes them (title 1, blank 2, counts 3-6, extra_header 7, box 8-10, Masses 12, its rows 14-15).
    "count": (lambda t: t.replace("\n49 atoms", "\n50 atoms"),
              r"mixed.data:[0-9]+: the Atoms section has 49 lines before \"Velocities\"; the header says 50 atoms"),
    "no-atoms": (lambda t: t[:t.index("Atoms #")], r"mixed.data: no Atoms section"),
    "zero-mass": (lambda t: t.replace("\n2 3.0\n", "\n2 0.0\n"),
                  r"mixed.data:15: the mass of atom type 2 must be > 0, got 0"),
    "no-mass": (lambda t: t.replace("\n2 3.0\n", "\n"),
                r"mixed.data:[0-9]+: the Masses section has 1 lines before \"Pair Coeffs\"; the header says 2 atom "
                r"types"),
    "triclinic": (lambda t: t.replace("1 bond types\n", "1 bond types\n0.5 0.0 0.0 xy xz yz\n"),
                  r"mixed.data:7: a triclinic box \(xy xz yz not all 0\) is not supported yet"),
    # What LAMMPS's read_data refuses too ("Unknown identifier in data file"), not skipped:
    "header-typo": (lambda t: t.replace("2 atom types", "2 atomtypes"),
                    r"mixed.data:4: not a header line of a LAMMPS data file .*\"2 atomtypes\""),
    "box-numbers": (lambda t: t.replace("-1.0 11.0 ylo yhi", "11.0 ylo yhi"),
                    r"mixed.data:9: not a header line of a LAMMPS data file .*\"11.0 ylo yhi\""),
    "section-typo": (lambda t: t.replace("Velocities", "Velocity"),
                     r"mixed.data:[0-9]+: \"Velocity\" is not a section of a LAMMPS data file"),
    # The style is named, never guessed from the column count.
    "no-style": (lambda t: t.replace("Atoms # molecular", "Atoms"),
                 r"mixed.data:[0-9]+: the Atoms section names no atom_style .*\[import\] atom_style"),
    "style": (lambda t: t.replace("Atoms # molecular", "Atoms # atomic"), r"atom_style atomic has no molecule IDs"),
    "type": (lambda t: t.replace("Atoms # molecular\n\n", "Atoms # molecular\n\n1000 1 7 0.0 0.0 0.0 0 0 0\n"),
             r"mixed.data:[0-9]+: atom type 7 is not in 1..2"),
    "number": (lambda t: t.replace("Velocities\n\n", "Velocities\n\n1 0.1x 0.0 0.0\n"),
               r"mixed.data:[0-9]+: a velocity must be a finite number, got \"0.1x\""),
    "unknown-velocity": (lambda t: t.replace("Velocities\n\n", "Velocities\n\n99 0.1 0.0 0.0\n"),
                         r"atom ID 99 is not in the Atoms section"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_a_malformed_data_file_gets_one_line_naming_the_file_and_line(tmp_path, case):
    import re
    atoms, velocities = mixed_molecules()
    data = write_data(tmp_path / "mixed.data", atoms, velocities)
    change, expected = BAD[case]
    data.write_text(change(data.read_text()))
    proc = run(scenario(tmp_path, data.name), "--out", tmp_path / "run")
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1, proc.stderr
    assert re.search(expected, proc.stderr), proc.stderr
    assert not (tmp_path / "run" / "summary.json").exists()


def test_python_builds_the_same_scenario_and_typed_balls(tmp_path):
    # lgvi.Scenario.from_lammps_data writes the same [import] the CLI reads: the run is bit-identical to
    # `lgvi run` of the file (the same compiled run loop); typed balls from Python reach the summary.
    # (The sanitized run's package is the source tree's, without the compiled module.)
    pytest.importorskip("lgvi._core")
    import lgvi
    atoms, velocities = mixed_molecules()
    data = write_data(tmp_path / "mixed.data", atoms, velocities)
    interaction = {"kind": "lennard-jones", "cutoff": 2.5, "mixing": "arithmetic",
                   "pair": [{"types": (1, 1), "epsilon": 1.0, "sigma": 1.0},
                            {"types": (2, 2), "epsilon": 1.7, "sigma": 1.2}]}
    sc = lgvi.Scenario.from_lammps_data(data, interaction=interaction, step=0.002, duration=0.02, every=5)
    result = lgvi.simulate(sc)
    text = scenario(tmp_path, data.name, duration=0.02, every=5).read_text().replace(
        "epsilon = 1.0\nsigma = 1.0\n", 'mixing = "arithmetic"\n')
    text += ("\n[[interaction.pair]]\ntypes = [1, 1]\nepsilon = 1.0\nsigma = 1.0\n"
             "\n[[interaction.pair]]\ntypes = [2, 2]\nepsilon = 1.7\nsigma = 1.2\n")
    (tmp_path / "file.toml").write_text(text)
    assert run(tmp_path / "file.toml", "--out", tmp_path / "cli").returncode == 0
    rows = np.loadtxt(tmp_path / "cli" / "trajectory.csv", delimiter=",", skiprows=1)
    assert result.x.shape == (3, 14, 3)  # t = 0, 5h, 10h
    assert np.array_equal(result.x.reshape(-1, 3), rows[:, 2:5])
    assert np.array_equal(result.w.reshape(-1, 3), rows[:, 12:15])
    with pytest.raises(ValueError, match=r"mixed.data:[0-9]+: the mass of atom type 2 must be > 0"):
        data.write_text(data.read_text().replace("\n2 3.0\n", "\n2 0.0\n"))
        lgvi.Scenario.from_lammps_data(data, interaction=interaction, step=0.002, duration=0.02)
    body = lgvi.Body(balls=[((0, 0, 0), 1.0, 0.0, 2), {"position": (1, 0, 0), "mass": 1.0, "radius": 0.0},
                            ((0, 1, 0), 1.0, 0.0)])
    assert [b["type"] for b in body.balls] == [2, 1, 1]
    with pytest.raises(ValueError, match=r"balls\[0\]\.type"):
        lgvi.Body(balls=[((0, 0, 0), 1.0, 0.0, 0)])


def test_the_bent_fluid_data_file_is_its_generators_output(tmp_path):
    # scenarios/data/bent-fluid.data is what make_bent_fluid.py writes (deterministic: PCG64, seed 5).
    subprocess.run([os.environ.get("LGVI_PYTHON", "/usr/bin/python3"),
                    str(SOURCE / "scenarios" / "data" / "make_bent_fluid.py"), str(tmp_path / "bent.data")], check=True)
    assert (tmp_path / "bent.data").read_bytes() == (SOURCE / "scenarios" / "data" / "bent-fluid.data").read_bytes()


def test_the_bent_fluid_scenario_runs_with_its_conservation_laws(tmp_path):
    # 200 steps of scenarios/bent-fluid.toml: the total linear momentum is conserved to round-off (each pair's
    # forces cancel exactly, in the periodic box too: ~1e-16 of sum |p_a|), |q| stays 1 to round-off without
    # normalization, and the energy error is bounded by the method's O(h^2) (measured 0.12 of E0 = 1867 here).
    text = (SOURCE / "scenarios" / "bent-fluid.toml").read_text()
    text = text.replace('lammps_data = "data/', f'lammps_data = "{SOURCE / "scenarios" / "data"}/')
    text = text.replace("duration = 20.0", "duration = 0.4").replace("every = 100", "every = 50")
    (tmp_path / "bent.toml").write_text(text)
    proc = run(tmp_path / "bent.toml", "--out", tmp_path / "run")
    assert proc.returncode == 0, proc.stderr
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert len(s["setup"]["bodies"]) == 1000
    assert s["max_linear_momentum_error"] < 1e-14
    assert s["max_abs_quat_norm_error"] < 1e-13
    assert s["max_abs_energy_error"] < 1e-3 * abs(s["initial_energy"])
    # The atoms' velocities were drawn at kT = 1.2; the rigid projection keeps the 6 rigid degrees of freedom of
    # each molecule's 9, each still holding kT/2 on average: T = 1.2 within its sampling error, sqrt(2 / 5997)
    # relative (1.8 %; 5 % is three of those).
    assert s["thermodynamics"]["temperature"]["initial"] == pytest.approx(1.2, rel=0.05)
    assert [p["mixed"] for p in s["setup"]["interaction"]["pairs"]] == [False, True, False]


@pytest.mark.skipif(LAMMPS is None, reason="LAMMPS (lmp, Debian's lammps package) is not installed")
def test_the_bent_fluid_starts_as_in_lammps(tmp_path):
    # scenarios/bent-fluid.toml's data file read by LAMMPS with the same coefficients (pair_coeff per type, mixed
    # geometrically): step-0 energies, temperature and pressure to 1e-10 relative, as above.
    text = (SOURCE / "scenarios" / "bent-fluid.toml").read_text()
    data = SOURCE / "scenarios" / "data" / "bent-fluid.data"
    text = text.replace('lammps_data = "data/bent-fluid.data"', f'lammps_data = "{data}"').replace(
        "duration = 20.0", "duration = 0.0").replace("every = 100", "every = 1")
    (tmp_path / "bent.toml").write_text(text)
    proc = run(tmp_path / "bent.toml", "--out", tmp_path / "run")
    assert proc.returncode == 0, proc.stderr
    expect_lammps_start(tmp_path, data, tmp_path / "run",
                        "pair_coeff 1 1 1.0 1.0\npair_coeff 2 2 0.3 0.7\npair_modify mix geometric\n")


def test_the_particle_exports_keep_the_atom_types(tmp_path):
    # The LAMMPS dump's type column and the extended XYZ's species are the data file's atom types, site by site (so
    # OVITO colours the sites by species), where a [[bodies]] scenario of one type numbers the radii instead (test_exports.py).
    atoms, velocities = mixed_molecules()
    data = write_data(tmp_path / "mixed.data", atoms, velocities)
    types = {}
    for mol, t, _ in atoms:
        types.setdefault(mol, []).append(t)
    for fmt, name in (("lammps-dump", "trajectory.lammpstrj"), ("xyz", "trajectory.xyz")):
        text = scenario(tmp_path, data.name).read_text().replace("[output]\n", f'[output]\nformat = "{fmt}"\n')
        (tmp_path / "s.toml").write_text(text)
        assert run(tmp_path / "s.toml", "--out", tmp_path / fmt).returncode == 0
        lines = (tmp_path / fmt / name).read_text().splitlines()
        if fmt == "lammps-dump":
            rows = [line.split() for line in lines[9:9 + int(lines[3])]]
            written = {}
            for row in rows:  # id mol type ...: mol is the body's place, here the molecule ID (1, 2, ... in order)
                written.setdefault(int(row[1]), []).append(int(row[2]))
        else:
            rows = [line.split() for line in lines[2:2 + int(lines[0])]]
            species = [r[0] for r in rows]
            assert set(species) == {"type1", "type2"}
            assert sorted(species) == sorted(f"type{t}" for _, t, _ in atoms)
            continue
        # Each molecule's sites in increasing atom ID (the IDs are the atoms' places in `atoms`).
        assert written == types


def test_the_lammps_dump_keeps_the_data_files_atom_and_molecule_ids(tmp_path):
    # The dump's id and mol columns are the data file's atom and molecule IDs, whatever their numbering (molecule 0
    # for free atoms, as in the file), so that an analysis of the dump meets the file's atoms: each atom's unwrapped
    # position at step 0 is the file's, to the round-off of turning each molecule into its principal axes and back
    # (a few ulps of coordinates below 13: 1e-12).
    atoms, velocities = mixed_molecules()
    atoms = [(7 * mol + 3, t, x) for mol, t, x in atoms]  # molecule IDs 10, 17, 24, ...
    atoms += [(0, 1, np.array([4.6, 0.6, 0.6])), (0, 2, np.array([0.6, 4.6, 0.6]))]  # two free atoms, at odd places
    velocities = np.vstack([velocities, [[0.1, 0.2, 0.3], [-0.3, 0.0, 0.1]]])
    ids = 5 + 3 * np.random.default_rng(11).permutation(len(atoms))  # atom IDs 5, 8, 11, ... in no order
    data = write_data(tmp_path / "ids.data", atoms, velocities, ids=ids)
    text = scenario(tmp_path, data.name).read_text().replace("[output]\n", '[output]\nformat = "lammps-dump"\n')
    (tmp_path / "s.toml").write_text(text)
    out = run(tmp_path / "s.toml", "--out", tmp_path / "dump")
    assert out.returncode == 0, out.stderr
    lines = (tmp_path / "dump" / "trajectory.lammpstrj").read_text().splitlines()
    assert lines[8] == "ITEM: ATOMS id mol type x y z ix iy iz"
    rows = [line.split() for line in lines[9:9 + int(lines[3])]]
    assert sorted(int(r[0]) for r in rows) == sorted(ids.tolist())
    by_id = {atom_id: atom for atom_id, atom in zip(ids.tolist(), atoms)}
    for r in rows:
        mol, typ, x = by_id[int(r[0])]
        assert (int(r[1]), int(r[2])) == (mol, typ)
        unwrapped = np.array([float(c) for c in r[3:6]]) + (UPPER - LOWER) * np.array([int(c) for c in r[6:9]])
        np.testing.assert_allclose(unwrapped, x, rtol=0, atol=1e-12)


def test_overlapping_molecules_are_named(tmp_path):
    # Two molecules of balls placed 0.05 apart: the start's overlap names both bodies by their molecule IDs.
    atoms, velocities = mixed_molecules()
    atoms = [(m, t, x) for m, t, x in atoms if m in (2, 3)]
    shift = atoms[0][2] - [a for a in atoms if a[0] == 3][0][2] + [0.0, 0.0, 0.05]
    atoms = [(m, t, x + shift if m == 3 else x) for m, t, x in atoms]
    data = write_data(tmp_path / "two.data", atoms, velocities[:len(atoms)])
    proc = run(scenario(tmp_path, data.name, extra="radius = 0.3"), "--out", tmp_path / "run")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert 'at the start' in proc.stderr and '("mol3" and "mol2")' in proc.stderr, proc.stderr


def test_from_string_reads_relative_paths_from_the_directory_given(tmp_path, monkeypatch):
    """Scenario.from_string(text, name, directory): the data file named by a relative path is read from
    `directory`, as a scenario file's are from its folder; without it, from the current directory (here
    another folder, where the file is not: the reader's error names the key)."""
    pytest.importorskip("lgvi._core")  # the compiled module (not in the sanitizer build's run of this file)
    import lgvi
    atoms, velocities = mixed_molecules()
    data = write_data(tmp_path / "mixed.data", atoms, velocities)
    text = scenario(tmp_path, data.name).read_text()
    from_file = lgvi.Scenario.from_toml(tmp_path / "imported.toml")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    from_text = lgvi.Scenario.from_string(text, "imported", directory=tmp_path)
    assert from_text.toml == from_file.toml  # the same bodies, the data file's checksum included
    with pytest.raises(ValueError, match="import.lammps_data"):
        lgvi.Scenario.from_string(text, "imported")
    with pytest.raises(ValueError, match="^directory: must be an existing folder"):
        lgvi.Scenario.from_string(text, "imported", directory=tmp_path / "missing")
    with pytest.raises(ValueError, match="^name: .* absolute path"):  # which folder would be meant is unclear
        lgvi.Scenario.from_string(text, str(tmp_path / "imported"), directory=elsewhere)
    # Without directory, a folder in the name is the scenario file's folder, as before.
    assert lgvi.Scenario.from_string(text, str(tmp_path / "imported")).toml == from_file.toml
