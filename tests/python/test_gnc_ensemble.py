"""Monte Carlo for guidance, navigation and control (issue 30): [ensemble] metrics (pointing error, settling
time, wheel torque and speed, time at a limit, control effort) checked against the member's own trajectory
and summary; attitude errors drawn as rotations (their distribution, and their composition with the base's
attitude, given by a quaternion or by initial.attitude); inertia elements varied by index; the 200-member
scenarios/ensembles/slew-wheels-monte-carlo.toml identical on 1 and 2 threads and on 2 MPI ranks, and from
lgvi.ensemble; bad sweeps refused in one line naming the key; the figures.

Run by ctest (python.pytest) with PYTHONPATH=<build>/python, LGVI_BINARY and LGVI_SOURCE_DIR set.
"""

import csv
import math
import os
import pathlib
import shutil
import subprocess
import tomllib

import numpy as np
import pytest

BINARY = os.environ.get("LGVI_BINARY")
SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
pytestmark = pytest.mark.skipif(BINARY is None, reason="LGVI_BINARY not set (run through ctest)")
MPIRUN = shutil.which("mpirun")
MPI_ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
MONTE_CARLO = SOURCE / "scenarios" / "ensembles" / "slew-wheels-monte-carlo.toml"
SLEW_WHEELS = SOURCE / "scenarios" / "slew-wheels.toml"
TARGET = np.array([0.7562745640951468, 0.6527986923612583, -0.00817345814594061, 0.04284676809356561])


def ensemble(*args, mpi=0, figures=False):
    cmd = ([MPIRUN, "-n", str(mpi), "--oversubscribe"] if mpi else []) + [BINARY, "ensemble", *map(str, args), "-q"]
    return subprocess.run(cmd + ([] if figures else ["--no-figures"]), capture_output=True, text=True, env=MPI_ENV,
                          timeout=600)


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def product(a, b):
    """Hamilton's product of scalar-first quaternions (numpy, independent of the C++ one)."""
    return np.concatenate([[a[0] * b[0] - a[1:] @ b[1:]], a[0] * b[1:] + b[0] * a[1:] + np.cross(a[1:], b[1:])])


def pointing_error_deg(q, target=TARGET):
    """The angle of target^* q per row (degrees), 2 asin |Im(target^* q)|."""
    w, v = target[0], target[1:]
    rel = q[:, :1] * (-v) + w * q[:, 1:] - np.cross(v, q[:, 1:])
    return np.degrees(2.0 * np.arcsin(np.minimum(1.0, np.linalg.norm(rel, axis=1))))


def small_sweep(tmp_path, members=3, duration=120.0, every=10, metrics=None, extra=""):
    """A sweep over slew-wheels.toml (copied next to it, shortened, written every `every` steps)."""
    base = SLEW_WHEELS.read_text().replace("duration = 300.0", f"duration = {duration}").replace(
        "every = 10", f"every = {every}")
    (tmp_path / "slew-wheels.toml").write_text(base)
    metrics = metrics or ["pointing_error_deg", "settling_time", "max_wheel_torque", "max_wheel_speed",
                          "saturation_time", "control_effort"]
    text = (f'[ensemble]\nscenario = "slew-wheels.toml"\nmembers = {members}\nseed = 4\n'
            f'metrics = [{", ".join(chr(34) + m + chr(34) for m in metrics)}]\nsettle_band_deg = 0.1\n'
            f'trajectories = "all"\n{extra}'
            '[[vary]]\nkey = "body.inertia[0][0]"\nuniform = { low = 9.5, high = 10.5 }\n'
            '[[vary]]\nkey = "initial.quaternion"\nattitude_error_deg = 2.0\n')
    (tmp_path / "sweep.toml").write_text(text)
    return tmp_path / "sweep.toml"


