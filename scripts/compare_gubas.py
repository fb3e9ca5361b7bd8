#!/usr/bin/python3
"""lgvi against GUBAS (meyeralexj/gubas, the binary-asteroid simulator built on the
full-body LGVI of Lee, Leok & McClamroch) on GUBAS's Didymos example at order 2
(scenarios/didymos-order2.toml):

    /usr/bin/python3 scripts/compare_gubas.py GUBAS_DIR LGVI_BINARY OUT_DIR [--repeat 5]

GUBAS_DIR is a checkout of GUBAS with its C++ part built as GUBAS's
compileCommand.txt says (g++ hou_cpp.cpp -o hou_cpp_final -larmadillo; Debian:
libarmadillo-dev, and python3-scipy for its Python driver). Nothing of GUBAS is
part of lgvi: this script copies GUBAS's files into OUT_DIR/gubas, writes there
GUBAS's own example configuration changed to the case (expansion and
inertia-integral orders 2, one day, output every 30 s step; the primary stays
the example's polyhedron, the secondary its ellipsoid), and
runs GUBAS's driver. It runs lgvi on the scenario, and compares, over the day:

* the relative position r = R_p^T (x_s - x_p) in the primary's frame (GUBAS's
  state), relative to |r|;
* the relative attitude C = R_p^T R_s and the primary's attitude R_p, as angles;
* the total energy's change over the day in each program;

and, as the scale those differences should be judged on, lgvi's own truncation
error: the same quantities between lgvi at 30 s and lgvi at 30/16 s. Times per
step: GUBAS's integrator (hou_cpp_final, which reads its inputs and writes every
state in binary) and `lgvi run` (wall_seconds: the loop with its diagnostics, no
trajectory rows but the first and last), each run --repeat times in this
invocation, medians.
"""
import argparse
import json
import pathlib
import re
import shutil
import statistics
import subprocess
import sys
import time

import numpy as np

from lgvi.plot import rotation_matrix as rotation  # R = pi(q), q scalar-first

ROOT = pathlib.Path(__file__).resolve().parent.parent
SCENARIO = ROOT / "scenarios" / "didymos-order2.toml"
CHANGES = [  # (GUBAS's example line, the line for this case)
    ("Gravity Expansion Truncation Order: 4", "Gravity Expansion Truncation Order: 2"),
    ("Primary Inertia Integral Truncation Order: 4", "Primary Inertia Integral Truncation Order: 2"),
    ("Secondary Inertia Integral Truncation Order: 4", "Secondary Inertia Integral Truncation Order: 2"),
    ("Final Time: 7200.", "Final Time: 86400."),
    ("Fixed Output Frequency: 3600.", "Fixed Output Frequency: 30."),
]


