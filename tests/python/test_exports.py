"""The exports for viewers, [output] format = "xyz" (extended XYZ for OVITO),
"vtk" (VTK XML PolyData series with a .pvd index for ParaView) and
"lammps-dump" (a LAMMPS text dump): the same scenario is run through the CLI in
csv and each export, and the exports are read back (the XYZ and the dump by the
small parsers below, the VTK by VTK's own vtkXMLPolyDataReader from Debian's
python3-vtk9, the dump also by LAMMPS's own read_dump and rerun where Debian's
lammps is installed) and compared with the CSV. Interrupted and killed runs
resume to byte-identical files. Run by ctest (python.exports) with
LGVI_BINARY set."""
import json
import os
import pathlib
import shutil
import signal
import subprocess
import time
import xml.etree.ElementTree as ET

import numpy as np
import pytest

BINARY = os.environ.get("LGVI_BINARY")
SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
pytestmark = pytest.mark.skipif(BINARY is None, reason="LGVI_BINARY not set (run through ctest)")

# The columns of an XYZ line as the writer promises them (src/io/formats/xyz.cpp).
PROPERTIES = "species:S:1:pos:R:3:orientation:R:4:radius:R:1:body:I:1:id:I:1:velo:R:3:omega:R:3"

# A [[bodies]] scenario with both kinds of body: a rubble pile of three balls
# and a body given by mass and inertia (one site, the sphere of its mean
# moment), tumbling in a uniform field.
MIXED = """
[[bodies]]
name = "pile"
position = [1.0, 2.0, 3.0]
quaternion = [0.9, 0.3, -0.2, 0.2449489742783178]
momentum = [0.3, -0.1, 0.2]
omega = [0.4, -1.1, 0.7]
[[bodies.ball]]
position = [0.0, 0.0, 0.0]
mass = 1.0
radius = 0.3
[[bodies.ball]]
position = [0.7, 0.1, 0.0]
mass = 0.5
radius = 0.2
[[bodies.ball]]
position = [0.1, 0.6, 0.3]
mass = 0.25
radius = 0.15

[[bodies]]
name = "top hat"
mass = 2.0
inertia = [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.5]]
position = [-2.0, 0.0, 0.5]
quaternion = [1.0, 0.0, 0.0, 0.0]
momentum = [0.0, 0.5, 0.0]
omega = [0.1, 1.3, 0.05]

[potential]
kind = "uniform"
g = [0.0, 0.0, -1.0]

[integrator]
method = "lgvi"
step = 0.01
duration = 3.0

[output]
every = 7
"""

# Body-frame balls (position, mass, radius) of MIXED, and (mass, J) of the other body.
PILE = [((0.0, 0.0, 0.0), 1.0, 0.3), ((0.7, 0.1, 0.0), 0.5, 0.2), ((0.1, 0.6, 0.3), 0.25, 0.15)]
TOP_HAT_MASS, TOP_HAT_INERTIA = 2.0, np.diag([1.0, 2.0, 2.5])


def run(*args):
    return subprocess.run([BINARY, "run", *map(str, args), "--no-figures", "-q"], capture_output=True, text=True)


def with_format(text, fmt):
    return text.replace("[output]\n", f'[output]\nformat = "{fmt}"\n', 1)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The MIXED scenario run in csv and every export: {format: run folder}."""
    tmp = tmp_path_factory.mktemp("exports")
    out = {}
    for fmt in ("csv", "xyz", "vtk", "lammps-dump"):
        scenario = tmp / f"mixed-{fmt}.toml"
        scenario.write_text(with_format(MIXED, fmt))
        out[fmt] = tmp / fmt
        proc = run(scenario, "--out", out[fmt])
        assert proc.returncode == 0, proc.stderr
    return out


def csv_rows(folder):
    """The long-format CSV: {column: array of shape (steps, bodies)}."""
    with open(folder / "trajectory.csv") as f:
        names = f.readline().strip().split(",")
    data = np.loadtxt(folder / "trajectory.csv", delimiter=",", skiprows=1)
    bodies = int(data[:, 1].max()) + 1
    data = data.reshape(-1, bodies, len(names))
    return {n: data[:, :, i] for i, n in enumerate(names)}


def balls_about_com(balls):
    """The balls' body-frame centres about the centre of mass, computed in
    RigidBody::from_balls's order (so bit for bit the same doubles)."""
    m, c = 0.0, np.zeros(3)
    for pos, mass, _ in balls:
        m += mass
        c = c + mass * np.array(pos)
    c = c / m
    return [np.array(pos) - c for pos, _, _ in balls], m


