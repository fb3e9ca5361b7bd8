"""The Python package `import lgvi` (pybind11 + numpy): results equal to the
CLI's to the last bit, a potential written in Python, the stepping object,
loading runs, plotting from memory, the examples, every error path, and the
docstrings and type stubs.

Run by ctest (python.pytest) with PYTHONPATH=<build>/python (the built
package, with its compiled lgvi._core), LGVI_BINARY (the built `lgvi`) and
LGVI_SOURCE_DIR set.
"""

import ast
import inspect
import json
import math
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest

BINARY = os.environ.get("LGVI_BINARY")
SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
PAPER_ORBIT = SOURCE / "scenarios" / "paper-orbit.toml"

if BINARY is None:  # outside ctest: only if the built package is on the path
    pytest.importorskip("lgvi._core", reason="the built lgvi package (build/python) is not on PYTHONPATH")
import lgvi  # noqa: E402
from lgvi import plot  # noqa: E402

needs_cli = pytest.mark.skipif(BINARY is None, reason="LGVI_BINARY not set (run through ctest)")
FIGURES = ("trajectory.png", "body_motion.png", "energy_error.png", "quaternion_error.png", "momentum_error.png")
WALL_TIME_FIELDS = ("wall_seconds", "ns_per_step")


def package_env(**extra):
    """The environment for a child Python that imports this same (built) lgvi package."""
    here = str(pathlib.Path(lgvi.__file__).resolve().parents[1])
    path = os.pathsep.join([here] + [p for p in [os.environ.get("PYTHONPATH")] if p])
    return dict(os.environ, PYTHONPATH=path, **extra)


def run_cli(scenario_path, out_dir):
    proc = subprocess.run([BINARY, "run", str(scenario_path), "--out", str(out_dir), "--no-figures", "-q"],
                          capture_output=True, text=True)
    return proc


def cli_run(scenario_path, out_dir):
    """The CLI's trajectory (np.loadtxt of its 17-digit CSV: exact) and summary."""
    proc = run_cli(scenario_path, out_dir)
    assert proc.returncode == 0, proc.stderr
    with open(out_dir / "trajectory.csv", encoding="utf-8") as f:
        header = f.readline().strip()
    data = np.loadtxt(out_dir / "trajectory.csv", delimiter=",", skiprows=1, ndmin=2)
    summary = json.loads((out_dir / "summary.json").read_text())
    return header, data, summary


def without_wall_time(summary):
    return {k: v for k, v in summary.items() if k not in WALL_TIME_FIELDS}


def short_orbit(**changes):
    """The paper's orbit, shortened (and otherwise changed) for quick tests."""
    changes.setdefault("duration", 2.0)
    return lgvi.Scenario.from_toml(PAPER_ORBIT).replace(**changes)


@pytest.fixture(scope="module")
def paper_orbit_cli(tmp_path_factory):
    if BINARY is None:
        pytest.skip("LGVI_BINARY not set")
    out = tmp_path_factory.mktemp("paper-orbit-cli")
    return out, cli_run(PAPER_ORBIT, out)


@pytest.fixture(scope="module")
def paper_orbit_result():
    return lgvi.simulate(lgvi.Scenario.from_toml(PAPER_ORBIT))


# ---------------------------------------------------------------------------
# (1) The same numbers as the CLI, to the last bit

@needs_cli
def test_simulate_equals_the_cli_bit_for_bit_on_the_paper_orbit(paper_orbit_cli, paper_orbit_result):
    _, (header, data, summary) = paper_orbit_cli
    r = paper_orbit_result
    assert header == ",".join(lgvi.COLUMNS)
    assert r.data.shape == data.shape == (10001, 21)
    assert np.array_equal(r.data, data)  # bit-identical: %.17g round-trips every double
    assert list(r.columns) == header.split(",")
    for i, name in enumerate(lgvi.COLUMNS):
        assert np.array_equal(r.columns[name], data[:, i]), name
    named = {"t": r.t, "x": r.x, "q": r.q, "p": r.p, "w": r.w, "energy": r.energy, "energy_error": r.energy_error,
             "quat_norm_error": r.quat_norm_error, "L": r.L, "momentum_error": r.momentum_error}
    assert np.array_equal(np.column_stack(list(named.values())), data)
    assert r.q.shape == (10001, 4) and np.array_equal(r.q[0], [1.0, 0.0, 0.0, 0.0])  # scalar first
    assert without_wall_time(r.summary) == without_wall_time(summary)
    assert set(summary) - set(r.summary) == set()
    assert r.completed and r.error == ""


# "exact" needs a free body; these tests run the orbit.
ORBIT_METHODS = [m for m in lgvi.METHODS if m != "exact"]


@needs_cli
@pytest.mark.parametrize("method", ORBIT_METHODS)
@pytest.mark.parametrize("solver", lgvi.SOLVERS)
def test_every_method_and_solver_equals_the_cli(tmp_path, method, solver):
    sc = short_orbit(method=method, solver=solver, duration=5.0, every=7, predictor_order=2, name="variant")
    path = sc.save(tmp_path / "variant.toml")
    _, data, summary = cli_run(path, tmp_path / "run")
    r = lgvi.simulate(sc)
    assert np.array_equal(r.data, data)
    assert without_wall_time(r.summary) == without_wall_time(summary)
    assert r.summary["setup"]["integrator"]["method"] == method
    assert r.summary["setup"]["integrator"]["solver"] == solver


def test_scenario_built_in_code_equals_the_file(paper_orbit_result):
    body = lgvi.Body.from_balls([((0.0, 0.0, 0.0), 1.0, 0.1), ((1.0, 0.0, 0.0), 1.0, 0.1),
                                 {"position": (0.5, math.sqrt(3.0) / 2.0, 0.0), "mass": 1.0, "radius": 0.1}])
    sc = lgvi.Scenario(body=body, potential=lgvi.potential.central(1.0), position=(8, 0, 0),
                       quaternion=(1, 0, 0, 0), momentum=(0, 1, 0), w=(1, 2, 3), step=0.01, duration=1000.0,
                       every=10, name="paper-orbit")
    r = lgvi.simulate(sc)
    assert np.array_equal(r.data, paper_orbit_result.data)
    assert without_wall_time(r.summary) == without_wall_time(paper_orbit_result.summary)


