"""Composition methods from Python and the command line: `order` and
`composition` reach the run, the Python run equals the CLI's to the last bit,
the summary records the table, and bad values fail with the reader's
messages. The numerics (orders, conservation) are tested in
tests/test_composition.cpp.
"""

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

BINARY = os.environ.get("LGVI_BINARY")
SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
PAPER_ORBIT = SOURCE / "scenarios" / "paper-orbit.toml"

if BINARY is None:
    pytest.importorskip("lgvi._core", reason="the built lgvi package (build/python) is not on PYTHONPATH")
import lgvi  # noqa: E402

needs_cli = pytest.mark.skipif(BINARY is None, reason="LGVI_BINARY not set (run through ctest)")


def short_orbit(**changes):
    return lgvi.Scenario.from_toml(PAPER_ORBIT).replace(duration=10.0, every=100, **changes)


def test_order_and_composition_properties():
    s = short_orbit(order=6)
    assert s.order == 6
    assert len(s.composition) == 9
    # Kahan & Li s9odr6a's first and middle coefficients, as the header has them.
    assert s.composition[0] == pytest.approx(0.39216144400731413928, abs=1e-16)
    assert s.composition[4] == pytest.approx(0.79854399093482996340, abs=1e-16)
    assert sum(s.composition) == pytest.approx(1.0, abs=9 * 2.2e-16)
    plain = short_orbit()
    assert plain.order == 2 and plain.composition == (1.0,)
    # Setting one drops the other.
    assert short_orbit(order=4).replace(composition=[0.5, 0.5]).order == 2
    assert short_orbit(composition=[0.5, 0.5]).replace(order=8).composition[0] == pytest.approx(0.7416703643506129)


def test_higher_order_is_more_accurate_and_keeps_the_invariants():
    # Paper orbit to t = 10 at h = 0.01: order 4 brings the energy error from
    # ~6e-7 to ~1e-11 (docs/method.md, 1e5 steps); |q| - 1 and the momentum stay at
    # round-off (1e3 steps x 5 sub-steps: well under 1e-13, allowed 1e-12).
    r2 = lgvi.simulate(short_orbit())
    r4 = lgvi.simulate(short_orbit(order=4))
    e2 = np.max(np.abs(r2.energy_error))
    e4 = np.max(np.abs(r4.energy_error))
    assert e4 < e2 / 1000
    assert np.max(np.abs(r4.quat_norm_error)) < 1e-12
    assert np.max(np.abs(r4.momentum_error)) < 1e-11


@needs_cli
def test_cli_and_python_agree_to_the_last_bit_and_summary_records_the_table(tmp_path):
    scenario = short_orbit(method="so3-lgvi", composition=[0.5, 0.5])
    path = tmp_path / "s.toml"
    scenario.save(path)
    out = tmp_path / "run"
    subprocess.run([BINARY, "run", str(path), "--out", str(out)], check=True, capture_output=True)
    summary = json.loads((out / "summary.json").read_text())
    integ = summary["setup"]["integrator"]
    assert integ["order"] == 2 and integ["composition"] == [0.5, 0.5]
    python = lgvi.simulate(scenario)
    final = summary["final"]
    assert python.q[-1].tolist() == final["quaternion"]
    assert python.x[-1].tolist() == final["position"]
    show = subprocess.run([BINARY, "show", str(out)], check=True, capture_output=True, text=True).stdout
    assert "composed to order 2" in show and "per sub-step" in show


@pytest.mark.parametrize("changes, message", [
    (dict(order=3), "integrator.order"),
    (dict(order=4, method="rk4-normalized"), "symmetric one-step"),
    (dict(composition=[0.5, 0.6]), "sum to 1"),
    (dict(composition=[0.2, 0.3, 0.5]), "palindromic"),
    (dict(composition=0.5), "composition: must be a sequence"),
    (dict(composition=[0.5, "a"]), "composition[1]"),
])
def test_bad_values_name_the_key(changes, message):
    with pytest.raises(ValueError, match=message.replace("[", r"\[")):
        short_orbit(**changes)
