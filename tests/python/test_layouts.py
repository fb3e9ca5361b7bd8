"""The two row layouts of a trajectory ([output] layout = "single-body" | "long") and the one Result that
reads both (issue 27, "one face"). The layout only chooses which columns the run loop writes, so every number
written in both is the same double: the assertions here are bit for bit (np.array_equal), except where a
column exists in one layout only and Python computes it (said where). Run by ctest with LGVI_BINARY set."""
import json
import os
import pathlib
import subprocess
import warnings

import numpy as np
import pytest

BINARY = os.environ.get("LGVI_BINARY")
SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
pytestmark = pytest.mark.skipif(BINARY is None, reason="LGVI_BINARY not set (run through ctest)")


def run(scenario, out, *extra):
    return subprocess.run([BINARY, "run", str(scenario), "--out", str(out), "--no-figures", "-q", *extra],
                          capture_output=True, text=True)


def variant(tmp_path, name, replacements, file_name):
    text = (SOURCE / "scenarios" / f"{name}.toml").read_text()
    for old, new in replacements:
        assert old in text, old
        text = text.replace(old, new, 1)
    path = tmp_path / file_name
    path.write_text(text)
    return path


def orbit(tmp_path, layout=None, name="orbit.toml"):
    """The paper's orbit, 2 time units (200 steps, a row every 10), in the given layout (None: the default)."""
    extra = [("duration = 1000.0", "duration = 2.0")]
    if layout:
        extra.append(("every = 10", f'every = 10\nlayout = "{layout}"'))
    return variant(tmp_path, "paper-orbit", extra, name)


# The paper-orbit body as a [[bodies]] scenario of one body (the same balls, state and integrator).
ONE_OF_BODIES = """
[[bodies]]
name = "triangle"
position = [8.0, 0.0, 0.0]
quaternion = [1.0, 0.0, 0.0, 0.0]
momentum = [0.0, 1.0, 0.0]
w = [1.0, 2.0, 3.0]
[[bodies.ball]]
position = [0.0, 0.0, 0.0]
mass = 1.0
radius = 0.1
[[bodies.ball]]
position = [1.0, 0.0, 0.0]
mass = 1.0
radius = 0.1
[[bodies.ball]]
position = [0.5, 0.8660254037844386, 0.0]
mass = 1.0
radius = 0.1
[potential]
kind = "central"
mu = 1.0
[integrator]
method = "lgvi"
solver = "newton"
step = 0.01
duration = 2.0
[output]
every = 10
"""


def test_a_body_in_the_long_layout_writes_the_single_body_layouts_numbers(tmp_path):
    import lgvi
    assert run(orbit(tmp_path), tmp_path / "single").returncode == 0
    proc = run(orbit(tmp_path, "long", "long.toml"), tmp_path / "long")
    assert proc.returncode == 0, proc.stderr
    single, long = lgvi.load(tmp_path / "single"), lgvi.load(tmp_path / "long")
    assert (single.layout, long.layout) == ("single-body", "long")
    assert single.data.shape == (21, 21) and long.data.shape == (21, 1, 26)
    assert single.bodies == long.bodies == 1
    # Each body quantity, with the body axis in either layout, and one body's arrays: the same doubles.
    for quantity in ("x", "q", "p", "w", "quat_norm_error"):
        assert single.per_body(quantity).shape == long.per_body(quantity).shape
        assert np.array_equal(single.per_body(quantity), long.per_body(quantity)), quantity
        assert np.array_equal(getattr(single.body(0), quantity), getattr(long.body(0), quantity)), quantity
    for quantity in ("t", "energy", "energy_error", "L", "momentum_error"):
        assert np.array_equal(getattr(single, quantity), getattr(long, quantity)), quantity
    # The total linear momentum of one body is its p (the long layout's P columns hold it bit for bit); its
    # relative change the single-body layout has no column for: numpy's norm against Eigen's, a few ulps.
    assert np.array_equal(single.P, long.P)
    np.testing.assert_allclose(single.linear_momentum_error, long.linear_momentum_error, rtol=1e-14, atol=1e-300)
    # The summaries differ only in nothing: both are a [body] scenario's, with its wall-clock times.
    s1, s2 = (json.loads((tmp_path / d / "summary.json").read_text()) for d in ("single", "long"))
    for s in (s1, s2):
        for key in ("wall_seconds", "ns_per_step", "scenario"):
            s.pop(key, None)
    assert s1 == s2


def test_one_body_of_bodies_in_the_single_body_layout_is_the_body_scenarios_file(tmp_path):
    # A system of one body is stepped with the same arithmetic as the [body] scenario (N = 1 of the N-body
    # stepper): in the single-body layout its trajectory.csv is the [body] scenario's, byte for byte, and its
    # default (long) layout holds the same numbers.
    import lgvi
    (tmp_path / "one.toml").write_text(ONE_OF_BODIES + 'layout = "single-body"\n')
    (tmp_path / "one-long.toml").write_text(ONE_OF_BODIES)
    for scenario, out in ((orbit(tmp_path), "body"), (tmp_path / "one.toml", "one"),
                          (tmp_path / "one-long.toml", "one-long")):
        proc = run(scenario, tmp_path / out)
        assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "one" / "trajectory.csv").read_bytes() == (tmp_path / "body" / "trajectory.csv").read_bytes()
    one, one_long = lgvi.load(tmp_path / "one"), lgvi.load(tmp_path / "one-long")
    assert one.layout == "single-body" and one_long.layout == "long"
    assert one.names == one_long.names == ["triangle"]
    assert np.array_equal(one.per_body("q"), one_long.per_body("q"))
    assert one.body("triangle").name == "triangle"