def test_scenario_properties_round_trip_exactly():
    J = np.array([[2.0, 0.1, 0.0], [0.1, 3.0, 0.2], [0.0, 0.2, 4.0]])
    q = np.array([0.9, 0.1, -0.3, 0.2])
    q /= np.linalg.norm(q)
    sc = lgvi.Scenario(body=lgvi.Body(mass=1.7, inertia=J), potential=lgvi.potential.uniform([0, 0, -9.81]),
                       position=(0.1, 1e-300, -7.3), quaternion=q, velocity=(1 / 3, 0, 2), omega=(0.3, -0.2, 0.1),
                       step=1e-3, duration=0.1, method="lgvi-lagrangian", solver="broyden", tolerance=1e-14,
                       max_iterations=20, predictor_order=1, every=3, output_format="npz", name="mine")
    assert np.array_equal(sc.body.inertia, J) and sc.body.mass == 1.7
    assert np.array_equal(sc.position, [0.1, 1e-300, -7.3])
    assert np.max(np.abs(sc.quaternion - q)) <= 2e-16  # normalized again, as the file reader does
    assert np.array_equal(sc.momentum, 1.7 * np.array([1 / 3, 0, 2]))
    assert np.allclose(sc.omega, [0.3, -0.2, 0.1], rtol=1e-15, atol=1e-16)
    assert (sc.step, sc.duration, sc.steps, sc.every) == (1e-3, 0.1, 100, 3)
    assert (sc.method, sc.solver, sc.tolerance, sc.max_iterations, sc.predictor_order) == \
        ("lgvi-lagrangian", "broyden", 1e-14, 20, 1)
    assert sc.potential == {"kind": "uniform", "g": [0.0, 0.0, -9.81]} and sc.output_format == "npz"
    assert sc.name == "mine"
    again = lgvi.Scenario.from_string(sc.toml, "mine")
    assert again.toml == sc.toml and np.array_equal(again.w, sc.w)
    assert np.array_equal(lgvi.simulate(again).data, lgvi.simulate(sc).data)


# ---------------------------------------------------------------------------
# (2) A potential written in Python

def python_central_gravity(body, mu):
    """The built-in central gravity, in numpy: V = -mu sum m_i / |x + R rho_i|,
    force -dV/dx = sum f_i, body torque M = sum rho_i x (R^T f_i)."""
    rho = np.array([b["position"] for b in body.balls])
    m = np.array([b["mass"] for b in body.balls])

    def central(x, q):
        R = plot.rotation_matrix(q)  # q scalar-first (w, x, y, z)
        arm = rho @ R.T                   # R rho_i
        pos = x + arm
        d = np.sqrt(np.sum(pos * pos, axis=1))
        f = (-mu * m / d ** 3)[:, None] * pos
        return -mu * np.sum(m / d), f.sum(axis=0), np.cross(rho, f @ R).sum(axis=0)  # R^T f_i = (f R)_i
    return central


def test_python_central_gravity_reproduces_the_builtin_trajectory():
    sc = short_orbit(duration=20.0, every=1)  # 2000 steps
    central = python_central_gravity(sc.body, sc.potential["mu"])
    for x, q in ((sc.position, sc.quaternion), ((3.0, -2.0, 1.0), (0.5, 0.5, -0.5, 0.5))):
        e_py, f_py, m_py = central(np.asarray(x, float), np.asarray(q, float))
        e, f, m = sc.evaluate_potential(x, q)
        assert abs(e_py - e) <= 4e-16 * abs(e)
        assert np.max(np.abs(f_py - f)) <= 4e-16 * np.max(np.abs(f))
        assert np.max(np.abs(m_py - m)) <= 1e-14 * np.max(np.abs(f))  # torque: cancellation among the balls
    builtin = lgvi.simulate(sc)
    py = lgvi.simulate(sc, lgvi.PythonPotential(central))
    assert len(py) == len(builtin) == 2001 and py.completed
    # Tolerance: numpy sums in another order than the C++ loop, so each
    # evaluation differs from the built-in one by a few ulps (checked above).
    # Over n = 2000 steps such perturbations accumulate at most linearly, and
    # over t = 20 (a sixth of an orbit) the flow does not amplify them by more
    # than O(1): the bound n * eps ~ 4.4e-13 relative to each quantity's
    # scale, rounded up to 1e-12. (Observed: ~2e-16, a random walk.)
    tol = 1e-12
    cols = py.columns
    for name in ("t", "x", "y", "z", "qw", "qx", "qy", "qz", "px", "py", "pz", "wx", "wy", "wz", "energy",
                 "Lx", "Ly", "Lz"):
        scale = max(np.max(np.abs(builtin.columns[name])), 1e-300)
        assert np.max(np.abs(cols[name] - builtin.columns[name])) <= tol * scale, name
    scale_e, scale_l = np.max(np.abs(builtin.energy)), np.max(np.linalg.norm(builtin.L, axis=1))
    assert np.max(np.abs(py.energy_error - builtin.energy_error)) <= tol * scale_e
    assert np.max(np.abs(py.quat_norm_error - builtin.quat_norm_error)) <= tol
    assert np.max(np.abs(py.momentum_error - builtin.momentum_error)) <= tol * scale_l
    assert py.summary["setup"]["potential"]["kind"] == "python"
    assert without_wall_time(py.summary)["steps"] == builtin.summary["steps"]


def test_python_potential_forms_agree_and_check_derivatives():
    sc = short_orbit(duration=0.5, every=1)
    central = python_central_gravity(sc.body, 1.0)
    split = lgvi.PythonPotential(energy=lambda x, q: central(x, q)[0], force=lambda x, q: central(x, q)[1],
                                 torque=lambda x, q: central(x, q)[2])
    one = lgvi.simulate(sc, lgvi.PythonPotential(central))
    assert np.array_equal(lgvi.simulate(sc, split).data, one.data)
    assert np.array_equal(lgvi.simulate(sc, central).data, one.data)  # a bare callable
    tuples = lambda x, q: tuple(v.tolist() if isinstance(v, np.ndarray) else v for v in central(x, q))
    assert np.array_equal(lgvi.simulate(sc, tuples).data, one.data)  # lists are fine too
    check = lgvi.PythonPotential(central).check(sc.position, sc.quaternion)
    assert check["force_error"] < 1e-9 and check["torque_error"] < 1e-7
    wrong_sign = lgvi.PythonPotential(lambda x, q: (central(x, q)[0], central(x, q)[1], -central(x, q)[2]))
    assert wrong_sign.check(sc.position, sc.quaternion)["torque_error"] > 1.0


