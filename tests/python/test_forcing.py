"""Forcing from Python and the command line: [[forcing]] runs write the column
"work" and E - E0 - W as the energy error; lgvi.PythonForcing reproduces a
built-in forcing and steps through lgvi.Stepper exactly as simulate() runs;
bad forcing fails with one clear message. The numerics (momentum balance,
exact solutions, orders, resume) are tested in tests/test_forcing.cpp.
"""

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

BINARY = os.environ.get("LGVI_BINARY")
SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
SLEW = SOURCE / "scenarios" / "attitude-slew.toml"

if BINARY is None:
    pytest.importorskip("lgvi._core", reason="the built lgvi package (build/python) is not on PYTHONPATH")
import lgvi  # noqa: E402

needs_cli = pytest.mark.skipif(BINARY is None, reason="LGVI_BINARY not set (run through ctest)")

DAMPED = """
[body]
mass = 2.0
inertia = [[0.5, 0.0, 0.0], [0.0, 0.8, 0.0], [0.0, 0.0, 1.1]]
[potential]
kind = "central"
mu = 1.0
[initial]
position = [3.0, 0.0, 0.0]
quaternion = [1.0, 0.0, 0.0, 0.0]
momentum = [0.0, 1.1, 0.2]
w = [0.3, 0.9, 1.4]
[integrator]
method = "lgvi"
step = 0.01
duration = 2.0
"""
J_INV = np.diag([1 / 0.5, 1 / 0.8, 1 / 1.1])


def scenario(extra=""):
    return lgvi.Scenario.from_string(DAMPED + extra, "damped")


@needs_cli
def test_cli_slew_writes_work_and_the_energy_balance(tmp_path):
    out = tmp_path / "slew"
    subprocess.run([BINARY, "run", str(SLEW), "--no-figures", "-q", "--out", str(out)], check=True)
    r = lgvi.load(out)
    assert "work" in r.columns and r.data.shape[1] == 22
    e0 = r.columns["energy"][0]
    # The run loop's expression, evaluated in the same order: equal to the last bit.
    assert np.array_equal(r.columns["energy_error"], r.columns["energy"] - e0 - r.columns["work"])
    summary = json.loads((out / "summary.json").read_text())
    assert summary["work"] == r.columns["work"][-1]
    assert summary["energy_error_is"] == "E - E0 - work"
    # The slew settles: the attitude is within 1e-3 rad of the target (the
    # disturbance torque holds an offset of ~2 M_dist / k_p = 7e-4 rad).
    q = r.q[-1]
    target = np.array([np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)])
    assert 2 * np.arccos(min(1.0, abs(q @ target))) < 1e-3
    # The integrator's own energy error is far below the work done (9e-3 J).
    assert summary["max_abs_energy_error"] < 1e-8
    # lgvi show names the balance it reports and the momentum it does not conserve.
    shown = subprocess.run([BINARY, "show", str(out)], capture_output=True, text=True, check=True).stdout
    assert f"max |E - E0 - W| = {summary['max_abs_energy_error']:.3e} (W: the forcing's work, " in shown
    assert "-- a change: this run's dynamics does not conserve it" in shown


def test_python_forcing_matches_the_built_in_damping():
    c = 0.2

    def damping(t, x, q, p, w):
        return np.zeros(3), -0.5 * c * (J_INV @ w)

    built_in = lgvi.simulate(scenario(f"[[forcing]]\nkind = \"damping\"\nc = {c}\n"))
    python = lgvi.simulate(scenario(), forcing=lgvi.PythonForcing(damping))
    assert python.data.shape == built_in.data.shape == (201, 22)
    # The same formula, numpy's J^-1 against Eigen's: equal to a few ulps of
    # |w| ~ 1 per step, 1e-12 after 200 steps.
    np.testing.assert_allclose(python.data, built_in.data, rtol=0, atol=1e-12)
    assert python.columns["work"][-1] < -1e-2  # damping takes energy out


