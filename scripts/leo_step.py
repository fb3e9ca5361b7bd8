#!/usr/bin/python3
"""How the step size of scenarios/leo-gravity-gradient.toml changes the attitude: runs it for
ORBITS orbits at h = T/2000 ... T/25 (T = 5676.978 s), rows every T/5, and prints the largest
difference of the LVLH pitch and roll (Result.lvlh_angles) from the h = T/2000 run, the total
energy's relative error and that error over the rotational kinetic energy (summary
'rotation'). The table in docs/guide/orbit-attitude.md ('Choosing the step for an orbit').

    PYTHONPATH=build/python /usr/bin/python3 scripts/leo_step.py [--lgvi build/lgvi] [--orbits 100]
"""
import argparse
import json
import math
import pathlib
import re
import subprocess
import tempfile

import numpy as np

import lgvi

REPO = pathlib.Path(__file__).resolve().parent.parent
T = 5676.978  # the orbit's period, s
T_LIBRATION = T / math.sqrt(3 * (20.48 - 2.98) / 22.98)  # 2 pi / (n sqrt(3 (Jy - Jx) / Jz)), J = (2.98, 20.48, 22.98)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--lgvi", default=str(REPO / "build" / "lgvi"))
    parser.add_argument("--orbits", type=int, default=100)
    args = parser.parse_args()
    src = (REPO / "scenarios" / "leo-gravity-gradient.toml").read_text()
    runs = {}
    with tempfile.TemporaryDirectory() as tmp:
        for div in (2000, 1000, 500, 200, 100, 50, 25):
            text = re.sub(r"^step = .*$", f"step = {T / div!r}", src, flags=re.M)
            text = re.sub(r"^duration = .*$", f"duration = {T * args.orbits!r}", text, flags=re.M)
            text = re.sub(r"^every = .*$", f"every = {div // 5}", text, flags=re.M)
            path = pathlib.Path(tmp) / f"h{div}.toml"
            path.write_text(text)
            out = pathlib.Path(tmp) / f"h{div}"
            subprocess.run([args.lgvi, "run", str(path), "--out", str(out), "--no-figures", "-q"], check=True)
            runs[div] = (lgvi.load(out).lvlh_angles(), json.loads((out / "summary.json").read_text()))
    ref = runs[2000][0]
    print("| h | h [s] | steps per libration | max |dpitch| deg | max |droll| deg | max |E - E0|/|E0| "
          "| max |E - E0| / max T_rot |")
    for div, (a, s) in runs.items():
        if div == 2000:
            continue
        n = min(len(a), len(ref))
        dpitch = np.abs((a[:n, 1] - ref[:n, 1] + 180.0) % 360.0 - 180.0).max()
        droll = np.abs(a[:n, 0] - ref[:n, 0]).max()
        print(f"| T/{div} | {T / div:.4g} | {T_LIBRATION / (T / div):.0f} | {dpitch:.2g} | {droll:.2g} | "
              f"{s['max_abs_energy_error'] / abs(s['initial_energy']):.2g} | "
              f"{s['rotation']['energy_error_over_max_kinetic_energy']:.2g} |")


if __name__ == "__main__":
    main()