def test_check_gives_a_verdict_and_names_the_likely_mistake():
    sc = short_orbit(duration=0.5)
    central = python_central_gravity(sc.body, 1.0)
    # A generic state: close to the field (a torque far above the round-off floor, eps |V| / h ~ 3e-13 |V|)
    # and an attitude whose R moves the torque (at q = 1 the body and inertial frames agree).
    x, q = np.array([3.0, -2.0, 1.0]), np.array([0.5, 0.5, -0.5, 0.5])
    R = plot.rotation_matrix(q)
    good = lgvi.PythonPotential(central).check(x, q)
    # The stated tolerance: 1e-6 plus the round-off floor; a right potential's errors are ~1e-10
    # (4th-order differences with h = eps^(1/5): truncation and round-off ~1e-13 |V| each).
    assert good["passed"] and good["likely_mistake"] == "" and good["torque_error"] < 1e-8
    assert 1e-6 <= good["torque_tolerance"] < 1e-5 and 1e-6 <= good["force_tolerance"] < 1e-5
    wrong = {
        "inertial frame": lambda x, q: (central(x, q)[0], central(x, q)[1], R @ central(x, q)[2]),
        "the torque has the wrong sign": lambda x, q: (central(x, q)[0], central(x, q)[1], -central(x, q)[2]),
        "the force has the wrong sign": lambda x, q: (central(x, q)[0], -central(x, q)[1], central(x, q)[2]),
        "twice": lambda x, q: (central(x, q)[0], central(x, q)[1], 2 * central(x, q)[2]),
    }
    for mistake, potential in wrong.items():
        c = lgvi.PythonPotential(potential).check(x, q)
        assert not c["passed"] and mistake in c["likely_mistake"], (mistake, c)
        with pytest.raises(ValueError, match="check failed.*likely: .*" + mistake):
            lgvi.PythonPotential(potential).check(x, q, strict=True)
    assert lgvi.PythonPotential(central).check(x, q, strict=True)["passed"]
    # A wrong torque that is none of the known mistakes: not passed, nothing named.
    other = lgvi.PythonPotential(lambda x, q: (central(x, q)[0], central(x, q)[1], np.ones(3)))
    c = other.check(x, q)
    assert not c["passed"] and c["likely_mistake"] == ""


def test_energy_must_be_a_number_not_an_array():
    sc = scenario(duration=0.02)
    for value in (np.array([1.0]), [1.0]):
        with pytest.raises(ValueError, match=r"the returned energy must be a number"):
            lgvi.simulate(sc, lambda x, q, v=value: (v, np.zeros(3), np.zeros(3)))
    # Numbers, numpy scalars and 0-d arrays are numbers.
    for value in (1.0, np.float64(1.0), np.array(1.0)):
        assert lgvi.simulate(sc, lambda x, q, v=value: (v, np.zeros(3), np.zeros(3))).completed


def test_python_potential_sees_read_only_arrays():
    seen = []

    def spy(x, q):
        seen.append((x.shape, q.shape, x.flags.writeable, q.flags.writeable, x.dtype, q.copy()))
        return 0.0, np.zeros(3), np.zeros(3)
    lgvi.simulate(short_orbit(duration=0.03), spy)
    assert len(seen) == 4  # one evaluation per step, plus the initial state
    assert all(s[:5] == ((3,), (4,), False, False, np.float64) for s in seen)
    assert np.array_equal(seen[0][5], [1, 0, 0, 0])  # scalar first


# ---------------------------------------------------------------------------
# (3) Error paths: ValueError naming the argument

def body():
    return lgvi.Body(mass=1.0, inertia=np.diag([1.0, 2.0, 3.0]))


def scenario(**kw):
    """A free body at rest at the origin (the initial state has no defaults: each key is given unless kw has
    it or its alternative)."""
    args = dict(body=body(), step=0.01, duration=1.0, position=(0, 0, 0), quaternion=(1, 0, 0, 0))
    if "momentum" not in kw and "velocity" not in kw:
        args["momentum"] = (0, 0, 0)
    if "w" not in kw and "omega" not in kw:
        args["w"] = (0, 0, 0)
    args.update(kw)
    return lgvi.Scenario(**args)


def test_the_initial_state_and_ball_radii_are_required_as_in_scenario_files():
    # The TOML reader requires position, quaternion, momentum | velocity, w | omega and a ball's radius;
    # the Python front end asks for the same, in one line naming the key (no silent zeros).
    full = dict(body=body(), step=0.01, duration=1.0, position=(0, 0, 0), quaternion=(1, 0, 0, 0),
                momentum=(0, 0, 0), omega=(0, 0, 0))
    for drop, message in (("position", "position: missing"), ("quaternion", "quaternion: missing"),
                          ("momentum", "momentum, velocity: give one of them"),
                          ("omega", "w, omega: give one of them")):
        args = {k: v for k, v in full.items() if k != drop}
        with pytest.raises(ValueError, match=message) as info:
            lgvi.Scenario(**args)
        assert "\n" not in str(info.value) and "scenario file" in str(info.value)
    for ball in (((0, 0, 0), 1.0), {"position": (0, 0, 0), "mass": 1.0}):
        with pytest.raises(ValueError, match=r"balls\[0\]: needs .*radius.*0 for a point mass"):
            lgvi.Body.from_balls([ball, ((1, 0, 0), 1.0, 0.0), ((0, 1, 0), 1.0, 0.0)])


