"""Built-in potentials named from Python equal the scenario files' (the same
C++ reader builds both), including the heavy top and stop_at_contact."""
import math
import os
import pathlib
import tomllib

import numpy as np
import pytest

lgvi = pytest.importorskip("lgvi")
SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))


def test_heavy_top_built_in_code_equals_the_file():
    from_file = lgvi.Scenario.from_toml(SOURCE / "scenarios" / "heavy-top.toml").replace(duration=0.5)
    in_code = lgvi.Scenario(
        body=lgvi.Body(mass=1.0, inertia=np.diag([0.35, 0.35, 0.05])),
        potential=lgvi.potential.heavy_top((0.0, 0.0, -9.81), (0.0, 0.0, 0.5)),
        position=(0.0, 0.0, 0.0), quaternion=(math.cos(0.15), math.sin(0.15), 0.0, 0.0),
        momentum=(0.0, 0.0, 0.0), omega=(0.0, 0.0, 50.0), step=0.001, duration=0.5, every=10, name="heavy-top")
    a, b = lgvi.simulate(from_file), lgvi.simulate(in_code)
    # The file spells the quaternion with 16 digits; the code computes it: equal
    # to round-off at t = 0, and the flows then agree to ~1e-13 after 500 steps.
    assert np.max(np.abs(a.data - b.data)) < 1e-12
    assert a.summary["setup"]["potential"]["kind"] == "heavy-top"


def test_stop_at_contact_and_errors_name_the_argument():
    assert lgvi.potential.central(1.0, stop_at_contact=True) == {"kind": "central", "mu": 1.0,
                                                                  "stop_at_contact": True}
    with pytest.raises(ValueError, match="pivot_to_com"):
        lgvi.potential.heavy_top((0, 0, -9.81), (0, 0))
    with pytest.raises(ValueError, match="stop_at_contact"):
        lgvi.potential.spec({"kind": "central", "mu": 1.0, "stop_at_contact": "yes"})


@pytest.mark.parametrize("name", ["heavy-top", "leo-gravity-gradient", "paper-orbit", "attitude-slew"])
def test_scenario_potential_keeps_every_key_of_the_file(name):
    """Scenario.potential is the file's [potential] table, every key kept: an
    earlier version returned kind and mu/g only, dropping heavy-top's
    pivot_to_com, J2 and stop_at_contact, so that
    Scenario(potential=sc.potential) built another potential."""
    sc = lgvi.Scenario.from_toml(SOURCE / "scenarios" / f"{name}.toml")
    written = tomllib.loads((SOURCE / "scenarios" / f"{name}.toml").read_text()).get("potential", {"kind": "none"})
    assert sc.potential == written
    again = sc.replace(potential=sc.potential, duration=0.0)
    assert again.potential == written


def test_oblate_central_potential_from_code_equals_the_file():
    """lgvi.potential.central takes J2: the LEO scenario's potential built in
    code runs bit-identically to the file's (the same reader builds both, and
    the numbers are the same doubles)."""
    from_file = lgvi.Scenario.from_toml(SOURCE / "scenarios" / "leo-gravity-gradient.toml")
    table = from_file.potential
    in_code = from_file.replace(potential=lgvi.potential.central(
        table["mu"], j2=table["j2"], reference_radius=table["reference_radius"], pole=table["pole"]),
        duration=100 * from_file.step)
    short = from_file.replace(duration=100 * from_file.step)
    assert np.array_equal(lgvi.simulate(short).data, lgvi.simulate(in_code).data)
    with pytest.raises(ValueError, match="potential.j2"):
        lgvi.potential.central(1.0, j2="big", reference_radius=1.0)
    with pytest.raises(ValueError, match="reference_radius"):  # the reader: j2 needs its radius
        lgvi.Scenario(body=lgvi.Body(mass=1.0, inertia=np.eye(3)), potential=lgvi.potential.central(1.0, j2=1e-3),
                      position=(8, 0, 0), quaternion=(1, 0, 0, 0), momentum=(0, 0.35, 0), w=(0, 0, 0),
                      step=0.1, duration=1.0)


def test_central_model_key_and_a_mass_and_inertia_body_feels_the_gravity_gradient():
    """model="extended" (default) gives a body given by mass and inertia the gravity-gradient torque;
    model="point" is the point mass of before (its spin never changes: no torque at all, so w is
    constant to the last bit), stated in the summary's setup either way."""
    assert lgvi.potential.central(1.0, model="point") == {"kind": "central", "mu": 1.0, "model": "point"}
    assert lgvi.potential.central(1.0) == {"kind": "central", "mu": 1.0}
    with pytest.raises(ValueError, match="model"):
        lgvi.potential.central(1.0, model="balls")
    with pytest.raises(ValueError, match="potential.model"):
        lgvi.potential.spec({"kind": "central", "mu": 1.0, "model": 3})
    body = lgvi.Body(mass=30.0, inertia=np.diag([2.98, 20.48, 22.98]))
    runs = {}
    for model in ("extended", "point"):
        sc = lgvi.Scenario(body=body, potential=lgvi.potential.central(3.986004418e14, model=model),
                           position=(6878137.0, 0.0, 0.0), quaternion=(math.cos(0.05), 0.0, 0.0, math.sin(0.05)),
                           velocity=(0.0, 7612.608173223869, 0.0), omega=(0.0, 0.0, 1.1067834463349404e-3),
                           step=10.0, duration=1000.0)
        runs[model] = lgvi.simulate(sc)
        assert runs[model].summary["setup"]["potential"]["model"] == model
    # A 0.1 rad pitch offset in LEO: the gradient torque (3 n^2 (J_y - J_x) theta ~ 6e-6 N m) changes
    # w = 2 J Omega by ~1e-2 in 1000 s (a quarter of the libration period), against 0 exactly for the point mass.
    assert np.array_equal(runs["point"].w[-1], runs["point"].w[0])
    assert np.linalg.norm(runs["extended"].w[-1] - runs["extended"].w[0]) > 1e-3