def sites(q, x, rho):
    """x + R(q) rho with R = pi(q) as S3::matrix() forms it and the sum in
    site_position's order ((R_i0 rho_0 + R_i1 rho_1) + R_i2 rho_2); q scalar first."""
    s, v = q[0], np.array(q[1:])
    r = (2.0 * v)[:, None] * v[None, :]
    r[np.diag_indices(3)] += 2.0 * s * s - 1.0
    hat = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    r = r + (2.0 * s) * hat
    return np.array([x[i] + ((r[i, 0] * rho[0] + r[i, 1] * rho[1]) + r[i, 2] * rho[2]) for i in range(3)]), r


def expected_frames(csv):
    """Per frame: the sites' positions, quaternions (w, x, y, z), radii, bodies,
    velocities and angular velocities, from the CSV run."""
    rho, pile_mass = balls_about_com(PILE)
    radius_top_hat = np.sqrt(5.0 * np.trace(TOP_HAT_INERTIA) / (6.0 * TOP_HAT_MASS))
    j_inv_pile = np.linalg.inv(sum(
        m * (np.dot(p, p) * np.eye(3) - np.outer(p, p)) + 0.4 * m * r * r * np.eye(3)
        for p, (_, m, r) in zip(rho, PILE)))
    shapes = [(pile_mass, j_inv_pile, list(zip(rho, [r for _, _, r in PILE]))),
              (TOP_HAT_MASS, np.linalg.inv(TOP_HAT_INERTIA), [(np.zeros(3), radius_top_hat)])]
    frames = []
    for k in range(csv["t"].shape[0]):
        f = {key: [] for key in ("pos", "q", "radius", "body", "velo", "omega")}
        for a, (mass, j_inv, body_sites) in enumerate(shapes):
            q = np.array([csv[c][k, a] for c in ("qw", "qx", "qy", "qz")])
            x = np.array([csv[c][k, a] for c in ("x", "y", "z")])
            p = np.array([csv[c][k, a] for c in ("px", "py", "pz")])
            w = np.array([csv[c][k, a] for c in ("wx", "wy", "wz")])
            for rho_i, radius in body_sites:
                pos, r = sites(q, x, rho_i)
                f["pos"].append(pos)
                f["q"].append(q)
                f["radius"].append(radius)
                f["body"].append(a)
                f["velo"].append(p / mass)
                f["omega"].append(r @ (0.5 * j_inv @ w))
        frames.append({key: np.array(v) for key, v in f.items()})
    return frames


# ---- extended XYZ -------------------------------------------------------------


def parse_properties(spec):
    """[(name, type, columns)] of an extended XYZ Properties= value."""
    fields = spec.split(":")
    assert len(fields) % 3 == 0, spec
    return [(fields[i], fields[i + 1], int(fields[i + 2])) for i in range(0, len(fields), 3)]


def parse_comment(line):
    """The key=value pairs of an extended XYZ comment line (no quoted values here)."""
    pairs = dict(item.split("=", 1) for item in line.split())
    return pairs


def read_xyz(path):
    """Frames of an extended XYZ file: [(info dict, {property: array})]."""
    lines = path.read_text().splitlines()
    frames, i = [], 0
    while i < len(lines):
        n = int(lines[i])
        info = parse_comment(lines[i + 1])
        props = parse_properties(info["Properties"])
        width = sum(c for _, _, c in props)
        rows = [line.split() for line in lines[i + 2:i + 2 + n]]
        assert len(rows) == n, f"frame at line {i + 1}: {len(rows)} particle lines, header says {n}"
        assert all(len(r) == width for r in rows), "a line's columns differ from Properties="
        columns, start = {}, 0
        for name, kind, count in props:
            cells = [r[start:start + count] for r in rows]
            columns[name] = (np.array(cells, dtype=float) if kind == "R" else
                             np.array(cells, dtype=np.int64) if kind == "I" else np.array(cells))
            if count == 1:
                columns[name] = columns[name][:, 0]
            start += count
        frames.append((info, columns))
        i += 2 + n
    return frames