BAD_ARGUMENTS = [
    # Bodies
    (lambda: lgvi.Body(mass=-1.0, inertia=np.eye(3)), "mass"),
    (lambda: lgvi.Body(mass=float("nan"), inertia=np.eye(3)), "mass"),
    (lambda: lgvi.Body(mass="1", inertia=np.eye(3)), "mass"),
    (lambda: lgvi.Body(mass=1.0), "inertia"),
    (lambda: lgvi.Body(mass=1.0, inertia=[[1, 0], [0, 1]]), "inertia"),
    (lambda: lgvi.Body(mass=1.0, inertia=np.diag([1.0, np.inf, 1.0])), "inertia"),
    (lambda: lgvi.Body(mass=1.0, inertia=[[1, 0.5, 0], [0, 1, 0], [0, 0, 1]]), "inertia"),   # not symmetric
    (lambda: lgvi.Body(mass=1.0, inertia=np.diag([1.0, -1.0, 1.0])), "inertia"),              # not definite
    (lambda: lgvi.Body(mass=1.0, inertia=np.diag([1.0, 1.0, 3.0])), "inertia"),               # J1 + J2 < J3
    (lambda: lgvi.Body(balls=[]), "balls"),
    (lambda: lgvi.Body(mass=1.0, inertia=np.eye(3), balls=[((0, 0, 0), 1.0, 0.1)]), "balls"),
    (lambda: lgvi.Body(mass=1.0, inertia=np.diag([0.0, 1.0, 2.0])), "inertia"),  # a zero moment, not a line's
    (lambda: lgvi.Body.from_balls([((0, 0), 1.0, 0.1)]), "balls[0].position"),
    (lambda: lgvi.Body.from_balls([((0, 0, 0), 1.0, 0.1), ((1, 0, 0), -1.0, 0.1)]), "balls[1].mass"),
    (lambda: lgvi.Body.from_balls([((0, 0, 0), 1.0, -0.1)]), "balls[0].radius"),
    (lambda: lgvi.Body.from_balls([{"position": (0, 0, 0), "mas": 1.0}]), "balls[0]"),
    (lambda: lgvi.Body.from_balls([5]), "balls[0]"),
    # Initial state
    (lambda: scenario(quaternion=(1.0, 0.0, 0.0, 0.01)), "quaternion"),          # |q| - 1 = 5e-5
    (lambda: scenario(quaternion=(1.0 + 2e-6, 0.0, 0.0, 0.0)), "quaternion"),    # just beyond 1e-6
    (lambda: scenario(quaternion=(0.0, 0.0, 0.0, 0.0)), "quaternion"),
    (lambda: scenario(quaternion=(1.0, 0.0, 0.0)), "quaternion"),
    (lambda: scenario(quaternion=(np.nan, 0.0, 0.0, 1.0)), "quaternion"),
    (lambda: scenario(quaternion=[[1.0, 0.0, 0.0, 0.0]]), "quaternion"),
    (lambda: scenario(position=(np.nan, 0.0, 0.0)), "position"),
    (lambda: scenario(position=(1.0, 2.0)), "position"),
    (lambda: scenario(position="origin"), "position"),
    (lambda: scenario(momentum=(0, 0, 0), velocity=(0, 0, 0)), "momentum, velocity"),
    (lambda: scenario(velocity=(0, np.inf, 0)), "velocity"),
    (lambda: scenario(w=(1, 2, 3), omega=(1, 2, 3)), "w, omega"),
    (lambda: scenario(w=(1, 2, 3, 4)), "w"),
    (lambda: scenario(omega=(0, 0, -np.inf)), "omega"),
    (lambda: scenario(body="rigid"), "body"),
    # Integrator and output
    (lambda: scenario(step=0.0), "step"),
    (lambda: scenario(step=-0.01), "step"),
    (lambda: scenario(step=float("nan")), "step"),
    (lambda: scenario(step="0.01"), "step"),
    (lambda: scenario(duration=-1.0), "duration"),
    (lambda: scenario(duration=float("inf")), "duration"),
    (lambda: scenario(method="rk4"), "method"),
    (lambda: scenario(solver="gauss-seidel"), "solver"),
    (lambda: scenario(tolerance=0.1), "tolerance"),          # the C++ reader's range check
    (lambda: scenario(max_iterations=0), "max_iterations"),
    (lambda: scenario(predictor_order=4), "predictor_order"),
    (lambda: scenario(every=0), "every"),
    (lambda: scenario(every=1.5), "every"),
    (lambda: scenario(output_format="xlsx"), "output_format"),
    (lambda: scenario(name=""), "name"),
    (lambda: scenario(omega=(400.0, 0, 0)), "integrator.step"),  # rotation per step 4 rad: the reader says so
    # Potentials
    (lambda: lgvi.potential.central(-1.0), "mu"),
    (lambda: lgvi.potential.central(float("nan")), "mu"),
    (lambda: lgvi.potential.uniform([0.0, -9.81]), "g"),
    (lambda: scenario(potential="central"), "potential"),
    (lambda: scenario(potential={"kind": "magnetic"}), "potential.kind"),
    (lambda: scenario(potential={"kind": "central"}), "potential.mu"),
    (lambda: scenario(potential={"kind": "central", "mu": 1.0, "g": 1}), "potential"),
    (lambda: scenario(potential=lgvi.PythonPotential(lambda x, q: (0, 0, 0))), "potential"),
    (lambda: lgvi.PythonPotential(), "energy"),
    (lambda: lgvi.PythonPotential(5), "function"),
    (lambda: lgvi.PythonPotential(lambda x, q: 0, energy=lambda x, q: 0), "potential"),
    (lambda: lgvi.PythonPotential(energy=abs, force=abs, torque=3), "torque"),
    (lambda: lgvi.PythonPotential(abs).check((0, 0, 1), (2, 0, 0, 0)), "quaternion"),
    # simulate, Stepper, Scenario methods
    (lambda: lgvi.simulate(42), "scenario"),
    (lambda: lgvi.simulate(scenario(), potential="central"), "potential"),
    (lambda: lgvi.simulate(scenario(), potential=lgvi.potential.central(1.0)), "potential"),
    (lambda: lgvi.simulate(scenario(), potential=3.0), "potential"),
    (lambda: lgvi.Stepper(scenario(), potential=[1, 2, 3]), "potential"),
    (lambda: lgvi.Stepper(scenario()).step(-1), "n"),
    (lambda: lgvi.Stepper(scenario()).step(1.5), "n"),
    (lambda: lgvi.Stepper(scenario()).set_state(quaternion=(0.0, 0.0, 0.0, 2.0)), "quaternion"),
    (lambda: lgvi.Stepper(scenario()).set_state(position=(1.0, 2.0)), "position"),
    (lambda: lgvi.Stepper(scenario()).set_state(momentum=(np.nan, 0, 0)), "momentum"),
    (lambda: lgvi.Stepper(scenario()).set_state(w=(0, 0, 0), omega=(0, 0, 0)), "w, omega"),
    (lambda: lgvi.Stepper(scenario()).set_potential("uniform"), "potential"),
    (lambda: scenario().replace(stepsize=0.1), "stepsize"),
    (lambda: scenario().replace(step=0), "step"),
    (lambda: scenario().evaluate_potential((0, 0, 0), (1, 0, 0, 1)), "quaternion"),
    (lambda: scenario().evaluate_potential((0, 0), (1, 0, 0, 0)), "position"),
    (lambda: short_orbit().evaluate_potential(-short_orbit().body.balls[0]["position"], (1, 0, 0, 0)),
     "position"),  # ball 0 at the centre of the central field
    (lambda: lgvi.Scenario.from_string(b"[body]"), "text"),
    (lambda: lgvi.Result(np.zeros((3, 20))), "data"),
]


