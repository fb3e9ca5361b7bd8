"""The Python Stepper on a system of N bodies ([[bodies]]): the same steps as
lgvi.simulate, bit for bit (both run the one N-body stepper of the scenario's
method through the run loop's integrate_range), with the per-body arrays on a
leading body axis."""
import os
import pathlib
import re

import numpy as np
import pytest

SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
pytest.importorskip("lgvi._core", reason="the built lgvi package (build/python) is not on PYTHONPATH")
import lgvi  # noqa: E402
from lgvi import plot  # noqa: E402


def edited(name, **keys):
    """A bundled scenario with `key = value` lines replaced (every line that sets the key)."""
    text = (SOURCE / "scenarios" / name).read_text()
    for key, value in keys.items():
        text, n = re.subn(rf"^{key} = .*$", f"{key} = {value}", text, flags=re.M)
        assert n >= 1, key
    return lgvi.Scenario.from_string(text, name=pathlib.Path(name).stem)


def binary(duration=0.5):
    return edited("binary-asteroid.toml", duration=duration, every=1)


def lj_box():
    # 4 x 4 x 4 molecules of lj-fluid-periodic.toml in a periodic cube of side 8 (cutoff + skin 2.8 < 4).
    return edited("lj-fluid-periodic.toml", count=64, upper="[7.0, 7.0, 7.0]", duration=0.1, every=1)


def stepped_rows(stepper, steps):
    rows = [stepper.row]
    for k in range(1, steps + 1):
        stepper.step()
        assert stepper.k == k and stepper.t == k * stepper.h  # t0 + k h, never accumulated
        rows.append(stepper.row)
    return np.array(rows)


def test_a_system_steps_as_simulate_writes_it():
    sc = binary()
    r = lgvi.simulate(sc)
    st = lgvi.Stepper(sc)
    assert st.bodies == 2
    assert st.position.shape == (2, 3) and st.quaternion.shape == (2, 4) and st.rotation_matrix.shape == (2, 3, 3)
    rows = stepped_rows(st, sc.steps)
    assert rows.shape == r.data.shape  # (steps + 1, N, 26)
    assert np.array_equal(rows, r.data)
    bulk = lgvi.Stepper(sc)
    bulk.step(sc.steps)
    assert np.array_equal(bulk.row, r.data[-1])
    c = lgvi.BODIES_COLUMNS
    last = r.data[-1]
    assert np.array_equal(bulk.position, last[:, c.index("x"):c.index("z") + 1])
    assert np.array_equal(bulk.quaternion, last[:, c.index("qw"):c.index("qz") + 1])
    assert np.array_equal(bulk.momentum, last[:, c.index("px"):c.index("pz") + 1])
    assert np.array_equal(bulk.w, last[:, c.index("wx"):c.index("wz") + 1])
    assert bulk.energy == last[0, c.index("energy")] and bulk.energy_error == last[0, c.index("energy_error")]
    assert np.array_equal(bulk.angular_momentum, last[0, c.index("Lx"):c.index("Lz") + 1])
    assert np.array_equal(bulk.linear_momentum, last[0, c.index("Px"):c.index("Pz") + 1])
    # Omega_a = J_a^-1 w_a / 2 and R_a = pi(q_a), body by body (round-off of a 3x3 solve and of pi).
    inertias = bulk._core.inertias
    for a in range(2):
        # J^-1 w / 2 with the body's stored inverse against a 3x3 solve: a few units of round-off (1e-16).
        assert np.allclose(bulk.omega[a], 0.5 * np.linalg.solve(inertias[a], bulk.w[a]), rtol=1e-15, atol=0)
        assert np.allclose(bulk.rotation_matrix[a], plot.rotation_matrix(bulk.quaternion[a]), rtol=0, atol=1e-15)
    # Mutual gravity: the forces are equal and opposite (one pair evaluation, applied with both signs).
    assert np.array_equal(bulk.force[0], -bulk.force[1])


def test_a_periodic_fluid_steps_as_simulate_writes_it():
    sc = lj_box()
    r = lgvi.simulate(sc)
    rows = stepped_rows(lgvi.Stepper(sc), sc.steps)
    # The Stepper's rows are the long format's 26 columns; simulate's add the temperature and the pressure.
    assert rows.shape == r.data.shape[:2] + (26,)
    assert np.array_equal(rows, r.data[:, :, :26])


