"""Many-body scenarios ([[bodies]]) through `lgvi run` and the Python package:
the long trajectory format in every file format, the summary's per-body
states, results that do not depend on the number of threads, checkpoints and
resume, and the binary asteroid's conservation laws. Run by ctest with
LGVI_BINARY set."""
import json
import os
import pathlib
import signal
import subprocess
import time

import numpy as np
import pytest

BINARY = os.environ.get("LGVI_BINARY")
SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
pytestmark = pytest.mark.skipif(BINARY is None, reason="LGVI_BINARY not set (run through ctest)")

BODIES_HEADER = ("t,body,x,y,z,qw,qx,qy,qz,px,py,pz,wx,wy,wz,quat_norm_error,energy,energy_error,Px,Py,Pz,"
                 "linear_momentum_error,Lx,Ly,Lz,momentum_error")


def run(*args):
    return subprocess.run([BINARY, "run", *map(str, args), "--no-figures", "-q"], capture_output=True, text=True)


def variant(tmp_path, name, replacements, file_name=None):
    text = (SOURCE / "scenarios" / f"{name}.toml").read_text()
    for old, new in replacements:
        assert old in text, old
        text = text.replace(old, new)
    path = tmp_path / (file_name or f"{name}.toml")
    path.write_text(text)
    return path


