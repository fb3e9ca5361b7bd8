"""Contact between bodies through `lgvi run` and the Python package: a run that
meets a contact stops at the step computed here from its own rows, with a
whole partial output and a one-line message; shapes from Python; on_contact
"warn" and "ignore". Run by ctest with LGVI_BINARY set."""
import json
import math
import os
import pathlib
import subprocess

import numpy as np
import pytest

BINARY = os.environ.get("LGVI_BINARY")
SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
pytestmark = pytest.mark.skipif(BINARY is None, reason="LGVI_BINARY not set (run through ctest)")


def rotation(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def ball_gap(rows, balls):
    """min over ball pairs of (centre distance - r_i - r_j) for the two bodies' rows (t, body, x, q, ...)."""
    centres = []
    for row, body in zip(rows, balls):
        r = rotation(row[5:9])
        centres.append([(row[2:5] + r @ np.array(b["position"]), b["radius"]) for b in body])
    return min(np.linalg.norm(ci - cj) - ri - rj for ci, ri in centres[0] for cj, rj in centres[1])


def test_infall_stops_at_the_first_step_of_overlap_with_a_whole_partial_output(tmp_path):
    # The binary asteroid's secondary released at rest: it falls onto the
    # primary under mutual gravity. Every step written, so the rows show the
    # step before the contact (apart) and the contact step (overlapping),
    # computed here from the rows and the balls alone.
    text = (SOURCE / "scenarios" / "binary-asteroid.toml").read_text()
    for old, new in (("momentum = [0.0, -0.010585122480499263, 0.0]", "momentum = [0.0, 0.0, 0.0]"),
                     ("momentum = [0.0, 0.010585122480499263, 0.0]", "momentum = [0.0, 0.0, 0.0]"),
                     ("every = 10", "every = 1")):
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / "infall.toml"
    path.write_text(text)
    out = tmp_path / "run"
    proc = subprocess.run([BINARY, "run", str(path), "--out", str(out), "--no-figures", "-q"], capture_output=True,
                          text=True)
    assert proc.returncode == 1, proc.stderr
    first_line = proc.stderr.splitlines()[0]
    assert first_line.startswith("lgvi: error: contact: ball ") and "bodies[1] (\"secondary\")" in first_line
    summary = json.loads((out / "summary.json").read_text())
    assert summary["completed"] is False
    assert first_line == "lgvi: error: " + summary["error"]
    k = summary["steps"]
    assert f"(step {k})" in summary["error"] and 0 < k < summary["steps_planned"]
    lines = (out / "trajectory.csv").read_text().splitlines()
    assert len(lines) == 1 + 2 * (k + 1)  # header, then both bodies at steps 0..k: whole rows
    rows = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
    assert rows.shape[1] == 26 and rows[-1, 0] == pytest.approx(k * 0.01, rel=1e-12)
    balls = [b["balls"] for b in summary["setup"]["bodies"]]
    # The rows are written with 17 digits: the gaps are exact to ~1e-15, far
    # below one step's change of the gap (~1e-3 at the infall speed ~0.4).
    assert ball_gap(rows[-4:-2], balls) > 0.0
    assert ball_gap(rows[-2:], balls) < 0.0
    contact = summary["contacts"][0]
    assert contact["first_step"] == k and contact["bodies"] == ["primary", "secondary"]
    show = subprocess.run([BINARY, "show", str(out)], capture_output=True, text=True).stdout
    assert f"1 episode(s); the first: primary and secondary, steps {k} to {k}" in show
    assert contact["max_depth"] == pytest.approx(-ball_gap(rows[-2:], balls), abs=1e-12)


def test_shapes_from_python_have_the_exact_mass_and_inertia():
    import lgvi
    e = lgvi.Body.ellipsoid((3.0, 2.0, 0.5), density=2.0)
    m = 2.0 * 4.0 / 3.0 * math.pi * 3.0 * 2.0 * 0.5
    # The same formula in another order of operations: a few ulps.
    assert e.mass == pytest.approx(m, rel=1e-15)
    assert np.allclose(e.inertia, np.diag([m * (4 + 0.25) / 5, m * (9 + 0.25) / 5, m * (9 + 4) / 5]), rtol=1e-15, atol=0)
    assert e.extent == "ellipsoid" and list(e.semi_axes) == [3.0, 2.0, 0.5]
    s = lgvi.Body.sphere(0.5, mass=3.0)
    assert s.mass == 3.0 and s.inertia[0, 0] == pytest.approx(0.4 * 3.0 * 0.25, rel=1e-15)
    assert lgvi.Body(mass=1.0, inertia=np.eye(3), radius=2.0).extent == "sphere"
    assert lgvi.Body(mass=1.0, inertia=np.eye(3)).extent == "point"
    # A shape body in a single-body scenario: written as its shape keys and read back by the CLI's reader.
    sc = lgvi.Scenario(body=e, step=0.1, duration=1.0, position=(0, 0, 0), quaternion=(1, 0, 0, 0),
                       momentum=(0, 0, 0), omega=(0.1, 0.2, 0.3))
    assert 'shape = "ellipsoid"' in sc.toml and sc.body.mass == e.mass
    assert np.array_equal(sc.body.inertia, e.inertia)
    for call, message in ((lambda: lgvi.Body.sphere(1.0), "density, mass: give exactly one"),
                          (lambda: lgvi.Body.sphere(1.0, density=1.0, mass=1.0), "density, mass: give exactly one"),
                          (lambda: lgvi.Body.ellipsoid((1.0, -1.0, 1.0), density=1.0), "semi_axes"),
                          (lambda: lgvi.Body.sphere(-1.0, density=1.0), "radius")):
        with pytest.raises(ValueError, match=message):
            call()


def head_on(on_contact=None):
    """Two ellipsoids, long axes along x, closing at speed 1 from 10 apart, no forces: they touch at a
    centre distance 2 + 1.5 = 3.5, first overlap at step floor(6.5 / 0.07) + 1 = 93 (6.5 / 0.07 = 92.86)."""
    import lgvi
    bodies = [lgvi.Body.ellipsoid((2.0, 1.0, 0.5), density=1.0), lgvi.Body.ellipsoid((1.5, 0.5, 0.5), mass=2.0)]
    kw = {} if on_contact is None else {"on_contact": on_contact}
    return lgvi.Scenario.from_arrays(bodies=bodies, positions=[[0.0, 0, 0], [10.0, 0, 0]],
                                     quaternions=[[1.0, 0, 0, 0]] * 2, velocities=[[0.5, 0, 0], [-0.5, 0, 0]],
                                     omegas=np.zeros((2, 3)), names=["a", "b"], step=0.07, duration=20.0, every=10,
                                     **kw)


def test_python_stop_raises_with_the_run_so_far_and_warn_records_the_episode():
    import lgvi
    assert head_on().on_contact == "stop"
    with pytest.raises(lgvi.IntegrationError, match=r"contact: bodies\[0\] \(\"a\"\) and bodies\[1\] \(\"b\"\)") as e:
        lgvi.simulate(head_on())
    r = e.value.result
    assert r.summary["completed"] is False and r.summary["steps"] == 93
    assert r.t[-1] == pytest.approx(93 * 0.07, rel=1e-12)  # the contact step is the last row
    warned = lgvi.simulate(head_on("warn"))
    # Apart again when the centre distance passes -3.5: last overlap at floor(13.5 / 0.07) = 192 (192.86).
    (c,) = warned.summary["contacts"]
    assert (c["first_step"], c["last_step"]) == (93, 192)
    assert warned.summary["completed"] is True
    ignored = lgvi.simulate(head_on("ignore"))
    assert "contacts" not in ignored.summary and ignored.summary["setup"]["on_contact"] == "ignore"
    # The check only reads the state: the trajectories are the same.
    assert np.array_equal(warned.x, ignored.x) and np.array_equal(warned.q, ignored.q)


def test_resuming_a_run_that_a_contact_stopped_says_how_to_go_on(tmp_path):
    """A run stopped by a contact, with a checkpoint there: resuming it as it is would take one step
    and stop again, so --resume refuses in one line naming the fix ([run] on_contact = "warn"); with
    that set in the run's scenario copy it goes on and completes, with the episode from step 93 on."""
    scenario = tmp_path / "head-on.toml"
    scenario.write_text(head_on().toml)
    out = tmp_path / "run"
    proc = subprocess.run([BINARY, "run", str(scenario), "--out", str(out), "--checkpoint-every", "50",
                           "--no-figures", "-q"], capture_output=True, text=True)
    assert proc.returncode == 1 and "contact:" in proc.stderr
    proc = subprocess.run([BINARY, "run", "--resume", str(out), "--no-figures", "-q"], capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "stopped at step 93" in proc.stderr and 'on_contact = "warn"' in proc.stderr
    copy = out / "scenario.toml"
    text = copy.read_text()
    copy.write_text(text.replace('on_contact = "stop"', 'on_contact = "warn"') if 'on_contact = "stop"' in text
                    else text + '\n[run]\non_contact = "warn"\n')
    proc = subprocess.run([BINARY, "run", "--resume", str(out), "--no-figures", "-q"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["completed"] is True and summary["contacts"][0]["first_step"] == 93