def test_xyz_header_columns_and_sites_equal_the_csv_run(runs):
    csv = csv_rows(runs["csv"])
    want = expected_frames(csv)
    frames = read_xyz(runs["xyz"] / "trajectory.xyz")
    assert len(frames) == len(want) == csv["t"].shape[0]
    for k, ((info, cols), w) in enumerate(zip(frames, want)):
        assert info["Properties"] == PROPERTIES
        assert "Lattice" not in info  # not periodic: OVITO takes the bounding box
        assert len(cols["pos"]) == 4  # three balls and one centre of mass
        assert float(info["Time"]) == csv["t"][k, 0]
        assert float(info["energy_error"]) == csv["energy_error"][k, 0]
        assert int(info["frame"]) == k
        # One species per site radius, the LAMMPS dump's types: four radii here.
        assert list(cols["species"]) == [f"type{n}" for n in types_by_radius(list(w["radius"]))]
        assert list(cols["species"]) == ["type1", "type2", "type3", "type4"]
        assert list(cols["id"]) == [0, 1, 2, 3]
        assert np.array_equal(cols["body"], w["body"])
        # Exact: %.17g round-trips, and the expected positions are formed in the writer's order.
        assert np.array_equal(cols["pos"], w["pos"]), f"frame {k}: {cols['pos'] - w['pos']}"
        # OVITO's Orientation is (X, Y, Z, W): lgvi's (qx, qy, qz, qw).
        assert np.array_equal(cols["orientation"], w["q"][:, [1, 2, 3, 0]])
        assert np.array_equal(cols["radius"], w["radius"])
        assert np.array_equal(cols["velo"], w["velo"])  # p / m, one division
        # Omega = R J^-1 w / 2: numpy's inverse of J and its products round
        # differently from Eigen's; a few ulps of |omega| ~ 1 apart.
        assert np.allclose(cols["omega"], w["omega"], rtol=0, atol=1e-13), np.abs(cols["omega"] - w["omega"]).max()
    # The orientation column really is OVITO's: rotating the body-frame offset of
    # a ball by the scalar-last quaternion gives its position (Shoemake's q v q*).
    info, cols = frames[-1]
    rho, _ = balls_about_com(PILE)
    x, y, z, s = cols["orientation"][1]
    v = np.array([x, y, z])
    rotated = rho[1] + 2.0 * np.cross(v, np.cross(v, rho[1]) + s * rho[1])
    centre = np.array([csv[c][-1, 0] for c in ("x", "y", "z")])
    assert np.allclose(centre + rotated, cols["pos"][1], rtol=0, atol=1e-14)


def test_xyz_single_body_scenario_has_one_particle_per_ball(tmp_path):
    text = (SOURCE / "scenarios" / "paper-orbit.toml").read_text().replace("duration = 1000.0", "duration = 1.0")
    out = {}
    for fmt in ("csv", "xyz"):
        path = tmp_path / f"orbit-{fmt}.toml"
        path.write_text(with_format(text, fmt))
        out[fmt] = tmp_path / fmt
        proc = run(path, "--out", out[fmt])
        assert proc.returncode == 0, proc.stderr
    data = np.loadtxt(out["csv"] / "trajectory.csv", delimiter=",", skiprows=1)
    frames = read_xyz(out["xyz"] / "trajectory.xyz")
    assert len(frames) == len(data) == 11  # 100 steps, every 10th and the first
    rho, _ = balls_about_com([((0.0, 0.0, 0.0), 1.0, 0.1), ((1.0, 0.0, 0.0), 1.0, 0.1),
                              ((0.5, 0.8660254037844386, 0.0), 1.0, 0.1)])
    for (info, cols), row in zip(frames, data):
        assert float(info["Time"]) == row[0]
        assert len(cols["pos"]) == 3
        want = np.array([sites(row[4:8], row[1:4], r)[0] for r in rho])
        assert np.array_equal(cols["pos"], want)
    # The summary and scenario are stored beside the export, as for CSV.
    summary, csv_summary = (json.loads((out[f] / "summary.json").read_text()) for f in ("xyz", "csv"))
    assert summary["completed"] is True
    for key in ["steps", "max_abs_energy_error", "max_abs_quat_norm_error", "max_momentum_error", "final"]:
        assert summary[key] == csv_summary[key], key
    assert (out["xyz"] / "scenario.toml").read_text() == with_format(text, "xyz")