def test_point_masses_on_a_line_are_a_linear_body():
    # No moment about the line (J = I (1 - n n^T), I = sum m s^2 about the centre: 2 * 0.5^2), two rotational
    # degrees of freedom; one point mass has none (rigid_body.hpp).
    rod = lgvi.Body.from_balls([((0, 0, 0), 1.0, 0.0), ((0, 1, 0), 1.0, 0.0)])
    assert rod.rotational_dof == 2 and abs(abs(rod.linear_axis[1]) - 1.0) <= 1e-15
    assert np.allclose(rod.inertia, np.diag([0.5, 0.0, 0.5]), rtol=0, atol=1e-16)
    assert np.allclose(rod.inertia_inverse, np.diag([2.0, 0.0, 2.0]), rtol=0, atol=1e-15)
    point = lgvi.Body.from_balls([((1, 2, 3), 2.0, 0.0)])
    assert point.rotational_dof == 0 and not point.inertia.any() and not point.linear_axis.any()
    assert lgvi.Body.sphere(1.0, 0.5).rotational_dof == 3
    # Its state has no momentum about the axis: set_state refuses one, in one line, as a scenario file does.
    sc = lgvi.Scenario(body=rod, step=0.01, duration=1.0, position=(0, 0, 0), quaternion=(1, 0, 0, 0),
                       momentum=(0, 0, 0), omega=(0.3, 0.0, 0.2))
    stepper = lgvi.Stepper(sc)
    with pytest.raises(ValueError, match="no angular momentum about its axis") as info:
        stepper.set_state(w=(0.2, 0.1, 0.0))
    assert "\n" not in str(info.value)
    stepper.set_state(w=(0.2, 0.0, 0.1))
    stepper.step(10)
    assert stepper.w[1] == 0.0


@pytest.mark.parametrize("make, argument", BAD_ARGUMENTS, ids=[f"{i}-{a}" for i, (_, a) in enumerate(BAD_ARGUMENTS)])
def test_invalid_arguments_raise_value_error_naming_the_argument(make, argument):
    with pytest.raises(ValueError) as info:
        make()
    message = str(info.value)
    assert argument in message, message
    assert "\n" not in message


def test_quaternion_within_tolerance_is_accepted_and_normalized():
    sc = scenario(quaternion=(1.0 + 5e-7, 0.0, 0.0, 0.0))  # |q| - 1 = 5e-7 <= 1e-6
    assert np.array_equal(sc.quaternion, [1.0, 0.0, 0.0, 0.0])
    assert "scalar-first (w, x, y, z)" in str(pytest.raises(ValueError, scenario, quaternion=(2, 0, 0, 0)).value)


@needs_cli
@pytest.mark.parametrize("name", ["negative-duration", "non-unit-quaternion", "pi-rotation", "step-negative",
                                  "step-zero", "unknown-key", "wrong-type"])
def test_bad_scenario_files_give_the_clis_message(tmp_path, name):
    path = SOURCE / "tests" / "cli" / "bad" / f"{name}.toml"
    proc = run_cli(path, tmp_path / "run")
    assert proc.returncode == 2
    with pytest.raises(ValueError) as info:
        lgvi.Scenario.from_toml(path)
    assert proc.stderr.strip() == f"lgvi: error: {info.value}"
    with pytest.raises(ValueError) as again:
        lgvi.Scenario.from_string(path.read_text(), str(path))
    assert str(again.value) == str(info.value)


def test_scenario_text_errors_name_the_key():
    with pytest.raises(ValueError, match=r"^mine: key 'integrator.stepp': unknown key"):
        lgvi.Scenario.from_string(scenario().toml.replace("step =", "stepp ="), "mine")
    with pytest.raises(ValueError, match=r"^scenario:1:"):
        lgvi.Scenario.from_string("[body\n")
    with pytest.raises(FileNotFoundError):
        lgvi.Scenario.from_toml(SOURCE / "scenarios" / "missing.toml")
    with pytest.raises(FileNotFoundError):
        lgvi.simulate(str(SOURCE / "scenarios" / "missing.toml"))


def test_python_potential_errors():
    sc = short_orbit(duration=0.05)
    cases = [(lambda x, q: (0.0, np.zeros(2), np.zeros(3)), "force"),
             (lambda x, q: (0.0, np.zeros(3), "spin"), "torque"),
             (lambda x, q: ("high", np.zeros(3), np.zeros(3)), "energy"),
             (lambda x, q: (0.0, np.zeros(3)), "potential"),
             (lambda x, q: None, "potential")]
    for fn, argument in cases:
        with pytest.raises(ValueError, match=argument):
            lgvi.simulate(sc, fn)
        with pytest.raises(ValueError, match=argument):
            lgvi.Stepper(sc, fn)
    with pytest.raises(ValueError, match="force"):
        lgvi.simulate(sc, lgvi.PythonPotential(energy=lambda x, q: 0.0, force=lambda x, q: [0.0],
                                               torque=lambda x, q: [0.0, 0.0, 0.0]))

    def raising(x, q):
        raise ZeroDivisionError("inside the potential")
    with pytest.raises(ZeroDivisionError, match="inside the potential"):
        lgvi.simulate(sc, raising)


