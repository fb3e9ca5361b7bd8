#!/usr/bin/python3
"""Cost of the Python package against the CLI, and of a potential written in Python.

    /usr/bin/python3 benchmarks/bench_python.py [--lgvi build/lgvi] [--repeat 5]

1. The paper-orbit scenario (10^5 steps, 10^4 rows): `lgvi.simulate` (the
   call, returning numpy arrays and the summary dict) against `lgvi run
   --no-figures -q` (its integration loop as summary.json's wall_seconds,
   which includes formatting and writing the 17-digit CSV, and the whole
   process), medians of `--repeat` runs, interleaved in the same process.
2. Per step, on the same orbit (5000 steps): the built-in central gravity
   against potentials written in Python: a constant one (the floor: the
   cost of calling Python once per step, or three times with separate
   energy/force/torque functions) and central gravity written with plain
   Python floats and with numpy.

Prints Markdown tables.
"""

import argparse
import json
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

REPO = pathlib.Path(__file__).resolve().parent.parent
try:
    import lgvi
except ImportError:  # not registered with this interpreter: use the build tree
    sys.path.insert(0, str(REPO / "build" / "python"))
    import lgvi
import numpy as np


def median_time(fn, repeat):
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def python_central_gravity(body, mu):
    rho = np.array([b["position"] for b in body.balls])
    m = np.array([b["mass"] for b in body.balls])

    def central(x, q):
        R = lgvi.plot.rotation_matrix(q)  # q scalar-first (w, x, y, z)
        arm = rho @ R.T
        pos = x + arm
        d = np.sqrt(np.sum(pos * pos, axis=1))
        f = (-mu * m / d ** 3)[:, None] * pos
        return -mu * np.sum(m / d), f.sum(axis=0), np.cross(rho, f @ R).sum(axis=0)
    return central


def plain_python_central_gravity(body, mu):
    """The same in plain Python floats (no numpy): cheaper for a few balls."""
    balls = [(tuple(b["position"]), b["mass"]) for b in body.balls]

    def central(x, q):
        w, a, b, c = q  # scalar first
        R = ((1 - 2 * (b * b + c * c), 2 * (a * b - w * c), 2 * (a * c + w * b)),
             (2 * (a * b + w * c), 1 - 2 * (a * a + c * c), 2 * (b * c - w * a)),
             (2 * (a * c - w * b), 2 * (b * c + w * a), 1 - 2 * (a * a + b * b)))
        V, F, M = 0.0, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
        for rho, m in balls:
            arm = [R[i][0] * rho[0] + R[i][1] * rho[1] + R[i][2] * rho[2] for i in range(3)]
            p = [x[i] + arm[i] for i in range(3)]
            d = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) ** 0.5
            V -= mu * m / d
            f = [-mu * m / d ** 3 * p[i] for i in range(3)]
            F = [F[i] + f[i] for i in range(3)]
            b_f = [R[0][i] * f[0] + R[1][i] * f[1] + R[2][i] * f[2] for i in range(3)]  # R^T f
            M = [M[0] + rho[1] * b_f[2] - rho[2] * b_f[1], M[1] + rho[2] * b_f[0] - rho[0] * b_f[2],
                 M[2] + rho[0] * b_f[1] - rho[1] * b_f[0]]
        return V, F, M
    return central


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lgvi", default=str(REPO / "build" / "lgvi"), help="the lgvi binary")
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args(argv)
    scenario_path = REPO / "scenarios" / "paper-orbit.toml"
    sc = lgvi.Scenario.from_toml(scenario_path)
    lgvi.simulate(sc.replace(duration=1.0))  # warm up (numpy's C API, page faults)

    # 1. simulate() against the CLI, interleaved.
    py_call, py_loop, cli_loop, cli_process = [], [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.repeat):
            start = time.perf_counter()
            r = lgvi.simulate(sc)
            py_call.append(time.perf_counter() - start)
            py_loop.append(r.summary["wall_seconds"])
            start = time.perf_counter()
            subprocess.run([args.lgvi, "run", str(scenario_path), "--out", tmp, "--no-figures", "-q"], check=True)
            cli_process.append(time.perf_counter() - start)
            with open(os.path.join(tmp, "summary.json"), encoding="utf-8") as f:
                cli_loop.append(json.load(f)["wall_seconds"])
    py_process = []
    for _ in range(args.repeat):
        start = time.perf_counter()
        subprocess.run([sys.executable, "-c", f"import lgvi; lgvi.simulate({str(scenario_path)!r})"], check=True,
                       env=dict(os.environ, PYTHONPATH=str(pathlib.Path(lgvi.__file__).parents[1])))
        py_process.append(time.perf_counter() - start)
    med = {k: statistics.median(v) for k, v in (("py_call", py_call), ("py_loop", py_loop), ("cli_loop", cli_loop),
                                                 ("cli_process", cli_process), ("py_process", py_process))}
    steps = sc.steps
    print(f"## lgvi.simulate vs the CLI, scenarios/paper-orbit.toml ({steps} steps, {len(r)} rows), "
          f"median of {args.repeat}\n")
    print("| what | seconds | ns per step | / CLI |")
    print("|---|---:|---:|---:|")
    rows = [("CLI `lgvi run --no-figures -q`: wall_seconds (loop + 17-digit CSV)", med["cli_loop"], med["cli_loop"]),
            ("`lgvi.simulate(scenario)`: the call, numpy arrays + summary dict", med["py_call"], med["cli_loop"]),
            ("`lgvi.simulate`: its wall_seconds (loop + rows to memory)", med["py_loop"], med["cli_loop"]),
            ("CLI: whole process", med["cli_process"], med["cli_process"]),
            ("`python3 -c 'import lgvi; lgvi.simulate(path)'`: whole process", med["py_process"],
             med["cli_process"])]
    for name, seconds, ref in rows:
        print(f"| {name} | {seconds:.4f} | {seconds / steps * 1e9:.0f} | {seconds / ref:.2f} |")

    # 2. A potential written in Python, per step.
    short = sc.replace(duration=50.0)  # 5000 steps
    n = short.steps
    central = python_central_gravity(short.body, 1.0)
    zero3 = np.zeros(3)
    constant = lgvi.PythonPotential(lambda x, q: (0.0, zero3, zero3))
    three = lgvi.PythonPotential(energy=lambda x, q: 0.0, force=lambda x, q: zero3, torque=lambda x, q: zero3)
    plain = plain_python_central_gravity(short.body, 1.0)
    assert lgvi.PythonPotential(plain).check(short.position, short.quaternion)["torque_error"] < 1e-7
    cases = [("built-in central gravity (C++)", None),
             ("Python, constant, one function (x, q) -> (0, zeros, zeros): the call overhead", constant),
             ("Python, constant, three functions energy/force/torque", three),
             ("Python, central gravity in plain Python floats (3 balls)", lgvi.PythonPotential(plain)),
             ("Python, central gravity in numpy (3 balls)", lgvi.PythonPotential(central))]
    print(f"\n## A potential written in Python, paper orbit, {n} steps, median of {args.repeat}\n")
    print("| potential | microseconds per step | / built-in |")
    print("|---|---:|---:|")
    base = None
    for name, pot in cases:
        t = median_time(lambda: lgvi.simulate(short, pot), args.repeat) / n
        base = base or t
        print(f"| {name} | {t * 1e6:.3f} | {t / base:.0f} |")


if __name__ == "__main__":
    main()