# ---- VTK ----------------------------------------------------------------------


def read_pvd(path):
    """[(timestep, .vtp path)] of a ParaView collection, in file order."""
    root = ET.parse(path).getroot()
    assert root.tag == "VTKFile" and root.get("type") == "Collection"
    return [(float(d.get("timestep")), path.parent / d.get("file")) for d in root.iter("DataSet")]


def read_vtp(path):
    """Points, point-data arrays and field data of a .vtp, read by VTK itself."""
    vtk = pytest.importorskip("vtk", reason="needs Debian's python3-vtk9")
    from vtk.util.numpy_support import vtk_to_numpy
    reader = vtk.vtkXMLPolyDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    poly = reader.GetOutput()
    assert reader.GetErrorCode() == 0, path
    pd, fd = poly.GetPointData(), poly.GetFieldData()
    arrays = {pd.GetArrayName(i): vtk_to_numpy(pd.GetArray(i)) for i in range(pd.GetNumberOfArrays())}
    fields = {fd.GetArrayName(i): vtk_to_numpy(fd.GetArray(i)) for i in range(fd.GetNumberOfArrays())}
    return vtk_to_numpy(poly.GetPoints().GetData()), arrays, fields, poly.GetNumberOfVerts()


def test_vtk_series_read_by_vtk_equals_the_csv_run(runs):
    csv = csv_rows(runs["csv"])
    want = expected_frames(csv)
    index = read_pvd(runs["vtk"] / "trajectory.pvd")
    assert [t for t, _ in index] == list(csv["t"][:, 0])
    assert sorted(p.name for p in (runs["vtk"] / "trajectory").iterdir()) == [p.name for _, p in index]
    for (t, path), w in zip(index, want):
        points, arrays, fields, verts = read_vtp(path)
        assert points.dtype == np.float64 and verts == 4  # one vertex per site: ParaView draws them
        assert np.array_equal(points, w["pos"])  # exact: 17 digits, the writer's order
        assert np.array_equal(arrays["quaternion_wxyz"], w["q"])
        assert np.array_equal(arrays["radius"], w["radius"])
        assert np.array_equal(arrays["body"], w["body"])
        assert np.array_equal(arrays["velocity"], w["velo"])
        assert np.allclose(arrays["angular_velocity"], w["omega"], rtol=0, atol=1e-13)  # as for XYZ
        assert fields["TimeValue"][0] == t
    k = len(index) - 1
    assert read_vtp(index[k][1])[2]["energy_error"][0] == csv["energy_error"][k, 0]


# ---- LAMMPS dump ---------------------------------------------------------------


def read_lammps_dump(path):
    """Frames of a LAMMPS text dump: [(timestep, box bounds (3, 2), boundary flags, {column: array})]."""
    lines = path.read_text().splitlines()
    frames, i = [], 0
    while i < len(lines):
        assert lines[i] == "ITEM: TIMESTEP", (i, lines[i])
        step = int(lines[i + 1])
        assert lines[i + 2] == "ITEM: NUMBER OF ATOMS"
        n = int(lines[i + 3])
        assert lines[i + 4].startswith("ITEM: BOX BOUNDS ")
        flags = lines[i + 4].split()[3:]
        box = np.array([[float(v) for v in lines[i + 5 + d].split()] for d in range(3)])
        header = lines[i + 8].split()
        assert header[:2] == ["ITEM:", "ATOMS"]
        rows = [line.split() for line in lines[i + 9:i + 9 + n]]
        assert len(rows) == n and all(len(r) == len(header) - 2 for r in rows)
        columns = {}
        for c, name in enumerate(header[2:]):
            cells = [r[c] for r in rows]
            columns[name] = (np.array(cells, dtype=np.int64) if name in ("id", "mol", "type", "ix", "iy", "iz")
                             else np.array(cells, dtype=float))
        frames.append((step, box, flags, columns))
        i += 9 + n
    return frames