def test_integration_failure_raises_with_the_partial_result():
    sc = lgvi.Scenario.from_toml(SOURCE / "tests" / "cli" / "bad" / "no-root.toml")
    with pytest.raises(lgvi.IntegrationError) as info:
        lgvi.simulate(sc)
    e = info.value
    assert isinstance(e, RuntimeError)
    assert str(e).startswith("step 0 (from t = 0) failed: ") and "no root" in str(e)
    assert (e.step, e.time) == (0, 0.0)
    assert isinstance(e.result, lgvi.Result) and not e.result.completed and len(e.result) == 1
    assert e.result.error == str(e)
    r = lgvi.simulate(sc, check=False)
    assert not r.completed and r.error == str(e) and np.array_equal(r.data, e.result.data)
    # A Python potential that becomes non-finite at step 5: the rows up to the last good step.

    def blows_up(x, q):
        return 0.0, np.zeros(3), (np.full(3, np.nan) if x[0] > 0.45 else np.zeros(3))
    free = scenario(velocity=(10.0, 0.0, 0.0), duration=1.0)  # x_k = 0.1 k
    with pytest.raises(lgvi.IntegrationError, match="non-finite") as info:
        lgvi.simulate(free, blows_up)
    # Cause-neutral, naming the step, its time and what was not finite.
    assert str(info.value).startswith("step 4 (from t = 0.04) failed: the potential returned a non-finite torque")
    assert "ball" not in str(info.value)
    for which in ("energy", "force"):
        def bad(x, q, which=which):
            nan = np.nan if x[0] > 0.45 else 0.0
            return (nan if which == "energy" else 0.0), (np.full(3, nan) if which == "force" else np.zeros(3)), \
                np.zeros(3)
        with pytest.raises(lgvi.IntegrationError) as info:
            lgvi.simulate(free, bad)
        assert str(info.value).startswith(f"step 4 (from t = 0.04) failed: the potential returned a non-finite "
                                          f"{which}"), str(info.value)
    assert info.value.step == 4 and len(info.value.result) == 5 and info.value.result.t[-1] == 0.04
    assert np.array_equal(info.value.result.data, lgvi.simulate(free.replace(duration=0.04)).data)


# ---------------------------------------------------------------------------
# (4) The stepping object

@pytest.mark.parametrize("method", ORBIT_METHODS)
def test_stepper_rows_equal_simulates(method):
    sc = short_orbit(duration=3.0, every=1, method=method)
    r = lgvi.simulate(sc)
    st = lgvi.Stepper(sc)
    rows = [st.row]
    for k in range(1, sc.steps + 1):
        st.step()
        assert st.k == k and st.t == k * sc.step  # t0 + k h, never accumulated
        rows.append(st.row)
    assert np.array_equal(np.array(rows), r.data)
    bulk = lgvi.Stepper(sc)
    bulk.step(sc.steps)
    assert np.array_equal(bulk.row, r.data[-1])
    assert np.array_equal(bulk.quaternion, r.q[-1]) and np.array_equal(bulk.position, r.x[-1])
    assert np.array_equal(bulk.momentum, r.p[-1]) and np.array_equal(bulk.w, r.w[-1])
    assert bulk.energy == r.energy[-1] and bulk.energy_error == r.energy_error[-1]
    assert np.array_equal(bulk.angular_momentum, r.L[-1])
    assert np.allclose(bulk.omega, 0.5 * np.linalg.solve(sc.body.inertia, bulk.w), rtol=1e-15, atol=0)
    assert np.allclose(bulk.rotation_matrix, plot.rotation_matrix(bulk.quaternion), rtol=0, atol=1e-15)
    s = bulk.state
    assert s["k"] == sc.steps and np.array_equal(s["quaternion"], bulk.quaternion)
    e, f, m = sc.evaluate_potential(bulk.position, bulk.quaternion)
    assert bulk.potential_energy == e and np.array_equal(bulk.force, f) and np.array_equal(bulk.torque, m)


def test_stepper_with_a_python_potential_equals_simulate_with_it():
    sc = short_orbit(duration=1.0, every=1)
    central = python_central_gravity(sc.body, 1.0)
    r = lgvi.simulate(sc, central)
    st = lgvi.Stepper(sc, lgvi.PythonPotential(central))
    rows = [st.row]
    for _ in range(sc.steps):
        st.step()
        rows.append(st.row)
    assert np.array_equal(np.array(rows), r.data)


def thrust_scenario():
    return scenario(body=lgvi.Body(mass=2.0, inertia=np.diag([1.0, 2.0, 2.5])), velocity=(1.0, 0.0, 0.0),
                    omega=(0.0, 0.5, 1.0), step=0.01, duration=1.0)


def test_changing_a_parameter_between_steps_changes_the_motion():
    thrust = {"u": np.zeros(3)}

    def potential(x, q):  # V = -u . x: force u (inertial), no torque
        return -float(thrust["u"] @ x), thrust["u"].copy(), np.zeros(3)
    sc = thrust_scenario()
    h = sc.step
    free = lgvi.Stepper(sc)               # no potential at all
    ctl = lgvi.Stepper(sc, potential)
    free.step(10)
    ctl.step(10)
    assert np.array_equal(ctl.row, free.row)  # zero thrust: the same motion as the free body
    p0 = ctl.momentum
    thrust["u"] = np.array([0.0, 0.0, 3.0])
    ctl.refresh()                          # the next step starts from the new force
    ctl.step()
    # p1 = p0 + (h/2)(F0 + F1) with F0 = F1 = u: the whole impulse h u in this step.
    assert np.allclose(ctl.momentum - p0, h * thrust["u"], rtol=1e-14, atol=0)
    ctl.step(9)
    free.step(10)
    assert ctl.position[2] > 0.0 and free.position[2] == 0.0
    # Without refresh() the step starts from the force computed with the old value (here zero): half the impulse.
    late = lgvi.Stepper(sc, potential)
    thrust["u"] = np.zeros(3)
    late.step(10)
    p0 = late.momentum
    thrust["u"] = np.array([0.0, 0.0, 3.0])
    late.step()
    assert np.allclose(late.momentum - p0, 0.5 * h * thrust["u"], rtol=1e-14, atol=0)