def test_binary_asteroid_conserves_momenta_and_writes_the_long_format(tmp_path):
    out = tmp_path / "run"
    proc = run(SOURCE / "scenarios" / "binary-asteroid.toml", "--out", out)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["completed"]
    # Mutual gravity only: total linear and angular momentum are conserved by
    # the discrete Noether theorem, to round-off (40000 steps: ~1e-14).
    assert summary["max_linear_momentum_error"] <= 1e-13
    assert summary["max_relative_momentum_error"] <= 1e-12
    assert summary["max_abs_quat_norm_error"] <= 1e-13
    # The energy error is bounded and small for this smooth, well-resolved orbit
    # (h = 0.01, orbit period ~40): second order, ~1e-10 here.
    assert summary["max_abs_energy_error"] <= 1e-9
    names = [b["name"] for b in summary["final_bodies"]]
    assert names == ["primary", "secondary"]
    lines = (out / "trajectory.csv").read_text().splitlines()
    assert lines[0] == BODIES_HEADER
    assert len(lines) - 1 == 2 * (40000 // 10 + 1)  # two rows (one per body) per written step
    last = np.array([float(v) for v in lines[-1].split(",")])
    assert last[1] == 1.0 and np.array_equal(last[2:5], summary["final_bodies"][1]["position"])


@pytest.mark.parametrize("fmt", ["csv", "npz", "hdf5"])
def test_every_format_holds_steps_by_bodies_and_loads_bit_identically(tmp_path, fmt):
    import lgvi
    path = variant(tmp_path, "binary-asteroid", [("duration = 400.0", "duration = 5.0"),
                                                  ("every = 10", f'every = 10\nformat = "{fmt}"')])
    out = tmp_path / "run"
    proc = run(path, "--out", out)
    assert proc.returncode == 0, proc.stderr
    loaded = lgvi.load(out)
    assert loaded.layout == "long" and loaded.bodies == 2
    assert loaded.data.shape == (51, 2, 26)
    assert loaded.names == ["primary", "secondary"]
    if fmt == "npz":
        with np.load(out / "trajectory.npz") as z:
            assert z["trajectory"].shape == (51, 2, 26)
    if fmt == "hdf5":
        import h5py
        with h5py.File(out / "trajectory.h5") as f:
            assert f["trajectory"].shape == (51, 2, 26)
    memory = lgvi.simulate(lgvi.Scenario.from_toml(str(path)))
    assert np.array_equal(memory.data, loaded.data)  # the same run loop, bit for bit


def test_results_do_not_depend_on_the_number_of_threads(tmp_path):
    # 216 molecules: enough bodies for the per-body loops to use both threads.
    path = variant(tmp_path, "lj-gas", [("count = 1000", "count = 216"), ("duration = 2.0", "duration = 0.4"),
                                        ("every = 100", "every = 20")])
    one, two = tmp_path / "one", tmp_path / "two"
    assert run(path, "--out", one, "--threads", 1).returncode == 0
    assert run(path, "--out", two, "--threads", 2).returncode == 0
    assert (one / "trajectory.csv").read_bytes() == (two / "trajectory.csv").read_bytes()
    s1, s2 = (json.loads((d / "summary.json").read_text()) for d in (one, two))
    assert s1["final_bodies"] == s2["final_bodies"]


def test_resume_of_a_many_body_run_is_byte_identical(tmp_path):
    # In a periodic box (5 x 2.2 a side, the lattice continued across the faces), so that the temperature and
    # pressure columns and their statistics (the summary's "thermodynamics") go through the checkpoint too.
    path = variant(tmp_path, "lj-gas", [("count = 1000", "count = 125"), ("duration = 2.0", "duration = 200.0"),
                                        ("every = 100", "every = 500"),
                                        ("[interaction]", "[box]\nlower = [-1.1, -1.1, -1.1]\n"
                                                          "upper = [9.9, 9.9, 9.9]\n\n[interaction]")])
    full = tmp_path / "full"
    assert run(path, "--out", full, "--threads", 1).returncode == 0
    out = tmp_path / "run"
    proc = subprocess.Popen([BINARY, "run", str(path), "--out", str(out), "--checkpoint-every", "5000", "--no-figures",
                             "-q", "--threads", "1"], stderr=subprocess.PIPE, text=True)
    # SIGINT once the first checkpoint is on disk: the step loop runs and its
    # handler is installed (a fixed delay from launch raced with start-up).
    deadline = time.monotonic() + 60
    while not (out / "checkpoint.bin").is_file() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode in (0, 130), err
    if proc.returncode == 130:
        resumed = subprocess.run([BINARY, "run", "--resume", str(out), "--no-figures", "-q"], capture_output=True,
                                 text=True)
        assert resumed.returncode == 0, resumed.stderr
    assert (out / "trajectory.csv").read_bytes() == (full / "trajectory.csv").read_bytes()
    s_full, s_run = (json.loads((d / "summary.json").read_text()) for d in (full, out))
    assert (full / "trajectory.csv").read_text().split("\n", 1)[0].endswith(",temperature,pressure")
    for key in ("max_abs_energy_error", "max_linear_momentum_error", "max_momentum_error", "final_bodies",
                "thermodynamics"):
        assert s_full[key] == s_run[key], key


@pytest.mark.parametrize("replacements,message", [
    ([('name = "secondary"', 'name = "primary"')], 'the name "primary" is given to two bodies'),
    ([("position = [3.431372549019608", "position = [0.1")], "overlaps bodies[0]"),
    ([("[potential]\nkind = \"none\"", "[potential]\nkind = \"heavy-top\"\ng = [0, 0, -1]\npivot_to_com = [0, 0, 1]")],
     '"heavy-top" is a single body'),
    ([('method = "lgvi"', 'method = "exact"')], '"exact" is the exact flow of one free body'),
    ([("G = 1.0", "G = -1.0")], "interaction.G"),
    ([('model = "balls"', 'model = "spheres"')], "interaction.model"),
    ([("[[bodies]]\nname = \"primary\"", "[body]\nmass = 1.0\n[[bodies]]\nname = \"primary\"")],
     "give either [body] + [initial] (one body) or [[bodies]] tables, not both"),
])
def test_bad_many_body_scenarios_get_one_line_naming_the_key(tmp_path, replacements, message):
    path = variant(tmp_path, "binary-asteroid", replacements, "bad.toml")
    proc = run(path, "--out", tmp_path / "out")
    assert proc.returncode == 2
    assert message in proc.stderr, proc.stderr
    assert proc.stderr.count("\n") == 1


# ---------------------------------------------------------------------------
# Scenarios of many bodies from numpy arrays


def binary_asteroid_arrays():
    """The binary asteroid's bodies and states, read from its file with tomllib (not lgvi's reader)."""
    import tomllib
    import lgvi
    doc = tomllib.loads((SOURCE / "scenarios" / "binary-asteroid.toml").read_text())
    entries = doc["bodies"]
    return dict(
        bodies=[lgvi.Body(balls=[(b["position"], b["mass"], b["radius"]) for b in e["ball"]]) for e in entries],
        positions=np.array([e["position"] for e in entries]),
        quaternions=np.array([e["quaternion"] for e in entries]),
        momenta=np.array([e["momentum"] for e in entries]),
        omegas=np.array([e["omega"] for e in entries]),
        names=[e["name"] for e in entries],
        interaction=dict(doc["interaction"]),
        step=doc["integrator"]["step"],
        every=doc["output"]["every"]), doc


def test_from_arrays_gives_the_file_scenario_to_the_last_bit():
    # The same bodies and states as numpy arrays: the run equals the file's
    # run bit for bit (the same reader, the same loop), over a shortened span.
    import lgvi
    arrays, doc = binary_asteroid_arrays()
    duration = 50 * arrays["step"]
    from_file = lgvi.Scenario.from_string(
        (SOURCE / "scenarios" / "binary-asteroid.toml").read_text().replace(
            f"duration = {doc['integrator']['duration']}", f"duration = {duration!r}"), "binary-asteroid")
    assert from_file.steps == 50
    from_arrays = lgvi.Scenario.from_arrays(duration=duration, name="binary-asteroid", **arrays)
    a, b = lgvi.simulate(from_file), lgvi.simulate(from_arrays)
    assert a.summary["final_bodies"] == b.summary["final_bodies"]
    assert np.array_equal(a.data, b.data)


def test_from_arrays_one_body_for_all_rows_and_zero_momentum_gas():
    # 8 triangles on a cube's corners, spacing 3 sigma, at rest but spinning:
    # Lennard-Jones conserves the total linear momentum (0) to round-off.
    import lgvi
    tri = lgvi.Body(balls=[((0.5, 0, 0), 1, 0.1), ((-0.25, 0.433, 0), 1, 0.1), ((-0.25, -0.433, 0), 1, 0.1)])
    corners = 3.0 * np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], dtype=float)
    sc = lgvi.Scenario.from_arrays(bodies=tri, positions=corners, quaternions=np.tile([1.0, 0, 0, 0], (8, 1)),
                                   momenta=np.zeros((8, 3)), omegas=np.full((8, 3), 0.2),
                                   interaction={"kind": "lennard-jones", "epsilon": 1.0, "sigma": 1.0},
                                   step=0.005, duration=1.0, every=50, threads=1)
    r = lgvi.simulate(sc)
    # sum |p_a0| = 0: the error is absolute, |P| after 200 steps of summed
    # pair forces ~ 8 bodies x eps x |F| h ... well below 1e-13.
    assert r.summary["max_linear_momentum_error"] < 1e-13
    assert len(r.summary["final_bodies"]) == 8