def types_by_radius(radii):
    """LAMMPS types of the sites: their radii numbered from 1 in order of first appearance."""
    seen = []
    for r in radii:
        if r not in seen:
            seen.append(r)
    return [seen.index(r) + 1 for r in radii]


def test_lammps_dump_frames_equal_the_csv_run(runs):
    csv = csv_rows(runs["csv"])
    want = expected_frames(csv)
    frames = read_lammps_dump(runs["lammps-dump"] / "trajectory.lammpstrj")
    assert len(frames) == len(want) == csv["t"].shape[0]
    for k, ((step, box, flags, cols), w) in enumerate(zip(frames, want)):
        assert step == round(csv["t"][k, 0] / 0.01)  # the step number k of t = k h (h = 0.01)
        assert flags == ["ss", "ss", "ss"]  # not periodic: shrink-wrapped
        assert list(cols) == ["id", "mol", "type", "x", "y", "z", "ix", "iy", "iz"]
        assert list(cols["id"]) == [1, 2, 3, 4]
        assert list(cols["mol"]) == list(w["body"] + 1)
        assert list(cols["type"]) == types_by_radius(list(w["radius"])) == [1, 2, 3, 4]
        pos = np.column_stack([cols["x"], cols["y"], cols["z"]])
        assert np.array_equal(pos, w["pos"]), f"frame {k}: {pos - w['pos']}"  # exact, as the XYZ's
        # The spheres' extent: per axis, min(c - r) and max(c + r) over the sites.
        r = w["radius"][:, None]
        assert np.array_equal(box, np.column_stack([(pos - r).min(axis=0), (pos + r).max(axis=0)]))
        for image in ("ix", "iy", "iz"):
            assert not cols[image].any()
    assert frames[-1][0] == 300  # the last step is written: 3.0 / 0.01


def molecule(name, x, balls):
    """A [[bodies]] entry at rest at x, made of balls [(body-frame position, mass, radius)]."""
    text = (f'[[bodies]]\nname = "{name}"\nposition = {x}\nquaternion = [1.0, 0.0, 0.0, 0.0]\n'
            "momentum = [0.0, 0.0, 0.0]\nomega = [0.0, 0.0, 0.0]\n")
    for position, mass, radius in balls:
        text += f"[[bodies.ball]]\nposition = {position}\nmass = {mass}\nradius = {radius}\n"
    return text


PAIR = [([0.0, 0.0, 0.0], 1.0, 0.3), ([0.7, 0.0, 0.0], 0.5, 0.2)]
TWINS = (molecule("a", [0.0, 0.0, 0.0], PAIR) + molecule("b", [3.0, 0.0, 0.0], PAIR)
         + molecule("c", [0.0, 3.0, 0.0], [([0.0, 0.0, 0.0], 1.0, 0.2)])
         + '[potential]\nkind = "none"\n\n[integrator]\nstep = 0.01\nduration = 0.1\n\n[output]\n')


def test_lammps_dump_types_and_xyz_species_are_shared_by_equal_radii(tmp_path):
    # Two identical molecules and a ball of the second radius: three molecules, two types.
    path = tmp_path / "twins.toml"
    path.write_text(with_format(TWINS, "lammps-dump"))
    proc = run(path, "--out", tmp_path / "out")
    assert proc.returncode == 0, proc.stderr
    step, box, _, cols = read_lammps_dump(tmp_path / "out" / "trajectory.lammpstrj")[0]
    assert step == 0
    assert list(cols["mol"]) == [1, 1, 2, 2, 3]
    assert list(cols["type"]) == [1, 2, 1, 2, 2]
    # All sites at z = 0, radii 0.3 and 0.2: the box is the spheres' extent, never flat.
    assert list(box[2]) == [-0.3, 0.3]
    # The xyz export's species are the same types (OVITO colours by kind of site, not by molecule).
    path.write_text(with_format(TWINS, "xyz"))
    proc = run(path, "--out", tmp_path / "xyz")
    assert proc.returncode == 0, proc.stderr
    _, cols = read_xyz(tmp_path / "xyz" / "trajectory.xyz")[0]
    assert list(cols["species"]) == ["type1", "type2", "type1", "type2", "type2"]


