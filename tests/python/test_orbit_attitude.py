"""Issue 12, the spacecraft engineer: [initial] orbit / attitude from Python,
Result.rotation_matrices / euler_angles / lvlh_angles, the rotational
diagnostics of the summary, and body_motion.png for a body tiny against its
orbit. Needs the compiled lgvi._core (ctest sets PYTHONPATH to build/python)."""
import json
import math
import os
import pathlib
import struct

import numpy as np
import pytest

lgvi = pytest.importorskip("lgvi")
pytest.importorskip("lgvi._core")
from lgvi import _attitude  # noqa: E402

SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
LEO = SOURCE / "scenarios" / "leo-gravity-gradient.toml"
T_LEO = 5676.978  # the LEO orbit's period, s (2 pi sqrt(r^3 / mu), r = 6878137 m)


def axis_matrix(axis, deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    j, k = (axis + 1) % 3, (axis + 2) % 3
    m = np.eye(3)
    m[j, j], m[j, k], m[k, j], m[k, k] = c, -s, s, c
    return m


def test_euler_angles_of_hand_built_matrices():
    # Products of axis rotations with known angles come back to round-off
    # (1e-12 deg: a few eps in the matrix entries, through asin/atan2).
    R = axis_matrix(2, 30.0) @ axis_matrix(1, -20.0) @ axis_matrix(0, 10.0)
    np.testing.assert_allclose(_attitude.euler_angles(R, "ZYX", degrees=True), [30.0, -20.0, 10.0], atol=1e-12)
    # Extrinsic x, then y, then z about the fixed axes is the same matrix.
    np.testing.assert_allclose(_attitude.euler_angles(R, "xyz", degrees=True), [10.0, -20.0, 30.0], atol=1e-12)
    R = axis_matrix(2, 40.0) @ axis_matrix(0, 25.0) @ axis_matrix(2, -70.0)
    np.testing.assert_allclose(_attitude.euler_angles(R, "ZXZ", degrees=True), [40.0, 25.0, -70.0], atol=1e-12)
    with pytest.raises(ValueError, match="seq"):
        _attitude.euler_angles(R, "ZZX")
    with pytest.raises(ValueError, match="seq"):
        _attitude.euler_angles(R, "ZyX")


def test_euler_angles_agree_with_scipy_on_every_sequence():
    Rotation = pytest.importorskip("scipy.spatial.transform").Rotation
    rot = Rotation.random(50, random_state=3)
    for a in "xyz":
        for b in "xyz":
            for c in "xyz":
                if a == b or b == c:
                    continue
                for seq in (a + b + c, (a + b + c).upper()):
                    # 1e-9 rad: away from the singular middle angle both are
                    # round-off accurate (random rotations are never within 1e-4 of it).
                    np.testing.assert_allclose(_attitude.euler_angles(rot.as_matrix(), seq), rot.as_euler(seq),
                                               atol=1e-9, err_msg=seq)


def short_leo(tmp_path, orbits=3, every=57, step=None):
    text = LEO.read_text().replace("duration = 5676978.0", f"duration = {orbits * T_LEO!r}")
    text = text.replace("every = 57", f"every = {every}")
    if step is not None:
        text = text.replace("step = 10.0", f"step = {step!r}")
    return lgvi.Scenario.from_string(text, name="leo")


def test_leo_initial_lvlh_angles_and_rotational_summary(tmp_path):
    r = lgvi.simulate(short_leo(tmp_path))
    a = r.lvlh_angles()
    # The scenario's attitude = { pitch = 5.0 }: 5 deg back to round-off
    # (the quaternion holds the angle to ~1e-16 rad, 1e-14 deg; 1e-12 deg of slack).
    np.testing.assert_allclose(a[0], [0.0, 5.0, 0.0], atol=1e-12)
    # The pitch librates with an amplitude of 5 deg (5.17 over 1000 orbits, docs/guide/j2-leo.md);
    # roll and yaw stay small (0.22 and 0.17 deg over 1000 orbits).
    assert 4.5 < np.abs(a[:, 1]).max() < 5.3
    assert np.abs(a[:, [0, 2]]).max() < 0.3
    R = r.rotation_matrices()
    np.testing.assert_allclose(np.einsum("nij,nkj->nik", R, R), np.broadcast_to(np.eye(3), R.shape), atol=1e-13)
    s = r.summary
    rot = s["rotation"]
    # T0 = Omega.J Omega / 2 with Omega = (0, 0, n), Jz = 22.98 kg m^2 (the balls' moment).
    n = 2 * math.pi / T_LEO
    assert rot["initial_kinetic_energy"] == pytest.approx(0.5 * 22.98 * n * n, rel=1e-6)
    assert rot["min_kinetic_energy"] <= rot["initial_kinetic_energy"] <= rot["max_kinetic_energy"]
    assert rot["energy_error_over_max_kinetic_energy"] == pytest.approx(
        s["max_abs_energy_error"] / rot["max_kinetic_energy"], rel=1e-12)
    # J2: the angular momentum is conserved about the pole only; |L - L0| is a change.
    assert s["conserved"]["quantities"] == ["energy", "angular_momentum_along_pole"]
    assert "max_momentum_error" in s["conserved"]["changes_not_errors"]


def co_rotating(step, orbits=1.0):
    """A body given by mass and an isotropic inertia (no gravity-gradient
    torque, u x J u = 0, and a constant Omega is a free motion whatever its axis) on a
    circular orbit, set turning with the LVLH frame at roll, pitch, yaw =
    (10, 20, 30) deg."""
    T = 2 * math.pi * math.sqrt(7.0e6 ** 3 / 3.986004418e14)
    sc = lgvi.Scenario(body=lgvi.Body(mass=10.0, inertia=2.0 * np.eye(3)),
                       potential=lgvi.potential.central(3.986004418e14),
                       orbit=dict(radius=7.0e6, inclination=97.0, raan=20.0, true_anomaly=45.0),
                       attitude=dict(frame="lvlh", roll=10.0, pitch=20.0, yaw=30.0, rate="orbit"),
                       step=T / step, duration=orbits * T, every=10)
    return sc, lgvi.simulate(sc).lvlh_angles()


def test_co_rotating_body_keeps_its_lvlh_angles_to_truncation_error():
    sc, a = co_rotating(200)
    np.testing.assert_allclose(a[0], [10.0, 20.0, 30.0], atol=1e-12)  # round-off, as above
    drift = np.abs(a - a[0]).max(axis=0)
    _, a2 = co_rotating(400)
    drift2 = np.abs(a2 - a2[0]).max(axis=0)
    # The body turns at the exact orbit rate (constant Omega of an isotropic
    # body: the LGVI's rotation is exact) while the discrete orbit's phase is
    # off by O((n h)^2): pitch (about the orbit normal) drifts, measured 0.178
    # deg at h = T/200 over one orbit, 0.0444 at T/400 (0.0111 at T/800), a
    # ratio of 4.0: second order. Roll and yaw stay at round-off (measured
    # < 3e-12 deg; 1e-10 allows for another libm).
    assert drift[1] < 0.2
    assert 3.8 < drift[1] / drift2[1] < 4.2
    assert max(drift[0], drift[2], drift2[0], drift2[2]) < 1e-10


def test_scenario_orbit_keyword_writes_plain_keys():
    sc, _ = co_rotating(200, orbits=0.01)
    doc_keys = [line.split(" =")[0] for line in sc.toml.splitlines() if line and not line.startswith("#")]
    assert "orbit" not in doc_keys and "attitude" not in doc_keys
    assert {"position", "momentum", "quaternion", "w"} <= set(doc_keys)
    again = lgvi.Scenario.from_string(sc.toml)
    np.testing.assert_array_equal(again.position, sc.position)
    np.testing.assert_array_equal(again.quaternion, sc.quaternion)
    np.testing.assert_array_equal(again.w, sc.w)
    with pytest.raises(ValueError, match="initial.orbit"):
        lgvi.Scenario(body=lgvi.Body(mass=1.0, inertia=np.eye(3)), orbit=dict(radius=7e6, inclination=0.0),
                      quaternion=(1, 0, 0, 0), w=(0, 0, 0), step=1.0, duration=1.0)


def png_size(path):
    with open(path, "rb") as f:
        head = f.read(24)
    return struct.unpack(">II", head[16:24])


def test_body_motion_of_a_tiny_body_draws_lvlh_angles(tmp_path):
    r = lgvi.simulate(short_leo(tmp_path, orbits=2, every=5))
    written = lgvi.plot.draw_figures(r, tmp_path / "fig")
    path = [p for p in written if p.endswith("body_motion.png")][0]
    # The attitude figure is 8 x 4.5 in at 120 dpi; the path figure 6 x 4.5.
    assert png_size(path) == (960, 540)
    json.dumps(r.summary)  # the new keys are plain JSON


def test_system_result_attitude_helpers_per_body():
    """A Result of many bodies has the attitude helpers of one body's, per body: two
    satellites of the co-rotating kind, on different orbits and with no
    mutual interaction, give each the LVLH angles, rotation matrices and
    Euler angles of its own single-body run. The N-body step of independent
    bodies is the single-body step body by body, so the states agree to
    round-off of the summed energy only, i.e. exactly here (asserted to
    1e-12 deg to allow for a reordered sum)."""
    mu = 3.986004418e14
    body = lgvi.Body(mass=10.0, inertia=2.0 * np.eye(3))
    T = 2 * math.pi * math.sqrt(7.0e6 ** 3 / mu)
    singles = []
    for raan, pitch in ((20.0, 20.0), (80.0, -35.0)):
        sc = lgvi.Scenario(body=body, potential=lgvi.potential.central(mu),
                           orbit=dict(radius=7.0e6, inclination=97.0, raan=raan, true_anomaly=45.0),
                           attitude=dict(frame="lvlh", roll=10.0, pitch=pitch, yaw=30.0, rate="orbit"),
                           step=T / 200, duration=0.25 * T, every=10)
        singles.append((sc, lgvi.simulate(sc)))
    system = lgvi.Scenario.from_arrays(
        bodies=body, positions=[s.position for s, _ in singles], quaternions=[s.quaternion for s, _ in singles],
        momenta=[s.momentum for s, _ in singles], w=[s.w for s, _ in singles],
        potential=lgvi.potential.central(mu), step=T / 200, duration=0.25 * T, every=10)
    r = lgvi.simulate(system)
    angles = r.lvlh_angles()
    assert angles.shape == (len(r), 2, 3)
    assert r.rotation_matrices().shape == (len(r), 2, 3, 3)
    for b, (_, single) in enumerate(singles):
        np.testing.assert_allclose(angles[:, b], single.lvlh_angles(), rtol=0, atol=1e-12)
        np.testing.assert_allclose(r.euler_angles("zxz")[:, b], single.euler_angles("zxz"), rtol=0, atol=1e-14)