def angle(a, b):
    """The rotation angle of a^T b, from its skew part and trace (accurate near 0,
    where arccos of the trace alone loses half the digits)."""
    r = a.T @ b
    s = 0.5 * np.linalg.norm([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    return float(np.arctan2(s, (np.trace(r) - 1.0) / 2.0))


def run_gubas(gubas, work):
    work.mkdir(parents=True, exist_ok=True)
    for f in list(gubas.glob("*.py")) + [gubas / "hou_cpp_final"] + list((gubas / "example").glob("*.csv")):
        shutil.copy(f, work)
    cfg = (gubas / "example" / "hou_config.cfg").read_text()
    for old, new in CHANGES:
        if old not in cfg:
            sys.exit(f"GUBAS's example configuration has no line '{old}': another GUBAS version?")
        cfg = cfg.replace(old, new)
    (work / "hou_config.cfg").write_text(cfg)
    out = subprocess.run([sys.executable, "hou_shell_cfg.py"], cwd=work, capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"GUBAS failed:\n{out.stdout}\n{out.stderr}")
    (lagrangian,) = work.glob("LagrangianStateOut_*.csv")
    (energy,) = work.glob("Energy+AngMom_*.csv")
    # t, r (A frame, m), v (A frame), w_A, w_B, C = B into A (row-major), A into N (row-major), U.
    state = np.loadtxt(lagrangian, delimiter=",", ndmin=2)
    e = np.loadtxt(energy, delimiter=",", ndmin=2)[:, 0] * 1e6  # kg km^2/s^2 -> J
    return state, e


def run_lgvi(lgvi, scenario_text, out, every=None):
    text = scenario_text if every is None else re.sub(r"every = \d+", f"every = {every}", scenario_text)
    path = out.with_suffix(".toml")
    path.write_text(text)
    subprocess.run([lgvi, "run", path, "--out", out, "--force", "--no-figures", "-q", "--threads", "1"], check=True)
    rows = np.loadtxt(out / "trajectory.csv", delimiter=",", skiprows=1, ndmin=2)
    summary = json.loads((out / "summary.json").read_text())
    return rows.reshape(-1, 2, rows.shape[1]), summary


def frames(steps):
    """(t, r in the primary's frame, C = R_p^T R_s, R_p, energy) of lgvi's long-format rows."""
    t = steps[:, 0, 0]
    rp = rotation(steps[:, 0, 5:9])
    rs = rotation(steps[:, 1, 5:9])
    r = np.einsum("kji,kj->ki", rp, steps[:, 1, 2:5] - steps[:, 0, 2:5])
    c = np.einsum("kji,kjl->kil", rp, rs)
    return t, r, c, rp, steps[:, 0, 16]


def compare(a, b):
    """max |r_a - r_b| / |r|, max relative-attitude angle, max primary-attitude angle."""
    ta, ra, ca, pa = a[:4]
    tb, rb, cb, pb = b[:4]
    common = np.intersect1d(np.round(ta, 6), np.round(tb, 6))
    ia = np.searchsorted(np.round(ta, 6), common)
    ib = np.searchsorted(np.round(tb, 6), common)
    dr = np.max(np.linalg.norm(ra[ia] - rb[ib], axis=1) / np.linalg.norm(ra[ia], axis=1))
    dc = max(angle(ca[i], cb[j]) for i, j in zip(ia, ib))
    dp = max(angle(pa[i], pb[j]) for i, j in zip(ia, ib))
    return dr, dc, dp


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("gubas", type=pathlib.Path)
    ap.add_argument("lgvi")
    ap.add_argument("out", type=pathlib.Path)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    if not (args.gubas / "hou_cpp_final").exists():
        sys.exit(f"{args.gubas}/hou_cpp_final: not built (g++ -std=c++11 hou_cpp.cpp -o hou_cpp_final -larmadillo)")
    args.out.mkdir(parents=True, exist_ok=True)
    gstate, genergy = run_gubas(args.gubas, args.out / "gubas")
    g = (gstate[:, 0], gstate[:, 1:4], gstate[:, 13:22].reshape(-1, 3, 3), gstate[:, 22:31].reshape(-1, 3, 3), genergy)
    text = SCENARIO.read_text()
    steps, summary = run_lgvi(args.lgvi, text, args.out / "lgvi")
    lg = frames(steps)
    fine_text = re.sub(r"step = 30.0", "step = 1.875", text)
    fine, _ = run_lgvi(args.lgvi, fine_text, args.out / "lgvi-fine", every=16)
    lf = frames(fine)
    d_gubas = compare(lg, g)
    d_trunc = compare(lg, lf)
    d_gubas_fine = compare(g, lf)
    e0 = lg[4][0]

    # Timing: GUBAS's integrator alone (its Python driver computes the inertia
    # integrals and post-processes; hou_cpp_final reads ic_input.txt and writes
    # the binary states), net of its start-up: the time of 2880 steps minus that
    # of 1 step, over 2879; and lgvi run writing only the first and last rows.
    work = args.out / "gubas"
    full = (work / "ic_input.txt").read_text()
    if "\n86400.0\n" not in full:
        sys.exit("GUBAS's ic_input.txt has no final time 86400.0 line: another GUBAS version?")
    one = full.replace("\n86400.0\n", "\n30.0\n", 1)
    times = {"gubas": [], "lgvi": []}

    def gubas_seconds(ic):
        (work / "ic_input.txt").write_text(ic)
        start = time.perf_counter()
        subprocess.run(["./hou_cpp_final"], cwd=work, check=True, capture_output=True)
        return time.perf_counter() - start

    for _ in range(args.repeat):
        times["gubas"].append((gubas_seconds(full) - gubas_seconds(one)) / 2879)
        _, s = run_lgvi(args.lgvi, text, args.out / "lgvi-timing", every=100000)
        times["lgvi"].append(s["wall_seconds"] / 2880)
    tg, tl = statistics.median(times["gubas"]), statistics.median(times["lgvi"])

    print("Didymos example at order 2 (GUBAS), 86400 s in 2880 steps of 30 s:\n")
    print("| compared | max \\|r - r'\\| / \\|r\\| | max relative-attitude angle (rad) | max primary-attitude angle (rad) |")
    print("|---|---:|---:|---:|")
    print(f"| lgvi vs GUBAS, both h = 30 s | {d_gubas[0]:.3e} | {d_gubas[1]:.3e} | {d_gubas[2]:.3e} |")
    print(f"| lgvi h = 30 s vs lgvi h = 1.875 s (truncation error) | {d_trunc[0]:.3e} | {d_trunc[1]:.3e} | {d_trunc[2]:.3e} |")
    print(f"| GUBAS h = 30 s vs lgvi h = 1.875 s | {d_gubas_fine[0]:.3e} | {d_gubas_fine[1]:.3e} | {d_gubas_fine[2]:.3e} |")
    print()
    print("| program | max \\|E - E0\\| / \\|E0\\| over the day | time per step (median of "
          f"{args.repeat}) | / lgvi |")
    print("|---|---:|---:|---:|")
    print(f"| lgvi (quaternion LGVI, inertial frame) | {np.max(np.abs(lg[4] - e0)) / abs(e0):.3e} | "
          f"{tl * 1e6:.2f} us | 1.00 |")
    print(f"| GUBAS (rotation-matrix LGVI, relative frame; net of start-up) | {np.max(np.abs(genergy - genergy[0])) / abs(genergy[0]):.3e} | "
          f"{tg * 1e6:.2f} us | {tg / tl:.2f} |")
    print(f"\nE0: lgvi {e0:.10e} J, GUBAS {genergy[0]:.10e} J; timings (s per step): {json.dumps(times)}")


if __name__ == "__main__":
    main()