@pytest.mark.parametrize("change, message", [
    (dict(positions=np.zeros((2, 2))), "positions: must have shape"),
    (dict(quaternions=np.zeros((2, 4))), r"quaternions\[0\]"),
    (dict(velocities=np.zeros((2, 3))), "momenta, velocities: give one of them, not both"),
    (dict(names=["a"]), "names: must have one name per body"),
    (dict(names=["a", "a"]), "given to two bodies"),
    (dict(interaction={"kind": "gravity", "G": 1.0, "g": 2}), "unknown key"),
    (dict(positions=np.zeros((2, 3))), "overlaps"),
    (dict(bodies="ball"), "bodies: must be an lgvi.Body"),
])
def test_from_arrays_errors_name_the_argument(change, message):
    import lgvi
    ball = lgvi.Body(balls=[((0, 0, 0), 1.0, 0.5)])
    args = dict(bodies=ball, positions=np.array([[0.0, 0, 0], [3.0, 0, 0]]),
                quaternions=np.tile([1.0, 0, 0, 0], (2, 1)), momenta=np.zeros((2, 3)), omegas=np.zeros((2, 3)),
                step=0.01, duration=0.1)
    args.update(change)
    with pytest.raises(ValueError, match=message):
        lgvi.Scenario.from_arrays(**args)