def test_a_python_potential_acts_on_every_body_as_in_simulate():
    def trap(x, q):  # V = kappa |x|^2 / 2 on each body, weak beside the pair's gravity: an external field, no torque
        kappa = 1e-4
        return 0.5 * kappa * float(x @ x), -kappa * np.asarray(x, dtype=float), np.zeros(3)
    sc = binary(duration=0.2)
    r = lgvi.simulate(sc, trap)
    assert np.array_equal(stepped_rows(lgvi.Stepper(sc, trap), sc.steps), r.data)
    assert not np.array_equal(r.data, lgvi.simulate(sc).data)  # the field acts


def test_set_state_takes_every_body_at_once():
    sc = binary()
    st = lgvi.Stepper(sc)
    m, inertias = st._core.masses, st._core.inertias
    v = np.array([[0.0, 1e-4, 0.0], [0.0, -2e-4, 0.0]])
    omega = np.array([[0.0, 0.0, 3e-4], [1e-4, 0.0, 2e-4]])
    st.set_state(velocity=v, omega=omega)
    assert np.array_equal(st.momentum, m[:, None] * v)
    for a in range(2):
        assert np.array_equal(st.w[a], 2.0 * (inertias[a] @ omega[a]))
    # The momenta given are the total P; mutual forces change it by round-off only: sum_a p_a is
    # conserved by the LGVI's translational update when the forces sum to zero (equal and opposite).
    p0 = st.linear_momentum.copy()
    scale = np.abs(st.momentum).sum()
    st.step(50)
    assert np.max(np.abs(st.linear_momentum - p0)) <= 50 * 4 * np.finfo(float).eps * scale
    # k, t and the energy's reference are kept.
    assert st.k == 50


@pytest.mark.parametrize("change, message", [
    (dict(position=np.zeros(3)), r"^position: must have shape \(2, 3\), got shape \(3,\)$"),
    (dict(quaternion=[[1.0, 0, 0, 0], [0.0, 0, 0, 2.0]]), r"^quaternion\[1\]: "),
    (dict(momentum=[[0.0, 0, 0], [np.nan, 0, 0]]), r"^momentum: must be finite"),
    (dict(w=np.zeros((2, 3)), omega=np.zeros((2, 3))), r"^w, omega: give one of them, not both$"),
])
def test_set_state_refuses_a_wrong_shape_or_value_in_one_line(change, message):
    st = lgvi.Stepper(binary())
    before = st.row
    with pytest.raises(ValueError, match=message) as info:
        st.set_state(**change)
    assert "\n" not in str(info.value)
    assert np.array_equal(st.row, before)  # nothing changed


def test_python_is_called_from_one_thread_whatever_the_scenario_asks():
    # 64 bodies on 2 threads: the per-body loops run in parallel from 32 bodies on; a Python field must
    # still be called from the calling thread only (it holds the interpreter's lock), in simulate and in
    # the Stepper alike, and give the same rows (the results do not depend on the thread count).
    import threading
    text = lj_box().toml + "\n[run]\nthreads = 2\n"
    sc = lgvi.Scenario.from_string(text, name="lj-box-2-threads")
    callers = set()

    def trap(x, q):
        callers.add(threading.get_ident())
        kappa = 1e-3
        return 0.5 * kappa * float(x @ x), -kappa * np.asarray(x, dtype=float), np.zeros(3)
    r = lgvi.simulate(sc, trap)
    rows = stepped_rows(lgvi.Stepper(sc, trap), sc.steps)
    assert callers == {threading.get_ident()}
    assert np.array_equal(rows, r.data[:, :, :26])


def test_set_state_keeps_k_t_and_the_energy_reference():
    sc = binary()
    st = lgvi.Stepper(sc)
    e0 = st._core.initial_energy
    st.step(10)
    before = st.energy_error
    st.set_state(position=st.position)  # the same state, re-initialized there
    assert st.k == 10 and st.t == 10 * st.h
    assert st._core.initial_energy == e0 and st.energy_error == before


def test_a_refused_set_state_leaves_the_stepper_as_it_was():
    # The potential fails (NaN) beyond |x| = 100: set_state there is refused, and the next step is the
    # one a stepper that was never asked takes, bit for bit.
    def field(x, q):
        if np.linalg.norm(x) > 100.0:
            return float("nan"), np.zeros(3), np.zeros(3)
        return 0.0, np.zeros(3), np.zeros(3)
    sc = binary(duration=0.2)
    asked, untouched = lgvi.Stepper(sc, field), lgvi.Stepper(sc, field)
    asked.step(5)
    untouched.step(5)
    far = asked.position.copy()
    far[1] = [1000.0, 0.0, 0.0]
    with pytest.raises(ValueError, match="^state: "):
        asked.set_state(position=far)
    asked.step()
    untouched.step()
    assert np.array_equal(asked.row, untouched.row)