def test_lammps_dump_box_is_never_flat(tmp_path):
    # Point sites (radius 0) in the plane z = 0: their extent in z is empty, which LAMMPS refuses
    # as a box; the dump widens it by 0.5 each way.
    triangle = [([0.0, 0.0, 0.0], 1.0, 0.0), ([1.0, 0.0, 0.0], 1.0, 0.0), ([0.5, 0.8, 0.0], 1.0, 0.0)]
    path = tmp_path / "flat.toml"
    path.write_text(with_format(molecule("t", [0.0, 0.0, 0.0], triangle)
                                + '[potential]\nkind = "none"\n\n[integrator]\nstep = 0.01\nduration = 0.1\n\n'
                                  '[output]\n', "lammps-dump"))
    proc = run(path, "--out", tmp_path / "out")
    assert proc.returncode == 0, proc.stderr
    for _, box, _, cols in read_lammps_dump(tmp_path / "out" / "trajectory.lammpstrj"):
        assert not cols["z"].any()  # at rest in its plane
        assert list(box[2]) == [-0.5, 0.5]
        assert box[0, 1] - box[0, 0] == 1.0  # x: the sites' own extent, radius 0


LAMMPS = shutil.which(os.environ.get("LMP_BINARY", "lmp"))


@pytest.mark.skipif(LAMMPS is None, reason="LAMMPS (Debian's lammps, lmp) not installed")
def test_lammps_reads_the_dump_back(runs, tmp_path):
    # Another program's reader: LAMMPS takes the first frame's atoms (read_dump ... add keep), then
    # steps through every frame (rerun) and dumps what it read with 17 digits. The positions, ids,
    # types and time steps must come back unchanged.
    dump = runs["lammps-dump"] / "trajectory.lammpstrj"
    ours = read_lammps_dump(dump)
    (tmp_path / "in.read").write_text(f"""
units lj
atom_style atomic
boundary s s s
region everywhere block -100 100 -100 100 -100 100
create_box 4 everywhere
mass * 1.0
read_dump {dump} 0 x y z box yes add keep
dump back all custom 1 {tmp_path}/back.lammpstrj id type x y z
dump_modify back sort id format float %.17g
rerun {dump} dump x y z box yes
""")
    proc = subprocess.run([LAMMPS, "-in", "in.read", "-log", "none", "-screen", "none"], cwd=tmp_path,
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    back = read_lammps_dump(tmp_path / "back.lammpstrj")
    assert [f[0] for f in back] == [f[0] for f in ours]
    for (step, box, _, cols), (_, box_back, _, cols_back) in zip(ours, back):
        for name in ("id", "type", "x", "y", "z"):
            assert np.array_equal(cols_back[name], cols[name]), (step, name)


# ---- resume ------------------------------------------------------------------

STEPS = 4_000_000  # ~1 s: long enough to be stopped mid-way


def long_scenario(tmp_path, fmt):
    text = (SOURCE / "scenarios" / "paper-orbit.toml").read_text()
    text = text.replace("duration = 1000.0", f"duration = {STEPS // 100}.0").replace("every = 10", "every = 2000")
    path = tmp_path / f"long-{fmt}.toml"
    path.write_text(with_format(text, fmt))
    return path


def export_bytes(folder, fmt):
    """Every file of the export: {relative path: bytes}."""
    if fmt in ("xyz", "lammps-dump"):
        name = "trajectory.xyz" if fmt == "xyz" else "trajectory.lammpstrj"
        return {name: (folder / name).read_bytes()}
    files = {"trajectory.pvd": (folder / "trajectory.pvd").read_bytes()}
    for p in sorted((folder / "trajectory").iterdir()):
        files["trajectory/" + p.name] = p.read_bytes()
    return files


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("uninterrupted")
    out = {}
    for fmt in ("xyz", "vtk", "lammps-dump"):
        out[fmt] = tmp / fmt
        proc = run(long_scenario(tmp, fmt), "--out", out[fmt])
        assert proc.returncode == 0, proc.stderr
    return out


@pytest.mark.parametrize("fmt", ["xyz", "vtk", "lammps-dump"])
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGKILL])
def test_stopped_or_killed_run_resumes_byte_identical(tmp_path, uninterrupted, fmt, sig):
    out = tmp_path / "run"
    proc = subprocess.Popen([BINARY, "run", long_scenario(tmp_path, fmt), "--out", out, "--checkpoint-every", "100000",
                             "--no-figures", "-q"], stderr=subprocess.PIPE, text=True)
    # Signal once the first checkpoint (step 100000 of 4e6) is on disk: the step
    # loop is running, with the handler installed and something to resume from.
    # A fixed delay from launch raced with start-up on a loaded machine (no
    # checkpoint yet when killed, or SIGINT before the handler: status -2).
    deadline = time.monotonic() + 60
    while not (out / "checkpoint.bin").is_file() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    time.sleep(0.1)
    proc.send_signal(sig)
    proc.communicate(timeout=60)
    assert proc.returncode == (130 if sig == signal.SIGINT else -signal.SIGKILL), proc.returncode
    assert (out / "checkpoint.bin").is_file()
    if sig == signal.SIGINT:  # stopped cleanly: the files are valid up to the stop, and say so
        assert json.loads((out / "summary.json").read_text())["completed"] is False
    if fmt == "vtk" and sig == signal.SIGKILL:
        # Killed: the index is not closed, and every frame file listed in it is whole.
        text = (out / "trajectory.pvd").read_text()
        assert "</VTKFile>" not in text
        listed = [line for line in text.splitlines() if "<DataSet" in line]
        assert 0 < len(listed) < STEPS // 2000 + 1
        for line in listed:
            assert read_vtp(out / line.split('file="')[1].split('"')[0])[0].shape == (3, 3)
    resumed = run("--resume", out)
    assert resumed.returncode == 0, resumed.stderr
    assert export_bytes(out, fmt) == export_bytes(uninterrupted[fmt], fmt)
    assert json.loads((out / "summary.json").read_text())["completed"] is True