def test_replace_refuses_a_scenario_of_many_bodies():
    import lgvi
    sc = lgvi.Scenario.from_toml(SOURCE / "scenarios" / "binary-asteroid.toml")
    with pytest.raises(ValueError, match="from_arrays"):
        sc.replace(step=0.1)


def periodic_gas_arrays():
    """tests/cli/good/periodic-gas.toml's bodies and states as arrays (its own run of zero steps)."""
    import lgvi
    text = (SOURCE / "tests" / "cli" / "good" / "periodic-gas.toml").read_text()
    start = lgvi.simulate(lgvi.Scenario.from_string(text.replace("duration = 2.0", "duration = 0.0"), "periodic-gas"))
    final = start.summary["final_bodies"]
    tri = lgvi.Body(balls=[((0.0, 0.0, 0.0), 1.0, 0.5), ((1.0, 0.0, 0.0), 1.0, 0.5),
                           ((0.5, 0.8660254037844386, 0.0), 1.0, 0.5)])
    arrays = dict(bodies=tri, positions=[b["position"] for b in final], quaternions=[b["quaternion"] for b in final],
                  momenta=[b["momentum"] for b in final], w=[b["w"] for b in final],
                  names=[b["name"] for b in final],
                  interaction={"kind": "lennard-jones", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5},
                  box={"lower": [-1.1] * 3, "upper": [7.7] * 3, "periodic": [True, True, True]}, step=0.002)
    return text, arrays


def test_from_arrays_with_a_periodic_box_gives_the_file_scenario():
    # The periodic gas's bodies and states as arrays, with box=: the file's
    # run over 200 steps, to round-off. Not bit for bit: from_arrays
    # normalizes each quaternion, which moves the last bit of some (the
    # block's are unit to round-off, not exactly); the gas then amplifies a
    # 1e-16 difference to 1.2e-13 of its largest value (the energy, ~110) by
    # t = 0.4: 1e-11 allows a factor 100 more. The summary records the box.
    import lgvi
    text, arrays = periodic_gas_arrays()
    from_file = lgvi.Scenario.from_string(text.replace("duration = 2.0", "duration = 0.4"), "periodic-gas")
    from_arrays = lgvi.Scenario.from_arrays(duration=0.4, every=100, name="periodic-gas", **arrays)
    a, b = lgvi.simulate(from_file), lgvi.simulate(from_arrays)
    assert a.data.shape == b.data.shape == (3, 64, 28)  # with the temperature and pressure
    assert np.max(np.abs(a.data - b.data)) <= 1e-11
    assert b.summary["setup"]["box"] == {"lower": [-1.1] * 3, "upper": [7.7] * 3, "periodic": [True] * 3}
    # A periodic box conserves linear momentum (to round-off: each pair's
    # forces cancel exactly, their sums are rounded), not angular momentum.
    assert b.summary["max_linear_momentum_error"] < 1e-13
    assert "max_momentum_error" in b.summary["conserved"]["changes_not_errors"]
    assert b.summary["setup"]["box"] == {"lower": [-1.1] * 3, "upper": [7.7] * 3, "periodic": [True] * 3}
    # A periodic box conserves linear momentum (to round-off: each pair's
    # forces cancel exactly, the sums are rounded), not angular momentum.
    assert b.summary["max_linear_momentum_error"] < 1e-13
    assert "max_momentum_error" in b.summary["conserved"]["changes_not_errors"]


