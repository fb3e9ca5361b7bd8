"""Tests for lgvi.plot on a synthetic run directory."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from lgvi import plot

HEADER = ("t,x,y,z,qw,qx,qy,qz,px,py,pz,wx,wy,wz,energy,energy_error,"
          "quat_norm_error,Lx,Ly,Lz,momentum_error")
PERIOD = 50.0
FIGURES = ("trajectory.png", "body_motion.png", "energy_error.png",
           "quaternion_error.png", "momentum_error.png")
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def synthetic_columns(n=1001, t_end=100.0, radius=8.0, spin=0.3):
    """A circular orbit of period PERIOD and a body spinning about z at `spin`."""
    t = np.linspace(0.0, t_end, n)
    om = 2.0 * np.pi / PERIOD
    a = spin * t
    zeros = np.zeros_like(t)
    c = {
        "t": t, "x": radius * np.cos(om * t), "y": radius * np.sin(om * t), "z": zeros,
        "qw": np.cos(a / 2), "qx": zeros, "qy": zeros, "qz": np.sin(a / 2),
        "px": -radius * om * np.sin(om * t), "py": radius * om * np.cos(om * t), "pz": zeros,
        "wx": zeros, "wy": zeros, "wz": zeros + spin,
        "energy": zeros - 0.5, "energy_error": 3e-15 * np.sin(0.7 * t),
        "quat_norm_error": 2e-16 * np.cos(1.3 * t),
        "Lx": zeros, "Ly": zeros, "Lz": zeros + radius ** 2 * om,
        "momentum_error": 1e-15 * np.abs(np.sin(0.2 * t)),
    }
    return c


def write_run(run_dir, c, balls):
    """Write trajectory.csv (17 significant digits) and summary.json."""
    names = HEADER.split(",")
    data = np.column_stack([c[n] for n in names])
    np.savetxt(os.path.join(run_dir, "trajectory.csv"), data, fmt="%.17g",
               delimiter=",", header=HEADER, comments="")
    with open(os.path.join(run_dir, "summary.json"), "w", encoding="utf-8") as f:
        json.dump({"body": {"mass": 3.0, "balls": balls}}, f)


def triangle_balls(side=1.0, radius=0.1):
    r = side / np.sqrt(3.0)
    return [{"position": [r * np.cos(k * 2 * np.pi / 3), r * np.sin(k * 2 * np.pi / 3), 0.0],
             "mass": 1.0, "radius": radius} for k in range(3)]


@pytest.fixture
def run_dir(tmp_path):
    write_run(str(tmp_path), synthetic_columns(), triangle_balls())
    return tmp_path


def assert_pngs(directory):
    for name in FIGURES:
        path = directory / name
        assert path.is_file(), name
        data = path.read_bytes()
        assert data[:8] == PNG_MAGIC, name
        assert len(data) > 1000, name


def test_draw_figures_writes_five_pngs(run_dir):
    written = plot.draw_figures(str(run_dir))
    assert sorted(os.path.basename(p) for p in written) == sorted(FIGURES)
    assert_pngs(run_dir)


def test_draw_figures_out_dir_and_body_without_balls(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    write_run(str(run), synthetic_columns(n=201, t_end=30.0), [])  # no balls, no full orbit
    out = tmp_path / "figs"
    plot.draw_figures(str(run), str(out))
    assert_pngs(out)


def test_load_run_round_trips_exactly(run_dir):
    written = synthetic_columns()
    cols, summary = plot.load_run(str(run_dir))
    assert list(cols) == HEADER.split(",")
    for name, values in written.items():
        assert np.array_equal(cols[name], values), name
    assert len(summary["body"]["balls"]) == 3


def test_orbit_period():
    c = synthetic_columns()
    dt = c["t"][1] - c["t"][0]
    period = plot.orbit_period(c["t"], c["x"], c["y"])
    assert period is not None and abs(period - PERIOD) <= dt
    # Clockwise orbit, starting off the x axis.
    t = c["t"]
    period = plot.orbit_period(t, 5 * np.cos(1 - 2 * np.pi * t / PERIOD), 5 * np.sin(1 - 2 * np.pi * t / PERIOD))
    assert period is not None and abs(period - PERIOD) <= dt


def test_orbit_period_none_for_radial_and_short_motion():
    t = np.linspace(0.0, 10.0, 101)
    assert plot.orbit_period(t, 1.0 + t, 2.0 * (1.0 + t)) is None
    c = synthetic_columns(n=101, t_end=40.0)
    assert plot.orbit_period(c["t"], c["x"], c["y"]) is None
    assert plot.orbit_period(t[:1], t[:1] + 1, t[:1]) is None


EPS = np.finfo(float).eps


def test_rotation_matrix_about_z():
    # cos(a/2) and sin(a/2) are rounded, so |q| = 1 only to an ulp or so and
    # R = pi(q) inherits that: over this sweep the worst cases are 6 ulps
    # (R vs the exact matrix) and 12 ulps (R R^T - I), i.e. a flat 1e-15 is
    # slightly too tight; the bounds below are a few ulps with margin.
    for a in np.linspace(-np.pi, np.pi, 2001):
        R = plot.rotation_matrix([np.cos(a / 2), 0.0, 0.0, np.sin(a / 2)])
        expected = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
        assert np.max(np.abs(R - expected)) <= 8 * EPS, a
        assert np.max(np.abs(R @ R.T - np.eye(3))) <= 16 * EPS, a
    assert np.array_equal(plot.rotation_matrix([1.0, 0.0, 0.0, 0.0]), np.eye(3))


def test_rotation_matrix_general_and_batched():
    rng = np.random.default_rng(1)
    q = rng.normal(size=(20, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    R = plot.rotation_matrix(q)
    assert R.shape == (20, 3, 3)
    for qi, Ri in zip(q, R):
        assert np.array_equal(plot.rotation_matrix(qi), Ri)
        assert np.max(np.abs(Ri @ Ri.T - np.eye(3))) <= 1e-14
        assert abs(np.linalg.det(Ri) - 1.0) <= 1e-14
        # pi(q) v = q * v * conj(q) (Hamilton product, scalar-first).
        v = rng.normal(size=3)
        w, u = qi[0], qi[1:]
        rotated = v + 2 * w * np.cross(u, v) + 2 * np.cross(u, np.cross(u, v))
        assert np.allclose(Ri @ v, rotated, rtol=0, atol=1e-13)


def test_main_quiet_on_success(run_dir, capsys):
    assert plot.main([str(run_dir)]) == 0
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == ""
    assert_pngs(run_dir)


def test_main_missing_directory(tmp_path, capsys):
    assert plot.main([str(tmp_path / "nope")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("lgvi.plot: error: ") and err.count("\n") == 1


@pytest.mark.parametrize("problem", ["empty", "no_summary", "bad_header"])
def test_main_bad_run_directory(tmp_path, capsys, problem):
    write_run(str(tmp_path), synthetic_columns(n=11), triangle_balls())
    csv = tmp_path / "trajectory.csv"
    if problem == "empty":
        csv.write_text(HEADER + "\n")
    elif problem == "no_summary":
        (tmp_path / "summary.json").unlink()
    else:
        lines = csv.read_text().splitlines()
        csv.write_text("\n".join([lines[0].replace(",momentum_error", "")] + lines[1:]) + "\n")
    assert plot.main([str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("lgvi.plot: error: ") and err.count("\n") == 1


def test_module_entry_point_and_light_import(run_dir):
    python_dir = os.path.join(os.path.dirname(__file__), "..", "..", "python")
    env = dict(os.environ, PYTHONPATH=os.path.abspath(python_dir))
    check = "import sys, lgvi; assert 'matplotlib' not in sys.modules and 'numpy' not in sys.modules"
    subprocess.run([sys.executable, "-c", check], env=env, check=True)
    out = run_dir / "out"
    proc = subprocess.run([sys.executable, "-m", "lgvi.plot", str(run_dir), "--out", str(out)],
                          env=env, capture_output=True, text=True)
    assert proc.returncode == 0 and proc.stdout == "" and proc.stderr == ""
    assert_pngs(out)
    proc = subprocess.run([sys.executable, "-m", "lgvi.plot", str(run_dir / "missing")],
                          env=env, capture_output=True, text=True)
    assert proc.returncode == 1 and proc.stderr.startswith("lgvi.plot: error: ")