# ---- errors ------------------------------------------------------------------


def test_unknown_format_names_the_key_and_lists_the_formats(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(with_format(MIXED, "ovito"))
    proc = run(path, "--out", tmp_path / "out")
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert "key 'output.format'" in lines[0]
    assert '"ovito" is not one of "csv", "npz", "hdf5", "xyz", "vtk", "lammps-dump"' in lines[0]


def test_python_accepts_the_exports_and_load_refuses_them(runs):
    lgvi = pytest.importorskip("lgvi")
    assert lgvi.FORMATS == ("csv", "npz", "hdf5", "xyz", "vtk", "lammps-dump")
    body = lgvi.Body(mass=1.0, inertia=np.diag([1.0, 2.0, 3.0]))
    s = lgvi.Scenario(body=body, step=0.1, duration=1.0, position=(0, 0, 0), quaternion=(1, 0, 0, 0),
                      momentum=(0, 0, 0), w=(0, 0, 0), output_format="vtk")
    assert s.output_format == "vtk"
    with pytest.raises(ValueError, match='output_format: must be one of "csv", "npz", "hdf5", "xyz", "vtk", "lammps-dump"'):
        lgvi.Scenario(body=body, step=0.1, duration=1.0, position=(0, 0, 0), quaternion=(1, 0, 0, 0),
                      momentum=(0, 0, 0), w=(0, 0, 0), output_format="ovito")
    for target in (runs["xyz"], runs["xyz"] / "trajectory.xyz", runs["vtk"], runs["vtk"] / "trajectory.pvd",
                   runs["lammps-dump"], runs["lammps-dump"] / "trajectory.lammpstrj"):
        with pytest.raises(ValueError, match='export for viewers .* use|format = "csv", "npz" or "hdf5"'):
            lgvi.load(target)