@pytest.mark.parametrize("box, message", [
    ({"lower": [0, 0, 0]}, r"box\.upper: missing"),
    ({"lower": [0, 0, 0], "upper": [9, 9, 9], "periodic": [True, 1, True]}, "box.periodic: must be 3 booleans"),
    ({"lower": [0, 0, 0], "upper": [9, 9, 9], "wrap": True}, "box: unknown key 'wrap'"),
    ({"lower": [0, 0, 0], "upper": [9, 0, 9]}, r"key 'box\.upper\[1\]': must be greater than box\.lower\[1\] = 0"),
    ({"lower": [0, 0, 0], "upper": [5, 5, 5]}, r"key 'box': the interaction's reach, cutoff \+ skin = 2\.8, must be less"),
])
def test_from_arrays_box_errors_name_the_key(box, message):
    import lgvi
    _, arrays = periodic_gas_arrays()
    arrays["box"] = box
    with pytest.raises(ValueError, match=message):
        lgvi.Scenario.from_arrays(duration=0.1, **arrays)


def gas_kinetic_energy(r, summary, k):
    """The kinetic energy sum p^2 / 2m + w . J^-1 w / 8 of written step k, from the state and the summary's
    setup (every body of the gas is the same triangle)."""
    body = summary["setup"]["bodies"][0]
    inertia, mass = np.array(body["inertia"]), body["mass"]
    p, w = r.p[k], r.w[k]
    return float(np.sum(p * p) / (2 * mass) + np.einsum("ai,ai->", w, np.linalg.solve(inertia, w.T).T) / 8)


@pytest.mark.parametrize("fmt", ["csv", "npz"])
def test_a_periodic_gas_writes_its_temperature_and_pressure(tmp_path, fmt):
    # The molecular run's columns after the others: the temperature 2 K / (6 N - 3) (LAMMPS's count for rigid
    # bodies; its value against LAMMPS: test_the_periodic_start_equals_lammps) and the pressure; the summary's
    # "thermodynamics" holds the first, last and mean of the written frames.
    import lgvi
    text = (SOURCE / "tests" / "cli" / "good" / "periodic-gas.toml").read_text()
    path = tmp_path / "gas.toml"
    path.write_text(text.replace('format = "lammps-dump"', f'format = "{fmt}"'))
    assert run(path, "--out", tmp_path / "out").returncode == 0
    r = lgvi.load(tmp_path / "out")
    thermo = r.summary["thermodynamics"]
    assert thermo["degrees_of_freedom"] == 6 * 64 - 3 and thermo["frames"] == len(r.t) == 11
    assert thermo["volume"] == pytest.approx(8.8 ** 3, rel=1e-15)
    for k in (0, 5, len(r.t) - 1):
        # The same sum of 64 bodies' terms in another order: round-off, ~1e-15.
        assert r.temperature[k] == pytest.approx(2 * gas_kinetic_energy(r, r.summary, k) / 381, rel=1e-13)
    for name in ("temperature", "pressure"):
        values = r.columns[name]
        assert values.shape == (11,) and np.all(np.isfinite(values))
        assert thermo[name]["initial"] == values[0] and thermo[name]["final"] == values[-1]
        assert thermo[name]["mean"] == pytest.approx(np.mean(values), rel=1e-14)  # summed in another order
    # The file's header names them, after the system's columns.
    if fmt == "csv":
        header = (tmp_path / "out" / "trajectory.csv").read_text().split("\n", 1)[0]
        assert header == BODIES_HEADER + ",temperature,pressure"
        # lgvi show: a periodic box does not conserve the angular momentum, and its row says so; the linear
        # momentum's row does not (it is conserved, to round-off).
        shown = subprocess.run([BINARY, "show", str(tmp_path / "out")], capture_output=True, text=True).stdout
        rows = {line.split("  ")[0]: line for line in shown.splitlines()}
        assert r.summary["conserved"]["changes_not_errors"] == ["max_momentum_error", "max_relative_momentum_error"]
        assert rows["angular momentum"].endswith("-- a change: this run's dynamics does not conserve it")
        assert "a change" not in rows["linear momentum"]
    # Through the Python package: the same numbers, named by the summary.
    s = lgvi.simulate(lgvi.Scenario.from_string(path.read_text(), "gas"))
    assert np.array_equal(s.temperature, r.temperature) and np.array_equal(s.pressure, r.pressure)


