#!/usr/bin/python3
"""A gravity-gradient spacecraft in low Earth orbit with J2, 1000 orbits: lgvi against
rk4-normalized at equal cost (issue 9).

    /usr/bin/python3 scripts/leo_libration.py [--lgvi build/lgvi] [--out docs/leo] [--orbits 1000]

Runs scenarios/leo-gravity-gradient.toml with lgvi (its step, h = 10 s, one potential evaluation
per step) and with rk4-normalized at 4 h (four evaluations per step: the same number of
evaluations over the run). From each trajectory: the pitch libration angle (body x against the
local vertical, about the orbit normal), the relative energy error |E - E0| / |E0|, ||q| - 1|
and the change of the angular momentum about the pole, k . (L - L0) / |L0| (conserved by the
field's symmetry; the other components of L precess with the orbit's node). Writes
OUT/pitch.png, OUT/errors.png and OUT/comparison.md, and prints the table.
"""

import argparse
import json
import pathlib
import re
import subprocess
import tempfile

import numpy as np

REPO = pathlib.Path(__file__).resolve().parent.parent
SCENARIO = REPO / "scenarios" / "leo-gravity-gradient.toml"
POLE = np.array([0.0, 0.0, 1.0])


def pitch_angle(r):
    """Angle of body x from the radial direction about the orbit normal (rad)."""
    x, p = r.x, r.p
    radial = x / np.linalg.norm(x, axis=1)[:, None]
    normal = np.cross(x, p)
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    along = np.cross(normal, radial)
    body_x = r.rotation_matrices()[:, :, 0]
    return np.arctan2(np.einsum("ij,ij->i", body_x, along), np.einsum("ij,ij->i", body_x, radial))


def run(lgvi, method, step, orbits, every, out):
    text = SCENARIO.read_text()
    text = re.sub(r'method = "lgvi"', f'method = "{method}"', text)
    text = re.sub(r"step = 10\.0", f"step = {step!r}", text)
    text = re.sub(r"duration = 5676978\.0", f"duration = {5676.978 * orbits!r}", text)
    text = re.sub(r"every = 57", f"every = {every}", text)
    path = out.parent / f"{method}.toml"
    path.write_text(text)
    subprocess.run([lgvi, "run", str(path), "--out", str(out), "--force", "--no-figures", "-q"], check=True)
    import lgvi as lg
    return lg.load(out), json.loads((out / "summary.json").read_text())


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--lgvi", default=str(REPO / "build" / "lgvi"))
    parser.add_argument("--out", default=str(REPO / "docs" / "leo"))
    parser.add_argument("--orbits", type=int, default=1000)
    args = parser.parse_args()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        (tmp / "runs").mkdir()
        # every 8 lgvi steps = 2 RK4 steps of 4 h: rows at the same times, 71 per orbit.
        for method, step, every in (("lgvi", 10.0, 8), ("rk4-normalized", 40.0, 2)):
            r, summary = run(args.lgvi, method, step, args.orbits, every, tmp / "runs" / method)
            e0 = r.columns["energy"][0]
            l0 = r.L[0]
            results[method] = {
                "t": r.t, "pitch": pitch_angle(r),
                "energy": np.abs(r.columns["energy"] - e0) / abs(e0),
                "quat": np.abs(r.columns["quat_norm_error"]),
                "pole": np.abs((r.L - l0) @ POLE) / np.linalg.norm(l0),
                "evaluations": summary["potential_evaluations"], "wall": summary["wall_seconds"],
            }

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    period = 5676.978
    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharey=True)
    for ax, window in zip(axes, ((0, 10), (args.orbits - 10, args.orbits))):
        for method, style in (("lgvi", "-"), ("rk4-normalized", "--")):
            d = results[method]
            orbit = d["t"] / period
            sel = (orbit >= window[0]) & (orbit <= window[1])
            ax.plot(orbit[sel], np.degrees(d["pitch"][sel]), style, lw=1, label=method)
        ax.set_xlabel("orbits")
        ax.set_ylabel("pitch (deg)")
        ax.grid(alpha=0.3)
    axes[0].set_title("Gravity-gradient pitch libration, 500 km orbit with J2 (first and last 10 orbits)")
    axes[0].legend()
    fig.tight_layout()
    fig.savefig(out / "pitch.png", dpi=110)

    fig, axes = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
    floor = 1e-18  # exact zeros drawn at the floor (log axis)
    for method in results:
        d = results[method]
        orbit = d["t"] / period
        for ax, key in zip(axes, ("energy", "quat", "pole")):
            ax.semilogy(orbit, np.maximum(d[key], floor), lw=0.8, label=method)
    for ax, label in zip(axes, ("|E - E0| / |E0|", "||q| - 1| (floor 1e-18)", "|k.(L - L0)| / |L0|")):
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend()
    axes[-1].set_xlabel("orbits")
    axes[0].set_title("Equal cost: lgvi h = 10 s against rk4-normalized h = 40 s")
    fig.tight_layout()
    fig.savefig(out / "errors.png", dpi=110)

    lines = [f"# LEO gravity-gradient libration with J2, {args.orbits} orbits, equal cost",
             "",
             "`/usr/bin/python3 scripts/leo_libration.py` (scenarios/leo-gravity-gradient.toml). "
             "Maxima over the run; pitch amplitude over the last 10 orbits (it starts at 5 deg).",
             "",
             "| method | step | potential evaluations | max rel. energy error | final rel. energy error | "
             "max ||q|-1| | max rel. change of L about the pole | pitch amplitude, last 10 orbits (deg) |",
             "|---|---|---|---|---|---|---|---|"]
    for method, step in (("lgvi", 10.0), ("rk4-normalized", 40.0)):
        d = results[method]
        last = d["t"] / period >= args.orbits - 10
        lines.append(f"| {method} | {step:g} s | {d['evaluations']} | {d['energy'].max():.2e} | "
                     f"{d['energy'][-1]:.2e} | {d['quat'].max():.1e} | {d['pole'].max():.1e} | "
                     f"{np.degrees(np.abs(d['pitch'][last]).max()):.3f} |")
    text = "\n".join(lines) + "\n"
    (out / "comparison.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