def test_the_metrics_are_those_of_the_members_own_run(tmp_path):
    # Each member's run folder (trajectories = "all", every step written): the metrics recomputed from its
    # trajectory and summary by numpy. The pointing error is the same angle by another formula (asin here,
    # atan2 there): equal to 1e-9 deg, round-off of the angle near 0.001 deg (the 2 asin form loses digits
    # near 0, not beyond 1e-12 relative of the larger errors). The settling time is compared exactly: both
    # are a step's t = k h where the last excursion ends. The effort sum_i sum_k |u_i,k| h is the same sum in
    # another order: 1e-12 relative.
    path = small_sweep(tmp_path, members=3, every=1)
    proc = ensemble(path, "--out", tmp_path / "out", "--threads", "2")
    assert proc.returncode == 0, proc.stderr
    import lgvi
    table = rows(tmp_path / "out" / "members.csv")
    curves = rows(tmp_path / "out" / "pointing_error.csv")
    assert len(table) == 3 and len(curves) == 3 * 1201
    for m in table:
        i = int(m["index"])
        r = lgvi.load(tmp_path / "out" / "members" / f"{i:06d}")
        e = pointing_error_deg(r.q)
        assert float(m["pointing_error_deg"]) == pytest.approx(e[-1], abs=1e-9)
        curve = np.array([float(c["pointing_error_deg"]) for c in curves if int(c["index"]) == i])
        times = np.array([float(c["t"]) for c in curves if int(c["index"]) == i])
        assert np.array_equal(times, r.t)
        assert np.abs(curve - e).max() < 1e-9
        outside = np.nonzero(e > 0.1)[0]
        assert float(m["settling_time"]) == r.t[outside[-1] + 1]
        torques = np.column_stack([w["torque"] for w in r.wheels.values()])
        speeds = np.column_stack([w["speed"] for w in r.wheels.values()])
        assert float(m["max_wheel_torque"]) == np.abs(torques).max() == 0.01
        assert float(m["max_wheel_speed"]) == np.abs(speeds).max()
        effort = (np.abs(torques[:-1]) * 0.1).sum()
        assert float(m["control_effort"]) == pytest.approx(effort, rel=1e-12)
        assert float(m["control_effort"]) == r.summary["wheel_totals"]["control_effort"]
        # Time at a limit: the steps that began with some wheel's torque at its limit (0.01) or held at max_speed
        # (none reach 600 rad/s here).
        limited = (np.abs(torques[:-1]) == 0.01).any(axis=1).sum() * 0.1
        assert float(m["saturation_time"]) == pytest.approx(limited, rel=1e-12) and limited > 1.0
        assert float(m["saturation_time"]) == r.summary["wheel_totals"]["time_saturated"]


def test_attitude_errors_are_rotations_of_the_stated_size_composed_with_the_base(tmp_path):
    # 4000 draws of a 2 deg rms error: the angle's mean square within 4 standard errors of 4 deg^2 (its
    # variance is 2 sigma^4 for a normal angle), the axes unit vectors to round-off with a mean within 4
    # standard errors of 0 (each component's variance is 1/3 on the sphere); the member's quaternion is
    # q0 (x) dq to round-off.
    import lgvi
    from lgvi import _core
    base = (SOURCE / "scenarios" / "paper-orbit.toml").read_text()
    sweep = ('[ensemble]\nscenario = "paper-orbit.toml"\nmembers = 4000\nseed = 11\n'
             '[[vary]]\nkey = "initial.quaternion"\nattitude_error_deg = 2.0\n')
    plan = _core.ensemble_plan(sweep, "sweep", base)
    names = plan.header.split(",")
    at = names.index("initial.quaternion.error_deg")
    assert names[at:at + 4] == ["initial.quaternion.error_deg", "initial.quaternion.error_axis[0]",
                                "initial.quaternion.error_axis[1]", "initial.quaternion.error_axis[2]"]
    v = np.array([plan.varied(i) for i in range(plan.members)])
    angle, axis = v[:, 0], v[:, 1:]
    n = len(v)
    assert (angle >= 0).all()
    assert abs((angle ** 2).mean() - 4.0) < 4 * math.sqrt(2 * 16.0 / n)
    assert np.abs(np.linalg.norm(axis, axis=1) - 1).max() < 4e-16
    assert np.abs(axis.mean(axis=0)).max() < 4 * math.sqrt(1 / 3 / n)
    q0 = np.array(tomllib.loads(base)["initial"]["quaternion"], dtype=float)
    for i in (0, 1, 2, 3999):
        half = math.radians(angle[i]) / 2
        dq = np.concatenate([[math.cos(half)], math.sin(half) * axis[i]])
        q = np.array(tomllib.loads(plan.member_toml(i))["initial"]["quaternion"])
        assert np.abs(q - product(q0, dq)).max() < 1e-15
    # A base whose attitude is initial.attitude (LVLH): the draw becomes its error, a body-frame rotation
    # after roll, pitch and yaw; the run starts at q_base (x) dq.
    base = SLEW_WHEELS.read_text()
    plan = _core.ensemble_plan(sweep.replace("paper-orbit", "slew-wheels").replace("4000", "2"), "sweep", base)
    start = lgvi.Scenario.from_toml(SLEW_WHEELS)
    q_base = np.asarray(start.quaternion, dtype=float)
    for i in range(2):
        text = plan.member_toml(i)
        assert "error = [" in text
        (tmp_path / f"m{i}.toml").write_text(text)
        member = lgvi.Scenario.from_toml(tmp_path / f"m{i}.toml")
        a = plan.varied(i)
        half = math.radians(a[0]) / 2
        dq = np.concatenate([[math.cos(half)], math.sin(half) * np.array(a[1:])])
        assert np.abs(np.asarray(member.quaternion) - product(q_base, dq)).max() < 1e-15