def test_only_molecular_runs_have_thermodynamic_columns(tmp_path):
    # A gas in free space: a temperature, no pressure (no volume); a binary asteroid (gravity): neither.
    gas = variant(tmp_path, "lj-gas", [("count = 1000", "count = 27"), ("duration = 2.0", "duration = 0.02")])
    assert run(gas, "--out", tmp_path / "gas").returncode == 0
    header = (tmp_path / "gas" / "trajectory.csv").read_text().split("\n", 1)[0]
    assert header == BODIES_HEADER + ",temperature"
    summary = json.loads((tmp_path / "gas" / "summary.json").read_text())
    assert set(summary["thermodynamics"]) == {"degrees_of_freedom", "boltzmann_constant", "frames", "temperature"}
    binary = variant(tmp_path, "binary-asteroid", [("duration = 400.0", "duration = 1.0")])
    assert run(binary, "--out", tmp_path / "binary").returncode == 0
    assert (tmp_path / "binary" / "trajectory.csv").read_text().split("\n", 1)[0] == BODIES_HEADER
    assert "thermodynamics" not in json.loads((tmp_path / "binary" / "summary.json").read_text())
    # Mutual gravity in free space conserves both momenta: no row of lgvi show calls them a change.
    assert "a change" not in subprocess.run([BINARY, "show", str(tmp_path / "binary")], capture_output=True,
                                            text=True).stdout


LAMMPS = __import__("shutil").which(os.environ.get("LMP_BINARY", "lmp"))