def test_stepper_with_forcing_steps_like_simulate():
    def push(t, x, q, p, w):
        return np.array([0.01 * t, 0.0, -0.02]), np.array([0.0, 0.003, 0.0])

    forcing = lgvi.PythonForcing(push, velocity_dependent=False)
    run = lgvi.simulate(scenario(), forcing=forcing)
    stepper = lgvi.Stepper(scenario(), forcing=forcing)
    rows = [stepper.row]
    for _ in range(200):
        stepper.step()
        rows.append(stepper.row)
    assert np.array_equal(np.array(rows), run.data)
    assert stepper.work == run.columns["work"][-1]
    assert stepper.energy_error == run.columns["energy_error"][-1]


def test_forcing_on_one_named_body():
    text = """
[[bodies]]
name = "a"
mass = 1.0
inertia = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
position = [0.0, 0.0, 0.0]
quaternion = [1.0, 0.0, 0.0, 0.0]
momentum = [0.0, 0.0, 0.0]
w = [0.0, 0.0, 0.0]
[[bodies]]
name = "b"
mass = 1.0
inertia = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
position = [5.0, 0.0, 0.0]
quaternion = [1.0, 0.0, 0.0, 0.0]
momentum = [0.0, 0.0, 0.0]
w = [0.0, 0.0, 0.0]
[potential]
kind = "none"
[integrator]
step = 0.01
duration = 1.0
"""
    r = lgvi.simulate(lgvi.Scenario.from_string(text, "two"),
                      forcing=lgvi.PythonForcing(lambda t, x, q, p, w: ((1.0, 0.0, 0.0), (0.0, 0.0, 0.0)), body="b"))
    assert r.data.shape[2] == 27
    # A constant unit force on b alone for 1 s: p_b = (1, 0, 0) to round-off, a untouched.
    assert np.array_equal(r.p[-1, 0], [0.0, 0.0, 0.0])
    np.testing.assert_allclose(r.p[-1, 1], [1.0, 0.0, 0.0], rtol=0, atol=1e-14)


def test_bad_forcing_fails_clearly():
    with pytest.raises(ValueError, match="function: must be callable"):
        lgvi.PythonForcing(42)
    with pytest.raises(ValueError, match=r"forcing: must return \(force, torque\)"):
        lgvi.simulate(scenario(), forcing=lambda t, x, q, p, w: (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match='no body is named "c"'):
        lgvi.simulate(scenario(), forcing=lgvi.PythonForcing(lambda *a: ((0, 0, 0), (0, 0, 0)), body="c"))
    with pytest.raises(lgvi.IntegrationError, match="forcing returned a non-finite"):
        lgvi.simulate(scenario(), forcing=lambda t, x, q, p, w: ((np.nan, 0, 0), (0, 0, 0)))
    rk4 = scenario().replace(method="rk4-normalized")
    with pytest.raises(ValueError, match="does not take"):
        lgvi.simulate(rk4, forcing=lambda t, x, q, p, w: ((0, 0, 0), (0, 0, 0)))


def test_forcing_with_fresh_noise_on_every_call_is_named():
    """Noise drawn anew on every call is not a function of (t, state): the run stops at once with a
    message that says so and how to draw noise (once per control sample), not "too stiff"."""
    rng = np.random.default_rng(3)

    def noisy(t, x, q, p, w):
        return np.zeros(3), rng.normal(0.0, 1e-3, 3)

    for velocity_dependent in (True, False):
        with pytest.raises(Exception, match="different values for the same time and state") as info:
            lgvi.simulate(scenario(), forcing=lgvi.PythonForcing(noisy, velocity_dependent=velocity_dependent))
        assert "once per control sample" in str(info.value)


def test_noise_drawn_per_control_sample_runs():
    """The pattern of examples/gyro_noise.py: a generator seeded by (seed, sample number) gives the
    same noise at every call within a sample, so the run completes, and its rows repeat exactly."""
    period = 0.05

    def sampled(t, x, q, p, w):
        sample = int(np.floor(t / period + 1e-9))
        return np.zeros(3), -0.1 * (0.5 * J_INV @ w) + np.random.default_rng([5, sample]).normal(0.0, 1e-3, 3)

    a = lgvi.simulate(scenario(), forcing=lgvi.PythonForcing(sampled))
    b = lgvi.simulate(scenario(), forcing=lgvi.PythonForcing(sampled))
    assert a.completed
    assert np.array_equal(a.data, b.data)