def test_an_inertia_element_is_varied_by_its_indices(tmp_path):
    from lgvi import _core
    base = SLEW_WHEELS.read_text()
    sweep = ('[ensemble]\nscenario = "slew-wheels.toml"\n[[vary]]\nkey = "body.inertia[1][1]"\n'
             'values = [11.5, 12.5]\n')
    plan = _core.ensemble_plan(sweep, "sweep", base)
    assert plan.header.split(",")[1] == "body.inertia[1][1]"
    for i, value in enumerate((11.5, 12.5)):
        inertia = tomllib.loads(plan.member_toml(i))["body"]["inertia"]
        assert inertia == [[10.0, 0.0, 0.0], [0.0, value, 0.0], [0.0, 0.0, 14.0]]


@pytest.mark.parametrize("key", ["body.wheel[1].max_torque", "body.wheel.1.max_torque"])
def test_a_wheel_parameter_is_varied_by_its_wheels_index(tmp_path, key):
    # The second wheel's limit, in the form the reader's messages name it (body.wheel[1]) or by a dotted
    # index: that wheel's key alone changes, and the column is the key as given.
    from lgvi import _core
    sweep = f'[ensemble]\nscenario = "slew-wheels.toml"\n[[vary]]\nkey = "{key}"\nvalues = [0.002, 0.02]\n'
    plan = _core.ensemble_plan(sweep, "sweep", SLEW_WHEELS.read_text())
    assert plan.header.split(",")[1] == key
    for i, value in enumerate((0.002, 0.02)):
        wheels = tomllib.loads(plan.member_toml(i))["body"]["wheel"]
        assert [w["max_torque"] for w in wheels] == [0.01, value, 0.01, 0.01]


BAD = [
    ('key = "body.inertia[3][0]"\nvalues = [1.0]', "vary[0].key", "names no element"),
    ('key = "body.wheel[4].inertia"\nvalues = [0.01]', "vary[0].key", "names no table"),
    ('key = "body.wheel[01].inertia"\nvalues = [0.01]', "vary[0].key", "names no table"),
    ('key = "body.inertia[0]"\nvalues = [1.0]', "vary[0].key", "another shape"),
    ('key = "body.inertia[0][01]"\nvalues = [1.0]', "vary[0].key", "indices from 0"),
    ('key = "initial.quaternion"\nattitude_error_deg = -1.0', "vary[0].attitude_error_deg", "[0, 180]"),
    ('key = "initial.omega"\nattitude_error_deg = 1.0', "vary[0].key", "initial.attitude"),
]


@pytest.mark.parametrize("vary, key, words", BAD)
def test_bad_vary_entries_are_one_line(tmp_path, vary, key, words):
    small_sweep(tmp_path)
    draws = "" if "values" in vary else "members = 2\nseed = 1\n"  # a grid has no members or seed
    (tmp_path / "bad.toml").write_text(f'[ensemble]\nscenario = "slew-wheels.toml"\n{draws}[[vary]]\n{vary}\n')
    proc = ensemble(tmp_path / "bad.toml", "--out", tmp_path / "out")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert f"'{key}'" in proc.stderr and words in proc.stderr, proc.stderr


@pytest.mark.parametrize("edit, key, words", [
    (lambda t: t.replace('"control_effort"]', '"control_effort", "overshoot"]'), "ensemble.metrics[6]",
     "must be one of"),
    (lambda t: t.replace("settle_band_deg = 0.1\n", ""), "ensemble.settle_band_deg", "settling_time needs"),
    (lambda t: t.replace("settle_band_deg = 0.1", "settle_band_deg = 0.0"), "ensemble.settle_band_deg", "(0, 180)"),
    (lambda t: t.replace('"max_wheel_speed", ', '"max_wheel_speed", "max_wheel_speed", '), "ensemble.metrics[4]",
     "given twice"),
])
def test_bad_metrics_are_one_line(tmp_path, edit, key, words):
    path = small_sweep(tmp_path)
    path.write_text(edit(path.read_text()))
    proc = ensemble(path, "--out", tmp_path / "out")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert f"'{key}'" in proc.stderr and words in proc.stderr, proc.stderr