@pytest.mark.skipif(LAMMPS is None, reason="LAMMPS (Debian's lammps, lmp) not installed")
def test_the_periodic_start_equals_lammps():
    # benchmarks/lammps/compare_lammps.py --periodic: 1000 triangle molecules in a periodic cube, lgvi's step-0
    # potential and kinetic energy, temperature and pressure against LAMMPS's (fix rigid/nve/small; the pressure
    # of the rigid molecules from LAMMPS's per-atom data) to 1e-10 relative (measured: ~1e-15); it exits 1 if not.
    proc = subprocess.run([os.environ.get("LGVI_PYTHON", "/usr/bin/python3"),
                           str(SOURCE / "benchmarks" / "lammps" / "compare_lammps.py"), BINARY, LAMMPS, "--periodic"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "| pressure of the rigid molecules |" in proc.stdout


def test_show_counts_the_bodies_without_holding_their_lists(tmp_path):
    # lgvi show drops the per-body lists (final_bodies, setup.bodies) as it parses summary.json, counting the
    # first: the count and every row read from the rest (here the energy's E0 and the solver's iterations) are
    # the summary's, the lists' entries being skipped, not the keys after them.
    gas = variant(tmp_path, "lj-gas", [("count = 1000", "count = 27"), ("duration = 2.0", "duration = 0.02")])
    assert run(gas, "--out", tmp_path / "gas").returncode == 0
    summary = json.loads((tmp_path / "gas" / "summary.json").read_text())
    shown = subprocess.run([BINARY, "show", str(tmp_path / "gas")], capture_output=True, text=True, check=True).stdout
    rows = {line.split("  ")[0]: line for line in shown.splitlines()}
    assert rows["bodies"].split()[1] == str(len(summary["final_bodies"])) == "27"
    e0 = float(rows["energy"].split("E0 = ")[1].split(",")[0])  # printed to 10 digits
    assert e0 == pytest.approx(summary["initial_energy"], rel=1e-9)
    assert f"(max {summary['solver_iterations_max']})" in rows["solver iterations"]


def gas_with(tmp_path, folder, count, *extra):
    """scenarios/lj-gas.toml with `count` molecules over 10 steps, as FOLDER/gas.toml (one scenario name)."""
    (tmp_path / folder).mkdir()
    return variant(tmp_path, "lj-gas", [("count = 1000", f"count = {count}"), ("duration = 2.0", "duration = 0.02"),
                                        *extra], f"{folder}/gas.toml")


def test_the_lists_of_bodies_in_a_file_of_their_own_are_the_summarys_lists(tmp_path):
    # [output] body_lists = "file" (the default beyond 10 000 bodies) moves setup.bodies and final_bodies to
    # bodies.jsonl, one body a line: the same bodies and the same numbers to the bit (both files write
    # doubles with 17 significant digits), and nothing else changes but where the lists are.
    import lgvi
    inline = gas_with(tmp_path, "inline", 27)
    filed = gas_with(tmp_path, "filed", 27, ("every = 100", 'every = 100\nbody_lists = "file"'))
    for path in (inline, filed):
        proc = run(path, "--out", path.parent / "run")
        assert proc.returncode == 0, proc.stderr
    a, b = inline.parent / "run", filed.parent / "run"
    assert not (a / "bodies.jsonl").exists()
    sa, sb = (json.loads((d / "summary.json").read_text()) for d in (a, b))
    assert "bodies" not in sb["setup"] and "final_bodies" not in sb
    assert sb["body_lists"] == {"file": "bodies.jsonl", "bodies": 27}
    lines = (b / "bodies.jsonl").read_text().splitlines()
    assert len(lines) == 27
    expected = [{**setup, "final": {k: v for k, v in final.items() if k != "name"}}
                for setup, final in zip(sa["setup"]["bodies"], sa["final_bodies"])]
    assert [json.loads(line) for line in lines] == expected
    assert lgvi.load_bodies(a) == lgvi.load_bodies(b) == expected
    for s in (sa, sb):
        for key in ("wall_seconds", "ns_per_step", "final_bodies", "body_lists"):
            s.pop(key, None)
        s["setup"].pop("bodies", None)
    assert sa == sb
    assert (a / "trajectory.csv").read_bytes() == (b / "trajectory.csv").read_bytes()
    # The names for lgvi.load come from the file (its lines' first member).
    assert lgvi.load(b).names == lgvi.load(a).names == [f"molecule{i}" for i in range(27)]
    # The viewer draws the bodies from the file: the same page data.
    from lgvi import viewer
    assert viewer.page_data(lgvi.load(b)) == viewer.page_data(lgvi.load(a))
    shown = subprocess.run([BINARY, "show", str(b)], capture_output=True, text=True, check=True).stdout
    assert "bodies                 27 (the set-up and final state of each are in bodies.jsonl, a body a line)" \
        in shown.splitlines()
    # lgvi.simulate writes no file: its summary says so ("file": null), its names come from the scenario and
    # the final state is the arrays' last row, the CLI's to the bit.
    memory = lgvi.simulate(lgvi.Scenario.from_toml(str(filed)))
    assert memory.summary["body_lists"] == {"file": None, "bodies": 27}
    assert memory.names == lgvi.load(a).names
    assert memory.x[-1].tolist() == [body["final"]["position"] for body in expected]
    assert memory.q[-1].tolist() == [body["final"]["quaternion"] for body in expected]
    with pytest.raises(viewer.ViewError, match="kept no lists of bodies"):
        viewer.page_data(memory)
    # A trajectory taken away from the file: the bodies are numbered, with a warning saying why; the viewer
    # refuses it, naming the file.
    (b / "bodies.jsonl").unlink()
    with pytest.warns(UserWarning, match="bodies.jsonl: not there"):
        moved = lgvi.load(b)
    assert moved.names == [f"body{i}" for i in range(27)]
    with pytest.raises(viewer.ViewError, match="bodies.jsonl beside it, which is not there"):
        viewer.page_data(moved)
    # A run into the same folder that keeps its lists in the summary leaves no file of an earlier run's.
    assert run(filed, "--out", b, "--force").returncode == 0 and (b / "bodies.jsonl").exists()
    assert run(inline, "--out", b, "--force").returncode == 0
    assert not (b / "bodies.jsonl").exists() and len(json.loads((b / "summary.json").read_text())["final_bodies"]) == 27


def test_beyond_ten_thousand_bodies_their_lists_are_in_a_file_of_their_own(tmp_path):
    # kBodyListsInSummaryUpTo: 10 000 bodies keep their lists in summary.json, 10 001 write bodies.jsonl
    # (no steps: the set-up and the files only).
    for count, in_file in ((10000, False), (10001, True)):
        path = gas_with(tmp_path, str(count), count, ("duration = 0.02", "duration = 0.0"))
        proc = run(path, "--out", path.parent / "run")
        assert proc.returncode == 0, proc.stderr
        summary = json.loads((path.parent / "run" / "summary.json").read_text())
        assert ("body_lists" in summary) == in_file == (path.parent / "run" / "bodies.jsonl").exists()
        assert len(summary.get("final_bodies", ())) == (0 if in_file else count)
        if in_file:
            assert summary["body_lists"]["bodies"] == count
            assert len((path.parent / "run" / "bodies.jsonl").read_text().splitlines()) == count


def test_load_bodies_refuses_a_file_that_disagrees_with_its_summary_and_a_single_body(tmp_path):
    import lgvi
    filed = gas_with(tmp_path, "filed", 8, ("every = 100", 'every = 100\nbody_lists = "file"'))
    out = filed.parent / "run"
    assert run(filed, "--out", out).returncode == 0
    lines = (out / "bodies.jsonl").read_text().splitlines()
    assert len(lgvi.load_bodies(out)) == 8
    (out / "bodies.jsonl").write_text("\n".join(lines[:-1]) + "\n")  # a body short
    for load in (lgvi.load_bodies, lgvi.load):
        with pytest.raises(ValueError, match="holds 7 bodies where the summary's body_lists says 8"):
            load(out)
    (out / "bodies.jsonl").write_text("\n".join(lines[:3] + ["{not json"] + lines[4:]) + "\n")
    with pytest.raises(ValueError, match=r"bodies.jsonl:4: not valid JSON"):
        lgvi.load_bodies(out)
    with pytest.raises(ValueError, match=r"bodies.jsonl:4: not a body's line"):
        lgvi.load(out)
    single = tmp_path / "single"
    assert run(SOURCE / "tests" / "cli" / "good" / "short.toml", "--out", single).returncode == 0
    with pytest.raises(ValueError, match="no lists of bodies"):
        lgvi.load_bodies(single)


@pytest.mark.parametrize("scenario, old, new, expected", [
    ("lj-gas", "every = 100", 'every = 100\nbody_lists = "files"', ['output.body_lists', '"summary"', '"file"']),
    ("paper-orbit", "[output]\n", '[output]\nbody_lists = "file"\n',
     ["output.body_lists", "[[bodies]]", '"final"']),
])
def test_body_lists_refuses_a_wrong_value_or_a_single_body(tmp_path, scenario, old, new, expected):
    path = variant(tmp_path, scenario, [(old, new)])
    proc = run(path, "--out", tmp_path / "run")
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert all(e in proc.stderr for e in expected), proc.stderr