@pytest.mark.parametrize("layout", ["single-body", "long"])
def test_simulate_gives_the_clis_arrays_and_save_round_trips_them(tmp_path, layout):
    import lgvi
    path = orbit(tmp_path, layout)
    assert run(path, tmp_path / "cli").returncode == 0
    memory = lgvi.simulate(lgvi.Scenario.from_toml(str(path)))
    loaded = lgvi.load(tmp_path / "cli")
    assert memory.layout == loaded.layout == layout
    assert np.array_equal(memory.data, loaded.data)
    assert list(memory.columns) == list(loaded.columns)
    memory.save(tmp_path / "saved")
    again = lgvi.load(tmp_path / "saved")
    assert again.layout == layout and np.array_equal(again.data, memory.data)  # %.17g: the same doubles


def test_wheels_are_columns_in_one_layout_and_wheels_csv_in_the_other(tmp_path):
    import lgvi
    single = variant(tmp_path, "wheel-slew", [], "single.toml")
    long = variant(tmp_path, "wheel-slew", [("[output]\n", '[output]\nlayout = "long"\n')], "long.toml")
    for scenario, out in ((single, "single"), (long, "long")):
        proc = run(scenario, tmp_path / out)
        assert proc.returncode == 0, proc.stderr
    assert not (tmp_path / "single" / "wheels.csv").exists() and (tmp_path / "long" / "wheels.csv").exists()
    a, b = lgvi.load(tmp_path / "single"), lgvi.load(tmp_path / "long")
    assert list(a.wheels) == ["z"] and list(b.wheels) == b.names
    for quantity in ("speed", "momentum", "torque"):
        assert np.array_equal(a.wheels["z"][quantity], b.wheels[b.names[0]]["z"][quantity]), quantity
    assert np.array_equal(a.per_body("w"), b.per_body("w"))


def test_the_viewer_and_the_figures_take_either_layout(tmp_path):
    import lgvi
    from lgvi import plot, viewer
    results = {}
    for layout in ("single-body", "long"):
        path = orbit(tmp_path, layout, f"{layout}.toml")
        assert run(path, tmp_path / layout).returncode == 0
        results[layout] = lgvi.load(tmp_path / layout)
    (meta1, arrays1), (meta2, arrays2) = (viewer.page_data(r) for r in results.values())
    assert arrays1["pos"] == arrays2["pos"] and arrays1["quat"] == arrays2["quat"] and meta1["bodies"] == 1
    # The single-body layout draws the one-body figures (body_motion.png); the long one the system's.
    drawn = {layout: {os.path.basename(p) for p in plot.draw_figures(r, tmp_path / f"fig-{layout}")}
             for layout, r in results.items()}
    assert "body_motion.png" in drawn["single-body"] and "trajectory.png" in drawn["long"]


@pytest.mark.parametrize("text, expected", [
    # Two bodies in one body's columns.
    ("binary-asteroid", r'output\.layout.*"single-body" holds one body.*2 bodies.*"long"'),
    # A molecular run writes a temperature column, which the single-body layout has not.
    ("lj-gas", r'output\.layout.*temperature.*"long"'),
])
def test_the_single_body_layout_refuses_what_it_cannot_hold(tmp_path, text, expected):
    import re
    source = (SOURCE / "scenarios" / f"{text}.toml").read_text()
    if text == "lj-gas":  # one molecule of the gas: the refusal is about the interaction, not the count
        source = re.sub(r"^count = \d+", "count = 1", source, count=1, flags=re.M)
    source = source.replace("[output]\n", '[output]\nlayout = "single-body"\n', 1)
    assert 'layout = "single-body"' in source
    (tmp_path / "bad.toml").write_text(source)
    proc = run(tmp_path / "bad.toml", tmp_path / "out")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert re.search(expected, proc.stderr), proc.stderr
    assert not (tmp_path / "out").exists()  # refused before anything is written


def test_system_result_is_a_deprecated_name_for_the_long_layout():
    from lgvi import _columns, _result
    import lgvi
    m = len(_columns.BODIES_COLUMNS)
    rows = [[0.0, 0.0] + [float(i) for i in range(2, m)]]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        old = lgvi.SystemResult(rows)
    assert any(issubclass(w.category, DeprecationWarning) and "lgvi.Result" in str(w.message) for w in caught)
    assert old.layout == "long" and isinstance(old, lgvi.Result)
    # isinstance(r, SystemResult) still tells a many-body result, as it did: a Result of the long layout.
    assert isinstance(_result.Result(rows), lgvi.SystemResult)
    assert not isinstance(_result.Result([[float(i) for i in range(len(_columns.COLUMNS))]]), lgvi.SystemResult)