def test_set_potential_and_set_state():
    sc = thrust_scenario()
    st = lgvi.Stepper(sc)
    st.step(5)
    st.set_potential(lgvi.PythonPotential(lambda x, q: (0.0, np.array([0.0, 0.0, -1.0]), np.zeros(3))))
    assert np.array_equal(st.force, [0.0, 0.0, -1.0]) and st.potential is not None
    st.step(5)
    assert st.k == 10 and st.momentum[2] < 0.0
    st.set_potential(None)                 # back to the scenario's own (none)
    assert np.array_equal(st.force, [0.0, 0.0, 0.0]) and st.potential is None
    p = st.momentum
    st.step(3)
    assert np.array_equal(st.momentum, p)  # free flight conserves p exactly
    st.set_state(momentum=st.momentum + np.array([0.0, 1.0, 0.0]))  # an impulse
    assert st.momentum[1] == 1.0 and st.k == 13
    st.set_state(velocity=(0.0, 0.0, 0.0), omega=(0.0, 0.0, 2.0), position=(1.0, 2.0, 3.0),
                 quaternion=(0.0, 0.0, 0.0, 1.0))
    assert np.array_equal(st.momentum, [0.0, 0.0, 0.0]) and np.allclose(st.omega, [0.0, 0.0, 2.0], rtol=1e-15)
    assert np.array_equal(st.quaternion, [0.0, 0.0, 0.0, 1.0]) and np.array_equal(st.position, [1.0, 2.0, 3.0])
    st.step(100)
    assert np.array_equal(st.position, [1.0, 2.0, 3.0])
    assert abs(np.linalg.norm(st.quaternion) - 1.0) < 1e-14  # a steady spin: |q| stays 1 to round-off


def test_stepper_failure_keeps_the_last_good_state():
    sc = lgvi.Scenario.from_toml(SOURCE / "tests" / "cli" / "bad" / "no-root.toml")
    st = lgvi.Stepper(sc)
    before = st.row
    with pytest.raises(lgvi.IntegrationError, match=r"^step 0 \(from t = 0\) failed") as info:
        st.step()
    assert info.value.step == 0 and info.value.result is None
    assert st.k == 0 and np.array_equal(st.row, before)
    st.set_state(omega=(20.0, 0.0, 0.0))  # slow down: the run goes on
    st.step(10)
    assert st.k == 10


# ---------------------------------------------------------------------------
# (5) Loading runs

@needs_cli
def test_load_round_trips_a_cli_run_folder(paper_orbit_cli, paper_orbit_result, tmp_path):
    out, (_, data, summary) = paper_orbit_cli
    loaded = lgvi.load(out)
    assert np.array_equal(loaded.data, data) and np.array_equal(loaded.data, paper_orbit_result.data)
    assert loaded.summary == summary and loaded.completed
    assert loaded.scenario_toml == PAPER_ORBIT.read_text()
    assert np.array_equal(lgvi.load(out / "trajectory.csv").data, data)
    saved = paper_orbit_result.save(tmp_path / "saved")
    again = lgvi.load(saved)
    assert np.array_equal(again.data, paper_orbit_result.data) and again.summary == paper_orbit_result.summary
    assert again.scenario_toml == paper_orbit_result.scenario_toml
    columns, s = lgvi.load_run(out)
    assert list(columns) == list(lgvi.COLUMNS) and s == summary


@needs_cli
@pytest.mark.parametrize("fmt, file", [("npz", "trajectory.npz"), ("hdf5", "trajectory.h5")])
def test_load_reads_npz_and_hdf5_runs(tmp_path, fmt, file):
    if fmt == "hdf5":
        pytest.importorskip("h5py")
    sc = short_orbit(duration=3.0, every=3, output_format=fmt, name=f"orbit-{fmt}")
    path = sc.save(tmp_path / f"orbit-{fmt}.toml")
    proc = run_cli(path, tmp_path / "run")
    assert proc.returncode == 0, proc.stderr
    expected = lgvi.simulate(sc)
    for source in (tmp_path / "run", tmp_path / "run" / file):
        loaded = lgvi.load(source)
        assert np.array_equal(loaded.data, expected.data)
        assert without_wall_time(loaded.summary) == without_wall_time(expected.summary)
        assert loaded.scenario_toml == sc.toml
    written = plot.draw_figures(str(tmp_path / "run"), str(tmp_path / "figs"))
    assert sorted(os.path.basename(p) for p in written) == sorted(FIGURES)


def test_load_errors(tmp_path):
    with pytest.raises(FileNotFoundError):
        lgvi.load(tmp_path / "nothing")
    with pytest.raises(FileNotFoundError):
        lgvi.load(tmp_path)  # a folder without a trajectory
    (tmp_path / "t.txt").write_text("1,2,3\n")
    with pytest.raises(ValueError, match="unknown trajectory format"):
        lgvi.load(tmp_path / "t.txt")
    (tmp_path / "trajectory.csv").write_text("t,x\n0,1\n")
    with pytest.raises(ValueError, match="columns"):
        lgvi.load(tmp_path)
    (tmp_path / "bad.npz").write_bytes(b"PK\x03\x04 not really")
    with pytest.raises(ValueError, match="npz"):
        lgvi.load(tmp_path / "bad.npz")


# ---------------------------------------------------------------------------
# Plotting from memory, the examples, Ctrl-C

def test_draw_figures_from_memory(tmp_path):
    r = lgvi.simulate(short_orbit(duration=5.0))
    written = plot.draw_figures(r, str(tmp_path))
    assert sorted(os.path.basename(p) for p in written) == sorted(FIGURES)
    assert all((tmp_path / f).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for f in FIGURES)
    # Result.draw_figures stays working but is deprecated (the data class does not import the
    # figure module): it must warn, name the replacement, and still draw the five figures.
    with pytest.warns(DeprecationWarning, match=r"lgvi\.plot\.draw_figures"):
        assert len(r.draw_figures(tmp_path / "again")) == 5
    with pytest.raises(ValueError, match="out_dir"):
        plot.draw_figures(r)
    with pytest.raises(TypeError, match="source"):
        plot.draw_figures(42, str(tmp_path))