def test_metrics_the_base_cannot_give_are_refused(tmp_path):
    # paper-orbit.toml has neither an attitude controller nor wheels.
    shutil.copy(SOURCE / "scenarios" / "paper-orbit.toml", tmp_path / "paper-orbit.toml")
    for metric, words in (("settling_time", "attitude-control"), ("max_wheel_speed", "[[body.wheel]]")):
        (tmp_path / "s.toml").write_text(f'[ensemble]\nscenario = "paper-orbit.toml"\nmembers = 2\nseed = 1\n'
                                         f'metrics = ["{metric}"]\nsettle_band_deg = 0.1\n'
                                         '[[vary]]\nkey = "initial.quaternion"\nattitude_error_deg = 1.0\n')
        proc = ensemble(tmp_path / "s.toml", "--out", tmp_path / metric)
        assert proc.returncode == 2 and "'ensemble.metrics'" in proc.stderr and words in proc.stderr, proc.stderr


def test_the_monte_carlo_is_identical_on_threads_and_ranks_and_from_python(tmp_path):
    # scenarios/ensembles/slew-wheels-monte-carlo.toml, 200 members: members.csv and pointing_error.csv byte
    # for byte on 1 thread, 2 threads and mpirun -n 2; lgvi.ensemble gives the same table and curves. Every
    # member converges: it settles to 0.2 deg within 80 s and ends within 0.1 deg (the sensors' offset, each
    # member with its own noise); no wheel exceeds its torque limit (0.01 N m) or comes near its speed limit
    # (600 rad/s).
    outs = {}
    runs = [("t1", ["--threads", "1"], 0), ("t2", ["--threads", "2"], 0)] + ([("mpi2", [], 2)] if MPIRUN else [])
    for name, extra, mpi in runs:
        proc = ensemble(MONTE_CARLO, "--out", tmp_path / name, *extra, mpi=mpi)
        assert proc.returncode == 0, proc.stderr
        outs[name] = [(tmp_path / name / f).read_bytes() for f in ("members.csv", "pointing_error.csv")]
    for name in outs:
        assert outs[name] == outs["t1"], name
    table = rows(tmp_path / "t1" / "members.csv")
    assert len(table) == 200 and all(m["completed"] == "1" for m in table)
    settle = np.array([float(m["settling_time"]) for m in table])
    assert np.isfinite(settle).all() and settle.max() < 80.0
    assert max(float(m["pointing_error_deg"]) for m in table) < 0.1
    assert max(float(m["max_wheel_torque"]) for m in table) <= 0.01
    assert max(float(m["max_wheel_speed"]) for m in table) < 100.0
    # lgvi.ensemble sweeps a Scenario's text, in which initial.orbit and initial.attitude are converted to
    # plain keys (the attitude error then composes with that quaternion and leaves the rate as it was): the
    # CLI over the same text gives the same bytes.
    import lgvi
    sweep = tomllib.loads(MONTE_CARLO.read_text())
    sc = lgvi.Scenario.from_toml(SLEW_WHEELS)
    (tmp_path / "converted.toml").write_text(sc.toml)
    (tmp_path / "sweep.toml").write_text(MONTE_CARLO.read_text().replace("../slew-wheels.toml", "converted.toml"))
    proc = ensemble(tmp_path / "sweep.toml", "--out", tmp_path / "converted")
    assert proc.returncode == 0, proc.stderr
    result = lgvi.ensemble(sc, sweep["vary"], members=200, seed=30, metrics=sweep["ensemble"]["metrics"],
                           settle_band_deg=0.2)
    assert result.text.encode() == (tmp_path / "converted" / "members.csv").read_bytes()
    curves = rows(tmp_path / "converted" / "pointing_error.csv")
    frames = len(result.pointing_times)
    assert result.pointing_error.shape == (200, frames) and result.settle_band_deg == 0.2
    assert np.array_equal(result.pointing_error.ravel(), [float(c["pointing_error_deg"]) for c in curves])


def test_the_gnc_figures(tmp_path):
    path = small_sweep(tmp_path, members=4)
    proc = ensemble(path, "--out", tmp_path / "out", figures=True)
    assert proc.returncode == 0, proc.stderr
    for name in ("pointing_error.png", "metrics.png", "error_distribution.png"):
        assert (tmp_path / "out" / name).stat().st_size > 10000, name