EXAMPLES = [("paper_experiment.py", ["--duration", "3"], ["paper-orbit/trajectory.png", "paper/body_motion.png",
                                                           "paper-orbit/trajectory.csv"]),
            ("step_size_study.py", ["--duration", "2"], ["energy_error_vs_step.png"]),
            ("control_loop.py", ["--duration", "2"], []),
            ("gyro_noise.py", ["--duration", "5"], [])]


@pytest.mark.parametrize("script, args, outputs", EXAMPLES, ids=[e[0] for e in EXAMPLES])
def test_examples_run(tmp_path, script, args, outputs):
    cmd = [sys.executable, str(SOURCE / "examples" / script)] + args
    if outputs:
        cmd += ["--out", str(tmp_path)]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=package_env(MPLBACKEND="Agg"), cwd=tmp_path,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("|")  # a Markdown table
    for name in outputs:
        assert (tmp_path / name).is_file(), name


def test_ctrl_c_stops_a_long_run(tmp_path):
    script = f"""
import os, signal, threading, time, lgvi
sc = lgvi.Scenario.from_toml({str(PAPER_ORBIT)!r}).replace(duration=1e6, every=1000000)  # 10^8 steps, ~20 s
threading.Timer(0.3, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
start = time.perf_counter()
try:
    lgvi.simulate(sc)
    print("completed")
except KeyboardInterrupt:
    print("interrupted after", time.perf_counter() - start)
stepper = lgvi.Stepper(sc)
threading.Timer(0.3, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
start = time.perf_counter()
try:
    stepper.step(10 ** 8)
    print("completed")
except KeyboardInterrupt:
    print("interrupted after", time.perf_counter() - start, "at", stepper.k)
"""
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60, env=package_env())
    assert proc.returncode == 0, proc.stderr
    first, second = proc.stdout.splitlines()
    assert first.startswith("interrupted") and float(first.split()[-1]) < 2.0, proc.stdout
    words = second.split()  # the stepper stops at a leg boundary, in a consistent state
    assert words[0] == "interrupted" and float(words[2]) < 2.0 and int(words[-1]) % 4096 == 0, proc.stdout


# ---------------------------------------------------------------------------
# Docstrings and type stubs

PUBLIC_CLASSES = {"Body": lgvi.Body, "Scenario": lgvi.Scenario, "Result": lgvi.Result, "Stepper": lgvi.Stepper,
                  "PythonPotential": lgvi.PythonPotential}


def public_members(cls):
    return [n for n, _ in inspect.getmembers(cls) if not n.startswith("_") or n == "__call__"]


def test_every_public_name_has_a_docstring():
    import lgvi.potential as potential_module
    for name in lgvi.__all__:
        obj = getattr(lgvi, name)
        if isinstance(obj, (tuple, str)):
            continue
        assert inspect.getdoc(obj), name
    for name in ("none", "central", "uniform", "PythonPotential"):
        assert inspect.getdoc(getattr(potential_module, name)), name
    for name in ("draw_figures", "load_run", "rotation_matrix", "orbit_period", "main"):
        assert inspect.getdoc(getattr(plot, name)), name
    for cname, cls in PUBLIC_CLASSES.items():
        for member in public_members(cls):
            doc = inspect.getdoc(getattr(cls, member))
            assert doc, f"{cname}.{member}"
    for name in ("Body", "Scenario", "Stepper", "simulate", "parse_scenario", "read_scenario", "check_potential"):
        assert getattr(lgvi._core, name).__doc__, name


def test_quaternion_docstrings_say_scalar_first():
    takes_or_returns_q = [lgvi, lgvi.Scenario, lgvi.Scenario.quaternion, lgvi.Scenario.evaluate_potential,
                          lgvi.Result, lgvi.Result.q, lgvi.simulate, lgvi.Stepper, lgvi.Stepper.quaternion,
                          lgvi.Stepper.set_state, lgvi.Stepper.set_potential, lgvi.Stepper.state,
                          lgvi.PythonPotential, lgvi.PythonPotential.check, lgvi.PythonPotential.__call__,
                          lgvi.load, lgvi._core.Stepper.quaternion, lgvi._core.Scenario.quaternion]
    for obj in takes_or_returns_q:
        doc = " ".join(inspect.getdoc(obj).split())
        assert "scalar-first (w, x, y, z)" in doc, getattr(obj, "__qualname__", obj)
    assert "scalar-first (qw, qx, qy, qz)" in plot.__doc__


def test_type_stubs_cover_the_public_api():
    package = pathlib.Path(lgvi.__file__).parent
    tree = ast.parse((package / "__init__.pyi").read_text())
    top = set()
    classes = {}
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            top.add(node.name)
        if isinstance(node, ast.ClassDef):
            classes[node.name] = {n.name if isinstance(n, ast.FunctionDef) else n.target.id
                                  for n in node.body if isinstance(n, (ast.FunctionDef, ast.AnnAssign))}
        elif isinstance(node, ast.AnnAssign):
            top.add(node.target.id)
        elif isinstance(node, ast.ImportFrom):
            top.update(a.asname or a.name for a in node.names)
    assert set(lgvi.__all__) <= top
    for cname, cls in PUBLIC_CLASSES.items():
        if cname == "PythonPotential":
            continue  # in potential.pyi
        missing = set(public_members(cls)) - classes[cname]
        assert not missing, f"{cname}: {missing}"
    stub = ast.parse((package / "potential.pyi").read_text())
    names = {n.name for n in stub.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
    assert {"none", "central", "uniform", "PythonPotential"} <= names
    assert (package / "py.typed").is_file()


def test_import_is_light_and_the_package_is_the_built_one():
    check = ("import sys, lgvi; assert 'numpy' not in sys.modules and 'lgvi._core' not in sys.modules; "
             "lgvi.Scenario; assert 'lgvi._core' in sys.modules; print(lgvi.__version__, lgvi.__file__)")
    proc = subprocess.run([sys.executable, "-c", check], capture_output=True, text=True, env=package_env())
    assert proc.returncode == 0, proc.stderr
    version, path = proc.stdout.split()
    assert version == lgvi.__version__ and pathlib.Path(path).parent == pathlib.Path(lgvi.__file__).parent