def test_resume_and_the_members_table_with_metrics(tmp_path):
    # A folder stopped with one member done (its journal cut to that row, no tables): --resume completes it
    # to the bytes of the uninterrupted ensemble (members.csv and pointing_error.csv). With [output] format =
    # "npz" the members table members.npz holds the metric columns with the CSV's numbers (17 digits: the
    # same doubles).
    path = small_sweep(tmp_path, members=3, duration=30.0)
    path.write_text(path.read_text().replace('trajectories = "all"\n', ""))
    assert ensemble(path, "--out", tmp_path / "whole").returncode == 0
    assert ensemble(path, "--out", tmp_path / "cut").returncode == 0
    journal = (tmp_path / "cut" / "journal.csv").read_text().splitlines(keepends=True)
    (tmp_path / "cut" / "journal.csv").write_text(journal[0])
    for name in ("members.csv", "pointing_error.csv"):
        (tmp_path / "cut" / name).unlink()
    proc = ensemble("--resume", tmp_path / "cut")
    assert proc.returncode == 0, proc.stderr
    for name in ("members.csv", "pointing_error.csv"):
        assert (tmp_path / "cut" / name).read_bytes() == (tmp_path / "whole" / name).read_bytes(), name
    base = tmp_path / "slew-wheels.toml"
    base.write_text(base.read_text().replace("[output]\n", '[output]\nformat = "npz"\n'))
    assert ensemble(path, "--out", tmp_path / "npz").returncode == 0
    table = np.load(tmp_path / "npz" / "members.npz")
    for m in rows(tmp_path / "npz" / "members.csv"):
        i = int(m["index"])
        for name in ("pointing_error_deg", "settling_time", "control_effort", "max_wheel_speed"):
            # (settling_time is NaN here: 30 s is too short to settle)
            assert np.array_equal(table[name][i], float(m[name]), equal_nan=True), name


def test_a_failing_member_has_nan_metrics_and_a_padded_curve(tmp_path):
    # A grid over the solver's iteration limit: with 1 iteration the gyrostat's equation does not converge at
    # step 0, so member 1 fails there. Its metrics are NaN, and its pointing-error curve holds the initial state's
    # error (observed before the step) and NaN after it, so the two tables stay aligned. Member 0 completes.
    base = SLEW_WHEELS.read_text().replace("duration = 300.0", "duration = 30.0")
    (tmp_path / "slew-wheels.toml").write_text(base)
    (tmp_path / "sweep.toml").write_text(
        '[ensemble]\nscenario = "slew-wheels.toml"\nmetrics = ["pointing_error_deg", "settling_time", '
        '"max_wheel_speed"]\nsettle_band_deg = 0.2\n[[vary]]\nkey = "integrator.max_iterations"\nvalues = [50, 1]\n')
    proc = ensemble(tmp_path / "sweep.toml", "--out", tmp_path / "out")
    assert proc.returncode == 0, proc.stderr
    done, failed = rows(tmp_path / "out" / "members.csv")
    assert done["completed"] == "1" and failed["completed"] == "0" and "did not converge" in failed["error"]
    assert all(math.isnan(float(failed[m])) for m in ("pointing_error_deg", "settling_time", "max_wheel_speed"))
    assert math.isfinite(float(done["pointing_error_deg"]))
    curve = [float(c["pointing_error_deg"]) for c in rows(tmp_path / "out" / "pointing_error.csv")
             if c["index"] == "1"]
    assert len(curve) == 31 and curve[0] == pytest.approx(30.0, abs=1e-9) and all(math.isnan(e) for e in curve[1:])


def test_one_value_is_varied_once_whatever_its_spelling():
    # body.wheel[1] and body.wheel.1 are the same wheel: two [[vary]] of it are one line naming both.
    from lgvi import _core
    sweep = ('[ensemble]\nscenario = "slew-wheels.toml"\n[[vary]]\nkey = "body.wheel[1].max_torque"\n'
             'values = [0.002]\n[[vary]]\nkey = "body.wheel.1.max_torque"\nvalues = [0.02]\n')
    with pytest.raises(ValueError, match=r"'vary\[1\].key'.*the same value as vary\[0\]"):
        _core.ensemble_plan(sweep, "sweep", SLEW_WHEELS.read_text())


def test_a_body_named_with_brackets_is_varied_by_its_name():
    # A [[bodies]] name may hold brackets: "bodies.sat[1].omega" is that body's, not an entry's index.
    from lgvi import _core
    base = (SOURCE / "tests" / "reference" / "formation-wheels.toml").read_text().replace('"alpha"', '"sat[1]"')
    sweep = '[ensemble]\nscenario = "formation.toml"\n[[vary]]\nkey = "bodies.sat[1].omega"\nvalues = [[0.0, 0.0, 0.1]]\n'
    plan = _core.ensemble_plan(sweep, "sweep", base)
    assert tomllib.loads(plan.member_toml(0))["bodies"][0]["omega"] == [0.0, 0.0, 0.1]
